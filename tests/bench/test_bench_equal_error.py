"""The bench's equal-time comparison with Mitsuba (renderer/bench/
equal_error.py, and the pass images of renderer/bench/mitsuba_time.py):
speed-ups from errors against one reference, their bounds, and the check
that a renderer's error is its noise. Synthetic images with known
variances stand in for the renders."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))  # repo_paths.py
from repo_paths import REPO

sys.path.insert(0, str(REPO / "renderer" / "bench"))

from benchlib import rel_error
from equal_error import consistent, over_rounds, speedup
from mitsuba_time import PassImages, parse_args

SHAPE = (256, 256, 3)


def reference(rng: np.random.Generator) -> np.ndarray:
    """A positive image with structure (what a lampshade render looks like to
    relMSE: values from 0.01 to 2)."""
    return np.exp(rng.uniform(np.log(0.01), np.log(2.0), SHAPE))


def render(rng: np.random.Generator, ref: np.ndarray, sigma: float, bias: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """An image with Gaussian noise of relative standard deviation sigma
    (and a relative bias), and its own exact variance layer."""
    sd = sigma * ref
    return ref * (1.0 + bias) + rng.normal(0.0, 1.0, SHAPE) * sd, sd * sd


def err(e: float, se: float) -> dict[str, float]:
    return {"rel_mse_est": e, "rel_mse_est_se": se}


def test_speedup_is_the_ratio_of_error_times_time() -> None:
    s = speedup(err(1e-5, 1e-7), 4.0, err(3e-5, 1e-7), 2.0)
    assert s["ratio"] == pytest.approx(1.5)
    assert s["low"] < 1.5 < s["high"]
    assert s["resolved"]
    # Twice the time for half the error is the same efficiency.
    assert speedup(err(1e-5, 0), 2.0, err(2e-5, 0), 1.0)["ratio"] == pytest.approx(1.0)


def test_unresolved_error_gives_only_a_lower_bound() -> None:
    # Ours is within two standard errors of zero: the reference cannot see it.
    s = speedup(err(1e-7, 1e-7), 1.0, err(1e-5, 1e-7), 1.0)
    assert not s["resolved"]
    assert s["high"] == math.inf
    assert s["low"] == pytest.approx((1e-5 - 2e-7) / 3e-7)
    # A zero or negative estimate: infinite ratio, finite bound.
    z = speedup(err(-1e-8, 1e-7), 1.0, err(1e-5, 1e-7), 1.0)
    assert z["ratio"] == math.inf and math.isfinite(z["low"]) and not z["resolved"]


def test_speedup_refuses_non_positive_times() -> None:
    with pytest.raises(ValueError):
        speedup(err(1e-5, 0), 0.0, err(1e-5, 0), 1.0)
    with pytest.raises(ValueError):
        speedup(err(1e-5, 0), 1.0, err(1e-5, 0), math.nan)


def test_over_rounds() -> None:
    rounds = [
        {"ratio": 2.0, "low": 1.8, "resolved": True},
        {"ratio": 3.0, "low": 2.5, "resolved": True},
        {"ratio": 2.5, "low": 1.5, "resolved": False},
    ]
    r = over_rounds(rounds)
    assert (r["median"], r["min"], r["max"], r["low"], r["resolved"], r["n"]) == (2.5, 2.0, 3.0, 1.5, False, 3)
    with pytest.raises(ValueError):
        over_rounds([])


def test_speedup_of_synthetic_renders_matches_their_variances() -> None:
    """Two unbiased 'renderers' with relative noise 0.02 and 0.05 over 1 and
    2 seconds: the speed-up of the first is (0.05^2 x 2) / (0.02^2 x 1) =
    12.5. Each relMSE estimate over 196,608 values has a relative standard
    error of about sqrt(2 / 196608) = 0.32%, the ratio 0.45%; 5 sigma is
    2.3%."""
    rng = np.random.default_rng(17)
    ref = reference(rng)
    ref_var = np.zeros(SHAPE)
    a = rel_error(*render(rng, ref, 0.02), ref, ref_var)
    b = rel_error(*render(rng, ref, 0.05), ref, ref_var)
    s = speedup(a, 1.0, b, 2.0)
    assert s["resolved"]
    assert s["ratio"] == pytest.approx(12.5, rel=0.023)
    assert s["low"] <= 12.5 <= s["high"]
    assert consistent(a) and consistent(b)


def test_reference_noise_is_removed() -> None:
    """A noisy reference (relative noise 0.03, its variance layer exact):
    rel_mse_est of a render with relative noise 0.02 is still 0.02^2 x
    mean(ref^2 / (ref^2 + 0.01)), within 5 standard errors."""
    rng = np.random.default_rng(5)
    truth = reference(rng)
    ref, ref_var = render(rng, truth, 0.03)
    x, x_var = render(rng, truth, 0.02)
    e = rel_error(x, x_var, ref, ref_var)
    expected = float(np.mean(0.02**2 * truth**2 / (ref * ref + 0.01)))
    assert abs(e["rel_mse_est"] - expected) < 5 * e["rel_mse_est_se"]
    assert consistent(e)


def test_a_biased_render_is_not_consistent() -> None:
    """A render 1% too bright with 1% noise: its error is mostly bias, which
    its own variance does not predict."""
    rng = np.random.default_rng(9)
    ref = reference(rng)
    e = rel_error(*render(rng, ref, 0.01, bias=0.01), ref, np.zeros(SHAPE))
    assert e["bias_z"] > 4
    assert not consistent(e)
    assert not consistent({"bias_z": math.nan})


def test_pass_images_mean_and_variance_of_the_mean(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    passes = [rng.normal(1.0, 0.1, (4, 5, 3)) for _ in range(7)]
    acc = PassImages()
    for p in passes:
        acc.add(p)
    stack = np.stack(passes)
    assert acc.n == 7
    np.testing.assert_allclose(acc.mean, stack.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(acc.var_of_mean(), stack.var(axis=0, ddof=1) / 7, rtol=1e-10)
    out = tmp_path / "m.npz"
    acc.save(out)
    with np.load(out) as saved:
        np.testing.assert_array_equal(saved["mean"], acc.mean)
        assert int(saved["passes"]) == 7
    assert not list(tmp_path.glob("*.tmp*"))


def test_pass_images_need_two_passes() -> None:
    acc = PassImages()
    acc.add(np.ones((2, 2, 3)))
    with pytest.raises(ValueError):
        acc.var_of_mean()


@pytest.mark.parametrize("bad", [["--steady-time", "-1"], ["--steady-time", "nan"], ["--steady-time", "1e9"]])
def test_mitsuba_time_refuses_bad_steady_time(bad: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        parse_args(["scene.yaml", "--integrator", "direct", "--spp", "4", "--passes", "2", *bad])
    assert e.value.code == 2
    assert "--steady-time must be between 0 and 3600 s" in capsys.readouterr().err
