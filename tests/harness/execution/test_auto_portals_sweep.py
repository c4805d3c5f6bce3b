"""Scenes with `portals: auto` (issue 39) wherever the harness reads a scene,
with the real renderer: a tiny sweep of the lampshade with automatic
portals (configs/scenes/lampshade_auto.yaml, which includes lampshade.yaml),
`run` on it, and a Dask worker rendering it as here. The harness never reads
portals itself: the renderer finds them at scene build, from the files the
scene's pack carries."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import REPO

from portal_harness.core import exr
from portal_harness.core.paths import ResultsLayout
from portal_harness.execution.execute import Target, run_dask, run_local
from portal_harness.execution.renderer import renderer_version
from portal_harness.experiment import contract
from portal_harness.experiment.scene import spec_from_scene
from portal_harness.experiment.spec import RunSpec

pytestmark = pytest.mark.real
AUTO = REPO / "configs" / "scenes" / "lampshade_auto.yaml"
CliRunner = Callable[..., tuple[int, str, str]]


def test_01_auto_scene_is_read_with_its_include(real_renderer: Path) -> None:
    effective = contract.print_config(str(real_renderer), AUTO)
    assert [f.name for f in effective.files] == ["lampshade_auto.yaml", "lampshade.yaml"]
    assert effective.config["portals"] == "auto" or all("vertices" in p for p in effective.config["portals"])


def test_02_tiny_sweep_of_an_auto_scene(real_renderer: Path, tmp_path: Path, results: Path, cli: CliRunner) -> None:
    doc = {
        "name": "auto_tiny",
        "scene": str(AUTO),
        "integrator": "direct",
        "strategies": ["light", "antishadow_exact"],
        "sweep": {"params.s_L": [0.15, 0.6]},
        "fixed": {"params.s_P": 0.3, "film.width": 32, "film.height": 32},
        "budget": {"time_s": 0.2, "threads": 1, "seed": 1, "replicates": 2, "snapshots": {"every": 0.1}},
        "reference": {"strategy": "antishadow_exact", "spp": 256, "seed": 7},
        "axis": {"param": "params.s_L", "divide_by": "params.s_P"},
    }
    exp = tmp_path / "auto_tiny.yaml"
    exp.write_text(yaml.safe_dump(doc))
    status, out, err = cli("sweep", str(exp), "--no-progress", renderer=real_renderer)
    assert status == 0, out + err
    summary = json.loads((results / "experiments" / "auto_tiny" / "summary.json").read_text())
    rows = {(r["point"], r["strategy"]): r for r in summary["rows"] if r["region"] == "image"}
    for point in ("s_L=0.15", "s_L=0.6"):
        assert all(rows[(point, s)]["status"] == "done" for s in ("light", "antishadow_exact"))
        # Efficiency relative to light with its standard error (2 replicates);
        # the gain itself is the auto_portals experiment's to measure.
        r = rows[(point, "antishadow_exact")]
        assert r["efficiency_vs_light"] > 0 and r["efficiency_vs_light_stderr"] > 0, r
    status, out, err = cli("run", str(AUTO), "--strategy", "antishadow_exact", "--spp", "4", renderer=real_renderer)
    assert status == 0, out + err


def test_03_auto_scene_renders_on_a_dask_worker_as_here(real_renderer: Path, tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    renderer = str(real_renderer)
    version = renderer_version(renderer)
    overrides = {"film.width": "24", "film.height": "24"}
    spec = spec_from_scene(AUTO, overrides, renderer, strategy="antishadow_exact", spp=4, threads=1, seed=3)
    manifests: dict[str, dict[str, Any]] = {}

    def done(where: str) -> Callable[[RunSpec, dict[str, Any]], None]:
        return lambda _spec, manifest: manifests.__setitem__(where, manifest)

    here, there = ResultsLayout(tmp_path / "local"), ResultsLayout(tmp_path / "dask")
    run_local([spec], Target(here, renderer, version), 1, done("local"))
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None, silence_logs=40
    ) as cluster:
        run_dask([spec], Target(there, renderer, version), cluster.scheduler_address, done("dask"))
    assert manifests["dask"]["status"] == "done", manifests["dask"].get("error")
    assert manifests["local"]["status"] == "done"
    key = spec.key(version)
    ours, theirs = (exr.read_snapshot(r.run(key).dir / "final.exr") for r in (here, there))
    assert float(ours.rgb.mean()) > 0 and np.array_equal(ours.rgb, theirs.rgb)  # the same portals, found there
