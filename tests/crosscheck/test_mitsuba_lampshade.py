"""Tests of the Mitsuba 3 cross-check (tools/crosscheck/mitsuba_lampshade.py).

Not part of the default test run (`make test` runs tests/harness only). The
statistic tests need numpy alone; the conversion and end-to-end tests need a
python that imports mitsuba (this one, or .venv-xcheck's) and are skipped
without it; the end-to-end test also needs our render binary.

    .venv-xcheck/bin/python -m pytest -q tests/crosscheck
"""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:  # annotations only: without numpy the statistic tests are skipped
    import numpy

np = pytest.importorskip("numpy")

REPO = Path(__file__).resolve().parents[2]
TOOL_DIR = REPO / "tools" / "crosscheck"
SCRIPT = TOOL_DIR / "mitsuba_lampshade.py"
sys.path.insert(0, str(TOOL_DIR))

import mitsuba_lampshade as xcheck  # noqa: E402  (stdlib-only at import time)

SEED = 20240611


def mitsuba_python() -> str | None:
    """An interpreter that can import mitsuba, or None."""
    if importlib.util.find_spec("mitsuba") is not None:
        return sys.executable
    venv = REPO / ".venv-xcheck" / "bin" / "python"
    if venv.exists():
        ok = subprocess.run(
            [str(venv), "-c", "import mitsuba, OpenEXR, yaml, portal_harness.core.exr"], capture_output=True
        )
        if ok.returncode == 0:
            return str(venv)
    return None


def renderer() -> Path | None:
    for build in ("build",):
        p = REPO / "renderer" / build / "render"
        if p.exists():
            return p
    return None


needs_mitsuba = pytest.mark.skipif(
    mitsuba_python() is None, reason="mitsuba is not importable (create .venv-xcheck: see tools/crosscheck/README.md)"
)


# --- 1. The statistic ------------------------------------------------------


def synthetic(rng: numpy.random.Generator, bias: float) -> tuple[numpy.ndarray, numpy.ndarray, numpy.ndarray]:
    """Ours: one image with known per-pixel variance; Mitsuba: K runs."""
    h = w = 64
    k = 16
    truth = rng.uniform(0.1, 1.0, size=(h, w, 3))
    sigma_ours = 0.05 * truth  # standard error of our pixel mean
    sigma_run = 0.2 * truth  # standard error of one Mitsuba run
    ours = truth * (1.0 + bias) + sigma_ours * rng.standard_normal(truth.shape)
    runs = truth + sigma_run * rng.standard_normal((k, *truth.shape))
    return ours, sigma_ours**2, runs


def test_1_bound_is_the_bonferroni_quantile() -> None:
    # P(|Z| > 3) = 0.0027 and the bound for 3072 tests at alpha 1e-3.
    assert xcheck.normal_two_sided_quantile(math.erfc(3 / math.sqrt(2))) == pytest.approx(3.0, abs=1e-9)
    b = xcheck.normal_two_sided_quantile(1e-3 / 3072)
    assert math.erfc(b / math.sqrt(2)) == pytest.approx(1e-3 / 3072, rel=1e-9)
    assert 5.0 < b < 5.2


def test_2_unbiased_images_agree_and_z_is_standard_normal() -> None:
    rng = np.random.default_rng(SEED)
    ours, var, runs = synthetic(rng, 0.0)
    s = xcheck.compare(ours, var, runs, 8, 1e-3)["stats"]
    assert s["max_abs_z"] <= s["bound"]
    # 192 tests: mean z^2 has standard deviation sqrt(2/192) = 0.10.
    assert abs(s["mean_z2"] - 1.0) < 0.5
    for r, e in zip(s["mean_ratio_ours_over_mitsuba"], s["mean_ratio_sigma"], strict=True):
        assert abs(r - 1.0) < 5 * e


def test_3_a_two_percent_bias_is_detected() -> None:
    # Block sigma: sqrt(0.05^2 + 0.2^2 / 16) truth / 8 = 0.0088 truth, so a
    # 10% bias shifts every block by ~11 sigma: the block test must fail. A 2%
    # bias (~2.3 sigma per block) is too small for the block test but the
    # whole-image ratio (sigma ~0.0007) must see it at > 5 sigma.
    rng = np.random.default_rng(SEED + 1)
    ours, var, runs = synthetic(rng, 0.10)
    s = xcheck.compare(ours, var, runs, 8, 1e-3)["stats"]
    assert s["max_abs_z"] > s["bound"]
    ours, var, runs = synthetic(np.random.default_rng(SEED + 2), 0.02)
    s = xcheck.compare(ours, var, runs, 8, 1e-3)["stats"]
    assert all(
        abs(r - 1.02) < 5 * e for r, e in zip(s["mean_ratio_ours_over_mitsuba"], s["mean_ratio_sigma"], strict=True)
    )
    assert all(r - 1.0 > 5 * e for r, e in zip(s["mean_ratio_ours_over_mitsuba"], s["mean_ratio_sigma"], strict=True))


def test_4_noiseless_blocks_tolerate_float_rounding_only() -> None:
    rng = np.random.default_rng(SEED + 3)
    ours, var, runs = synthetic(rng, 0.0)
    # Block (0, 0) black in both, block (0, 1) a noiseless emitter whose two
    # float32 renderings differ by 3e-7 relative (as measured).
    ours[:8, :8] = 0.0
    var[:8, :8] = 0.0
    runs[:, :8, :8] = 0.0
    ours[:8, 8:16] = 27.777779
    var[:8, 8:16] = 0.0
    runs[:, :8, 8:16] = 27.777779 * (1 + 3e-7)
    s = xcheck.compare(ours, var, runs, 8, 1e-3)
    assert np.all(s["z"][0, 0] == 0.0)
    assert np.all(np.abs(s["z"][0, 1]) < 0.1)
    assert s["stats"]["max_abs_z"] <= s["stats"]["bound"]
    # A 1e-3 difference there is a real bias: far beyond the bound.
    ours[:8, 8:16] *= 1.001
    s = xcheck.compare(ours, var, runs, 8, 1e-3)
    assert np.all(np.abs(s["z"][0, 1]) > 50)
    # Light where the other renderer has none and neither has noise.
    ours[:8, 8:16] /= 1.001
    ours[0, 0, 0] = 1e-3
    s = xcheck.compare(ours, var, runs, 8, 1e-3)
    assert abs(s["z"][0, 0, 0]) > 1e4
    assert np.all(s["z"][0, 0, 1:] == 0.0)


# --- 2. The conversion (needs mitsuba) --------------------------------------

PROBE = r"""
import json, sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import mitsuba as mi
mi.set_variant("scalar_rgb")
import mitsuba_lampshade as xcheck

# Our light: counter-clockwise seen from below, so it emits towards -y.
cfg = {
    "camera": {"position": [0, 2, 8], "look_at": [0, 1.5, 0], "up": [0, 1, 0], "fov_y": 45},
    "film": {"width": 4, "height": 4},
    "materials": {},
    "shapes": [],
    "lights": [{"name": "lamp", "two_sided": False, "radiance": [1.0, 2.0, 3.0],
                "vertices": [[-0.3, 2.6, -0.3], [0.3, 2.6, -0.3], [0.3, 2.6, 0.3], [-0.3, 2.6, 0.3]]}],
}
scene = mi.load_dict(xcheck.build_scene_dict(cfg, {"type": "direct"}, Path(sys.argv[2]), 1))
out = {}
for name, o, d in (("from_below", [0.1, 2.0, 0.05], [0, 1, 0]), ("from_above", [0.1, 3.0, 0.05], [0, -1, 0])):
    si = scene.ray_intersect(mi.Ray3f(o, d))
    em = si.emitter(scene)
    le = em.eval(si)
    ctx = mi.BSDFContext()
    f = si.bsdf().eval(ctx, si, si.to_local(mi.Vector3f(0.3, -0.9 if d[1] > 0 else 0.9, 0.1)))
    out[name] = {"t": float(si.t), "le": [float(x) for x in le], "f": [float(x) for x in f]}
print(json.dumps(out))
"""


@needs_mitsuba
def test_5_light_emits_towards_our_normal_and_reflects_nothing(tmp_path: Path) -> None:
    python = mitsuba_python()
    assert python is not None  # needs_mitsuba
    proc = subprocess.run(
        [python, "-c", PROBE, str(TOOL_DIR), str(tmp_path)], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["from_below"]["t"] == pytest.approx(0.6, abs=1e-5)
    assert out["from_below"]["le"] == pytest.approx([1.0, 2.0, 3.0], rel=1e-6)
    assert out["from_above"]["t"] == pytest.approx(0.4, abs=1e-5)
    assert out["from_above"]["le"] == pytest.approx([0.0, 0.0, 0.0], abs=0)
    assert out["from_below"]["f"] == [0.0, 0.0, 0.0]
    assert out["from_above"]["f"] == [0.0, 0.0, 0.0]


# --- 3. End to end, small (needs mitsuba and our renderer) ------------------


@needs_mitsuba
@pytest.mark.skipif(renderer() is None, reason="our render binary is not built")
def test_6_small_direct_render_agrees_with_mitsuba(tmp_path: Path) -> None:
    # 64 x 64, 256 spp each: 64 blocks x 3 channels; a few seconds each.
    python = mitsuba_python()
    assert python is not None  # needs_mitsuba
    cmd = [
        python,
        str(SCRIPT),
        "--renderer",
        str(renderer()),
        "--integrator",
        "direct",
        "--ours-spp",
        "256",
        "--mitsuba-spp",
        "256",
        "--mitsuba-runs",
        "16",
        "--set",
        "film.width=64",
        "--set",
        "film.height=64",
        "--out",
        str(tmp_path),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode in (0, 1), proc.stderr
    s = json.loads((tmp_path / "summary.json").read_text())["stats"]
    assert s["tests"] == 192
    assert proc.returncode == 0, proc.stdout
    for r, e in zip(s["mean_ratio_ours_over_mitsuba"], s["mean_ratio_sigma"], strict=True):
        assert abs(r - 1.0) < 5 * e


def test_7_a_block_without_hits_tolerates_a_few_hits_worth_only() -> None:
    # Mitsuba found no light in block (0, 0) (a thin penumbra sliver it never
    # hit); ours found a little with a tiny variance. With the spp known, the
    # zero side gets one hit's variance, (h / N)^2 with h ~ 1 and N = 64 * 256.
    rng = np.random.default_rng(SEED + 4)
    ours, var, runs = synthetic(rng, 0.0)
    runs[:, :8, :8] = 0.0
    ours[:8, :8] = 0.0
    ours[0, 0] = 64 * 2.0 / (64 * 256)  # block mean: 2 hits' worth
    var[:8, :8] = 0.0
    var[0, 0] = (ours[0, 0] / 100) ** 2
    without = xcheck.compare(ours, var, runs, 8, 1e-3)["stats"]
    assert without["max_abs_z"] > 50  # the zero variance is not credible
    s = xcheck.compare(ours, var, runs, 8, 1e-3, ours_spp=256, mits_spp=256)["stats"]
    assert s["zero_hit_tests"] == 3
    assert s["max_abs_z"] <= s["bound"]
    # Fifty hits' worth is light the other renderer could not have missed.
    ours[0, 0] *= 25
    s = xcheck.compare(ours, var, runs, 8, 1e-3, ours_spp=256, mits_spp=256)["stats"]
    assert s["max_abs_z"] > s["bound"]
