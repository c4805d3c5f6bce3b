"""The SQLite index: WAL mode, curve queries, two writers at once."""

from __future__ import annotations

import multiprocessing
from pathlib import Path
from typing import Any

from portal_harness.execution import index
from portal_harness.execution.index import MetricRow


def _manifest(key: str, strategy: str, s_l: float, ratio: float) -> dict[str, Any]:
    return {
        "key": key,
        "kind": "run",
        "status": "done",
        "scene_hash": "h" * 16,
        "spec": {
            "strategy": strategy,
            "integrator": "direct",
            "scene": "/s.yaml",
            "spp": 0,
            "time_s": 1.0,
            "seed": 1,
            "threads": 1,
        },
        "renderer": {"version": "v"},
        "final": {"time_s": 1.0, "spp": 10},
        "timings": {},
        "exit_status": 0,
        "params": {"params.s_L": s_l, "params.s_P": 0.3, "ratio": ratio},
    }


def _rows(scale: float) -> list[MetricRow]:
    return [
        MetricRow(f"snapshot_{i:04d}.exr", False, 0.1 * i, i, region, scale / i, 2 * scale / i, 0.0, None)
        for i in (1, 2, 3)
        for region in ("image", "inset")
    ]


def test_01_wal_mode_and_curves(tmp_path: Path) -> None:
    conn = index.connect(tmp_path / "index.sqlite")
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    for key, strategy, s_l in (("a", "portal", 0.075), ("b", "portal", 0.3), ("c", "light", 0.075)):
        index.record_run(conn, _manifest(key, strategy, s_l, s_l / 0.3), tmp_path / key)
        index.record_metrics(conn, key, "ref", _rows(1.0))
    found = index.curves(conn, "portal", {"ratio": 0.075 / 0.3})
    assert list(found) == ["a"]
    assert found["a"] == [(0.1, 2.0), (0.2, 1.0), (0.30000000000000004, 2.0 / 3)]
    assert list(index.curves(conn, "portal")) == ["a", "b"]
    assert list(index.curves(conn, "light", {"params.s_L": 0.075}, metric="mse", region="inset")) == ["c"]
    # re-recording replaces, never duplicates
    index.record_metrics(conn, "a", "ref", _rows(2.0))
    assert len(index.metrics_of(conn, "a")) == 6
    conn.close()


def _writer(path: str, worker: int, count: int) -> None:
    conn = index.connect(Path(path))
    for i in range(count):
        key = f"w{worker}-{i}"
        index.record_run(conn, _manifest(key, "light", 0.3, 1.0), Path("/x") / key)
        index.record_metrics(conn, key, "ref", _rows(1.0))
    conn.close()


def test_02_two_processes_write_concurrently(tmp_path: Path) -> None:
    path = str(tmp_path / "index.sqlite")
    index.connect(Path(path)).close()
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_writer, args=(path, w, 40)) for w in (1, 2)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    conn = index.connect(Path(path))
    assert conn.execute("SELECT count(*) FROM runs").fetchone()[0] == 80
    assert conn.execute("SELECT count(*) FROM metrics").fetchone()[0] == 80 * 6
    assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    conn.close()
