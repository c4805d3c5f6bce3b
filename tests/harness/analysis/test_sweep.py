"""End-to-end sweeps with the fake renderer: runs, references, metrics,
figures, index rows; resuming after completion, after failures and after
the harness was killed."""

from __future__ import annotations

import itertools
import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from portal_harness.reference import pilot

CliRunner = Callable[..., tuple[int, str, str]]


def _keys_rendered(log: list[str]) -> list[str]:
    """Run keys of the logged renders (the attempt folder starts with the key)."""
    return [Path(line.split()[2]).name.split("-")[0] for line in log]


def test_01_sweep_metrics_figures_index_and_resume(
    cli: CliRunner, write_experiment: Callable[..., Path], results: Path, render_log: Callable[[], list[str]]
) -> None:
    exp = write_experiment()
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    # two region maps, two references (no extension needed at 2000 spp), two points x two strategies
    assert len(render_log()) == 2 + 2 + 4, out
    assert "8 rendered now" in out

    summary = json.loads((results / "experiments" / "tiny" / "summary.json").read_text())
    # tidy: one row per (point, strategy, region); regions: image, lit, the two insets and the
    # fake's three AOV classes (anti_umbra, anti_antumbra, emitter)
    regions = ["image", "lit", "left", "right", "anti_umbra", "anti_antumbra", "emitter"]
    assert len(summary["rows"]) == 2 * 2 * len(regions) and not summary["failures"]
    assert sorted({r["region"] for r in summary["rows"]}) == sorted(regions)
    for row in summary["rows"]:
        assert row["status"] == "done" and row["rel_mse"] > 0 and row["replicates"] == 1
        assert row["reference_noise_ratio"] <= 0.1 and row["bound"] == ""
    # the fake's portal strategy has a lower sigma at about the same cost: more efficient
    portal = [r for r in summary["rows"] if r["strategy"] == "portal"]
    assert all(r["efficiency_vs_light"] > 1.5 for r in portal)
    assert all(r["speedup_equal_error"] > 1.5 for r in portal)
    lit = {r["point"]: r for r in portal if r["region"] == "lit"}
    # lit leaves out the emitter rows (the fake's top two rows) and nothing else
    assert all(r["pixels"] == 16 * 14 for r in lit.values())
    csv_text = (results / "experiments" / "tiny" / "summary.csv").read_text()
    assert csv_text.startswith("point,axis,strategy,status,region,")
    assert len(csv_text.strip().splitlines()) == 1 + len(summary["rows"])

    conn = sqlite3.connect(results / "index.sqlite")
    assert conn.execute("SELECT count(*) FROM runs WHERE status = 'done'").fetchone()[0] == 8
    assert conn.execute("SELECT count(*) FROM runs WHERE kind = 'reference'").fetchone()[0] == 2
    # runs, region maps, reference parts and the reference the metrics use (here the only part)
    assert conn.execute("SELECT count(*) FROM experiment_runs WHERE experiment = 'tiny'").fetchone()[0] == 4 + 2 + 2 + 2
    n_metrics = conn.execute("SELECT count(*) FROM metrics WHERE region = 'image'").fetchone()[0]
    assert n_metrics >= 4 * 4  # several snapshots per run
    conn.close()

    status, out, _ = cli("query", "--strategy", "portal", "--param", "ratio=0.5")
    assert status == 0
    lines = out.strip().splitlines()
    assert lines[0] == "key,time_s,rel_mse" and len(lines) >= 4
    times = [float(line.split(",")[1]) for line in lines[1:]]
    assert times == sorted(times)

    status, out, err = cli("figures", str(exp))
    assert status == 0, err
    for name in ("error_time", "insets", "efficiency"):
        for ext in ("png", "pdf"):
            path = results / "figures" / f"tiny_{name}.{ext}"
            assert path.stat().st_size > 5000, path
            assert str(path) in out

    before = len(render_log())
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0 and len(render_log()) == before  # nothing rendered again
    assert "0 rendered now" in out


def test_02_failed_runs_are_recorded_and_the_sweep_goes_on(
    cli: CliRunner,
    write_experiment: Callable[..., Path],
    results: Path,
    render_log: Callable[[], list[str]],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("FAKE_RENDER_CRASH", "portal")
    monkeypatch.setenv("FAKE_RENDER_UNIMPLEMENTED", "projection")
    exp = write_experiment(strategies=["light", "portal", "projection"])
    status, out, _ = cli("sweep", str(exp), "--no-progress", "--jobs", "1")
    assert status == 1
    assert "4 failed:" in out
    assert "killed by SIGSEGV" in out and "simulated crash" in out and "not implemented" in out
    summary = json.loads((results / "experiments" / "tiny" / "summary.json").read_text())
    by = {(r["point"], r["strategy"]): r for r in summary["rows"]}
    assert by[("s_L=0.15", "light")]["status"] == "done" and by[("s_L=0.15", "light")]["rel_mse"] > 0
    assert by[("s_L=0.15", "portal")]["status"] == "failed"
    assert len(summary["failures"]) == 4
    conn = sqlite3.connect(results / "index.sqlite")
    assert conn.execute("SELECT count(*) FROM runs WHERE status = 'failed'").fetchone()[0] == 4
    conn.close()
    # figures still work with holes
    status, _, err = cli("figures", str(exp))
    assert status == 0, err
    # fixed renderer: only the failed runs are rendered again
    monkeypatch.delenv("FAKE_RENDER_CRASH")
    monkeypatch.delenv("FAKE_RENDER_UNIMPLEMENTED")
    before = len(render_log())
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0
    assert sorted(line.split()[0] for line in render_log()[before:]) == ["portal", "portal", "projection", "projection"]


def test_03_killed_sweep_resumes_without_redoing_finished_runs(
    write_experiment: Callable[..., Path], results: Path, fake_renderer: Path, render_log: Callable[[], list[str]]
) -> None:
    exp = write_experiment(strategies=["light", "portal", "projection"])
    env = {**os.environ, "FAKE_RENDER_SLEEP": "2.0"}  # each render takes about 0.4 s (refs 8 s)
    # short references, and a noise limit they meet without an extension
    exp_doc = exp.read_text().replace("spp: 2000", "spp: 80\n  noise_ratio: 0.99")
    assert "noise_ratio" in exp_doc
    exp.write_text(exp_doc)
    cmd = [
        sys.executable,
        "-m",
        "portal_harness",
        "sweep",
        str(exp),
        "--results",
        str(results),
        "--renderer",
        str(fake_renderer),
        "--no-progress",
        "--jobs",
        "1",
    ]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while len(render_log()) < 4 and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.15)  # the fourth render is under way
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    started = _keys_rendered(render_log())
    assert len(started) >= 4
    finished = {p.name for p in (results / "runs").iterdir() if (p / "manifest.json").exists()}
    finished |= {p.name for p in (results / "references").iterdir() if (p / "manifest.json").exists()}
    assert 2 <= len(finished) < 10
    time.sleep(0.5)  # the orphaned render got SIGTERM from the kernel and is gone

    status = subprocess.run(cmd, env={**os.environ}, capture_output=True, text=True, timeout=120)
    assert status.returncode == 0, status.stdout + status.stderr
    again = _keys_rendered(render_log())[len(started) :]
    assert not set(again) & finished, status.stdout  # nothing finished was redone
    assert len(again) == 10 - len(finished)  # 2 region maps, 2 references, 6 runs
    assert "cached" in status.stdout
    assert not any((results / "runs" / ".attempts").iterdir())


def test_04_bad_config_fails_before_any_render(
    cli: CliRunner, write_experiment: Callable[..., Path], render_log: Callable[[], list[str]]
) -> None:
    exp = write_experiment(strategies=["light", "portl"])
    status, _, err = cli("sweep", str(exp))
    assert status == 2
    # file:line:column of the offending item, then its key
    line = exp.read_text().splitlines().index("- portl") + 1
    assert f"{exp}:{line}:3: strategies.1: unknown strategy 'portl'" in err
    exp = write_experiment(scene="../scenes/missing.yaml")
    status, _, err = cli("sweep", str(exp))
    assert status == 2 and "scene: scene file" in err and "not found" in err
    assert render_log() == []


def test_05_metrics_command(
    cli: CliRunner, fake_scene: Path, results: Path, render_log: Callable[[], list[str]]
) -> None:
    status, out, err = cli(
        "run", str(fake_scene), "--strategy", "portal", "--time", "0.2", "--spp", "0", "--snapshot-every", "0.05"
    )
    assert status == 0, err
    key = out.split()[1].rstrip(":")
    status, out, err = cli("reference", str(fake_scene), "--spp", "256")
    assert status == 0 and "reference" in out
    status, out2, _ = cli("reference", str(fake_scene), "--spp", "256")
    assert "cached: nothing rendered" in out2 and len(render_log()) == 2
    status, out, err = cli("metrics", key, "--inset", "corner=0,0,4,4")
    assert status == 0, err
    lines = out.strip().splitlines()
    assert lines[0].startswith("run,reference,strategy,image,is_final,time_s,spp,region,mse,rel_mse")
    assert any(",corner," in line for line in lines) and any(",image," in line for line in lines)
    run_dir = results / "runs" / key
    assert (run_dir / "metrics.csv").exists() and (run_dir / "metrics.json").exists()
    status, out, _ = cli("metrics", str(run_dir), "--json")
    rows = json.loads(out)
    # a reference without the region AOV: the whole image and its lit pixels only
    assert rows and {r["region"] for r in rows} == {"image", "lit"}
    status, out, err = cli("metrics", key, "--inset", "huge=0,0,99,99")
    assert status == 2 and "does not fit" in err


def _summary(results: Path, name: str = "tiny") -> dict[str, Any]:
    summary: dict[str, Any] = json.loads((results / "experiments" / name / "summary.json").read_text())
    return summary


def test_06_a_biased_strategy_stops_the_sweep_before_any_run(
    cli: CliRunner,
    write_experiment: Callable[..., Path],
    results: Path,
    render_log: Callable[[], list[str]],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # the renderer's fault hook: portal's samples 5% too bright
    monkeypatch.setenv("PORTAL_LIGHTS_FAULT_BIAS", "portal:1.05")
    exp = write_experiment(reference={"strategies": ["light", "portal"], "spp": 2000, "seed": 99})
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 1
    assert "references light and portal disagree in region" in out and "one of the two strategies is biased" in out
    assert "stopped" in out
    # region maps and references only: nothing was measured against them
    assert len(render_log()) == 2 + 4
    # without the fault (and its cached references) the same sweep goes through, its bias statistic small
    monkeypatch.delenv("PORTAL_LIGHTS_FAULT_BIAS")
    shutil.rmtree(results / "references")
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out
    for ref in _summary(results)["references"]:
        assert ref["bias_max_abs_z"] < 4 and [p["strategy"] for p in ref["parts"]] == ["light", "portal"]


def test_07_a_short_reference_is_extended_until_it_resolves_every_region(
    cli: CliRunner, write_experiment: Callable[..., Path], results: Path, render_log: Callable[[], list[str]]
) -> None:
    exp = write_experiment(reference={"strategy": "light", "spp": 60, "seed": 99})
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out
    assert "extending reference" in out
    summary = _summary(results)
    for ref in summary["references"]:
        assert ref["parts"][0]["spp"] > 60 and not ref["capped"]
        assert all(c["ok"] for c in ref["noise"]), ref["noise"]
        manifest = json.loads((results / "references" / ref["key"] / "manifest.json").read_text())
        assert manifest["extensions"][0]["from_spp"] == 60
        assert manifest["final"]["spp"] == ref["parts"][0]["spp"]
    assert all(r["reference_noise_ratio"] <= 0.1 and r["bound"] == "" for r in summary["rows"])
    # the extended references are reused by the next sweep, and nothing is extended again
    before = len(render_log())
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0 and len(render_log()) == before and "extending" not in out


def test_08_replicates_auto_references_and_figures(
    cli: CliRunner, write_experiment: Callable[..., Path], results: Path
) -> None:
    exp = write_experiment(
        budget={"time_s": 0.2, "threads": 1, "seed": 1, "replicates": 3, "snapshots": {"every": 0.05}},
        reference={"strategies": "auto", "spp": 1500, "seed": 99, "pilot_time_s": 0.2},
    )
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out
    summary = _summary(results)
    # the pilot picks the fake's less noisy portal; light is the second, independent part
    for ref in summary["references"]:
        assert [p["strategy"] for p in ref["parts"]] == ["portal", "light"]
        assert abs(ref["bias_max_abs_z"]) < 4
    rows = [r for r in summary["rows"] if r["region"] == "lit"]
    assert rows and all(r["replicates"] == 3 for r in rows)
    portal = [r for r in rows if r["strategy"] == "portal"]
    # the fake's efficiency ratio: (1.2^2 x 0.01) / (0.7^2 x 0.011) = 2.67, within 5 standard errors
    for r in portal:
        assert 0 < r["efficiency_vs_light_stderr"] < 1
        assert abs(r["efficiency_vs_light"] - 2.67) < 5 * r["efficiency_vs_light_stderr"] + 0.1
    conn = sqlite3.connect(results / "index.sqlite")
    roles = dict(conn.execute("SELECT role, count(*) FROM experiment_runs GROUP BY role").fetchall())
    conn.close()
    assert roles == {"run": 2 * 2 * 3, "reference": 2, "reference_part": 4, "pilot": 4, "region_map": 2}
    status, out, err = cli("figures", str(exp))
    assert status == 0, err
    assert (results / "figures" / "tiny_efficiency.png").stat().st_size > 5000


def test_09_the_pilot_sets_the_first_reference_time(
    cli: CliRunner, write_experiment: Callable[..., Path], results: Path
) -> None:
    exp = write_experiment(reference={"strategies": "auto", "time_s": 1, "seed": 99, "pilot_time_s": 0.2})
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out
    for ref in _summary(results)["references"]:
        first, second = ref["parts"]
        assert (first["strategy"], second["strategy"]) == ("portal", "light")
        # T = 0.2 s x worst need (about 1 for the fake's portal) x 9 x 1.25, in whole seconds, at
        # least reference.time_s; the second part keeps reference.time_s
        assert 2.0 <= first["time_s"] <= 5.0 and abs(first["time_s"] - round(first["time_s"])) < 0.05, first
        assert second["time_s"] == pytest.approx(1.0, abs=0.02)
        assert all(c["ok"] for c in ref["noise"])


def test_10_run_keys_follow_the_included_files_and_meshes(
    cli: CliRunner,
    write_experiment: Callable[..., Path],
    fake_scene: Path,
    results: Path,
    render_log: Callable[[], list[str]],
) -> None:
    import yaml

    # scenes/top.yaml includes parts/base.yaml (the tiny lampshade), which reads two
    # meshes by paths relative to itself
    meshes = fake_scene.parent.parent / "meshes"
    meshes.mkdir()
    for name in ("cube.obj", "polys_le.ply"):
        shutil.copy(Path(__file__).resolve().parents[2] / "configs" / "meshes" / name, meshes / name)
    tree = yaml.safe_load(fake_scene.read_text())
    away = [{"translate": [40, 0, 0]}]  # out of sight: the fake renders from the effective config anyway
    tree["shapes"] += [
        {"name": "cube", "type": "mesh", "material": "white", "file": "../../meshes/cube.obj", "transform": away},
        {"name": "polys", "type": "mesh", "material": "red", "file": "../../meshes/polys_le.ply", "transform": away},
    ]
    base = fake_scene.parent / "parts" / "base.yaml"
    base.parent.mkdir()
    base.write_text(yaml.safe_dump(tree, sort_keys=False))
    (fake_scene.parent / "top.yaml").write_text("include: parts/base.yaml\nfilm: {width: 16}\n")
    exp = write_experiment(scene="../scenes/top.yaml")

    def sweep() -> set[str]:
        before = len(render_log())
        status, out, err = cli("sweep", str(exp), "--no-progress")
        assert status == 0, out + err
        return set(_keys_rendered(render_log()[before:]))

    first = sweep()
    assert len(first) == 2 + 2 + 4  # region maps, references, runs
    assert sweep() == set()
    # a touched file with the same bytes is the same scene: nothing is rendered again
    for f in (meshes / "cube.obj", meshes / "polys_le.ply", base):
        os.utime(f, ns=(0, 0))
    assert sweep() == set()
    # new bytes in a mesh, or in the included file: every render is redone, under new keys
    ply = (meshes / "polys_le.ply").read_bytes()
    at = ply.index(b"end_header\n") + len(b"end_header\n")  # the lowest byte of the first vertex's x
    seen = set(first)
    for f, data in (
        (meshes / "polys_le.ply", ply[:at] + bytes([ply[at] ^ 1]) + ply[at + 1 :]),
        (meshes / "cube.obj", (meshes / "cube.obj").read_bytes() + b"# more\n"),
        (base, base.read_bytes() + b"# more\n"),
    ):
        f.write_bytes(data)
        rendered = sweep()
        assert len(rendered) == 8 and not rendered & seen, f.name
        seen |= rendered


def test_11_a_pilot_too_short_for_the_firefly_test_is_drawn_again_by_samples(
    cli: CliRunner, write_experiment: Callable[..., Path], results: Path
) -> None:
    # 0.65 s of the fake draws 65 passes of light (0.01 s each) but 60 of portal (0.011 s):
    # only portal's pilots are drawn again, for pilot.MIN_SPP samples
    exp = write_experiment(reference={"strategies": "auto", "time_s": 1, "seed": 99, "pilot_time_s": 0.65})
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    conn = sqlite3.connect(results / "index.sqlite")
    pilots = conn.execute(
        "SELECT e.strategy, r.spp_target, r.time_target_s, r.final_spp FROM experiment_runs e "
        "JOIN runs r ON r.key = e.key WHERE e.role = 'pilot'"
    ).fetchall()
    by_time = conn.execute(
        "SELECT strategy, final_spp FROM runs WHERE time_target_s = 0.65 AND params_json LIKE '%pilot%'"
    ).fetchall()
    conn.close()
    # two points: every strategy's pilot by time, then portal's again by samples
    assert sorted(by_time) == [("light", 65)] * 2 + [("portal", 60)] * 2
    # the pilots the plan records, and scores, are the last ones drawn
    assert sorted(pilots) == [("light", 0, 0.65, 65)] * 2 + [("portal", pilot.MIN_SPP, 0.0, pilot.MIN_SPP)] * 2
    for ref in _summary(results)["references"]:
        assert [p["strategy"] for p in ref["parts"]] == ["portal", "light"]


def test_12_a_shared_reference_is_continued_from_what_is_stored(
    cli: CliRunner, write_experiment: Callable[..., Path], results: Path, render_log: Callable[[], list[str]]
) -> None:
    # Two experiments whose references draw the same sample stream (same scene, strategy, seed)
    # but were planned with different lengths: the second continues the first's stored and
    # extended references instead of rendering its own from the first pass.
    a = write_experiment("a", reference={"strategy": "light", "spp": 60, "seed": 99})
    status, out, _ = cli("sweep", str(a), "--no-progress")
    assert status == 0 and "extending reference" in out, out
    folders = [d for d in (results / "references").iterdir() if (d / "manifest.json").exists()]
    stored = {d.name: json.loads((d / "manifest.json").read_text()) for d in folders}
    extended = {k: m["final"]["spp"] for k, m in stored.items() if m.get("extensions")}
    assert len(extended) == 2
    b = write_experiment("b", reference={"strategy": "light", "spp": 80, "seed": 99, "noise_ratio": 0.05})
    status, out, _ = cli("sweep", str(b), "--no-progress")
    assert status == 0, out
    summary = _summary(results, "b")
    for ref in summary["references"]:
        (part,) = ref["parts"]
        assert part["key"] in extended  # the stored reference, not a new 80-spp one
        manifest = json.loads((results / "references" / part["key"] / "manifest.json").read_text())
        history = [(e["from_spp"], e["to_spp"]) for e in manifest["extensions"]]
        # every extension starts where the one before ended: nothing rendered twice
        assert history[0][0] == 60 and all(x[1] == y[0] for x, y in itertools.pairwise(history))
    # b has no reference folder of its own
    assert {d.name for d in (results / "references").iterdir() if (d / "manifest.json").exists()} == set(stored)
