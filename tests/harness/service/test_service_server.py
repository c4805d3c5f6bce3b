"""The real `portal-harness serve`, started as a process on a free port and
driven over HTTP, with the real renderer: a tiny sweep (16x16), the
service killed with SIGKILL in the middle of it and started again. The
sweep resumes: what was finished is not rendered again, nothing
half-finished counts as done."""

from __future__ import annotations

import json
import os
import sqlite3
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import yaml
from served import TOKEN, Service, free_port

REPO = Path(__file__).resolve().parents[3]


def _experiment() -> str:
    return yaml.safe_dump(
        {
            "name": "served_tiny",
            "scene": "lampshade.yaml",
            "integrator": "direct",
            "strategies": ["light", "portal"],
            "sweep": {"params.s_L": [0.15, 0.6]},
            "fixed": {"params.s_P": 0.3, "film.width": 16, "film.height": 16},
            "budget": {"time_s": 0.5, "threads": 1, "seed": 1, "replicates": 2, "snapshots": {"every": 0.1}},
            "reference": {"strategy": "light", "spp": 64, "seed": 7},
            "axis": {"param": "params.s_L", "divide_by": "params.s_P"},
        }
    )


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie is dead too (its parent, the killed service, cannot reap it until init does).
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.real
def test_01_sigkill_mid_sweep_then_restart_resumes_without_redoing_finished_runs(
    real_renderer: Path, tmp_path: Path
) -> None:
    root = tmp_path / "root"
    root.mkdir()
    (root / "lampshade.yaml").write_bytes((REPO / "configs" / "scenes" / "lampshade.yaml").read_bytes())
    results = tmp_path / "results"
    service = Service(results, root, real_renderer, free_port())
    service.start()
    try:
        # Without the token: refused over HTTP too.
        with pytest.raises(urllib.error.HTTPError) as refused:
            service.request("POST", "/api/experiments", _experiment().encode())
        assert refused.value.code == 401
        experiment_id = service.request("POST", "/api/experiments", _experiment().encode(), token=TOKEN)["id"]
        deadline = time.monotonic() + 120
        done_before: dict[str, str] = {}
        while time.monotonic() < deadline:
            view = service.get(f"/api/experiments/{experiment_id}")
            runs = [r for r in view["runs"] if r["role"] == "run"]
            finished = [r for r in runs if r["status"] == "done"]
            if 2 <= len(finished) < len(runs):
                break
            assert view["status"] in ("queued", "running"), view
            time.sleep(0.05)
        else:
            raise AssertionError("the sweep never reached its middle")
        with sqlite3.connect(results / "index.sqlite") as conn:
            worker = conn.execute("SELECT pid FROM service_experiments WHERE id = ?", (experiment_id,)).fetchone()[0]
        service.kill()
        # The worker (and its renders) die with the service.
        deadline = time.monotonic() + 10
        while _alive(worker) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(worker)
        for run in (results / "runs").iterdir():
            if run.name.startswith("."):
                continue
            manifest = json.loads((run / "manifest.json").read_text())
            if manifest["status"] == "done":
                done_before[manifest["key"]] = manifest["timings"]["started"]
        assert len(done_before) >= 2

        service.start()
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            view = service.get(f"/api/experiments/{experiment_id}")
            if view["status"] in ("done", "failed", "cancelled"):
                break
            time.sleep(0.1)
        assert view["status"] == "done", view
        assert view["restarts"] == 1 and view["progress"] == 1.0
        runs = [r for r in view["runs"] if r["role"] == "run"]
        assert len(runs) == 8 and {r["status"] for r in runs} == {"done"}
        for key, started in done_before.items():
            manifest = json.loads((results / "runs" / key / "manifest.json").read_text())
            assert manifest["timings"]["started"] == started, f"run {key} was rendered again"
        assert not [p for p in (results / "runs" / ".attempts").iterdir() if not p.name.startswith("trash-")]
        png = urllib.request.urlopen(f"http://127.0.0.1:{service.port}/api/runs/{runs[0]['key']}/image.png").read()
        assert png.startswith(b"\x89PNG")
    finally:
        service.stop()
