"""The closed form of the lampshade floor (tools/closed_form): its maths on
its own, the conservativeness of its mask by brute force, and (marked
`real`) a render of the real renderer against it, which must agree within
5 standard errors of the mean while a model 2% too bright must not."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))  # repo_paths.py
from repo_paths import REPO, real_renderer_fixture  # noqa: F401 (pytest finds it as `real_renderer`)

sys.path.insert(0, str(REPO / "tools" / "closed_form"))

from floor_check import closed_form_for, compare, load_config
from floor_model import (
    BOX_MAX,
    BOX_MIN,
    LIGHT_Y,
    PORTAL_Y,
    Camera,
    LampshadeModel,
    frustum_meets_box,
    projected_solid_angle_rect,
)

from portal_harness.core import exr

SCENE = REPO / "configs" / "scenes" / "lampshade.yaml"
SIZE = 48
# Pixels of the 48x48 mask at s_L = 0.6 (pinned: a change of the mask's
# geometry or of the camera shows here).
MASK_PIXELS_48 = 428


def _config(s_light: float, size: int) -> dict[str, Any]:
    """The effective config of the lampshade, as a render writes it (only the keys the model reads)."""
    a, h = max(s_light, 0.3) / 2 + 0.05, 0.15

    def quad(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> list[list[float]]:
        return [list(lo), list(hi), list(hi), list(lo)]  # only its bounds matter to the model

    shapes = {
        "floor": ((-3, 0, -3), (3, 0, 3)),
        "ceiling": ((-3, 4, -3), (3, 4, 3)),
        "back_wall": ((-3, 0, -3), (3, 4, -3)),
        "left_wall": ((-3, 0, -3), (-3, 4, 3)),
        "right_wall": ((3, 0, -3), (3, 4, 3)),
        "shade_left": ((-a, 2.2, -a), (-a, 2.65, a)),
        "shade_right": ((a, 2.2, -a), (a, 2.65, a)),
        "shade_back": ((-a, 2.2, -a), (a, 2.65, -a)),
        "shade_front": ((-a, 2.2, a), (a, 2.65, a)),
        "shade_top": ((-a, 2.65, -a), (a, 2.65, a)),
        "shade_bottom_back": ((-a, 2.2, -a), (a, 2.2, -h)),
        "shade_bottom_front": ((-a, 2.2, h), (a, 2.2, a)),
        "shade_bottom_left": ((-a, 2.2, -h), (-h, 2.2, h)),
        "shade_bottom_right": ((h, 2.2, -h), (a, 2.2, h)),
    }
    s = s_light / 2
    return {
        "camera": {"position": [0, 2, 8], "look_at": [0, 1.5, 0], "up": [0, 1, 0], "fov_y": 45},
        "film": {"width": size, "height": size},
        "materials": {"white": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
        "shapes": [{"name": n, "material": "white", "vertices": quad(lo, hi)} for n, (lo, hi) in shapes.items()]
        + [{"name": "box", "type": "box", "material": "white", "min": list(BOX_MIN), "max": list(BOX_MAX)}],
        "lights": [
            {
                "name": "lamp",
                "two_sided": False,
                "vertices": [[-s, 2.6, -s], [s, 2.6, -s], [s, 2.6, s], [-s, 2.6, s]],
                "radiance": [c * (0.5 / s_light) ** 2 for c in (40, 34, 24)],
            }
        ],
        "portals": [
            {"name": "opening", "light": "lamp", "vertices": [[-h, 2.2, -h], [h, 2.2, -h], [h, 2.2, h], [-h, 2.2, h]]}
        ],
        "render": {"integrator": "direct"},
    }


def test_lambert_rectangle_against_the_corner_form_factor() -> None:
    """Lambert's polygon formula against the classic point-to-parallel-rectangle
    form factor (sum over corners of signed corner terms), at random points."""
    rng = np.random.default_rng(3)
    px, pz = rng.uniform(-2, 2, 50), rng.uniform(-2, 2, 50)
    x0, z0 = rng.uniform(-0.5, 0.0, 50), rng.uniform(-0.5, 0.0, 50)
    x1, z1 = x0 + rng.uniform(0.01, 1, 50), z0 + rng.uniform(0.01, 1, 50)
    h = PORTAL_Y

    def corner(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        # pi x the form factor of [0, a] x [0, b] seen from below its corner at height h
        ra, rb = np.hypot(a, h), np.hypot(b, h)
        value: np.ndarray = 0.5 * (a / ra * np.arctan(b / ra) + b / rb * np.arctan(a / rb))
        return value

    u0, u1, w0, w1 = x0 - px, x1 - px, z0 - pz, z1 - pz
    exact = corner(u1, w1) - corner(u0, w1) - corner(u1, w0) + corner(u0, w0)
    got = projected_solid_angle_rect(px, pz, x0, x1, z0, z1, h)
    np.testing.assert_allclose(got, exact, rtol=1e-10, atol=1e-14)
    assert projected_solid_angle_rect(
        np.array(0.0), np.array(0.0), np.array(-1e5), np.array(1e5), np.array(-1e5), np.array(1e5), h
    ) == pytest.approx(math.pi, rel=1e-4)
    assert (
        projected_solid_angle_rect(
            np.array(0.0), np.array(0.0), np.array(0.1), np.array(0.1), np.array(0.0), np.array(1.0), h
        )
        == 0.0
    )


def test_visible_rectangle_by_brute_force() -> None:
    """E_geom against Monte Carlo over the light with the portal as a stencil."""
    model = LampshadeModel.from_config(_config(0.6, 8))
    rng = np.random.default_rng(5)
    k = PORTAL_Y / LIGHT_Y
    for p in [(0.0, 0.0), (-0.3, 0.2), (-1.0, 0.4), (0.3, -2.0), (1.9, 0.1)]:
        q = (rng.random((400_000, 2)) - 0.5) * model.s_light
        through = np.all(np.abs(np.array(p) * (1 - k) + q * k) <= model.s_portal / 2, axis=1)
        d2 = (q[:, 0] - p[0]) ** 2 + (q[:, 1] - p[1]) ** 2 + LIGHT_Y**2
        samples = through * LIGHT_Y**2 / d2**2 * model.s_light**2  # cos cos / r^2 dA
        mc, se = samples.mean(), samples.std() / math.sqrt(samples.size)
        x0, x1, z0, z1 = model.visible_rectangle(np.array(p[0]), np.array(p[1]))
        exact = float(projected_solid_angle_rect(np.array(p[0]), np.array(p[1]), x0, x1, z0, z1, PORTAL_Y))
        assert abs(mc - exact) < 5 * se + 1e-12, (p, mc, se, exact)


def test_frustum_test_against_sampled_segments() -> None:
    rng = np.random.default_rng(7)
    box_lo, box_hi = np.array(BOX_MIN), np.array(BOX_MAX)
    for _ in range(300):
        a_lo = rng.uniform(-1, 2, 2)
        a_hi = a_lo + rng.uniform(0, 0.6, 2)
        b_lo = rng.uniform(-0.3, 0.3, 2)
        b_hi = b_lo + rng.uniform(0, 0.2, 2)
        meets = bool(frustum_meets_box(a_lo, a_hi, 0.0, b_lo, b_hi, PORTAL_Y, box_lo, box_hi))
        pa = a_lo + rng.random((4000, 2)) * (a_hi - a_lo)
        pb = b_lo + rng.random((4000, 2)) * (b_hi - b_lo)
        t = rng.random((4000, 1)) * (1.0 / PORTAL_Y)  # heights 0..1: the box's
        xz = pa + t * (pb - pa)
        y = t[:, 0] * PORTAL_Y
        hit = np.any(
            (xz[:, 0] >= box_lo[0])
            & (xz[:, 0] <= box_hi[0])
            & (xz[:, 1] >= box_lo[2])
            & (xz[:, 1] <= box_hi[2])
            & (y <= box_hi[1])
        )
        assert meets or not hit  # a sampled hit is always found


def test_mask_is_conservative_by_ray_sampling() -> None:
    """Random rays through masked pixels: every one reaches the floor inside
    the room past the box, and every segment from its floor point to a random
    point of its visible rectangle misses the box."""
    model = LampshadeModel.from_config(_config(1.2, 32))
    form = closed_form_for(_config(1.2, 32), 2)
    ys, xs = np.nonzero(form.mask)
    rng = np.random.default_rng(11)
    idx = rng.integers(0, ys.size, 20000)
    d = model.camera.directions(xs[idx] + rng.random(idx.size), ys[idx] + rng.random(idx.size))
    o = model.camera.origin
    t_floor = -o[1] / d[:, 1]
    p = o + t_floor[:, None] * d
    assert np.all(np.abs(p[:, [0, 2]]) < 3)
    box_lo, box_hi = np.array(BOX_MIN), np.array(BOX_MAX)

    def segment_hits_box(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        dd = b - a
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (box_lo - a) / dd, (box_hi - a) / dd
        lo = np.nanmax(np.minimum(t0, t1), axis=1)
        hi = np.nanmin(np.maximum(t0, t1), axis=1)
        hits: np.ndarray = (lo <= hi) & (hi >= 0) & (lo <= 1)
        return hits

    assert not np.any(segment_hits_box(o + 0 * p, p))
    x0, x1, z0, z1 = model.visible_rectangle(p[:, 0], p[:, 2])
    lit = (x0 < x1) & (z0 < z1)
    u, w = rng.random(p.shape[0]), rng.random(p.shape[0])
    q = np.stack([x0 + u * (x1 - x0), np.full(p.shape[0], PORTAL_Y), z0 + w * (z1 - z0)], axis=1)
    assert not np.any(segment_hits_box(p[lit], q[lit]))
    # ...and the mask is not empty next to the box's shadow: it covers most of the lit floor.
    assert lit.mean() > 0.5


def test_film_position_inverts_the_camera() -> None:
    cam = Camera.from_config(_config(0.6, 8)["camera"], 40, 30)
    d = cam.directions(np.array(12.25), np.array(7.5))
    assert cam.film_position(cam.origin + 3.0 * d) == pytest.approx((12.25, 7.5))


@pytest.mark.real
def test_render_agrees_with_the_closed_form(real_renderer: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = subprocess.run(
        [
            str(real_renderer),
            str(SCENE),
            "--set",
            "params.s_L=0.6",
            "--set",
            f"film.width={SIZE}",
            "--set",
            f"film.height={SIZE}",
            "--strategy",
            "antishadow_exact",
            "--spp",
            "400",
            "--time",
            "0",
            "--seed",
            "21",
            "--threads",
            "2",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    form = closed_form_for(load_config(out), 16)
    mask = form.mask
    assert int(mask.sum()) == MASK_PIXELS_48
    px, py = form.model.camera.film_position(np.zeros(3))  # the floor point under the lamp
    assert mask[int(py), int(px)] and form.expected[int(py), int(px), 0] > 0
    snap = exr.read_snapshot(out / "final.exr")
    right = compare(snap.rgb, snap.variance, form.expected, mask, snap.header.render_time_s)
    assert abs(right.z) < 5, right
    # The integration error of the closed form is far below the statistical error.
    assert abs(form.integration_error(mask)["mean_difference"]) < 0.05 * right.standard_error
    wrong = compare(snap.rgb, snap.variance, 1.02 * form.expected, mask, snap.header.render_time_s)
    assert abs(wrong.z) > 5, wrong
