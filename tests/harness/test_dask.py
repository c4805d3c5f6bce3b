"""The Dask path: a two-point sweep on a real LocalCluster over loopback;
tasks return the run folders' files, installed by the client."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Callable

import pytest

CliRunner = Callable[..., tuple[int, str, str]]


def test_01_two_point_sweep_on_a_local_cluster(cli: CliRunner, write_experiment: Callable[..., Path], results: Path,
                                               render_log: Callable[[], list[str]],
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    distributed = pytest.importorskip("distributed")
    monkeypatch.setenv("FAKE_RENDER_CRASH", "projection")  # a task whose render fails must not stop the sweep
    exp = write_experiment(strategies=["light", "portal", "projection"])
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None, silence_logs=40) as cluster:
        status, out, err = cli("sweep", str(exp), "--scheduler", cluster.scheduler_address, "--no-progress")
    assert status == 1, out + err  # the two projection runs failed
    assert "2 failed:" in out and "SIGSEGV" in out
    summary = json.loads((results / "experiments" / "tiny" / "summary.json").read_text())
    done = [r for r in summary["rows"] if r["status"] == "done"]
    assert len(done) == 4 and all(r["rel_mse"] > 0 for r in done)
    assert len(render_log()) == 2 + 6
    # the files came back over the wire into this results folder; nothing left on the workers' side here
    for row in summary["rows"]:
        run = results / "runs" / row["key"]
        assert (run / "manifest.json").exists() and (run / "stderr.txt").exists()
        if row["status"] == "done":
            assert (run / "final.exr").stat().st_size > 0 and (run / "metrics.json").exists()
    failed = next(r for r in summary["rows"] if r["status"] == "failed")
    assert "simulated crash" in (results / "runs" / failed["key"] / "stderr.txt").read_text()
    conn = sqlite3.connect(results / "index.sqlite")
    assert conn.execute("SELECT count(*) FROM runs").fetchone()[0] == 8
    conn.close()
    # resuming locally renders only what failed
    monkeypatch.delenv("FAKE_RENDER_CRASH")
    before = len(render_log())
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0 and len(render_log()) == before + 2
