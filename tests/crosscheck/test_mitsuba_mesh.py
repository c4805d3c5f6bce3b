"""Tests of the cross-check's file meshes (tools/crosscheck/mitsuba_lampshade.py,
obj_to_ply.py, point_probe.py) and of the mesh scene
configs/scenes/lampshade_mesh.yaml.

Not part of `make test` (like test_mitsuba_lampshade.py). Tests 1-3 need the
standard library alone; 4, 5 and 7 need our render binary; 5-8 need a python
that imports mitsuba (this one or .venv-xcheck's) and are skipped without it.

    .venv-xcheck/bin/python -m pytest -q tests/crosscheck
"""

from __future__ import annotations

import json
import math
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
TOOL_DIR = REPO / "tools" / "crosscheck"
SCRIPT = TOOL_DIR / "mitsuba_lampshade.py"
SCENE = REPO / "configs" / "scenes" / "lampshade_mesh.yaml"
HEAD_PLY = REPO / "configs" / "scenes" / "meshes" / "little_lamp_head.ply"
sys.path.insert(0, str(TOOL_DIR))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import mitsuba_lampshade as xcheck  # noqa: E402  (stdlib-only at import time)
import obj_to_ply  # noqa: E402
from test_mitsuba_lampshade import mitsuba_python, renderer  # noqa: E402

needs_mitsuba = pytest.mark.skipif(
    mitsuba_python() is None, reason="mitsuba is not importable (create .venv-xcheck: see tools/crosscheck/README.md)"
)
needs_renderer = pytest.mark.skipif(renderer() is None, reason="our render binary is not built")

Matrix = list[list[float]]


def identity() -> Matrix:
    return [[float(i == j) for j in range(4)] for i in range(4)]


def matmul(a: Matrix, b: Matrix) -> Matrix:
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def op_matrix(op: dict[str, Any]) -> Matrix:
    """One `transform:` operation of our YAML as a 4x4 matrix, written here
    from the README's definitions (not from the renderer's code)."""
    m = identity()
    if "translate" in op:
        for i in range(3):
            m[i][3] = float(op["translate"][i])
    elif "scale" in op:
        s = op["scale"]
        for i in range(3):
            m[i][i] = float(s[i] if isinstance(s, list) else s)
    elif "rotate" in op:
        # Rodrigues: right-handed, counter-clockwise seen from the axis's tip.
        ax = [float(x) for x in op["rotate"]["axis"]]
        n = math.sqrt(sum(x * x for x in ax))
        x, y, z = (c / n for c in ax)
        t = math.radians(float(op["rotate"]["angle"]))
        c, s, k = math.cos(t), math.sin(t), 1.0 - math.cos(t)
        r = [
            [c + x * x * k, x * y * k - z * s, x * z * k + y * s],
            [y * x * k + z * s, c + y * y * k, y * z * k - x * s],
            [z * x * k - y * s, z * y * k + x * s, c + z * z * k],
        ]
        for i in range(3):
            m[i][:3] = r[i]
    else:
        m = [[float(v) for v in op["matrix"][4 * i : 4 * i + 4]] for i in range(4)]
    return m


def compose(ops: list[dict[str, Any]]) -> Matrix:
    m = identity()
    for op in ops:
        m = matmul(op_matrix(op), m)
    return m


def read_ply_vertices(path: Path) -> list[tuple[float, float, float]]:
    """The float xyz vertices of a PLY as obj_to_ply writes it."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").split("\n")
    n = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    return [struct.unpack_from("<3f", data, end + 12 * i) for i in range(n)]


def print_config(scene: Path) -> dict[str, Any]:
    exe = renderer()
    assert exe is not None
    proc = subprocess.run(
        [str(exe), "--print-config", str(scene), "--format", "json"], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    cfg: dict[str, Any] = json.loads(proc.stdout)["config"]
    return cfg


# --- 1. Without mitsuba ---------------------------------------------------------


def test_1_obj_to_ply_keeps_vertices_and_winding(tmp_path: Path) -> None:
    obj = tmp_path / "m.obj"
    # v, v/vt, v//vn and v/vt/vn corners, a negative index and a quad.
    obj.write_text(
        "# test\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\no a\nf 1 2/1 3//1\ng b\nf 1/1/1 -3 -2 -1\n"
    )
    vertices, triangles = obj_to_ply.read_obj(obj)
    assert vertices == [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    # The quad 1 -3 -2 -1 (= 1 2 3 4 after four vertices) becomes a fan from
    # its first corner, in its order.
    assert triangles == [(0, 1, 2), (0, 1, 2), (0, 2, 3)]
    ply = tmp_path / "m.ply"
    obj_to_ply.write_ply(ply, vertices, triangles)
    assert read_ply_vertices(ply) == vertices
    data = ply.read_bytes()
    assert b"format binary_little_endian 1.0\n" in data
    body = data[data.index(b"end_header\n") + 11 + 12 * 4 :]
    assert [struct.unpack_from("<B3i", body, 13 * i) for i in range(3)] == [(3, *t) for t in triangles]
    for bad in ("v 0 0 0\nf 1 2 0\n", "v 0 0 0\nf 1 1 -2\n", "v 0 0\n", "v 0 0 0\n"):
        obj.write_text(bad)
        with pytest.raises(obj_to_ply.ObjError):
            obj_to_ply.read_obj(obj)


def test_2_to_world_is_our_matrices_in_order_then_the_recentring() -> None:
    scale = {"matrix": [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1]}
    move = {"matrix": [1, 0, 0, 1, 0, 1, 0, 2, 0, 0, 1, 3, 0, 0, 0, 1]}
    # Scale first, then translate (as our `transform:` and Mitsuba's to_world).
    m = xcheck.file_mesh_to_world([scale, move], [0.5, 0.5, 0.5])
    assert m == [[2, 0, 0, 0.5], [0, 2, 0, 1.5], [0, 0, 2, 2.5], [0, 0, 0, 1]]
    assert xcheck.file_mesh_to_world(None, [0, 0, 0]) == identity()
    with pytest.raises(xcheck.SetupError):
        xcheck.file_mesh_to_world([{"translate": [1, 2, 3]}], [0, 0, 0])


def test_3_file_mesh_shape_names_the_file_checks_digest_and_flips_mirrors(tmp_path: Path) -> None:
    ply = tmp_path / "t.ply"
    obj_to_ply.write_ply(ply, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    entry = {"file": str(ply), "digest": {"fnv1a64": xcheck.fnv1a64(ply), "bytes": ply.stat().st_size}}
    shape = xcheck.file_mesh_shape(entry, [0, 0, 0], "t")
    assert shape == {
        "type": "ply",
        "filename": str(ply),
        "to_world": identity(),
        "face_normals": True,
        "flip_normals": False,
    }
    mirror = {**entry, "transform": [{"matrix": [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}]}
    assert xcheck.file_mesh_shape(mirror, [0, 0, 0], "t")["flip_normals"] is True
    with pytest.raises(xcheck.SetupError, match="changed since"):
        xcheck.file_mesh_shape({**entry, "digest": {"fnv1a64": "0" * 16}}, [0, 0, 0], "t")
    with pytest.raises(xcheck.SetupError, match="neither"):
        xcheck.file_mesh_shape({"file": str(tmp_path / "t.stl")}, [0, 0, 0], "t")
    with pytest.raises(xcheck.SetupError, match="not found"):
        xcheck.file_mesh_shape({"file": str(tmp_path / "missing.ply")}, [0, 0, 0], "t")


@needs_renderer
def test_4_the_scene_loads_the_committed_ply_with_its_transform() -> None:
    # Our effective config names the committed binary PLY by its absolute
    # path, with one matrix that is the YAML's five operations composed, and
    # our FNV-1a digest, which the converter recomputes.
    import yaml

    cfg = print_config(SCENE)
    head = cfg["shapes"][-1]
    assert head["name"] == "lamp_head" and head["type"] == "mesh"
    assert Path(head["file"]) == HEAD_PLY.resolve()
    assert head["digest"]["fnv1a64"] == xcheck.fnv1a64(HEAD_PLY)
    ops = yaml.safe_load(SCENE.read_text())["shapes"][-1]["transform"]
    assert len(ops) == 5
    want = compose(ops)
    (only,) = head["transform"]
    got = [[float(x) for x in only["matrix"][4 * i : 4 * i + 4]] for i in range(4)]
    for i in range(4):
        assert got[i] == pytest.approx(want[i], abs=1e-12)


# --- 2. Conversion (needs mitsuba) ----------------------------------------------

PROBE = r"""
import json, sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import mitsuba as mi
mi.set_variant("scalar_rgb")
import mitsuba_lampshade as xcheck

cfg = json.loads(sys.argv[3])
offset = json.loads(sys.argv[4])
sd = xcheck.build_scene_dict(cfg, {"type": "direct"}, Path(sys.argv[2]), 1, offset)
scene = mi.load_dict(sd, optimize=False)  # no merging of the meshes that share a BSDF
out = {"keys": sorted(sd)}
for shape in scene.shapes():
    entry = sd[shape.id()]
    if "filename" not in entry or not entry["filename"].endswith(sys.argv[5]):
        continue
    m = entry["to_world"].matrix
    out[shape.id()] = {
        "type": entry["type"],
        "filename": entry["filename"],
        "face_normals": entry["face_normals"],
        "flip_normals": entry["flip_normals"],
        "to_world": [[float(m[i][j]) for j in range(4)] for i in range(4)],
        "positions": [float(x) for x in shape.vertex_positions_buffer()],
        "emitter": shape.emitter() is not None,
    }
probes = {}
for name, o, d in json.loads(sys.argv[6]):
    si = scene.ray_intersect(mi.Ray3f(o, d))
    le = si.emitter(scene).eval(si) if si.is_valid() and si.emitter(scene) is not None else [0, 0, 0]
    probes[name] = {"t": float(si.t), "le": [float(x) for x in le]}
out["probes"] = probes
out["recentre"] = xcheck.recentre_offset(cfg)
print(json.dumps(out))
"""


def probe(
    tmp_path: Path, cfg: dict[str, Any], offset: list[float], suffix: str, rays: list[Any] | None = None
) -> dict[str, Any]:
    python = mitsuba_python()
    assert python is not None  # needs_mitsuba
    args = [python, "-c", PROBE, str(TOOL_DIR), str(tmp_path), json.dumps(cfg), json.dumps(offset), suffix]
    proc = subprocess.run([*args, json.dumps(rays or [])], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out: dict[str, Any] = json.loads(proc.stdout.strip().splitlines()[-1])
    return out


@needs_mitsuba
@needs_renderer
def test_5_the_mitsuba_dict_has_our_file_and_transform(tmp_path: Path) -> None:
    np = pytest.importorskip("numpy")
    cfg = print_config(SCENE)
    head = cfg["shapes"][-1]
    offset = [0.25, -1.5, 0.125]  # as recentring would move it
    out = probe(tmp_path, cfg, offset, "little_lamp_head.ply")
    key = f"shape_{len(cfg['shapes']) - 1:02d}_lamp_head"
    assert key in out["keys"]
    got = out[key]
    assert got["type"] == "ply" and Path(got["filename"]) == HEAD_PLY.resolve()
    assert got["face_normals"] is True and got["flip_normals"] is False and got["emitter"] is False
    m = np.array(head["transform"][0]["matrix"], dtype=np.float64).reshape(4, 4)
    m[:3, 3] -= offset
    np.testing.assert_allclose(got["to_world"], m, rtol=0, atol=1e-6)  # Mitsuba keeps it in float32
    # Every vertex of the file, where our matrix puts it (float32 positions).
    v = np.array(read_ply_vertices(HEAD_PLY), dtype=np.float64)
    want = v @ m[:3, :3].T + m[:3, 3]
    pos = np.array(got["positions"]).reshape(-1, 3)
    assert pos.shape == want.shape == (18552, 3)
    np.testing.assert_allclose(pos, want, rtol=0, atol=1e-5)
    # It stands on the floor (y = 0 before the move), sunk by at most 2 mm.
    assert -0.003 < pos[:, 1].min() + offset[1] < 0.0


@needs_mitsuba
def test_6_a_mesh_light_emits_on_our_side_also_when_mirrored(tmp_path: Path) -> None:
    # A one-triangle mesh light in the plane z = 0 whose winding faces +z.
    # Ours keeps the emitting side of the surface under a mirroring transform
    # (the triangles are reversed, the normal follows the inverse transpose):
    # scale(-1, 1, 1) must still emit towards +z only.
    ply = tmp_path / "tri.ply"
    obj_to_ply.write_ply(ply, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    rays: list[tuple[str, list[float], list[float]]] = [
        ("front", [-0.2, 0.2, 1.0], [0.0, 0.0, -1.0]),
        ("back", [-0.2, 0.2, -1.0], [0.0, 0.0, 1.0]),
    ]
    for sx in (1, -1):
        mesh = {"file": str(ply), "transform": [{"matrix": [sx, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}]}
        cfg = {
            "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 45},
            "film": {"width": 4, "height": 4},
            "materials": {},
            "shapes": [],
            "lights": [{"name": "panel", "mesh": mesh, "radiance": [1.0, 2.0, 3.0], "two_sided": False}],
        }
        # Mirrored, the triangle lies at x < 0; unmirrored at x > 0.
        shot = [[n, [o[0] * -sx, *o[1:]], d] for n, o, d in rays]
        out = probe(tmp_path, cfg, [0, 0, 0], "tri.ply", shot)
        entry = out["light_00_panel"]
        assert entry["emitter"] is True and entry["flip_normals"] is (sx < 0)
        # Recentring counts a mesh light as its bounding box's centre.
        assert out["recentre"] == pytest.approx([0.5 * sx, 0.5, 0.0], abs=1e-7)
        assert out["probes"]["front"]["t"] == pytest.approx(1.0, abs=1e-6)
        assert out["probes"]["front"]["le"] == pytest.approx([1.0, 2.0, 3.0], rel=1e-6)
        assert out["probes"]["back"]["t"] == pytest.approx(1.0, abs=1e-6)
        assert out["probes"]["back"]["le"] == [0.0, 0.0, 0.0]


@needs_mitsuba
@needs_renderer
def test_7_small_mesh_scene_agrees_with_mitsuba_on_the_mesh(tmp_path: Path) -> None:
    # 64 x 64, 256 spp each, the portal strategy: a few seconds.
    python = mitsuba_python()
    assert python is not None
    cmd = [python, str(SCRIPT), "--scene", str(SCENE), "--renderer", str(renderer()), "--strategy", "portal"]
    cmd += ["--ours-spp", "256", "--mitsuba-spp", "256", "--mitsuba-runs", "16"]
    cmd += ["--set", "film.width=64", "--set", "film.height=64", "--out", str(tmp_path)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    s = json.loads((tmp_path / "summary.json").read_text())["stats"]
    head = s["focus"]["lamp_head"]
    assert head["blocks"] > 0 and head["pixels"] > 50
    for r, e in zip(head["ratio_ours_over_mitsuba"], head["ratio_sigma"], strict=True):
        assert abs(r - 1.0) < 5 * e


QUADRATURE = r"""
import json, sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import mitsuba as mi
mi.set_variant("scalar_rgb")
import mitsuba_lampshade as xcheck
import point_probe

cfg = json.loads(sys.argv[3])
scene = mi.load_dict(xcheck.build_scene_dict(cfg, {"type": "direct"}, Path(sys.argv[2]), 1, [0, 0, 0]), optimize=False)
p, n = (0.3, 0.0, -0.2), (0.0, 1.0, 0.0)
out = {m: point_probe.quadrature(scene, cfg, [0, 0, 0], p, n, [0.5, 0.5, 0.5], m, 40) for m in point_probe.MODELS}
print(json.dumps(out))
"""


@needs_mitsuba
def test_8_point_quadrature_matches_lamberts_closed_form(tmp_path: Path) -> None:
    # A square light 1 above a floor point, nothing in between: all three
    # shadow-ray models must give Lambert's irradiance times albedo / pi.
    python = mitsuba_python()
    assert python is not None
    light = [[-0.5, 1.0, -0.5], [0.5, 1.0, -0.5], [0.5, 1.0, 0.5], [-0.5, 1.0, 0.5]]  # emits down
    cfg = {
        "camera": {"position": [0, 2, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 45},
        "film": {"width": 4, "height": 4},
        "materials": {"grey": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
        "shapes": [
            {"name": "floor", "type": "mesh", "material": "grey", "quads": [[0, 1, 2, 3]],
             "vertices": [[-3, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]]}
        ],
        "lights": [{"name": "lamp", "vertices": light, "radiance": [2.0, 2.0, 2.0], "two_sided": False}],
    }  # fmt: skip
    proc = subprocess.run(
        [python, "-c", QUADRATURE, str(TOOL_DIR), str(tmp_path), json.dumps(cfg)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    # Lambert: E = L / 2 sum_i angle(v_i, v_i+1) (n . unit(v_i x v_i+1)), v_i the
    # unit directions from p to the corners, in the order that makes E > 0.
    p = (0.3, 0.0, -0.2)
    v = []
    for q in light:
        d = [q[k] - p[k] for k in range(3)]
        r = math.sqrt(sum(x * x for x in d))
        v.append([x / r for x in d])
    e = 0.0
    for i in range(4):
        a, b = v[i], v[(i + 1) % 4]
        c = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        cn = math.sqrt(sum(x * x for x in c))
        e += math.acos(max(-1.0, min(1.0, sum(x * y for x, y in zip(a, b, strict=True))))) * c[1] / cn
    want = abs(e) / 2 * 2.0 * 0.5 / math.pi
    for model in ("exact", "mitsuba", "ours"):
        # 2 x 40 x 40 stratified samples of a smooth integrand: well within 0.5%.
        assert out[model] == pytest.approx([want] * 3, rel=5e-3), model
