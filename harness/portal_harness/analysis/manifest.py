"""results/experiments/NAME/manifest.json: what a sweep was made with and
what it cost, next to its summary, small enough to commit (.gitignore keeps
those of the NAME_full experiments): the renderer's version, the git
commit of the checkout, the machine, the sweep's wall time, the replicates
of every (point, strategy) and, with `precision:`, the precision each
headline value reached.

The replicates it records also let a sweep whose run folders were lost (a
new machine) start with as many replicates per cell as the recorded one
ended with (`planned_replicates`), so that it needs one round, not the
adaptive rounds that found those numbers.
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import socket
import subprocess
from pathlib import Path
from typing import Any

from portal_harness.core.paths import ResultsLayout, find_repo_root
from portal_harness.execution import store

FILE = "manifest.json"
SCHEMA = 1


def path_of(layout: ResultsLayout, name: str) -> Path:
    return layout.experiment_dir(name) / FILE


def read(layout: ResultsLayout, name: str) -> dict[str, Any] | None:
    try:
        data = json.loads(path_of(layout, name).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def planned_replicates(layout: ResultsLayout, name: str) -> dict[tuple[str, str], int]:
    """(point, strategy) -> replicates, from the experiment's manifest (empty without one)."""
    data = read(layout, name) or {}
    out: dict[tuple[str, str], int] = {}
    replicates = data.get("replicates")
    if not isinstance(replicates, dict):
        return out
    for point, by in replicates.items():
        if isinstance(by, dict):
            for strategy, n in by.items():
                if isinstance(n, int) and not isinstance(n, bool) and n > 0:
                    out[(str(point), str(strategy))] = n
    return out


def precision_spent_s(layout: ResultsLayout, name: str, target: float, max_time_s: float) -> float:
    """The sweep time earlier sweeps of the experiment spent under the same
    precision target and time cap (their manifest's precision.spent_s): the
    cap holds for all of them together, so a second sweep (make figures'
    second pass, or one after an interruption) does not start it anew."""
    info = (read(layout, name) or {}).get("precision")
    if not isinstance(info, dict) or info.get("target_rel_se") != target or info.get("max_time_s") != max_time_s:
        return 0.0
    spent = info.get("spent_s")
    return float(spent) if isinstance(spent, (int, float)) and not isinstance(spent, bool) else 0.0


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict[str, Any]:
    return {
        "hostname": socket.gethostname(),
        "cores": os.cpu_count(),
        "cpu_model": _cpu_model(),
        "platform": platform.platform(),
    }


def git_commit(root: Path | None = None) -> dict[str, Any] | None:
    """HEAD of the checkout the harness runs from (or of `root`), and whether
    its tracked files outside results/ differ from it; None outside git.
    results/ is left out because a sweep rewrites committed summaries and
    manifests there (and a FULL redo moves them aside first): those are its
    outputs, and "dirty" is to say whether the code that made them is HEAD's."""
    try:
        root = root or find_repo_root(Path(__file__).resolve().parent)
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=30, check=False
        )
        if head.returncode != 0:
            return None
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)results"],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
    except (OSError, subprocess.SubprocessError, RuntimeError):
        return None
    return {"commit": head.stdout.strip(), "dirty": bool(dirty.stdout.strip()) if dirty.returncode == 0 else None}


SWEEPS = "sweeps.json"  # beside the manifest, in the results folder only (.gitignore keeps it out)


def _sweeps_wall(layout: ResultsLayout, name: str, wall_time_s: float, rendered: bool) -> float:
    """Appends this sweep to the folder's sweep log and returns the wall time of its sweeps that rendered."""
    path = layout.experiment_dir(name) / SWEEPS
    try:
        log = json.loads(path.read_text())
        sweeps = [x for x in log if isinstance(x, dict)] if isinstance(log, list) else []
    except (OSError, ValueError):
        sweeps = []
    sweeps.append(
        {
            "written": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "wall_time_s": round(wall_time_s, 1),
            "rendered": rendered,
        }
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    store.write_json_atomic(path, sweeps)
    walls = [x.get("wall_time_s") for x in sweeps if x.get("rendered")]
    return float(sum(w for w in walls if isinstance(w, (int, float)) and not isinstance(w, bool)))


def write(
    layout: ResultsLayout,
    name: str,
    renderer_version: str,
    wall_time_s: float,
    rendered: bool,
    replicates: dict[tuple[str, str], int],
    render_time_s: float,
    precision: dict[str, Any] | None,
) -> Path:
    """Writes the manifest. `rendered`: this sweep rendered something. The
    manifest's wall time is the sum over the sweeps of this results folder
    that rendered (SWEEPS, not committed: a sweep on a fresh clone starts
    from zero, whatever manifest it found): make figures' second pass may
    add the precision's last replicates, and a sweep resumed after a crash
    adds its own time; a sweep that rendered nothing adds none."""
    wall = _sweeps_wall(layout, name, wall_time_s, rendered)
    by: dict[str, dict[str, int]] = {}
    for (point, strategy), n in replicates.items():
        by.setdefault(point, {})[strategy] = n
    data = {
        "schema": SCHEMA,
        "experiment": name,
        "written": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "renderer_version": renderer_version,
        "git": git_commit(),
        "machine": machine(),
        "wall_time_s": round(wall, 1),
        "last_sweep_wall_time_s": round(wall_time_s, 1),
        "render_time_s": round(render_time_s, 1),
        "replicates": by,
        "precision": precision,
    }
    path = path_of(layout, name)
    path.parent.mkdir(parents=True, exist_ok=True)
    store.write_json_atomic(path, data)
    return path
