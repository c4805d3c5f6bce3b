"""The harness asks the renderer for its contract: `render --describe` for
its names, `render --print-config` for a scene as the renderer reads it
(includes, params, overrides, defaults). These tests run the real binary."""

from __future__ import annotations

import dataclasses
import hashlib
import os
from pathlib import Path

import pytest
import yaml

from portal_harness.core import exr
from portal_harness.core.errors import ConfigError, RendererError
from portal_harness.execution import renderer
from portal_harness.experiment import contract
from portal_harness.experiment.scene import read_scene
from portal_harness.experiment.spec import NO_SNAPSHOTS, SNAPSHOT_KEYS

REPO = Path(__file__).resolve().parents[3]
GOOD = REPO / "tests" / "configs" / "good"
BAD = REPO / "tests" / "configs" / "bad"
LAMPSHADE = REPO / "configs" / "scenes" / "lampshade.yaml"


def test_01_describe_is_parsed_and_cached(real_renderer: Path) -> None:
    c = contract.describe(real_renderer)
    assert c.program == "render" and "light" in c.strategies and c.integrators == ("direct", "path")
    assert contract.describe(str(real_renderer)) is c  # one --describe per binary
    with pytest.raises(RendererError, match="renderer not found"):
        contract.describe(real_renderer.parent / "no-such-render")


def test_02_the_harness_constants_match_the_renderer(real_renderer: Path) -> None:
    c = contract.describe(real_renderer)
    # exr.py reads what the renderer writes
    assert c.exr_channels == exr.RGB_CHANNELS + exr.VARIANCE_CHANNELS
    assert c.region_channels == exr.REGION_CHANNELS
    header_fields = {f.name for f in dataclasses.fields(exr.SnapshotHeader)} - {"width", "height"}
    assert set(c.exr_attributes) == header_fields
    # runs.py reads its exit statuses
    assert dict(c.exit_codes) == {
        "done": renderer.EXIT_OK,
        "runtime": renderer.EXIT_RUNTIME,
        "usage": renderer.EXIT_USAGE,
        "interrupted": renderer.EXIT_INTERRUPTED,
    }
    # the schedules the harness sets are the renderer's
    assert all(c.snapshot_unit(k) in ("s", "spp") for k in SNAPSHOT_KEYS)
    assert {"start", "snapshot", "final"} <= set(c.json_events)


def test_03_scene_with_includes_as_the_renderer_reads_it(real_renderer: Path) -> None:
    info = read_scene(str(real_renderer), GOOD / "include_lampshade.yaml")
    assert len(info.files) > 1 and info.files[0] == (GOOD / "include_lampshade.yaml").resolve()
    assert info.effective.params["s_L"] > 0 and isinstance(info.effective.get("lights.0.vertices.0.0"), float)
    assert info.width > 0 and info.effective.render["strategy"] in contract.describe(real_renderer).strategies


def test_04_params_are_evaluated_after_the_overrides(real_renderer: Path) -> None:
    e = contract.print_config(real_renderer, LAMPSHADE, [("params.s_P", "0.5")])
    assert e.params["s_P"] == 0.5 and e.params["h"] == pytest.approx(0.25)  # h: "=s_P / 2"


def test_05_digest_follows_the_included_files(real_renderer: Path, tmp_path: Path) -> None:
    base = tmp_path / "base.yaml"
    base.write_text(LAMPSHADE.read_text())
    (tmp_path / "top.yaml").write_text("include: base.yaml\nrender: {spp: 2}\n")
    before = read_scene(str(real_renderer), tmp_path / "top.yaml")
    assert [f.name for f in before.files] == ["top.yaml", "base.yaml"]
    base.write_text(LAMPSHADE.read_text().replace("fov_y: 45", "fov_y: 40"))
    os.utime(base, ns=(0, 0))  # a different stamp even within the file system's time resolution
    after = read_scene(str(real_renderer), tmp_path / "top.yaml")
    assert after.sha256 != before.sha256 and after.effective.get("camera.fov_y") == 40
    # a self-contained scene keeps its plain file digest (existing run keys stay valid)
    assert read_scene(str(real_renderer), base).sha256 == hashlib.sha256(base.read_bytes()).hexdigest()


def test_06_bad_includes_and_overrides_are_the_renderers_messages(real_renderer: Path) -> None:
    with pytest.raises(ConfigError, match=r"cycle_b\.yaml:2:10: .*include cycle"):
        read_scene(str(real_renderer), BAD / "include_cycle.yaml")
    with pytest.raises(ConfigError, match=r"include_missing\.yaml:2:10: .*No such file"):
        read_scene(str(real_renderer), BAD / "include_missing.yaml")
    with pytest.raises(ConfigError) as e:
        read_scene(str(real_renderer), LAMPSHADE, [("film.widht", "3")])
    assert str(e.value) == '--set film.widht=3: unknown key "widht" in film (expected width, height)'


def test_07_print_config_is_cached_until_a_file_changes(real_renderer: Path, tmp_path: Path) -> None:
    scene = tmp_path / "s.yaml"
    scene.write_text(LAMPSHADE.read_text())
    first = contract.print_config(real_renderer, scene, [("params.s_L", "0.3")])
    assert contract.print_config(real_renderer, scene, [("params.s_L", "0.3")]) is first
    assert contract.print_config(real_renderer, scene, [("params.s_L", "0.4")]) is not first
    tree = yaml.safe_load(scene.read_text())
    tree["film"]["width"] = 8
    scene.write_text(yaml.safe_dump(tree, sort_keys=False))
    again = contract.print_config(real_renderer, scene, [("params.s_L", "0.3")])
    assert again is not first and again.width == 8


def test_08_no_snapshots_is_off_for_the_renderer(real_renderer: Path, tmp_path: Path) -> None:
    # the schedule NO_SNAPSHOTS asks for is one the renderer takes as "off"
    e = contract.print_config(real_renderer, LAMPSHADE, [(f"render.snapshots.{k}", v) for k, v in NO_SNAPSHOTS])
    assert all(e.render["snapshots"].get(k, 0) == 0 for k in SNAPSHOT_KEYS)
