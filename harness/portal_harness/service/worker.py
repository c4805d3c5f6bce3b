"""What runs one queued experiment: `python -m portal_harness.service.worker`,
a child of the service in its own process group (the dispatcher cancels
by killing the group), dying with the service (Linux's parent-death
signal), so that a killed service leaves no sweep behind. The sweep is the
CLI's (sweep.sweep), so a sweep started again after a kill resumes: the
store installs finished runs atomically and never counts an attempt.

After the sweep: the figures (figures.make_all) and, when the viewer
module is installed, the comparison viewer's bundle. The worker records
the final status itself (done, or failed with the reason); the dispatcher
records what a worker could not (killed, cancelled).
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import json
import os
import shutil
import signal
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path

from portal_harness.analysis.sweep import sweep
from portal_harness.core.errors import HarnessError
from portal_harness.core.paths import ResultsLayout
from portal_harness.execution.batch import SweepOptions
from portal_harness.execution.renderer import renderer_version
from portal_harness.experiment.loader import load_experiment
from portal_harness.experiment.model import Experiment
from portal_harness.service import queue as q
from portal_harness.service.submission import SubmissionError, check_files

LOG_NAME = "sweep.log"


def _die_with(parent: int) -> None:
    """SIGTERM when the service dies; exits at once if it already has."""
    with contextlib.suppress(OSError):
        ctypes.CDLL("libc.so.6").prctl(1, int(signal.SIGTERM), 0, 0, 0)
    if os.getppid() != parent:
        sys.exit(1)


def bundle_dir(layout: ResultsLayout, name: str) -> Path:
    """Where the comparison viewer's files of an experiment are cached."""
    return layout.experiment_dir(name) / "viewer"


def write_viewer_bundle(layout: ResultsLayout, experiment: Experiment) -> Path:
    """The viewer's bundle (ImportError while the viewer module is not installed)."""
    from portal_harness.viewer.bundle import write_bundle  # type: ignore[import-not-found,unused-ignore]

    # Written beside the served folder and swapped in whole: a page loading the
    # old bundle never gets a mix of old and new image scripts.
    out = bundle_dir(layout, experiment.name)
    fresh = out.with_name(f"{out.name}.new-{os.getpid()}")
    stale = out.with_name(f"{out.name}.old-{os.getpid()}")
    shutil.rmtree(fresh, ignore_errors=True)
    write_bundle(layout, experiment, fresh)
    if out.exists():
        out.rename(stale)
    fresh.rename(out)
    shutil.rmtree(stale, ignore_errors=True)
    return out


def run(
    experiment_id: str,
    results: Path,
    renderer: str,
    scheduler: str | None,
    jobs: int | None,
    figures: bool = True,
    roots: tuple[Path, ...] = (),
) -> int:
    layout = ResultsLayout(results)
    queue = q.Queue(layout.index_path)
    row = queue.get(experiment_id)
    if row is None:
        print(f"no experiment {experiment_id} in the queue", file=sys.stderr)
        return 2
    experiment = load_experiment(Path(row["file"]), renderer, relative_to=Path(row["base"]))
    if roots:
        # Again, as the sweep starts: a file may have become a link out of the roots since it was submitted.
        try:
            check_files(experiment, renderer, roots)
        except SubmissionError as e:
            raise HarnessError(f"{e.file}: {e.key}: {e.message}") from None
    options = SweepOptions(
        layout=layout,
        renderer=renderer,
        renderer_version=renderer_version(renderer),
        jobs=jobs,
        scheduler=scheduler,
        progress=False,
    )
    print(f"renders on {'the Dask scheduler ' + scheduler if scheduler else 'the local pool'}", flush=True)
    status = sweep(experiment, options, out=sys.stdout)
    sys.stdout.flush()
    problems = _figures(layout, experiment) if figures else []
    for p in problems:
        print(p, file=sys.stderr)
    if status == 0:
        queue.finish(experiment_id, q.DONE, "; ".join(problems) or None, only_if=q.RUNNING)
    else:
        queue.finish(experiment_id, q.FAILED, _failure_reason(layout, experiment.name), only_if=q.RUNNING)
    return status


def _figures(layout: ResultsLayout, experiment: Experiment) -> list[str]:
    """The figures and the viewer's bundle; returns the problems (figures of
    a partial sweep may fail: the sweep's status stands)."""
    problems = []
    try:
        from portal_harness.figures.make_all import make_all

        for path in make_all(experiment, layout):
            print(f"figure: {path}")
    except Exception as e:
        problems.append(f"figures: {type(e).__name__}: {e}")
    try:
        print(f"viewer: {write_viewer_bundle(layout, experiment)}")
    except ImportError:
        print("viewer: the viewer module is not installed: no bundle")
    except Exception as e:
        problems.append(f"viewer bundle: {type(e).__name__}: {e}")
    return problems


def _failure_reason(layout: ResultsLayout, name: str) -> str:
    """The sweep's own account: its failures and problems from summary.json, else a pointer to the log."""
    try:
        data = json.loads(layout.summary_json(name).read_text())
    except (OSError, ValueError):
        return f"the sweep failed (see {LOG_NAME})"
    lines = [*data.get("failures", []), *data.get("problems", [])]
    if not lines:
        return f"the sweep stopped (a biased reference? see {LOG_NAME})"
    return f"{len(lines)} failed: " + "; ".join(lines[:5]) + (" ..." if len(lines) > 5 else "")


def be_nicer(steps: int) -> None:
    """Raises this process's niceness and, on Linux with autogroups, its session's: the dispatcher starts
    the worker in a session of its own (so that a cancel kills its whole group), and the scheduler then
    weighs that session's group against the API's group as equals whatever the processes' nice values;
    the group's own nice is what yields the cores to the API (without it, 50 clients' reads stalled
    0.5-0.8 s in bursts behind the renders; tools/service_load, docs/service.md)."""
    os.nice(steps)
    with contextlib.suppress(OSError):  # no autogroups (another kernel, or CONFIG_SCHED_AUTOGROUP off)
        Path("/proc/self/autogroup").write_text(f"{steps}\n")


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m portal_harness.service.worker")
    p.add_argument("--id", required=True)
    p.add_argument("--results", type=Path, required=True)
    p.add_argument("--renderer", required=True)
    p.add_argument("--scheduler")
    p.add_argument("--jobs", type=int)
    p.add_argument("--parent", type=int, required=True)
    p.add_argument("--no-figures", action="store_true", help="no figures, no viewer bundle after the sweep")
    p.add_argument("--nice", type=int, default=0, help="raise this process's niceness (its renders inherit it)")
    p.add_argument("--root", dest="roots", action="append", type=Path, default=[], help="the service's --root folders")
    args = p.parse_args(argv)
    _die_with(args.parent)
    if args.nice:
        be_nicer(args.nice)
    try:
        return run(
            args.id, args.results, args.renderer, args.scheduler, args.jobs, not args.no_figures, tuple(args.roots)
        )
    except HarnessError as e:
        print(f"worker: {e}", file=sys.stderr)
        q.Queue(ResultsLayout(args.results).index_path).finish(args.id, q.FAILED, str(e), only_if=q.RUNNING)
        return e.exit_status
    except Exception as e:
        traceback.print_exc()
        q.Queue(ResultsLayout(args.results).index_path).finish(
            args.id, q.FAILED, f"worker error: {type(e).__name__}: {e}", only_if=q.RUNNING
        )
        return 1


if __name__ == "__main__":
    sys.exit(main())
