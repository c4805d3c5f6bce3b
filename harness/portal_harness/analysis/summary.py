"""The tidy summary of a sweep: one row per (point, strategy, region), in
long form (pandas and seaborn read it directly), from the index's metrics.

For each row, over the K replicates j (independent seeds) of the strategy
at the point, with F the reference's noise in the region (noise_check.py)
and relMSE_j, t_j the final image's error and render time:

- rel_mse = mean_j (relMSE_j - F): the reference's noise removed (not
  where the reference does not resolve the error: see bound below);
  rel_mse_stderr = sd_j / sqrt(K) (Celarek et al. 2019, "Quantifying the
  error of light transport algorithms": errors of independent runs, their
  mean and its standard error);
- efficiency = 1 / mean_j ((relMSE_j - F) t_j), the inverse of the mean
  cost-error product, so that runs whose times differ slightly weigh alike;
- efficiency_vs_light = mean_j c_light,j / mean_j c_j with c = (relMSE - F) t,
  its standard error by the delta method over two independent means:
  ratio x sqrt((se_light / mean_light)^2 + (se / mean)^2);
- speedup_equal_error = t_light / T, T the time the strategy's curve needs
  to reach light's mean final error (speedup.py), mean over replicates;
  its standard error is that of the mean over the strategy's replicates
  (with `precision:`, light's too: light's mean error e_L sets T ~ 1/e_L,
  so its relative standard error is added in quadrature: precision.py);
- reference_noise_ratio = F / mean_j relMSE_j (the measured error, F
  included: it is the ratio noise_check.py limits);
- bound = "lower" where that ratio exceeds reference.noise_ratio (or
  fireflies carry F: noise_check.py): the
  reference does not resolve the error, so F is not subtracted and the
  efficiency is a lower bound (the measured error overestimates the true).
  speedup_bound is "lower"/"upper" where the curves only bound the time.
"""

from __future__ import annotations

import math
import sqlite3
import statistics
from dataclasses import dataclass
from typing import Any

from portal_harness.analysis.speedup import combined_bound, time_to_error
from portal_harness.execution import index

BASELINE = "light"

# Column order of summary.csv (the tidy table).
COLUMNS = (
    "point",
    "axis",
    "strategy",
    "status",
    "region",
    "region_kind",
    "pixels",
    "replicates",
    "time_s",
    "spp",
    "rel_mse",
    "rel_mse_stderr",
    "rel_mse_measured",
    "reference_noise",
    "reference_noise_ratio",
    "efficiency",
    "efficiency_stderr",
    "efficiency_vs_light",
    "efficiency_vs_light_stderr",
    "speedup_equal_error",
    "speedup_equal_error_stderr",
    "speedup_bound",
    "time_to_light_error_s",
    "bound",
)


# The columns an experiment with `precision:` adds at the end (analysis/precision.py).
PRECISION_COLUMNS = (
    "precision_target",
    "efficiency_vs_light_rel_se",
    "speedup_equal_error_rel_se",
    "precision_reached",
)


def columns(facet_keys: tuple[str, ...], precision: bool = False) -> tuple[str, ...]:
    """The columns of an experiment's summary: one per facet key (its
    full --set key, e.g. render.portal_weight) after `axis`; with
    `precision`, PRECISION_COLUMNS at the end."""
    at = COLUMNS.index("axis") + 1
    return COLUMNS[:at] + facet_keys + COLUMNS[at:] + (PRECISION_COLUMNS if precision else ())


@dataclass(frozen=True)
class Replicate:
    """One finished run's final values and curve in one region."""

    rel_mse: float  # measured, reference noise included
    time_s: float
    spp: int
    curve: tuple[tuple[float, float], ...]  # (time_s, measured relMSE) of every image


def _mean_se(values: list[float]) -> tuple[float, float]:
    if not values:
        return math.nan, math.nan
    mean = statistics.fmean(values)
    se = statistics.stdev(values) / math.sqrt(len(values)) if len(values) > 1 else math.nan
    return mean, se


def _ratio_se(num: tuple[float, float], den: tuple[float, float]) -> tuple[float, float]:
    (a, sa), (b, sb) = num, den
    if not (math.isfinite(a) and math.isfinite(b)) or a <= 0 or b <= 0:
        return math.nan, math.nan
    r = a / b
    return r, r * math.hypot(sa / a, sb / b) if math.isfinite(sa) and math.isfinite(sb) else math.nan


def replicates_of(conn: sqlite3.Connection, keys: list[str], reference_key: str) -> dict[str, list[Replicate]]:
    """By region, the replicates of one (point, strategy) with a final image."""
    out: dict[str, list[Replicate]] = {}
    for key in keys:
        rows = [
            m for m in index.metrics_of(conn, key, reference_key) if m["error"] is None and m["rel_mse"] is not None
        ]
        for region in {m["region"] for m in rows}:
            mine = [m for m in rows if m["region"] == region]
            final = next((m for m in mine if m["is_final"]), None)
            if final is None or not final["time_s"]:
                continue
            out.setdefault(region, []).append(
                Replicate(
                    rel_mse=float(final["rel_mse"]),
                    time_s=float(final["time_s"]),
                    spp=int(final["spp"] or 0),
                    curve=tuple((float(m["time_s"]), float(m["rel_mse"])) for m in mine if m["time_s"]),
                )
            )
    return out


def _cost(r: Replicate, floor: float, corrected: bool) -> float:
    return max(r.rel_mse - (floor if corrected else 0.0), 0.0) * r.time_s


@dataclass(frozen=True)
class RegionInfo:
    kind: str
    pixels: int
    floor: float
    fireflies: bool = False  # the floor rests on a few samples (noise_check.firefly_share)


def rows_for_point(
    point: str,
    axis: float,
    strategies: tuple[str, ...],
    reps: dict[str, dict[str, list[Replicate]]],
    regions: dict[str, RegionInfo],
    noise_ratio: float,
    status: dict[str, str],
    facets: tuple[tuple[str, Any], ...] = (),
    light_in_speedup_se: bool = False,
) -> list[dict[str, Any]]:
    """reps: strategy -> region -> replicates; status: strategy -> "done"
    when every replicate is, else the status of the first that is not;
    facets: the point's (key, value) of each facet key, a column each;
    light_in_speedup_se: the speed-up's standard error includes light's
    (the module docstring; experiments with `precision:`)."""
    out: list[dict[str, Any]] = []
    for region, info in regions.items():
        floor = info.floor
        base = reps.get(BASELINE, {}).get(region, [])
        base_cost = _mean_se([_cost(r, floor, True) for r in base])
        base_error, base_error_se = _mean_se([max(r.rel_mse - floor, 0.0) for r in base])
        base_rel = base_error_se / base_error if light_in_speedup_se and base_error > 0 else 0.0
        base_time = statistics.fmean([r.time_s for r in base]) if base else math.nan
        for strategy in strategies:
            mine = reps.get(strategy, {}).get(region, [])
            row: dict[str, Any] = {
                "point": point,
                "axis": axis,
                **dict(facets),
                "strategy": strategy,
                "status": status.get(strategy, "missing"),
                "region": region,
                "region_kind": info.kind,
                "pixels": info.pixels,
                "replicates": len(mine),
                "reference_noise": floor,
            }
            if not mine:
                out.append(row)
                continue
            measured = statistics.fmean([r.rel_mse for r in mine])
            ratio = floor / measured if measured > 0 else (math.nan if floor == 0 else math.inf)
            resolved = not (ratio > noise_ratio) and not info.fireflies
            cost = _mean_se([_cost(r, floor, resolved) for r in mine])
            # Unresolved: the floor is not subtracted (it may exceed the error it
            # would be taken from), so rel_mse is the measured error, an upper bound.
            rel, rel_se = _mean_se([r.rel_mse - (floor if resolved else 0.0) for r in mine])
            eff = 1.0 / cost[0] if cost[0] > 0 else math.nan
            eff_se = eff * cost[1] / cost[0] if cost[0] > 0 else math.nan
            vs, vs_se = _ratio_se(base_cost, cost)
            row.update(
                {
                    "time_s": statistics.fmean([r.time_s for r in mine]),
                    "spp": statistics.fmean([r.spp for r in mine]),
                    "rel_mse": rel,
                    "rel_mse_stderr": rel_se,
                    "rel_mse_measured": measured,
                    "reference_noise_ratio": ratio,
                    "efficiency": eff,
                    "efficiency_stderr": eff_se,
                    "efficiency_vs_light": vs,
                    "efficiency_vs_light_stderr": vs_se,
                    "bound": "" if resolved else "lower",
                }
            )
            row.update(_speedup(strategy, mine, floor, base_error, base_time, base_rel))
            out.append(row)
    return out


def _speedup(
    strategy: str, mine: list[Replicate], floor: float, target: float, t_light: float, target_rel_se: float = 0.0
) -> dict[str, Any]:
    if strategy == BASELINE and math.isfinite(t_light):
        # By definition: light reaches its own final error at the end of its budget.
        return {
            "speedup_equal_error": 1.0,
            "speedup_equal_error_stderr": 0.0,
            "speedup_bound": "",
            "time_to_light_error_s": t_light,
        }
    found = [time_to_error([(t, e - floor) for t, e in r.curve], target) for r in mine]
    times = [f for f in found if f is not None]
    if not times or not math.isfinite(t_light):
        return {"speedup_bound": ""}
    speed, speed_se = _mean_se([t_light / f.time_s for f in times])
    if target_rel_se:  # light's mean error, the target, is itself an estimate (T ~ 1/target)
        speed_se = math.hypot(speed_se, speed * target_rel_se)
    bound = combined_bound([f.bound for f in times])
    return {
        "speedup_equal_error": speed,
        "speedup_equal_error_stderr": speed_se,
        "speedup_bound": bound,
        "time_to_light_error_s": statistics.fmean([f.time_s for f in times]),
    }


def wide(rows: list[dict[str, Any]], region: str) -> list[dict[str, Any]]:
    """The tidy rows of one region, one per (point, strategy): the table `sweep` prints."""
    return [r for r in rows if r["region"] == region]
