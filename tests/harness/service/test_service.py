"""The service's API (FastAPI's TestClient, in-process; sweeps run in real
worker processes with the fake renderer): submit, follow, fetch, cancel,
a renderer crash, and every refusal of the security section."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from service_client import (
    AUTH,
    TOKEN,
    YAML,
    experiment_text,
    make_client_fixture,
    refusal,
    root_fixture,
    submit,
    tmp_results,
    wait_for,
)

FIXTURES = (make_client_fixture, root_fixture)


def test_01_a_submitted_experiment_runs_to_done_with_events_images_summary_figures(
    make_client: Callable[..., TestClient],
) -> None:
    client = make_client()
    experiment_id = submit(client, experiment_text(sweep={"params.s_L": [0.15, 0.6]}, strategies=["light"]))
    listed = client.get("/api/experiments").json()
    assert [e["id"] for e in listed] == [experiment_id] and listed[0]["status"] in ("queued", "running")
    # The event stream, followed from the start to its end.
    kinds: list[str] = []
    run_progress: dict[str, list[float]] = {}
    with client.stream("GET", f"/api/experiments/{experiment_id}/events") as stream:
        kind = ""
        for line in stream.iter_lines():
            if line.startswith("event: "):
                kind = line.removeprefix("event: ")
                kinds.append(kind)
            elif line.startswith("data: ") and kind == "progress":
                data = json.loads(line.removeprefix("data: "))
                if "key" in data:
                    run_progress.setdefault(data["key"], []).append(data["progress"])
    assert kinds[-1] == "end" and "status" in kinds and "progress" in kinds
    view = wait_for(client, experiment_id, {"done"})
    assert view["progress"] == 1.0 and view["error"] is None
    runs = [r for r in view["runs"] if r["role"] == "run"]
    assert len(runs) == 2 and {r["status"] for r in runs} == {"done"}
    assert {r["point"] for r in runs} == {"s_L=0.15", "s_L=0.6"}
    assert all(r["spp"] > 0 and r["time_s"] > 0 for r in runs)
    assert any(r["role"] in ("reference", "reference_part") and r["status"] == "done" for r in view["runs"])
    # Every run's progress went up to 1, never down.
    for r in runs:
        values = run_progress[r["key"]]
        assert values[-1] == 1.0 and values == sorted(values)
    key = runs[0]["key"]
    png = client.get(f"/api/runs/{key}/image.png")
    assert png.status_code == 200 and png.content.startswith(b"\x89PNG")
    exr = client.get(f"/api/runs/{key}/image.exr")
    assert exr.status_code == 200 and exr.content.startswith(b"\x76\x2f\x31\x01")
    csv = client.get(f"/api/experiments/{experiment_id}/summary.csv")
    assert (csv.status_code == 200 and csv.text.startswith("point,")) or "strategy" in csv.text.splitlines()[0]
    assert client.get(f"/api/experiments/{experiment_id}/summary.json").json()["experiment"] == "svc_tiny"
    figures = client.get(f"/api/experiments/{experiment_id}/figures").json()
    assert any(f.endswith(".png") for f in figures) and any(f.endswith(".pdf") for f in figures)
    fig = client.get(f"/api/experiments/{experiment_id}/figures/{figures[0]}")
    assert fig.status_code == 200 and len(fig.content) > 1000
    assert client.get(f"/api/experiments/{experiment_id}/figures/..%2Findex.sqlite").status_code == 404
    assert client.get("/api/runs/..%2F..%2Findex.sqlite/image.exr").status_code == 404
    # A snapshot by its file name (as the viewer's bundle names them); never a path.
    snapshot = sorted(p.name for p in (tmp_results(client) / "runs" / key).glob("*.exr") if p.name != "final.exr")[0]
    assert client.get(f"/api/runs/{key}/image.png", params={"image": snapshot}).content.startswith(b"\x89PNG")
    for bad in ("../manifest.json", "..%2Ffinal.exr", "nothing.exr", "manifest.json"):
        assert client.get(f"/api/runs/{key}/image.png", params={"image": bad}).status_code == 404
    assert "sweep svc_tiny" in client.get(f"/api/experiments/{experiment_id}/log").text
    # The comparison viewer: its page, and the bundle the worker wrote after the sweep.
    viewer = f"/api/experiments/{experiment_id}/viewer"
    bundle = client.get(f"{viewer}/bundle.js")
    assert bundle.status_code == 200 and bundle.text.startswith("window.PORTAL_BUNDLE")
    image = client.get(f"{viewer}/img/0.js")
    assert image.status_code == 200 and "PORTAL_IMAGE(0" in image.text
    assert client.get(f"{viewer}/..%2F..%2F..%2Findex.sqlite").status_code == 404
    assert client.get(f"{viewer}/%00").status_code == 404  # was a 500 (issue 42)
    assert client.get("/viewer/viewer.html").status_code == 200


def test_02_a_renderer_crash_is_a_failed_run_with_its_stderr(
    make_client: Callable[..., TestClient], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("FAKE_RENDER_CRASH", "portal")
    client = make_client(figures=False)
    experiment_id = submit(client, experiment_text(sweep={"params.s_L": [0.6]}))
    view = wait_for(client, experiment_id, {"done", "failed"})
    assert view["status"] == "failed" and "failed" in view["error"]
    crashed = [r for r in view["runs"] if r["strategy"] == "portal" and r["role"] == "run"]
    assert crashed and crashed[0]["status"] == "failed"
    assert "SIGSEGV" in crashed[0]["error"] or "signal" in crashed[0]["error"]
    assert crashed[0]["stderr_tail"] is not None
    assert [r["status"] for r in view["runs"] if r["strategy"] == "light" and r["role"] == "run"] == ["done"]


def test_03_cancel_stops_the_sweep_and_installs_nothing_half_written(
    make_client: Callable[..., TestClient], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("FAKE_RENDER_SLEEP", "20")  # 0.2 s of virtual render time: 4 s
    client = make_client(figures=False)
    experiment_id = submit(client, experiment_text())
    queued_id = submit(client, experiment_text(name="svc_second"))
    # The second waits its turn; cancelling it takes effect at once.
    r = client.delete(f"/api/experiments/{queued_id}", headers=AUTH)
    assert r.status_code == 200 and r.json()["status"] == "cancelled"
    attempts = tmp_path / "results" / "runs" / ".attempts"
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:  # a render in progress (the first are the region maps)
        if attempts.is_dir() and any(attempts.iterdir()):
            break
        time.sleep(0.05)
    else:
        raise AssertionError("no render started")
    r = client.delete(f"/api/experiments/{experiment_id}", headers=AUTH)
    assert r.status_code == 202 and r.json()["status"] == "cancelling"
    view = wait_for(client, experiment_id, {"cancelled", "done", "failed"}, timeout_s=20)
    assert view["status"] == "cancelled"
    assert "running" not in {r["status"] for r in view["runs"]}
    # Every installed run folder holds a complete run: a manifest, and a final image if it says done.
    for parent in ("runs", "references"):
        folder = tmp_path / "results" / parent
        for run in folder.iterdir() if folder.is_dir() else []:
            if run.name.startswith("."):
                continue
            manifest = json.loads((run / "manifest.json").read_text())
            assert manifest["status"] != "done" or (run / "final.exr").is_file()
    # Purged: the record goes.
    assert client.delete(f"/api/experiments/{experiment_id}?purge=true", headers=AUTH).status_code == 200
    assert client.get(f"/api/experiments/{experiment_id}").status_code == 404


def test_04_writes_need_the_token(make_client: Callable[..., TestClient]) -> None:
    client = make_client()
    assert client.post("/api/experiments", content=experiment_text(), headers=YAML).status_code == 401
    wrong = {"Authorization": "Bearer s3cret-tokeN", **YAML}
    assert client.post("/api/experiments", content=experiment_text(), headers=wrong).status_code == 401
    basic = {"Authorization": f"Basic {TOKEN}", **YAML}
    assert client.post("/api/experiments", content=experiment_text(), headers=basic).status_code == 401
    assert client.delete("/api/experiments/x").status_code == 401
    # Reads are open on loopback; an unknown id is 404 everywhere.
    assert client.get("/api/experiments").status_code == 200
    for path in ("", "/events", "/summary.csv", "/figures", "/log", "/viewer/index.html"):
        assert client.get(f"/api/experiments/nope{path}").status_code == 404, path
    assert client.delete("/api/experiments/nope", headers=AUTH).status_code == 404
    assert client.get("/").status_code == 200


def test_05_off_loopback_every_request_needs_the_token(make_client: Callable[..., TestClient]) -> None:
    client = make_client(host="0.0.0.0")
    for path in ("/api/experiments", "/", "/docs", "/openapi.json", "/static/app.js"):
        assert client.get(path).status_code == 401, path
    assert client.get("/api/experiments", headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 200
    assert client.get("/api/experiments?token=nope").status_code == 401
    # A page opened with ?token= sets a cookie that authorises reads, never writes.
    page = client.get(f"/?token={TOKEN}")
    assert page.status_code == 200 and "HttpOnly" in page.headers["set-cookie"]
    assert client.get("/api/experiments").status_code == 200
    assert client.post("/api/experiments", content=experiment_text(), headers=YAML).status_code == 401
    assert client.delete("/api/experiments/x").status_code == 401
    client.cookies.clear()
    assert client.get("/api/experiments").status_code == 401
    client.cookies.set("portal_harness_token", "nope")
    assert client.get("/api/experiments").status_code == 401


def test_06_paths_must_stay_inside_the_roots(
    make_client: Callable[..., TestClient], root: Path, tmp_path: Path, fake_scene: Path
) -> None:
    client = make_client()
    body = refusal(client, experiment_text(scene="../scenes/tiny.yaml"))
    assert body["key"] == "scene" and body["line"] == 2 and "'..'" in body["message"]
    body = refusal(client, experiment_text(scene=str(fake_scene)))  # absolute, outside the root
    assert body["key"] == "scene" and "absolute path outside" in body["message"]
    assert refusal(client, experiment_text(scene="/etc/passwd"))["key"] == "scene"
    # A symbolic link in the root that leads out of it.
    (root / "scenes" / "link.yaml").symlink_to(fake_scene)
    body = refusal(client, experiment_text(scene="scenes/link.yaml"))
    assert "symbolic link" in body["message"]
    # An absolute path inside the root is fine.
    r = client.post("/api/experiments", content=experiment_text(scene=str(root / "scenes" / "tiny.yaml")), headers=AUTH)
    assert r.status_code == 202, r.text
    client.delete(f"/api/experiments/{r.json()['id']}", headers=AUTH)
    # A scene inside the root that includes a file outside it (through a link or not).
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "base.yaml").write_bytes(fake_scene.read_bytes())
    (root / "scenes" / "incl.yaml").write_text(f"include: {outside / 'base.yaml'}\n")
    body = refusal(client, experiment_text(scene="scenes/incl.yaml", name="incl"))
    assert "outside the --root folders" in body["message"] and str(outside) not in json.dumps(body)
    (root / "scenes" / "inner").symlink_to(outside)
    (root / "scenes" / "incl2.yaml").write_text("include: inner/base.yaml\n")
    body = refusal(client, experiment_text(scene="scenes/incl2.yaml", name="incl2"))
    assert "outside the --root folders" in body["message"]
    # A scene that is in no root.
    assert refusal(client, experiment_text(scene="scenes/nope.yaml"))["message"].endswith(
        "no such file in the --root folders"
    )


def test_07_bad_yaml_and_bad_experiments_are_422_with_file_key_line(make_client: Callable[..., TestClient]) -> None:
    client = make_client()
    body = refusal(client, "name: x\nscene: [unclosed\nstrategies: [light]\n")
    assert body["file"] == "experiment.yaml" and body["line"] == 3 and "syntax" in body["message"]
    body = refusal(client, experiment_text(strategies=["light", "prtal"]))
    assert body["key"] == "strategies.1" and body["line"] == 6 and "prtal" in body["message"]
    body = refusal(client, experiment_text(budget=None))
    assert body["key"] == "budget"
    # The renderer's own check of the scene's keys: its message, at the scene's line.
    body = refusal(client, experiment_text(fixed={"params.s_P": 0.3, "film.widht": 16}))
    assert "widht" in body["message"]
    assert refusal(client, "- a list\n")["line"] == 1
    assert refusal(client, "a: 1\n---\nb: 2\n")["message"].startswith("expected one YAML document")


def test_08_alias_bombs_oversized_bodies_and_other_types_are_refused(make_client: Callable[..., TestClient]) -> None:
    client = make_client(max_body_bytes=4096)
    bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 10)}]\n" for i in range(8)
    )
    body = refusal(client, bomb)
    assert "aliases expand" in body["message"]
    assert "aliases" in refusal(client, "a: &a [*a]\n")["message"]  # an alias of its own ancestor
    big = "description: " + "x" * 5000 + "\n"
    assert client.post("/api/experiments", content=big, headers=AUTH).status_code == 413

    def chunks() -> Iterator[bytes]:
        for _ in range(10):
            yield b"#" * 1000 + b"\n"

    assert client.post("/api/experiments", content=chunks(), headers=AUTH).status_code == 413
    assert (
        client.post("/api/experiments", content="{}", headers={**AUTH, "Content-Type": "application/json"}).status_code
        == 415
    )


def test_09_docs_are_served_without_the_network(make_client: Callable[..., TestClient]) -> None:
    client = make_client()
    page = client.get("/docs")
    assert page.status_code == 200 and "swagger" in page.text.lower()
    assert "http://" not in page.text and "https://" not in page.text
    for asset in ("/docs-assets/swagger-ui-bundle.js", "/docs-assets/swagger-ui.css"):
        assert client.get(asset).status_code == 200
    paths = client.get("/openapi.json").json()["paths"]
    assert {"/api/experiments", "/api/experiments/{experiment_id}", "/api/experiments/{experiment_id}/events"} <= set(
        paths
    )


def test_10_the_viewer_route_waits_for_a_finished_experiment(make_client: Callable[..., TestClient]) -> None:
    client = make_client(parallel=0)  # nothing starts: the experiment stays queued
    experiment_id = submit(client, experiment_text(sweep={"params.s_L": [0.6]}, strategies=["light"]))
    r = client.get(f"/api/experiments/{experiment_id}/viewer/bundle.js")
    assert r.status_code == 409 and "queued" in r.json()["message"]
    client.delete(f"/api/experiments/{experiment_id}", headers=AUTH)


def test_11_the_worker_checks_the_roots_again_when_the_sweep_starts(
    make_client: Callable[..., TestClient], root: Path, tmp_path: Path, fake_scene: Path, fake_renderer: Path
) -> None:
    from portal_harness.core.errors import HarnessError
    from portal_harness.service import queue as q
    from portal_harness.service import worker

    client = make_client(parallel=0)  # nothing starts: the test plays the worker
    experiment_id = submit(client, experiment_text())
    # After validation the scene becomes a link to a file outside the roots.
    outside = tmp_path / "elsewhere.yaml"
    outside.write_bytes(fake_scene.read_bytes())
    (root / "scenes" / "tiny.yaml").unlink()
    (root / "scenes" / "tiny.yaml").symlink_to(outside)
    results = tmp_path / "results"
    q.Queue(results / "index.sqlite").mark_running(experiment_id, None)
    with pytest.raises(HarnessError, match="outside the --root folders"):
        worker.run(experiment_id, results, str(fake_renderer), None, None, False, (root.resolve(),))
    assert not (results / "runs").exists()


def test_12_a_sweep_runs_on_the_dask_scheduler_given(
    make_client: Callable[..., TestClient], render_log: Callable[[], list[str]]
) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None, silence_logs=40
    ) as cluster:
        client = make_client(scheduler=cluster.scheduler_address, figures=False)
        experiment_id = submit(client, experiment_text(sweep={"params.s_L": [0.6]}, strategies=["light", "portal"]))
        view = wait_for(client, experiment_id, {"done", "failed"}, timeout_s=120)
        # The worker's log says where the renders went: the scheduler, not the local pool.
        log = client.get(f"/api/experiments/{experiment_id}/log").text
    assert view["status"] == "done", view["error"]
    runs = [r for r in view["runs"] if r["role"] == "run"]
    assert len(runs) == 2 and {r["status"] for r in runs} == {"done"} and all(r["progress"] == 1.0 for r in runs)
    assert cluster.scheduler_address in log, log
    assert len(render_log()) >= 2
