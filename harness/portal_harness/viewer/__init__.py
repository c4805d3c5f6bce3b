"""The comparison viewer: the data of an experiment for the browser
(bundle.py), the static report folder (report.py) and the page itself
(static/)."""
