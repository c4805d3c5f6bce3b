"""`sweep`: expand an experiment's cross product, make each point's
reference, run every (point, strategy, replicate), compute metrics per
region, check that the references resolve them, write the tidy summary.

The stages, in order (references.py says more of each):
1. pilots: when reference.strategies is auto, a short render per candidate
   strategy and point chooses the reference strategies (pilot.py);
2. references: one or two independent renders per point; two are tested
   against each other region by region (a disagreement beyond
   reference.bias_z sigma stops the sweep, exit status 1) and combined;
3. runs: K = budget.replicates independent seeds per (point, strategy);
4. metrics of every image against its point's reference, per region
   (regions.py), then the noise check (noise_check.py): a reference whose
   noise exceeds reference.noise_ratio of the smallest error in some
   region is extended (extend.py, render --resume) and the metrics redone,
   at most MAX_EXTENSION_ROUNDS times or until reference.max_time_s;
5. with `precision:` (precision.py), two stages: the headline values'
   relative standard errors from the first budget.replicates replicates
   fix how many more each (point, strategy) gets (new seeds, at most
   precision.max_replicates, cut to precision.max_time_s); they are run,
   and the metrics and the noise check done again, once;
6. the tidy summary (summary.py): summary.csv/json, one row per (point,
   strategy, region); the printed table is its `lit` (or image) region;
   and the manifest (manifest.py): renderer, commit, machine, wall time,
   replicates, precision reached.

Resuming is the default: a run whose folder holds a "done" manifest is not
rendered again; failed runs are retried (unless --skip-failed). A failed run
never stops the sweep; the exit status is 1 if any run or reference failed.

This module runs the stages in order; each lives where it belongs: the plan
(execution/plan.py), the batches of renders (execution/batch.py), the region
renders (execution/region_renders.py), the reference strategies
(reference/choice.py), the references' lifecycle (reference/lifecycle.py), the
metrics (sweep_metrics.py), the summary (sweep_summary.py) and the console
report (console.py).
"""

from __future__ import annotations

import sqlite3
import statistics
import sys
import time
from typing import Any, TextIO

from portal_harness.analysis import manifest, precision
from portal_harness.analysis.console import print_report
from portal_harness.analysis.sweep_metrics import compute_metrics
from portal_harness.analysis.sweep_summary import (
    failures_of,
    references_info,
    section_failures,
    summarize,
    write_summary,
)
from portal_harness.execution import index, store
from portal_harness.execution.batch import SweepOptions, execute_specs
from portal_harness.execution.execute import plan_jobs
from portal_harness.execution.plan import PlannedRun, more_replicates, plan_runs
from portal_harness.execution.region_renders import region_maps, region_sections
from portal_harness.experiment.model import Experiment, Precision
from portal_harness.reference import references
from portal_harness.reference.choice import choose_reference_strategies
from portal_harness.reference.lifecycle import (
    MAX_EXTENSION_ROUNDS,
    adopt_stored_parts,
    build_references,
    check_references,
    extend_references,
    record_plan,
)
from portal_harness.reference.noise_check import RegionCheck
from portal_harness.reference.references import PointReference


def sweep(experiment: Experiment, options: SweepOptions, out: TextIO | None = None) -> int:
    """Runs the whole sweep; returns the exit status (0 all done, 1 failures or a bias)."""
    out = out or sys.stdout
    started = time.monotonic()
    layout = options.layout
    layout.root.mkdir(parents=True, exist_ok=True)
    store.clean_stale_attempts(layout)
    runs = plan_runs(experiment, options.renderer_version)
    if experiment.precision is not None:
        # Resuming: the replicates an earlier sweep added, found in the store or
        # recorded in its manifest (its run folders lost: rendered again at once).
        runs += more_replicates(
            experiment,
            runs,
            options.renderer_version,
            layout,
            manifest.planned_replicates(layout, experiment.name),
        )
    precision_info: dict[str, Any] | None = None
    spent_before = 0.0
    if experiment.precision is not None:
        p = experiment.precision
        spent_before = manifest.precision_spent_s(layout, experiment.name, p.rel_se, p.max_time_s)
    conn = index.connect(layout.index_path)
    manifests: dict[str, dict[str, Any]] = {}
    try:
        maps = region_maps(experiment, options, conn, manifests)
        sections = region_sections(experiment, options, conn, manifests)
        chosen = choose_reference_strategies(experiment, options, conn, manifests, maps)
        pilot_keys = {pid: c.pilot_keys for pid, c in chosen.items()}
        refs = {
            p.id: references.plan(
                experiment, p, chosen[p.id].strategies, options.renderer_version, chosen[p.id].first_time_s
            )
            for p in experiment.reference_points()
        }
        for pid, ref in refs.items():
            ref.region_map_key, ref.fractions = maps[pid]
            ref.parts = adopt_stored_parts(ref, options)
        record_plan(conn, experiment, runs, refs, pilot_keys, sections)
        part_specs = [part.spec for ref in refs.values() for part in ref.parts]
        manifests.update(execute_specs(part_specs, options, conn, desc="references"))
        biased = build_references(experiment, refs, options, conn, manifests)
        if biased:
            return _stop_biased(
                experiment, biased, "no run was measured against them", conn, runs, refs, pilot_keys, out, sections
            )
        manifests.update(execute_specs([r.spec for r in runs], options, conn, desc="runs"))
        measured = _measure(experiment, runs, refs, options, conn, manifests, out)
        if isinstance(measured, list):
            return _stop_biased(
                experiment, measured, "found after extending references", conn, runs, refs, pilot_keys, out, sections
            )
        problems, checks = measured
        rows = summarize(experiment, runs, refs, conn, manifests)
        if experiment.precision is not None:
            p = experiment.precision
            rounds: list[dict[str, Any]] = []
            # Two stages (precision.py): the first budget.replicates of every cell
            # fix how many replicates each needs; the estimates and their standard
            # errors come from all of them, and no value is looked at again.
            n0 = experiment.budget.replicates if experiment.budget is not None else 0
            first = [r for r in runs if r.replicate < n0]
            first_rows = rows if len(first) == len(runs) else summarize(experiment, first, refs, conn, manifests)
            values = precision.headline_values(first_rows, p)
            added, cut = _second_stage(experiment, runs, values, manifests, options, started - spent_before, out)
            if added:
                runs += added
                record_plan(conn, experiment, runs, refs, pilot_keys, sections)
                manifests.update(execute_specs([r.spec for r in added], options, conn, desc="replicates"))
                measured = _measure(experiment, runs, refs, options, conn, manifests, out)
                if isinstance(measured, list):
                    return _stop_biased(
                        experiment,
                        measured,
                        "found after extending references",
                        conn,
                        runs,
                        refs,
                        pilot_keys,
                        out,
                        sections,
                    )
                problems, checks = measured
                rows = summarize(experiment, runs, refs, conn, manifests)
                rounds.append({"added": len(added), "elapsed_s": round(time.monotonic() - started, 1)})
            values = precision.headline_values(rows, p)
            precision_info = {
                **precision.report(values, p),
                "max_replicates": p.max_replicates,
                "max_time_s": p.max_time_s,
                "stopped": _stopped(values, _cell_counts(runs), p, cut),
                "rounds": rounds,
                "spent_s": round(spent_before + time.monotonic() - started, 1),
            }
        record_plan(conn, experiment, runs, refs, pilot_keys, sections)
        info = references_info(refs, checks, manifests)
        failures = failures_of(runs, refs, manifests) + section_failures(sections, manifests)
        write_summary(experiment, layout, rows, info, failures, problems, precision_info)
        manifest.write(
            layout,
            experiment.name,
            options.renderer_version,
            time.monotonic() - started,
            any(not m.get("cached") for m in manifests.values()),
            _replicates(runs),
            _render_time(manifests),
            precision_info,
        )
    finally:
        conn.close()
        # Again at the end: a process of a killed earlier sweep (the pool's
        # workers die with their parent, but not at once) may still have been
        # alive when this sweep started, and its attempt folder kept.
        store.clean_stale_attempts(layout)
    print_report(
        experiment.name,
        len(runs),
        sum(len(r.parts) for r in refs.values()),
        manifests,
        info,
        rows,
        layout.summary_json(experiment.name),
        problems,
        failures,
        out,
    )
    return 1 if failures or problems else 0


def _measure(
    experiment: Experiment,
    runs: list[PlannedRun],
    refs: dict[str, PointReference],
    options: SweepOptions,
    conn: sqlite3.Connection,
    manifests: dict[str, dict[str, Any]],
    out: TextIO,
) -> tuple[list[str], dict[str, list[RegionCheck]]] | list[str]:
    """Metrics of every finished run, the noise check, and the references'
    extensions it asks for (each followed by metrics and the check again):
    (problems, checks), or the bias test's lines when an extension brought
    out a disagreement between a point's two references."""
    problems = compute_metrics(experiment, runs, refs, options, conn, manifests)
    checks = check_references(experiment, runs, refs, conn)
    for _ in range(MAX_EXTENSION_ROUNDS):
        extended = extend_references(experiment, refs, checks, options, manifests, out)
        if not extended:
            break
        for pid in extended:
            for part in refs[pid].parts:
                index.record_run(conn, manifests[part.key], options.layout.run(part.key, True).dir)
        biased = build_references(experiment, {pid: refs[pid] for pid in extended}, options, conn, manifests)
        if biased:
            return biased
        problems = compute_metrics(experiment, runs, refs, options, conn, manifests)
        checks = check_references(experiment, runs, refs, conn)
    return problems, checks


def _cell_counts(runs: list[PlannedRun]) -> dict[precision.Cell, int]:
    counts: dict[precision.Cell, int] = {}
    for r in runs:
        counts[(r.point.id, r.strategy)] = counts.get((r.point.id, r.strategy), 0) + 1
    return counts


def _replicates(runs: list[PlannedRun]) -> dict[tuple[str, str], int]:
    return _cell_counts(runs)


def _render_time(manifests: dict[str, dict[str, Any]]) -> float:
    """The wall time of every render the sweep used (cached ones included): what it cost to make."""
    total = 0.0
    for m in manifests.values():
        wall = (m.get("timings") or {}).get("wall_s")
        if isinstance(wall, (int, float)):
            total += float(wall)
    return total


def _second_stage(
    experiment: Experiment,
    runs: list[PlannedRun],
    values: list[precision.Value],
    manifests: dict[str, dict[str, Any]],
    options: SweepOptions,
    started: float,
    out: TextIO,
) -> tuple[list[PlannedRun], bool]:
    """The second stage's runs: the replicates the first stage's `values`
    call for (precision.allocate, with the first stage's safety factor and
    precision.MIN_FINAL_REPLICATES) that `runs` does not hold yet (a resumed
    sweep holds them), cut to what fits in precision.max_time_s by the
    measured wall time of a run; and whether the cut dropped some."""
    p, budget = experiment.precision, experiment.budget
    assert p is not None and budget is not None
    n0 = budget.replicates
    have = _cell_counts(runs)
    first = {cell: min(n, n0) for cell, n in have.items()}
    missing = [v for v in values if not precision.reached(v, p.rel_se)]
    if missing:
        worst = max(missing, key=lambda v: v.rel_se if v.rel_se == v.rel_se else float("inf"))
        print(
            f"precision: first stage ({n0} replicates): {len(missing)} of {len(values)} headline values above "
            f"rel. SE {p.rel_se:g} (worst: {worst.name}, {worst.rel_se:.3g})",
            file=out,
        )
    order = precision.allocate(values, first, p, precision.variance_safety(n0), precision.MIN_FINAL_REPLICATES)
    seen, todo = dict(first), []
    for cell in order:
        seen[cell] += 1
        if seen[cell] > have.get(cell, 0):
            todo.append(cell)
    if not todo:
        return [], False
    cut = False
    if p.max_time_s:
        walls = [
            float(w)
            for r in runs
            if isinstance(w := ((manifests.get(r.key) or {}).get("timings") or {}).get("wall_s"), (int, float))
        ]
        # x 1.5: a run's metrics and the harness's own work come on top of its render
        per_run = 1.5 * (statistics.fmean(walls) if walls else budget.time_s)
        parallel = plan_jobs(budget.threads, options.jobs)
        left = p.max_time_s - (time.monotonic() - started)
        fit = max(int(left * parallel / max(per_run, 1e-3)), 0)
        cut, todo = fit < len(todo), todo[:fit]
        if not todo:
            return [], cut
    added = more_replicates(experiment, runs, options.renderer_version, None, _counts_after(have, todo))
    by = _cell_counts(added)
    print(
        "precision: adding " + ", ".join(f"{n} x {strategy} at {point}" for (point, strategy), n in sorted(by.items())),
        file=out,
    )
    return added, cut


def _stopped(values: list[precision.Value], counts: dict[precision.Cell, int], p: Precision, cut: bool) -> str:
    """Why the sweep ended where it did: "reached" (every value), else "max_time_s" (the
    second stage was cut), "max_replicates" (a value short of it has a cell at the cap),
    or "second_stage" (the first stage underestimated a variance; no third stage)."""
    short = [v for v in values if not precision.reached(v, p.rel_se)]
    if not short:
        return "reached"
    if cut:
        return "max_time_s"
    if any(counts.get(c, 0) >= p.max_replicates for v in short for c, _ in v.terms):
        return "max_replicates"
    return "second_stage"


def _counts_after(counts: dict[precision.Cell, int], order: list[precision.Cell]) -> dict[precision.Cell, int]:
    out = dict(counts)
    for cell in order:
        out[cell] = out.get(cell, 0) + 1
    return out


def _stop_biased(
    experiment: Experiment,
    biased: list[str],
    when: str,
    conn: sqlite3.Connection,
    runs: list[PlannedRun],
    refs: dict[str, PointReference],
    pilot_keys: dict[str, dict[str, str]],
    out: TextIO,
    sections: dict[str, str],
) -> int:
    """Reports a failed bias test; the sweep stops with exit status 1."""
    record_plan(conn, experiment, runs, refs, pilot_keys, sections)
    for line in biased:
        print(f"bias: {line}", file=out)
    print(
        f"sweep {experiment.name}: stopped: the two references of a point disagree, so one of their "
        f"strategies is biased ({when})",
        file=out,
    )
    return 1
