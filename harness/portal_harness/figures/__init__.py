"""The figures of an experiment, one module per figure, with their shared
data (data.py), style (style.py) and layout (layout.py); make_all.py draws them all.

May import every package below it (core/ to analysis/), never service/, viewer/ or cli."""

import matplotlib

matplotlib.use("Agg")  # pinned: figures are files, never windows
