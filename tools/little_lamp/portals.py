#!/usr/bin/env python3
"""The portals of the Little Lamp (configs/scenes/little_lamp.yaml), and the
check that they catch every path of the bulb's light.

The lamp head (Mesh042, 26,464 triangles) opens towards the desk through a
planar circular rim. Its interior (Mesh017, `LampInterior`) is missing from
the source, so the head is also open at the back, towards the neck (a ring
of open edges, and vents on its sides). This script

1. fits the rim's plane and radius (the head's vertices farthest along the
   head's axis) and writes a 32-gon circumscribed about the rim, in a plane
   just beyond every vertex of the head: the front portal;
2. finds the open edges of the back half of the head (edges of one
   triangle) and writes a 32-gon behind them, perpendicular to the axis,
   large enough that every line from the bulb through an open edge crosses
   it: the back portal;
3. casts N rays from the bulb in uniform directions against the head and
   counts those that leave it: through the front portal, through the back
   one, or through neither (a path no portal covers).

Usage: tools/little_lamp/portals.py [--rays N] [--assets DIR]
(DIR: the lamp's meshes, default configs/scenes/little_lamp/meshes).
Needs numpy (the harness venv has it)."""

from __future__ import annotations

import argparse
import collections
import math
from pathlib import Path

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]

ROOT = Path(__file__).resolve().parents[2]
# The bulb of lamp_reproduce.xml: model/spemitter.obj (a unit sphere) scaled
# by 0.005 and moved to this point.
BULB_CENTRE = np.array([2.22, 3.94, -0.03])
BULB_RADIUS = 0.005
# The head's axis: the normal of its small planar opening at the very back
# (the neck's hole), pointing towards the front opening.
AXIS = np.array([0.4491, -0.8935, 0.0077])
BACK_HOLE = np.array([1.5395, 5.2828, -0.0395])
SIDES = 32


def load_obj(path: Path) -> tuple[Array, npt.NDArray[np.int64]]:
    """Vertices and fan-triangulated faces (v, v/vt, v//vn, v/vt/vn; negative indices)."""
    verts: list[list[float]] = []
    faces: list[tuple[int, int, int]] = []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            idx = [int(tok.split("/")[0]) for tok in line.split()[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            faces.extend((idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1))
    return np.array(verts), np.array(faces, dtype=np.int64)


def open_vertices(verts: Array, faces: npt.NDArray[np.int64]) -> Array:
    """Vertices on edges that belong to one triangle only (positions welded at 1e-6)."""
    first: dict[tuple[float, ...], int] = {}
    weld = np.array([first.setdefault(tuple(np.round(v, 6)), i) for i, v in enumerate(verts)])
    count: collections.Counter[tuple[int, int]] = collections.Counter()
    for a, b, c in weld[faces]:
        for e in ((a, b), (b, c), (c, a)):
            count[(min(e), max(e))] += 1
    ends = {v for e, n in count.items() if n == 1 for v in e}
    return verts[sorted(ends)]


def ngon(centre: Array, normal: Array, inradius: float) -> Array:
    """A regular SIDES-gon about centre, circumscribed about the circle of
    `inradius`, wound counter-clockwise seen from the side normal points to."""
    e1 = np.cross(normal, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    r = inradius / math.cos(math.pi / SIDES)
    return np.array(
        [
            centre + r * (math.cos(2 * math.pi * k / SIDES) * e1 + math.sin(2 * math.pi * k / SIDES) * e2)
            for k in range(SIDES)
        ]
    )


def portals(head: Array, head_faces: npt.NDArray[np.int64]) -> tuple[Array, Array]:
    axis = AXIS / np.linalg.norm(AXIS)
    t = (head - BACK_HOLE) @ axis
    rim = head[t > t.max() - 1e-3]
    centre = rim.mean(0)
    normal = np.linalg.svd(rim - centre)[2][2]
    normal = normal if normal @ axis > 0 else -normal
    radius = float(np.linalg.norm((rim - centre) - np.outer((rim - centre) @ normal, normal), axis=1).max())
    beyond = float(((head - centre) @ normal).max()) + 1e-3
    front = ngon(centre + normal * beyond, normal, radius)

    edges = open_vertices(head, head_faces)
    back_edges = edges[(edges - BACK_HOLE) @ axis < 0.6]
    t_plane = float(((back_edges - BACK_HOLE) @ axis).min()) - 0.01
    plane_centre = BACK_HOLE + axis * t_plane
    t_bulb = float((BULB_CENTRE - BACK_HOLE) @ axis)
    reach = 0.0
    for q in back_edges:
        w = q - BULB_CENTRE
        x = BULB_CENTRE + w * (t_plane - t_bulb) / (w @ axis)
        reach = max(reach, float(np.linalg.norm((x - plane_centre) - ((x - plane_centre) @ axis) * axis)))
    back = ngon(plane_centre, -axis, reach + 3 * BULB_RADIUS)
    return front, back


def first_hits(verts: Array, faces: npt.NDArray[np.int64], origin: Array, dirs: Array) -> Array:
    """Distance to the first triangle along each ray (inf on a miss): Moeller-Trumbore, 100 rays at a time."""
    a = verts[faces[:, 0]]
    e1, e2 = verts[faces[:, 1]] - a, verts[faces[:, 2]] - a
    s = origin - a
    q = np.cross(s, e1)
    out = np.full(len(dirs), np.inf)
    for i in range(0, len(dirs), 100):
        d = dirs[i : i + 100][:, None, :]
        p = np.cross(d, e2[None])
        det = (e1[None] * p).sum(-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            u = (s[None] * p).sum(-1) * inv
            v = (d * q[None]).sum(-1) * inv
            t = (e2[None] * q[None]).sum(-1) * inv
        hit = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)
        out[i : i + 100] = np.where(hit, t, np.inf).min(1)
    return out


def crosses(poly: Array, origin: Array, dirs: Array) -> npt.NDArray[np.bool_]:
    """Rays from origin that pass through the (regular, convex) polygon."""
    centre = poly.mean(0)
    normal = np.cross(poly[1] - poly[0], poly[2] - poly[0])
    normal /= np.linalg.norm(normal)
    den = dirs @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((centre - origin) @ normal) / den
    x = origin + dirs * t[:, None]
    r = np.linalg.norm((x - centre) - np.outer((x - centre) @ normal, normal), axis=1)
    inradius = float(np.linalg.norm(poly[0] - centre)) * math.cos(math.pi / len(poly))
    result: npt.NDArray[np.bool_] = (t > 0) & (r <= inradius)
    return result


def yaml_polygon(name: str, poly: Array) -> str:
    points = ", ".join("[" + ", ".join(f"{c:.6f}" for c in p) + "]" for p in poly)
    return f"  - name: {name}\n    light: obj_line536\n    vertices: [{points}]\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rays", type=int, default=20000)
    parser.add_argument("--assets", type=Path, default=ROOT / "configs/scenes/little_lamp/meshes")
    args = parser.parse_args()
    head, faces = load_obj(args.assets / "Mesh042.obj")
    front, back = portals(head, faces)
    print("portals:\n" + yaml_polygon("front", front) + yaml_polygon("back", back), end="")
    rng = np.random.default_rng(1)
    z = rng.uniform(-1, 1, args.rays)
    phi = rng.uniform(0, 2 * math.pi, args.rays)
    s = np.sqrt(1 - z * z)
    dirs = np.stack([s * np.cos(phi), s * np.sin(phi), z], 1)
    leaves = ~np.isfinite(first_hits(head, faces, BULB_CENTRE, dirs))
    f, b = crosses(front, BULB_CENTRE, dirs), crosses(back, BULB_CENTRE, dirs)
    n = args.rays
    for label, mask in (
        ("leave the head", leaves),
        ("leave through the front portal", leaves & f),
        ("leave through the back portal", leaves & b),
        ("leave through neither", leaves & ~f & ~b),
    ):
        k = int(mask.sum())
        print(f"# {label}: {k} of {n} directions ({100 * k / n:.3f} % +- {100 * math.sqrt(max(k, 1)) / n:.3f} %)")


if __name__ == "__main__":
    main()
