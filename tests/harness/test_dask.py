"""The Dask path: a two-point sweep on a real LocalCluster over loopback;
tasks return the run folders' files, installed by the client."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable
from pathlib import Path

import pytest

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
