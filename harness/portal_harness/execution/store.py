"""The run store: run folders under results/runs/ and results/references/,
their manifests, and the atomic installation of a finished attempt.

A run renders into a private attempt folder (<runs>/.attempts/<key>-<pid>-<n>);
its manifest is written there, then the whole folder is renamed to
<runs>/<key>. A run folder therefore always holds a complete attempt, and a
run counts as finished only if its manifest exists and says "done". An
attempt interrupted at any point leaves only an attempt folder, which later
sweeps remove.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import shutil
import time
from pathlib import Path
from typing import Any

from portal_harness.core.paths import ResultsLayout, RunLayout

STATUS_DONE = "done"
STATUS_FAILED = "failed"
STATUS_INTERRUPTED = "interrupted"
MANIFEST_SCHEMA = 1
_counter = itertools.count()


def finite_or_none(value: Any) -> Any:
    """A value for strict JSON (and empty CSV cells): NaN and infinities become None."""
    return None if isinstance(value, float) and not math.isfinite(value) else value


def write_json_atomic(path: Path, data: Any) -> None:
    """Writes JSON to a temporary name, fsyncs and renames it into place."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "w") as f:
        json.dump(data, f, indent=2, sort_keys=True, default=str)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def read_manifest(run: RunLayout) -> dict[str, Any] | None:
    """The manifest of a run folder, or None if absent or unreadable."""
    try:
        with open(run.manifest) as f:
            data = json.load(f)
    except (OSError, json.JSONDecodeError):
        return None
    return data if isinstance(data, dict) else None


def is_done(run: RunLayout) -> bool:
    m = read_manifest(run)
    return m is not None and m.get("status") == STATUS_DONE


def new_attempt(layout: ResultsLayout, key: str, reference: bool) -> RunLayout:
    parent = layout.attempts_dir(reference)
    parent.mkdir(parents=True, exist_ok=True)
    folder = parent / f"{key}-{os.getpid()}-{next(_counter)}-{time.time_ns() % 10**9}"
    folder.mkdir()
    return RunLayout(folder)


def install(layout: ResultsLayout, key: str, reference: bool, attempt: RunLayout) -> RunLayout:
    """Moves a complete attempt (manifest included) to its run folder,
    replacing an older attempt (e.g. a failed one)."""
    target = layout.run(key, reference)
    target.dir.parent.mkdir(parents=True, exist_ok=True)
    if target.dir.exists():
        trash = layout.attempts_dir(reference) / f"trash-{key}-{os.getpid()}-{next(_counter)}"
        os.replace(target.dir, trash)
        os.replace(attempt.dir, target.dir)
        shutil.rmtree(trash, ignore_errors=True)
    else:
        os.replace(attempt.dir, target.dir)
    return target


def remove_run(layout: ResultsLayout, key: str, reference: bool) -> None:
    """Removes a run folder: renamed away first, so it vanishes at once."""
    target = layout.run(key, reference)
    if not target.dir.exists():
        return
    trash = layout.attempts_dir(reference) / f"trash-{key}-{os.getpid()}-{next(_counter)}"
    trash.parent.mkdir(parents=True, exist_ok=True)
    os.replace(target.dir, trash)
    shutil.rmtree(trash, ignore_errors=True)


def install_files(layout: ResultsLayout, key: str, reference: bool, files: dict[str, bytes]) -> RunLayout:
    """Installs a run folder shipped back as bytes (the Dask path): every file
    is written to a fresh attempt, the manifest last, then installed."""
    attempt = new_attempt(layout, key, reference)
    manifest_name = attempt.manifest.name
    for name, data in sorted(files.items()):
        if name == manifest_name:
            continue
        dest = attempt.dir / name
        if dest.resolve().parent != attempt.dir.resolve():
            raise ValueError(f"refusing to write {name!r} outside the run folder")
        dest.write_bytes(data)
    if manifest_name in files:
        tmp = attempt.manifest.with_name(f".{manifest_name}.tmp")
        tmp.write_bytes(files[manifest_name])
        os.replace(tmp, attempt.manifest)
    return install(layout, key, reference, attempt)


def pack_files(run: RunLayout) -> dict[str, bytes]:
    """The files of a run folder by name (not recursive)."""
    return {p.name: p.read_bytes() for p in sorted(run.dir.iterdir()) if p.is_file() and not p.name.startswith(".")}


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean_stale_attempts(layout: ResultsLayout) -> int:
    """Removes attempt folders whose harness process is gone; returns how many."""
    removed = 0
    for reference in (False, True):
        parent = layout.attempts_dir(reference)
        if not parent.is_dir():
            continue
        for folder in parent.iterdir():
            parts = folder.name.split("-")
            try:
                pid = int(parts[-3]) if not folder.name.startswith("trash-") else int(parts[-2])
            except (ValueError, IndexError):
                continue
            if pid != os.getpid() and not _pid_alive(pid):
                shutil.rmtree(folder, ignore_errors=True)
                removed += 1
    return removed
