"""Two independent references of one point: a bias test between them, and
their combination into the reference the metrics use.

Bias test. Renders A and B with different strategies and seeds are
independent, and both unbiased strategies have the same expected image. Over
the pixels p and channels c of a region, D = sum_pc (a_pc - b_pc) then has
mean 0. Pixels are independent (each has its own random streams), but the
channels of one pixel are not: a sample's R, G and B come from the same
path (here exactly proportional), so the variance of a pixel's sum over
channels is up to (sum_c sd_pc)^2, and that bound is used,

    z = D / sqrt(sum_p (sum_c sqrt(va_pc + vb_pc))^2)  ~  N(0, 1)

(by the central limit theorem over the region; the channels' variances
alone, sum_pc (va_pc + vb_pc), would make z up to sqrt(3) too large, and
false alarms likely). This is the variance of the mean exactly when the
channels are proportional, and an overestimate (a more conservative test)
otherwise. |z| > bias_z (default 4, a
false alarm probability of 6e-5 per region) means one strategy is biased
there, and the sweep stops: nothing measured against such a reference could
be trusted. A region where both are exactly equal (no light reaches it) has
z = 0.

Combination. Each region class of the AOV (and the pixels with no majority
class, as one more group) gets the inverse-variance weights of its pooled
relative variances,

    w_A = V_B / (V_A + V_B),  V_X = mean over the group of var_X / (m^2 + eps),

with m = (a + b) / 2. Pooled over many pixels, V_X is nearly a constant, so
the weights are (almost) independent of the pixel values they weight: per
pixel weights from the pixel's own noisy variance would correlate with its
value and bias the combination. The combined variance is
w_A^2 va + w_B^2 vb.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from portal_harness.core import exr
from portal_harness.core.metrics import rel_variance_floor
from portal_harness.core.regions import NamedRegion, class_map


@dataclass(frozen=True)
class RegionDisagreement:
    region: str
    z: float
    mean_difference: float  # mean of a - b over the region's pixel-channels
    pixels: int


def disagreement(a: exr.Snapshot, b: exr.Snapshot, regions: list[NamedRegion]) -> list[RegionDisagreement]:
    out = []
    for r in regions:
        d = a.rgb[r.mask] - b.rgb[r.mask]  # (pixels, channels)
        sd_pixel = np.sum(np.sqrt(a.variance[r.mask] + b.variance[r.mask]), axis=-1)
        total, var = float(np.sum(d)), float(np.sum(sd_pixel * sd_pixel))
        # Without variance no difference is 0 sigma, and any other infinitely many.
        z = total / math.sqrt(var) if var > 0 else (math.copysign(math.inf, total) if total != 0 else 0.0)
        out.append(RegionDisagreement(r.name, z, float(np.mean(d)) if d.size else 0.0, r.pixels))
    return out


def failures(found: list[RegionDisagreement], z_max: float) -> list[RegionDisagreement]:
    return [d for d in found if abs(d.z) > z_max]


def _groups(a: exr.Snapshot, fractions: np.ndarray | None) -> np.ndarray:
    """Per pixel, the group its weights come from: its AOV class (-1 when no
    class has the majority), or 0 everywhere without the AOV."""
    if fractions is None:
        return np.zeros(a.rgb.shape[:2], dtype=np.int64)
    return class_map(fractions)


def weights(a: exr.Snapshot, b: exr.Snapshot, fractions: np.ndarray | None) -> np.ndarray:
    """Per pixel, the weight of A (B gets 1 - it)."""
    groups = _groups(a, fractions)
    m = 0.5 * (a.rgb + b.rgb)
    w = np.full(groups.shape, 0.5)
    for g in np.unique(groups):
        mask = groups == g
        va, vb = rel_variance_floor(m, a.variance, mask), rel_variance_floor(m, b.variance, mask)
        if va + vb > 0:
            w[mask] = vb / (va + vb)
    return w


def combine(
    a: exr.Snapshot, b: exr.Snapshot, strategy_label: str, config_hash: str, fractions: np.ndarray | None
) -> exr.Snapshot:
    """The combined reference (carrying the region AOV `fractions`, if any);
    its header sums the two renders' samples and time."""
    w = weights(a, b, fractions)[..., None]
    rgb = w * a.rgb + (1 - w) * b.rgb
    variance = w * w * a.variance + (1 - w) * (1 - w) * b.variance
    header = replace(
        a.header,
        render_time_s=a.header.render_time_s + b.header.render_time_s,
        spp=a.header.spp + b.header.spp,
        strategy=strategy_label,
        config_hash=config_hash,
        rays=a.header.rays + b.header.rays,
        nonfinite_samples=a.header.nonfinite_samples + b.header.nonfinite_samples,
    )
    return exr.Snapshot(path=a.path, header=header, rgb=rgb, variance=variance, regions=fractions)
