"""What the API shows of an experiment: its queue row, and each of its
renders with a status and a progress read from the store. A finished
render has its manifest; a render in progress is an attempt folder whose
events.jsonl the renderer writes live (one JSON line per snapshot), so the
progress of a run is the renderer's own stream, read from its tail.

Views are cached for a fraction of a second, so that many clients polling
or following events cost one look at the store per experiment.
"""

from __future__ import annotations

import os
import threading
import time
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


class Views:
    """Cached views of experiments (the API's JSON of one experiment)."""

    def __init__(self, layout: ResultsLayout, queue: q.Queue, ttl_s: float = 0.25) -> None:
        self.layout = layout
        self.queue = queue
        self.ttl_s = ttl_s
        self._manifests = _ManifestCache()
        self._cache: dict[str, tuple[float, dict[str, Any]]] = {}  # by id: (when its build started, view)
        self._building: dict[str, threading.Lock] = {}
        self._lock = threading.Lock()

    def peek(self, experiment_id: str) -> dict[str, Any] | None:
        """The cached view if it is recent enough, without any I/O (for the event loop)."""
        with self._lock:
            cached = self._cache.get(experiment_id)
        if cached is not None and time.monotonic() - cached[0] < self._ttl(cached[1]):
            return cached[1]
        return None

    def _ttl(self, view: dict[str, Any]) -> float:
        # A finished experiment's renders change only if another sweep redoes one.
        return self.ttl_s * (8 if view["status"] in q.FINISHED else 1)

    def get(self, experiment_id: str, fresh: bool = False) -> dict[str, Any] | None:
        """The view, rebuilt when older than the TTL (or `fresh`); concurrent
        callers wait for one rebuild instead of each doing their own."""
        if not fresh:
            found = self.peek(experiment_id)
            if found is not None:
                return found
        with self._lock:
            building = self._building.setdefault(experiment_id, threading.Lock())
            asked = time.monotonic()
        with building:
            with self._lock:
                cached = self._cache.get(experiment_id)
            # Built by another caller while this one waited (after it asked, if it asked for a fresh one).
            if cached is not None and (cached[0] >= asked or (not fresh and self.peek(experiment_id) is not None)):
                return cached[1]
            row = self.queue.get(experiment_id)
            if row is None:
                with self._lock:
                    self._cache.pop(experiment_id, None)
                return None
            started = time.monotonic()
            view = self._build(row)
            with self._lock:
                self._cache[experiment_id] = (started, view)
            return view

    def summary(self, row: dict[str, Any]) -> dict[str, Any]:
        """The short form of the list: no runs."""
        view = self.get(str(row["id"]))
        if view is None:
            return _head(row, 0.0)
        return {k: v for k, v in view.items() if k != "runs"}

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

    def _build(self, row: dict[str, Any]) -> dict[str, Any]:
        status = str(row["status"])
        attempts = _attempts(self.layout)
        runs: list[dict[str, Any]] = []
        for r in self.queue.runs(str(row["id"])):
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
        progress = 1.0 if status == q.DONE else (sum(r["progress"] for r in planned) / len(planned) if planned else 0.0)
        return {**_head(row, progress), "runs": runs}


def _head(row: dict[str, Any], progress: float) -> dict[str, Any]:
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
