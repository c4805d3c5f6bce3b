"""One run through the store with the fake renderer: manifest, caching,
failures kept with their stderr, nothing half-finished counted as finished."""

from __future__ import annotations

import dataclasses
import json
import os
import re
from collections.abc import Callable
from pathlib import Path

import pytest

from portal_harness.analysis import measure
from portal_harness.core import exr
from portal_harness.core.errors import ConfigError
from portal_harness.core.metrics import Region
from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.core.regions import regions_of
from portal_harness.execution import runs, store
from portal_harness.execution.renderer import renderer_version
from portal_harness.experiment.scene import spec_from_scene


@pytest.fixture
def layout(results: Path) -> ResultsLayout:
    return ResultsLayout(results)


def test_01_run_writes_manifest_snapshots_and_is_cached(
    fake_scene: Path, fake_renderer: Path, layout: ResultsLayout, render_log: Callable[[], list[str]]
) -> None:
    version = renderer_version(str(fake_renderer))
    assert version == "0.1.0-fake"
    spec = spec_from_scene(
        fake_scene, {}, str(fake_renderer), strategy="portal", spp=0, time_s=0.2, snapshots={"every": "0.05"}
    )
    events: list[str] = []
    m = runs.execute(spec, layout, str(fake_renderer), version, on_event=lambda e: events.append(e["event"]))
    assert m["status"] == "done" and not m["cached"]
    assert events[0] == "start" and events[-1] == "final" and events.count("snapshot") >= 3
    run = layout.run(m["key"])
    on_disk = json.loads(run.manifest.read_text())
    assert on_disk["status"] == "done" and on_disk["key"] == m["key"]
    for field in ("spec", "params", "command", "renderer", "host", "timings", "exit_status", "snapshots"):
        assert field in on_disk
    assert on_disk["renderer"]["version"] == "0.1.0-fake"
    assert on_disk["command"][3] == str(run.dir)
    for s in on_disk["snapshots"]:
        assert exr.read_header(run.resolve(s["file"])).spp == s["spp"]
    assert run.config.exists() and run.final.exists() and run.events.exists()
    assert exr.read_header(run.final).render_time_s == pytest.approx(on_disk["final"]["time_s"])
    assert not any(layout.attempts_dir().iterdir())
    again = runs.execute(spec, layout, str(fake_renderer), version)
    assert again["cached"] and len(render_log()) == 1


def test_02_crash_is_failed_with_stderr_kept(
    fake_scene: Path,
    fake_renderer: Path,
    layout: ResultsLayout,
    render_log: Callable[[], list[str]],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("FAKE_RENDER_CRASH", "portal")
    version = renderer_version(str(fake_renderer))
    spec = spec_from_scene(
        fake_scene, {}, str(fake_renderer), strategy="portal", spp=0, time_s=0.2, snapshots={"every": "0.05"}
    )
    m = runs.execute(spec, layout, str(fake_renderer), version)
    assert m["status"] == "failed" and m["signal"] == "SIGSEGV"
    assert "SIGSEGV" in m["error"]
    run = layout.run(m["key"])
    assert "simulated crash" in run.stderr.read_text()
    assert "simulated crash" in m["stderr_tail"]
    assert not store.is_done(run)
    # a failed run is retried, and recorded as done once it works
    monkeypatch.delenv("FAKE_RENDER_CRASH")
    m2 = runs.execute(spec, layout, str(fake_renderer), version)
    assert m2["status"] == "done" and not m2["cached"] and store.is_done(run)
    assert len(render_log()) == 2


def test_03_unimplemented_strategy_and_config_errors_fail(
    fake_scene: Path,
    fake_renderer: Path,
    layout: ResultsLayout,
    render_log: Callable[[], list[str]],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("FAKE_RENDER_UNIMPLEMENTED", "antishadow_exact")
    version = renderer_version(str(fake_renderer))
    spec = spec_from_scene(fake_scene, {}, str(fake_renderer), strategy="antishadow_exact", spp=4)
    m = runs.execute(spec, layout, str(fake_renderer), version)
    assert m["status"] == "failed" and m["exit_status"] == 1 and "not implemented" in m["stderr_tail"]
    # the renderer checks the schedule before any render: its message, as a ConfigError
    with pytest.raises(ConfigError, match=re.escape("render.snapshots.every=-1")):
        spec_from_scene(fake_scene, {}, str(fake_renderer), strategy="light", spp=4, snapshots={"every": "-1"})
    # and a render it refuses anyway fails with exit status 2
    bad = dataclasses.replace(spec, strategy="light", snapshots=(("every", "-1"),))
    m = runs.execute(bad, layout, str(fake_renderer), version)
    assert m["status"] == "failed" and m["exit_status"] == 2


def test_04_interrupted_attempt_is_never_installed(
    fake_scene: Path, fake_renderer: Path, layout: ResultsLayout, monkeypatch: pytest.MonkeyPatch
) -> None:
    version = renderer_version(str(fake_renderer))
    spec = spec_from_scene(fake_scene, {}, str(fake_renderer), strategy="light", spp=8)
    key = spec.key(version)

    def interrupted(*args: object, **kwargs: object) -> dict[str, object]:
        raise KeyboardInterrupt

    monkeypatch.setattr(runs, "execute_in", interrupted)
    with pytest.raises(KeyboardInterrupt):
        runs.execute(spec, layout, str(fake_renderer), version)
    assert not layout.run(key).dir.exists()
    # a leftover attempt of a dead process is cleaned; of a live one, kept
    dead = layout.attempts_dir() / f"{key}-999999999-0-1"
    dead.mkdir(parents=True)
    assert store.clean_stale_attempts(layout) >= 1 and not dead.exists()


def test_05_folder_without_done_manifest_is_redone(
    fake_scene: Path, fake_renderer: Path, layout: ResultsLayout, render_log: Callable[[], list[str]]
) -> None:
    version = renderer_version(str(fake_renderer))
    spec = spec_from_scene(fake_scene, {}, str(fake_renderer), strategy="light", spp=8)
    run = layout.run(spec.key(version))
    run.dir.mkdir(parents=True)
    (run.dir / "final.exr").write_bytes(b"half")
    store.write_json_atomic(run.manifest, {"status": "interrupted"})
    m = runs.execute(spec, layout, str(fake_renderer), version)
    assert m["status"] == "done" and len(render_log()) == 1
    assert exr.read_header(run.final).spp == 8


def test_06_corrupt_snapshot_is_reported_not_averaged(
    fake_scene: Path, fake_renderer: Path, layout: ResultsLayout, render_log: Callable[[], list[str]]
) -> None:
    version = renderer_version(str(fake_renderer))
    spec = spec_from_scene(
        fake_scene, {}, str(fake_renderer), strategy="light", spp=0, time_s=0.1, snapshots={"every": "0.02"}
    )
    m = runs.execute(spec, layout, str(fake_renderer), version)
    run = layout.run(m["key"])
    ref = exr.read_snapshot(run.final)
    victim = run.resolve(m["snapshots"][1]["file"])
    victim.write_bytes(victim.read_bytes()[:300])
    rows = measure.compute(run, m, ref, regions_of(ref, (Region("a", 0, 0, 4, 4),))[::2])  # image and "a"
    bad = [r for r in rows if r.error]
    assert len(bad) == 1 and bad[0].image == victim.name and bad[0].mse is None
    assert bad[0].error is not None and "corrupt" in bad[0].error
    good = [r for r in rows if not r.error]
    assert len(good) == 2 * (len(m["snapshots"]) - 1 + 1)
    final_rows = [r for r in good if r.is_final]
    assert all(r.mse == 0.0 for r in final_rows)


def test_07_install_files_writes_manifest_last(layout: ResultsLayout, tmp_path: Path) -> None:
    files = {"final.exr": b"x", "manifest.json": json.dumps({"status": "done", "key": "k"}).encode(), "stderr.txt": b""}
    run = store.install_files(layout, "k", False, files)
    assert store.is_done(run) and (run.dir / "final.exr").read_bytes() == b"x"
    with pytest.raises(ValueError):
        store.install_files(layout, "k2", False, {"../evil": b"x"})


def test_08_relative_paths_in_manifest(tmp_path: Path) -> None:
    run = RunLayout(tmp_path / "r")
    run.dir.mkdir()
    assert run.relative(run.dir / "snapshot_0001.exr") == "snapshot_0001.exr"
    assert run.relative(os.path.join("elsewhere", "final.exr")) == "final.exr"
