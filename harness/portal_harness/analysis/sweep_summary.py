"""The tidy summary of a sweep (summary.csv/json, summary.py's rows), the
references' record in it, and the failures it lists."""

from __future__ import annotations

import csv
import io
import sqlite3
from typing import Any

from portal_harness.analysis import precision, summary
from portal_harness.core.paths import ResultsLayout
from portal_harness.execution import store
from portal_harness.execution.plan import PlannedRun, reference_id
from portal_harness.experiment.model import Experiment
from portal_harness.reference import noise_check, references
from portal_harness.reference.lifecycle import firefly_shares_of, floors_of
from portal_harness.reference.references import PointReference


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
        pid, ref = point.id, refs[reference_id(experiment, point)]
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
            light_in_speedup_se=experiment.precision is not None,
        )
    if experiment.precision is not None:
        precision.mark_rows(rows, experiment.precision)
    return rows


def write_summary(
    experiment: Experiment,
    layout: ResultsLayout,
    rows: list[dict[str, Any]],
    references_info: list[dict[str, Any]],
    failures: list[str],
    problems: list[str],
    precision_info: dict[str, Any] | None = None,
) -> None:
    """summary.json and summary.csv; `precision_info`: with `precision:`, the
    precision reached (precision.report) and how the rounds ended, in summary.json."""
    folder = layout.experiment_dir(experiment.name)
    folder.mkdir(parents=True, exist_ok=True)
    columns = summary.columns(experiment.facets, experiment.precision is not None)
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
            **({"precision": precision_info} if precision_info is not None else {}),
        },
    )
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for r in clean:
        writer.writerow({k: _csv_cell(r.get(k)) for k in columns})
    tmp = layout.summary_csv(experiment.name).with_name(".summary.csv.tmp")
    tmp.write_text(buffer.getvalue())
    tmp.replace(layout.summary_csv(experiment.name))


def _csv_cell(value: Any) -> Any:
    """None as an empty cell, booleans as true/false (precision_reached)."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return value


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
