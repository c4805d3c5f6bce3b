"""Image error metrics and the regression statistic: pure numpy, no I/O.

Images are float arrays of shape (height, width, 3), row 0 at the top.
Every metric is averaged over pixels and channels alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# relMSE = (x - r)^2 / (r^2 + REL_EPSILON): the epsilon keeps black pixels
# of the reference from dominating (the usual choice in rendering papers).
REL_EPSILON = 0.01
WHOLE_IMAGE = "image"


@dataclass(frozen=True)
class Region:
    """A rectangle in pixel coordinates: columns [x, x + width), rows [y, y + height)."""

    name: str
    x: int
    y: int
    width: int
    height: int

    def fits(self, image_width: int, image_height: int) -> bool:
        return (
            self.width > 0
            and self.height > 0
            and self.x >= 0
            and self.y >= 0
            and self.x + self.width <= image_width
            and self.y + self.height <= image_height
        )


def crop(image: np.ndarray, region: Region | None) -> np.ndarray:
    """The pixels of `region` (the whole image for None)."""
    if region is None:
        return image
    if not region.fits(image.shape[1], image.shape[0]):
        raise ValueError(f"region {region} does not fit an image of {image.shape[1]}x{image.shape[0]}")
    return image[region.y : region.y + region.height, region.x : region.x + region.width]


# A region: a rectangle, a boolean mask of shape (height, width), or None
# for the whole image.
Selection = Region | np.ndarray | None


def select(image: np.ndarray, region: Selection) -> np.ndarray:
    """The pixels of `region`: a crop for a rectangle, (N, channels) for a mask."""
    if region is None or isinstance(region, Region):
        return crop(image, region)
    if region.shape != image.shape[:2]:
        raise ValueError(f"mask of shape {region.shape} does not fit an image of {image.shape[1]}x{image.shape[0]}")
    return image[region]


def _mean(values: np.ndarray) -> float:
    """The mean, nan for an empty region (never a numpy warning)."""
    return float(np.mean(values)) if values.size else math.nan


def _check(image: np.ndarray, reference: np.ndarray) -> None:
    if image.shape != reference.shape:
        raise ValueError(f"image shape {image.shape} differs from reference shape {reference.shape}")


def mse(image: np.ndarray, reference: np.ndarray, region: Selection = None) -> float:
    """Mean squared error over the pixels and channels of `region`."""
    _check(image, reference)
    d = select(image, region).astype(np.float64) - select(reference, region).astype(np.float64)
    return _mean(d * d)


def rel_mse(image: np.ndarray, reference: np.ndarray, region: Selection = None, epsilon: float = REL_EPSILON) -> float:
    """Relative MSE: (x - r)^2 / (r^2 + epsilon) per pixel and channel, averaged."""
    _check(image, reference)
    x = select(image, region).astype(np.float64)
    r = select(reference, region).astype(np.float64)
    return _mean((x - r) ** 2 / (r * r + epsilon))


def rel_variance_floor(
    reference: np.ndarray, reference_variance: np.ndarray, region: Selection = None, epsilon: float = REL_EPSILON
) -> float:
    """The part of a relMSE that is the reference's own noise:
    E[(x - R)^2] = MSE(x) + Var(R) for an independent reference R, so a curve
    cannot fall below about mean(Var(R) / (R^2 + epsilon))."""
    r = select(reference, region).astype(np.float64)
    v = select(reference_variance, region).astype(np.float64)
    return _mean(v / (r * r + epsilon))


def efficiency(rel_mse_value: float, time_s: float) -> float:
    """Monte Carlo efficiency 1 / (relMSE x time); inf for a zero error, nan for bad input."""
    if not (math.isfinite(rel_mse_value) and math.isfinite(time_s)) or time_s <= 0 or rel_mse_value < 0:
        return math.nan
    if rel_mse_value == 0:
        return math.inf
    return 1.0 / (rel_mse_value * time_s)


def relative_variance(mean: np.ndarray, variance: np.ndarray, epsilon: float = REL_EPSILON) -> np.ndarray:
    """Per pixel and channel, the variance of the mean relative to the squared
    mean: the expected relMSE of an unbiased image, estimated from one render."""
    m = mean.astype(np.float64)
    return variance.astype(np.float64) / (m * m + epsilon)


@dataclass(frozen=True)
class VarianceEstimate:
    """The mean of a per-pixel statistic over R independent renders and M
    pixel-channels, with its standard error."""

    value: float
    standard_error: float
    replicates: int
    pixels: int


def pooled_estimate(replicates: list[np.ndarray]) -> VarianceEstimate:
    """Mean of per-pixel values over R >= 2 renders with different seeds, and
    its standard error from the spread between the renders at each pixel.

    With w_ki the value of render k at pixel-channel i, W = mean_ki w_ki has
    Var(W) = sum_i sigma_i^2 / (R M^2), since pixels are independent and the
    renders are i.i.d. at each pixel; s_i^2 = sum_k (w_ki - mean_k w_ki)^2 / (R - 1)
    is unbiased for sigma_i^2 whatever the (heavy-tailed) distribution, and
    pixel heterogeneity does not enter it."""
    if len(replicates) < 2:
        raise ValueError("the standard error needs at least two renders with different seeds")
    w = np.stack([np.asarray(r, dtype=np.float64).reshape(-1) for r in replicates])
    r_count, m_count = w.shape
    spread = np.var(w, axis=0, ddof=1)
    value = float(np.mean(w))
    se = math.sqrt(float(np.sum(spread)) / (r_count * m_count * m_count))
    return VarianceEstimate(value=value, standard_error=se, replicates=r_count, pixels=m_count)


def regression_z(current: VarianceEstimate, baseline: VarianceEstimate) -> float:
    """z of the rise of `current` over `baseline`: two independent estimates,
    each approximately normal (central limit theorem over M pixels)."""
    se = math.hypot(current.standard_error, baseline.standard_error)
    if se == 0:
        return 0.0 if current.value == baseline.value else math.copysign(math.inf, current.value - baseline.value)
    return (current.value - baseline.value) / se


def ratio_bound(current: VarianceEstimate, baseline: VarianceEstimate, z_max: float) -> float:
    """The largest ratio current/baseline that still passes at z_max."""
    if baseline.value <= 0:
        return math.inf
    return 1.0 + z_max * math.hypot(current.standard_error, baseline.standard_error) / baseline.value
