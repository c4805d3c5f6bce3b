"""The plan of a sweep: one PlannedRun per (point, strategy, replicate), with
its key and the point whose reference it is measured against."""

from __future__ import annotations

from dataclasses import dataclass

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


def plan_runs(experiment: Experiment, renderer_version: str) -> list[PlannedRun]:
    assert experiment.budget is not None
    out = []
    for point in experiment.points():
        for strategy in experiment.strategies:
            for k in range(experiment.budget.replicates):
                spec = experiment.run_spec(point, strategy, replicate=k)
                key = spec.key(renderer_version)
                out.append(PlannedRun(point, strategy, k, spec, key, reference_id(experiment, point)))
    return out
