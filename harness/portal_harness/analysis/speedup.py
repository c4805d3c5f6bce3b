"""Equal-error speed-up: how long a strategy needs to reach the error light
sampling reaches at the end of its budget, read off its error-over-time
curve.

A curve is the (render time, relMSE - reference noise) of a run's snapshots
and final image. Between the last snapshot above the target error and the
first at or below it, the time is interpolated linearly in log-log (an
unbiased estimator's relMSE falls as 1/t, a straight line there). A curve
that starts at or below the target only bounds the time from above (the
speed-up is then a lower bound); one that never reaches it bounds the time
from below (the speed-up is an upper bound).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

LOWER, UPPER = "lower", "upper"
# Floor-corrected errors can reach 0 (or below) by noise; logs need a positive value.
_TINY = 1e-300


@dataclass(frozen=True)
class TimeToError:
    time_s: float
    bound: str  # "", LOWER (speed-up >= the value) or UPPER (speed-up <= the value)


def time_to_error(curve: list[tuple[float, float]], target: float) -> TimeToError | None:
    """curve: (time_s, error) with time_s > 0, any order."""
    points = sorted((t, e) for t, e in curve if t > 0 and math.isfinite(e))
    if not points or not (target > 0):
        return None
    if points[0][1] <= target:
        return TimeToError(points[0][0], LOWER)
    for (t0, e0), (t1, e1) in itertools.pairwise(points):
        if e1 <= target:
            l0, l1 = math.log(max(e0, _TINY)), math.log(max(e1, _TINY))
            lt = math.log(target)
            frac = (lt - l0) / (l1 - l0) if l1 != l0 else 1.0
            return TimeToError(math.exp(math.log(t0) + frac * (math.log(t1) - math.log(t0))), "")
    return TimeToError(points[-1][0], UPPER)


def combined_bound(bounds: list[str]) -> str:
    """The bound of a mean of replicate speed-ups: any one-sided replicate makes it one-sided."""
    kinds = {b for b in bounds if b}
    if kinds == {LOWER}:
        return LOWER
    if kinds == {UPPER}:
        return UPPER
    return "mixed" if kinds else ""
