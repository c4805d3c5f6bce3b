"""The reference of each sweep point: chosen, rendered, tested, combined,
and extended until it resolves the errors it is compared with.

1. Strategies: reference.strategies, or a pilot (pilot.py) picks the
   lowest-variance strategy and an independent second one.
2. Parts: one render per strategy (own seed, region AOV, resumable), in
   results/references/<key>/ like any reference.
3. Bias test and combination (reference_pair.py): two parts that disagree
   beyond reference.bias_z sigma in some region stop the sweep; otherwise
   they are combined into results/references/<combined key>/final.exr, the
   image every metric of the point is computed against. The combined key
   hashes the parts' keys and sample counts, so extending a part makes a new
   combined reference (and the metrics are recomputed).
4. Noise check and extension (noise_check.py, extend.py), after the runs'
   metrics are known: see lifecycle.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from portal_harness.core import exr
from portal_harness.core.errors import CorruptExrError
from portal_harness.core.paths import ResultsLayout
from portal_harness.core.regions import NamedRegion, regions_of
from portal_harness.execution import store
from portal_harness.execution.runs import final_record, now
from portal_harness.experiment.model import Experiment, Point
from portal_harness.experiment.spec import RunSpec, short_hash
from portal_harness.reference.reference_pair import RegionDisagreement, combine, disagreement

COMBINATION_SCHEME = 1


@dataclass(frozen=True)
class Part:
    spec: RunSpec
    key: str


@dataclass
class PointReference:
    """What the sweep knows of one point's reference."""

    point: Point
    parts: tuple[Part, ...]
    key: str | None = None  # of the image the metrics use (combined, or the only part)
    snapshot: exr.Snapshot | None = None
    part_snapshots: list[exr.Snapshot] = field(default_factory=list)
    regions: list[NamedRegion] = field(default_factory=list)
    disagreements: list[RegionDisagreement] = field(default_factory=list)
    error: str | None = None
    capped: bool = False  # an extension was cut at reference.max_time_s
    fractions: np.ndarray | None = None  # the point's region AOV (config.region_map_spec)
    region_map_key: str | None = None  # of the render it comes from

    @property
    def strategies(self) -> tuple[str, ...]:
        return tuple(p.spec.strategy for p in self.parts)


def plan(
    experiment: Experiment,
    point: Point,
    strategies: tuple[str, ...],
    renderer_version: str,
    first_time_s: float | None = None,
) -> PointReference:
    """The parts; the first renders for `first_time_s` when given (pilot.first_time)."""
    parts = []
    for i, strategy in enumerate(strategies):
        spec = experiment.reference_spec(point, strategy, part=i, time_s=first_time_s if i == 0 else None)
        parts.append(Part(spec, spec.key(renderer_version)))
    return PointReference(point, tuple(parts))


def combined_key(parts: tuple[Part, ...], spps: list[int], region_map_key: str | None) -> str:
    """Changes with the parts' sample counts and with the region map (the weights' groups)."""
    return short_hash(
        {
            "kind": "combined_reference",
            "scheme": COMBINATION_SCHEME,
            "parts": [[p.key, n] for p, n in zip(parts, spps, strict=True)],
            "region_map": region_map_key,
        }
    )


def _combined_manifest(
    ref: PointReference,
    key: str,
    snapshot: exr.Snapshot,
    final_file: str,
    renderer_version: str,
    manifests: dict[str, dict[str, Any]],
) -> dict[str, Any]:
    first = ref.parts[0].spec
    spec = {
        **first.to_dict(),
        "strategy": snapshot.header.strategy,
        "spp": snapshot.header.spp,
        "time_s": snapshot.header.render_time_s,
    }
    made = now()
    return {
        "schema": store.MANIFEST_SCHEMA,
        "key": key,
        "kind": "reference",
        "status": store.STATUS_DONE,
        "error": None,
        "spec": spec,
        "params": first.params(),
        "scene_hash": first.scene_hash(),
        "renderer": {"path": None, "version": renderer_version, "config_hash": snapshot.header.config_hash},
        "timings": {"started": made, "finished": made, "render_time_s": snapshot.header.render_time_s},
        "final": final_record(final_file, snapshot.header),
        "snapshots": [],
        "parts": [
            {
                "key": p.key,
                "strategy": p.spec.strategy,
                "spp": manifests[p.key]["final"]["spp"],
                "time_s": manifests[p.key]["final"]["time_s"],
            }
            for p in ref.parts
        ],
        "combination": "inverse pooled relative variance per region class (reference_pair.py)",
    }


def build(
    ref: PointReference,
    experiment: Experiment,
    layout: ResultsLayout,
    renderer_version: str,
    manifests: dict[str, dict[str, Any]],
) -> None:
    """Reads the parts, tests them against each other, and makes (or finds)
    the image the metrics use. Fills ref in place; ref.error on failure."""
    ref.error = None
    snaps = []
    for part in ref.parts:
        m = manifests.get(part.key)
        if m is None or m.get("status") != store.STATUS_DONE:
            ref.error = f"reference {part.spec.strategy} [{part.key}] {(m or {}).get('status', 'missing')}"
            return
        try:
            snaps.append(exr.read_snapshot(layout.run(part.key, True).final))
        except CorruptExrError as e:
            ref.error = f"reference {part.spec.strategy} [{part.key}]: {e}"
            return
    ref.part_snapshots = snaps
    if len(snaps) == 1:
        ref.key, ref.snapshot = ref.parts[0].key, snaps[0]
    else:
        ref.key = combined_key(ref.parts, [s.header.spp for s in snaps], ref.region_map_key)
        ref.snapshot = _combined(ref, ref.key, snaps[0], snaps[1], layout, renderer_version, manifests)
    # One set of regions for the bias test and for every metric of the point.
    ref.regions = regions_of(ref.snapshot, experiment.insets, experiment.lit_threshold, ref.fractions)
    ref.disagreements = disagreement(snaps[0], snaps[1], ref.regions) if len(snaps) == 2 else []


def _combined(
    ref: PointReference,
    key: str,
    a: exr.Snapshot,
    b: exr.Snapshot,
    layout: ResultsLayout,
    renderer_version: str,
    manifests: dict[str, dict[str, Any]],
) -> exr.Snapshot:
    """The combined reference `key`: read when it was made before, else
    made and installed. Either way it is read back from its file, so that
    the metrics see the same float image whether it was cached or not. Its
    manifest goes into `manifests`, to be indexed by the caller like a
    rendered run's."""
    target = layout.run(key, True)
    if store.is_done(target):
        try:
            snapshot = exr.read_snapshot(target.final)
            manifests[key] = {**(store.read_manifest(target) or {}), "cached": True}
            return snapshot
        except CorruptExrError:
            pass  # made again below
    label = "+".join(p.spec.strategy for p in ref.parts)
    combined = combine(a, b, label, short_hash([a.header.config_hash, b.header.config_hash]), ref.fractions)
    attempt = store.new_attempt(layout, key, True)
    exr.write_snapshot(attempt.final, combined)
    manifest = _combined_manifest(ref, key, combined, attempt.relative(attempt.final), renderer_version, manifests)
    store.write_json_atomic(attempt.manifest, manifest)
    store.install(layout, key, True, attempt)
    manifests[key] = store.read_manifest(target) or {}
    return exr.read_snapshot(target.final)


def format_disagreement(ref: PointReference, z_max: float) -> list[str]:
    a, b = ref.strategies
    out = []
    for d in ref.disagreements:
        if abs(d.z) > z_max:
            out.append(
                f"{ref.point.id}: references {a} and {b} disagree in region {d.region} "
                f"({d.pixels} pixels): z = {d.z:+.1f} (limit {z_max:g}), mean difference "
                f"{d.mean_difference:+.4g}; one of the two strategies is biased there"
            )
    return out


def max_abs_z(ref: PointReference) -> float:
    finite = [abs(d.z) for d in ref.disagreements]
    return max(finite) if finite else math.nan
