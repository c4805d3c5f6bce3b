"""What the figures read: an experiment's cells (point, strategy) from the
index, its tidy summary (summary.json), error curves of runs, and the image of a
run at equal render time (images through exr.py)."""

from __future__ import annotations

import json
import math
import sqlite3
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from portal_harness.core.errors import HarnessError
from portal_harness.core.paths import ResultsLayout
from portal_harness.execution import index
from portal_harness.execution.index import ROLE_REFERENCE, ROLE_RUN
from portal_harness.experiment.model import Experiment, Point


@dataclass(frozen=True)
class Cell:
    """One (point, strategy) of an experiment as the index knows it."""

    key: str
    reference_key: str | None
    status: str | None
    run_dir: Path | None


@dataclass(frozen=True)
class ExperimentData:
    points: tuple[Point, ...]
    runs: dict[tuple[str, str], Cell]  # replicate 0 of (point, strategy)
    replicates: dict[tuple[str, str], list[Cell]]  # every replicate
    references: dict[str, Cell]
    summary: list[dict[str, Any]]  # summary.json's tidy rows


def load(experiment: Experiment, conn: sqlite3.Connection, layout: ResultsLayout) -> ExperimentData:
    rows = index.membership(conn, experiment.name)
    runs: dict[tuple[str, str], Cell] = {}
    replicates: dict[tuple[str, str], list[Cell]] = {}
    references: dict[str, Cell] = {}
    for r in rows:
        cell = Cell(r["key"], r["reference_key"], r["status"], Path(r["run_dir"]) if r["run_dir"] else None)
        if r["role"] == ROLE_REFERENCE:
            references[r["point"]] = cell
        elif r["role"] == ROLE_RUN:
            replicates.setdefault((r["point"], r["strategy"]), []).append(cell)
            if r["replicate"] == 0:
                runs[(r["point"], r["strategy"])] = cell
    points = tuple(p for p in experiment.points() if p.id in references)
    if not points:
        raise HarnessError(f"no runs of experiment {experiment.name!r} in the index: run `portal-harness sweep` first")
    try:
        summary = json.loads(layout.summary_json(experiment.name).read_text())["rows"]
    except (OSError, ValueError, KeyError):
        raise HarnessError(f"no summary of experiment {experiment.name!r}: run `portal-harness sweep` first") from None
    return ExperimentData(points, runs, replicates, references, summary)


def cell_done(cell: Cell | None) -> bool:
    return cell is not None and cell.status == "done" and cell.run_dir is not None


def run_curve(conn: sqlite3.Connection, cell: Cell, region: str, metric: str) -> list[tuple[float, float, float]]:
    """(time_s, metric, reference noise) of a run's images in one region, in time order."""
    return sorted(
        (m["time_s"], m[metric], m["floor_rel"] or 0.0)
        for m in index.metrics_of(conn, cell.key, cell.reference_key)
        if m["region"] == region and m["error"] is None and m["time_s"] and m[metric]
    )


def mean_curve(
    curves: list[list[tuple[float, float, float]]],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Replicates aligned by image index (the same snapshot schedule): mean
    time, mean value, smallest and largest value."""
    n = min(len(c) for c in curves)
    t = np.array([[c[i][0] for i in range(n)] for c in curves])
    v = np.array([[c[i][1] for i in range(n)] for c in curves])
    return t.mean(axis=0), v.mean(axis=0), v.min(axis=0), v.max(axis=0)


@dataclass(frozen=True)
class Chosen:
    image: Path
    time_s: float
    rel_mse: dict[str, float | None]


# Images compared "at equal time" may differ in time by this fraction. A run
# stops after the pass that crosses its budget, so runs with one budget end
# a pass apart (milliseconds, in either order), while consecutive snapshots
# of a schedule are at least a quarter of their time apart. Without the
# tolerance, every run that overshot the shortest run's final time by a
# millisecond was shown at its previous snapshot (1.5 s beside 2.0 s).
EQUAL_TIME_TOLERANCE = 0.02


def pick_time(times: list[float], time_s: float, tolerance: float = EQUAL_TIME_TOLERANCE) -> float | None:
    """Of a run's image times, the last one within `time_s` up to the
    tolerance (the earliest if none is); None without images."""
    if not times:
        return None
    ordered = sorted(times)
    within = [t for t in ordered if t <= time_s * (1 + tolerance)]
    return within[-1] if within else ordered[0]


def times_agree(times: list[float], tolerance: float = EQUAL_TIME_TOLERANCE) -> bool:
    """True when images at these times count as rendered at equal time."""
    return not times or max(times) <= min(times) * (1 + tolerance)


def choose_image(conn: sqlite3.Connection, cell: Cell, time_s: float) -> Chosen | None:
    """The run's image at `time_s`: its last image rendered within `time_s`
    up to EQUAL_TIME_TOLERANCE (the earliest if none is)."""
    assert cell.run_dir is not None
    rows = [m for m in index.metrics_of(conn, cell.key, cell.reference_key) if m["error"] is None]
    chosen_t = pick_time([m["time_s"] for m in rows], time_s)
    if chosen_t is None:
        return None
    at = [m for m in rows if m["time_s"] == chosen_t]
    image = next((m["image"] for m in at if m["is_final"]), at[0]["image"])
    return Chosen(cell.run_dir / image, chosen_t, {m["region"]: m["rel_mse"] for m in at if m["image"] == image})


def common_time(times: list[list[float]], upper: float, tolerance: float = EQUAL_TIME_TOLERANCE) -> float:
    """The time to compare runs at (their image times given): the latest
    time up to `upper` (the shortest final) at which the images pick_time
    takes agree within the tolerance; a run whose last pass overshot the
    budget by more than the tolerance is then compared at the snapshot all
    runs share, not at its previous snapshot beside the others' finals.
    When no time agrees (path tracing's passes can be longer than the
    tolerance, so no two runs have images that close), the time whose
    images are the closest in time (the figure prints each image's time and
    says that they differ)."""
    best, best_spread = upper, math.inf
    for t in [upper, *sorted({t for ts in times for t in ts}, reverse=True)]:
        picked = [pick_time(ts, t, tolerance) for ts in times]
        chosen = [p for p in picked if p is not None]
        if len(chosen) < len(picked) or not chosen or min(chosen) <= 0:
            continue
        if t <= upper * (1 + tolerance) and times_agree(chosen, tolerance):
            return t
        spread = max(chosen) / min(chosen)
        if spread < best_spread:
            best, best_spread = t, spread
    return best


def equal_time(experiment: Experiment, conn: sqlite3.Connection, data: ExperimentData, point: Point) -> float:
    """The configured comparison time, else the latest time up to the shortest
    final time of the point's runs at which each run has an image (common_time)."""
    if experiment.equal_time_s is not None:
        return experiment.equal_time_s
    finals: list[float] = []
    times: list[list[float]] = []
    for strategy in experiment.strategies:
        cell = data.runs.get((point.id, strategy))
        if cell_done(cell):
            assert cell is not None
            row = index.run_row(conn, cell.key)
            if row is not None and row["final_time_s"]:
                finals.append(float(row["final_time_s"]))
                metrics = index.metrics_of(conn, cell.key, cell.reference_key)
                times.append(sorted({float(m["time_s"]) for m in metrics if m["error"] is None}))
    return common_time(times, min(finals)) if finals else math.inf


def reference_groups(data: ExperimentData) -> list[list[Point]]:
    """Consecutive points measured against the same reference image (facets
    that only change how the image is sampled share one): the insets figure
    draws each such reference once."""
    groups: list[list[Point]] = []
    last: str | None = None
    for p in data.points:
        cell = data.references.get(p.id)
        key = cell.key if cell is not None else None
        if groups and key is not None and key == last:
            groups[-1].append(p)
        else:
            groups.append([p])
        last = key
    return groups
