"""Paper quality defined by precision: the headline values of an experiment
with `precision:` (experiment/precision.py), their relative standard errors,
where the next replicates go, and the marks of the values that did not
reach the target.

The headline values are, at every point and for every strategy but light,
in every headline region (`precision.of`): the efficiency relative to
light and the equal-error speed-up (summary.py). Both are ratios of means
over independent replicates of two cells (point, strategy): the
strategy's and light's at the same point. Their relative variance is the
sum of the two cells' terms, each falling as 1/K with the cell's K
replicates:

- efficiency_vs_light = mean c_light / mean c (c = cost-error product):
  (se_c/mean_c)^2 + (se_light/mean_light)^2, the strategy's and light's
  efficiency rows' relative standard errors;
- speedup_equal_error = t_light / T, T the time to reach light's mean
  final error e_L: the spread of the strategy's replicate speed-ups, and
  light's error, whose relative error moves T (relMSE ~ 1/t for an
  unbiased estimator, so T ~ 1/e_L) and the speed-up by as much:
  (se_e_L/e_L)^2, light's rel_mse row. With precision the summary's
  speed-up standard error includes this term (summary.rows_for_point).

Two stages, no peeking (Stein's two-stage procedure). Stopping as soon as
the *estimated* relative standard error is below the target picks the runs
whose variance happened to be underestimated (and, the SE being relative,
whose mean happened to be large): on the fake renderer (3 first
replicates, target 3%, cap 16) such rounds reported 2.5% where the
estimates' spread was 3.7%, and +-2 SE covered the true ratio 81% of the
time. So the sweep looks once:

1. the first stage, budget.replicates = n0 replicates of every cell,
   gives each value's terms;
2. `allocate` fixes the second stage from them. First every cell of a
   value is topped up to MIN_FINAL_REPLICATES (or the cap), one replicate
   per cell in turn, so that no reported standard error rests on a handful
   of replicates even when the time cap cuts the stage: the White Room's
   FULL run (2026-12-07) spent its cap on path tracing's urgent replicates
   and kept its direct-light cells at 4 when the top-ups came last. Then,
   while some value's predicted relative variance, its terms inflated by
   variance_safety(n0) (the one-sided SAFETY_CONFIDENCE upper bound of a
   variance from n0 replicates), is above the target's, the value furthest
   from it gets one replicate, in whichever of its two cells lowers its
   predicted variance most: a cell's term a K/(K + k) after k more (light's
   cell serves every value of its point, so its replicates are shared; a
   cell at precision.max_replicates gets no more, the value's other cell
   may);
3. the second stage is run, and every value and its standard error come
   from all the replicates of its cells. The measured rel. SE is the
   verdict (reached or not), but nothing more is added on it.

Measured on 200 seeded sweeps of a numpy copy of the fake renderer (both
points, 400 values; 3 + up to 16 replicates, target 3%; with the top-ups
still last, before 2026-12-07, and not measured again since: without a
time cap the order moves only where the greedy loop starts): +-1 SE / +-2 SE
cover the true ratio 66% / 94% of the time (efficiency; speed-up 66% /
93%), against 50% / 81% with the rounds; 99.8% of the values reach the
target, with 15 replicates per cell on average. A resumed sweep derives
the same second stage from the same first replicates, so it adds nothing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from portal_harness.analysis.summary import BASELINE, PRECISION_COLUMNS
from portal_harness.experiment.model import Precision

EFFICIENCY, SPEEDUP = "efficiency_vs_light", "speedup_equal_error"
MEASURES = (EFFICIENCY, SPEEDUP)
COLUMNS = PRECISION_COLUMNS  # the columns summary.csv gains with precision (summary.columns)
# (point, strategy)
Cell = tuple[str, str]
# The one-sided confidence at which the first stage's variances are bounded (variance_safety).
SAFETY_CONFIDENCE = 0.8
# Every cell of a headline value ends with at least this many replicates (or the cap): a
# standard error from fewer is itself too noisy to report as one (module docstring).
MIN_FINAL_REPLICATES = 8


@dataclass(frozen=True)
class Value:
    """One headline value: its relative standard error and the cells its
    relative variance comes from, with each cell's term (rel. variance)."""

    point: str
    strategy: str
    region: str
    measure: str
    value: float
    rel_se: float  # NaN: no standard error (fewer than two replicates, or no value)
    terms: tuple[tuple[Cell, float], ...]

    @property
    def name(self) -> str:
        return f"{self.strategy} {self.point} {self.region} {self.measure}"


def _num(row: dict[str, Any] | None, key: str) -> float:
    value = (row or {}).get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return math.nan
    return float(value)


def _rel2(se: float, value: float) -> float:
    return (se / value) ** 2 if math.isfinite(se) and math.isfinite(value) and value > 0 else math.nan


def headline_values(rows: Iterable[dict[str, Any]], precision: Precision) -> list[Value]:
    """The headline values of the tidy rows (summary.py), in their order."""
    rows = list(rows)
    light = {(r["point"], r["region"]): r for r in rows if r["strategy"] == BASELINE}
    out: list[Value] = []
    for r in rows:
        if r["strategy"] == BASELINE or r["region"] not in precision.regions:
            continue
        base = light.get((r["point"], r["region"]))
        own_cell: Cell = (r["point"], r["strategy"])
        light_cell: Cell = (r["point"], BASELINE)
        for measure in MEASURES:
            value, se = _num(r, measure), _num(r, f"{measure}_stderr")
            rel_se = math.sqrt(_rel2(se, value)) if math.isfinite(_rel2(se, value)) else math.nan
            if measure == EFFICIENCY:
                own = _rel2(_num(r, "efficiency_stderr"), _num(r, "efficiency"))
                other = _rel2(_num(base, "efficiency_stderr"), _num(base, "efficiency"))
            else:
                other = _rel2(_num(base, "rel_mse_stderr"), _num(base, "rel_mse"))
                total = rel_se**2
                own = max(total - other, 0.0) if math.isfinite(other) else total
            terms = tuple((c, a) for c, a in ((own_cell, own), (light_cell, other)) if math.isfinite(a))
            out.append(Value(r["point"], r["strategy"], r["region"], measure, value, rel_se, terms))
    return out


def reached(value: Value, target: float) -> bool:
    return math.isfinite(value.rel_se) and value.rel_se <= target


def allocate(
    values: list[Value], counts: dict[Cell, int], precision: Precision, safety: float = 1.0, minimum: int = 0
) -> list[Cell]:
    """The second stage's replicates, one cell per replicate in the order
    they were given (a stage cut short by the time cap keeps a prefix): the
    top-ups to `minimum` replicates of every cell of a value (capped), one
    cell after another in turn, then the most urgent first; empty when no
    cell is below `minimum` and every value is predicted to reach the
    target or no cell that would help can grow. `values` are the first
    stage's, `safety` the factor its variance terms are inflated by
    (variance_safety)."""
    target2 = precision.rel_se**2
    extra: dict[Cell, int] = {}
    order: list[Cell] = []
    floor = min(minimum, precision.max_replicates)
    cells = list(dict.fromkeys(c for v in values for c in ((v.point, BASELINE), (v.point, v.strategy))))
    short = [c for c in cells if 0 < counts.get(c, 0) < floor]
    while short:
        for c in short:
            extra[c] = extra.get(c, 0) + 1
            order.append(c)
        short = [c for c in short if counts[c] + extra[c] < floor]

    def predicted(v: Value) -> float:
        return sum(safety * a * counts[c] / (counts[c] + extra.get(c, 0)) for c, a in v.terms if counts.get(c))

    def below_cap(c: Cell) -> bool:
        return counts.get(c, 0) > 0 and counts[c] + extra.get(c, 0) < precision.max_replicates

    def gain(term: tuple[Cell, float]) -> float:
        c, a = term
        n, k = counts[c], extra.get(c, 0)
        return a * n / (n + k) - a * n / (n + k + 1)

    open_ = [v for v in values if v.terms]
    while open_:
        worst = max(open_, key=predicted)
        if predicted(worst) <= target2:
            break
        candidates = [t for t in worst.terms if below_cap(t[0]) and gain(t) > 0]
        if not candidates:
            open_.remove(worst)  # capped (or nothing helps): it is marked if it falls short
            continue
        cell = max(candidates, key=gain)[0]
        extra[cell] = extra.get(cell, 0) + 1
        order.append(cell)
    return order


def variance_safety(n0: int, confidence: float = SAFETY_CONFIDENCE) -> float:
    """The factor a variance estimated from n0 replicates is multiplied by
    to bound the true one at `confidence` (one-sided, normal replicates):
    (n0 - 1) / chi2_{n0-1}(1 - confidence): 4.5 at n0 = 3, 3.0 at 4,
    1.8 at 8 for confidence 0.8."""
    df = n0 - 1
    if df < 1:
        return math.inf
    return df / _chi2_quantile(1.0 - confidence, df)


def _chi2_quantile(p: float, df: int) -> float:
    lo, hi = 0.0, float(df)
    while _chi2_cdf(hi, df) < p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _chi2_cdf(mid, df) < p else (lo, mid)
    return 0.5 * (lo + hi)


def _chi2_cdf(x: float, df: int) -> float:
    """The regularized lower incomplete gamma P(df/2, x/2), by its series."""
    if x <= 0:
        return 0.0
    a, z = df / 2.0, x / 2.0
    term = total = 1.0 / a
    k = 1
    while term > total * 1e-15:
        term *= z / (a + k)
        total += term
        k += 1
    return min(1.0, total * math.exp(-z + a * math.log(z) - math.lgamma(a)))


def mark_rows(rows: list[dict[str, Any]], precision: Precision) -> None:
    """Adds the precision columns (COLUMNS) to the tidy rows: on every row of
    a headline value its relative standard errors and whether both reached
    the target (True/False); the other rows leave them empty."""
    by = {(v.point, v.strategy, v.region, v.measure): v for v in headline_values(rows, precision)}
    for r in rows:
        mine = [by.get((r["point"], r["strategy"], r["region"], m)) for m in MEASURES]
        if not any(mine):
            continue
        r["precision_target"] = precision.rel_se
        for m, v in zip(MEASURES, mine, strict=True):
            r[f"{m}_rel_se"] = v.rel_se if v is not None else math.nan
        r["precision_reached"] = all(v is not None and reached(v, precision.rel_se) for v in mine)


def unreached(row: dict[str, Any], measure: str) -> bool:
    """A headline value of a summary row (summary.json's, or summary.csv's
    as text) whose relative standard error is above its target, or unknown:
    the tables and figures mark it."""
    target = _text_num(row.get("precision_target"))
    if measure not in MEASURES or not math.isfinite(target):
        return False  # not a headline value, or an experiment without precision
    rel_se = _text_num(row.get(f"{measure}_rel_se"))
    return not (math.isfinite(rel_se) and rel_se <= target)


def _text_num(value: Any) -> float:
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return math.nan
    return _num({"v": value}, "v")


def report(values: list[Value], precision: Precision) -> dict[str, Any]:
    """The precision reached, for summary.json and the manifest."""
    return {
        "target_rel_se": precision.rel_se,
        "regions": list(precision.regions),
        "values": [
            {
                "point": v.point,
                "strategy": v.strategy,
                "region": v.region,
                "measure": v.measure,
                "value": v.value if math.isfinite(v.value) else None,
                "rel_se": v.rel_se if math.isfinite(v.rel_se) else None,
                "reached": reached(v, precision.rel_se),
            }
            for v in values
        ],
    }
