"""End to end with the real renderer (renderer/build/render) at 32x32:
its EXR output and header, a tiny sweep with figures, resume, failures.
Skipped until the renderer is built."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import REPO

from portal_harness.core import exr
from portal_harness.core.paths import ResultsLayout
from portal_harness.execution import index
from portal_harness.execution.renderer import renderer_version
from portal_harness.experiment.loader import load_experiment
from portal_harness.figures import data as figure_data

pytestmark = pytest.mark.real
SCENE = REPO / "configs" / "scenes" / "lampshade.yaml"
TINY = ["--set", "film.width=32", "--set", "film.height=24"]


def test_01_reads_the_renderers_output_with_its_header(real_renderer: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = subprocess.run(
        [
            str(real_renderer),
            str(SCENE),
            *TINY,
            "--out",
            str(out),
            "--spp",
            "8",
            "--time",
            "0",
            "--seed",
            "5",
            "--threads",
            "1",
            "--strategy",
            "light",
            "--set",
            "render.snapshots.every_spp=4",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    events = [json.loads(line) for line in proc.stdout.splitlines()]
    start, final = events[0], events[-1]
    assert start["event"] == "start" and final["event"] == "final"
    snap = exr.read_snapshot(out / "final.exr")
    h = snap.header
    assert (h.width, h.height) == (32, 24) and snap.rgb.shape == (24, 32, 3)
    assert h.spp == 8 == final["spp"]
    assert h.strategy == "light" and h.integrator == "direct" and h.seed == 5
    assert h.config_hash == start["config_hash"] and len(h.config_hash) == 16
    assert h.renderer_version == start["renderer_version"] == renderer_version(str(real_renderer))
    assert h.render_time_s == pytest.approx(final["time_s"], rel=1e-6, abs=1e-6)
    assert h.rays == pytest.approx(final["rays"]) and h.rays > 0
    assert h.nonfinite_samples == final["nonfinite"]
    assert np.all(snap.variance >= 0) and float(snap.rgb.max()) > 0
    assert float(snap.variance.max()) > 0  # 8 spp: the variance layer is filled
    snaps = [e for e in events if e["event"] == "snapshot"]
    assert snaps and exr.read_header(snaps[0]["path"]).spp == snaps[0]["spp"]
    effective = yaml.safe_load((out / "config.yaml").read_text())
    assert effective["film"]["width"] == 32


def _experiment(tmp_path: Path, strategies: list[str]) -> Path:
    doc = {
        "name": "real_tiny",
        "scene": str(SCENE),
        "integrator": "direct",
        "strategies": strategies,
        "sweep": {"params.s_L": [0.15, 1.2]},
        "fixed": {"params.s_P": 0.3, "film.width": 32, "film.height": 32},
        "budget": {"time_s": 0.3, "threads": 1, "seed": 1, "snapshots": {"every": 0.1}},
        "reference": {"strategy": "light", "spp": 256, "seed": 7},
        "insets": [{"name": "floor", "x": 10, "y": 20, "width": 12, "height": 8}],
        "axis": {"param": "params.s_L", "divide_by": "params.s_P"},
    }
    path = tmp_path / "real_tiny.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_02_tiny_sweep_figures_and_resume(
    real_renderer: Path, tmp_path: Path, results: Path, cli: Callable[..., tuple[int, str, str]]
) -> None:
    exp = _experiment(tmp_path, ["light_area", "light", "portal"])
    status, out, err = cli("sweep", str(exp), "--no-progress", renderer=real_renderer)
    summary = json.loads((results / "experiments" / "real_tiny" / "summary.json").read_text())
    rows = {(r["point"], r["strategy"]): r for r in summary["rows"] if r["region"] == "image"}
    for point in ("s_L=0.15", "s_L=1.2"):
        for strategy in ("light_area", "light"):
            r = rows[(point, strategy)]
            assert r["status"] == "done", out
            assert 0 < r["rel_mse"] < 10 and r["time_s"] >= 0.25 and r["spp"] >= 1
    # portal may not be implemented yet: then it is recorded as failed and the exit status says so
    portal_ok = all(rows[(p, "portal")]["status"] == "done" for p in ("s_L=0.15", "s_L=1.2"))
    assert status == (0 if portal_ok else 1), out + err
    status, out, err = cli("figures", str(exp))
    assert status == 0, err
    for name in ("error_time", "insets", "efficiency"):
        assert (results / "figures" / f"real_tiny_{name}.png").stat().st_size > 5000
    _assert_images_at_equal_time(exp, results, real_renderer)
    status, out, _ = cli("sweep", str(exp), "--no-progress", renderer=real_renderer)
    rendered_now = int(out.split(" rendered now")[0].split()[-1])
    assert rendered_now == (0 if portal_ok else 2)


def _assert_images_at_equal_time(exp: Path, results: Path, renderer: Path) -> None:
    """The insets' and the viewer's images of one point are at one render
    time, up to the snapshot tolerance (runs overshoot their 0.3 s budget by
    a pass, differently; their previous snapshot is 0.1 s earlier)."""
    experiment = load_experiment(exp, str(renderer))
    layout = ResultsLayout(results)
    conn = index.connect(layout.index_path)
    try:
        data = figure_data.load(experiment, conn, layout)
        for point in data.points:
            t_eq = figure_data.equal_time(experiment, conn, data, point)
            chosen = [
                figure_data.choose_image(conn, cell, t_eq)
                for (p, _), cell in data.runs.items()
                if p == point.id and figure_data.cell_done(cell)
            ]
            times = [c.time_s for c in chosen if c is not None]
            assert len(times) >= 2 and min(times) >= 0.29, times
            assert figure_data.times_agree(times), (point.id, times)
    finally:
        conn.close()


def test_03_renderer_config_error_is_refused_before_rendering(
    real_renderer: Path, results: Path, cli: Callable[..., tuple[int, str, str]]
) -> None:
    # render --print-config checks the override: its message, exit 2, no run folder
    status, out, err = cli("run", str(SCENE), *TINY, "--set", "film.width=-3", "--spp", "2", renderer=real_renderer)
    assert status == 2 and out == ""
    assert "--set film.width=-3: " in err
    assert not (results / "runs").exists()


def test_04_real_references_extended_tested_and_a_biased_strategy_caught(
    real_renderer: Path,
    tmp_path: Path,
    results: Path,
    cli: Callable[..., tuple[int, str, str]],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    doc = yaml.safe_load(_experiment(tmp_path, ["light", "antishadow_exact"]).read_text())
    doc["sweep"] = {"params.s_L": [1.2]}
    doc["reference"] = {"strategies": ["antishadow_exact", "light"], "spp": 64, "seed": 7, "max_time_s": 10}
    path = tmp_path / "real_tiny.yaml"
    path.write_text(yaml.safe_dump(doc))
    status, out, err = cli("sweep", str(path), "--no-progress", renderer=real_renderer)
    assert status == 0, out + err
    summary = json.loads((results / "experiments" / "real_tiny" / "summary.json").read_text())
    (ref,) = summary["references"]
    # render --resume grew the better part until every region was resolved
    assert "extending reference" in out and ref["parts"][0]["spp"] > 64
    # (at this size a few heavy-tailed pixels near the opening's rim keep the whole image's ratio
    # near its limit; the floor, where the strategies differ, is resolved)
    noise = {c["region"]: c for c in ref["noise"]}
    assert noise["floor"]["ok"] and noise["floor"]["ratio"] <= 0.1, out
    assert abs(ref["bias_max_abs_z"]) < 4
    # the two parts and the one combined reference in use: superseded combinations are removed
    folders = sorted(p.name for p in (results / "references").iterdir() if not p.name.startswith("."))
    assert len(folders) == 3 and ref["key"] in folders
    regions = {r["region"] for r in summary["rows"]}
    assert {"image", "lit", "floor", "anti_antumbra"} <= regions
    floor = next(r for r in summary["rows"] if r["region"] == "floor" and r["strategy"] == "antishadow_exact")
    assert floor["efficiency_vs_light"] > 10 and floor["bound"] == "", out
    # the renderer's bias hook makes antishadow_exact 10% too bright: the two references disagree
    # (measured: z = +6.7 to +8.9 in every region with light)
    monkeypatch.setenv("PORTAL_LIGHTS_FAULT_BIAS", "antishadow_exact:1.1")
    doc["reference"]["seed"] = 8  # new references (the unbiased ones are cached)
    doc["reference"]["spp"] = 1024  # enough samples for the 10% to stand out of light's noise
    path.write_text(yaml.safe_dump(doc))
    status, out, err = cli("sweep", str(path), "--no-progress", renderer=real_renderer)
    assert status == 1, out + err
    assert "references antishadow_exact and light disagree in region" in out and "stopped" in out
