"""`sweep`: expand an experiment's cross product, make each point's
reference, run every (point, strategy), compute metrics, write a summary.

Resuming is the default: a run whose folder holds a "done" manifest is not
rendered again; failed runs are retried (unless --skip-failed). A failed run
never stops the sweep; the exit status is 1 if any run or reference failed.
"""

from __future__ import annotations

import csv
import io
import math
import sqlite3
import sys
from dataclasses import dataclass
from typing import Any, TextIO

from tqdm import tqdm

from portal_harness import exr, index, measure, store
from portal_harness.config import Experiment, Point
from portal_harness.errors import CorruptExrError
from portal_harness.execute import Target, plan_jobs, run_dask, run_local
from portal_harness.metrics import WHOLE_IMAGE, efficiency, floor_corrected_efficiency
from portal_harness.paths import ResultsLayout
from portal_harness.spec import RunSpec

ROLE_RUN = "run"
ROLE_REFERENCE = "reference"
BASELINE_STRATEGY = "light"


@dataclass(frozen=True)
class PlannedRun:
    point: Point
    strategy: str
    spec: RunSpec
    key: str
    reference_key: str


@dataclass(frozen=True)
class Plan:
    runs: tuple[PlannedRun, ...]
    references: tuple[tuple[Point, RunSpec, str], ...]

    def specs(self) -> list[RunSpec]:
        """References first (each once), then runs, in sweep order."""
        seen: set[str] = set()
        out: list[RunSpec] = []
        for _, spec, key in self.references:
            if key not in seen:
                seen.add(key)
                out.append(spec)
        out += [r.spec for r in self.runs]
        return out


def make_plan(experiment: Experiment, renderer_version: str) -> Plan:
    runs: list[PlannedRun] = []
    refs: list[tuple[Point, RunSpec, str]] = []
    for point in experiment.points():
        ref = experiment.reference_spec(point)
        ref_key = ref.key(renderer_version)
        refs.append((point, ref, ref_key))
        for strategy in experiment.strategies:
            spec = experiment.run_spec(point, strategy)
            runs.append(PlannedRun(point, strategy, spec, spec.key(renderer_version), ref_key))
    return Plan(runs=tuple(runs), references=tuple(refs))


def record_plan(conn: sqlite3.Connection, experiment: Experiment, plan: Plan) -> None:
    rows: list[tuple[str, str, str, str, str | None, float]] = [
        (point.id, spec.strategy, ROLE_REFERENCE, key, None, point.axis_value) for point, spec, key in plan.references
    ]
    rows += [(r.point.id, r.strategy, ROLE_RUN, r.key, r.reference_key, r.point.axis_value) for r in plan.runs]
    index.record_membership(conn, experiment.name, rows)


@dataclass(frozen=True)
class SweepOptions:
    layout: ResultsLayout
    renderer: str
    renderer_version: str
    jobs: int | None = None
    scheduler: str | None = None
    retry_failed: bool = True
    progress: bool = True


def execute_specs(specs: list[RunSpec], options: SweepOptions, conn: sqlite3.Connection,
                  desc: str = "renders", force: bool = False) -> dict[str, dict[str, Any]]:
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
            or (not options.retry_failed and existing.get("status") == store.STATUS_FAILED))
        if existing is not None and finished and not force:
            manifests[key] = {**existing, "cached": True}
            index.record_run(conn, existing, run.dir)
        else:
            todo.append(spec)
            queued.add(key)
    if not todo:
        return manifests
    bar = tqdm(total=len(todo), desc=desc, unit="render", disable=not options.progress, file=sys.stderr,
               dynamic_ncols=True)

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


def compute_metrics(experiment: Experiment, plan: Plan, options: SweepOptions, conn: sqlite3.Connection,
                    manifests: dict[str, dict[str, Any]]) -> list[str]:
    """Metrics of every finished run against its point's reference; returns problems found."""
    problems: list[str] = []
    references: dict[str, exr.Snapshot | None] = {}
    for planned in plan.runs:
        manifest = manifests.get(planned.key)
        if manifest is None or manifest.get("status") != store.STATUS_DONE:
            continue
        ref_key = planned.reference_key
        if ref_key not in references:
            ref_manifest = manifests.get(ref_key)
            references[ref_key] = None
            if ref_manifest is not None and ref_manifest.get("status") == store.STATUS_DONE:
                try:
                    references[ref_key] = exr.read_snapshot(options.layout.run(ref_key, True).final)
                except CorruptExrError as e:
                    problems.append(f"reference {ref_key} ({planned.point.id}): {e}")
        reference = references[ref_key]
        if reference is None:
            continue
        run = options.layout.run(planned.key)
        have_rows = bool(index.metrics_of(conn, planned.key, ref_key))
        if measure.up_to_date(run, ref_key, experiment.insets):
            rows = measure.read_rows(run)
            if not have_rows:
                index.record_metrics(conn, planned.key, ref_key, rows)
        else:
            rows = measure.compute(run, manifest, reference, experiment.insets)
            measure.write_files(run, planned.key, ref_key, experiment.insets, rows)
            index.record_metrics(conn, planned.key, ref_key, rows)
        for row in rows:
            if row.error:
                problems.append(f"{planned.strategy} {planned.point.id} {row.image}: {row.error}")
    return problems


def summarize(experiment: Experiment, plan: Plan, conn: sqlite3.Connection,
              manifests: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (point, strategy): status and the final image's metrics;
    efficiency = 1 / (relMSE x time); efficiency_vs_light uses the
    reference-noise-corrected efficiency of both (metrics.floor_corrected_efficiency)
    and is a lower bound where reference_limited is true."""
    rows: list[dict[str, Any]] = []
    for planned in plan.runs:
        manifest = manifests.get(planned.key, {})
        row: dict[str, Any] = {
            "point": planned.point.id, "axis": planned.point.axis_value, "strategy": planned.strategy,
            "key": planned.key, "reference_key": planned.reference_key,
            "status": manifest.get("status", "missing"), "error": manifest.get("error"),
        }
        final = [m for m in index.metrics_of(conn, planned.key, planned.reference_key) if m["is_final"]]
        for m in final:
            suffix = "" if m["region"] == WHOLE_IMAGE else f"_{m['region']}"
            row[f"rel_mse{suffix}"] = m["rel_mse"]
            row[f"mse{suffix}"] = m["mse"]
            if m["region"] == WHOLE_IMAGE:
                row["time_s"] = m["time_s"]
                row["spp"] = m["spp"]
                row["rel_mse_floor"] = m["floor_rel"]
                if m["rel_mse"] is not None:
                    row["efficiency"] = efficiency(m["rel_mse"], m["time_s"])
                    row["efficiency_corrected"], row["reference_limited"] = floor_corrected_efficiency(
                        m["rel_mse"], m["floor_rel"] or 0.0, m["time_s"])
        rows.append(row)
    for row in rows:
        base = next((r for r in rows if r["point"] == row["point"] and r["strategy"] == BASELINE_STRATEGY), None)
        e, b = row.get("efficiency_corrected", math.nan), (base or {}).get("efficiency_corrected", math.nan)
        row["efficiency_vs_light"] = e / b if math.isfinite(e) and math.isfinite(b) and b > 0 else math.nan
    return rows


def write_summary(experiment: Experiment, layout: ResultsLayout, rows: list[dict[str, Any]],
                  failures: list[str], problems: list[str]) -> None:
    folder = layout.experiment_dir(experiment.name)
    folder.mkdir(parents=True, exist_ok=True)
    clean = [{k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in r.items()} for r in rows]
    store.write_json_atomic(layout.summary_json(experiment.name), {
        "experiment": experiment.name, "file": str(experiment.path), "rows": clean,
        "failures": failures, "problems": problems,
    })
    fields: list[str] = []
    for r in rows:
        fields += [k for k in r if k not in fields]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    for r in clean:
        writer.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in fields})
    layout.summary_csv(experiment.name).write_text(buffer.getvalue())


def print_table(rows: list[dict[str, Any]], out: TextIO) -> None:
    header = (f"{'point':<22} {'strategy':<17} {'status':<12} {'time_s':>7} {'spp':>7} {'relMSE':>10} "
              f"{'eff/light':>10}")
    print(header, file=out)
    print("-" * len(header), file=out)
    for r in rows:
        def fmt(v: Any, spec: str) -> str:
            return format(v, spec) if isinstance(v, (int, float)) and math.isfinite(v) else "-"
        print(f"{r['point']:<22} {r['strategy']:<17} {r['status']:<12} {fmt(r.get('time_s'), '7.2f'):>7} "
              f"{fmt(r.get('spp'), '7d'):>7} {fmt(r.get('rel_mse'), '10.3e'):>10} "
              f"{'>' if r.get('reference_limited') else ' '}{fmt(r.get('efficiency_vs_light'), '9.3g'):>9}", file=out)
    print("(eff/light: efficiency relative to light sampling, reference noise removed; "
          "'>' a lower bound, the run's error being within 2x the reference's noise)", file=out)


def failures_of(plan: Plan, manifests: dict[str, dict[str, Any]]) -> list[str]:
    out = []
    for point, _, key in plan.references:
        m = manifests.get(key)
        if m is None or m.get("status") != store.STATUS_DONE:
            out.append(f"reference {point.id} [{key}]: {(m or {}).get('status', 'missing')}: "
                       f"{(m or {}).get('error') or ''} {_last_line((m or {}).get('stderr_tail'))}".rstrip())
    for r in plan.runs:
        m = manifests.get(r.key)
        if m is None or m.get("status") != store.STATUS_DONE:
            out.append(f"{r.strategy} {r.point.id} [{r.key}]: {(m or {}).get('status', 'missing')}: "
                       f"{(m or {}).get('error') or ''} {_last_line((m or {}).get('stderr_tail'))}".rstrip())
    return out


def _last_line(text: str | None) -> str:
    lines = [line for line in (text or "").splitlines() if line.strip()]
    return f"(stderr: {lines[-1][:160]})" if lines else ""


def sweep(experiment: Experiment, options: SweepOptions, out: TextIO | None = None) -> int:
    """Runs the whole sweep; returns the exit status (0 all done, 1 failures)."""
    out = out or sys.stdout
    layout = options.layout
    layout.root.mkdir(parents=True, exist_ok=True)
    store.clean_stale_attempts(layout)
    plan = make_plan(experiment, options.renderer_version)
    conn = index.connect(layout.index_path)
    try:
        record_plan(conn, experiment, plan)
        specs = plan.specs()
        manifests = execute_specs(specs, options, conn)
        rendered = sum(1 for m in manifests.values() if not m.get("cached"))
        problems = compute_metrics(experiment, plan, options, conn, manifests)
        rows = summarize(experiment, plan, conn, manifests)
        failures = failures_of(plan, manifests)
        write_summary(experiment, layout, rows, failures, problems)
    finally:
        conn.close()
    print(f"sweep {experiment.name}: {len(specs)} renders ({len(plan.references)} references), "
          f"{rendered} rendered now, {len(specs) - rendered} cached", file=out)
    print_table(rows, out)
    print(f"summary: {layout.summary_json(experiment.name)}", file=out)
    for p in problems:
        print(f"problem: {p}", file=out)
    if failures:
        print(f"{len(failures)} failed:", file=out)
        for f in failures:
            print(f"  {f}", file=out)
    return 1 if failures or problems else 0
