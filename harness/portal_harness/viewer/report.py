"""`portal-harness report`: the comparison viewer of one experiment as a
self-contained static folder that opens from disk (file://), for a paper's
supplemental material.

  DIR/viewer.html, viewer.css, js/   the page (static/, copied)
  DIR/index.html                     opens viewer.html
  DIR/data/                          the experiment's bundle (bundle.py)
  DIR/portal-report.json             marks DIR as a report

The folder is built beside DIR under a temporary name and renamed into
place, so DIR is never half-written; a DIR that is not empty is replaced
only if it is an earlier report (it holds the marker).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from datetime import UTC, datetime
from pathlib import Path

from portal_harness import __version__
from portal_harness.core.errors import ConfigError
from portal_harness.core.paths import ResultsLayout
from portal_harness.experiment.model import Experiment
from portal_harness.viewer.bundle import write_bundle

STATIC = Path(__file__).resolve().parent / "static"
PAGE = "viewer.html"
DATA_FOLDER = "data"  # the page's default ?bundle=
MARKER = "portal-report.json"
INDEX_HTML = (
    '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
    f'<meta http-equiv="refresh" content="0; url={PAGE}"><title>report</title></head>'
    f'<body><a href="{PAGE}">{PAGE}</a></body></html>\n'
)


def check_target(out: Path) -> None:
    """Refuses a DIR that is a file, or a folder that is neither empty nor an earlier report."""
    if not out.exists():
        return
    if not out.is_dir():
        raise ConfigError("--out", str(out), "exists and is not a folder")
    if any(out.iterdir()) and not (out / MARKER).is_file():
        raise ConfigError(
            "--out",
            str(out),
            f"not empty and not an earlier report (no {MARKER}): choose another folder or empty this one",
        )


def _install(built: Path, out: Path) -> None:
    """Puts `built` at `out`, replacing an earlier report: one rename each,
    so `out` is always either the old report or the new one (or, for an
    instant, absent), never a mixture."""
    if not out.exists():
        built.rename(out)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
    old.rmdir()
    out.rename(old)
    built.rename(out)
    shutil.rmtree(old, ignore_errors=True)


def write_report(layout: ResultsLayout, experiment: Experiment, out: Path) -> Path:
    """Writes the report of a swept experiment into `out`; returns the page's path."""
    out = Path(os.path.abspath(out))
    check_target(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    built = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    try:
        shutil.copytree(STATIC, built, dirs_exist_ok=True, ignore=shutil.ignore_patterns("__pycache__"))
        write_bundle(layout, experiment, built / DATA_FOLDER)
        (built / "index.html").write_text(INDEX_HTML)
        (built / MARKER).write_text(
            json.dumps(
                {
                    "experiment": experiment.name,
                    "experiment_file": str(experiment.path),
                    "harness_version": __version__,
                    "written": datetime.now(UTC).isoformat(timespec="seconds"),
                },
                indent=2,
            )
            + "\n"
        )
        built.chmod(0o755)  # mkdtemp's 0700 would hide the report from a web server's user
        _install(built, out)
    except BaseException:
        shutil.rmtree(built, ignore_errors=True)
        raise
    return out / PAGE
