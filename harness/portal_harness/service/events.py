"""An experiment's server-sent event stream: what changed in its view
(progress.py) since the last look, every poll interval.

Events (each `data:` one JSON object):
- `status`: the experiment's status (`{id, status, progress, error}`), or
  a render's (`{id, key, role, status, error, stderr_tail}`);
- `progress`: the experiment's (`{id, progress}`) or a render's
  (`{id, key, progress, spp, time_s}`), from the renderer's own stream, at
  most every PROGRESS_S (a render's last progress before the stream ends);
- `summary`: the first event: the experiment's `{id, status, progress,
  error, restarts, run_count, renders}` (renders: how many are in each status), not
  each render's history; after it, only what changes;
- `end`: the experiment finished (or was deleted); the stream closes.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator
from typing import Any

import anyio

from portal_harness.service import queue as q
from portal_harness.service.progress import head
from portal_harness.service.views import Views

KEEPALIVE_S = 15.0
# Progress events of a stream at most this often (50 clients of 2 renders at 4 Hz made 600 events/s).
PROGRESS_S = 1.0


def format_event(kind: str, data: dict[str, Any]) -> str:
    return f"event: {kind}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n"


def changes(
    view: dict[str, Any], last: dict[str, tuple[str, float]], experiment_id: str, progress: bool = True
) -> list[tuple[str, dict[str, Any]]]:
    """The events between the state `last` (updated in place) and `view`;
    without `progress`, status changes only (progress waits for the next call with it)."""
    out: list[tuple[str, dict[str, Any]]] = []
    for run in view["runs"]:
        key = run["key"]
        prev = last.get(key)
        if not progress:
            if prev is None or prev[0] != run["status"]:
                out.append(("status", _run_status(experiment_id, run)))
                last[key] = (run["status"], prev[1] if prev is not None else -1.0)
            continue
        if prev is None or prev[0] != run["status"]:
            out.append(("status", _run_status(experiment_id, run)))
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
    if progress and (prev is None or prev[1] != view["progress"]):
        out.append(("progress", {"id": experiment_id, "progress": view["progress"]}))
    last[""] = (view["status"], view["progress"] if progress or prev is None else prev[1])
    return out


def _run_status(experiment_id: str, run: dict[str, Any]) -> dict[str, Any]:
    return {
        "id": experiment_id,
        "key": run["key"],
        "role": run["role"],
        "status": run["status"],
        "error": run["error"],
        "stderr_tail": run["stderr_tail"],
    }


def summary(view: dict[str, Any], experiment_id: str) -> dict[str, Any]:
    """The first event of a stream: the experiment's state in one object, its renders counted by status."""
    counts: dict[str, int] = {}
    for r in view["runs"]:
        counts[r["status"]] = counts.get(r["status"], 0) + 1
    return {
        "id": experiment_id,
        "status": view["status"],
        "progress": view["progress"],
        "error": view["error"],
        "restarts": view["restarts"],
        "run_count": sum(1 for r in view["runs"] if r["role"] == "run"),
        "renders": counts,
    }


async def _opening(views: Views, experiment_id: str) -> dict[str, Any] | None:
    """The view a stream opens with: its row (one query) and the cache, without a thread unless the
    view must be built (50 streams opening at once would otherwise queue for the thread pool)."""
    row = views.queue.get(experiment_id)
    if row is None:
        return None
    cached = views.servable(row)
    if cached is None:
        cached = await anyio.to_thread.run_sync(views.current, row)
    return {**cached.view, **head(row, cached.view["progress"])}


async def stream(views: Views, experiment_id: str, poll_s: float) -> AsyncIterator[str]:
    """The event stream of one experiment, until it finishes: a summary, then what changes."""
    yield "retry: 2000\n\n"
    view = await _opening(views, experiment_id)
    if view is None:
        yield format_event("status", {"id": experiment_id, "status": "deleted"})
        yield format_event("end", {"id": experiment_id})
        return
    last: dict[str, tuple[str, float]] = {}
    changes(view, last, experiment_id)  # the state at connection: said by the summary, not render by render
    yield format_event("summary", summary(view, experiment_id))
    quiet_since = progress_sent = time.monotonic()
    while view["status"] not in q.FINISHED:
        await asyncio.sleep(poll_s)
        views.watch(experiment_id)
        # The cache the refresher keeps (views.py), shared by every stream: no query, no thread.
        cached = views.cached(experiment_id)
        if cached is None:
            found = await anyio.to_thread.run_sync(views.get, experiment_id)
            if found is None:
                yield format_event("status", {"id": experiment_id, "status": "deleted"})
                yield format_event("end", {"id": experiment_id})
                return
            view = found
        else:
            view = cached.view
        # Status changes at once; progress at most every PROGRESS_S (and all of it before the end).
        now = time.monotonic()
        with_progress = now - progress_sent >= PROGRESS_S or view["status"] in q.FINISHED
        if with_progress:
            progress_sent = now
        found_changes = changes(view, last, experiment_id, with_progress)
        for kind, data in found_changes:
            yield format_event(kind, data)
        if found_changes:
            quiet_since = time.monotonic()
        elif time.monotonic() - quiet_since > KEEPALIVE_S:
            yield ": keep-alive\n\n"
            quiet_since = time.monotonic()
    yield format_event("end", {"id": experiment_id, "status": view["status"]})
