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
5. the tidy summary (summary.py): summary.csv/json, one row per (point,
   strategy, region); the printed table is its `lit` (or image) region.

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
import sys
from typing import Any, TextIO

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
from portal_harness.execution.plan import PlannedRun, plan_runs
from portal_harness.execution.region_renders import region_maps, region_sections
from portal_harness.experiment.model import Experiment
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
from portal_harness.reference.references import PointReference


def sweep(experiment: Experiment, options: SweepOptions, out: TextIO | None = None) -> int:
    """Runs the whole sweep; returns the exit status (0 all done, 1 failures or a bias)."""
    out = out or sys.stdout
    layout = options.layout
    layout.root.mkdir(parents=True, exist_ok=True)
    store.clean_stale_attempts(layout)
    runs = plan_runs(experiment, options.renderer_version)
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
        problems = compute_metrics(experiment, runs, refs, options, conn, manifests)
        checks = check_references(experiment, runs, refs, conn)
        for _ in range(MAX_EXTENSION_ROUNDS):
            extended = extend_references(experiment, refs, checks, options, manifests, out)
            if not extended:
                break
            for pid in extended:
                for part in refs[pid].parts:
                    index.record_run(conn, manifests[part.key], layout.run(part.key, True).dir)
            biased = build_references(experiment, {pid: refs[pid] for pid in extended}, options, conn, manifests)
            if biased:
                return _stop_biased(
                    experiment, biased, "found after extending references", conn, runs, refs, pilot_keys, out, sections
                )
            problems = compute_metrics(experiment, runs, refs, options, conn, manifests)
            checks = check_references(experiment, runs, refs, conn)
        record_plan(conn, experiment, runs, refs, pilot_keys, sections)
        rows = summarize(experiment, runs, refs, conn, manifests)
        info = references_info(refs, checks, manifests)
        failures = failures_of(runs, refs, manifests) + section_failures(sections, manifests)
        write_summary(experiment, layout, rows, info, failures, problems)
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
