"""Executing one RunSpec: render into an attempt folder, check what the
renderer wrote, write the manifest last, install the folder.

`execute_in` is the part that needs the renderer and can run anywhere (a
local process-pool worker or a Dask worker); `execute` adds the store:
cache look-up and installation.
"""

from __future__ import annotations

import datetime as dt
import os
import platform
import socket
import sys
from pathlib import Path
from typing import Any

from portal_harness.core import exr
from portal_harness.core.errors import CorruptExrError
from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.execution import store
from portal_harness.execution.renderer import EXIT_INTERRUPTED, EXIT_OK, EventCallback, render
from portal_harness.experiment.spec import RunSpec


def now() -> str:
    """A manifest's timestamp: UTC, ISO 8601, milliseconds."""
    return dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")


def final_record(file: str, header: exr.SnapshotHeader) -> dict[str, Any]:
    """A manifest's `final` entry for a final image with this header."""
    return {
        "file": file,
        "time_s": header.render_time_s,
        "spp": header.spp,
        "rays": header.rays,
        "nonfinite": header.nonfinite_samples,
    }


def _host() -> dict[str, Any]:
    return {
        "hostname": socket.gethostname(),
        "platform": platform.platform(),
        "python": sys.version.split()[0],
        "cpus": os.cpu_count(),
    }


def file_tail(path: Path, limit: int = 2000) -> str:
    try:
        data = path.read_bytes()
    except OSError:
        return ""
    return data[-limit:].decode(errors="replace")


def default_timeout(spec: RunSpec) -> float | None:
    """Wall-clock limit after which a render counts as hung: generous, since
    only a renderer that ignores its own time limit should ever reach it."""
    if spec.time_s > 0:
        return 3.0 * spec.time_s + 60.0
    return None


def execute_in(
    spec: RunSpec,
    run: RunLayout,
    renderer: str,
    renderer_version: str,
    key: str,
    scene_path: str | None = None,
    on_event: EventCallback | None = None,
    final_dir: str | None = None,
) -> dict[str, Any]:
    """Renders `spec` into the (empty) folder `run` and writes its manifest
    there, last. Returns the manifest. `final_dir` is where the folder will be
    installed (recorded in the reproducible command)."""
    command = spec.command(renderer, scene_path or spec.scene, str(run.dir))
    started = now()
    result = render(command, run.events, run.stderr, on_event=on_event, timeout_s=default_timeout(spec))
    finished = now()

    start_event = next((e for e in result.events if e.get("event") == "start"), {})
    final_event = next((e for e in result.events if e.get("event") == "final"), None)
    snapshots: list[dict[str, Any]] = [
        {
            "index": int(e.get("index", 0)),
            "file": run.relative(str(e.get("path", ""))),
            "time_s": float(e.get("time_s", 0.0)),
            "spp": int(e.get("spp", 0)),
        }
        for e in result.events
        if e.get("event") == "snapshot"
    ]

    error: str | None = None
    status = store.STATUS_DONE
    if result.timed_out:
        status, error = store.STATUS_FAILED, f"renderer still running after {default_timeout(spec):.0f} s: killed"
    elif result.signal_name is not None:
        status, error = store.STATUS_FAILED, f"renderer killed by {result.signal_name}"
    elif result.exit_status == EXIT_INTERRUPTED:
        status, error = store.STATUS_INTERRUPTED, "renderer interrupted (exit 3)"
    elif result.exit_status != EXIT_OK:
        status, error = store.STATUS_FAILED, f"renderer exited with status {result.exit_status}"

    final: dict[str, Any] | None = None
    if status == store.STATUS_DONE:
        try:
            snap = exr.read_snapshot(run.final)
            final = final_record(run.relative(run.final), snap.header)
            if snap.header.strategy != spec.strategy or snap.header.integrator != spec.integrator:
                status, error = (
                    store.STATUS_FAILED,
                    (
                        f"final.exr says strategy={snap.header.strategy} integrator={snap.header.integrator}, "
                        f"expected {spec.strategy}/{spec.integrator}"
                    ),
                )
        except CorruptExrError as e:
            status, error = store.STATUS_FAILED, str(e)
        if status == store.STATUS_DONE and final_event is None:
            status, error = store.STATUS_FAILED, "no final event on the renderer's stdout"
        if status == store.STATUS_DONE:
            for s in snapshots:
                try:
                    exr.read_header(run.resolve(s["file"]))
                except CorruptExrError as e:
                    status, error = store.STATUS_FAILED, str(e)
                    break

    out_dir = final_dir or str(run.dir)
    manifest: dict[str, Any] = {
        "schema": store.MANIFEST_SCHEMA,
        "key": key,
        "kind": "reference" if spec.reference else "run",
        "status": status,
        "error": error,
        "spec": spec.to_dict(),
        "params": spec.params(),
        "scene_hash": spec.scene_hash(),
        "command": spec.command(renderer, spec.scene, out_dir),
        "renderer": {"path": renderer, "version": renderer_version, "config_hash": start_event.get("config_hash")},
        "host": _host(),
        "timings": {
            "started": started,
            "finished": finished,
            "wall_s": round(result.wall_s, 3),
            "render_time_s": final["time_s"] if final else None,
        },
        "exit_status": result.exit_status,
        "signal": result.signal_name,
        "snapshots": snapshots,
        "final": final,
        "malformed_stdout_lines": result.malformed_lines[:20],
        "stderr_file": run.relative(run.stderr),
        "stderr_tail": file_tail(run.stderr),
    }
    store.write_json_atomic(run.manifest, manifest)
    return manifest


def execute(
    spec: RunSpec,
    layout: ResultsLayout,
    renderer: str,
    renderer_version: str,
    on_event: EventCallback | None = None,
    force: bool = False,
    retry_failed: bool = True,
) -> dict[str, Any]:
    """Runs `spec` unless its folder already holds a finished run (a failed
    one is retried unless retry_failed is False). Returns the manifest, with
    "cached": True when nothing was rendered."""
    key = spec.key(renderer_version)
    target = layout.run(key, spec.reference)
    existing = store.read_manifest(target)
    status = existing.get("status") if existing is not None else None
    if (
        existing is not None
        and not force
        and (status == store.STATUS_DONE or (not retry_failed and status == store.STATUS_FAILED))
    ):
        return {**existing, "cached": True}
    # An interrupted harness leaves the attempt folder behind; it is never
    # installed, so nothing half-finished is counted as finished.
    attempt = store.new_attempt(layout, key, spec.reference)
    manifest = execute_in(spec, attempt, renderer, renderer_version, key, on_event=on_event, final_dir=str(target.dir))
    store.install(layout, key, spec.reference, attempt)
    return {**manifest, "cached": False}
