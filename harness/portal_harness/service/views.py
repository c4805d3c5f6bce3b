"""The views of experiments the API answers with, cached per experiment so
that a read costs the same whatever the number of runs an experiment holds.

A read of an experiment is one query (its queue row: status, times, error
are always current) and the cached rest: its progress, its counts of
renders by status and its renders (the detail view's `runs`, kept encoded
as JSON). The rest is rebuilt (progress.ViewBuilder: the store's state of
every render) only

- by a refresher thread, every `ttl_s`, for running experiments that a
  client read within the last WATCH_S seconds (the readers never wait for
  it, and 50 clients of one experiment cost one rebuild per period);
- by a read that finds the row changed since the cache was built (another
  status, a restart) or nothing cached: once per change.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass
from typing import Any

from portal_harness.core.paths import ResultsLayout
from portal_harness.service import queue as q
from portal_harness.service.progress import ViewBuilder, head

WATCH_S = 30.0  # a running experiment read within this many seconds is kept fresh


def stamp(row: dict[str, Any]) -> tuple[Any, ...]:
    """What of a row, when it changes, changes the renders' view."""
    return (row["status"], row["started"], row["finished"], row["restarts"])


def _counts(runs: list[dict[str, Any]]) -> dict[str, int]:
    out: dict[str, int] = {}
    for r in runs:
        out[r["status"]] = out.get(r["status"], 0) + 1
    return out


@dataclass(frozen=True)
class Cached:
    stamp: tuple[Any, ...]
    view: dict[str, Any]  # progress.ViewBuilder.build
    runs_json: bytes  # view["runs"], encoded
    runs: int  # planned runs (role run)
    counts: dict[str, int]  # renders by status
    built: float  # time.monotonic() when built

    @staticmethod
    def of(row: dict[str, Any], view: dict[str, Any]) -> Cached:
        runs = view["runs"]
        return Cached(
            stamp=stamp(row),
            view=view,
            runs_json=json.dumps(runs, separators=(",", ":")).encode(),
            runs=sum(1 for r in runs if r["role"] == "run"),
            counts=_counts(runs),
            built=time.monotonic(),
        )


class Views:
    """Cached views of experiments; `start` runs the refresher thread."""

    def __init__(self, layout: ResultsLayout, queue: q.Queue, ttl_s: float = 0.25) -> None:
        self.queue = queue
        self.ttl_s = ttl_s
        self.builder = ViewBuilder(layout, queue)
        self._cache: dict[str, Cached] = {}
        self._watched: dict[str, float] = {}  # id -> when last read
        self._locks: dict[str, threading.Lock] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # --- reads ---------------------------------------------------------------------------------------------------

    def cached(self, experiment_id: str) -> Cached | None:
        """The cache of an experiment, without any I/O (for the event loop)."""
        with self._lock:
            return self._cache.get(experiment_id)

    def current(self, row: dict[str, Any]) -> Cached:
        """The cache of the experiment of `row`, rebuilt first if the row changed since."""
        experiment_id = str(row["id"])
        with self._lock:
            self._watched[experiment_id] = time.monotonic()
            found = self._cache.get(experiment_id)
        if found is not None and found.stamp == stamp(row):
            return found
        return self._rebuild(row)

    def status(self, row: dict[str, Any], c: Cached | None = None) -> dict[str, Any]:
        """The status read: head of the row, progress and counts from the cache `c` (by default current)."""
        c = c if c is not None else self.current(row)
        return {**head(row, c.view["progress"]), "run_count": c.runs, "renders": c.counts}

    def detail_of(self, row: dict[str, Any], c: Cached | None = None) -> bytes:
        """The detail view of the row's experiment (its status and every render), as JSON."""
        c = c if c is not None else self.current(row)
        first = json.dumps(head(row, c.view["progress"]), separators=(",", ":")).encode()
        return first[:-1] + b',"runs":' + c.runs_json + b"}"

    def servable(self, row: dict[str, Any]) -> Cached | None:
        """A cache a read may answer `row` with at once, without I/O: the current one, or, while the
        experiment is queued or running, the last one (its status and times come from the row, always
        current; its progress and renders are at most one refresher period late, and the refresher is
        told to catch up). None when a build is due: nothing cached, or the experiment finished since."""
        experiment_id = str(row["id"])
        with self._lock:
            found = self._cache.get(experiment_id)
            if found is not None and found.stamp != stamp(row) and row["status"] not in q.FINISHED:
                self._watched[experiment_id] = time.monotonic()
                return found
        return found if found is not None and found.stamp == stamp(row) else None

    def get(self, experiment_id: str, fresh: bool = False) -> dict[str, Any] | None:
        """The whole view (a dict), rebuilt if `fresh`; None if there is no such experiment."""
        row = self.queue.get(experiment_id)
        if row is None:
            self.forget(experiment_id)
            return None
        c = self._rebuild(row) if fresh else self.current(row)
        return {**c.view, **head(row, c.view["progress"])}

    def watch(self, experiment_id: str) -> None:
        """Keeps the experiment's cache refreshed (a client follows it)."""
        with self._lock:
            self._watched[experiment_id] = time.monotonic()

    def forget(self, experiment_id: str) -> None:
        with self._lock:
            self._cache.pop(experiment_id, None)
            self._watched.pop(experiment_id, None)
        self.builder.forget(experiment_id)

    # --- rebuilds ------------------------------------------------------------------------------------------------

    def _rebuild(self, row: dict[str, Any]) -> Cached:
        """Builds the cache of `row`'s experiment; concurrent callers share one build."""
        experiment_id = str(row["id"])
        with self._lock:
            lock = self._locks.setdefault(experiment_id, threading.Lock())
            asked = time.monotonic()
        with lock:
            with self._lock:
                found = self._cache.get(experiment_id)
            if found is not None and found.built >= asked and found.stamp == stamp(row):
                return found  # built by another caller while this one waited
            made = Cached.of(row, self.builder.build(row))
            with self._lock:
                self._cache[experiment_id] = made
            return made

    def refresh(self) -> None:
        """One pass of the refresher: rebuilds the running experiments read lately."""
        now = time.monotonic()
        with self._lock:
            ids = [i for i, c in self._cache.items() if c.stamp[0] in (q.RUNNING, q.QUEUED)]
            watched = {i for i, t in self._watched.items() if now - t < WATCH_S}
        for experiment_id in ids:
            if experiment_id not in watched:
                continue
            row = self.queue.get(experiment_id)
            cached = self.cached(experiment_id)
            if row is None:
                self.forget(experiment_id)
            elif row["status"] == q.RUNNING or cached is None or stamp(row) != cached.stamp:
                self._rebuild(row)

    def _loop(self) -> None:
        while not self._stop.wait(self.ttl_s):
            try:
                self.refresh()
            except Exception:  # a failed pass is retried at the next; reads rebuild on their own
                continue

    def start(self) -> None:
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name="views-refresher", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
