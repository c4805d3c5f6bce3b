"""metrics.py against hand-computed values, and the regression statistic's
calibration on synthetic data."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from portal_harness.core import exr, metrics
from portal_harness.core.metrics import Region, VarianceEstimate


def _images() -> tuple[np.ndarray, np.ndarray]:
    # 2x2 pixels, 3 channels; differences chosen to be easy by hand.
    ref = np.array([[[1.0, 0.0, 2.0], [0.5, 0.5, 0.5]], [[0.0, 0.0, 0.0], [3.0, 1.0, 0.1]]])
    img = ref.copy()
    img[0, 0] = (2.0, 0.1, 2.0)  # diffs 1, 0.1, 0
    img[1, 1] = (3.0, 0.0, 0.1)  # diffs 0, -1, 0
    return img, ref


def test_01_mse_by_hand() -> None:
    img, ref = _images()
    # squares: 1 + 0.01 + 1 = 2.01 over 12 values
    assert metrics.mse(img, ref) == pytest.approx(2.01 / 12, rel=1e-12)


def test_02_rel_mse_by_hand() -> None:
    img, ref = _images()
    # 1/(1+0.01) + 0.01/(0+0.01) + 1/(1+0.01) over 12
    expected = (1 / 1.01 + 1.0 + 1 / 1.01) / 12
    assert metrics.rel_mse(img, ref) == pytest.approx(expected, rel=1e-12)


def test_03_region_metrics_by_hand() -> None:
    img, ref = _images()
    top_left = Region("tl", x=0, y=0, width=1, height=1)
    assert metrics.mse(img, ref, top_left) == pytest.approx(1.01 / 3, rel=1e-12)
    assert metrics.rel_mse(img, ref, top_left) == pytest.approx((1 / 1.01 + 1.0) / 3, rel=1e-12)
    bottom_row = Region("b", x=0, y=1, width=2, height=1)
    assert metrics.mse(img, ref, bottom_row) == pytest.approx(1.0 / 6, rel=1e-12)
    with pytest.raises(ValueError):
        metrics.mse(img, ref, Region("out", x=1, y=1, width=2, height=1))


def test_04_metrics_of_synthetic_exrs(tmp_path: Path, write_exr: Callable[..., None]) -> None:
    img, ref = _images()
    write_exr(tmp_path / "img.exr", img, np.zeros_like(img))
    write_exr(tmp_path / "ref.exr", ref, np.full_like(ref, 0.02))
    a, b = exr.read_snapshot(tmp_path / "img.exr"), exr.read_snapshot(tmp_path / "ref.exr")
    # float32 storage: 0.1 is not exact, hence the tolerance.
    assert metrics.mse(a.rgb, b.rgb) == pytest.approx(2.01 / 12, rel=1e-6)
    # floor: mean of 0.02 / (r^2 + 0.01)
    r = ref.astype(np.float32).astype(np.float64)
    assert metrics.rel_variance_floor(b.rgb, b.variance) == pytest.approx(
        float(np.mean(0.02 / (r * r + 0.01))), rel=1e-6
    )


def test_05_efficiency() -> None:
    assert metrics.efficiency(0.01, 4.0) == pytest.approx(25.0)
    assert metrics.efficiency(0.0, 1.0) == math.inf
    assert math.isnan(metrics.efficiency(0.1, 0.0))
    assert math.isnan(metrics.efficiency(float("nan"), 1.0))


def test_06_pooled_estimate_by_hand() -> None:
    a = np.array([1.0, 2.0, 3.0, 4.0])
    b = np.array([3.0, 2.0, 1.0, 4.0])
    est = metrics.pooled_estimate([a, b])
    assert est.value == pytest.approx(2.5)
    # per-pixel sample variances (ddof 1): 2, 0, 2, 0 -> SE^2 = 4 / (2 * 16)
    assert est.standard_error == pytest.approx(math.sqrt(4 / 32))
    with pytest.raises(ValueError):
        metrics.pooled_estimate([a])


def _renders(rng: np.random.Generator, true_var: np.ndarray, spp: int, seeds: int) -> list[np.ndarray]:
    """Per-pixel variance-of-the-mean estimates of `seeds` renders with spp
    exponential (heavy-ish tailed) samples per pixel."""
    out = []
    for _ in range(seeds):
        samples = rng.exponential(np.sqrt(true_var)[None, :], size=(spp, true_var.size))
        out.append(samples.var(axis=0, ddof=1) / spp)
    return out


def test_07_regression_z_is_calibrated_under_no_change(rng: np.random.Generator) -> None:
    # Heterogeneous pixels (a factor 1000 between them), as in a real image.
    true_var = np.exp(rng.uniform(-3.5, 3.5, size=2000))
    zs = []
    for _ in range(150):
        base = metrics.pooled_estimate(_renders(rng, true_var, 8, 2))
        cur = metrics.pooled_estimate(_renders(rng, true_var, 8, 2))
        zs.append(metrics.regression_z(cur, base))
    zs_a = np.asarray(zs)
    # z is approximately standard normal: its spread is about 1 (150 draws:
    # the sample sd lies within 0.75-1.3 with overwhelming probability).
    assert abs(float(np.mean(zs_a))) < 0.4
    assert 0.75 < float(np.std(zs_a)) < 1.3
    assert float(np.max(np.abs(zs_a))) < 4.5


def test_08_regression_z_detects_halved_samples(rng: np.random.Generator) -> None:
    true_var = np.exp(rng.uniform(-3.5, 3.5, size=2000))
    base = metrics.pooled_estimate(_renders(rng, true_var, 16, 2))
    worse = metrics.pooled_estimate(_renders(rng, true_var, 8, 2))
    assert worse.value / base.value == pytest.approx(2.0, rel=0.3)
    assert metrics.regression_z(worse, base) > 4.0
    assert metrics.ratio_bound(worse, base, 4.0) < 1.6


def test_09_identical_estimates_give_zero() -> None:
    e = VarianceEstimate(1.0, 0.0, 2, 10)
    assert metrics.regression_z(e, e) == 0.0
    assert metrics.regression_z(VarianceEstimate(2.0, 0.0, 2, 10), e) == math.inf


def test_10_relative_variance() -> None:
    mean = np.array([[[0.0, 1.0, 2.0]]])
    var = np.array([[[0.01, 0.02, 0.04]]])
    np.testing.assert_allclose(metrics.relative_variance(mean, var), [[[1.0, 0.02 / 1.01, 0.04 / 4.01]]])
