"""portal_harness: the experiment harness of portal-lights.

A thin pipeline, file to file: experiment config -> runs of the renderer ->
metrics against references -> figures, with a run store, a SQLite index and a
variance regression check. The renderer is driven only through its
command-line contract (notes/renderer_contract.md); the harness never samples
light.
"""

__version__ = "0.1.0"
