"""Issue 42, items 6 and 7: a status read costs the same whatever the
number of runs of the experiment (one index query, no rebuild of its
view), an event stream opens with a summary, not every render's history;
the progress of an unfinished experiment never shows 100%; `portal-harness
report` reads an experiment the service stored."""

from __future__ import annotations

import json
import os
import sqlite3
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from service_client import AUTH, experiment_text, make_client_fixture, root_fixture, submit, tmp_results, wait_for

from portal_harness.service import queue as q
from portal_harness.service.progress import ViewBuilder

FIXTURES = (make_client_fixture, root_fixture)


def fake_experiment(results: Path, experiment_id: str, runs: int) -> None:
    """An experiment of `runs` planned runs, queued in the index (nothing renders: parallel=0)."""
    rows = [q.PlannedRunRow(f"key{i:05d}", f"s_L={i}", "light", 0, f"s_L={i}", 0, 2.0) for i in range(runs)]
    q.Queue(results / "index.sqlite").add(experiment_id, f"many_{runs}", results / "x.yaml", results, rows)


def events_of(client: TestClient, experiment_id: str) -> list[tuple[str, dict[str, Any]]]:
    out: list[tuple[str, dict[str, Any]]] = []
    kind = ""
    with client.stream("GET", f"/api/experiments/{experiment_id}/events") as stream:
        for line in stream.iter_lines():
            if line.startswith("event: "):
                kind = line.removeprefix("event: ")
            elif line.startswith("data: "):
                out.append((kind, json.loads(line.removeprefix("data: "))))
    return out


def test_01_a_status_read_does_constant_work_whatever_the_runs(
    make_client: Callable[..., TestClient], monkeypatch: pytest.MonkeyPatch
) -> None:
    statements: list[str] = []
    connect = sqlite3.connect

    def counted(*args: Any, **kwargs: Any) -> sqlite3.Connection:
        conn: sqlite3.Connection = connect(*args, **kwargs)
        conn.set_trace_callback(statements.append)
        return conn

    monkeypatch.setattr(sqlite3, "connect", counted)  # the queue's connections: every statement counted
    builds: list[str] = []
    build = ViewBuilder.build

    def counted_build(self: ViewBuilder, row: dict[str, Any]) -> dict[str, Any]:
        builds.append(str(row["id"]))
        return build(self, row)

    monkeypatch.setattr(ViewBuilder, "build", counted_build)
    client = make_client(parallel=0, poll_s=60)  # no refresher pass during the test
    results = tmp_results(client)
    for runs in (10, 2000):
        fake_experiment(results, f"many-{runs}", runs)
    cost: dict[tuple[int, str], tuple[int, int]] = {}
    for runs in (10, 2000):
        for kind, path in (
            ("status", f"/api/experiments/many-{runs}?runs=false"),
            ("detail", f"/api/experiments/many-{runs}"),
        ):
            first = client.get(path).json()  # the first read builds the view once
            assert first["status"] == "queued"
            del statements[:], builds[:]
            for _ in range(5):
                assert client.get(path).status_code == 200
            cost[(runs, kind)] = (len(statements), len(builds))
    status = client.get("/api/experiments/many-2000?runs=false").json()
    assert status["run_count"] == 2000 and status["renders"] == {"queued": 2000} and status["progress"] == 0
    # The same number of queries for 10 runs as for 2000: one per read (the row), and no rebuild.
    for kind in ("status", "detail"):
        assert cost[(10, kind)] == cost[(2000, kind)] == (5, 0), cost
    # The list: one query for every experiment, no rebuild.
    del statements[:], builds[:]
    listed = client.get("/api/experiments").json()
    assert {e["id"] for e in listed} == {"many-10", "many-2000"} and len(statements) == 1 and builds == []
    # A running experiment whose row changed is answered at once from its last view (status and times from
    # the row, renders caught up by the refresher): 50 clients reading it at the change wait for no build.
    with sqlite3.connect(results / "index.sqlite") as conn:
        conn.execute("UPDATE service_experiments SET status = 'running', started = 1 WHERE id = 'many-10'")
    del statements[:], builds[:]
    for _ in range(5):
        read = client.get("/api/experiments/many-10?runs=false").json()
        assert read["status"] == "running" and read["progress"] < 1
    assert (len(statements), len(builds)) == (5, 0)
    # A finished one is built once at its first read, so that its final view is never stale.
    with sqlite3.connect(results / "index.sqlite") as conn:
        conn.execute("UPDATE service_experiments SET status = 'failed', finished = 2 WHERE id = 'many-10'")
    for _ in range(5):
        assert client.get("/api/experiments/many-10?runs=false").json()["status"] == "failed"
    assert builds == ["many-10"]
    # A stream opens with a summary, not 2000 render events.
    assert client.delete("/api/experiments/many-2000", headers=AUTH).json()["status"] == "cancelled"
    events = events_of(client, "many-2000")
    assert [k for k, _ in events] == ["summary", "end"], events
    assert events[0][1]["run_count"] == 2000 and events[0][1]["renders"] == {"cancelled": 2000}


def test_02_progress_report_and_summary_of_a_served_experiment(
    make_client: Callable[..., TestClient], tmp_path: Path, fake_renderer: Path
) -> None:
    from portal_harness.cli import main

    client = make_client(figures=False)
    experiment_id = submit(client, experiment_text(sweep={"params.s_L": [0.6]}, strategies=["light"]))
    # Queued or running: never 100 %.
    seen = [client.get(f"/api/experiments/{experiment_id}?runs=false").json()]
    view = wait_for(client, experiment_id, {"done", "failed"})
    assert view["status"] == "done" and view["progress"] == 1.0
    assert all(s["progress"] < 1 for s in seen if s["status"] in ("queued", "running"))
    events = events_of(client, experiment_id)
    assert [k for k, _ in events] == ["summary", "end"] and events[0][1]["status"] == "done"
    # Every run done, but the experiment still running (measuring, drawing): at most 99 %.
    results = tmp_results(client)
    with sqlite3.connect(results / "index.sqlite") as conn:
        conn.execute("UPDATE service_experiments SET status = 'running' WHERE id = ?", (experiment_id,))
    running = client.get(f"/api/experiments/{experiment_id}").json()
    assert running["status"] == "running" and {r["status"] for r in running["runs"] if r["role"] == "run"} == {"done"}
    assert running["progress"] == 0.99
    with sqlite3.connect(results / "index.sqlite") as conn:
        conn.execute("UPDATE service_experiments SET status = 'done' WHERE id = ?", (experiment_id,))
    # `portal-harness report` of the stored experiment: by its file, and by its id.
    stored = results / "service" / experiment_id / "experiment.yaml"
    common = ["--results", str(results), "--renderer", str(fake_renderer)]
    for i, target in enumerate((str(stored), experiment_id)):
        out = tmp_path / f"report{i}"
        assert main(["report", target, "--out", str(out), *common]) == 0
        assert (out / "viewer.html").is_file()


@pytest.mark.skipif(not Path("/proc/self/autogroup").exists(), reason="no scheduler autogroups on this kernel")
def test_03_a_nicer_worker_yields_its_whole_session_to_the_api() -> None:
    """The worker runs in a session of its own; with autogroups, its processes' nice alone does not yield
    the cores to the API's session (the groups weigh as equals), so the worker also nices its group."""
    import subprocess
    import sys

    probe = (
        "import os; from portal_harness.service.worker import be_nicer; be_nicer(7); "
        "print(os.nice(0)); print(open('/proc/self/autogroup').read().split()[-1])"
    )
    # A new session, as the dispatcher starts a worker: never the test runner's own group.
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, start_new_session=True
    )
    own_nice = os.nice(0)
    assert done.stdout.split() == [str(min(own_nice + 7, 19)), "7"], done.stdout
