#!/usr/bin/env python3
"""Writes a held-out Mitsuba 3 scene (issues 39 and 40): a room lit only by
two lamps in opaque housings, whose meshes are stored in ONE Mitsuba
`serialized` file of several shapes, for `portal-harness import-mitsuba`
and the renderer's automatic portals (tests/tools/test_held_out.py).

    python3 tools/held_out/make_scene.py OUT [--seed N] [--segments N]

writes OUT/scene.xml (version 3.0.0) and OUT/meshes/lamps.serialized:

- the room: floor, ceiling and four walls as `rectangle`s, a table top as
  a `cube`; diffuse BSDFs;
- a desk lamp on the table: a cone-frustum housing of SEGMENTS facets with
  a wall thickness (outer and inner surfaces, joined by a rim at the open
  bottom, a closed top), on a stand (a post and an arm, separate shapes),
  lit by a small square `area` emitter facing down inside it;
- a wall sconce: a box housing open at top and bottom, with a wall
  thickness (outer and inner walls joined by a rim at either end), lit by
  a small `sphere` `area` emitter at its centre.

The serialized file's shapes, by `shape_index`: 0 desk housing, 1 desk
stand, 2 sconce housing. It is written by the writer of the mesh fixtures
(tests/configs/meshes/make_fixtures.py), format version 4, single precision.

Same arguments, same bytes. --seed moves and resizes the lamps a little
(seed 0: the nominal scene), always keeping each emitter strictly inside
its housing and the housings clear of every other shape."""

from __future__ import annotations

import argparse
import math
import random
import sys
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "configs" / "meshes"))
from make_fixtures import Tri, Vec, serialized_file, serialized_shape, serialized_stream

SERIALIZED = "meshes/lamps.serialized"
SHAPE_NAMES = ("desk_housing", "desk_stand", "sconce_housing")
ROOM = (3.0, 2.8, 3.0)  # half width (x), height (y), half depth (z)


@dataclass(frozen=True)
class Layout:
    """Where the lamps are; every length in metres, y up."""

    desk_centre: tuple[float, float]  # x, z of the desk lamp's axis
    desk_y: tuple[float, float]  # bottom rim, top of the housing
    desk_r: tuple[float, float]  # outer radius at the bottom, at the top
    desk_bulb_y: float
    desk_bulb_half: float
    sconce_centre: tuple[float, float, float]
    sconce_half: tuple[float, float, float]  # outer half extents
    sconce_bulb_r: float
    thickness: float
    table_y: float  # top of the table


def layout(seed: int) -> Layout:
    rng = random.Random(seed)

    def j(scale: float) -> float:
        return 0.0 if seed == 0 else rng.uniform(-scale, scale)

    return Layout(
        desk_centre=(0.5 + j(0.2), -0.5 + j(0.15)),
        desk_y=(1.05 + j(0.05), 1.35 + j(0.05)),
        desk_r=(0.18 + j(0.03), 0.08 + j(0.02)),
        desk_bulb_y=1.25,
        desk_bulb_half=0.03,
        sconce_centre=(-ROOM[0] + 0.14, 1.65 + j(0.1), -1.0 + j(0.3)),
        sconce_half=(0.1, 0.15 + j(0.03), 0.15 + j(0.03)),
        sconce_bulb_r=0.03,
        thickness=0.01,
        table_y=0.75,
    )


def ring(cx: float, cz: float, r: float, y: float, n: int) -> list[Vec]:
    return [(cx + r * math.cos(2 * math.pi * k / n), y, cz + r * math.sin(2 * math.pi * k / n)) for k in range(n)]


def rect_ring(cx: float, cz: float, hx: float, hz: float, y: float) -> list[Vec]:
    return [(cx - hx, y, cz - hz), (cx + hx, y, cz - hz), (cx + hx, y, cz + hz), (cx - hx, y, cz + hz)]


class Mesh:
    def __init__(self) -> None:
        self.verts: list[Vec] = []
        self.tris: list[Tri] = []

    def add(self, pts: list[Vec]) -> list[int]:
        base = len(self.verts)
        self.verts += pts
        return list(range(base, base + len(pts)))

    def band(self, a: list[int], b: list[int]) -> None:
        """Quads between two rings of equal length, each split in two."""
        n = len(a)
        for k in range(n):
            i, i1, j, j1 = a[k], a[(k + 1) % n], b[k], b[(k + 1) % n]
            self.tris += [(i, j, j1), (i, j1, i1)]

    def fan(self, centre: Vec, rim: list[int]) -> None:
        c = self.add([centre])[0]
        n = len(rim)
        self.tris += [(c, rim[(k + 1) % n], rim[k]) for k in range(n)]

    def box(self, lo: Vec, hi: Vec) -> None:
        cx, cz, hx, hz = (lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2, (hi[0] - lo[0]) / 2, (hi[2] - lo[2]) / 2
        bottom, top = self.add(rect_ring(cx, cz, hx, hz, lo[1])), self.add(rect_ring(cx, cz, hx, hz, hi[1]))
        self.band(bottom, top)
        self.tris += [(bottom[0], bottom[1], bottom[2]), (bottom[0], bottom[2], bottom[3])]
        self.tris += [(top[0], top[2], top[1]), (top[0], top[3], top[2])]


def desk_housing(lay: Layout, n: int) -> Mesh:
    """A cone frustum open at the bottom, closed at the top, wall thickness t:
    outer side, inner side, the rim joining them at the bottom, two caps."""
    (cx, cz), (y0, y1), (r0, r1), t = lay.desk_centre, lay.desk_y, lay.desk_r, lay.thickness
    m = Mesh()
    outer0, outer1 = m.add(ring(cx, cz, r0, y0, n)), m.add(ring(cx, cz, r1, y1, n))
    # The inner surface is the outer one moved in by t (along x-z) and its cap down by t.
    r1_inner = r1 + (r0 - r1) * t / (y1 - y0) - t
    inner0, inner1 = m.add(ring(cx, cz, r0 - t, y0, n)), m.add(ring(cx, cz, r1_inner, y1 - t, n))
    m.band(outer0, outer1)
    m.band(inner1, inner0)
    m.band(inner0, outer0)  # the rim, in the plane y = y0
    m.fan((cx, y1, cz), outer1)
    m.fan((cx, y1 - t, cz), list(reversed(inner1)))
    return m


def desk_stand(lay: Layout) -> Mesh:
    """A post on the table beside the housing and an arm over its top (5 mm clear)."""
    (cx, cz), (_, y1), (r0, _) = lay.desk_centre, lay.desk_y, lay.desk_r
    px = cx + r0 + 0.1
    m = Mesh()
    m.box((px - 0.015, lay.table_y, cz - 0.015), (px + 0.015, y1 + 0.04, cz + 0.015))
    m.box((cx, y1 + 0.005, cz - 0.012), (px - 0.015, y1 + 0.03, cz + 0.012))
    return m


def sconce_housing(lay: Layout) -> Mesh:
    """A box open at top and bottom, wall thickness t: outer and inner walls,
    a rim at either end."""
    (cx, cy, cz), (hx, hy, hz), t = lay.sconce_centre, lay.sconce_half, lay.thickness
    m = Mesh()
    o0, o1 = m.add(rect_ring(cx, cz, hx, hz, cy - hy)), m.add(rect_ring(cx, cz, hx, hz, cy + hy))
    i0, i1 = m.add(rect_ring(cx, cz, hx - t, hz - t, cy - hy)), m.add(rect_ring(cx, cz, hx - t, hz - t, cy + hy))
    m.band(o0, o1)
    m.band(i1, i0)
    m.band(i0, o0)
    m.band(o1, i1)
    return m


def matrix(centre: Vec, u: Vec, v: Vec, w: Vec) -> str:
    """The to_world matrix (row-major) that maps local x, y, z to u, v, w and the origin to centre."""
    rows = [(u[i], v[i], w[i], centre[i]) for i in range(3)] + [(0.0, 0.0, 0.0, 1.0)]
    return " ".join(f"{x:.9g}" for row in rows for x in row)


def rectangle(name: str, bsdf: str, centre: Vec, u: Vec, v: Vec) -> str:
    """A Mitsuba rectangle ([-1, 1]^2, normal +z) spanning centre +- u +- v."""
    w = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    n = math.sqrt(sum(c * c for c in w))
    w = (w[0] / n, w[1] / n, w[2] / n)
    return (
        f'  <shape type="rectangle" id="{name}">\n'
        f'    <transform name="to_world"><matrix value="{matrix(centre, u, v, w)}"/></transform>\n'
        f'    <ref id="{bsdf}"/>\n  </shape>\n'
    )


def scene_xml(lay: Layout, width: int, height: int, spp: int) -> str:
    X, H, Z = ROOM
    (dx, dz), (y0, y1) = lay.desk_centre, lay.desk_y
    sx, sy, sz = lay.sconce_centre
    parts = [
        '<?xml version="1.0" encoding="utf-8"?>\n',
        "<!-- Held-out test scene of portal-lights (tools/held_out/make_scene.py): a room lit only\n"
        "     by a desk lamp and a wall sconce in opaque housings (meshes in lamps.serialized). -->\n",
        '<scene version="3.0.0">\n',
        '  <integrator type="direct"/>\n',
        '  <sensor type="perspective">\n',
        '    <float name="fov" value="75"/>\n',
        '    <string name="fov_axis" value="x"/>\n',
        '    <transform name="to_world"><lookat origin="1.6, 1.7, 2.7" target="-0.8, 1.0, -1.0" up="0, 1, 0"/>'
        "</transform>\n",
        f'    <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>\n',
        f'    <film type="hdrfilm"><integer name="width" value="{width}"/>'
        f'<integer name="height" value="{height}"/></film>\n',
        "  </sensor>\n",
        '  <bsdf type="diffuse" id="wall"><rgb name="reflectance" value="0.75, 0.73, 0.7"/></bsdf>\n',
        '  <bsdf type="diffuse" id="floorboards"><rgb name="reflectance" value="0.45, 0.4, 0.35"/></bsdf>\n',
        '  <bsdf type="diffuse" id="wood"><rgb name="reflectance" value="0.5, 0.3, 0.15"/></bsdf>\n',
        '  <bsdf type="diffuse" id="housing"><rgb name="reflectance" value="0.2, 0.25, 0.3"/></bsdf>\n',
        '  <bsdf type="diffuse" id="metal"><rgb name="reflectance" value="0.3, 0.3, 0.3"/></bsdf>\n',
        rectangle("floor", "floorboards", (0.0, 0.0, 0.0), (X, 0.0, 0.0), (0.0, 0.0, -Z)),
        rectangle("ceiling", "wall", (0.0, H, 0.0), (X, 0.0, 0.0), (0.0, 0.0, Z)),
        rectangle("wall_back", "wall", (0.0, H / 2, -Z), (X, 0.0, 0.0), (0.0, H / 2, 0.0)),
        rectangle("wall_front", "wall", (0.0, H / 2, Z), (-X, 0.0, 0.0), (0.0, H / 2, 0.0)),
        rectangle("wall_left", "wall", (-X, H / 2, 0.0), (0.0, 0.0, Z), (0.0, H / 2, 0.0)),
        rectangle("wall_right", "wall", (X, H / 2, 0.0), (0.0, 0.0, -Z), (0.0, H / 2, 0.0)),
        '  <shape type="cube" id="table">\n'
        '    <transform name="to_world"><scale value="0.8, 0.03, 0.5"/>'
        f'<translate value="{dx:.9g}, {lay.table_y - 0.03:.9g}, {dz:.9g}"/></transform>\n'
        '    <ref id="wood"/>\n  </shape>\n',
    ]
    for index, (name, bsdf) in enumerate(zip(SHAPE_NAMES, ("housing", "metal", "housing"), strict=True)):
        parts.append(
            f'  <shape type="serialized" id="{name}">\n'
            f'    <string name="filename" value="{SERIALIZED}"/>\n'
            f'    <integer name="shape_index" value="{index}"/>\n'
            f'    <ref id="{bsdf}"/>\n  </shape>\n'
        )
    h = lay.desk_bulb_half
    assert y0 < lay.desk_bulb_y < y1 - lay.thickness
    facing_down = matrix((dx, lay.desk_bulb_y, dz), (h, 0, 0), (0, 0, h), (0, -1, 0))
    parts.append(
        '  <shape type="rectangle" id="desk_bulb">\n'
        f'    <transform name="to_world"><matrix value="{facing_down}"/>'
        "</transform>\n"
        '    <emitter type="area"><rgb name="radiance" value="60, 52, 40"/></emitter>\n  </shape>\n'
    )
    parts.append(
        '  <shape type="sphere" id="sconce_bulb">\n'
        f'    <point name="center" x="{sx:.9g}" y="{sy:.9g}" z="{sz:.9g}"/>\n'
        f'    <float name="radius" value="{lay.sconce_bulb_r:.9g}"/>\n'
        '    <emitter type="area"><rgb name="radiance" value="20, 22, 26"/></emitter>\n  </shape>\n'
    )
    parts.append("</scene>\n")
    return "".join(parts)


def serialized_bytes(lay: Layout, segments: int) -> bytes:
    meshes = (desk_housing(lay, segments), desk_stand(lay), sconce_housing(lay))
    streams = [serialized_stream(4, m.verts, m.tris, name=n) for m, n in zip(meshes, SHAPE_NAMES, strict=True)]
    return serialized_file(4, [serialized_shape(4, s) for s in streams])


def write_scene(
    out: Path, *, seed: int = 0, segments: int = 24, width: int = 64, height: int = 48, spp: int = 16
) -> Path:
    """Writes OUT/scene.xml and OUT/meshes/lamps.serialized; returns the XML's path."""
    lay = layout(seed)
    (out / "meshes").mkdir(parents=True, exist_ok=True)
    (out / SERIALIZED).write_bytes(serialized_bytes(lay, segments))
    xml = out / "scene.xml"
    xml.write_text(scene_xml(lay, width, height, spp))
    return xml


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("out", type=Path, help="folder to write scene.xml and meshes/ into")
    ap.add_argument("--seed", type=int, default=0, help="moves and resizes the lamps a little (0: nominal)")
    ap.add_argument("--segments", type=int, default=24, help="facets of the desk lamp's cone (3..32)")
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--height", type=int, default=48)
    ap.add_argument("--spp", type=int, default=16)
    a = ap.parse_args(argv)
    if not 3 <= a.segments <= 32:
        ap.error("--segments must be 3..32 (a portal polygon has at most 32 vertices)")
    print(write_scene(a.out, seed=a.seed, segments=a.segments, width=a.width, height=a.height, spp=a.spp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
