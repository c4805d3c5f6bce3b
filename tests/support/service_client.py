"""Helpers of the service's API tests (FastAPI's TestClient, in-process):
the fixtures `root` (a --root folder with the tiny scene) and `make_client`
(clients of apps over a temporary results folder), the token, the tiny
experiment over the root's scenes/tiny.yaml, submitting, waiting, refusals.
A test module imports the fixtures (`*_fixture`) and names them in its
FIXTURES, so that pytest finds them there."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import tiny_experiment
from fastapi.testclient import TestClient

from portal_harness.core.paths import ResultsLayout
from portal_harness.service.app import create_app
from portal_harness.service.settings import ServiceSettings

TOKEN = "s3cret-token"
AUTH = {"Authorization": f"Bearer {TOKEN}", "Content-Type": "application/yaml"}
YAML = {"Content-Type": "application/yaml"}


@pytest.fixture(name="root")
def root_fixture(tmp_path: Path, fake_scene: Path) -> Path:
    """A --root folder holding the tiny scene as scenes/tiny.yaml."""
    folder = tmp_path / "root"
    (folder / "scenes").mkdir(parents=True)
    (folder / "scenes" / "tiny.yaml").write_bytes(fake_scene.read_bytes())
    return folder


def experiment_text(**sections: Any) -> str:
    """The shared tiny experiment, over the service root's scenes/tiny.yaml."""
    doc = tiny_experiment("svc_tiny", {"scene": "scenes/tiny.yaml", **sections})
    return yaml.safe_dump(doc, sort_keys=False)


@pytest.fixture(name="make_client")
def make_client_fixture(
    tmp_path: Path, root: Path, fake_renderer: Path, render_log: Callable[[], list[str]]
) -> Iterator[Callable[..., TestClient]]:
    clients: list[TestClient] = []

    def make(host: str = "127.0.0.1", renderer: Path | None = None, poll_s: float = 0.05, **extra: Any) -> TestClient:
        settings = ServiceSettings(
            layout=ResultsLayout(tmp_path / "results"),
            renderer=str(renderer or fake_renderer),
            roots=(root.resolve(),),
            token=TOKEN,
            host=host,
            poll_s=poll_s,
            **extra,
        )
        client = TestClient(create_app(settings))
        client.__enter__()
        clients.append(client)
        return client

    yield make
    for c in clients:
        c.__exit__(None, None, None)


def tmp_results(client: TestClient) -> Path:
    root: Path = client.app.state.settings.layout.root  # type: ignore[attr-defined]
    return root


def wait_for(client: TestClient, experiment_id: str, statuses: set[str], timeout_s: float = 60) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        view: dict[str, Any] = client.get(f"/api/experiments/{experiment_id}").json()
        if view["status"] in statuses:
            return view
        time.sleep(0.1)
    raise AssertionError(f"experiment {experiment_id} still {view['status']} after {timeout_s} s")


def submit(client: TestClient, text: str) -> str:
    r = client.post("/api/experiments", content=text, headers=AUTH)
    assert r.status_code == 202, r.text
    return str(r.json()["id"])


def refusal(client: TestClient, text: str) -> dict[str, Any]:
    r = client.post("/api/experiments", content=text, headers=AUTH)
    assert r.status_code == 422, r.text
    body: dict[str, Any] = r.json()
    assert set(body) >= {"file", "key", "line", "message"}
    return body


TINY = experiment_text()  # the tiny experiment as text: a base for edits (with_line)


def listing(folder: Path) -> list[str]:
    """Every file and folder under `folder` but the index's own files (its WAL changes with reads)."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if not p.name.startswith("index.sqlite"))


def refused(client: TestClient, text: str, status: int = 422) -> dict[str, Any]:
    """The body of a refusal, after checking that it is located and that it left nothing behind."""
    results = tmp_results(client)
    before = listing(results)
    started = time.monotonic()
    r = client.post("/api/experiments", content=text, headers=AUTH)
    elapsed = time.monotonic() - started
    assert r.status_code == status, r.text
    body: dict[str, Any] = r.json()
    # Located: the file and the line (and the key, but for a YAML syntax error, which has none).
    assert body["file"] == "experiment.yaml" and body["line"] is not None, body
    assert body["key"] or body["message"].startswith("YAML syntax error"), body
    assert listing(results) == before, "a refusal left something behind"
    assert client.get("/api/experiments").json() == []
    assert elapsed < 10, f"refused after {elapsed:.1f} s"
    return body


def with_line(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)
