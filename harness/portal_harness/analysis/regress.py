"""`regress`: fixed-seed, fixed-sample renders of every (point, strategy),
their relative variance compared with a committed baseline.

Statistic (derived in harness/README.md): for each render, the renderer's
variance layer gives per pixel and channel the variance of the mean v; we
use w = v / (mean^2 + 0.01), the expected relMSE of that pixel. Over R seeds
and the M pixel-channels of the experiment's insets (the whole image if it
has none), W = mean(w) and its standard error come from
metrics.pooled_estimate; a strategy fails when
z = (W - W_base) / sqrt(SE^2 + SE_base^2) > z_max (one-sided: only a rise
fails), i.e. when W / W_base exceeds the printed ratio bound.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from portal_harness.core import exr, metrics
from portal_harness.core.errors import ConfigError, CorruptExrError
from portal_harness.core.metrics import VarianceEstimate
from portal_harness.execution import index, store
from portal_harness.execution.batch import SweepOptions, execute_specs
from portal_harness.experiment.model import Experiment

BASELINE_SCHEMA = 1


@dataclass(frozen=True)
class Verdict:
    name: str
    status: str  # ok | RISE | improved | new | FAILED | missing
    current: VarianceEstimate | None
    baseline: VarianceEstimate | None
    z: float | None
    bound: float | None
    note: str = ""

    @property
    def fails(self) -> bool:
        return self.status in ("RISE", "FAILED")


def _estimate(d: dict[str, Any]) -> VarianceEstimate:
    return VarianceEstimate(float(d["value"]), float(d["standard_error"]), int(d["replicates"]), int(d["pixels"]))


def judge(
    name: str, current: VarianceEstimate | None, baseline: VarianceEstimate | None, z_max: float, error: str = ""
) -> Verdict:
    if current is None:
        return Verdict(name, "FAILED", None, baseline, None, None, error)
    if baseline is None:
        return Verdict(name, "new", current, None, None, None, "no baseline entry: run with --update")
    z = metrics.regression_z(current, baseline)
    bound = metrics.ratio_bound(current, baseline, z_max)
    status = "RISE" if z > z_max else ("improved" if z < -z_max else "ok")
    return Verdict(name, status, current, baseline, z, bound)


def read_baseline(path: Path) -> dict[str, Any] | None:
    try:
        with open(path) as f:
            data = json.load(f)
    except FileNotFoundError:
        return None
    except (OSError, json.JSONDecodeError) as e:
        raise ConfigError(str(path), "", f"unreadable baseline: {e}") from None
    if not isinstance(data, dict) or not isinstance(data.get("entries"), dict):
        raise ConfigError(str(path), "entries", "expected a mapping of baseline entries")
    return data


def settings_of(experiment: Experiment) -> dict[str, Any]:
    assert experiment.regress is not None
    return {
        "spp": experiment.regress.spp,
        "seeds": list(experiment.regress.seeds),
        "width": experiment.width,
        "height": experiment.height,
        "integrator": experiment.integrator,
        "fixed": dict(experiment.fixed),
        "regions": [[r.name, r.x, r.y, r.width, r.height] for r in experiment.insets],
    }


def print_table(verdicts: list[Verdict], z_max: float, out: TextIO) -> None:
    header = f"{'point/strategy':<36} {'baseline':>11} {'current':>11} {'ratio':>7} {'bound':>7} {'z':>7}  verdict"
    print(header, file=out)
    print("-" * len(header), file=out)

    def num(v: float | None, spec: str) -> str:
        width = int(spec.split(".")[0])
        return format(v, spec) if v is not None and math.isfinite(v) else "-".rjust(width)

    for v in verdicts:
        ratio = v.current.value / v.baseline.value if v.current and v.baseline and v.baseline.value > 0 else None
        print(
            f"{v.name:<36} {num(v.baseline.value if v.baseline else None, '11.4e')} "
            f"{num(v.current.value if v.current else None, '11.4e')} {num(ratio, '7.3f')} "
            f"{num(v.bound, '7.3f')} {num(v.z, '7.2f')}  {v.status}{'  ' + v.note if v.note else ''}",
            file=out,
        )
    print(f"(relative variance mean(var / (mean^2 + 0.01)); fails when z > {z_max:g}, i.e. ratio > bound)", file=out)


def regress(experiment: Experiment, options: SweepOptions, update: bool, out: TextIO | None = None) -> int:
    """Renders, compares (or rewrites the baseline with --update); returns the exit status."""
    out = out or sys.stdout
    settings = experiment.regress
    if settings is None:
        raise ConfigError(str(experiment.path), "regress", "missing (the regress command needs spp and seeds)")
    baseline_path = experiment.baseline_path(options.layout)
    baseline = None if update else read_baseline(baseline_path)

    groups: dict[str, list[str]] = {}
    specs = []
    for point in experiment.points():
        for strategy in experiment.strategies:
            name = f"{point.id}/{strategy}"
            for seed in settings.seeds:
                spec = experiment.regress_spec(point, strategy, seed)
                specs.append(spec)
                groups.setdefault(name, []).append(spec.key(options.renderer_version))
    options.layout.root.mkdir(parents=True, exist_ok=True)
    conn = index.connect(options.layout.index_path)
    try:
        # Always render: a rebuilt renderer may keep its version string.
        manifests = execute_specs(specs, options, conn, desc="regress renders", force=True)
    finally:
        conn.close()

    estimates: dict[str, VarianceEstimate | None] = {}
    errors: dict[str, str] = {}
    for name, keys in groups.items():
        replicates = []
        for key in keys:
            m = manifests.get(key, {})
            if m.get("status") != store.STATUS_DONE:
                errors[name] = f"run {key} {m.get('status', 'missing')}: {m.get('error') or ''}".strip()
                break
            try:
                snap = exr.read_snapshot(options.layout.run(key).final)
            except CorruptExrError as e:
                errors[name] = str(e)
                break
            w = metrics.relative_variance(snap.rgb, snap.variance)
            replicates.append(
                np.concatenate([metrics.crop(w, r).reshape(-1) for r in experiment.insets]) if experiment.insets else w
            )
        estimates[name] = metrics.pooled_estimate(replicates) if name not in errors else None

    entries = (baseline or {}).get("entries", {})
    verdicts = [
        judge(
            name,
            estimates[name],
            _estimate(entries[name]) if name in entries else None,
            settings.z_max,
            errors.get(name, ""),
        )
        for name in groups
    ]
    if baseline is not None:
        verdicts += [
            Verdict(name, "missing", None, _estimate(entries[name]), None, None, "not in this config")
            for name in entries
            if name not in groups
        ]
        if baseline.get("settings") != settings_of(experiment):
            print(
                f"note: settings differ from the baseline's: baseline {baseline.get('settings')}, "
                f"now {settings_of(experiment)}",
                file=out,
            )
        if baseline.get("renderer_version") != options.renderer_version:
            print(
                f"note: baseline made with renderer {baseline.get('renderer_version')}, now {options.renderer_version}",
                file=out,
            )
    elif not update:
        print(f"no baseline at {baseline_path}: run `portal-harness regress --update` to create it", file=out)

    print_table(verdicts, settings.z_max, out)
    failed = [v for v in verdicts if v.fails]
    if update:
        good = {v.name: asdict(v.current) for v in verdicts if v.current is not None}
        baseline_path.parent.mkdir(parents=True, exist_ok=True)
        store.write_json_atomic(
            baseline_path,
            {
                "schema": BASELINE_SCHEMA,
                "experiment": experiment.name,
                "renderer_version": options.renderer_version,
                "created": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
                "statistic": "mean over seeds, pixels and channels of var / (mean^2 + 0.01)",
                "settings": settings_of(experiment),
                "entries": good,
            },
        )
        print(f"baseline written: {baseline_path} ({len(good)} entries)", file=out)
    if failed:
        print(f"regress FAILED: {', '.join(v.name + ' ' + v.status for v in failed)}", file=out)
        return 1
    if baseline is None and not update:
        return 1
    print("regress passed", file=out)
    return 0
