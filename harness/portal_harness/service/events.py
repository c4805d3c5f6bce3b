"""An experiment's server-sent event stream: what changed in its view
(progress.py) since the last look, every poll interval.

Events (each `data:` one JSON object):
- `status`: the experiment's status (`{id, status, progress, error}`), or
  a render's (`{id, key, role, status, error, stderr_tail}`);
- `progress`: the experiment's (`{id, progress}`) or a render's
  (`{id, key, progress, spp, time_s}`), from the renderer's own stream;
- `end`: the experiment finished (or was deleted); the stream closes.
On connecting, a client first gets every render's status and progress.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator
from typing import Any

import anyio

from portal_harness.service import queue as q
from portal_harness.service.progress import Views

KEEPALIVE_S = 15.0


def format_event(kind: str, data: dict[str, Any]) -> str:
    return f"event: {kind}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n"


def changes(
    view: dict[str, Any], last: dict[str, tuple[str, float]], experiment_id: str
) -> list[tuple[str, dict[str, Any]]]:
    """The events between the state `last` (updated in place) and `view`."""
    out: list[tuple[str, dict[str, Any]]] = []
    for run in view["runs"]:
        key = run["key"]
        prev = last.get(key)
        if prev is None or prev[0] != run["status"]:
            out.append(
                (
                    "status",
                    {
                        "id": experiment_id,
                        "key": key,
                        "role": run["role"],
                        "status": run["status"],
                        "error": run["error"],
                        "stderr_tail": run["stderr_tail"],
                    },
                )
            )
        if prev is None or prev[1] != run["progress"]:
            out.append(
                (
                    "progress",
                    {
                        "id": experiment_id,
                        "key": key,
                        "progress": run["progress"],
                        "spp": run["spp"],
                        "time_s": run["time_s"],
                    },
                )
            )
        last[key] = (run["status"], run["progress"])
    prev = last.get("")
    if prev is None or prev[0] != view["status"]:
        out.append(
            (
                "status",
                {"id": experiment_id, "status": view["status"], "progress": view["progress"], "error": view["error"]},
            )
        )
    if prev is None or prev[1] != view["progress"]:
        out.append(("progress", {"id": experiment_id, "progress": view["progress"]}))
    last[""] = (view["status"], view["progress"])
    return out


async def stream(views: Views, experiment_id: str, poll_s: float) -> AsyncIterator[str]:
    """The event stream of one experiment, until it finishes."""
    last: dict[str, tuple[str, float]] = {}
    quiet_since = time.monotonic()
    yield "retry: 2000\n\n"
    while True:
        # A recent view is shared by every stream of the experiment: no thread, no I/O.
        view = views.peek(experiment_id) or await anyio.to_thread.run_sync(views.get, experiment_id)
        if view is None:
            yield format_event("status", {"id": experiment_id, "status": "deleted"})
            yield format_event("end", {"id": experiment_id})
            return
        found = changes(view, last, experiment_id)
        for kind, data in found:
            yield format_event(kind, data)
        if found:
            quiet_since = time.monotonic()
        elif time.monotonic() - quiet_since > KEEPALIVE_S:
            yield ": keep-alive\n\n"
            quiet_since = time.monotonic()
        if view["status"] in q.FINISHED:
            yield format_event("end", {"id": experiment_id, "status": view["status"]})
            return
        await asyncio.sleep(poll_s)
