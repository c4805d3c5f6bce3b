#!/usr/bin/env python3
"""Writes the mesh fixtures of tests/configs (good: meshes/, bad: bad/meshes/).
Run from anywhere; the files are committed, this script says how they were made."""

from __future__ import annotations

import pathlib
import struct
import zlib

HERE = pathlib.Path(__file__).resolve().parent
BAD = HERE.parent / "bad" / "meshes"

# The corners of a box by bits (x, y, z) of the index, as config_scene.c's
# load_box numbers them, and its faces. Each OBJ face starts at the quad's
# second corner: assimp splits (a, b, c, d) into (a, b, c), (a, c, d), which
# then are Embree's split of the box's quad (v0, v1, v3), (v2, v3, v1).
BOX_FACES = [(0, 4, 6, 2), (1, 3, 7, 5), (0, 1, 5, 4), (2, 6, 7, 3), (0, 2, 3, 1), (4, 5, 7, 6)]


def cube_obj() -> str:
    lines = ["# unit cube [-0.5, 0.5] x [0, 1] x [-0.5, 0.5], the box of good/mesh_cube_box.yaml"]
    for i in range(8):
        x = 0.5 if i & 1 else -0.5
        y = 1 if i & 2 else 0
        z = 0.5 if i & 4 else -0.5
        lines.append(f"v {x} {y} {z}")
    for f in BOX_FACES:
        a, b, c, d = f
        lines.append("f " + " ".join(str(k + 1) for k in (b, c, d, a)))
    return "\n".join(lines) + "\n"


MIXED_OBJ = """\
# v/vt/vn forms, negative indices, a quad, a pentagon, a triangle; two
# objects and two groups: 2 + 3 + 1 triangles (test_mesh_file.c), a line.
mtllib not_there.mtl
o floor
v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 1 0
usemtl white
f 1/1/1 4/4/1 3/3/1 2/2/1
o pentagon
g front
v 0 0.5 0
v 0.4 0.5 0
v 0.5 0.8 0
v 0.2 1.0 0
v -0.1 0.8 0
f -5//1 -4//1 -3//1 -2//1 -1//1
g side
v 0 0 0.5
v 0 0.5 0.5
v 0 0.5 -0.5
f -3/1 -2/2 -1/3
l 1 2
"""


def ply_header(fmt: str, nv: int, nf: int) -> bytes:
    return (
        "ply\n"
        f"format {fmt} 1.0\n"
        "comment extra properties, which the loader ignores\n"
        f"element vertex {nv}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty double confidence\n"
        f"element face {nf}\n"
        "property list uchar int vertex_indices\n"
        "property int flags\n"
        "element camera 1\n"
        "property float fov\n"
        "end_header\n"
    ).encode()


# A unit square (0, 3, 2, 1) and a pentagon (0, 3, 2, 4, 1) over it, both
# counter-clockwise seen from +y: 2 + 3 triangles of area 1 + 1.25, 6
# vertices of which 5 are used (vertex 5 is in no face).
PLY_V = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1), (1.5, 0, 0.5), (0.5, 0, -0.5)]
PLY_F = [(0, 3, 2, 1), (0, 3, 2, 4, 1)]


def ply_binary(endian: str) -> bytes:
    fmt = "binary_little_endian" if endian == "<" else "binary_big_endian"
    b = ply_header(fmt, len(PLY_V), len(PLY_F))
    for v in PLY_V:
        b += struct.pack(endian + "fffBd", *v, 200, 0.25)
    for f in PLY_F:
        b += struct.pack(endian + "B" + "i" * len(f) + "i", len(f), *f, 7)
    b += struct.pack(endian + "f", 45.0)
    return b


def ply_ascii() -> bytes:
    b = ply_header("ascii", len(PLY_V), len(PLY_F))
    for v in PLY_V:
        b += (" ".join(f"{c:g}" for c in v) + " 200 0.25\n").encode()
    for f in PLY_F:
        b += (f"{len(f)} " + " ".join(map(str, f)) + " 7\n").encode()
    b += b"45\n"
    return b


def ply_body_newline() -> bytes:
    """A valid binary little-endian PLY whose body starts with the byte 0x0a:
    the first vertex's x is the float 0a 00 80 3f (1 + 10 ulp). Assimp 5.2.5
    skipped that byte as if it ended the header's line, misread every count
    and aborted on an assertion; the renderer reads PLY itself. A unit square
    in y = 0 as two triangles, counter-clockwise seen from +y."""
    x0 = struct.unpack("<f", b"\x0a\x00\x80\x3f")[0]
    verts = [(x0, 0, 0), (0, 0, 0), (0, 0, 1), (1, 0, 1)]
    b = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    for v in verts:
        b += struct.pack("<fff", *v)
    for f in [(1, 2, 3), (1, 3, 0)]:
        b += struct.pack("<B3i", 3, *f)
    assert b[b.index(b"end_header\n") + 11] == 0x0A
    return b


# A unit square in y = 0 (2 triangles) and 3 degenerate triangles: collinear
# corners, a repeated corner, and a quad whose corners lie on one line (2
# triangles once cut). Vertex 4 is used only by degenerate ones.
DEGENERATE_PLY = b"""ply
format ascii 1.0
comment 2 sound triangles, 4 of zero area
element vertex 5
property float x
property float y
property float z
element face 5
property list uchar int vertex_indices
end_header
0 0 0
1 0 0
1 0 1
0 0 1
2 0 0
3 0 3 2
3 0 2 1
3 0 1 4
3 2 2 3
4 0 1 4 1
"""


def lamp_grid_obj() -> str:
    """The lampshade's square lamp (side 0.6 at y = 2.6, emitting down) as 12
    triangles of unequal areas, for the mesh-light tests."""
    xs, zs = (-0.3, -0.1, 0.05, 0.3), (-0.3, 0.0, 0.3)
    lines = ["# the lampshade's lamp at s_L = 0.6 as a mesh light: an uneven 3 x 2 grid, counter-clockwise from below"]
    for z in zs:
        lines.extend(f"v {x} 2.6 {z}" for x in xs)
    for j in range(len(zs) - 1):
        for i in range(len(xs) - 1):
            a, b = 1 + j * len(xs) + i, 2 + j * len(xs) + i
            c, d = b + len(xs), a + len(xs)
            lines.append(f"f {a} {b} {c}")
            lines.append(f"f {a} {c} {d}")
    return "\n".join(lines) + "\n"


def lamp_sphere_obj(segments: int = 8, rings: int = 6, radius: float = 0.12) -> str:
    """A UV sphere of 2 * segments * (rings - 1) triangles centred at (0, 2.45, 0),
    wound counter-clockwise seen from outside (it emits outwards): a bulb inside
    the lampshade, for the mesh-light tests."""
    import math

    lines = [f"# UV sphere, radius {radius}, centre (0, 2.45, 0), {segments} segments, {rings} rings, outward"]
    lines.append(f"v 0 {2.45 + radius} 0")
    for r in range(1, rings):
        theta = math.pi * r / rings
        for k in range(segments):
            phi = 2 * math.pi * k / segments
            x, y, z = math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi)
            lines.append(f"v {radius * x:.9f} {2.45 + radius * y:.9f} {radius * z:.9f}")
    lines.append(f"v 0 {2.45 - radius} 0")
    south = 2 + segments * (rings - 1)

    def ring(r: int, k: int) -> int:
        return 2 + (r - 1) * segments + k % segments

    for k in range(segments):
        lines.append(f"f 1 {ring(1, k + 1)} {ring(1, k)}")
        lines.append(f"f {south} {ring(rings - 1, k)} {ring(rings - 1, k + 1)}")
        for r in range(1, rings - 1):
            a, b, c, d = ring(r, k), ring(r, k + 1), ring(r + 1, k + 1), ring(r + 1, k)
            lines.append(f"f {a} {b} {c}")
            lines.append(f"f {a} {c} {d}")
    return "\n".join(lines) + "\n"


# Mitsuba's serialized format (renderer/src/config/mesh_serialized.h), written
# from its documentation: per shape a header (id 0x041C, version) and a zlib
# stream (flags, a name in version 4, counts, positions, optional normals,
# texture coordinates and colors, uint32 indices); at the end each shape's
# offset (uint64 in version 4, uint32 in version 3) and the shape count.
SERIALIZED_ID = 0x041C
HAS_NORMALS, HAS_TEXCOORDS, HAS_COLORS, SINGLE, DOUBLE = 0x0001, 0x0002, 0x0008, 0x1000, 0x2000

Vec = tuple[float, float, float]
Tri = tuple[int, int, int]

# Three shapes whose geometry test_mesh_serialized.c knows:
# 0 "square": the unit square at y = 0 facing +y, its two triangles with
#   corners of their own (6 vertices at 4 positions, joined by the loader);
# 1 "tetra": a tetrahedron with corners at 0.1 steps, 4 triangles;
# 2 "cube": cube.obj's box with 4 vertices a face (24 at 8 positions), as
#   exporters that split vertices by normal write it, each quad from its
#   second corner as in cube.obj: joined, it is cube.obj's mesh exactly.
SQUARE_V: list[Vec] = [(0, 0, 0), (0, 0, 1), (1, 0, 1), (0, 0, 0), (1, 0, 1), (1, 0, 0)]
SQUARE_T: list[Tri] = [(0, 1, 2), (3, 4, 5)]
TETRA_V: list[Vec] = [(0.1, 0.2, 0.3), (1.1, 0.2, 0.3), (0.1, 1.2, 0.3), (0.1, 0.2, 1.3)]
TETRA_T: list[Tri] = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def cube_split() -> tuple[list[Vec], list[Tri]]:
    verts: list[Vec] = []
    tris: list[Tri] = []
    for face in BOX_FACES:
        base = len(verts)
        a, b, c, d = face
        for i in (b, c, d, a):
            verts.append((0.5 if i & 1 else -0.5, 1.0 if i & 2 else 0.0, 0.5 if i & 4 else -0.5))
        tris += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return verts, tris


def serialized_stream(
    version: int,
    verts: list[Vec],
    tris: list[Tri],
    *,
    double: bool = False,
    attributes: int = 0,
    name: str = "",
    counts: tuple[int, int] | None = None,
    flags: int | None = None,
    extra: bytes = b"",
) -> bytes:
    """The uncompressed content of one shape; counts, flags and extra bytes
    can be made to lie for the bad fixtures."""
    real = "d" if double else "f"
    nv, nt = counts if counts else (len(verts), len(tris))
    body = struct.pack("<I", flags if flags is not None else attributes | (DOUBLE if double else SINGLE))
    if version == 4:
        body += name.encode() + b"\0"
    body += struct.pack("<QQ", nv, nt)
    body += b"".join(struct.pack("<3" + real, *v) for v in verts)
    if attributes & HAS_NORMALS:
        body += struct.pack("<3" + real, 0.0, 1.0, 0.0) * len(verts)
    if attributes & HAS_TEXCOORDS:
        body += b"".join(struct.pack("<2" + real, v[0], v[2]) for v in verts)
    if attributes & HAS_COLORS:
        body += struct.pack("<3" + real, 0.8, 0.5, 0.2) * len(verts)
    body += b"".join(struct.pack("<3I", *t) for t in tris)
    return body + extra


def serialized_shape(version: int, stream: bytes) -> bytes:
    return struct.pack("<HH", SERIALIZED_ID, version) + zlib.compress(stream)


def serialized_file(version: int, shapes: list[bytes], offsets: list[int] | None = None) -> bytes:
    data = b""
    at = []
    for shape in shapes:
        at.append(len(data))
        data += shape
    entry = "<Q" if version == 4 else "<I"
    data += b"".join(struct.pack(entry, o) for o in (offsets if offsets is not None else at))
    return data + struct.pack("<I", len(shapes))


def serialized_shapes(version: int, double: bool) -> bytes:
    """The three shapes, the square with normals and texture coordinates,
    the tetrahedron with colors, the cube with normals."""
    cube_v, cube_t = cube_split()
    streams = [
        serialized_stream(
            version, SQUARE_V, SQUARE_T, double=double, attributes=HAS_NORMALS | HAS_TEXCOORDS, name="square"
        ),
        serialized_stream(version, TETRA_V, TETRA_T, double=double, attributes=HAS_COLORS, name="tetra"),
        serialized_stream(version, cube_v, cube_t, double=double, attributes=HAS_NORMALS, name="cube"),
    ]
    return serialized_file(version, [serialized_shape(version, s) for s in streams])


def serialized_bad() -> dict[str, bytes]:
    """Bad serialized files, each with one defect, by file name."""
    good = serialized_shapes(4, False)
    tetra = serialized_stream(4, TETRA_V, TETRA_T, name="tetra")
    one = serialized_shape(4, tetra)

    def single(stream: bytes) -> bytes:
        return serialized_file(4, [serialized_shape(4, stream)])

    nan_v = [(0.0, 0.0, 0.0), (float("nan"), 0.0, 0.0), (0.0, 1.0, 0.0)]
    corrupt = bytearray(one)
    corrupt[len(one) // 2] ^= 0xFF
    return {
        "serialized_empty.serialized": b"",
        "serialized_wrong_id.serialized": b"\x1d\x04" + good[2:],
        "serialized_version5.serialized": good[:2] + b"\x05\x00" + good[4:],
        "serialized_truncated.serialized": good[: len(good) // 2],
        "serialized_no_shapes.serialized": good[:-4] + struct.pack("<I", 0),
        "serialized_huge_shape_count.serialized": good[:-4] + struct.pack("<I", 1 << 30),
        "serialized_bad_offset.serialized": serialized_file(4, [one], offsets=[1 << 40]),
        "serialized_offset_not_header.serialized": serialized_file(4, [one], offsets=[6]),
        "serialized_stream_cut.serialized": serialized_file(4, [one[: len(one) - 12]]),
        "serialized_corrupt.serialized": serialized_file(4, [bytes(corrupt)]),
        "serialized_lying_vertices.serialized": single(serialized_stream(4, TETRA_V, TETRA_T, counts=(40, 4))),
        "serialized_lying_triangles.serialized": single(serialized_stream(4, TETRA_V, TETRA_T, counts=(4, 9))),
        "serialized_short_count.serialized": single(serialized_stream(4, TETRA_V, TETRA_T, counts=(4, 3))),
        "serialized_huge_count.serialized": single(serialized_stream(4, TETRA_V, TETRA_T, counts=(1 << 40, 4))),
        "serialized_large_count.serialized": single(serialized_stream(4, TETRA_V, TETRA_T, counts=(100_000_000, 4))),
        "serialized_index.serialized": single(serialized_stream(4, TETRA_V, [(0, 1, 2), (0, 1, 4)])),
        "serialized_nan.serialized": single(serialized_stream(4, nan_v, [(0, 1, 2)])),
        "serialized_no_precision.serialized": single(serialized_stream(4, TETRA_V, TETRA_T, flags=HAS_NORMALS)),
        "serialized_no_triangles.serialized": single(serialized_stream(4, TETRA_V, [])),
    }


def write(path: pathlib.Path, data: str | bytes) -> None:
    path.write_bytes(data if isinstance(data, bytes) else data.encode())


def main() -> None:
    write(HERE / "cube.obj", cube_obj())
    write(HERE / "mixed.obj", MIXED_OBJ)
    write(HERE / "polys_ascii.ply", ply_ascii())
    write(HERE / "polys_le.ply", ply_binary("<"))
    write(HERE / "polys_be.ply", ply_binary(">"))
    write(HERE / "body_newline.ply", ply_body_newline())
    write(HERE / "degenerate_tris.ply", DEGENERATE_PLY)
    write(HERE / "lamp_grid.obj", lamp_grid_obj())
    write(HERE / "lamp_sphere.obj", lamp_sphere_obj())
    write(HERE / "shapes_v4_single.serialized", serialized_shapes(4, False))
    write(HERE / "shapes_v4_double.serialized", serialized_shapes(4, True))
    write(HERE / "shapes_v3_single.serialized", serialized_shapes(3, False))
    write(HERE / "shapes_v3_double.serialized", serialized_shapes(3, True))
    # Bad ones.
    write(BAD / "index_out_of_range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    write(BAD / "negative_out_of_range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n")
    write(BAD / "zero_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    write(BAD / "nan_vertex.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    write(BAD / "inf_vertex.ply", ply_ascii().replace(b"\n1 0 0 200", b"\ninf 0 0 200"))
    write(BAD / "garbage.obj", "this is not a mesh\nat all\n")
    write(BAD / "binary.obj", b"\x7fELF\x02\x01\x01\x00\x00\x00garbage")
    write(BAD / "empty.obj", "")
    write(BAD / "ply_content.obj", ply_ascii())
    write(BAD / "obj_content.ply", MIXED_OBJ)
    write(BAD / "cube.stl", "solid cube\nendsolid cube\n")
    write(
        BAD / "huge_count.ply",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n"
        b"property float x\nproperty float y\nproperty float z\n"
        b"element face 1\nproperty list uchar int vertex_indices\nend_header\n" + bytes(64),
    )
    write(
        BAD / "large_count.ply",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
        b"property float x\nproperty float y\nproperty float z\n"
        b"element face 2000000000\nproperty list uchar int vertex_indices\nend_header\n" + bytes(64),
    )
    le = ply_binary("<")
    write(BAD / "truncated.ply", le[:-30])
    write(BAD / "no_end_header.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n")
    write(BAD / "face_index.ply", ply_ascii().replace(b"\n4 0 3 2 1 7", b"\n4 0 3 2 9 7"))
    write(BAD / "degenerate.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n")
    write(BAD / "all_degenerate.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 3 2 1\n")
    write(
        BAD / "points_only.ply",
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        b"end_header\n0 0 0\n1 0 0\n0 1 0\n",
    )
    for name, data in serialized_bad().items():
        write(BAD / name, data)


if __name__ == "__main__":
    main()
