#!/usr/bin/env python3
"""Makes configs/scenes/white_room/ (scene.yaml and meshes/) from the night
White Room's Mitsuba XML: `portal-harness import-mitsuba`, then every OBJ
the import copied or wrote converted to a binary little-endian PLY.

    .venv/bin/python tools/white_room/make_scene.py \
        ../shared/assets/white_room/scene_night_flat.xml configs/scenes/white_room

The import's scene.yaml is kept byte for byte, except that each
`file: meshes/NAME.obj` becomes `file: meshes/NAME.ply` and the header gains
the lines of this conversion. The folder's other files (README.md,
LICENSE.txt) are left alone; meshes/ is replaced whole.

A PLY holds what the renderer reads of the OBJ (`v` and `f` lines): the
positions as float32, each distinct position once (the renderer joins
identical vertices anyway; the OBJ files repeat them per face corner), in
order of first use (the first one may be swapped: convert()), and the faces as triangles, each polygon a fan in its
vertex order (so every triangle keeps the polygon's winding: a mesh light
emits from the same side). Triangles whose area is at most DEGENERATE_REL
times their squared longest edge are dropped and counted in the header: the
renderer refuses a mesh with a degenerate triangle (1e-10, its
POLYGON_AREA_REL; here with a margin for the shapes' transforms), and such
a triangle covers no area. Same input, same bytes."""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from portal_harness.mitsuba_import import MitsubaImportError, import_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "crosscheck"))
import obj_to_ply  # tools/crosscheck/obj_to_ply.py: its OBJ reader
from obj_to_ply import ObjError

DEGENERATE_REL = 1e-8
MESH_DIR = "meshes"
WHITESPACE = np.array([0x09, 0x0A, 0x0B, 0x0C, 0x0D, 0x20], dtype=np.uint8)


@dataclass(frozen=True)
class Converted:
    ply: bytes
    vertices: int
    triangles: int
    dropped: int  # degenerate triangles left out


def read_obj(path: Path) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.int64]]:
    """Positions (float32) and fan-triangulated faces of an OBJ file (the cross-check's reader)."""
    verts, tris = obj_to_ply.read_obj(path)
    return np.array(verts, dtype=np.float32), np.array(tris, dtype=np.int64)


def convert(path: Path) -> Converted:
    """The binary PLY of an OBJ file (see the module's docstring)."""
    verts, tris = read_obj(path)
    p = verts.astype(np.float64)[tris]  # (n, 3 corners, xyz), the float32 values
    edges = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 1], p[:, 0] - p[:, 2]], axis=1)
    area = 0.5 * np.linalg.norm(np.cross(edges[:, 0], -edges[:, 2]), axis=1)
    longest2 = (edges**2).sum(axis=2).max(axis=1)
    keep = area > DEGENERATE_REL * longest2
    tris = tris[keep]
    # Distinct positions, numbered in order of first use by the kept triangles.
    _, first, inverse = np.unique(verts, axis=0, return_index=True, return_inverse=True)
    canon = first[inverse.reshape(-1)][tris]  # each corner -> first vertex with its position
    used, order = np.unique(canon.reshape(-1), return_index=True)
    used = used[np.argsort(order, kind="stable")]
    # Assimp 5.2.5 (the renderer's reader) skips a newline byte after
    # end_header, even in a binary body, and then misreads every count: a
    # body starting with 0x0a aborts the renderer (an ai_assert in its
    # triangulation; measured on Mesh020 and Mesh034). The body starts with
    # no whitespace byte: the first vertex whose first byte is safe is
    # swapped in (the faces follow).
    lead = verts[used].astype("<f4").view(np.uint8).reshape(-1, 12)[:, 0]
    safe = np.flatnonzero(~np.isin(lead, WHITESPACE))
    if len(safe) == 0:
        raise ObjError(f"{path}: every vertex's first byte is whitespace to assimp's PLY reader")
    used[[0, safe[0]]] = used[[safe[0], 0]]
    remap = np.full(len(verts), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    faces = remap[canon]
    head = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment from {path.name} by tools/white_room/make_scene.py\n"
        f"element vertex {len(used)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    body["n"] = 3
    body["i"] = faces
    ply = head.encode("ascii") + verts[used].astype("<f4").tobytes() + body.tobytes()
    return Converted(ply, len(used), len(faces), int((~keep).sum()))


def make(xml: Path, dest: Path) -> Path:
    """Imports xml and writes dest/scene.yaml and dest/meshes/*.ply; returns scene.yaml's path."""
    with tempfile.TemporaryDirectory(prefix=".white_room.", dir=dest.parent if dest.parent.is_dir() else None) as t:
        scene, _ = import_scene(xml, Path(t) / "import")
        src = scene.parent / MESH_DIR
        text = scene.read_text()
        staged = Path(t) / MESH_DIR
        staged.mkdir()
        notes = []
        total = dropped = 0
        for obj in sorted(src.iterdir()):
            if obj.suffix.lower() != ".obj":
                raise ObjError(f"{obj}: expected only OBJ files in the import's meshes/")
            c = convert(obj)
            (staged / f"{obj.stem}.ply").write_bytes(c.ply)
            total += c.triangles
            dropped += c.dropped
            if c.dropped:
                notes.append(f"{obj.stem} {c.dropped}")
            old = f"file: {MESH_DIR}/{obj.name}"
            if old not in text:
                raise ObjError(f"{scene}: {old!r} not found")
            pattern = rf"(?m)(\bfile: ){MESH_DIR}/{re.escape(obj.name)}(?=$|[,}}])"
            text = re.sub(pattern, rf"\g<1>{MESH_DIR}/{obj.stem}.ply", text)
        header = [
            "# Meshes converted to binary PLY by tools/white_room/make_scene.py (float32 positions, each once;",
            f"# polygons as triangle fans): {total} triangles; {dropped} degenerate triangles dropped"
            + (f" ({', '.join(notes)})." if notes else "."),
        ]
        lines = text.split("\n")
        cut = next(i for i, line in enumerate(lines) if not line.startswith("#"))
        text = "\n".join(lines[:cut] + header + lines[cut:])
        dest.mkdir(parents=True, exist_ok=True)
        old_meshes = dest / MESH_DIR
        if old_meshes.exists():
            for f in old_meshes.iterdir():
                f.unlink()
            old_meshes.rmdir()
        staged.rename(old_meshes)
        (dest / "scene.yaml").write_text(text)
    return dest / "scene.yaml"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("xml", type=Path, help="the Mitsuba scene (scene_night_flat.xml)")
    ap.add_argument("dest", type=Path, help="the folder to write (configs/scenes/white_room)")
    args = ap.parse_args(argv)
    try:
        path = make(args.xml, args.dest)
    except (ObjError, MitsubaImportError) as e:
        print(f"make_scene: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
