"""The Little Lamp as committed (configs/scenes/little_lamp*): the import is
the importer's output as it stands, the meshes are the third party's bytes,
and the scene with its portals loads and renders in the real renderer."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from portal_harness.mitsuba_import import import_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))  # repo_paths.py
from repo_paths import REAL_RENDERER, REPO

SHARED = REPO.parent / "shared" / "assets" / "little_lamp"
COMMITTED = REPO / "configs" / "scenes" / "little_lamp"
SCENE = REPO / "configs" / "scenes" / "little_lamp.yaml"


def test_01_committed_import_is_what_the_importer_writes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    if not (SHARED / "lamp_reproduce.xml").is_file():
        pytest.skip("../shared/assets/little_lamp is not beside the project")
    # The header names the XML as the command line did: run it as the README says.
    monkeypatch.chdir(REPO)
    out, _ = import_scene(
        Path(os.path.relpath(SHARED / "lamp_reproduce.xml", REPO)), tmp_path / "ll", skip_missing=True
    )
    assert out.read_text() == (COMMITTED / "scene.yaml").read_text()
    fresh = sorted(p.name for p in (tmp_path / "ll" / "meshes").iterdir())
    assert fresh == sorted(p.name for p in (COMMITTED / "meshes").iterdir())
    for name in fresh:
        assert (tmp_path / "ll" / "meshes" / name).read_bytes() == (COMMITTED / "meshes" / name).read_bytes(), name
    assert (COMMITTED / "LICENSE.txt").read_bytes() == (SHARED / "LICENSE.txt").read_bytes()


@pytest.mark.real
def test_02_scene_loads_with_two_portals_of_its_mesh_light() -> None:
    if not REAL_RENDERER.is_file():
        pytest.skip("renderer/build/render not built")
    out = subprocess.run(
        [str(REAL_RENDERER), "--print-config", str(SCENE), "--format", "json"],
        capture_output=True,
        text=True,
        check=True,
    )
    doc = json.loads(out.stdout)
    (light,) = doc["config"]["lights"]
    assert light["mesh"]["file"].endswith("meshes/spemitter.obj")
    assert [p["name"] for p in doc["config"]["portals"]] == ["front", "back"]
    assert all(len(p["vertices"]) == 32 and p["light"] == light["name"] for p in doc["config"]["portals"])
    # Every mesh the scene reads is among the files its run keys digest.
    meshes = {Path(s["file"]).name for s in doc["config"]["shapes"] if "file" in s} | {"spemitter.obj"}
    assert meshes <= {Path(f).name for f in doc["files"]}


@pytest.mark.real
@pytest.mark.parametrize("strategy", ["light", "antishadow_exact"])
def test_03_renders(tmp_path: Path, strategy: str) -> None:
    if not REAL_RENDERER.is_file():
        pytest.skip("renderer/build/render not built")
    args = [str(REAL_RENDERER), str(SCENE), "--spp", "2", "--strategy", strategy, "--out", str(tmp_path)]
    args += ["--set", "film.width=32", "--set", "film.height=32", "--threads", "2", "--quiet"]
    out = subprocess.run(args, capture_output=True, text=True, check=True)
    final = json.loads(out.stdout.splitlines()[-1])
    assert final["event"] == "final" and final["spp"] == 2 and final["nonfinite"] == 0
    assert final["light_samples"] > 0
