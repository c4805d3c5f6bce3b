"""The order a sweep renders its runs in (execution/plan.py): replicate by
replicate over every point and strategy, for the first stage and for the
replicates precision adds, so that a change in the machine's load falls on
every strategy alike (efficiency is measured in wall time)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from portal_harness.execution.plan import more_replicates, plan_runs
from portal_harness.experiment.loader import load_experiment


def test_runs_are_interleaved_replicate_by_replicate(
    write_experiment: Callable[..., Path], real_renderer: Path
) -> None:
    path = write_experiment(
        sweep={"params.s_L": [0.15, 0.6]},
        strategies=["light", "portal", "antishadow"],
        budget={"time_s": 0.2, "threads": 1, "seed": 1, "replicates": 2},
    )
    exp = load_experiment(path, str(real_renderer))
    runs = plan_runs(exp, "v")
    order = [(r.replicate, r.point.id, r.strategy) for r in runs]
    assert order[:6] == [
        (0, "s_L=0.15", "light"),
        (0, "s_L=0.15", "portal"),
        (0, "s_L=0.15", "antishadow"),
        (0, "s_L=0.6", "light"),
        (0, "s_L=0.6", "portal"),
        (0, "s_L=0.6", "antishadow"),
    ]
    assert [k for k, _, _ in order] == [0] * 6 + [1] * 6
    # the same runs as cell by cell: every (point, strategy, replicate) once
    assert len(set(order)) == 12 and len({r.key for r in runs}) == 12
    # replicates added unevenly (precision's second stage) alternate too
    added = more_replicates(exp, runs, "v", None, {("s_L=0.15", "light"): 5, ("s_L=0.15", "antishadow"): 4})
    assert [(r.replicate, r.strategy) for r in added] == [
        (2, "light"),
        (2, "antishadow"),
        (3, "light"),
        (3, "antishadow"),
        (4, "light"),
    ]
