"""The experiment queue, kept in the results index (results/index.sqlite,
WAL): one row per submitted experiment and one per planned run, so that a
restarted service finds what was queued or running.

Statuses: queued -> running -> done | failed | cancelled (a queued one may
be cancelled at once). Run folders are not this module's: their state is
read from the store (progress.py).
"""

from __future__ import annotations

import datetime as dt
import secrets
import sqlite3
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from portal_harness.execution import index

QUEUED = "queued"
RUNNING = "running"
DONE = "done"
FAILED = "failed"
CANCELLED = "cancelled"
STATUSES = (QUEUED, RUNNING, DONE, FAILED, CANCELLED)
FINISHED = frozenset({DONE, FAILED, CANCELLED})

_SCHEMA = """
CREATE TABLE IF NOT EXISTS service_experiments (
    id TEXT PRIMARY KEY,
    seq INTEGER NOT NULL,
    name TEXT NOT NULL,
    status TEXT NOT NULL,
    submitted TEXT NOT NULL,
    started TEXT,
    finished TEXT,
    error TEXT,
    file TEXT NOT NULL,
    base TEXT NOT NULL,
    pid INTEGER,
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    restarts INTEGER NOT NULL DEFAULT 0
);
CREATE INDEX IF NOT EXISTS service_experiments_by_status ON service_experiments(status, seq);
CREATE TABLE IF NOT EXISTS service_runs (
    experiment_id TEXT NOT NULL REFERENCES service_experiments(id) ON DELETE CASCADE,
    ord INTEGER NOT NULL,
    key TEXT NOT NULL,
    point TEXT NOT NULL,
    strategy TEXT NOT NULL,
    replicate INTEGER NOT NULL,
    reference_point TEXT NOT NULL,
    spp INTEGER NOT NULL,
    time_s REAL NOT NULL,
    PRIMARY KEY (experiment_id, ord)
);
CREATE INDEX IF NOT EXISTS service_runs_by_key ON service_runs(key);
"""


def now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")


def new_id() -> str:
    """A fresh experiment id: sortable by submission time, unguessable in its tail."""
    return f"{dt.datetime.now(dt.UTC).strftime('%Y%m%d-%H%M%S')}-{secrets.token_hex(4)}"


@dataclass(frozen=True)
class PlannedRunRow:
    key: str
    point: str
    strategy: str
    replicate: int
    reference_point: str
    spp: int
    time_s: float


class Queue:
    """The queue's tables over one SQLite file; one connection per thread
    (the API answers from a thread pool), each opened without touching the
    schema, which `create` makes once at start."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._local = threading.local()

    def create(self) -> None:
        conn = index.connect(self.path)  # the index's own tables and pragmas first
        try:
            conn.executescript(_SCHEMA)
        finally:
            conn.close()

    def conn(self) -> sqlite3.Connection:
        conn: sqlite3.Connection | None = getattr(self._local, "conn", None)
        if conn is None:
            conn = sqlite3.connect(str(self.path), timeout=index.BUSY_TIMEOUT_S, isolation_level=None)
            conn.row_factory = sqlite3.Row
            conn.execute(f"PRAGMA busy_timeout = {int(index.BUSY_TIMEOUT_S * 1000)}")
            conn.execute("PRAGMA foreign_keys = ON")
            self._local.conn = conn
        return conn

    @contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        conn = self.conn()
        conn.execute("BEGIN IMMEDIATE")
        try:
            yield conn
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        conn.execute("COMMIT")

    def add(self, experiment_id: str, name: str, file: Path, base: Path, runs: list[PlannedRunRow]) -> None:
        with self._write() as c:
            seq = c.execute("SELECT COALESCE(MAX(seq), 0) + 1 FROM service_experiments").fetchone()[0]
            c.execute(
                "INSERT INTO service_experiments (id, seq, name, status, submitted, file, base) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (experiment_id, seq, name, QUEUED, now(), str(file), str(base)),
            )
            c.executemany(
                "INSERT INTO service_runs VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [
                    (experiment_id, i, r.key, r.point, r.strategy, r.replicate, r.reference_point, r.spp, r.time_s)
                    for i, r in enumerate(runs)
                ],
            )

    def get(self, experiment_id: str) -> dict[str, Any] | None:
        row = self.conn().execute("SELECT * FROM service_experiments WHERE id = ?", (experiment_id,)).fetchone()
        return dict(row) if row is not None else None

    def all(self) -> list[dict[str, Any]]:
        return [dict(r) for r in self.conn().execute("SELECT * FROM service_experiments ORDER BY seq DESC")]

    def runs(self, experiment_id: str) -> list[dict[str, Any]]:
        return [
            dict(r)
            for r in self.conn().execute(
                "SELECT * FROM service_runs WHERE experiment_id = ? ORDER BY ord", (experiment_id,)
            )
        ]

    def active_with_name(self, name: str) -> str | None:
        row = (
            self.conn()
            .execute("SELECT id FROM service_experiments WHERE name = ? AND status IN (?, ?)", (name, QUEUED, RUNNING))
            .fetchone()
        )
        return None if row is None else str(row[0])

    def next_queued(self) -> dict[str, Any] | None:
        row = (
            self.conn()
            .execute(
                "SELECT * FROM service_experiments WHERE status = ? AND cancel_requested = 0 ORDER BY seq LIMIT 1",
                (QUEUED,),
            )
            .fetchone()
        )
        return dict(row) if row is not None else None

    def with_status(self, status: str) -> list[dict[str, Any]]:
        return [
            dict(r)
            for r in self.conn().execute("SELECT * FROM service_experiments WHERE status = ? ORDER BY seq", (status,))
        ]

    def set_pid(self, experiment_id: str, pid: int) -> None:
        with self._write() as c:
            c.execute("UPDATE service_experiments SET pid = ? WHERE id = ?", (pid, experiment_id))

    def mark_running(self, experiment_id: str, pid: int | None) -> None:
        with self._write() as c:
            c.execute(
                "UPDATE service_experiments SET status = ?, pid = ?, started = COALESCE(started, ?), error = NULL "
                "WHERE id = ?",
                (RUNNING, pid, now(), experiment_id),
            )

    def requeue(self, experiment_id: str) -> None:
        """A running experiment whose service died: queued again, to resume."""
        with self._write() as c:
            c.execute(
                "UPDATE service_experiments SET status = ?, pid = NULL, restarts = restarts + 1 WHERE id = ?",
                (QUEUED, experiment_id),
            )

    def finish(self, experiment_id: str, status: str, error: str | None = None, only_if: str | None = None) -> bool:
        """Sets a final status (only if the current one is `only_if`, when given); True if it changed."""
        assert status in FINISHED
        with self._write() as c:
            sql = "UPDATE service_experiments SET status = ?, finished = ?, error = ?, pid = NULL WHERE id = ?"
            args: list[Any] = [status, now(), error, experiment_id]
            if only_if is not None:
                sql += " AND status = ?"
                args.append(only_if)
            return c.execute(sql, args).rowcount > 0

    def request_cancel(self, experiment_id: str) -> None:
        with self._write() as c:
            c.execute("UPDATE service_experiments SET cancel_requested = 1 WHERE id = ?", (experiment_id,))

    def delete(self, experiment_id: str) -> None:
        with self._write() as c:
            c.execute("DELETE FROM service_runs WHERE experiment_id = ?", (experiment_id,))
            c.execute("DELETE FROM service_experiments WHERE id = ?", (experiment_id,))

    def membership(self, name: str) -> list[dict[str, Any]]:
        """The index's record of the experiment's renders other than its runs
        (references, their parts, pilots, region maps), once a sweep has planned them."""
        return [
            dict(r)
            for r in self.conn().execute(
                "SELECT * FROM experiment_runs WHERE experiment = ? AND role != ? ORDER BY point, role, replicate",
                (name, index.ROLE_RUN),
            )
        ]

    def reference_of(self, key: str) -> str | None:
        """The reference key a run was measured against (the index's membership)."""
        row = (
            self.conn()
            .execute(
                "SELECT reference_key FROM experiment_runs WHERE key = ? AND reference_key IS NOT NULL LIMIT 1", (key,)
            )
            .fetchone()
        )
        return None if row is None else str(row[0])
