"""Closed form of the lampshade floor under the direct integrator, per pixel.

A floor point p (y = 0, Lambertian, albedo rho) that the box does not shadow
receives light from the lamp only through the portal, so its radiance is

    L(p) = rho / pi * L_e * E_geom(p),

with E_geom(p) the projected (cosine-weighted) solid angle of the visible part
of the light: the light square projected from p onto the portal plane and
clipped to the portal. Both squares are axis-aligned and horizontal, so the
projection is an axis-aligned square and the clip an interval intersection
per axis; E_geom follows from Lambert's polygon formula.

A pixel's expected value (box filter: film position uniform in the pixel) is
the mean of L over the pixel's footprint, integrated by an n x n midpoint
grid in film coordinates. `floor_mask` selects the pixels for which this is
the whole story (see its docstring for why the test is conservative).

Everything is read from an effective config (the config.yaml of a run
folder) and checked against the canonical scene (shared/scenes/lampshade.md):
`LampshadeModel.from_config` raises ModelMismatch for any other scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

# The canonical scene (shared/scenes/lampshade.md).
ROOM_HALF = 3.0
ROOM_HEIGHT = 4.0
LIGHT_Y = 2.6
PORTAL_Y = 2.2
SHADE_TOP = 2.65
SHADE_MARGIN = 0.05
BOX_MIN = (0.5, 0.0, -0.5)
BOX_MAX = (1.5, 1.0, 0.5)
POWER_RADIANCE = (40.0, 34.0, 24.0)  # radiance = POWER_RADIANCE * (0.5 / s_L)^2
FLOOR_ALBEDO = (0.5, 0.5, 0.5)
WALLS = {  # name -> (AABB min, AABB max) of the room's other surfaces
    "ceiling": ((-3.0, 4.0, -3.0), (3.0, 4.0, 3.0)),
    "back_wall": ((-3.0, 0.0, -3.0), (3.0, 4.0, -3.0)),
    "left_wall": ((-3.0, 0.0, -3.0), (-3.0, 4.0, 3.0)),
    "right_wall": ((3.0, 0.0, -3.0), (3.0, 4.0, 3.0)),
}
SHADE_PARTS = (
    "shade_left",
    "shade_right",
    "shade_back",
    "shade_front",
    "shade_top",
    "shade_bottom_back",
    "shade_bottom_front",
    "shade_bottom_left",
    "shade_bottom_right",
)
# Geometry read from a config must match the canonical values to this.
TOLERANCE = 1e-9
# Occluders are grown by this much in the conservative tests (float safety).
GROW = 1e-6


class ModelMismatch(ValueError):
    """The config is not the canonical lampshade scene the model describes."""


@dataclass(frozen=True)
class Camera:
    """The renderer's pinhole camera (renderer/src/scene/camera.c): the direction
    through film position (px, py), in pixels, row 0 at the top, is
    normalize(top_left + px * dx + py * dy)."""

    origin: np.ndarray
    top_left: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    width: int
    height: int

    @staticmethod
    def from_config(camera: dict[str, Any], width: int, height: int) -> Camera:
        position = np.asarray(camera["position"], dtype=np.float64)
        look_at = np.asarray(camera["look_at"], dtype=np.float64)
        up = np.asarray(camera["up"], dtype=np.float64)
        forward = _normalize(look_at - position)
        right = _normalize(np.cross(forward, up))
        true_up = np.cross(right, forward)
        half_h = math.tan(0.5 * float(camera["fov_y"]) * math.pi / 180.0)
        half_w = half_h * width / height
        top_left = forward - right * half_w + true_up * half_h
        return Camera(
            origin=position,
            top_left=top_left,
            dx=right * (2.0 * half_w / width),
            dy=true_up * (-2.0 * half_h / height),
            width=width,
            height=height,
        )

    def film_position(self, point: np.ndarray) -> tuple[float, float]:
        """The film position (px, py) whose ray passes through `point` (in front)."""
        m = np.stack([self.dx, self.dy, -(np.asarray(point, dtype=np.float64) - self.origin)], axis=1)
        px, py, _ = np.linalg.solve(m, -self.top_left)
        return float(px), float(py)

    def directions(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Unit directions, shape px.shape + (3,)."""
        d = self.top_left + px[..., None] * self.dx + py[..., None] * self.dy
        unit: np.ndarray = d / np.linalg.norm(d, axis=-1, keepdims=True)
        return unit


def _normalize(v: np.ndarray) -> np.ndarray:
    return v / float(np.linalg.norm(v))


def _close(a: Any, b: Any) -> bool:
    return bool(
        np.allclose(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64), rtol=TOLERANCE, atol=TOLERANCE)
    )


def _centred_square(vertices: Any, y: float, what: str) -> float:
    """Side of an axis-aligned square centred on the y axis at height y."""
    v = np.asarray(vertices, dtype=np.float64)
    if v.shape != (4, 3) or not _close(v[:, 1], [y] * 4):
        raise ModelMismatch(f"{what}: expected 4 vertices at y = {y}, got {v.tolist()}")
    half = float(np.max(np.abs(v[:, [0, 2]])))
    if not _close(np.abs(v[:, [0, 2]]), np.full((4, 2), half)) or not _close(v[:, [0, 2]].sum(axis=0), [0, 0]):
        raise ModelMismatch(f"{what}: not an axis-aligned square centred at x = z = 0: {v.tolist()}")
    return 2.0 * half


def _aabb(shape: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    if shape.get("type") == "box":
        return np.asarray(shape["min"], dtype=np.float64), np.asarray(shape["max"], dtype=np.float64)
    v = np.asarray(shape["vertices"], dtype=np.float64)
    return v.min(axis=0), v.max(axis=0)


@dataclass(frozen=True)
class LampshadeModel:
    """The lampshade scene as the closed form needs it."""

    s_light: float
    s_portal: float
    radiance: np.ndarray  # (3,)
    albedo: np.ndarray  # (3,) of the floor
    shade_half: float  # a
    camera: Camera

    @property
    def occluders(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Every surface but the floor, as AABBs (the shade as one), grown by GROW:
        the camera's rays must miss all of them."""
        a = self.shade_half
        boxes = [(np.array(BOX_MIN), np.array(BOX_MAX)), (np.array([-a, PORTAL_Y, -a]), np.array([a, SHADE_TOP, a]))]
        boxes += [(np.array(lo), np.array(hi)) for lo, hi in WALLS.values()]
        return [(lo - GROW, hi + GROW) for lo, hi in boxes]

    @staticmethod
    def from_config(cfg: dict[str, Any]) -> LampshadeModel:
        """Reads and checks an effective config (a run folder's config.yaml)."""
        lights = cfg.get("lights") or []
        portals = cfg.get("portals") or []
        if len(lights) != 1 or len(portals) != 1:
            raise ModelMismatch(f"expected one light and one portal, got {len(lights)} and {len(portals)}")
        light, portal = lights[0], portals[0]
        if light.get("two_sided", False):
            raise ModelMismatch("the lamp must be one-sided")
        s_l = _centred_square(light["vertices"], LIGHT_Y, "light")
        s_p = _centred_square(portal["vertices"], PORTAL_Y, "portal")
        v = np.asarray(light["vertices"], dtype=np.float64)
        normal = np.cross(v[1] - v[0], v[2] - v[0])
        if not normal[1] < 0:
            raise ModelMismatch("the lamp must emit downwards (vertices counter-clockwise seen from below)")
        if portal.get("light") != light.get("name"):
            raise ModelMismatch("the portal must belong to the lamp")
        radiance = np.asarray(light["radiance"], dtype=np.float64)
        expected = np.asarray(POWER_RADIANCE) * (0.5 / s_l) ** 2
        if not np.allclose(radiance, expected, rtol=1e-9, atol=0):
            raise ModelMismatch(
                f"lamp radiance {radiance.tolist()} is not (40, 34, 24) (0.5 / s_L)^2 = {expected.tolist()}"
            )

        shapes = {s.get("name"): s for s in cfg.get("shapes") or []}
        expected_names = {"floor", "box", *WALLS, *SHADE_PARTS}
        if set(shapes) != expected_names or len(cfg["shapes"]) != len(expected_names):
            raise ModelMismatch(f"shapes {sorted(map(str, shapes))} are not the lampshade's {sorted(expected_names)}")
        materials = cfg.get("materials") or {}
        floor = shapes["floor"]
        material = materials[floor["material"]]
        if material.get("type") != "diffuse" or not _close(material["albedo"], FLOOR_ALBEDO):
            raise ModelMismatch(f"floor material {material} is not white diffuse {FLOOR_ALBEDO}")
        lo, hi = _aabb(floor)
        if not (_close(lo, [-ROOM_HALF, 0, -ROOM_HALF]) and _close(hi, [ROOM_HALF, 0, ROOM_HALF])):
            raise ModelMismatch(f"floor AABB {lo.tolist()}..{hi.tolist()} is not [-3, 3] x {{0}} x [-3, 3]")
        if not all(_close(_aabb(shapes[n]), bounds) for n, bounds in WALLS.items()):
            raise ModelMismatch("room walls or ceiling differ from the canonical room")
        if not _close(_aabb(shapes["box"]), (BOX_MIN, BOX_MAX)):
            raise ModelMismatch("the box differs from [0.5, 1.5] x [0, 1] x [-0.5, 0.5]")
        a = max(s_l, s_p) / 2 + SHADE_MARGIN
        parts = [_aabb(shapes[n]) for n in SHADE_PARTS]
        shade_lo = np.min([p[0] for p in parts], axis=0)
        shade_hi = np.max([p[1] for p in parts], axis=0)
        if not (_close(shade_lo, [-a, PORTAL_Y, -a]) and _close(shade_hi, [a, SHADE_TOP, a])):
            raise ModelMismatch(
                f"shade AABB {shade_lo.tolist()}..{shade_hi.tolist()} is not [-a, a] x [2.2, 2.65] x [-a, a], a = {a}"
            )
        # The bottom plate must leave exactly the portal open: its four quads
        # (as in the scene file) lie in y = 2.2 and have the hole's edges at +-s_P/2.
        h = s_p / 2
        plates = {
            "shade_bottom_back": ((-a, -a), (a, -h)),
            "shade_bottom_front": ((-a, h), (a, a)),
            "shade_bottom_left": ((-a, -h), (-h, h)),
            "shade_bottom_right": ((h, -h), (a, h)),
        }
        for name, ((x0, z0), (x1, z1)) in plates.items():
            if not _close(_aabb(shapes[name]), ((x0, PORTAL_Y, z0), (x1, PORTAL_Y, z1))):
                raise ModelMismatch(f"{name} does not border the portal as in the scene file")
        film = cfg["film"]
        camera = Camera.from_config(cfg["camera"], int(film["width"]), int(film["height"]))
        return LampshadeModel(
            s_light=s_l,
            s_portal=s_p,
            radiance=radiance,
            albedo=np.asarray(material["albedo"], dtype=np.float64),
            shade_half=a,
            camera=camera,
        )

    # --- the closed form at floor points ------------------------------------------------

    def visible_rectangle(self, px: np.ndarray, pz: np.ndarray) -> tuple[np.ndarray, ...]:
        """The visible part of the light from floor points (px, 0, pz), in the
        portal plane: the light square projected through p, clipped to the
        portal. Bounds (x0, x1, z0, z1); empty where x0 >= x1 or z0 >= z1."""
        k = PORTAL_Y / LIGHT_Y  # p + (q - p) k: a point q of the light seen from p
        half = k * self.s_light / 2
        hp = self.s_portal / 2
        cx, cz = px * (1 - k), pz * (1 - k)
        return (
            np.maximum(cx - half, -hp),
            np.minimum(cx + half, hp),
            np.maximum(cz - half, -hp),
            np.minimum(cz + half, hp),
        )

    def radiance_at(self, px: np.ndarray, pz: np.ndarray) -> np.ndarray:
        """L(p) per channel, shape px.shape + (3,), for unshadowed floor points."""
        x0, x1, z0, z1 = self.visible_rectangle(px, pz)
        e = projected_solid_angle_rect(px, pz, x0, x1, z0, z1, PORTAL_Y)
        radiance: np.ndarray = (self.albedo / math.pi * self.radiance) * e[..., None]
        return radiance


def projected_solid_angle_rect(
    px: np.ndarray, pz: np.ndarray, x0: np.ndarray, x1: np.ndarray, z0: np.ndarray, z1: np.ndarray, height: float
) -> np.ndarray:
    """Lambert's polygon formula: the cosine-weighted solid angle, seen from
    floor points (px, 0, pz) with normal +y, of the horizontal rectangle
    [x0, x1] x {height} x [z0, z1]; 0 for an empty rectangle.

    E = 1/2 |sum over edges (v_i, v_i+1) of theta_i * (n . g_i)|, with v the
    corners relative to p, theta_i the angle between v_i and v_i+1 and g_i the
    unit normal of the plane through p and the edge."""
    px, pz = np.asarray(px, dtype=np.float64), np.asarray(pz, dtype=np.float64)
    empty = (x1 <= x0) | (z1 <= z0)
    xs = (x0, x1, x1, x0)
    zs = (z0, z0, z1, z1)
    corners = [
        np.stack(np.broadcast_arrays(xs[i] - px, np.full_like(px, height), zs[i] - pz), axis=-1) for i in range(4)
    ]
    total = np.zeros(np.broadcast(px, x0).shape)
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        c = np.cross(a, b)
        norm_c = np.linalg.norm(c, axis=-1)
        theta = np.arctan2(norm_c, np.sum(a * b, axis=-1))
        with np.errstate(invalid="ignore", divide="ignore"):
            total += np.where(norm_c > 0, theta * c[..., 1] / norm_c, 0.0)
    return np.where(empty, 0.0, 0.5 * np.abs(total))


# --- conservative occlusion tests ----------------------------------------------------------


def frustum_meets_box(
    a_lo: np.ndarray,
    a_hi: np.ndarray,
    ya: float | np.ndarray,
    b_lo: np.ndarray,
    b_hi: np.ndarray,
    yb: float | np.ndarray,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
) -> np.ndarray:
    """Whether conv(A u B) meets the closed AABB [box_lo, box_hi], for
    horizontal axis-aligned rectangles A = [a_lo, a_hi] (xz bounds, shape
    (..., 2)) at height ya and B at height yb != ya (B may be a point).

    conv(A u B) is the union of the segments between A and B; at parameter t
    its slice is (1 - t) A + t B, the rectangle with linearly interpolated
    bounds at height ya + t (yb - ya). It meets the box iff some t in [0, 1]
    satisfies six linear inequalities (height in the box's y range, the
    slice's x and z intervals overlapping the box's): an exact test."""
    shape = np.broadcast_shapes(a_lo.shape, b_lo.shape)[:-1]
    t_lo = np.zeros(shape)
    t_hi = np.ones(shape)
    ya_arr, yb_arr = np.broadcast_to(ya, shape), np.broadcast_to(yb, shape)

    def require(c0: np.ndarray, c1: np.ndarray) -> None:
        """Keep the t with c0 + c1 t >= 0."""
        nonlocal t_lo, t_hi
        with np.errstate(divide="ignore", invalid="ignore"):
            root = -c0 / c1
        t_lo = np.where(c1 > 0, np.maximum(t_lo, root), t_lo)
        t_hi = np.where(c1 < 0, np.minimum(t_hi, root), t_hi)
        t_hi = np.where((c1 == 0) & (c0 < 0), -1.0, t_hi)

    require(ya_arr - box_lo[1], yb_arr - ya_arr)  # y(t) >= box y min
    require(box_hi[1] - ya_arr, ya_arr - yb_arr)  # y(t) <= box y max
    for axis, box_axis in ((0, 0), (1, 2)):
        hi_a, hi_b = a_hi[..., axis], b_hi[..., axis]
        lo_a, lo_b = a_lo[..., axis], b_lo[..., axis]
        require(hi_a - box_lo[box_axis], hi_b - hi_a)  # slice's upper bound >= box's lower
        require(box_hi[box_axis] - lo_a, lo_a - lo_b)  # slice's lower bound <= box's upper
    return t_lo <= t_hi


@dataclass(frozen=True)
class PixelModel:
    """Expected pixel values of the direct integrator and where they hold."""

    expected: np.ndarray  # (height, width, 3)
    mask: np.ndarray  # (height, width) bool: footprint entirely on unshadowed, unoccluded floor
    n: int  # sub-pixel grid of `expected`


def footprint_corners(model: LampshadeModel) -> tuple[np.ndarray, np.ndarray]:
    """Camera rays through every pixel corner: directions (H+1, W+1, 3) and
    their floor hits (H+1, W+1, 3) (NaN where the ray does not go down)."""
    cam = model.camera
    py, px = np.meshgrid(
        np.arange(cam.height + 1, dtype=np.float64), np.arange(cam.width + 1, dtype=np.float64), indexing="ij"
    )
    d = cam.directions(px, py)
    return d, _floor_hit(cam.origin, d)


def _floor_hit(origin: np.ndarray, d: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d[..., 1] < 0, -origin[1] / d[..., 1], np.nan)
    hit: np.ndarray = origin + t[..., None] * d
    return hit


def floor_mask(model: LampshadeModel) -> np.ndarray:
    """Pixels whose whole footprint is floor that the closed form describes
    exactly: a conservative test, (H, W) bool.

    Footprint: the film square [x, x+1] x [y, y+1] maps to a pyramid of
    camera rays, the convex hull of its four corner rays. If all four go
    down, every ray of the pyramid does, and their floor hits fill the convex
    quadrilateral F of the corners' hits; F must lie strictly inside the room.
    Below, AABB(F) (its xz bounding rectangle, a superset of F) is used.

    Camera visibility: the segments from the camera C to F lie in
    conv({C} u AABB(F)), tested exactly (frustum_meets_box) against every
    other surface as an AABB (the box; the whole shade as one box; walls and
    ceiling as flat boxes), each grown by GROW.

    Shadow: light reaches p in F only along segments from p to its visible
    rectangle V(p) in the portal plane (the shade is closed but for the
    portal, and the visible rectangle already accounts for the bottom plate;
    the lamp lies within the shade's walls, so nothing between portal and
    lamp blocks). The union of V(p) over p in AABB(F) lies in S = portal
    intersected with the union of the projected light squares, an
    axis-aligned rectangle; all the segments lie in conv(AABB(F) u S), tested
    exactly against the grown box (the room's walls and ceiling cannot meet
    it: both rectangles are strictly inside the room below the ceiling).
    Where S is empty no light arrives anywhere in F (L = 0, exactly right).

    So every test is exact on a superset of the true set of segments: a
    pixel may be rejected needlessly near the box, never accepted wrongly."""
    _, hits = footprint_corners(model)
    corners = np.stack([hits[:-1, :-1], hits[:-1, 1:], hits[1:, :-1], hits[1:, 1:]], axis=0)  # (4, H, W, 3)
    ok = np.all(np.isfinite(corners[..., 0]), axis=0)
    corners = np.nan_to_num(corners)
    lo = corners[..., [0, 2]].min(axis=0)  # (H, W, 2)
    hi = corners[..., [0, 2]].max(axis=0)
    ok &= np.all(lo > -ROOM_HALF + GROW, axis=-1) & np.all(hi < ROOM_HALF - GROW, axis=-1)
    cam = model.camera.origin
    c_xz = np.broadcast_to(cam[[0, 2]], lo.shape)
    for box_lo, box_hi in model.occluders:
        ok &= ~frustum_meets_box(lo, hi, 0.0, c_xz, c_xz, float(cam[1]), box_lo, box_hi)
    k = PORTAL_Y / LIGHT_Y
    half, hp = k * model.s_light / 2, model.s_portal / 2
    s_lo = np.maximum(lo * (1 - k) - half, -hp)
    s_hi = np.minimum(hi * (1 - k) + half, hp)
    lit = np.all(s_lo < s_hi, axis=-1)
    box_lo, box_hi = np.array(BOX_MIN) - GROW, np.array(BOX_MAX) + GROW
    shadowed = frustum_meets_box(lo, hi, 0.0, s_lo, s_hi, PORTAL_Y, box_lo, box_hi)
    ok &= ~(lit & shadowed)
    result: np.ndarray = ok
    return result


def expected_pixels(model: LampshadeModel, n: int = 16) -> PixelModel:
    """Mean of L over each pixel's footprint by the n x n midpoint rule in film
    coordinates (the box filter), vectorised over all pixels and one row of
    sub-pixel points at a time. The mask is floor_mask, and also requires
    every sub-pixel ray to hit the floor inside the room (implied by the
    corner test; checked as a safeguard)."""
    cam = model.camera
    py, px = np.meshgrid(np.arange(cam.height, dtype=np.float64), np.arange(cam.width, dtype=np.float64), indexing="ij")
    offsets = (np.arange(n) + 0.5) / n
    total = np.zeros((cam.height, cam.width, 3))
    inside = np.ones((cam.height, cam.width), dtype=bool)
    for oy in offsets:
        sx = px[..., None] + offsets  # (H, W, n)
        sy = np.broadcast_to(py[..., None] + oy, sx.shape)
        hit = _floor_hit(cam.origin, cam.directions(sx, sy))
        inside &= np.all(
            np.isfinite(hit[..., 0]) & (np.abs(hit[..., 0]) < ROOM_HALF) & (np.abs(hit[..., 2]) < ROOM_HALF), axis=-1
        )
        total += np.nan_to_num(model.radiance_at(hit[..., 0], hit[..., 2])).sum(axis=-2)
    return PixelModel(expected=total / (n * n), mask=floor_mask(model) & inside, n=n)
