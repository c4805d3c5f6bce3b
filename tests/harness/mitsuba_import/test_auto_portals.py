"""`import-mitsuba` writes `portals: auto` (issue 39): every imported emitter
gets the portals the renderer finds at scene build, unless
`--no-auto-portals`. The end-to-end test imports a lamp in a shade open at
the bottom through a hole, with no portal written by hand, and shows the gain with the
real renderer: antishadow_exact's shadow rays leave through the found
portal instead of hitting the shade."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
import yaml

from portal_harness import cli as harness_cli
from portal_harness.mitsuba_import import import_scene
from portal_harness.mitsuba_import.writer import AUTO_PORTALS_NOTE

CAMERA = """
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 1.5, 7" target="0, 1, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="24"/></film>
  </sensor>"""
# A 0.5 x 0.5 light at y = 3 emitting downwards (a rectangle's +z turned to -y).
LIGHT = """
  <shape type="rectangle" id="bulb">
    <transform name="to_world"><scale value="0.25"/><rotate x="1" angle="90"/><translate y="3"/></transform>
    <emitter type="area"><rgb name="radiance" value="5"/></emitter>
  </shape>"""
FLOOR = """
  <shape type="rectangle" id="floor">
    <transform name="to_world"><scale value="5"/><rotate x="1" angle="-90"/></transform>
  </shape>"""


def _wall(to_world: str) -> str:
    return f'\n  <shape type="rectangle"><transform name="to_world">{to_world}</transform></shape>'


# The shade: a 3 x 1.5 x 3 box about the light, y from 2 to 3.5, its bottom
# four plates about a 0.6 x 0.6 hole (rectangles in the xy plane turned flat).
SHADE = (
    _wall('<scale x="1.5" y="0.6"/><rotate x="1" angle="90"/><translate y="2" z="0.9"/>')
    + _wall('<scale x="1.5" y="0.6"/><rotate x="1" angle="90"/><translate y="2" z="-0.9"/>')
    + _wall('<scale x="0.6" y="0.3"/><rotate x="1" angle="90"/><translate x="0.9" y="2"/>')
    + _wall('<scale x="0.6" y="0.3"/><rotate x="1" angle="90"/><translate x="-0.9" y="2"/>')
    + _wall('<scale value="1.5"/><rotate x="1" angle="90"/><translate y="3.5"/>')
    + _wall('<scale x="1.5" y="0.75"/><translate y="2.75" z="1.5"/>')
    + _wall('<scale x="1.5" y="0.75"/><translate y="2.75" z="-1.5"/>')
    + _wall('<scale x="1.5" y="0.75"/><rotate y="1" angle="90"/><translate x="1.5" y="2.75"/>')
    + _wall('<scale x="1.5" y="0.75"/><rotate y="1" angle="90"/><translate x="-1.5" y="2.75"/>')
)


def _xml(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0">{CAMERA}{body}\n</scene>\n')
    return path


def test_01_every_import_with_a_light_says_portals_auto(tmp_path: Path) -> None:
    path, _ = import_scene(_xml(tmp_path, LIGHT + FLOOR), tmp_path / "out")
    text = path.read_text()
    doc = yaml.safe_load(text)
    assert doc["portals"] == "auto"
    assert list(doc) == ["camera", "film", "materials", "shapes", "lights", "portals", "render"]
    assert AUTO_PORTALS_NOTE in text.split("\n\n")[0]  # the header says what it means and how to turn it off


def test_02_the_flag_turns_it_off(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xml = _xml(tmp_path, LIGHT + FLOOR)
    assert harness_cli.main(["import-mitsuba", str(xml), "--out", str(tmp_path / "off"), "--no-auto-portals"]) == 0
    off = (tmp_path / "off" / "scene.yaml").read_text()
    assert "portals" not in yaml.safe_load(off) and "portals: auto" not in off
    assert harness_cli.main(["import-mitsuba", str(xml), "--out", str(tmp_path / "on")]) == 0
    assert yaml.safe_load((tmp_path / "on" / "scene.yaml").read_text())["portals"] == "auto"
    path, _ = import_scene(xml, tmp_path / "api", auto_portals=False)
    assert path.read_text() == off  # the API's flag writes the same file
    capsys.readouterr()


def test_03_no_light_no_portals(tmp_path: Path) -> None:
    path, report = import_scene(_xml(tmp_path, FLOOR), tmp_path / "out")
    assert "portals" not in yaml.safe_load(path.read_text())
    assert any("no area light" in line for line in report.lines())


def _blocked(renderer: Path, config: Path, out: Path) -> tuple[float, dict[str, float]]:
    """antishadow_exact, 4 spp: the fraction of its shadow rays that hit something, and the final event."""
    args = [str(renderer), str(config), "--out", str(out), "--strategy", "antishadow_exact", "--spp", "4"]
    args += ["--time", "0", "--seed", "3", "--threads", "1", "--quiet"]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    final = json.loads(proc.stdout.splitlines()[-1])
    assert final["event"] == "final" and final["nonfinite"] == 0
    return final["shadow_blocked"] / final["shadow_rays"], final


@pytest.mark.real
def test_04_imported_lamp_in_a_shade_gets_its_opening(real_renderer: Path, tmp_path: Path) -> None:
    xml = _xml(tmp_path, LIGHT + SHADE + FLOOR)
    auto, _ = import_scene(xml, tmp_path / "auto")
    hand_off, _ = import_scene(xml, tmp_path / "none", auto_portals=False)
    blocked_auto, a = _blocked(real_renderer, auto, tmp_path / "ra")
    blocked_none, b = _blocked(real_renderer, hand_off, tmp_path / "rb")
    # Without portals antishadow_exact samples the light: most shadow rays hit
    # the shade. With the found opening, the hole, they leave through it.
    assert blocked_none > 0.6, b
    assert blocked_auto < 0.1 * blocked_none, a
