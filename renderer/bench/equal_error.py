"""Equal-time error of two renderers against one reference, for the bench's
`mitsuba_efficiency` section: how much faster one converges than the other.

A render's inverse efficiency is its error times its time, rel_mse_est x
seconds (benchlib.rel_error: relMSE with the reference's own noise
removed). For an unbiased renderer it does not depend on how long the
render ran (the error falls as 1 / time), so the ratio of two renderers'
products is how many times longer one needs for the same error. Pure
functions of the measured numbers; bench.py renders and reads the images.
"""

from __future__ import annotations

import math
from statistics import median
from typing import Any


def speedup(a: dict[str, Any], a_s: float, b: dict[str, Any], b_s: float) -> dict[str, float]:
    """How many times less time a needs than b for the same error: (b's
    error x time) / (a's). a and b are rel_error results, a_s and b_s the
    seconds they took. `low` and `high` bound it by two standard errors of
    both estimates (b's error taken at least zero), so that an error the
    reference cannot resolve gives a bound, not a number: `resolved` says
    whether both estimates are above two standard errors."""
    ea, eb = a["rel_mse_est"], b["rel_mse_est"]
    sa, sb = a["rel_mse_est_se"], b["rel_mse_est_se"]
    if not (a_s > 0 and b_s > 0):
        raise ValueError(f"times must be positive (got {a_s}, {b_s})")
    ratio = (eb * b_s) / (ea * a_s) if ea > 0 else math.inf
    low = (max(eb - 2 * sb, 0.0) * b_s) / ((ea + 2 * sa) * a_s)
    high = ((eb + 2 * sb) * b_s) / ((ea - 2 * sa) * a_s) if ea - 2 * sa > 0 else math.inf
    return {
        "ratio": ratio,
        "low": low,
        "high": high,
        "resolved": bool(ea > 2 * sa and eb > 2 * sb),
    }


def over_rounds(rounds: list[dict[str, float]]) -> dict[str, Any]:
    """speedup's results of independent rounds: the median ratio, its range,
    and the smallest `low` (the bound every round supports)."""
    if not rounds:
        raise ValueError("no rounds")
    ratios = [r["ratio"] for r in rounds]
    return {
        "median": median(ratios),
        "min": min(ratios),
        "max": max(ratios),
        "low": min(r["low"] for r in rounds),
        "resolved": all(r["resolved"] for r in rounds),
        "n": len(rounds),
    }


def consistent(err: dict[str, Any], z_max: float = 4.0) -> bool:
    """Whether a render's error against the reference is what its own
    variance predicts (bias_z within z_max standard errors): a renderer
    whose image differed from the reference's by more than noise would
    show a large positive bias_z, and its error would not be noise."""
    z = err.get("bias_z", math.nan)
    return bool(math.isfinite(z) and z <= z_max)
