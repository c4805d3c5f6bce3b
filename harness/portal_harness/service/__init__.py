"""`portal-harness serve`: the experiment service over the results store (HTTP API, queue, workers, page)."""
