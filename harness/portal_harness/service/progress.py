"""What the API shows of an experiment: its queue row, and each of its
renders with a status and a progress read from the store. A finished
render has its manifest; a render in progress is an attempt folder whose
events.jsonl the renderer writes live (one JSON line per snapshot), so the
progress of a run is the renderer's own stream, read from its tail.

The views are cached and refreshed by views.py.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Any

from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.execution import store
from portal_harness.execution.index import ROLE_RUN
from portal_harness.execution.renderer import parse_events
from portal_harness.service import queue as q

TAIL_BYTES = 8192
# What a manifest's status means for a render of the service.
_RUN_STATUS = {store.STATUS_DONE: q.DONE, store.STATUS_FAILED: q.FAILED, store.STATUS_INTERRUPTED: q.CANCELLED}
_REFERENCE_ROLES = {"reference", "reference_part"}
UNFINISHED_MAX = 0.99  # the most progress a queued or running experiment shows


def tail_events(path: Path) -> list[dict[str, Any]]:
    """The complete JSON lines at the end of an events file (a partial last line is skipped)."""
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            start = max(0, size - TAIL_BYTES)
            f.seek(start)
            data = f.read()
    except OSError:
        return []
    lines = data.split(b"\n")
    if start > 0:
        lines = lines[1:]  # the first line may be cut
    if not data.endswith(b"\n"):
        lines = lines[:-1]
    return parse_events(lines)


def progress_of(events: list[dict[str, Any]], spp_target: int = 0, time_target_s: float = 0.0) -> dict[str, Any]:
    """(progress in 0..1, spp, time_s) of a render from its latest events:
    render time over the time limit, else samples over the sample limit
    (the limits of its start event when the caller knows none)."""
    progress, spp, time_s = 0.0, 0, 0.0
    for e in events:
        if e.get("event") == "start":
            spp_target = spp_target or int(e.get("spp_target") or 0)
            time_target_s = time_target_s or float(e.get("time_target_s") or 0.0)
    for e in events:
        kind = e.get("event")
        if kind in ("snapshot", "final"):
            spp = int(e.get("spp") or 0)
            time_s = float(e.get("time_s") or 0.0)
            parts = []
            if time_target_s > 0:
                parts.append(time_s / time_target_s)
            if spp_target > 0:
                parts.append(spp / spp_target)
            progress = max(parts) if parts else 0.0
            if kind == "final":
                progress = 1.0
    return {"progress": min(1.0, max(0.0, progress)), "spp": spp, "time_s": time_s}


class _ManifestCache:
    """Parsed manifests by path, kept while the file's mtime stays (finished runs never change)."""

    def __init__(self) -> None:
        self._by: dict[str, tuple[int, dict[str, Any] | None]] = {}
        self._lock = threading.Lock()

    def read(self, run: RunLayout) -> dict[str, Any] | None:
        path = str(run.manifest)
        try:
            mtime = os.stat(path).st_mtime_ns
        except OSError:
            return None
        with self._lock:
            found = self._by.get(path)
        if found is not None and found[0] == mtime:
            return found[1]
        m = store.read_manifest(run)
        small = None
        if m is not None:
            final = m.get("final") or {}
            small = {
                "status": m.get("status"),
                "error": m.get("error"),
                "stderr_tail": m.get("stderr_tail"),
                "spp": final.get("spp"),
                "time_s": final.get("time_s"),
            }
        with self._lock:
            self._by[path] = (mtime, small)
        return small


def _attempts(layout: ResultsLayout) -> dict[str, Path]:
    """Attempt folders in progress, by run key (runs and references)."""
    out: dict[str, Path] = {}
    for reference in (False, True):
        try:
            names = os.listdir(layout.attempts_dir(reference))
        except OSError:
            continue
        for name in names:
            if name.startswith("trash-"):
                continue
            key = name.split("-", 1)[0]
            out[key] = layout.attempts_dir(reference) / name
    return out


class ViewBuilder:
    """Builds the view of one experiment (its JSON: the queue row's head, and
    each render's state from the store); its run list, which never changes
    once submitted, is read from the queue once per experiment."""

    def __init__(self, layout: ResultsLayout, queue: q.Queue) -> None:
        self.layout = layout
        self.queue = queue
        self._manifests = _ManifestCache()
        self._planned: dict[str, list[dict[str, Any]]] = {}
        self._lock = threading.Lock()

    def forget(self, experiment_id: str) -> None:
        with self._lock:
            self._planned.pop(experiment_id, None)

    def _planned_runs(self, experiment_id: str) -> list[dict[str, Any]]:
        with self._lock:
            found = self._planned.get(experiment_id)
        if found is None:
            found = self.queue.runs(experiment_id)
            with self._lock:
                self._planned[experiment_id] = found
        return found

    def _render(
        self, key: str, reference: bool, attempts: dict[str, Path], status: str, spp: int = 0, time_s: float = 0.0
    ) -> dict[str, Any]:
        m = self._manifests.read(self.layout.run(key, reference))
        if m is not None:
            run_status = _RUN_STATUS.get(str(m["status"]), q.FAILED)
            done = run_status == q.DONE
            return {
                "status": run_status,
                "progress": 1.0 if done else 0.0,
                "spp": m["spp"],
                "time_s": m["time_s"],
                "error": m["error"],
                "stderr_tail": None if done else m["stderr_tail"],
            }
        attempt = attempts.get(key)
        if attempt is not None and status == q.RUNNING:
            p = progress_of(tail_events(RunLayout(attempt).events), spp, time_s)
            return {"status": q.RUNNING, **p, "error": None, "stderr_tail": None}
        pending = {q.QUEUED: q.QUEUED, q.RUNNING: q.QUEUED, q.CANCELLED: q.CANCELLED}.get(status, q.FAILED)
        return {"status": pending, "progress": 0.0, "spp": None, "time_s": None, "error": None, "stderr_tail": None}

    def build(self, row: dict[str, Any]) -> dict[str, Any]:
        """The experiment's view now: its head (head()) and `runs`."""
        status = str(row["status"])
        attempts = _attempts(self.layout) if status == q.RUNNING else {}
        runs: list[dict[str, Any]] = []
        for r in self._planned_runs(str(row["id"])):
            state = self._render(r["key"], False, attempts, status, r["spp"], r["time_s"])
            runs.append(
                {
                    "key": r["key"],
                    "point": r["point"],
                    "strategy": r["strategy"],
                    "role": ROLE_RUN,
                    "replicate": r["replicate"],
                    "target_spp": r["spp"],
                    "target_time_s": r["time_s"],
                    **state,
                }
            )
        seen = {r["key"] for r in runs}
        for m in self.queue.membership(str(row["name"])):
            if m["key"] in seen:  # a reference of one part is that part
                continue
            seen.add(m["key"])
            state = self._render(m["key"], m["role"] in _REFERENCE_ROLES, attempts, status)
            runs.append(
                {
                    "key": m["key"],
                    "point": m["point"],
                    "strategy": m["strategy"],
                    "role": m["role"],
                    "replicate": m["replicate"],
                    "target_spp": None,
                    "target_time_s": None,
                    **state,
                }
            )
        planned = [r for r in runs if r["role"] == ROLE_RUN]
        progress = sum(r["progress"] for r in planned) / len(planned) if planned else 0.0
        return {**head(row, progress), "runs": runs}


def head(row: dict[str, Any], progress: float) -> dict[str, Any]:
    """The row's status, times and error (always current) with `progress`, which may come from an older
    view: 1 once done, and never 100% before (every run done, the sweep may still measure and draw)."""
    if row["status"] == q.DONE:
        progress = 1.0
    elif row["status"] in (q.QUEUED, q.RUNNING):
        progress = min(progress, UNFINISHED_MAX)
    return {
        "id": row["id"],
        "name": row["name"],
        "status": row["status"],
        "submitted": row["submitted"],
        "started": row["started"],
        "finished": row["finished"],
        "progress": round(progress, 4),
        "error": row["error"],
        "restarts": row["restarts"],
    }
