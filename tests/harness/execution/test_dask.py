"""The Dask path: a two-point sweep on a real LocalCluster over loopback;
tasks return the run folders' files, installed by the client. A scene with
includes and meshes travels whole and renders on a worker as it does here."""

from __future__ import annotations

import json
import shutil
import sqlite3
import subprocess
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import REPO

from portal_harness.core import exr
from portal_harness.core.paths import ResultsLayout
from portal_harness.execution.execute import Target, run_dask, run_local
from portal_harness.execution.renderer import renderer_version
from portal_harness.experiment import contract
from portal_harness.experiment.scene import spec_from_scene
from portal_harness.experiment.spec import RunSpec

CliRunner = Callable[..., tuple[int, str, str]]


def test_01_two_point_sweep_on_a_local_cluster(
    cli: CliRunner,
    write_experiment: Callable[..., Path],
    results: Path,
    render_log: Callable[[], list[str]],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    distributed = pytest.importorskip("distributed")
    monkeypatch.setenv("FAKE_RENDER_CRASH", "projection")  # a task whose render fails must not stop the sweep
    exp = write_experiment(strategies=["light", "portal", "projection"])
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None, silence_logs=40
    ) as cluster:
        status, out, err = cli("sweep", str(exp), "--scheduler", cluster.scheduler_address, "--no-progress")
    assert status == 1, out + err  # the two projection runs failed
    assert "2 failed:" in out and "SIGSEGV" in out
    summary = json.loads((results / "experiments" / "tiny" / "summary.json").read_text())
    image = [r for r in summary["rows"] if r["region"] == "image"]
    done = [r for r in image if r["status"] == "done"]
    assert len(done) == 4 and all(r["rel_mse"] > 0 for r in done)
    assert len(render_log()) == 2 + 2 + 6  # region maps, references, runs
    # the files came back over the wire into this results folder; nothing left on the workers' side here
    conn = sqlite3.connect(results / "index.sqlite")
    members = conn.execute(
        "SELECT e.key, e.strategy, r.status FROM experiment_runs e JOIN runs r ON r.key = e.key WHERE e.role = 'run'"
    ).fetchall()
    assert len(members) == 6
    for key, strategy, run_status in members:
        run = results / "runs" / key
        assert (run / "manifest.json").exists() and (run / "stderr.txt").exists()
        if run_status == "done":
            assert (run / "final.exr").stat().st_size > 0 and (run / "metrics.json").exists()
        else:
            assert strategy == "projection"
            assert "simulated crash" in (run / "stderr.txt").read_text()
    assert conn.execute("SELECT count(*) FROM runs WHERE kind = 'run'").fetchone()[0] == 6 + 2
    conn.close()
    # resuming locally renders only what failed
    monkeypatch.delenv("FAKE_RENDER_CRASH")
    before = len(render_log())
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0 and len(render_log()) == before + 2


def _mesh_scene(folder: Path, absolute_mesh: bool = False) -> Path:
    """scenes/top.yaml includes parts/base.yaml, which reads an OBJ and a
    binary PLY by paths relative to itself (or the PLY by its absolute path)."""
    meshes = folder / "meshes"
    meshes.mkdir(parents=True)
    for name in ("cube.obj", "polys_le.ply"):
        shutil.copy(REPO / "tests" / "configs" / "meshes" / name, meshes / name)
    ply = str(meshes / "polys_le.ply") if absolute_mesh else "../../meshes/polys_le.ply"
    base = folder / "scenes" / "parts" / "base.yaml"
    base.parent.mkdir(parents=True)
    base.write_text(
        f"""camera: {{position: [0, 3, 6], look_at: [0, 0.5, 0], up: [0, 1, 0], fov_y: 50}}
film: {{width: 24, height: 16}}
materials:
  grey: {{type: diffuse, albedo: [0.6, 0.6, 0.6]}}
shapes:
  - {{type: quad, material: grey, vertices: [[-4, 0, -4], [-4, 0, 4], [4, 0, 4], [4, 0, -4]]}}
  - {{name: cube, type: mesh, material: grey, file: ../../meshes/cube.obj, transform: [{{translate: [-1, 0, 0]}}]}}
  - {{name: polys, type: mesh, material: grey, file: "{ply}", transform: [{{scale: 0.5}}]}}
lights:
  - name: panel
    vertices: [[-0.5, 3, -0.5], [0.5, 3, -0.5], [0.5, 3, 0.5], [-0.5, 3, 0.5]]
    radiance: [4, 4, 4]
render: {{integrator: direct, strategy: light, spp: 8, time: 0, seed: 7, threads: 1, resumable: true}}
"""
    )
    top = folder / "scenes" / "top.yaml"
    top.write_text("include: parts/base.yaml\nrender: {spp: 6}\n")
    return top


def _local_cluster() -> Any:
    distributed = pytest.importorskip("distributed")
    return distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None, silence_logs=40
    )


@pytest.mark.real
def test_02_a_scene_with_includes_and_meshes_renders_on_a_worker_as_here(real_renderer: Path, tmp_path: Path) -> None:
    renderer = str(real_renderer)
    version = renderer_version(renderer)
    scene = _mesh_scene(tmp_path / "project")
    spec = spec_from_scene(scene, {}, renderer)
    assert len(contract.print_config(renderer, scene).files) == 4  # top, base, the OBJ, the PLY
    manifests: dict[str, dict[str, Any]] = {}

    def done(where: str) -> Callable[[RunSpec, dict[str, Any]], None]:
        return lambda _spec, manifest: manifests.__setitem__(where, manifest)

    here, there = ResultsLayout(tmp_path / "local"), ResultsLayout(tmp_path / "dask")
    run_local([spec], Target(here, renderer, version), 1, done("local"))
    with _local_cluster() as cluster:
        run_dask([spec], Target(there, renderer, version), cluster.scheduler_address, done("dask"))
    assert manifests["dask"]["status"] == "done", manifests["dask"].get("error")
    assert manifests["local"]["status"] == "done"
    key = spec.key(version)
    a, b = here.run(key).dir, there.run(key).dir
    ours, theirs = exr.read_snapshot(a / "final.exr"), exr.read_snapshot(b / "final.exr")
    assert ours.header.spp == theirs.header.spp == 6 and float(ours.rgb.mean()) > 0
    assert np.array_equal(ours.rgb, theirs.rgb) and np.array_equal(ours.variance, theirs.variance)
    # the worker's config.yaml names this machine's meshes, as a local run's does (only
    # the output folder differs), so the run folder renders again, and resumes, here
    lines_here, lines_there = ((d / "config.yaml").read_text().splitlines() for d in (a, b))
    differ = [(x, y) for x, y in zip(lines_here, lines_there, strict=True) if x != y]
    assert [x.split(":")[0].strip() for x, _ in differ] == ["output"], differ
    assert str(tmp_path / "project" / "meshes" / "polys_le.ply") in "\n".join(lines_there)
    proc = subprocess.run(
        [renderer, "--resume", str(b), "--spp", "8", "--threads", "1", "--quiet"], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    assert exr.read_snapshot(b / "final.exr").header.spp == 8


@pytest.mark.real
def test_03_a_file_the_worker_would_not_have_fails_the_run(real_renderer: Path, tmp_path: Path) -> None:
    renderer = str(real_renderer)
    version = renderer_version(renderer)
    scene = _mesh_scene(tmp_path / "project", absolute_mesh=True)
    spec = spec_from_scene(scene, {}, renderer)
    changed = replace(spec, seed=8)
    manifests: list[dict[str, Any]] = []
    layout = ResultsLayout(tmp_path / "results")
    with _local_cluster() as cluster:
        run_dask(
            [spec], Target(layout, renderer, version), cluster.scheduler_address, lambda _s, m: manifests.append(m)
        )
        # a file that changed after the run was planned: refused before anything is sent
        (tmp_path / "project" / "meshes" / "cube.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        run_dask(
            [changed], Target(layout, renderer, version), cluster.scheduler_address, lambda _s, m: manifests.append(m)
        )
    assert [m["status"] for m in manifests] == ["failed", "failed"]
    assert "was not shipped to the worker (an absolute path" in manifests[0]["error"]
    assert "polys_le.ply" in manifests[0]["error"]
    assert "changed since the run was planned" in manifests[1]["error"]
    assert not layout.runs_dir.exists() or not any(p.name != ".attempts" for p in layout.runs_dir.iterdir())
