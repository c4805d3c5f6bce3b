"""`portal-harness import-mitsuba`: every supported Mitsuba feature, every
warning and error, the safe-parsing refusals, and an end-to-end render of an
imported scene against a hand-written equivalent with the real renderer.
Fixtures are small XML files written into tmp_path."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path
from typing import Any

import matplotlib.image
import numpy as np
import pytest
import yaml
from conftest import REPO

from portal_harness import cli
from portal_harness.core import exr
from portal_harness.mitsuba_import import MitsubaImportError, import_scene
from portal_harness.mitsuba_import.report import Report
from portal_harness.mitsuba_import.scene import convert
from portal_harness.mitsuba_import.sensor import fov_y
from portal_harness.mitsuba_import.tessellate import cube, cylinder, disk, sphere
from portal_harness.mitsuba_import.transforms import parse_transform
from portal_harness.mitsuba_import.xmltree import parse_file

LAMP = REPO.parent / "shared" / "assets" / "little_lamp" / "lamp_reproduce.xml"
CAMERA = """
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 1, 6" target="0, 1, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="24"/></film>
  </sensor>"""
LIGHT = """
  <shape type="rectangle" id="lamp">
    <transform name="to_world"><rotate x="1" angle="90"/><translate y="3"/></transform>
    <emitter type="area"><rgb name="radiance" value="5, 4, 3"/></emitter>
    <bsdf type="diffuse"><rgb name="reflectance" value="0 0 0"/></bsdf>
  </shape>"""
TRIANGLE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def scene_xml(body: str, camera: bool = True, light: bool = True) -> str:
    return f'<scene version="3.0.0">{CAMERA if camera else ""}{LIGHT if light else ""}{body}\n</scene>\n'


def write(tmp_path: Path, body: str, name: str = "scene.xml", **kw: bool) -> Path:
    path = tmp_path / name
    path.write_text(scene_xml(body, **kw))
    return path


def run_import(xml: Path, **kw: Any) -> tuple[dict[str, Any], list[str], Path]:
    out = xml.parent / "out"
    path, report = import_scene(xml, out, **kw)
    return yaml.safe_load(path.read_text()), report.lines(), out


def warned(lines: list[str], *words: str) -> list[str]:
    return [w for w in lines if all(x in w for x in words)]


def line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


# ---------------------------------------------------------------- parsing


def test_01_defaults_and_parameters_are_substituted(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<default name="w" value="40"/><default name="refl" value="0.25"/>'
        '<shape type="cube"><bsdf type="twosided"><bsdf type="diffuse">'
        '<rgb name="reflectance" value="$refl, $refl, 0.5"/></bsdf></bsdf></shape>',
    )
    doc, _, _ = run_import(xml)
    assert list(doc["materials"].values()) == [{"type": "diffuse", "albedo": [0.25, 0.25, 0.5]}]
    out, _ = convert(xml, defines={"refl": "0.75"})
    assert next(iter(out.materials.values()))["albedo"] == [0.75, 0.75, 0.5]


def test_02_undefined_parameter_is_an_error_at_its_line(tmp_path: Path) -> None:
    xml = write(tmp_path, '<shape type="cube"><float name="x" value="$nope"/></shape>')
    with pytest.raises(MitsubaImportError) as e:
        convert(xml)
    assert e.value.line == line_of(xml.read_text(), "$nope") and "$nope" in str(e.value)


def test_03_elements_know_their_lines(tmp_path: Path) -> None:
    xml = tmp_path / "s.xml"
    xml.write_text('<scene version="3.0.0">\n\n  <shape type="cube">\n    <ref id="x"/>\n  </shape>\n</scene>\n')
    root = parse_file(xml)
    assert root.line == 1 and root.children[0].line == 3 and root.children[0].children[0].line == 4


BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE lolz [
 <!ENTITY lol "lol">
 <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
 <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
]>
<scene version="3.0.0"><shape type="obj"><string name="filename" value="&lol4;"/></shape></scene>
"""
EXTERNAL = """<?xml version="1.0"?>
<!DOCTYPE scene [<!ENTITY secret SYSTEM "file:///etc/passwd">]>
<scene version="3.0.0"><shape type="obj"><string name="filename" value="&secret;"/></shape></scene>
"""
EXTERNAL_DTD = """<?xml version="1.0"?>
<!DOCTYPE scene SYSTEM "http://example.invalid/scene.dtd">
<scene version="3.0.0"/>
"""


@pytest.mark.parametrize("text", [BILLION_LAUGHS, EXTERNAL, EXTERNAL_DTD], ids=["laughs", "entity", "dtd"])
def test_04_entities_and_dtds_are_refused(tmp_path: Path, text: str) -> None:
    xml = tmp_path / "evil.xml"
    xml.write_text(text)
    with pytest.raises(MitsubaImportError) as e:
        import_scene(xml, tmp_path / "out")
    assert e.value.line == 2 and "refused" in str(e.value)
    assert not (tmp_path / "out").exists()


def test_05_malformed_xml_names_its_line(tmp_path: Path) -> None:
    xml = tmp_path / "bad.xml"
    xml.write_text('<scene version="3.0.0">\n<shape type="cube">\n</scene>\n')
    with pytest.raises(MitsubaImportError) as e:
        convert(xml)
    assert e.value.line == 3 and "malformed XML" in str(e.value)


# ---------------------------------------------------------------- transforms


def _renderer_compose(ops: list[dict[str, Any]]) -> np.ndarray:
    """The renderer's reading of a transform list: each op applied after the previous ones."""
    total = np.eye(4)
    for op in ops:
        m = np.eye(4)
        if "translate" in op:
            m[:3, 3] = op["translate"]
        elif "scale" in op:
            m[:3, :3] = np.diag(np.broadcast_to(op["scale"], 3))
        elif "rotate" in op:
            k = np.array(op["rotate"]["axis"], float)
            k /= np.linalg.norm(k)
            t = math.radians(op["rotate"]["angle"])
            kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            m[:3, :3] = np.eye(3) + math.sin(t) * kx + (1 - math.cos(t)) * kx @ kx
        else:
            m = np.array(op["matrix"]).reshape(4, 4)
        total = m @ total
    return total


def test_06_transforms_compose_in_mitsubas_order(tmp_path: Path) -> None:
    xml = tmp_path / "t.xml"
    xml.write_text(
        '<scene version="3.0.0"><transform name="to_world">'
        '<scale value="2"/><rotate y="1" angle="90"/><translate x="1" y="2" z="3"/>'
        '<scale x="1" y="3" z="1"/><matrix value="1 0 0 5 0 1 0 0 0 0 1 0 0 0 0 1"/>'
        "</transform></scene>"
    )
    tr = parse_file(xml).children[0]
    ops, m = parse_transform(tr, Report(str(xml)))
    assert [next(iter(op)) for op in ops] == [
        "scale",
        "rotate",
        "translate",
        "scale",
        "matrix",
    ]
    # (1, 0, 0): scaled to (2, 0, 0), rotated about +y by 90 degrees to (0, 0, -2), translated to (1, 2, 1),
    # scaled in y to (1, 6, 1), shifted in x to (6, 6, 1).
    assert np.allclose(m @ [1, 0, 0, 1], [6, 6, 1, 1])
    assert np.allclose(_renderer_compose(ops), m)


def test_07_lookat_is_mitsubas_basis(tmp_path: Path) -> None:
    xml = tmp_path / "t.xml"
    xml.write_text(
        '<scene version="3.0.0"><transform name="to_world">'
        '<lookat origin="1, 2, 3" target="1, 2, 10" up="0, 1, 0"/></transform></scene>'
    )
    ops, m = parse_transform(parse_file(xml).children[0], Report(str(xml)))
    # Local +z towards the target, +y up, +x = up x dir (left).
    assert np.allclose(m[:3, 2], [0, 0, 1]) and np.allclose(m[:3, 1], [0, 1, 0]) and np.allclose(m[:3, 0], [1, 0, 0])
    assert np.allclose(m[:3, 3], [1, 2, 3]) and np.allclose(_renderer_compose(ops), m)


def test_08_singular_transform_is_an_error(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<shape type="cube"><transform name="to_world"><scale z="0"/></transform></shape>',
    )
    with pytest.raises(MitsubaImportError, match="singular"):
        convert(xml)


# ---------------------------------------------------------------- shapes


def test_09_file_meshes_are_copied_with_relative_paths(tmp_path: Path) -> None:
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "tri.obj").write_text(TRIANGLE_OBJ)
    (tmp_path / "models" / "tri.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    )
    xml = write(
        tmp_path,
        '<shape type="obj" id="a"><string name="filename" value="models/tri.obj"/>'
        '<transform name="to_world"><translate x="1"/></transform></shape>'
        '<shape type="ply" id="b"><string name="filename" value="models/tri.ply"/></shape>'
        '<shape type="obj" id="c"><string name="filename" value="models/tri.obj"/></shape>',
    )
    doc, _, out = run_import(xml)
    a, b, c = doc["shapes"]
    assert a["type"] == "mesh" and a["file"] == "meshes/tri.obj" and a["transform"] == [{"translate": [1.0, 0.0, 0.0]}]
    assert b["file"] == "meshes/tri.ply" and c["file"] == "meshes/tri.obj"  # one copy per source
    assert (out / "meshes" / "tri.obj").read_text() == TRIANGLE_OBJ


def test_10_rectangle_and_cube_are_quad_and_box(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<shape type="rectangle"><transform name="to_world"><scale value="3"/></transform></shape><shape type="cube"/>',
    )
    doc, lines, _ = run_import(xml)
    quad, box = doc["shapes"]
    assert quad["type"] == "quad" and quad["vertices"] == [
        [-1, -1, 0],
        [1, -1, 0],
        [1, 1, 0],
        [-1, 1, 0],
    ]
    assert quad["transform"] == [{"scale": 3.0}]
    assert box == {
        "name": box["name"],
        "material": "mitsuba_default",
        "type": "box",
        "min": [-1, -1, -1],
        "max": [1, 1, 1],
    }
    assert len(warned(lines, "no BSDF")) == 1  # the default material is announced once


def _outward(verts: np.ndarray, faces: list[tuple[int, int, int]], centre: np.ndarray) -> np.ndarray:
    v = verts[np.array(faces)]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return np.asarray(np.einsum("ij,ij->i", n, v.mean(axis=1) - centre))


def test_11_tessellations_wind_towards_mitsubas_normals() -> None:
    verts, faces = sphere(np.array([1.0, 2.0, 3.0]), 2.0)
    assert np.allclose(np.linalg.norm(verts - [1, 2, 3], axis=1), 2.0) and np.all(
        _outward(verts, faces, np.array([1.0, 2.0, 3.0])) > 0
    )
    verts, faces = cube()
    assert np.all(_outward(verts, faces, np.zeros(3)) > 0)
    verts, faces = cylinder(np.zeros(3), np.array([0.0, 0.0, 2.0]), 0.5)
    v = verts[np.array(faces)]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    radial = v.mean(axis=1) * [1, 1, 0]
    assert np.all(np.einsum("ij,ij->i", n, radial) > 0)
    verts, faces = disk()
    v = verts[np.array(faces)]
    assert np.all(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])[:, 2] > 0)


def test_12_sphere_cylinder_disk_become_obj_files(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<shape type="sphere" id="ball"><point name="center" x="0" y="1" z="0"/><float name="radius" value="0.5"/>'
        "</shape>"
        '<shape type="cylinder"><float name="radius" value="0.2"/></shape><shape type="disk"/>',
    )
    doc, lines, out = run_import(xml)
    files = [s["file"] for s in doc["shapes"]]
    assert files[0] == "meshes/ball.obj" and all((out / f).is_file() for f in files)
    v = np.array(
        [[float(x) for x in ln.split()[1:]] for ln in (out / files[0]).read_text().splitlines() if ln.startswith("v ")]
    )
    assert np.allclose(np.linalg.norm(v - [0, 1, 0], axis=1), 0.5)
    assert len(warned(lines, "tessellated")) == 3


def test_13_missing_mesh_is_an_error_naming_file_and_line(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<shape type="obj">\n<string name="filename" value="gone.obj"/></shape>',
    )
    with pytest.raises(MitsubaImportError) as e:
        import_scene(xml, tmp_path / "out")
    assert e.value.line == line_of(xml.read_text(), "gone.obj") and "gone.obj" in str(e.value)
    assert not (tmp_path / "out").exists()
    doc, lines, _ = run_import(xml, skip_missing=True)
    assert "shapes" not in doc and len(warned(lines, "gone.obj", "--skip-missing")) == 1


def test_14_unsupported_shapes_and_parameters_are_warned(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<shape type="heightfield"><string name="filename" value="x.exr"/></shape>'
        '<shape type="cube"><boolean name="odd" value="true"/></shape>'
        '<shape type="cube"><boolean name="odd" value="true"/></shape>',
    )
    _, lines, _ = run_import(xml)
    assert len(warned(lines, "heightfield", "skipped")) == 1
    odd = warned(lines, 'name="odd"')
    assert len(odd) == 1 and "also at lines" in odd[0]  # one message, both lines


# ---------------------------------------------------------------- BSDFs


def test_15_bsdfs_map_to_the_renderers_materials(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<bsdf type="twosided" id="metal"><bsdf type="roughconductor"><float name="alpha" value="0.3"/>'
        '<string name="distribution" value="ggx"/><rgb name="specular_reflectance" value="0.5"/></bsdf></bsdf>'
        '<bsdf type="twosided" id="gold"><bsdf type="conductor"><string name="material" value="Au"/></bsdf></bsdf>'
        '<bsdf type="twosided" id="coat"><bsdf type="roughplastic">'
        '<rgb name="diffuse_reflectance" value="0.1 0.2 0.3"/></bsdf></bsdf>'
        '<shape type="cube"><ref id="metal"/></shape><shape type="cube"><ref id="gold"/></shape>'
        '<shape type="cube"><ref id="coat"/></shape><shape type="cube"><ref id="metal"/></shape>',
    )
    doc, lines, _ = run_import(xml, smooth_alpha=0.001)
    m = doc["materials"]
    assert m["metal"] == {"type": "ggx", "albedo": [0.5, 0.5, 0.5], "roughness": 0.3}
    assert m["gold"] == {
        "type": "ggx",
        "albedo": [1.0, 0.782, 0.344],
        "roughness": 0.001,
    }
    assert m["coat"] == {"type": "diffuse", "albedo": [0.1, 0.2, 0.3]}
    assert [s["material"] for s in doc["shapes"]] == ["metal", "gold", "coat", "metal"]
    assert len(warned(lines, "smooth conductor", "0.001")) == 1
    assert len(warned(lines, "specular coat is dropped")) == 1
    assert len(warned(lines, "Schlick", "material none")) == 1  # once, though two shapes use it


def test_16_one_sided_beckmann_and_unknown_bsdfs_are_warned(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<shape type="cube"><bsdf type="diffuse"/></shape>'
        '<shape type="cube"><bsdf type="roughconductor"><float name="alpha" value="2"/></bsdf></shape>'
        '<shape type="cube"><bsdf type="principled"/></shape>',
    )
    doc, lines, _ = run_import(xml)
    assert len(warned(lines, "one-sided")) == 3
    assert warned(lines, "beckmann") and warned(lines, "clamped to 1")
    assert warned(lines, "'principled' not supported")
    assert sorted(m.get("roughness", 0) for m in doc["materials"].values()) == [
        0,
        0,
        1.0,
    ]


def test_17_dielectric_shapes_are_skipped(tmp_path: Path) -> None:
    xml = write(tmp_path, '<shape type="sphere"><bsdf type="dielectric"/></shape>')
    doc, lines, _ = run_import(xml)
    assert "shapes" not in doc and len(warned(lines, "dielectric", "shadow ray")) == 1
    assert not warned(lines, "tessellated")


def test_18_textures_become_their_mean_colour(tmp_path: Path) -> None:
    img = np.zeros((4, 4, 3))
    img[:, :2] = [1.0, 0.5, 0.0]  # sRGB; half the image black
    matplotlib.image.imsave(tmp_path / "tex.png", img)
    exr.write_exr(
        tmp_path / "tex.exr",
        {c: np.full((2, 2), v) for c, v in zip("RGB", (0.2, 0.4, 0.6), strict=True)},
        {},
    )
    xml = write(
        tmp_path,
        '<texture type="bitmap" id="png"><string name="filename" value="tex.png"/></texture>'
        '<shape type="cube"><bsdf type="diffuse" id="p"><ref name="reflectance" id="png"/></bsdf></shape>'
        '<shape type="cube"><bsdf type="diffuse" id="e"><texture type="bitmap" name="reflectance">'
        '<string name="filename" value="tex.exr"/></texture></bsdf></shape>'
        '<shape type="cube"><bsdf type="diffuse" id="m"><texture type="bitmap" name="reflectance">'
        '<string name="filename" value="missing.jpg"/></texture></bsdf></shape>'
        '<shape type="cube"><bsdf type="diffuse" id="c"><texture type="checkerboard" name="reflectance"/>'
        "</bsdf></shape>",
    )
    doc, lines, _ = run_import(xml)
    m = doc["materials"]
    half_srgb = ((0.5 + 0.055) / 1.055) ** 2.4
    assert np.allclose(m["p"]["albedo"], [0.5, half_srgb / 2, 0.0], atol=2e-3)
    assert np.allclose(m["e"]["albedo"], [0.2, 0.4, 0.6], atol=1e-6)
    assert m["m"]["albedo"] == [0.5, 0.5, 0.5] and warned(lines, "missing.jpg is missing", "grey 0.5")
    assert np.allclose(m["c"]["albedo"], [0.3, 0.3, 0.3])
    assert len(warned(lines, "mean colour")) == 3


# ---------------------------------------------------------------- emitters


def test_19_rectangle_emitter_is_a_polygon_light_facing_its_normal(
    tmp_path: Path,
) -> None:
    xml = write(tmp_path, "", light=True)
    doc, lines, _ = run_import(xml)
    (light,) = doc["lights"]
    assert light["name"] == "lamp" and light["radiance"] == [5, 4, 3] and light["two_sided"] is False
    m = _renderer_compose(light["transform"])
    v = np.array([(m @ [*p, 1])[:3] for p in light["vertices"]])
    normal = np.cross(v[1] - v[0], v[2] - v[0])
    # Mitsuba's normal +z, rotated 90 degrees about +x, points to -y: down from y = 3, as the winding does.
    assert np.allclose(v[:, 1], 3) and normal[1] < 0 and abs(normal[0]) + abs(normal[2]) < 1e-12
    assert not warned(lines, "of an emitter")  # its black diffuse BSDF changes nothing


def test_20_flip_normals_reverses_the_winding(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<shape type="rectangle" id="flipped"><boolean name="flip_normals" value="true"/>'
        '<emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>',
    )
    doc, _, _ = run_import(xml)
    v = np.array(doc["lights"][1]["vertices"])
    assert np.cross(v[1] - v[0], v[2] - v[0])[2] < 0


def test_21_mesh_emitters_are_mesh_lights(tmp_path: Path) -> None:
    (tmp_path / "bulb.obj").write_text(TRIANGLE_OBJ)
    xml = write(
        tmp_path,
        '<shape type="obj" id="bulb"><string name="filename" value="bulb.obj"/>'
        '<transform name="to_world"><scale value="0.5"/><translate value="1, 2, 3"/></transform>'
        '<emitter type="area"><spectrum name="radiance" value="50"/></emitter></shape>'
        '<shape type="obj" id="flipped"><string name="filename" value="bulb.obj"/>'
        '<boolean name="flip_normals" value="true"/><emitter type="area"/></shape>'
        '<shape type="sphere" id="globe"><emitter type="area"><rgb name="radiance" value="2"/></emitter></shape>',
    )
    doc, _lines, out = run_import(xml)
    _, bulb, flipped, globe = doc["lights"]
    assert bulb == {
        "name": "bulb",
        "mesh": {
            "file": "meshes/bulb.obj",
            "transform": [{"scale": 0.5}, {"translate": [1.0, 2.0, 3.0]}],
        },
        "radiance": [50.0, 50.0, 50.0],
        "two_sided": False,
    }
    assert flipped["mesh"]["file"] != "meshes/bulb.obj" and flipped["radiance"] == [
        1.0,
        1.0,
        1.0,
    ]
    assert "f 1 3 2" in (out / flipped["mesh"]["file"]).read_text()
    assert globe["mesh"]["file"] == "meshes/globe.obj" and (out / "meshes" / "globe.obj").is_file()
    assert "shapes" not in doc  # emitters are lights, not shapes as well


def test_22_other_emitters_are_skipped_with_a_warning(tmp_path: Path) -> None:
    xml = write(
        tmp_path,
        '<emitter type="point"/><emitter type="spot"/><emitter type="envmap">'
        '<string name="filename" value="sky.exr"/></emitter><emitter type="constant"/>',
    )
    doc, lines, _ = run_import(xml)
    assert len(doc["lights"]) == 1
    for kind in ("point", "spot", "envmap", "constant"):
        assert len(warned(lines, f"{kind} emitter skipped")) == 1


# ---------------------------------------------------------------- sensor and integrator


@pytest.mark.parametrize(
    ("axis", "expected"),
    [
        ("x", 2 * math.degrees(math.atan(math.tan(math.radians(30)) * 3 / 4))),
        ("y", 60.0),
        ("smaller", 60.0),
        ("larger", 2 * math.degrees(math.atan(math.tan(math.radians(30)) * 3 / 4))),
        ("diagonal", 2 * math.degrees(math.atan(math.tan(math.radians(30)) * 3 / 5))),
    ],
)
def test_23_fov_axes_become_fov_y(axis: str, expected: float) -> None:
    assert fov_y(60.0, axis, 400, 300) == pytest.approx(expected, abs=1e-12)


def test_24_sensor_becomes_camera_film_and_spp(tmp_path: Path) -> None:
    xml = tmp_path / "s.xml"
    xml.write_text(
        '<scene version="2.0.0"><default name="w" value="64"/>'
        '<sensor type="perspective"><float name="fov" value="90"/><string name="fov_axis" value="y"/>'
        '<transform name="to_world"><rotate y="1" angle="90"/><translate x="1" y="2" z="3"/></transform>'
        '<film type="hdrfilm"><integer name="width" value="$w"/><integer name="height" value="32"/>'
        '<rfilter type="gaussian"/></film>'
        '<sampler type="independent"><integer name="sample_count" value="16"/></sampler></sensor>'
        '<integrator type="path"><integer name="max_depth" value="5"/></integrator>' + LIGHT + "</scene>"
    )
    doc, lines, _ = run_import(xml)
    cam = doc["camera"]
    assert np.allclose(cam["position"], [1, 2, 3]) and np.allclose(cam["look_at"], [2, 2, 3])  # +z rotated to +x
    assert np.allclose(cam["up"], [0, 1, 0]) and cam["fov_y"] == pytest.approx(90.0)
    assert doc["film"] == {"width": 64, "height": 32}
    assert doc["render"]["spp"] == 16 and doc["render"]["integrator"] == "path" and doc["render"]["max_depth"] == 4
    assert warned(lines, "gaussian", "ignored")


def test_25_integrators(tmp_path: Path) -> None:
    body = '<integrator type="direct"/>'
    doc, lines, _ = run_import(write(tmp_path, body))
    assert doc["render"]["integrator"] == "direct" and not warned(lines, "<integrator")
    (tmp_path / "out").rename(tmp_path / "out1")
    doc, lines, _ = run_import(write(tmp_path, '<integrator type="bdpt"/>'))
    assert "integrator" not in doc["render"] and warned(lines, "'bdpt' ignored")
    (tmp_path / "out").rename(tmp_path / "out2")
    doc, lines, _ = run_import(write(tmp_path, '<integrator type="path"/>'))
    assert doc["render"]["max_depth"] == 64 and warned(lines, "unbounded max_depth")


def test_26_mirrored_camera_is_warned(tmp_path: Path) -> None:
    xml = tmp_path / "s.xml"
    xml.write_text(
        '<scene version="3.0.0"><sensor type="perspective"><transform name="to_world"><scale x="-1"/>'
        '<lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform></sensor>' + LIGHT + "</scene>"
    )
    _, lines, _ = run_import(xml)
    assert warned(lines, "mirrors the image")


# ---------------------------------------------------------------- command line


def test_27_cli_errors_exit_2_with_file_and_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xml = write(
        tmp_path,
        '<shape type="ply">\n<string name="filename" value="gone.ply"/></shape>',
    )
    assert cli.main(["import-mitsuba", str(xml), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"{xml}:{line_of(xml.read_text(), 'gone.ply')}: mesh file gone.ply not found" in err
    assert not (tmp_path / "out").exists()
    assert (
        cli.main(
            [
                "import-mitsuba",
                str(xml),
                "--out",
                str(tmp_path / "out"),
                "--skip-missing",
            ]
        )
        == 0
    )
    captured = capsys.readouterr()
    assert "warning:" in captured.err and "scene.yaml" in captured.out
    # An existing, non-empty folder is not overwritten without --force.
    assert (
        cli.main(
            [
                "import-mitsuba",
                str(xml),
                "--out",
                str(tmp_path / "out"),
                "--skip-missing",
            ]
        )
        == 2
    )
    args = [
        "import-mitsuba",
        str(xml),
        "--out",
        str(tmp_path / "out"),
        "--skip-missing",
        "--force",
    ]
    assert cli.main(args) == 0


def test_28_little_lamp_imports_with_skip_missing(tmp_path: Path) -> None:
    if not LAMP.is_file():
        pytest.skip("the Little Lamp assets are not on this machine")
    with pytest.raises(MitsubaImportError) as e:
        import_scene(LAMP, tmp_path / "strict")
    assert e.value.line == 149 and "models/box.obj" in str(e.value)
    path, report = import_scene(LAMP, tmp_path / "ll", skip_missing=True)
    doc = yaml.safe_load(path.read_text())
    lines = report.lines()
    for missing in ("Mesh017.obj", "Mesh001.obj", "Mesh049.obj", "box.obj"):
        assert len(warned(lines, missing, "skipped")) == 1
    (light,) = doc["lights"]
    assert light["mesh"]["file"] == "meshes/spemitter.obj" and light["radiance"] == [50000.0] * 3
    assert doc["film"] == {"width": 1000, "height": 1000} and doc["camera"]["fov_y"] == pytest.approx(42.0)
    assert warned(lines, "dielectric") and warned(lines, "envmap") and warned(lines, "manifold_path_guiding")
    assert all((path.parent / s["file"]).is_file() for s in doc["shapes"] if "file" in s)


# ---------------------------------------------------------------- end to end


E2E_BODY = """
  <integrator type="direct"/>
  <shape type="cube">
    <transform name="to_world"><scale x="0.5" y="0.5" z="0.5"/><translate x="-1" y="0.5" z="0"/></transform>
    <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.6 0.5 0.4"/></bsdf></bsdf>
  </shape>
  <shape type="obj">
    <string name="filename" value="floor.obj"/>
    <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></bsdf>
  </shape>
  <shape type="sphere">
    <point name="center" x="1" y="0.6" z="0"/><float name="radius" value="0.6"/>
    <bsdf type="twosided"><bsdf type="roughconductor"><float name="alpha" value="0.2"/>
      <string name="distribution" value="ggx"/></bsdf></bsdf>
  </shape>"""
FLOOR_OBJ = "v -4 0 -4\nv -4 0 4\nv 4 0 4\nv 4 0 -4\nf 1 2 3 4\n"


def _render(renderer: Path, config: Path, out: Path) -> exr.Snapshot:
    proc = subprocess.run(
        [
            str(renderer),
            str(config),
            "--out",
            str(out),
            "--spp",
            "8",
            "--time",
            "0",
            "--seed",
            "3",
            "--threads",
            "1",
            "--set",
            "film.width=32",
            "--set",
            "film.height=24",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    return exr.read_snapshot(out / "final.exr")


@pytest.mark.real
def test_29_imported_scene_renders_as_its_hand_written_equivalent(real_renderer: Path, tmp_path: Path) -> None:
    (tmp_path / "floor.obj").write_text(FLOOR_OBJ)
    xml = write(tmp_path, E2E_BODY)
    path, _ = import_scene(xml, tmp_path / "imported")
    sphere_obj = tmp_path / "imported" / yaml.safe_load(path.read_text())["shapes"][2]["file"]
    # The same scene written by hand: camera, box, light and floor in world
    # coordinates, the sphere from the tessellation the importer wrote.
    hand = {
        "camera": {
            "position": [0, 1, 6],
            "look_at": [0, 1, 0],
            "up": [0, 1, 0],
            "fov_y": 2 * math.degrees(math.atan(math.tan(math.radians(20)) * 24 / 32)),
        },
        "film": {"width": 32, "height": 24},
        "materials": {
            "box": {"type": "diffuse", "albedo": [0.6, 0.5, 0.4]},
            "floor": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]},
            "metal": {"type": "ggx", "albedo": [1, 1, 1], "roughness": 0.2},
        },
        "shapes": [
            {
                "type": "box",
                "material": "box",
                "min": [-1.5, 0, -0.5],
                "max": [-0.5, 1, 0.5],
            },
            {
                "type": "mesh",
                "material": "floor",
                "vertices": [[-4, 0, -4], [-4, 0, 4], [4, 0, 4], [4, 0, -4]],
                "quads": [[0, 1, 2, 3]],
            },
            {"type": "mesh", "material": "metal", "file": str(sphere_obj)},
        ],
        # Mitsuba's rectangle rotated 90 degrees about +x at y = 3: emitting downwards.
        "lights": [
            {
                "name": "lamp",
                "vertices": [[-1, 3, -1], [1, 3, -1], [1, 3, 1], [-1, 3, 1]],
                "radiance": [5, 4, 3],
                "two_sided": False,
            }
        ],
        "render": {"integrator": "direct", "spp": 8},
    }
    hand_path = tmp_path / "hand.yaml"
    hand_path.write_text(yaml.safe_dump(hand))
    a = _render(real_renderer, path, tmp_path / "ra")
    b = _render(real_renderer, hand_path, tmp_path / "rb")
    assert a.rgb.mean() > 0.01  # lit
    # Same seed, same geometry up to the rounding of the transforms: most
    # pixels are bit for bit the same, the others differ in the last float bits.
    assert (a.rgb == b.rgb).all(axis=-1).mean() > 0.5
    assert np.allclose(a.rgb, b.rgb, rtol=1e-5, atol=1e-7)
    cams = []
    for config in (path, hand_path):
        proc = subprocess.run(
            [str(real_renderer), "--print-config", str(config), "--format", "json"],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert proc.returncode == 0, proc.stderr
        cams.append(json.loads(proc.stdout)["config"]["camera"])
    for key in ("position", "up"):
        assert np.allclose(cams[0][key], cams[1][key])
    dirs = [np.subtract(c["look_at"], c["position"]) for c in cams]
    assert np.allclose(dirs[0] / np.linalg.norm(dirs[0]), dirs[1] / np.linalg.norm(dirs[1]))
    assert cams[0]["fov_y"] == pytest.approx(cams[1]["fov_y"], abs=1e-9)


# ---------------------------------------------------------------- serialized meshes

# Three shapes (tests/configs/meshes/make_fixtures.py): 0 a unit square
# facing +y, 1 a tetrahedron, 2 cube.obj's cube with its vertices split by face.
SERIALIZED = REPO / "tests" / "configs" / "meshes" / "shapes_v4_single.serialized"
SERIALIZED_BODY = """
  <shape type="serialized" id="cube">
    <string name="filename" value="shapes.serialized"/>
    <integer name="shape_index" value="2"/>
    <transform name="to_world"><scale value="0.8"/><translate x="-0.5" y="0" z="0"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.7 0.2 0.1"/></bsdf>
  </shape>
  <shape type="serialized" id="floor">
    <string name="filename" value="shapes.serialized"/>
    <transform name="to_world"><translate x="-0.5" z="-0.5"/><scale value="6"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
  </shape>"""


def test_30_serialized_shapes_keep_their_shape_index(tmp_path: Path) -> None:
    (tmp_path / "shapes.serialized").write_bytes(SERIALIZED.read_bytes())
    legacy = """
  <shape type="serialized" id="tetra">
    <string name="filename" value="shapes.serialized"/><integer name="shapeIndex" value="1"/>
  </shape>
  <shape type="serialized" id="bulb">
    <string name="filename" value="shapes.serialized"/>
    <transform name="to_world"><translate y="2"/></transform>
    <emitter type="area"><rgb name="radiance" value="2"/></emitter>
  </shape>"""
    doc, lines, out = run_import(write(tmp_path, SERIALIZED_BODY + legacy))
    cube_, floor, tetra = doc["shapes"]
    assert cube_["type"] == "mesh" and cube_["file"] == "meshes/shapes.serialized" and cube_["shape_index"] == 2
    assert cube_["transform"] == [{"scale": 0.8}, {"translate": [-0.5, 0.0, 0.0]}]
    assert floor["file"] == cube_["file"] and floor["shape_index"] == 0  # Mitsuba's default, written out
    assert tetra["shape_index"] == 1  # Mitsuba 0.6's shapeIndex
    bulb = next(light for light in doc["lights"] if light["name"] == "bulb")
    assert bulb["mesh"] == {
        "file": "meshes/shapes.serialized",
        "shape_index": 0,
        "transform": [{"translate": [0.0, 2.0, 0.0]}],
    }
    # One copy of the file for all four shapes, its bytes unchanged; no shape skipped, no parameter ignored.
    assert sorted(p.name for p in (out / "meshes").iterdir()) == ["shapes.serialized"]
    assert (out / "meshes" / "shapes.serialized").read_bytes() == SERIALIZED.read_bytes()
    assert not warned(lines, "skipped") and not warned(lines, "ignored")

    bad = write(
        tmp_path,
        '<shape type="serialized">\n<string name="filename" value="shapes.serialized"/>\n'
        '<integer name="shape_index" value="-1"/></shape>',
        name="bad.xml",
    )
    with pytest.raises(MitsubaImportError) as e:
        import_scene(bad, tmp_path / "bad_out")
    assert e.value.line == line_of(bad.read_text(), 'value="-1"') and "non-negative integer" in str(e.value)


@pytest.mark.real
def test_31_serialized_cube_renders_as_the_same_obj(real_renderer: Path, tmp_path: Path) -> None:
    """The imported scene with the serialized cube renders bit for bit as
    the same scene with cube.obj in its place (the loader joins the split
    vertices back into cube.obj's mesh); a shape_index past the file's
    shapes is the renderer's error at its line in scene.yaml."""
    (tmp_path / "shapes.serialized").write_bytes(SERIALIZED.read_bytes())
    (tmp_path / "cube.obj").write_bytes((REPO / "tests" / "configs" / "meshes" / "cube.obj").read_bytes())
    ser, _ = import_scene(write(tmp_path, SERIALIZED_BODY, name="ser.xml"), tmp_path / "ser")
    obj_body = SERIALIZED_BODY.replace(
        '<shape type="serialized" id="cube">\n    <string name="filename" value="shapes.serialized"/>\n'
        '    <integer name="shape_index" value="2"/>',
        '<shape type="obj" id="cube">\n    <string name="filename" value="cube.obj"/>',
    )
    assert obj_body != SERIALIZED_BODY
    obj, _ = import_scene(write(tmp_path, obj_body, name="obj.xml"), tmp_path / "obj")
    a = _render(real_renderer, ser, tmp_path / "ra")
    b = _render(real_renderer, obj, tmp_path / "rb")
    assert a.rgb.mean() > 0.01 and np.array_equal(a.rgb, b.rgb)

    text = ser.read_text().replace("shape_index: 2", "shape_index: 7")
    ser.write_text(text)
    proc = subprocess.run([str(real_renderer), "--print-config", str(ser)], capture_output=True, text=True, timeout=60)
    line = 1 + text.splitlines().index(next(ln for ln in text.splitlines() if "shape_index: 7" in ln))
    assert proc.returncode == 2
    assert (
        f"scene.yaml:{line}:" in proc.stderr and "shape_index 7 is out of range (the file holds 3 shapes" in proc.stderr
    )
