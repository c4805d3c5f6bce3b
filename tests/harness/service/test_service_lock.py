"""Issue 42, item 3: one server per results folder. A second `serve` on the
folder of a running one (on another port, so the port is not what stops
it) refuses before it touches anything: a clear message naming the lock and
the pid that holds it, a non-zero exit, the token file unchanged, and the
first server's sweep unharmed."""

from __future__ import annotations

import os
import sqlite3
import subprocess
import time
from pathlib import Path

import pytest
from served import Service, free_port
from service_client import experiment_text


def test_01_a_second_server_on_the_same_store_refuses_and_changes_nothing(
    tmp_path: Path, fake_scene: Path, fake_renderer: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("FAKE_RENDER_SLEEP", "10")  # each render lasts seconds: the sweep is running
    root = tmp_path / "root"
    (root / "scenes").mkdir(parents=True)
    (root / "scenes" / "tiny.yaml").write_bytes(fake_scene.read_bytes())
    results = tmp_path / "results"
    first = Service(results, root, fake_renderer, free_port(), token=None)  # it makes the token file
    first.start()
    try:
        token_file = results / "service" / "token"
        token_bytes = token_file.read_bytes()
        token = token_bytes.decode().strip()
        text = experiment_text(sweep={"params.s_L": [0.6]}).encode()
        experiment_id = first.request("POST", "/api/experiments", text, token=token)["id"]
        deadline = time.monotonic() + 60
        while first.get(f"/api/experiments/{experiment_id}")["status"] != "running":
            assert time.monotonic() < deadline, "the sweep never started"
            time.sleep(0.05)
        index_rows = len(first.get("/api/experiments"))
        # `running` is written just before the worker is spawned and its pid just after: wait for both.
        worker = None
        while worker is None:
            assert time.monotonic() < deadline, "the worker's pid was never recorded"
            with sqlite3.connect(results / "index.sqlite") as conn:
                row = conn.execute("SELECT pid FROM service_experiments WHERE id = ?", (experiment_id,)).fetchone()
            worker = row[0]
            time.sleep(0.05)

        second = Service(results, root, fake_renderer, free_port(), token=None)
        started = time.monotonic()
        done = subprocess.run(second.command(), env=second.env(), capture_output=True, text=True, timeout=60)
        assert done.returncode != 0
        assert first.process is not None
        lock = str(results.resolve() / "serve.lock")
        assert lock in done.stderr and f"pid {first.process.pid}" in done.stderr, done.stderr
        assert "one server per results folder" in done.stderr
        assert time.monotonic() - started < 30

        # Nothing changed: the token file, the queue, the running sweep and its worker.
        assert token_file.read_bytes() == token_bytes
        assert first.process.poll() is None
        assert len(first.get("/api/experiments")) == index_rows
        os.kill(worker, 0)  # still alive

        def renders() -> list[tuple[str, str, float]]:
            view = first.get(f"/api/experiments/{experiment_id}")
            assert view["status"] == "running" and view["restarts"] == 0 and view["error"] is None, view
            return [(r["key"], r["status"], r["progress"]) for r in view["runs"]]

        before = renders()
        deadline = time.monotonic() + 60
        while renders() == before:  # and still rendering: some render moves on
            assert time.monotonic() < deadline, "the sweep stopped"
            time.sleep(0.2)
        assert first.request("DELETE", f"/api/experiments/{experiment_id}", token=token)["status"] == "cancelling"
    finally:
        first.stop()
    # Once the first is gone, a server starts on the folder (the lock died with its holder).
    third = Service(results, root, fake_renderer, free_port(), token=None)
    third.start()
    try:
        assert third.get(f"/api/experiments/{experiment_id}")["id"] == experiment_id
    finally:
        third.stop()
