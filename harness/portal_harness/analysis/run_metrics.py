"""`portal-harness metrics` and `reindex`: metrics of named runs against a
reference (the run's experiment reference, the finished reference of its scene
hash, or the one given), and the index rebuilt from the run folders."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any, TextIO

from portal_harness.analysis import measure
from portal_harness.core import exr
from portal_harness.core.errors import ConfigError, CorruptExrError, HarnessError
from portal_harness.core.metrics import Region
from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.core.regions import regions_of
from portal_harness.execution import index, store


def resolve_run(layout: ResultsLayout, name: str) -> RunLayout:
    """A run folder, or the run (else reference) of that key."""
    p = Path(name)
    if p.is_dir():
        return RunLayout(p.resolve())
    for reference in (False, True):
        run = layout.run(name, reference)
        if run.dir.is_dir():
            return run
    raise ConfigError(name, "", "no such run folder or run key")


def reference_for(
    layout: ResultsLayout, conn: sqlite3.Connection, manifest: dict[str, Any], given: str | None
) -> RunLayout:
    """The reference a run is measured against: `given`, else its
    experiment's, else the finished reference of its scene hash."""
    if given:
        return resolve_run(layout, given)
    key = index.experiment_reference_key(conn, manifest["key"])
    if key is not None and store.is_done(layout.run(key, True)):
        return layout.run(key, True)
    found = index.find_reference(conn, manifest["scene_hash"])
    if found is None:
        raise HarnessError(
            f"no reference for run {manifest['key']} (scene hash {manifest['scene_hash']}): "
            "make one with `portal-harness reference` or pass --reference"
        )
    return RunLayout(Path(found["run_dir"]))


def measure_runs(
    layout: ResultsLayout,
    names: list[str],
    reference_name: str | None,
    insets: tuple[Region, ...],
    lit_threshold: float,
    err: TextIO,
) -> tuple[int, list[dict[str, Any]]]:
    """Measures each named run against its reference, writes the run folder's
    metrics files and the index rows; returns (status, one dict per image and
    region). Status 1 if a run is not finished or an image is corrupt (told on `err`)."""
    conn = index.connect(layout.index_path)
    status = 0
    results: list[dict[str, Any]] = []
    try:
        for name in names:
            run = resolve_run(layout, name)
            manifest = store.read_manifest(run)
            if manifest is None or manifest.get("status") != store.STATUS_DONE:
                print(
                    f"{run.dir}: not a finished run (status {(manifest or {}).get('status', 'no manifest')}): skipped",
                    file=err,
                )
                status = 1
                continue
            ref_run = reference_for(layout, conn, manifest, reference_name)
            ref_manifest = store.read_manifest(ref_run)
            ref_key = (ref_manifest or {}).get("key", ref_run.dir.name)
            try:
                reference = exr.read_snapshot(ref_run.final)
            except CorruptExrError as e:
                raise HarnessError(f"reference unusable: {e}") from None
            for r in insets:
                if not r.fits(reference.header.width, reference.header.height):
                    raise ConfigError(
                        "--inset", r.name, f"does not fit the {reference.header.width}x{reference.header.height} image"
                    )
            regions = regions_of(reference, insets, lit_threshold)
            rows = measure.compute(run, manifest, reference, regions)
            measure.write_files(run, manifest["key"], ref_key, regions, rows)
            index.record_run(conn, manifest, run.dir)
            index.record_metrics(conn, manifest["key"], ref_key, rows)
            for row in rows:
                if row.error:
                    print(f"corrupt: {row.error}", file=err)
                    status = 1
                results.append(
                    {
                        "run": manifest["key"],
                        "reference": ref_key,
                        "strategy": manifest["spec"]["strategy"],
                        **row.__dict__,
                    }
                )
    finally:
        conn.close()
    return status, results


def reindex(layout: ResultsLayout) -> int:
    """Re-records every run folder's manifest and metrics in the index; returns the folders indexed."""
    conn = index.connect(layout.index_path)
    count = 0
    try:
        for parent in (layout.runs_dir, layout.references_dir):
            if not parent.is_dir():
                continue
            for folder in sorted(parent.iterdir()):
                run = RunLayout(folder)
                manifest = store.read_manifest(run)
                if manifest is None:
                    continue
                index.record_run(conn, manifest, folder)
                count += 1
                if run.metrics_json.exists():
                    data = json.loads(run.metrics_json.read_text())
                    index.record_metrics(conn, manifest["key"], data["reference_key"], measure.read_rows(run))
    finally:
        conn.close()
    return count
