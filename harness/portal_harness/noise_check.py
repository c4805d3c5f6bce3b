"""Is a reference good enough for the errors it is compared with?

An independent reference R adds its own variance to every measured error:
E[relMSE(x, R)] = relMSE(x) + F, with F = mean Var(R) / (R^2 + eps) over
the region (metrics.rel_variance_floor). The harness removes F, but F is
itself only estimated; so for every region a figure or table reports, F
must be at most `noise_ratio` (default 1/10) of the smallest error measured
there (the mean final relMSE over replicates of the best strategy). Then
the correction is small and its uncertainty negligible.

When a region falls short, the reference is extended (extend.py) with the
part that is cheapest there: with pooled relative variances V_A, V_B of the
two parts, the combination has 1/V = 1/V_A + 1/V_B; scaling A's samples by
g divides V_A by g, so reaching V / f needs g = V_A (f / V - 1 / V_B). The
factor f brings F to noise_ratio x the region's true error (relMSE - F),
with a margin of EXTENSION_MARGIN for the noise of these estimates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from portal_harness import exr
from portal_harness.metrics import rel_variance_floor
from portal_harness.regions import NamedRegion

EXTENSION_MARGIN = 1.25
# One round multiplies a part's samples by at most this much; the next
# round looks again with the better estimates (MAX_EXTENSION_ROUNDS in sweep.py).
MAX_FACTOR_PER_ROUND = 16.0
# Without reference.max_time_s, a part may grow to this many times its first render time.
DEFAULT_CAP_FACTOR = 20.0


@dataclass(frozen=True)
class RegionCheck:
    region: str
    floor: float  # the reference's noise in relMSE units
    smallest_error: float  # smallest mean final relMSE of any strategy (measured, floor included)
    ratio: float  # floor / smallest_error; nan when both are 0
    ok: bool


def check(floors: dict[str, float], smallest: dict[str, float], noise_ratio: float) -> list[RegionCheck]:
    out = []
    for region, floor in floors.items():
        err = smallest.get(region, math.nan)
        if not math.isfinite(err):
            continue
        ratio = floor / err if err > 0 else (math.nan if floor <= 0 else math.inf)
        out.append(RegionCheck(region, floor, err, ratio, not (ratio > noise_ratio)))
    return out


def pooled_relative_variance(part: exr.Snapshot, mean: np.ndarray, region: NamedRegion) -> float:
    """A part's variance relative to the combined `mean`, pooled over the region."""
    return rel_variance_floor(mean, part.variance, region.mask) if region.pixels else 0.0


@dataclass(frozen=True)
class Extension:
    part: int  # index of the reference part to extend
    factor: float  # its samples are multiplied by this
    regions: tuple[str, ...]


def plan_extension(
    failed: list[RegionCheck],
    parts: list[exr.Snapshot],
    mean: np.ndarray,
    regions: list[NamedRegion],
    noise_ratio: float,
) -> Extension | None:
    """The one extension that brings every failed region within the limit."""
    by_name = {r.name: r for r in regions}
    needs: dict[int, float] = {}
    names: dict[int, list[str]] = {}
    for c in failed:
        region = by_name[c.region]
        true_error = max(c.smallest_error - c.floor, 0.0)
        if true_error <= 0:
            # The error is all reference noise: at least halve it, then look again.
            f = 2.0 * EXTENSION_MARGIN
        else:
            target = noise_ratio * true_error / (1 - noise_ratio)
            f = EXTENSION_MARGIN * c.floor / target
        v = [pooled_relative_variance(p, mean, region) for p in parts]
        best = int(np.argmin(v))
        if len(parts) == 1 or v[best] == 0:
            g = f
        else:
            combined = 1.0 / sum(1.0 / x for x in v if x > 0)
            others = sum(1.0 / x for i, x in enumerate(v) if i != best and x > 0)
            g = v[best] * (f / combined - others)
        needs[best] = max(needs.get(best, 1.0), g)
        names.setdefault(best, []).append(c.region)
    if not needs:
        return None
    part = max(needs, key=lambda k: needs[k])
    return Extension(part, min(max(needs[part], 1.05), MAX_FACTOR_PER_ROUND), tuple(names[part]))
