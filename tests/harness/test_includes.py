"""The harness reads scenes with `include:` as the renderer does: merged for
key checks, and hashed over every file involved for run keys."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from portal_harness.errors import ConfigError
from portal_harness.includes import load_merged, merge
from portal_harness.schema import read_scene, read_yaml

REPO = Path(__file__).resolve().parents[2]
GOOD = REPO / "tests" / "configs" / "good"


def test_merge_rules() -> None:
    base = {"a": {"x": 1, "y": [1, 2]}, "b": 2, "c": {"k": 1}}
    over = {"a": {"y": [3], "z": 4}, "c": None, "d": 5}
    assert merge(base, over) == {"a": {"x": 1, "y": [3], "z": 4}, "b": 2, "c": None, "d": 5}
    assert list(merge(base, over)["a"]) == ["x", "y", "z"]  # first-seen order


def test_same_merge_as_the_renderer() -> None:
    # The renderer's test (test_config.c) checks that include_merge.yaml
    # loads to exactly include_merge_expected.yaml; null removes a section.
    tree, files = load_merged(GOOD / "include_merge.yaml")
    expected = read_yaml(GOOD / "include_merge_expected.yaml", "expected")
    assert {k: v for k, v in tree.items() if v is not None} == expected
    assert [f.name for f in files] == ["include_merge.yaml", "mid.yaml", "base_room.yaml", "render_quick.yaml"]


def test_read_scene_sees_included_keys() -> None:
    info = read_scene(GOOD / "include_lampshade.yaml")
    assert "params.s_L" in info.scalars and "lights.0.vertices.0.0" in info.scalars


def test_hash_follows_included_files(tmp_path: Path) -> None:
    (tmp_path / "base.yaml").write_text("params: {s: 1}\n")
    (tmp_path / "top.yaml").write_text("include: base.yaml\nrender: {spp: 2}\n")
    before = read_scene(tmp_path / "top.yaml").sha256
    (tmp_path / "base.yaml").write_text("params: {s: 2}\n")
    assert read_scene(tmp_path / "top.yaml").sha256 != before
    # A self-contained scene keeps its plain file digest (existing run keys stay valid).
    assert read_scene(tmp_path / "base.yaml").sha256 == hashlib.sha256(b"params: {s: 2}\n").hexdigest()


def test_bad_includes(tmp_path: Path) -> None:
    (tmp_path / "a.yaml").write_text("include: b.yaml\n")
    (tmp_path / "b.yaml").write_text("include: ./a.yaml\n")
    with pytest.raises(ConfigError, match="include cycle"):
        load_merged(tmp_path / "a.yaml")
    (tmp_path / "c.yaml").write_text("include: missing.yaml\n")
    with pytest.raises(ConfigError, match="not found"):
        load_merged(tmp_path / "c.yaml")
    (tmp_path / "d.yaml").write_text("include: 3\n")
    with pytest.raises(ConfigError, match="expected a path"):
        load_merged(tmp_path / "d.yaml")
