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

Fireflies. F is estimated from the reference's own sample variance, which
a heavy-tailed estimator underestimates until its rare large samples have
been drawn many times: where they have been drawn once, a pixel's value
rests on that one sample, its standard error is about its value, and F
is carried by those few pixels. A pixel-channel is such a firefly when
its relative standard error is at least FIREFLY_REL_SE (a handful of
samples, 1 / FIREFLY_REL_SE^2 = 4, carry it) and it is bright enough to
count in the relMSE (m^2 >= eps). When fireflies hold more than
FIREFLY_SHARE_MAX of a region's F, F (and every error corrected by it) is
not to be trusted however small it looks, and the region fails: the
reference is extended by FIREFLY_EXTENSION, and where the cap stops that,
its values are reported as bounds. Measured on the stored references:
the path-traced lampshade's `projection` part at ratio 0.25 has 169 such
pixels holding 0.60 of its F (20x the `light` part's F), the Little
Lamp's path references 0.90-0.92; every direct reference of the
lampshade and multi_lamp 0 to 0.05, except the `projection` part at
ratio 0.25 (0.67).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from portal_harness.core import exr
from portal_harness.core.metrics import REL_EPSILON, rel_variance_floor
from portal_harness.core.regions import NamedRegion

EXTENSION_MARGIN = 1.25
# One round multiplies a part's samples by at most this much; the next
# round looks again with the better estimates (MAX_EXTENSION_ROUNDS in lifecycle.py).
MAX_FACTOR_PER_ROUND = 16.0
# Without reference.max_time_s, a part may grow to this many times its first render time.
DEFAULT_CAP_FACTOR = 20.0
FIREFLY_REL_SE = 0.5
FIREFLY_SHARE_MAX = 0.5
# Four times the samples halve a firefly's relative standard error.
FIREFLY_EXTENSION = 4.0


@dataclass(frozen=True)
class RegionCheck:
    region: str
    floor: float  # the reference's noise in relMSE units
    smallest_error: float  # smallest mean final relMSE of any strategy (measured, floor included)
    ratio: float  # floor / smallest_error; nan when both are 0
    ok: bool
    firefly_share: float = 0.0  # of the floor held by firefly pixels (firefly_share)

    @property
    def fireflies(self) -> bool:
        return self.firefly_share > FIREFLY_SHARE_MAX


def firefly_share(rgb: np.ndarray, variance: np.ndarray, mask: np.ndarray, epsilon: float = REL_EPSILON) -> float:
    """The share of a region's reference noise F (metrics.rel_variance_floor)
    held by pixel-channels whose relative standard error is at least
    FIREFLY_REL_SE and that are bright enough to count (m^2 >= epsilon)."""
    m = rgb[mask].astype(np.float64)
    v = variance[mask].astype(np.float64)
    contribution = v / (m * m + epsilon)
    total = float(np.sum(contribution))
    if total <= 0:
        return 0.0
    firefly = (v >= FIREFLY_REL_SE**2 * m * m) & (m * m >= epsilon)
    return float(np.sum(contribution[firefly])) / total


def check(
    floors: dict[str, float],
    smallest: dict[str, float],
    noise_ratio: float,
    shares: dict[str, float] | None = None,
) -> list[RegionCheck]:
    """Per region with a measured error: the reference resolves it when its
    noise is at most noise_ratio of it and fireflies do not carry that noise."""
    out = []
    for region, floor in floors.items():
        err = smallest.get(region, math.nan)
        if not math.isfinite(err):
            continue
        ratio = floor / err if err > 0 else (math.nan if floor <= 0 else math.inf)
        share = (shares or {}).get(region, 0.0)
        ok = not (ratio > noise_ratio) and not share > FIREFLY_SHARE_MAX
        out.append(RegionCheck(region, floor, err, ratio, ok, share))
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
        if not (c.ratio > noise_ratio) and c.fireflies:
            f = FIREFLY_EXTENSION  # resolved on paper, but the floor rests on a few samples
        elif true_error <= 0:
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
