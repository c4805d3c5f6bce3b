"""The night White Room as committed (configs/scenes/white_room/): the
import of ../shared/assets/white_room/scene_night_flat.xml by
tools/white_room/make_scene.py (import-mitsuba, then binary PLY), byte for
byte; the PLY conversion on small files; and the committed scene loads."""

from __future__ import annotations

import hashlib
import importlib.util
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest
from conftest import REAL_RENDERER, REPO

SHARED = REPO.parent / "shared" / "assets" / "white_room"
COMMITTED = REPO / "configs" / "scenes" / "white_room"


def _tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_scene", REPO / "tools" / "white_room" / "make_scene.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["make_scene"] = mod
    spec.loader.exec_module(mod)
    return mod


def _digests(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def test_01_committed_scene_is_what_the_tool_writes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    if not (SHARED / "scene_night_flat.xml").is_file():
        pytest.skip("../shared/assets/white_room is not beside the project (the source of configs/scenes/white_room)")
    # The header names the XML as the command line did: run it as the README says.
    monkeypatch.chdir(REPO)
    xml = Path(os.path.relpath(SHARED / "scene_night_flat.xml", REPO))
    out = _tool().make(xml, tmp_path / "white_room")
    assert out.read_text() == (COMMITTED / "scene.yaml").read_text()
    assert _digests(tmp_path / "white_room" / "meshes") == _digests(COMMITTED / "meshes")
    assert (COMMITTED / "LICENSE.txt").read_bytes() == (SHARED / "LICENSE.txt").read_bytes()


def test_02_obj_becomes_binary_ply_of_its_triangles(tmp_path: Path) -> None:
    tool = _tool()
    obj = tmp_path / "m.obj"
    # A quad with repeated corners (v, v/vt, v//vn forms), a triangle of zero
    # area (dropped), and a vertex that repeats the first's position.
    obj.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 0\nv 2 0 0\nf 1/1 2/2 3//3 4/4/4\nf 5 2 6\nf -1 -2 -3\n")
    c = tool.convert(obj)
    assert (c.triangles, c.dropped) == (3, 1)
    head, _, body = c.ply.partition(b"end_header\n")
    assert b"format binary_little_endian 1.0" in head and b"element vertex 5" in head
    import numpy as np

    verts = np.frombuffer(body[: 5 * 12], "<f4").reshape(-1, 3)
    faces = np.frombuffer(body[5 * 12 :], dtype=[("n", "u1"), ("i", "<i4", (3,))])
    assert list(faces["n"]) == [3, 3, 3]
    tris = verts[faces["i"]]
    # The quad's fan keeps its winding (+z), the last face its own (-z).
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    assert list(np.sign(normals[:, 2])) == [1, 1, -1]
    assert body[0] not in tool.WHITESPACE


def test_03_body_never_starts_with_whitespace(tmp_path: Path) -> None:
    # x = 0.906922 starts with byte 0x0a: assimp skips it as a newline (and aborts).
    obj = tmp_path / "m.obj"
    obj.write_text("v 0.906922 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n")
    c = _tool().convert(obj)
    body = c.ply.partition(b"end_header\n")[2]
    assert body[0] not in (0x09, 0x0A, 0x0B, 0x0C, 0x0D, 0x20)


@pytest.mark.real
def test_04_committed_scenes_load() -> None:
    if not REAL_RENDERER.is_file():
        pytest.skip("renderer/build/render is not built")
    for name in ("white_room_night.yaml", "white_room_night_hand.yaml"):
        proc = subprocess.run(
            [str(REAL_RENDERER), "--print-config", str(REPO / "configs" / "scenes" / name)],
            capture_output=True,
            text=True,
            check=False,
        )
        assert proc.returncode == 0, proc.stderr
        if name.endswith("_hand.yaml"):
            assert all(p in proc.stdout for p in ("drum_top", "drum_bottom", "pendant_top", "pendant_bottom"))
