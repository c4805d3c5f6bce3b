"""The references of a sweep after they are planned: stored parts adopted,
references built and bias-tested, the noise check against the runs' errors and
the extension rounds it asks for, and the experiment's renders recorded in the index."""

from __future__ import annotations

import math
import sqlite3
from typing import Any, TextIO

from portal_harness.core.metrics import rel_variance_floor
from portal_harness.execution import index, store
from portal_harness.execution.batch import SweepOptions
from portal_harness.execution.index import (
    ROLE_PILOT,
    ROLE_REFERENCE,
    ROLE_REFERENCE_PART,
    ROLE_REGION_MAP,
    ROLE_REGION_SECTION,
    ROLE_RUN,
)
from portal_harness.execution.plan import PlannedRun, reference_id
from portal_harness.experiment.model import Experiment
from portal_harness.reference import extend, noise_check, references
from portal_harness.reference.references import PointReference

MAX_EXTENSION_ROUNDS = 3


def record_plan(
    conn: sqlite3.Connection,
    experiment: Experiment,
    runs: list[PlannedRun],
    refs: dict[str, PointReference],
    pilots: dict[str, dict[str, str]],
    sections: dict[str, str] | None = None,
) -> None:
    """Records the experiment's renders in the index; `sections` are the
    region-section renders' keys by reference point (figures.region_sections)."""
    rows: list[index.MembershipRow] = []
    # One set of reference rows per point, also where points share a reference (facets.py).
    for point in experiment.points():
        point_id, ref_id, axis = point.id, reference_id(experiment, point), point.axis_value
        ref = refs[ref_id]
        if ref.key is not None:
            label = "+".join(ref.strategies)
            rows.append((point_id, label, ROLE_REFERENCE, 0, ref.key, None, axis))
        rows += [
            (point_id, p.spec.strategy, ROLE_REFERENCE_PART, i, p.key, None, axis) for i, p in enumerate(ref.parts)
        ]
        rows += [(point_id, s, ROLE_PILOT, 0, key, None, axis) for s, key in pilots.get(ref_id, {}).items()]
        if ref.region_map_key is not None:
            rows.append((point_id, "light", ROLE_REGION_MAP, 0, ref.region_map_key, None, axis))
        if sections and ref_id in sections:
            rows.append((point_id, "light", ROLE_REGION_SECTION, 0, sections[ref_id], None, axis))
    rows += [
        (r.point.id, r.strategy, ROLE_RUN, r.replicate, r.key, refs[r.reference].key, r.point.axis_value) for r in runs
    ]
    index.record_membership(conn, experiment.name, rows)


def _final_errors(conn: sqlite3.Connection, runs: list[PlannedRun], ref: PointReference) -> dict[str, float]:
    """Per region, the smallest mean (over replicates) final relMSE of any
    strategy at any point that uses this reference."""
    by: dict[tuple[str, str, str], list[float]] = {}
    for r in runs:
        if r.reference != ref.point.id or ref.key is None:
            continue
        for m in index.metrics_of(conn, r.key, ref.key):
            if m["is_final"] and m["error"] is None and m["rel_mse"] is not None:
                by.setdefault((r.point.id, r.strategy, m["region"]), []).append(float(m["rel_mse"]))
    smallest: dict[str, float] = {}
    for (_, _, region), values in by.items():
        mean = sum(values) / len(values)
        smallest[region] = min(smallest.get(region, math.inf), mean)
    return smallest


def floors_of(ref: PointReference) -> dict[str, float]:
    assert ref.snapshot is not None
    return {r.name: rel_variance_floor(ref.snapshot.rgb, ref.snapshot.variance, r.mask) for r in ref.regions}


def firefly_shares_of(ref: PointReference) -> dict[str, float]:
    assert ref.snapshot is not None
    return {r.name: noise_check.firefly_share(ref.snapshot.rgb, ref.snapshot.variance, r.mask) for r in ref.regions}


def check_references(
    experiment: Experiment, runs: list[PlannedRun], refs: dict[str, PointReference], conn: sqlite3.Connection
) -> dict[str, list[noise_check.RegionCheck]]:
    return {
        pid: noise_check.check(
            floors_of(ref), _final_errors(conn, runs, ref), experiment.reference.noise_ratio, firefly_shares_of(ref)
        )
        for pid, ref in refs.items()
        if ref.snapshot is not None
    }


def extend_references(
    experiment: Experiment,
    refs: dict[str, PointReference],
    checks: dict[str, list[noise_check.RegionCheck]],
    options: SweepOptions,
    manifests: dict[str, dict[str, Any]],
    out: TextIO,
) -> list[str]:
    """One round of extensions; returns the points extended."""
    extended = []
    for pid, found in checks.items():
        ref = refs[pid]
        failed = [c for c in found if not c.ok]
        if not failed or ref.snapshot is None:
            continue
        plan = noise_check.plan_extension(
            failed, ref.part_snapshots, ref.snapshot.rgb, ref.regions, experiment.reference.noise_ratio
        )
        if plan is None:
            continue
        part = ref.parts[plan.part]
        snap = ref.part_snapshots[plan.part]
        factor = plan.factor
        history = (manifests.get(part.key) or {}).get("extensions") or []
        first_time = float(history[0].get("from_time_s", 0.0)) if history else snap.header.render_time_s
        cap = experiment.reference.max_time_s or noise_check.DEFAULT_CAP_FACTOR * first_time
        if snap.header.render_time_s * factor > cap:
            factor = cap / max(snap.header.render_time_s, 1e-9)
            ref.capped = True
            if factor < 1.05:
                continue
        total = max(snap.header.spp + 1, math.ceil(snap.header.spp * factor))
        print(
            f"extending reference {pid} {part.spec.strategy} from {snap.header.spp} to {total} spp "
            f"(regions {', '.join(plan.regions)})",
            file=out,
        )
        manifest = extend.extend(options.layout, part.key, total, options.renderer, part.spec.threads)
        if manifest.get("status") != store.STATUS_DONE:
            print(f"  failed: {manifest.get('error')}", file=out)
            continue
        manifests[part.key] = manifest
        extended.append(pid)
    return extended


def adopt_stored_parts(ref: PointReference, options: SweepOptions) -> tuple[references.Part, ...]:
    """The reference's parts, each replaced by a stored reference of the same
    sample stream when its own is not rendered (extend.stored_stream): a
    reference another experiment planned with another first time, and maybe
    extended, is continued by the noise check from its stored samples."""
    parts = []
    for part in ref.parts:
        found = extend.stored_stream(options.layout, part.spec, options.renderer_version)
        parts.append(part if found is None else references.Part(found, found.key(options.renderer_version)))
    return tuple(parts)


def build_references(
    experiment: Experiment,
    refs: dict[str, PointReference],
    options: SweepOptions,
    conn: sqlite3.Connection,
    manifests: dict[str, dict[str, Any]],
) -> list[str]:
    """Builds each point's reference; returns the bias-test failures, as messages."""
    biased: list[str] = []
    for ref in refs.values():
        before = ref.key
        references.build(ref, experiment, options.layout, options.renderer_version, manifests)
        if before is not None and before != ref.key and before not in {p.key for p in ref.parts}:
            # An extension superseded this combined reference: nothing refers to it any more.
            store.remove_run(options.layout, before, True)
            index.forget_run(conn, before)
        if ref.key is not None and ref.key in manifests and len(ref.parts) > 1:
            index.record_run(conn, manifests[ref.key], options.layout.run(ref.key, True).dir)
        biased += references.format_disagreement(ref, experiment.reference.bias_z) if len(ref.parts) > 1 else []
    return biased
