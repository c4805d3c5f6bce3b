"""Experiments the service stored (RESULTS/service/ID/experiment.yaml), for
the command line (`portal-harness report`, `figures`, `sweep`): their paths
resolve against the --root folder they were submitted to, which the queue
records, not against the stored file's folder."""

from __future__ import annotations

import sqlite3
from pathlib import Path

from portal_harness.core.paths import ResultsLayout
from portal_harness.service.queue import Queue
from portal_harness.service.settings import SPOOL_NAME


def _id_of(layout: ResultsLayout, path: Path) -> str | None:
    """The experiment id `path` names: RESULTS/service/ID[/experiment.yaml], or a bare ID."""
    spool = (layout.root / SPOOL_NAME).resolve()
    try:
        candidate = path.resolve() if path.exists() else None
    except OSError:  # no such path can exist (a name too long): the loader says so
        return None
    if candidate is None:
        return path.name if len(path.parts) == 1 and (spool / path.name).is_dir() else None
    folder = candidate.parent if candidate.is_file() else candidate
    return folder.name if folder.parent == spool else None


def stored_experiment(layout: ResultsLayout, path: Path) -> tuple[Path, Path | None]:
    """(the experiment file, the folder its relative paths resolve against:
    None for the file's own folder). A path that names no stored experiment
    is returned as it is."""
    experiment_id = _id_of(layout, path)
    if experiment_id is None or not layout.index_path.is_file():
        return path, None
    try:
        row = Queue(layout.index_path).get(experiment_id)
    except sqlite3.Error:  # an index without the service's tables
        return path, None
    if row is None:
        return path, None
    here = layout.root / SPOOL_NAME / experiment_id / Path(row["file"]).name  # the results folder may have moved
    return (here if here.is_file() else Path(row["file"])), Path(row["base"])
