"""The SQLite index of runs and metrics (results/index.sqlite).

It answers questions such as "all relMSE curves for strategy X at ratio Y"
without walking run folders. The run folders stay the source of truth: the
index can be rebuilt from their manifests and metrics files (`reindex`).
WAL journal and a busy timeout let two harness processes share one results
folder; every write is one short transaction.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

BUSY_TIMEOUT_S = 60.0
METRIC_COLUMNS = ("mse", "rel_mse")

_SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    key TEXT PRIMARY KEY,
    kind TEXT NOT NULL,
    status TEXT NOT NULL,
    strategy TEXT NOT NULL,
    integrator TEXT NOT NULL,
    scene TEXT NOT NULL,
    scene_hash TEXT NOT NULL,
    renderer_version TEXT NOT NULL,
    spp_target INTEGER, time_target_s REAL, seed INTEGER, threads INTEGER,
    final_time_s REAL, final_spp INTEGER,
    exit_status INTEGER, error TEXT,
    started TEXT, finished TEXT,
    run_dir TEXT NOT NULL,
    params_json TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS run_params (
    key TEXT NOT NULL REFERENCES runs(key) ON DELETE CASCADE,
    name TEXT NOT NULL,
    value_real REAL,
    value_text TEXT,
    PRIMARY KEY (key, name)
);
CREATE INDEX IF NOT EXISTS run_params_by_value ON run_params(name, value_real);
CREATE TABLE IF NOT EXISTS experiment_runs (
    experiment TEXT NOT NULL,
    point TEXT NOT NULL,
    strategy TEXT NOT NULL,
    role TEXT NOT NULL,
    replicate INTEGER NOT NULL,
    key TEXT NOT NULL,
    reference_key TEXT,
    axis_value REAL,
    PRIMARY KEY (experiment, point, strategy, role, replicate)
);
CREATE TABLE IF NOT EXISTS metrics (
    key TEXT NOT NULL,
    reference_key TEXT NOT NULL,
    image TEXT NOT NULL,
    is_final INTEGER NOT NULL,
    time_s REAL,
    spp INTEGER,
    region TEXT NOT NULL,
    mse REAL,
    rel_mse REAL,
    floor_rel REAL,
    error TEXT,
    PRIMARY KEY (key, reference_key, image, region)
);
CREATE INDEX IF NOT EXISTS metrics_by_key ON metrics(key, region);
"""


def connect(path: Path) -> sqlite3.Connection:
    """Opens (and creates) the index in WAL mode with a busy timeout."""
    path.parent.mkdir(parents=True, exist_ok=True)
    conn = sqlite3.connect(str(path), timeout=BUSY_TIMEOUT_S, isolation_level=None)
    conn.row_factory = sqlite3.Row
    conn.execute(f"PRAGMA busy_timeout = {int(BUSY_TIMEOUT_S * 1000)}")
    conn.execute("PRAGMA journal_mode = WAL")
    conn.execute("PRAGMA synchronous = NORMAL")
    conn.execute("PRAGMA foreign_keys = ON")
    with _transaction(conn):
        # Membership without replicates (an older harness's): every sweep
        # records its membership afresh, so the table can simply be rebuilt.
        columns = [r[1] for r in conn.execute("PRAGMA table_info(experiment_runs)")]
        if columns and "replicate" not in columns:
            conn.execute("DROP TABLE experiment_runs")
        for statement in _SCHEMA.split(";"):
            if statement.strip():
                conn.execute(statement)
    return conn


class _transaction:
    """BEGIN IMMEDIATE ... COMMIT: takes the write lock up front so that two
    writers wait for each other (busy timeout) instead of failing on upgrade."""

    def __init__(self, conn: sqlite3.Connection) -> None:
        self.conn = conn

    def __enter__(self) -> sqlite3.Connection:
        self.conn.execute("BEGIN IMMEDIATE")
        return self.conn

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        self.conn.execute("COMMIT" if exc_type is None else "ROLLBACK")


def record_run(conn: sqlite3.Connection, manifest: dict[str, Any], run_dir: Path) -> None:
    """Inserts or replaces a run (and its parameters) from its manifest."""
    spec = manifest["spec"]
    final = manifest.get("final") or {}
    timings = manifest.get("timings") or {}
    params: dict[str, Any] = manifest.get("params") or {}
    with _transaction(conn):
        conn.execute("DELETE FROM run_params WHERE key = ?", (manifest["key"],))
        conn.execute(
            """INSERT OR REPLACE INTO runs VALUES
               (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)""",
            (
                manifest["key"],
                manifest["kind"],
                manifest["status"],
                spec["strategy"],
                spec["integrator"],
                spec["scene"],
                manifest["scene_hash"],
                manifest["renderer"]["version"],
                spec["spp"],
                spec["time_s"],
                spec["seed"],
                spec["threads"],
                final.get("time_s"),
                final.get("spp"),
                manifest.get("exit_status"),
                manifest.get("error"),
                timings.get("started"),
                timings.get("finished"),
                str(run_dir),
                json.dumps(params, sort_keys=True),
            ),
        )
        conn.executemany(
            "INSERT INTO run_params VALUES (?, ?, ?, ?)",
            [
                (
                    manifest["key"],
                    name,
                    float(v) if isinstance(v, (int, float)) else None,
                    None if isinstance(v, (int, float)) else str(v),
                )
                for name, v in params.items()
            ],
        )


# Roles of an experiment's renders in experiment_runs.
ROLE_RUN = "run"  # replicate k of (point, strategy)
ROLE_REFERENCE = "reference"  # the point's (combined) reference
ROLE_REFERENCE_PART = "reference_part"  # one of its independent renders (replicate = part)
ROLE_PILOT = "pilot"  # a pilot render choosing the reference strategy
ROLE_REGION_MAP = "region_map"  # the render whose region AOV gives the point's classes
ROLE_REGION_SECTION = "region_section"  # the same in the view of figures.region_sections

MembershipRow = tuple[str, str, str, int, str, str | None, float]


def forget_run(conn: sqlite3.Connection, key: str) -> None:
    """Removes a run and its metrics (a superseded combined reference)."""
    with _transaction(conn):
        conn.execute("DELETE FROM metrics WHERE key = ? OR reference_key = ?", (key, key))
        conn.execute("DELETE FROM run_params WHERE key = ?", (key,))
        conn.execute("DELETE FROM runs WHERE key = ?", (key,))


def record_membership(conn: sqlite3.Connection, experiment: str, rows: Iterable[MembershipRow]) -> None:
    """The rows (point, strategy, role, replicate, key, reference_key,
    axis_value) of an experiment, replacing all its earlier rows (a sweep
    records its whole plan)."""
    with _transaction(conn):
        conn.execute("DELETE FROM experiment_runs WHERE experiment = ?", (experiment,))
        conn.executemany(
            "INSERT OR REPLACE INTO experiment_runs VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            [(experiment, *row) for row in rows],
        )


@dataclass(frozen=True)
class MetricRow:
    image: str
    is_final: bool
    time_s: float | None
    spp: int | None
    region: str
    mse: float | None
    rel_mse: float | None
    floor_rel: float | None
    error: str | None


def record_metrics(conn: sqlite3.Connection, key: str, reference_key: str, rows: list[MetricRow]) -> None:
    """Replaces the metrics of run `key` against `reference_key`."""
    with _transaction(conn):
        conn.execute("DELETE FROM metrics WHERE key = ? AND reference_key = ?", (key, reference_key))
        conn.executemany(
            "INSERT INTO metrics VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            [
                (
                    key,
                    reference_key,
                    r.image,
                    int(r.is_final),
                    r.time_s,
                    r.spp,
                    r.region,
                    r.mse,
                    r.rel_mse,
                    r.floor_rel,
                    r.error,
                )
                for r in rows
            ],
        )


def membership(conn: sqlite3.Connection, experiment: str) -> list[sqlite3.Row]:
    return conn.execute(
        """SELECT e.*, r.status, r.run_dir, r.final_time_s, r.final_spp, r.error
           FROM experiment_runs e LEFT JOIN runs r ON r.key = e.key
           WHERE e.experiment = ? ORDER BY e.axis_value, e.point, e.role, e.strategy""",
        (experiment,),
    ).fetchall()


def run_row(conn: sqlite3.Connection, key: str) -> sqlite3.Row | None:
    row: sqlite3.Row | None = conn.execute("SELECT * FROM runs WHERE key = ?", (key,)).fetchone()
    return row


def metrics_of(conn: sqlite3.Connection, key: str, reference_key: str | None = None) -> list[sqlite3.Row]:
    if reference_key is None:
        return conn.execute("SELECT * FROM metrics WHERE key = ? ORDER BY time_s", (key,)).fetchall()
    return conn.execute(
        "SELECT * FROM metrics WHERE key = ? AND reference_key = ? ORDER BY time_s", (key, reference_key)
    ).fetchall()


def experiment_reference_key(conn: sqlite3.Connection, key: str) -> str | None:
    """The reference a sweep measured the run `key` against, if any experiment ran it."""
    row = conn.execute(
        "SELECT reference_key FROM experiment_runs WHERE key = ? AND reference_key IS NOT NULL", (key,)
    ).fetchone()
    return None if row is None else str(row["reference_key"])


def find_reference(conn: sqlite3.Connection, scene_hash: str) -> sqlite3.Row | None:
    """The finished reference of a scene with the most samples."""
    row: sqlite3.Row | None = conn.execute(
        """SELECT * FROM runs WHERE kind = 'reference' AND status = 'done' AND scene_hash = ?
           ORDER BY final_spp DESC LIMIT 1""",
        (scene_hash,),
    ).fetchone()
    return row


def strategies(conn: sqlite3.Connection) -> list[str]:
    """The strategies of the indexed runs, sorted."""
    return [row[0] for row in conn.execute("SELECT DISTINCT strategy FROM runs ORDER BY strategy")]


def curves(
    conn: sqlite3.Connection,
    strategy: str,
    params: dict[str, float] | None = None,
    region: str = "image",
    metric: str = "rel_mse",
) -> dict[str, list[tuple[float, float]]]:
    """Every finished run of `strategy` whose parameters match `params`
    (e.g. {"ratio": 0.25} or {"params.s_L": 0.075}, compared with a relative
    tolerance of 1e-9): its (time_s, metric) points in time order, by run key."""
    if metric not in METRIC_COLUMNS:
        raise ValueError(f"unknown metric {metric!r} (expected {'|'.join(METRIC_COLUMNS)})")
    sql = [
        f"SELECT m.key, m.time_s, m.{metric} AS value FROM metrics m JOIN runs r ON r.key = m.key",
        "WHERE r.strategy = ? AND r.status = 'done' AND m.region = ? AND m.error IS NULL",
    ]
    args: list[Any] = [strategy, region]
    for name, value in (params or {}).items():
        sql.append(
            "AND EXISTS (SELECT 1 FROM run_params p WHERE p.key = r.key AND p.name = ?"
            " AND abs(p.value_real - ?) <= 1e-9 * max(1.0, abs(?)))"
        )
        args += [name, float(value), float(value)]
    sql.append("ORDER BY m.key, m.time_s")
    out: dict[str, list[tuple[float, float]]] = {}
    for row in conn.execute(" ".join(sql), args):
        out.setdefault(row["key"], []).append((row["time_s"], row["value"]))
    return out
