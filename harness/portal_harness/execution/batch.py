"""Running a batch of RunSpecs (runs, references, pilots, region maps):
finished ones are taken from the store, the rest rendered locally or on Dask,
each indexed as it ends, under one progress bar."""

from __future__ import annotations

import sqlite3
import sys
from dataclasses import dataclass
from typing import Any

from tqdm import tqdm

from portal_harness.core.paths import ResultsLayout
from portal_harness.execution import index, store
from portal_harness.execution.execute import Target, plan_jobs, run_dask, run_local
from portal_harness.experiment.spec import RunSpec


@dataclass(frozen=True)
class SweepOptions:
    layout: ResultsLayout
    renderer: str
    renderer_version: str
    jobs: int | None = None
    scheduler: str | None = None
    retry_failed: bool = True
    progress: bool = True


def execute_specs(
    specs: list[RunSpec], options: SweepOptions, conn: sqlite3.Connection, desc: str = "renders", force: bool = False
) -> dict[str, dict[str, Any]]:
    """Runs every spec not already finished (all of them if `force`), indexing
    each as it ends. Returns the manifests by key (cached ones included)."""
    manifests: dict[str, dict[str, Any]] = {}
    todo: list[RunSpec] = []
    queued: set[str] = set()
    for spec in specs:
        key = spec.key(options.renderer_version)
        if key in manifests or key in queued:
            continue
        run = options.layout.run(key, spec.reference)
        existing = store.read_manifest(run)
        finished = existing is not None and (
            existing.get("status") == store.STATUS_DONE
            or (not options.retry_failed and existing.get("status") == store.STATUS_FAILED)
        )
        if existing is not None and finished and not force:
            manifests[key] = {**existing, "cached": True}
            index.record_run(conn, existing, run.dir)
        else:
            todo.append(spec)
            queued.add(key)
    if not todo:
        return manifests
    bar = tqdm(
        total=len(todo), desc=desc, unit="render", disable=not options.progress, file=sys.stderr, dynamic_ncols=True
    )

    def done(spec: RunSpec, manifest: dict[str, Any]) -> None:
        key = manifest["key"]
        manifests[key] = manifest
        if manifest.get("installed", True):
            index.record_run(conn, manifest, options.layout.run(key, spec.reference).dir)
        label = "reference" if spec.reference else spec.strategy
        bar.set_postfix_str(f"{label} {dict(spec.labels) or ''} {manifest['status']}", refresh=False)
        bar.update(1)

    target = Target(options.layout, options.renderer, options.renderer_version, options.retry_failed, force)
    try:
        if options.scheduler:
            run_dask(todo, target, options.scheduler, done)
        else:
            threads = max(s.threads for s in todo)
            run_local(todo, target, plan_jobs(threads, options.jobs), done)
    finally:
        bar.close()
    return manifests
