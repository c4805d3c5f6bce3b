"""The plan of a sweep: one PlannedRun per (point, strategy, replicate), with
its key and the point whose reference it is measured against."""

from __future__ import annotations

from dataclasses import dataclass

from portal_harness.core.paths import ResultsLayout
from portal_harness.execution import store
from portal_harness.experiment.model import Experiment, Point
from portal_harness.experiment.spec import RunSpec


@dataclass(frozen=True)
class PlannedRun:
    point: Point
    strategy: str
    replicate: int
    spec: RunSpec
    key: str
    reference: str = ""  # the id of the point whose reference this run is measured against


def reference_id(experiment: Experiment, point: Point) -> str:
    return experiment.reference_point(point).id


def interleaved(runs: list[PlannedRun]) -> list[PlannedRun]:
    """The runs in the order they are rendered: replicate by replicate, each
    round over every point and strategy. Efficiency is measured in wall
    time, so a change in the machine's load falls on whatever runs then;
    spread this way it falls on every strategy alike and cancels in their
    ratios to light. (Rendered cell by cell, a load that came and went
    during one strategy's block biased its ratio: docs/experiments.md,
    "Checking the precision".)"""
    points = {r.point.id: i for i, r in reversed(list(enumerate(runs)))}
    strategies = {r.strategy: i for i, r in reversed(list(enumerate(runs)))}
    return sorted(runs, key=lambda r: (r.replicate, points[r.point.id], strategies[r.strategy]))


def plan_runs(experiment: Experiment, renderer_version: str) -> list[PlannedRun]:
    """Replicates 0..budget.replicates-1 of every (point, strategy), interleaved."""
    assert experiment.budget is not None
    out = []
    for point in experiment.points():
        for strategy in experiment.strategies:
            for k in range(experiment.budget.replicates):
                spec = experiment.run_spec(point, strategy, replicate=k)
                key = spec.key(renderer_version)
                out.append(PlannedRun(point, strategy, k, spec, key, reference_id(experiment, point)))
    return interleaved(out)


def more_replicates(
    experiment: Experiment,
    runs: list[PlannedRun],
    renderer_version: str,
    layout: ResultsLayout | None,
    wanted: dict[tuple[str, str], int],
) -> list[PlannedRun]:
    """Further replicates of each (point, strategy) beyond those `runs` hold
    (replicates 0..K-1, as plan_runs makes them): up to wanted[(point id,
    strategy)] replicates, and with `layout`, every further one the store
    holds finished (an earlier sweep's precision rounds: experiments with
    `precision:`, capped at its max_replicates), interleaved."""
    have: dict[tuple[str, str], int] = {}
    for r in runs:
        cell = (r.point.id, r.strategy)
        have[cell] = max(have.get(cell, 0), r.replicate + 1)
    cap = experiment.precision.max_replicates if experiment.precision is not None else None
    out = []
    for point in experiment.points():
        for strategy in experiment.strategies:
            cell = (point.id, strategy)
            k = have.get(cell, 0)
            while cap is None or k < cap:
                spec = experiment.run_spec(point, strategy, replicate=k)
                key = spec.key(renderer_version)
                if k >= wanted.get(cell, 0) and (layout is None or not store.is_done(layout.run(key))):
                    break
                out.append(PlannedRun(point, strategy, k, spec, key, reference_id(experiment, point)))
                k += 1
    return interleaved(out)
