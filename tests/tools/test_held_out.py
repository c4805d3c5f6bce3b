"""The held-out Mitsuba scene (tools/held_out/make_scene.py; issues 39 and 40):
a room lit by a desk lamp in a cone-frustum housing and a wall sconce in a
box housing, their meshes in one `serialized` file. Generated into tmp,
imported with `portal-harness import-mitsuba` (`portals: auto`, nothing
written by hand), then, in the real renderer:

- `--print-config` finds portals for both lamps, complete on its escaping
  rays (0 missed, the 3/N bound), the sconce's tight (its two openings);
- `light` and `antishadow_exact` with auto portals (direct, `defensive: 0`,
  `mis: none`: no BSDF technique that a gap could hide behind; independent
  seeds) agree block by block: max |z| under the two-sided Bonferroni bound
  for ALPHA over all block-channel tests, as tools/crosscheck does;
- the gain: antishadow_exact's shadow rays are blocked less often than
  light's (counters of the render's final JSON event);
- negative control: the found portals frozen into the config with one
  removed (the sconce's lower opening) make the same z-test fail.

What the finder returns for the desk lamp's frustum today: its bottom
opening, plus sliver portals on the housing's sides below the light's
plane (the tessellated frustum's quads are planar only up to float32
rounding, so hull facets and triangles do not match exactly). Those are
complete but blocked by the housing itself, which is why its blocked
fraction is far from the sconce's 0; the test records it without asserting
a tightness that the finder does not have yet."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))  # repo_paths.py
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools" / "crosscheck"))
from mitsuba_lampshade import block_mean, normal_two_sided_quantile
from repo_paths import REPO, real_renderer_fixture  # noqa: F401 (pytest finds it as `real_renderer`)

from portal_harness.core import exr

GENERATOR = REPO / "tools" / "held_out" / "make_scene.py"
LAMPS = ("desk_bulb", "sconce_bulb")
WIDTH, HEIGHT, SPP, BLOCK = 64, 48, 128, 4
ALPHA = 1e-3  # overall false-alarm rate of the z-test, as tools/crosscheck's default
FLOAT_REL_TOL = 1e-5  # float32 rounding of equal noiseless blocks (tools/crosscheck)
RENDER_SETS = [
    f"film.width={WIDTH}",
    f"film.height={HEIGHT}",
    "render.integrator=direct",
    "render.mis=none",
    "render.defensive=0",
]


def run(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    out = subprocess.run(args, capture_output=True, text=True, cwd=cwd)
    assert out.returncode == 0, f"{' '.join(args)} failed ({out.returncode}):\n{out.stderr}"
    return out


def render(renderer: Path, scene: Path, out: Path, strategy: str, seed: int) -> tuple[exr.Snapshot, dict[str, Any]]:
    args = [str(renderer), str(scene), "--strategy", strategy, "--spp", str(SPP), "--out", str(out)]
    args += ["--threads", "2", "--quiet", "--set", f"render.seed={seed}"]
    for s in RENDER_SETS:
        args += ["--set", s]
    final = json.loads(run(args, scene.parent).stdout.splitlines()[-1])
    assert final["event"] == "final" and final["spp"] == SPP and final["nonfinite"] == 0
    return exr.read_snapshot(out / "final.exr"), final


def block_z(a: exr.Snapshot, b: exr.Snapshot) -> tuple[float, float, int]:
    """max |z| over BLOCK x BLOCK blocks and the three channels, the Bonferroni
    bound for ALPHA over that many tests, and the number of tests."""
    ma, mb = block_mean(a.rgb, BLOCK), block_mean(b.rgb, BLOCK)
    var = (block_mean(a.variance, BLOCK) + block_mean(b.variance, BLOCK)) / (BLOCK * BLOCK)
    var = var + (FLOAT_REL_TOL * np.maximum(np.abs(ma), np.abs(mb))) ** 2
    diff = ma - mb
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(var > 0, diff / np.sqrt(np.where(var > 0, var, 1.0)), np.where(diff == 0, 0.0, np.inf))
    return float(np.abs(z).max()), normal_two_sided_quantile(ALPHA / z.size), int(z.size)


def blocked(final: dict[str, Any]) -> float:
    return float(final["shadow_blocked"]) / float(final["shadow_rays"])


@pytest.mark.real
def test_held_out_scene_imports_with_auto_portals_and_renders_unbiased(real_renderer: Path, tmp_path: Path) -> None:
    run([sys.executable, str(GENERATOR), str(tmp_path / "xml")], REPO)
    xml = tmp_path / "xml" / "scene.xml"
    run([sys.executable, "-m", "portal_harness", "import-mitsuba", str(xml), "--out", str(tmp_path / "imp")], REPO)
    scene = tmp_path / "imp" / "scene.yaml"
    text = scene.read_text()
    assert "\nportals: auto\n" in text and "shape_index: 2" in text

    # The finder, as --print-config reports it.
    doc = json.loads(run([str(real_renderer), "--print-config", str(scene), "--format", "json"], tmp_path).stdout)
    found = doc["auto_portals"]
    assert sorted(found) == sorted(LAMPS)
    for name in LAMPS:
        f = found[name]
        print(
            f"{name}: {f['n_portals']} portal(s), area {f['area']:.6f} of hull {f['hull_area']:.6f}, "
            f"blocked {f['blocked_fraction']:.4f}, bound {f['bound']:.3g} "
            f"({f['n_escaped']} of {f['n_rays']} rays escaped, {f['n_missed']} missed)"
        )
        assert f["enclosed"] and not f["warning"], f["note"]
        assert f["n_portals"] == len(f["portals"]) >= 1
        assert f["n_missed"] == 0 and f["n_escaped"] > 10_000 and f["bound"] == pytest.approx(3 / f["n_escaped"])
    # The sconce's box: exactly its two openings, (0.2 - 2 t) x (0.3 - 2 t) each, nothing blocked.
    sconce = found["sconce_bulb"]
    assert sconce["n_portals"] == 2 and sconce["blocked_fraction"] < 0.01
    assert sconce["area"] == pytest.approx(2 * 0.18 * 0.28, rel=1e-4)
    # The desk lamp: its bottom opening (an inner 24-gon of radius 0.17) is among the portals.
    desk = found["desk_bulb"]
    assert desk["area"] >= 0.99 * 24 / 2 * 0.17**2 * np.sin(2 * np.pi / 24)

    # Unbiased: light against antishadow_exact with the auto portals.
    light, light_final = render(real_renderer, scene, tmp_path / "light", "light", seed=11)
    exact, exact_final = render(real_renderer, scene, tmp_path / "exact", "antishadow_exact", seed=12)
    assert light.rgb.mean() > 0 and exact.rgb.mean() > 0
    max_z, bound, tests = block_z(light, exact)
    print(f"light vs antishadow_exact (auto): max |z| {max_z:.3f}, bound {bound:.3f} over {tests} tests")
    assert max_z < bound

    # The gain: fewer blocked shadow rays, more that reach a lamp.
    b_light, b_exact = blocked(light_final), blocked(exact_final)
    useful = (1 - b_exact) / (1 - b_light)
    print(f"blocked shadow rays: light {b_light:.4f}, antishadow_exact {b_exact:.4f}; unblocked x{useful:.2f}")
    assert b_exact < b_light and useful > 1.5

    # Negative control: the portals frozen, the sconce's lower opening removed.
    portals = [p for name in LAMPS for p in found[name]["portals"]]
    lower = min(sconce["portals"], key=lambda p: max(v[1] for v in p["vertices"]))
    kept = [p for p in portals if p["name"] != lower["name"]]
    assert len(kept) == len(portals) - 1
    gap = scene.with_name("gap.yaml")
    gap.write_text(text.replace("\nportals: auto\n", "\nportals: " + json.dumps(kept) + "\n"))
    holed, _ = render(real_renderer, gap, tmp_path / "gap", "antishadow_exact", seed=12)
    gap_z, gap_bound, _ = block_z(light, holed)
    print(f"light vs antishadow_exact without {lower['name']}: max |z| {gap_z:.3f}, bound {gap_bound:.3f}")
    assert gap_z > gap_bound
