"""Running renders: the renderer as a subprocess, one run into the store, the
local or Dask pool, the SQLite index, sweep plans and progress bars.

May import core/ and experiment/."""
