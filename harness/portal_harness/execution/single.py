"""One render outside a sweep (`portal-harness run`, `reference`): executed
into the store with a live progress bar, then recorded in the index."""

from __future__ import annotations

from typing import Any

from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.execution import index, runs
from portal_harness.execution.progress import RunProgress
from portal_harness.experiment.spec import RunSpec


def run_and_index(
    spec: RunSpec, layout: ResultsLayout, renderer: str, version: str, force: bool = False
) -> tuple[dict[str, Any], RunLayout]:
    """Renders `spec` unless a finished run of its key exists (or `force`);
    returns its manifest and its run folder, indexed."""
    progress = RunProgress(spec.time_s, spec.spp)
    try:
        manifest = runs.execute(spec, layout, renderer, version, on_event=progress, force=force)
    finally:
        progress.close()
    run = layout.run(spec.key(version), spec.reference)
    conn = index.connect(layout.index_path)
    try:
        index.record_run(conn, manifest, run.dir)
    finally:
        conn.close()
    return manifest, run
