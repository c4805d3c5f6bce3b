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
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import sqlite3
import sys
from dataclasses import dataclass
from typing import Any, TextIO

from tqdm import tqdm

from portal_harness import exr, extend, index, measure, noise_check, pilot, references, store, summary
from portal_harness.config import Experiment, Point
from portal_harness.errors import CorruptExrError
from portal_harness.execute import Target, plan_jobs, run_dask, run_local
from portal_harness.index import (
    ROLE_PILOT,
    ROLE_REFERENCE,
    ROLE_REFERENCE_PART,
    ROLE_REGION_MAP,
    ROLE_REGION_SECTION,
    ROLE_RUN,
)
from portal_harness.metrics import WHOLE_IMAGE, rel_variance_floor
from portal_harness.paths import ResultsLayout
from portal_harness.references import PointReference
from portal_harness.regions import LIT, regions_of
from portal_harness.spec import RunSpec

MAX_EXTENSION_ROUNDS = 3


@dataclass(frozen=True)
class PlannedRun:
    point: Point
    strategy: str
    replicate: int
    spec: RunSpec
    key: str
    reference: str = ""  # the id of the point whose reference this run is measured against


def _reference_id(experiment: Experiment, point: Point) -> str:
    return experiment.reference_point(point).id


def plan_runs(experiment: Experiment, renderer_version: str) -> list[PlannedRun]:
    assert experiment.budget is not None
    out = []
    for point in experiment.points():
        for strategy in experiment.strategies:
            for k in range(experiment.budget.replicates):
                spec = experiment.run_spec(point, strategy, replicate=k)
                key = spec.key(renderer_version)
                out.append(PlannedRun(point, strategy, k, spec, key, _reference_id(experiment, point)))
    return out


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
        point_id, ref_id, axis = point.id, _reference_id(experiment, point), point.axis_value
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


@dataclass(frozen=True)
class SweepOptions:
    layout: ResultsLayout
    renderer: str
    renderer_version: str
    jobs: int | None = None
    scheduler: str | None = None
    retry_failed: bool = True
    progress: bool = True


def execute_specs(
    specs: list[RunSpec], options: SweepOptions, conn: sqlite3.Connection, desc: str = "renders", force: bool = False
) -> dict[str, dict[str, Any]]:
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
            or (not options.retry_failed and existing.get("status") == store.STATUS_FAILED)
        )
        if existing is not None and finished and not force:
            manifests[key] = {**existing, "cached": True}
            index.record_run(conn, existing, run.dir)
        else:
            todo.append(spec)
            queued.add(key)
    if not todo:
        return manifests
    bar = tqdm(
        total=len(todo), desc=desc, unit="render", disable=not options.progress, file=sys.stderr, dynamic_ncols=True
    )

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


def compute_metrics(
    experiment: Experiment,
    runs: list[PlannedRun],
    refs: dict[str, PointReference],
    options: SweepOptions,
    conn: sqlite3.Connection,
    manifests: dict[str, dict[str, Any]],
) -> list[str]:
    """Metrics of every finished run against its point's reference, on the
    point's regions; returns the problems found."""
    problems: list[str] = []
    for planned in runs:
        manifest = manifests.get(planned.key)
        ref = refs[planned.reference]
        if manifest is None or manifest.get("status") != store.STATUS_DONE or ref.snapshot is None:
            continue
        assert ref.key is not None
        run = options.layout.run(planned.key)
        if measure.up_to_date(run, ref.key, ref.regions):
            rows = measure.read_rows(run)
            if not index.metrics_of(conn, planned.key, ref.key):
                index.record_metrics(conn, planned.key, ref.key, rows)
        else:
            rows = measure.compute(run, manifest, ref.snapshot, ref.regions)
            measure.write_files(run, planned.key, ref.key, ref.regions, rows)
            index.record_metrics(conn, planned.key, ref.key, rows)
        for row in rows:
            if row.error:
                problems.append(f"{planned.strategy} {planned.point.id} {row.image}: {row.error}")
    return problems


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


def _status(runs: list[PlannedRun], manifests: dict[str, dict[str, Any]], point: str, strategy: str) -> str:
    for r in runs:
        if r.point.id == point and r.strategy == strategy:
            status = (manifests.get(r.key) or {}).get("status", "missing")
            if status != store.STATUS_DONE:
                return str(status)
    return store.STATUS_DONE


def summarize(
    experiment: Experiment,
    runs: list[PlannedRun],
    refs: dict[str, PointReference],
    conn: sqlite3.Connection,
    manifests: dict[str, dict[str, Any]],
) -> list[dict[str, Any]]:
    """The tidy rows (summary.py) of every point, region and strategy."""
    rows: list[dict[str, Any]] = []
    for point in experiment.points():
        pid, ref = point.id, refs[_reference_id(experiment, point)]
        if ref.snapshot is None or ref.key is None:
            continue
        floors = floors_of(ref)
        shares = firefly_shares_of(ref)
        regions = {
            r.name: summary.RegionInfo(r.kind, r.pixels, floors[r.name], shares[r.name] > noise_check.FIREFLY_SHARE_MAX)
            for r in ref.regions
        }
        reps = {
            s: summary.replicates_of(conn, [r.key for r in runs if r.point.id == pid and r.strategy == s], ref.key)
            for s in experiment.strategies
        }
        status = {s: _status(runs, manifests, pid, s) for s in experiment.strategies}
        rows += summary.rows_for_point(
            pid,
            point.axis_value,
            experiment.strategies,
            reps,
            regions,
            experiment.reference.noise_ratio,
            status,
            facets=point.facets,
        )
    return rows


def write_summary(
    experiment: Experiment,
    layout: ResultsLayout,
    rows: list[dict[str, Any]],
    references_info: list[dict[str, Any]],
    failures: list[str],
    problems: list[str],
) -> None:
    folder = layout.experiment_dir(experiment.name)
    folder.mkdir(parents=True, exist_ok=True)
    columns = summary.columns(experiment.facets)
    clean = [{k: store.finite_or_none(r.get(k)) for k in columns} for r in rows]
    store.write_json_atomic(
        layout.summary_json(experiment.name),
        {
            "experiment": experiment.name,
            "file": str(experiment.path),
            "columns": list(columns),
            "rows": clean,
            "references": references_info,
            "failures": failures,
            "problems": problems,
        },
    )
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for r in clean:
        writer.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in columns})
    tmp = layout.summary_csv(experiment.name).with_name(".summary.csv.tmp")
    tmp.write_text(buffer.getvalue())
    tmp.replace(layout.summary_csv(experiment.name))


def references_info(
    refs: dict[str, PointReference],
    checks: dict[str, list[noise_check.RegionCheck]],
    manifests: dict[str, dict[str, Any]],
) -> list[dict[str, Any]]:
    out = []
    for pid, ref in refs.items():
        parts = []
        for p in ref.parts:
            final = (manifests.get(p.key) or {}).get("final") or {}
            parts.append(
                {"strategy": p.spec.strategy, "key": p.key, "spp": final.get("spp"), "time_s": final.get("time_s")}
            )
        out.append(
            {
                # Capped: an extension was cut at the cap and some region is still unresolved.
                "point": pid,
                "key": ref.key,
                "parts": parts,
                "error": ref.error,
                "capped": ref.capped and any(not c.ok for c in checks.get(pid, [])),
                "bias_max_abs_z": store.finite_or_none(references.max_abs_z(ref)),
                "noise": [
                    {
                        "region": c.region,
                        "floor": c.floor,
                        "smallest_error": c.smallest_error,
                        "ratio": store.finite_or_none(c.ratio),
                        "firefly_share": c.firefly_share,
                        "ok": c.ok,
                    }
                    for c in checks.get(pid, [])
                ],
            }
        )
    return out


def _fmt(v: Any, spec: str) -> str:
    return format(v, spec) if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def print_table(rows: list[dict[str, Any]], out: TextIO) -> None:
    """The tidy summary's `lit` region (the whole image if there is none), one line per (point, strategy)."""
    region = LIT if any(r["region"] == LIT for r in rows) else WHOLE_IMAGE
    width = max([22, *(len(str(r["point"])) for r in rows)])  # facets make point names longer
    header = (
        f"{'point':<{width}} {'strategy':<17} {'reps':>4} {'time_s':>7} {'relMSE':>10} {'eff/light':>16} "
        f"{'speed-up':>10} {'ref/err':>7}"
    )
    print(f"region {region}:", file=out)
    print(header, file=out)
    print("-" * len(header), file=out)
    for r in summary.wide(rows, region):
        eff = f"{'>' if r.get('bound') else ' '}{_fmt(r.get('efficiency_vs_light'), '.3g')}"
        se = _fmt(r.get("efficiency_vs_light_stderr"), ".2g")
        if se != "-":
            eff += f" ±{se}"
        mark = {"lower": ">", "upper": "<", "mixed": "~"}.get(r.get("speedup_bound") or "", " ")
        print(
            f"{r['point']:<{width}} {r['strategy']:<17} {r.get('replicates', 0):>4} {_fmt(r.get('time_s'), '7.2f'):>7} "
            f"{_fmt(r.get('rel_mse'), '10.3e'):>10} {eff:>16} {mark}{_fmt(r.get('speedup_equal_error'), '.3g'):>9} "
            f"{_fmt(r.get('reference_noise_ratio'), '7.3f'):>7}",
            file=out,
        )
    print(
        "(eff/light: efficiency relative to light sampling, reference noise removed, ± a standard error over "
        "replicates; '>' a lower bound where the reference does not resolve the error; speed-up: light's time "
        "over the time to reach light's final error, '>'/'<' where the curve only bounds it; ref/err: reference "
        "noise over the run's error)",
        file=out,
    )


def print_references(info: list[dict[str, Any]], out: TextIO) -> None:
    for ref in info:
        parts = ", ".join(f"{p['strategy']} {_fmt(p['time_s'], '.1f')} s/{p['spp']} spp" for p in ref["parts"])
        worst = max((c for c in ref["noise"] if c["ratio"] is not None), key=lambda c: c["ratio"], default=None)
        noise = f"worst noise ratio {worst['ratio']:.3f} ({worst['region']})" if worst else "noise ratio -"
        capped = ", capped: values there are bounds" if ref["capped"] else ""
        print(
            f"reference {ref['point']}: {parts}; bias |z| max {_fmt(ref['bias_max_abs_z'], '.2f')}; {noise}{capped}",
            file=out,
        )


def failures_of(
    runs: list[PlannedRun], refs: dict[str, PointReference], manifests: dict[str, dict[str, Any]]
) -> list[str]:
    """Every render that did not finish, and every reference that could not
    be made from finished parts (an unreadable image): each once."""
    out = []
    for pid, ref in refs.items():
        unfinished = False
        for p in ref.parts:
            m = manifests.get(p.key)
            if m is None or m.get("status") != store.STATUS_DONE:
                unfinished = True
                out.append(
                    f"reference {pid} {p.spec.strategy} [{p.key}]: {(m or {}).get('status', 'missing')}: "
                    f"{(m or {}).get('error') or ''} {_last_line((m or {}).get('stderr_tail'))}".rstrip()
                )
        if ref.error and not unfinished:
            out.append(f"reference {pid}: {ref.error}")
    for r in runs:
        m = manifests.get(r.key)
        if m is None or m.get("status") != store.STATUS_DONE:
            out.append(
                f"{r.strategy} {r.point.id} #{r.replicate} [{r.key}]: {(m or {}).get('status', 'missing')}: "
                f"{(m or {}).get('error') or ''} {_last_line((m or {}).get('stderr_tail'))}".rstrip()
            )
    return out


def section_failures(sections: dict[str, str], manifests: dict[str, dict[str, Any]]) -> list[str]:
    """The region-section renders that did not finish (their figure panel is then empty)."""
    out = []
    for pid, key in sections.items():
        m = manifests.get(key)
        if m is None or m.get("status") != store.STATUS_DONE:
            out.append(
                f"region section {pid} [{key}]: {(m or {}).get('status', 'missing')}: "
                f"{(m or {}).get('error') or ''} {_last_line((m or {}).get('stderr_tail'))}".rstrip()
            )
    return out


def _last_line(text: str | None) -> str:
    lines = [line for line in (text or "").splitlines() if line.strip()]
    return f"(stderr: {lines[-1][:160]})" if lines else ""


def region_sections(
    experiment: Experiment, options: SweepOptions, conn: sqlite3.Connection, manifests: dict[str, dict[str, Any]]
) -> dict[str, str]:
    """Per reference point, the key of its render of figures.region_sections
    (none without the key): the figures read its region AOV, and nothing
    else uses it, so a failed one is only listed with the failures."""
    if experiment.region_sections is None:
        return {}
    specs = {p.id: experiment.region_section_spec(p) for p in experiment.reference_points()}
    manifests.update(execute_specs(list(specs.values()), options, conn, desc="region sections"))
    return {pid: spec.key(options.renderer_version) for pid, spec in specs.items()}


def region_maps(
    experiment: Experiment, options: SweepOptions, conn: sqlite3.Connection, manifests: dict[str, dict[str, Any]]
) -> dict[str, tuple[str, Any]]:
    """Per reference point, (key, fractions) of its region-map render (fractions None if it failed)."""
    specs = {p.id: experiment.region_map_spec(p) for p in experiment.reference_points()}
    manifests.update(execute_specs(list(specs.values()), options, conn, desc="region maps"))
    out: dict[str, tuple[str, Any]] = {}
    for pid, spec in specs.items():
        key = spec.key(options.renderer_version)
        fractions = None
        if (manifests.get(key) or {}).get("status") == store.STATUS_DONE:
            with contextlib.suppress(CorruptExrError):
                fractions = exr.read_snapshot(options.layout.run(key).final).regions
        out[pid] = (key, fractions)
    return out


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
    # Combined references are computed, not rendered: they have no command.
    rendered = sum(1 for m in manifests.values() if not m.get("cached") and m.get("command"))
    cached = sum(1 for m in manifests.values() if m.get("cached") and m.get("command"))
    print(
        f"sweep {experiment.name}: {len(runs)} runs, {sum(len(r.parts) for r in refs.values())} reference "
        f"renders, {rendered} rendered now, {cached} cached",
        file=out,
    )
    print_references(info, out)
    print_table(rows, out)
    print(
        f"summary: {layout.summary_json(experiment.name)} (and .csv: one row per point, strategy and region)", file=out
    )
    for p in problems:
        print(f"problem: {p}", file=out)
    if failures:
        print(f"{len(failures)} failed:", file=out)
        for f in failures:
            print(f"  {f}", file=out)
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
