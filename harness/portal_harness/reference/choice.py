"""Choosing each reference point's reference strategies: given, or by pilot
renders (pilot.py), with the first reference part's length the pilots predict."""

from __future__ import annotations

import contextlib
import math
import sqlite3
from dataclasses import dataclass
from typing import Any

from portal_harness.core import exr
from portal_harness.core.errors import CorruptExrError
from portal_harness.core.regions import regions_of
from portal_harness.execution import store
from portal_harness.execution.batch import SweepOptions, execute_specs
from portal_harness.experiment.model import Experiment
from portal_harness.experiment.spec import RunSpec
from portal_harness.reference import noise_check, pilot


@dataclass(frozen=True)
class ReferenceChoice:
    strategies: tuple[str, ...]
    first_time_s: float | None  # the first part's render time, predicted by the pilot
    pilot_keys: dict[str, str]  # by strategy


def _first_time(experiment: Experiment, ranked: list[pilot.PilotResult]) -> float | None:
    r = experiment.reference
    budget = experiment.budget
    if r.time_s <= 0 or budget is None or budget.time_s <= 0:
        return None  # sample-limited references keep their spp; the noise check extends them
    predicted = pilot.first_time(ranked, budget.time_s, r.noise_ratio, noise_check.EXTENSION_MARGIN)
    if predicted is None:
        return None
    cap = r.max_time_s or noise_check.DEFAULT_CAP_FACTOR * r.time_s
    # Whole seconds: the time is part of the reference's key.
    return float(min(max(math.ceil(predicted), r.time_s), cap))


def _pilot_snapshots(
    specs: dict[tuple[str, str], RunSpec], options: SweepOptions, manifests: dict[str, dict[str, Any]]
) -> dict[tuple[str, str], exr.Snapshot]:
    """The final images of the pilots that finished, by (point, strategy)."""
    out: dict[tuple[str, str], exr.Snapshot] = {}
    for k, spec in specs.items():
        key = spec.key(options.renderer_version)
        if (manifests.get(key) or {}).get("status") == store.STATUS_DONE:
            with contextlib.suppress(CorruptExrError):
                out[k] = exr.read_snapshot(options.layout.run(key).final)
    return out


def choose_reference_strategies(
    experiment: Experiment,
    options: SweepOptions,
    conn: sqlite3.Connection,
    manifests: dict[str, dict[str, Any]],
    maps: dict[str, tuple[str, Any]],
) -> dict[str, ReferenceChoice]:
    """Per reference point, the reference strategies (given, or by pilot) and the first part's time."""
    points = experiment.reference_points()
    given = experiment.reference.strategies
    if given:
        return {p.id: ReferenceChoice(given, None, {}) for p in points}
    specs = {(p.id, s): experiment.pilot_spec(p, s) for p in points for s in experiment.strategies}
    manifests.update(execute_specs(list(specs.values()), options, conn, desc="pilots"))
    snaps = _pilot_snapshots(specs, options, manifests)
    # A pilot whose time drew fewer than pilot.MIN_SPP samples cannot tell
    # fireflies from a few samples' ordinary noise: it is drawn again, by
    # samples (pilot.py).
    by_id = {p.id: p for p in points}
    short = {
        k: experiment.pilot_spec(by_id[k[0]], k[1], spp=pilot.MIN_SPP)
        for k, snap in snaps.items()
        if snap.header.spp < pilot.MIN_SPP
    }
    if short:
        manifests.update(execute_specs(list(short.values()), options, conn, desc="pilots by samples"))
        redone = _pilot_snapshots(short, options, manifests)
        snaps.update(redone)
        specs.update({k: short[k] for k in redone})
    chosen: dict[str, ReferenceChoice] = {}
    for p in points:
        keys = {s: specs[(p.id, s)].key(options.renderer_version) for s in experiment.strategies}
        by_strategy = {s: snaps[(p.id, s)] for s in experiment.strategies if (p.id, s) in snaps}
        ranked: list[pilot.PilotResult] = []
        if by_strategy:
            # The pilots' regions: a light-sampled pilot (or any) stands in for the reference.
            stand_in = by_strategy.get(pilot.BASELINE) or next(iter(by_strategy.values()))
            ranked = pilot.score(
                by_strategy, regions_of(stand_in, experiment.insets, experiment.lit_threshold, maps[p.id][1])
            )
        chosen[p.id] = ReferenceChoice(pilot.choose(ranked), _first_time(experiment, ranked), keys)
    return chosen
