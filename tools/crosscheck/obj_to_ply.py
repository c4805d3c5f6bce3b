#!/usr/bin/env python3
"""Converts a Wavefront OBJ mesh to a binary little-endian PLY (positions and
triangles only).

Used once, to make configs/scenes/meshes/little_lamp_head.ply from "Little
Lamp" (CC0) models/Mesh042.obj, so that the cross-check loads a third-party
mesh from a binary PLY:

    python3 tools/crosscheck/obj_to_ply.py ../shared/assets/little_lamp/models/Mesh042.obj \
        configs/scenes/meshes/little_lamp_head.ply

Reads `v` and `f` lines only (`f` in the v, v/vt, v//vn and v/vt/vn forms,
negative indices relative to the vertices so far); texture coordinates,
normals, groups and materials are dropped, because our renderer shades with
the geometric normal and Mitsuba is given `face_normals`. A polygon becomes a
fan of triangles in its vertex order, so every triangle keeps the polygon's
winding. Vertices are written as float32 and in the file's order, unused ones
included: the PLY is the OBJ's geometry, nothing more. Standard library only.
"""

from __future__ import annotations

import argparse
import struct
import sys
from collections.abc import Sequence
from pathlib import Path


class ObjError(Exception):
    """A line of the OBJ file that cannot be converted (with its location)."""


def _index(token: str, count: int, where: str) -> int:
    """Zero-based vertex index of one `f` corner (v, v/vt, v//vn, v/vt/vn)."""
    head = token.split("/", 1)[0]
    try:
        i = int(head)
    except ValueError:
        raise ObjError(f"{where}: bad vertex index {token!r}") from None
    # OBJ indices are 1-based; negative ones count back from the last vertex.
    k = i - 1 if i > 0 else count + i
    if i == 0 or not 0 <= k < count:
        raise ObjError(f"{where}: vertex index {i} out of range (1..{count} or -{count}..-1)")
    return k


def read_obj(path: Path) -> tuple[list[tuple[float, float, float]], list[tuple[int, int, int]]]:
    """Vertices and triangles (zero-based, fan-triangulated) of an OBJ file."""
    vertices: list[tuple[float, float, float]] = []
    triangles: list[tuple[int, int, int]] = []
    with path.open(encoding="utf-8") as f:
        for number, line in enumerate(f, start=1):
            where = f"{path}:{number}"
            fields = line.split()
            if not fields:
                continue
            if fields[0] == "v":
                if len(fields) < 4:
                    raise ObjError(f"{where}: a vertex needs x y z")
                try:
                    x, y, z = (float(s) for s in fields[1:4])
                except ValueError:
                    raise ObjError(f"{where}: bad vertex {line.strip()!r}") from None
                vertices.append((x, y, z))
            elif fields[0] == "f":
                corners = [_index(t, len(vertices), where) for t in fields[1:]]
                if len(corners) < 3:
                    raise ObjError(f"{where}: a face needs at least 3 vertices")
                for k in range(1, len(corners) - 1):
                    triangles.append((corners[0], corners[k], corners[k + 1]))
    if not triangles:
        raise ObjError(f"{path}: no faces")
    return vertices, triangles


def write_ply(path: Path, vertices: Sequence[Sequence[float]], tris: Sequence[Sequence[int]]) -> None:
    """Binary little-endian PLY: float xyz, uchar-count int faces."""
    head = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = b"".join(struct.pack("<3f", *map(float, v)) for v in vertices)
    body += b"".join(struct.pack("<B3i", 3, *t) for t in tris)
    path.write_bytes(head.encode("ascii") + body)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("obj", type=Path, help="input OBJ file")
    p.add_argument("ply", type=Path, help="output PLY file (binary little-endian)")
    args = p.parse_args(argv)
    try:
        vertices, triangles = read_obj(args.obj)
    except (OSError, UnicodeDecodeError, ObjError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    write_ply(args.ply, vertices, triangles)
    print(f"{args.ply}: {len(vertices)} vertices, {len(triangles)} triangles", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
