"""The experiment: the renderer's contract, run specs, scenes, and the
experiment config's model, schema and loader (everything checked before any render).

May import core/ only."""
