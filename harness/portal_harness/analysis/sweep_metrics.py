"""Metrics of a sweep's finished runs against their points' references, per
region (measure.py), reused when up to date."""

from __future__ import annotations

import sqlite3
from typing import Any

from portal_harness.analysis import measure
from portal_harness.execution import index, store
from portal_harness.execution.batch import SweepOptions
from portal_harness.execution.plan import PlannedRun
from portal_harness.experiment.model import Experiment
from portal_harness.reference.references import PointReference


def compute_metrics(
    experiment: Experiment,
    runs: list[PlannedRun],
    refs: dict[str, PointReference],
    options: SweepOptions,
    conn: sqlite3.Connection,
    manifests: dict[str, dict[str, Any]],
) -> list[str]:
    """Metrics of every finished run against its point's reference, on the
    point's regions; returns the problems found."""
    problems: list[str] = []
    for planned in runs:
        manifest = manifests.get(planned.key)
        ref = refs[planned.reference]
        if manifest is None or manifest.get("status") != store.STATUS_DONE or ref.snapshot is None:
            continue
        assert ref.key is not None
        run = options.layout.run(planned.key)
        if measure.up_to_date(run, ref.key, ref.regions):
            rows = measure.read_rows(run)
            if not index.metrics_of(conn, planned.key, ref.key):
                index.record_metrics(conn, planned.key, ref.key, rows)
        else:
            rows = measure.compute(run, manifest, ref.snapshot, ref.regions)
            measure.write_files(run, planned.key, ref.key, ref.regions, rows)
            index.record_metrics(conn, planned.key, ref.key, rows)
        for row in rows:
            if row.error:
                problems.append(f"{planned.strategy} {planned.point.id} {row.image}: {row.error}")
    return problems
