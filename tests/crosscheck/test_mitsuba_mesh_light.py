"""Tests of the cross-check's mesh lights (tools/crosscheck/mitsuba_lampshade.py)
on the two mesh-light scenes of tests/configs/good: mesh_light_sphere.yaml
(an 80-triangle UV sphere emitting outwards, moved by a transform) and
mesh_light_grid.yaml (the lampshade's square lamp as 12 triangles emitting
down).

Not part of `make test` (like the other files here). Test 1 needs our render
binary alone; tests 2-4 also need a python that imports mitsuba (this one or
.venv-xcheck's) and are skipped without it.

    .venv-xcheck/bin/python -m pytest -q tests/crosscheck
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
TOOL_DIR = REPO / "tools" / "crosscheck"
SCRIPT = TOOL_DIR / "mitsuba_lampshade.py"
SPHERE = REPO / "tests" / "configs" / "good" / "mesh_light_sphere.yaml"
GRID = REPO / "tests" / "configs" / "good" / "mesh_light_grid.yaml"
MESHES = REPO / "tests" / "configs" / "meshes"
sys.path.insert(0, str(TOOL_DIR))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import mitsuba_lampshade as xcheck  # noqa: E402  (stdlib-only at import time)
import obj_to_ply  # noqa: E402
from test_mitsuba_lampshade import mitsuba_python, renderer  # noqa: E402
from test_mitsuba_mesh import print_config  # noqa: E402

needs_mitsuba = pytest.mark.skipif(
    mitsuba_python() is None, reason="mitsuba is not importable (create .venv-xcheck: see tools/crosscheck/README.md)"
)
needs_renderer = pytest.mark.skipif(renderer() is None, reason="our render binary is not built")

Vec = tuple[float, float, float]


def sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def unit(a: Vec) -> Vec:
    n = math.sqrt(sum(x * x for x in a))
    return (a[0] / n, a[1] / n, a[2] / n)


IDENTITY = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]


def matrix(mesh: dict[str, Any]) -> list[float]:
    """The effective config's one row-major matrix (none: the identity)."""
    ops = mesh.get("transform") or [{"matrix": IDENTITY}]
    (only,) = ops
    return [float(x) for x in only["matrix"]]


def world_triangles(mesh: dict[str, Any], offset: Vec) -> list[tuple[Vec, Vec, Vec]]:
    """The mesh light's triangles in Mitsuba's world, from the OBJ file read
    here (obj_to_ply's reader) and the effective config's one matrix, in the
    file's winding."""
    vertices, triangles = obj_to_ply.read_obj(Path(mesh["file"]))
    m = matrix(mesh)

    def place(v: Vec) -> Vec:
        r = [m[4 * i] * v[0] + m[4 * i + 1] * v[1] + m[4 * i + 2] * v[2] + m[4 * i + 3] - offset[i] for i in range(3)]
        return (r[0], r[1], r[2])

    return [(place(vertices[a]), place(vertices[b]), place(vertices[c])) for a, b, c in triangles]


# The Mitsuba side, run by mitsuba_python(): the scene dict of our effective
# config (recentred as the script does), the light's dict entry, its faces as
# Mitsuba loaded them, and rays shot at it.
PROBE = r"""
import json, sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import mitsuba as mi
mi.set_variant("scalar_rgb")
import mitsuba_lampshade as xcheck

cfg = json.loads(sys.argv[3])
offset = xcheck.recentre_offset(cfg)
sd = xcheck.build_scene_dict(cfg, {"type": "direct"}, Path(sys.argv[2]), 1, offset)
scene = mi.load_dict(sd, optimize=False)
out = {"offset": offset, "lights": {}}
for shape in scene.shapes():
    key = shape.id()
    if not key.startswith("light_"):
        continue
    entry = dict(sd[key])
    m = entry.pop("to_world").matrix
    entry["to_world"] = [[float(m[i][j]) for j in range(4)] for i in range(4)]
    pos = [float(x) for x in shape.vertex_positions_buffer()]
    corners = [pos[3 * int(i) : 3 * int(i) + 3] for i in shape.faces_buffer()]
    out["lights"][key] = {
        "entry": entry,
        "emits": shape.emitter() is not None,
        "triangles": [corners[3 * f : 3 * f + 3] for f in range(shape.face_count())],
    }
probes = []
for o, d in json.loads(sys.argv[4]):
    si = scene.ray_intersect(mi.Ray3f(o, d))
    em = si.emitter(scene) if si.is_valid() else None
    le = em.eval(si) if em is not None else [0.0, 0.0, 0.0]
    probes.append({"t": float(si.t), "n": [float(x) for x in si.n], "le": [float(x) for x in le]})
out["probes"] = probes
print(json.dumps(out))
"""


def probe(tmp_path: Path, cfg: dict[str, Any], rays: list[tuple[Vec, Vec]]) -> dict[str, Any]:
    python = mitsuba_python()
    assert python is not None  # needs_mitsuba
    args = [python, "-c", PROBE, str(TOOL_DIR), str(tmp_path), json.dumps(cfg), json.dumps(rays)]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out: dict[str, Any] = json.loads(proc.stdout.strip().splitlines()[-1])
    return out


def canonical(tri: list[Any]) -> tuple[tuple[float, ...], ...]:
    """A triangle's corners rounded to 1e-5, rotated (not reordered) so the
    smallest comes first: equal for the same winding, different if reversed."""
    pts = [tuple(round(float(x), 5) + 0.0 for x in p) for p in tri]
    k = pts.index(min(pts))
    return tuple(pts[k:] + pts[:k])


def check_mesh_light(tmp_path: Path, scene: Path, obj: str, offset_want: Vec, faces: int) -> list[Vec]:
    """The Mitsuba dict of the scene's one mesh light: our file, our matrix
    minus the recentring, face normals, the area emitter with our radiance,
    a black BSDF; every triangle in our winding, emitting on its winding's
    side with Mitsuba's normal = ours, and dark from behind. Returns the
    triangles' normals (ours)."""
    cfg = print_config(scene)
    (light,) = cfg["lights"]
    assert "mesh" in light and light["two_sided"] is False
    # Where the recentring will move the light: its bounding box's centre.
    tris = world_triangles(light["mesh"], (0.0, 0.0, 0.0))
    assert len(tris) == faces
    lo = [min(p[i] for t in tris for p in t) for i in range(3)]
    hi = [max(p[i] for t in tris for p in t) for i in range(3)]
    assert [(a + b) / 2 for a, b in zip(lo, hi, strict=True)] == pytest.approx(offset_want, abs=1e-6)
    tris = world_triangles(light["mesh"], offset_want)
    # A ray at each triangle's centroid along its normal (ours: the winding's
    # right-hand rule), from 1 cm in front and from 1 cm behind.
    normals = [unit(cross(sub(b, a), sub(c, a))) for a, b, c in tris]
    centres = [tuple(sum(p[i] for p in t) / 3 for i in range(3)) for t in tris]
    rays: list[tuple[Vec, Vec]] = []
    for n, c in zip(normals, centres, strict=True):
        rays.append(((c[0] + 0.01 * n[0], c[1] + 0.01 * n[1], c[2] + 0.01 * n[2]), (-n[0], -n[1], -n[2])))
        rays.append(((c[0] - 0.01 * n[0], c[1] - 0.01 * n[1], c[2] - 0.01 * n[2]), n))
    out = probe(tmp_path, cfg, rays)
    assert out["offset"] == pytest.approx(offset_want, abs=1e-6)
    (key,) = out["lights"]
    assert key == f"light_00_{light['name']}"
    got = out["lights"][key]
    entry = got["entry"]
    assert entry["type"] == "obj" and Path(entry["filename"]) == (MESHES / obj).resolve()
    assert entry["face_normals"] is True and entry["flip_normals"] is False
    assert entry["emitter"] == {"type": "area", "radiance": {"type": "rgb", "value": light["radiance"]}}
    assert entry["bsdf"]["type"] == "twosided" and entry["bsdf"]["material"]["reflectance"]["value"] == [0, 0, 0]
    flat = matrix(light["mesh"])
    want = [flat[4 * i : 4 * i + 4] for i in range(4)]
    for i in range(3):
        want[i][3] -= offset_want[i]
    for i in range(4):
        assert entry["to_world"][i] == pytest.approx(want[i], abs=1e-6)  # Mitsuba keeps it in float32
    # Mitsuba's triangles are ours, corner for corner and in the same winding.
    assert got["emits"] is True
    assert sorted(canonical(list(t)) for t in got["triangles"]) == sorted(canonical(list(t)) for t in tris)
    radiance = [float(x) for x in light["radiance"]]
    for f in range(faces):
        front, back = out["probes"][2 * f], out["probes"][2 * f + 1]
        assert front["t"] == pytest.approx(0.01, abs=1e-5) and back["t"] == pytest.approx(0.01, abs=1e-5)
        assert front["n"] == pytest.approx(normals[f], abs=1e-5)  # the side Mitsuba emits on
        assert front["le"] == pytest.approx(radiance, rel=1e-6)
        assert back["le"] == [0.0, 0.0, 0.0]
    return normals


@needs_renderer
def test_1_our_effective_config_names_the_file_and_one_matrix() -> None:
    # The form the converter reads: {name, mesh: {file, transform: [{matrix}],
    # digest}, radiance, two_sided}; file_mesh_shape turns the mesh into the
    # `obj` shape on the same file with the transform minus the recentring.
    cfg = print_config(SPHERE)
    (light,) = cfg["lights"]
    mesh = light["mesh"]
    assert Path(mesh["file"]) == (MESHES / "lamp_sphere.obj").resolve()
    assert mesh["digest"]["fnv1a64"] == xcheck.fnv1a64(Path(mesh["file"]))
    assert light["radiance"] == [30, 25, 20] and light["two_sided"] is False
    shape = xcheck.file_mesh_shape(mesh, [0.05, 2.45, 0.0], "bulb")
    assert shape == {
        "type": "obj",
        "filename": mesh["file"],
        "to_world": [[1, 0, 0, 0], [0, 1, 0, -2.45], [0, 0, 1, 0], [0, 0, 0, 1]],
        "face_normals": True,
        "flip_normals": False,
    }
    assert "transform" not in print_config(GRID)["lights"][0]["mesh"]


@needs_mitsuba
@needs_renderer
def test_2_the_sphere_bulb_emits_outwards_from_every_triangle(tmp_path: Path) -> None:
    # Centre (0, 2.45, 0) in the file, moved 5 cm in x by the transform.
    normals = check_mesh_light(tmp_path, SPHERE, "lamp_sphere.obj", (0.05, 2.45, 0.0), 80)
    # The file's winding faces outwards (so a reversed converter would leave
    # the inside lit and the room dark): each normal points away from the
    # centre, which the recentring put at the origin.
    cfg = print_config(SPHERE)
    tris = world_triangles(cfg["lights"][0]["mesh"], (0.05, 2.45, 0.0))
    for n, t in zip(normals, tris, strict=True):
        c = [sum(p[i] for p in t) / 3 for i in range(3)]
        assert sum(n[i] * c[i] for i in range(3)) > 0.9 * math.sqrt(sum(x * x for x in c))


@needs_mitsuba
@needs_renderer
def test_3_the_grid_lamp_emits_down_from_every_triangle(tmp_path: Path) -> None:
    normals = check_mesh_light(tmp_path, GRID, "lamp_grid.obj", (0.0, 2.6, 0.0), 12)
    for n in normals:
        assert n == pytest.approx((0.0, -1.0, 0.0), abs=1e-12)


@needs_mitsuba
def test_4_two_sided_mesh_lights_are_refused(tmp_path: Path) -> None:
    ply = tmp_path / "tri.ply"
    obj_to_ply.write_ply(ply, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    python = mitsuba_python()
    assert python is not None
    cfg = {
        "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 45},
        "film": {"width": 4, "height": 4},
        "materials": {},
        "shapes": [],
        "lights": [{"name": "panel", "mesh": {"file": str(ply)}, "radiance": [1, 1, 1], "two_sided": True}],
    }
    code = (
        "import json, sys; from pathlib import Path; sys.path.insert(0, sys.argv[1]);"
        "import mitsuba as mi; mi.set_variant('scalar_rgb'); import mitsuba_lampshade as x\n"
        "try:\n x.build_scene_dict(json.loads(sys.argv[3]), {'type': 'direct'}, Path(sys.argv[2]), 1)\n"
        "except x.SetupError as e:\n print('refused:', e)"
    )
    proc = subprocess.run(
        [python, "-c", code, str(TOOL_DIR), str(tmp_path), json.dumps(cfg)], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    assert "refused: light 'panel': two-sided" in proc.stdout


@needs_mitsuba
@needs_renderer
def test_5_small_sphere_scene_agrees_with_mitsuba(tmp_path: Path) -> None:
    # 64 x 64, 256 spp each, antishadow_exact: a few seconds.
    python = mitsuba_python()
    assert python is not None
    cmd = [python, str(SCRIPT), "--scene", str(SPHERE), "--renderer", str(renderer()), "--strategy", "antishadow_exact"]
    cmd += ["--ours-spp", "256", "--mitsuba-spp", "256", "--mitsuba-runs", "16"]
    cmd += ["--set", "film.width=64", "--set", "film.height=64", "--out", str(tmp_path)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    s = json.loads((tmp_path / "summary.json").read_text())["stats"]
    # The whole image within 5 sigma of Mitsuba's (a bulb emitting inwards
    # would leave it black).
    for r, e in zip(s["mean_ratio_ours_over_mitsuba"], s["mean_ratio_sigma"], strict=True):
        assert abs(r - 1.0) < 5 * e


@needs_mitsuba
def test_6_vertex_normals_in_the_file_do_not_turn_the_emitting_side(tmp_path: Path) -> None:
    # Ours ignores an OBJ's `vn` (the winding decides). Mitsuba emits on the
    # side of its shading normal, which without face_normals would follow
    # the file's `vn` (measured: a triangle wound towards +z with vn = -z
    # then emits towards -z only). The converter's face_normals keeps it on
    # the winding's side.
    obj = tmp_path / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 -1\nf 1//1 2//1 3//1\n")
    cfg = {
        "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_y": 45},
        "film": {"width": 4, "height": 4},
        "materials": {},
        "shapes": [],
        "lights": [{"name": "panel", "mesh": {"file": str(obj)}, "radiance": [1.0, 2.0, 3.0], "two_sided": False}],
    }
    # Recentred to the bounding box's centre (0.5, 0.5, 0): the triangle's
    # point (0.2, 0.2) is at (-0.3, -0.3).
    rays: list[tuple[Vec, Vec]] = [((-0.3, -0.3, 1.0), (0.0, 0.0, -1.0)), ((-0.3, -0.3, -1.0), (0.0, 0.0, 1.0))]
    out = probe(tmp_path, cfg, rays)
    front, back = out["probes"]
    assert front["t"] == pytest.approx(1.0, abs=1e-6) and back["t"] == pytest.approx(1.0, abs=1e-6)
    assert front["le"] == pytest.approx([1.0, 2.0, 3.0], rel=1e-6)
    assert back["le"] == [0.0, 0.0, 0.0]
    assert front["n"] == pytest.approx([0.0, 0.0, 1.0], abs=1e-6)
    assert out["lights"]["light_00_panel"]["entry"]["face_normals"] is True
