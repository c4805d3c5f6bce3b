"""The `portal-harness` command: argument parsing and exit statuses only.

Exit statuses: 0 success; 1 a run failed (or regress found a rise);
2 bad configuration or usage, found before any render; 130 interrupted.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from portal_harness import __version__
from portal_harness.analysis.run_metrics import measure_runs, reindex
from portal_harness.analysis.sweep import sweep
from portal_harness.core.errors import ConfigError, HarnessError
from portal_harness.core.metrics import Region
from portal_harness.core.paths import ResultsLayout, default_renderer, default_results, find_repo_root
from portal_harness.core.regions import DEFAULT_LIT_THRESHOLD
from portal_harness.execution import index, store
from portal_harness.execution.batch import SweepOptions
from portal_harness.execution.renderer import renderer_version
from portal_harness.execution.single import run_and_index
from portal_harness.experiment.limits import Limits
from portal_harness.experiment.loader import load_experiment
from portal_harness.experiment.model import Experiment
from portal_harness.experiment.scene import spec_from_scene
from portal_harness.experiment.spec import NO_SNAPSHOTS

REFERENCE_SPP = 1024
# serve --nice: the renders of a service's sweeps yield the CPU to its API (issue 42: p50 336 -> 52 ms under load).
DEFAULT_SWEEP_NICE = 10


def _common() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(add_help=False)
    p.add_argument(
        "--results", type=Path, default=None, help="results folder (default: $PORTAL_RESULTS or <repo>/results)"
    )
    p.add_argument(
        "--renderer",
        type=Path,
        default=None,
        help="renderer binary (default: $PORTAL_RENDERER or <repo>/renderer/build/render)",
    )
    return p


def _render_options(p: argparse.ArgumentParser, default_strategy: str | None) -> None:
    p.add_argument("config", type=Path, help="scene file (configs/scenes/*.yaml)")
    p.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scalar of the scene, e.g. params.s_L=0.075 (repeatable)",
    )
    # Names are the renderer's (render --describe): it checks them.
    p.add_argument("--strategy", default=default_strategy, help="sampling strategy (render --describe lists them)")
    p.add_argument("--integrator", help="direct or path (render --describe lists them)")
    p.add_argument("--spp", type=int, help="samples per pixel (0: no limit)")
    p.add_argument("--time", type=float, help="render time limit in seconds (0: no limit)")
    p.add_argument("--seed", type=int)
    p.add_argument("--threads", help="renderer threads, N or auto")
    p.add_argument("--force", action="store_true", help="render even if a finished run exists")


def _execution_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--jobs", type=int, default=None, help="concurrent renders (default and maximum: cores // renderer threads)"
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run renders on a Dask distributed cluster (e.g. tcp://host:8786) instead of locally",
    )
    p.add_argument("--skip-failed", action="store_true", help="do not retry runs recorded as failed")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _limit_options(p: argparse.ArgumentParser) -> None:
    """The bounds on one experiment's work (experiment/limits.py), each with its default."""
    d = Limits()
    g = p.add_argument_group("limits on one experiment's work (checked before anything runs)")
    g.add_argument("--max-points", type=int, default=d.max_points, help=f"points of the sweep (default {d.max_points})")
    g.add_argument("--max-runs", type=int, default=d.max_runs, help=f"runs (default {d.max_runs})")
    g.add_argument(
        "--max-total-time",
        type=float,
        default=d.max_total_time_s,
        metavar="SECONDS",
        help=f"budgeted render time of runs and references (default {d.max_total_time_s:g})",
    )
    g.add_argument(
        "--max-snapshots", type=int, default=d.max_snapshots, help=f"snapshots per run (default {d.max_snapshots})"
    )
    g.add_argument(
        "--max-bytes", type=int, default=d.max_bytes, help=f"bytes of images written (default {d.max_bytes})"
    )
    g.add_argument("--max-pixels", type=int, default=d.max_pixels, help=f"pixels of the film (default {d.max_pixels})")


def _limits(args: argparse.Namespace) -> Limits | None:
    if getattr(args, "no_limits", False):
        return None
    return Limits(
        max_points=args.max_points,
        max_runs=args.max_runs,
        max_total_time_s=args.max_total_time,
        max_snapshots=args.max_snapshots,
        max_bytes=args.max_bytes,
        max_pixels=args.max_pixels,
    )


def build_parser() -> argparse.ArgumentParser:
    common = _common()
    parser = argparse.ArgumentParser(
        prog="portal-harness", description="Experiment harness of portal-lights (see harness/README.md)."
    )
    parser.add_argument("--version", action="version", version=f"portal-harness {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser(
        "run",
        parents=[common],
        help="one render with a live progress bar",
        description="One render of a scene into results/runs/<key>/, following the renderer's "
        "snapshot stream with a live progress bar. Unset options come from the "
        "scene's render section. A finished run with the same key is not redone.",
    )
    _render_options(p, None)
    p.add_argument("--snapshot-every", type=float, help="snapshot period in seconds")

    p = sub.add_parser(
        "reference",
        parents=[common],
        help="a cached high-sample reference render",
        description="A high-sample reference render of a scene with an unbiased strategy "
        "(light sampling by default), cached in results/references/ by the hash of "
        "the scene, so a second call is free.",
    )
    _render_options(p, "light")

    p = sub.add_parser(
        "sweep",
        parents=[common],
        help="run an experiment's whole sweep",
        description="Expand the experiment's cross product, make each point's reference, run "
        "every point and strategy, compute metrics and write a summary. Resumes: "
        "finished runs are not redone. Exit 1 if any run failed.",
    )
    p.add_argument("experiment", type=Path, help="experiment file (configs/experiments/*.yaml)")
    _execution_options(p)
    _limit_options(p)
    p.add_argument("--no-limits", action="store_true", help="lift the limits on the work of the sweep")

    p = sub.add_parser(
        "metrics",
        parents=[common],
        help="MSE and relMSE of runs against a reference",
        description="MSE and relMSE (per channel, averaged) of every snapshot of each run "
        "against its reference, for the whole image and named insets; written to "
        "the run folder as metrics.csv/metrics.json, indexed, and printed as CSV.",
    )
    p.add_argument("runs", nargs="+", help="run folders or run keys")
    p.add_argument(
        "--reference",
        help="reference run folder or key (default: the run's experiment "
        "reference, else the finished reference of the same scene hash)",
    )
    p.add_argument("--experiment", type=Path, help="take the insets from this experiment file")
    p.add_argument(
        "--inset", action="append", default=[], metavar="NAME=X,Y,W,H", help="an inset rectangle in pixels (repeatable)"
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of CSV")

    p = sub.add_parser(
        "figures",
        parents=[common],
        help="the experiment's three figures and summary.tex",
        description="Error-over-time curves, the inset comparison and the efficiency plot of an "
        "experiment that has been swept, as PNG and PDF in results/figures/, and the booktabs "
        "tables of its summary in results/experiments/NAME/summary.tex. Reads stored runs only.",
    )
    p.add_argument("experiment", type=Path)

    p = sub.add_parser(
        "regress",
        parents=[common],
        help="variance regression test against a baseline",
        description="Fixed-seed, fixed-sample renders of every point and strategy; their "
        "relative variance is compared with the stored baseline; exit 1 with a table "
        "if a strategy's variance rose beyond noise. --update rewrites the baseline.",
    )
    p.add_argument("experiment", type=Path)
    p.add_argument("--update", action="store_true", help="rewrite the baseline from this run")
    _execution_options(p)

    p = sub.add_parser(
        "query",
        parents=[common],
        help="error curves from the index",
        description="Print (key, time_s, value) of every indexed run of a strategy whose "
        "parameters match, e.g. --strategy portal --param ratio=0.25.",
    )
    p.add_argument("--strategy", required=True)
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="e.g. ratio=0.25 or params.s_L=0.075 (repeatable)",
    )
    p.add_argument("--region", default="image")
    p.add_argument("--metric", default="rel_mse", choices=index.METRIC_COLUMNS)

    p = sub.add_parser(
        "import-mitsuba",
        help="convert a Mitsuba 3 (or 2) XML scene into the renderer's YAML",
        description="Convert a Mitsuba XML scene into DIR/scene.yaml with its meshes in DIR/meshes/. "
        "What has no equivalent gets one warning naming its XML line; errors (missing mesh files, "
        "bad XML) exit 2 with file:line and write nothing. See harness/README.md.",
    )
    p.add_argument("scene", type=Path, help="the Mitsuba scene (.xml)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder (new or empty)")
    p.add_argument(
        "--define",
        "-D",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set a $NAME parameter, over its <default> (repeatable), as mitsuba -D does",
    )
    p.add_argument("--skip-missing", action="store_true", help="skip shapes whose mesh file is missing (a warning)")
    p.add_argument(
        "--smooth-alpha",
        type=float,
        default=None,
        help="GGX roughness of smooth conductors (default: 0.001, the renderer's smallest)",
    )
    p.add_argument("--force", action="store_true", help="replace DIR if it is not empty")
    p.add_argument(
        "--no-auto-portals",
        dest="auto_portals",
        action="store_false",
        help="write no `portals: auto` (by default the renderer finds every imported light's portals)",
    )

    p = sub.add_parser(
        "serve",
        parents=[common],
        help="the experiment service: HTTP API, queue and web page",
        description="A long-running HTTP service over the results store: submit experiments (their YAML), "
        "follow their sweeps live, fetch images, summaries and figures; a web page at / and the API's "
        "documentation at /docs. Writes need a bearer token (--token-file or $PORTAL_HARNESS_TOKEN; without "
        "either, on loopback, one is made in RESULTS/service/token). See docs/service.md.",
    )
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8750)
    p.add_argument(
        "--root",
        dest="roots",
        action="append",
        type=Path,
        default=[],
        metavar="DIR",
        help="a folder submitted experiments may name files in (repeatable; default: <repo>/configs)",
    )
    p.add_argument("--token-file", type=Path, help="file whose first line is the bearer token")
    p.add_argument(
        "--scheduler", metavar="ADDRESS", help="run renders on this Dask scheduler instead of the local pool"
    )
    p.add_argument("--jobs", type=int, default=None, help="concurrent renders of a sweep (default: cores // threads)")
    p.add_argument("--parallel", type=int, default=1, help="sweeps run at once (default 1)")
    p.add_argument("--max-body", type=int, default=256 * 1024, metavar="BYTES", help="request body limit")
    p.add_argument("--no-figures", action="store_true", help="no figures (nor viewer bundle) after each sweep")
    p.add_argument(
        "--nice",
        type=int,
        default=DEFAULT_SWEEP_NICE,
        help=f"niceness added to the sweeps' processes: keeps the API responsive (default {DEFAULT_SWEEP_NICE})",
    )
    _limit_options(p)

    p = sub.add_parser(
        "report",
        parents=[common],
        help="the comparison viewer of an experiment as a static folder",
        description="The experiment's comparison viewer (images of every strategy against the reference, "
        "zoom to pixels, exposure, relative-error maps, insets, relMSE per region, interactive charts) as a "
        "self-contained folder that opens from disk: DIR/viewer.html. Reads stored runs only. A non-empty "
        "DIR is replaced only if it is an earlier report.",
    )
    p.add_argument("experiment", type=Path, help="experiment file (configs/experiments/*.yaml), swept")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder (new, empty or a report)")

    sub.add_parser(
        "reindex",
        parents=[common],
        help="rebuild the index from the run folders",
        description="Re-record every run folder's manifest and metrics in results/index.sqlite.",
    )

    p = sub.add_parser(
        "results-page",
        parents=[common],
        help="regenerate the tables of docs/results.md and the README from the stored summaries",
        description="Rewrites the generated block of the results page (docs/results.md) from "
        "results/experiments/NAME/summary.csv (by default the committed ones of the FULL experiments): "
        "per experiment, the efficiency relative to light in the lit region and the insets, with standard "
        "errors and bounds; and the README's results table (analysis/readme_table.py) from the FULL "
        "summaries. The hand-written text around them is kept. With --check, changes nothing and exits 1 "
        "when either is stale.",
    )
    p.add_argument(
        "experiments", nargs="*", metavar="NAME", help="experiments to list (default: every FULL one, NAME_full)"
    )
    p.add_argument("--page", type=Path, help="the page (default: docs/results.md of the repository)")
    p.add_argument(
        "--readme", type=Path, help="the README whose results table is generated (default: the repository's)"
    )
    p.add_argument("--check", action="store_true", help="exit 1 if a page differs from what would be written")
    return parser


def _layout(args: argparse.Namespace) -> ResultsLayout:
    return ResultsLayout((args.results or default_results()).resolve())


def _renderer(args: argparse.Namespace) -> tuple[str, str]:
    path = str((args.renderer or default_renderer()).resolve())
    return path, renderer_version(path)


def _parse_sets(sets: list[str], flag: str = "--set") -> dict[str, str]:
    out: dict[str, str] = {}
    for item in sets:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError(flag, item, "expected KEY=VALUE")
        out[key.strip()] = value.strip()
    return out


def cmd_run(args: argparse.Namespace, reference: bool = False) -> int:
    overrides = _parse_sets(args.sets)
    snapshots = None
    if not reference and args.snapshot_every is not None:
        snapshots = {"every": str(args.snapshot_every)}
    if reference:
        snapshots = dict(NO_SNAPSHOTS)
    spp, time_s = args.spp, args.time
    if reference:
        # A reference has exactly the limits asked for: 1024 spp unless told otherwise.
        spp = spp if spp is not None else (0 if time_s else REFERENCE_SPP)
        time_s = time_s if time_s is not None else 0.0
    renderer, version = _renderer(args)
    spec = spec_from_scene(
        args.config,
        overrides,
        renderer,
        strategy=args.strategy,
        integrator=args.integrator,
        spp=spp,
        time_s=time_s,
        seed=args.seed,
        threads=args.threads,
        snapshots=snapshots,
        reference=reference,
    )
    key = spec.key(version)
    manifest, run = run_and_index(spec, _layout(args), renderer, version, force=args.force)
    what = "reference" if reference else "run"
    cached = " (cached: nothing rendered)" if manifest.get("cached") else ""
    print(f"{what} {key}: {manifest['status']}{cached}")
    print(f"folder: {run.dir}")
    if manifest.get("final"):
        f = manifest["final"]
        print(f"final: {f['time_s']:.2f} s, {f['spp']} spp, scene hash {manifest['scene_hash']}")
    if manifest["status"] != store.STATUS_DONE:
        print(f"error: {manifest.get('error')}", file=sys.stderr)
        tail = (manifest.get("stderr_tail") or "").strip()
        if tail:
            print(f"renderer stderr (tail):\n{tail}", file=sys.stderr)
        return 3 if manifest["status"] == store.STATUS_INTERRUPTED else 1
    return 0


def _sweep_options(args: argparse.Namespace) -> SweepOptions:
    renderer, version = _renderer(args)
    return SweepOptions(
        layout=_layout(args),
        renderer=renderer,
        renderer_version=version,
        jobs=args.jobs,
        scheduler=args.scheduler,
        retry_failed=not args.skip_failed,
        progress=not args.no_progress,
    )


def _experiment(args: argparse.Namespace, path: Path, limits: Limits | None = None) -> Experiment:
    """The experiment of a file; one the service stored (RESULTS/service/ID/experiment.yaml, or the
    folder, or its ID) with its paths resolved against the root it was submitted to."""
    renderer, _ = _renderer(args)
    from portal_harness.service.stored import stored_experiment

    file, base = stored_experiment(_layout(args), path)
    return load_experiment(file, renderer, relative_to=base, limits=limits)


def cmd_sweep(args: argparse.Namespace) -> int:
    experiment = _experiment(args, args.experiment, _limits(args))
    if experiment.budget is None:
        raise ConfigError(str(args.experiment), "budget", "missing (a sweep needs time_s or spp)")
    return sweep(experiment, _sweep_options(args))


def cmd_regress(args: argparse.Namespace) -> int:
    from portal_harness.analysis.regress import regress

    experiment = _experiment(args, args.experiment)
    if experiment.regress is None:
        raise ConfigError(str(args.experiment), "regress", "missing (the regress command needs spp and seeds)")
    return regress(experiment, _sweep_options(args), update=args.update)


def cmd_figures(args: argparse.Namespace) -> int:
    from portal_harness.figures.make_all import make_all

    experiment = _experiment(args, args.experiment)
    for path in make_all(experiment, _layout(args)):
        print(path)
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from portal_harness.viewer.report import check_target, write_report

    check_target(args.out)  # before loading anything: a refused DIR costs nothing
    experiment = _experiment(args, args.experiment)
    print(write_report(_layout(args), experiment, args.out))
    return 0


def _parse_insets(items: list[str]) -> tuple[Region, ...]:
    out = []
    for item in items:
        name, sep, rect = item.partition("=")
        try:
            x, y, w, h = (int(v) for v in rect.split(","))
        except ValueError:
            raise ConfigError("--inset", item, "expected NAME=X,Y,WIDTH,HEIGHT in pixels") from None
        if not sep or not name:
            raise ConfigError("--inset", item, "expected NAME=X,Y,WIDTH,HEIGHT in pixels")
        out.append(Region(name, x, y, w, h))
    return tuple(out)


def cmd_metrics(args: argparse.Namespace) -> int:
    experiment = _experiment(args, args.experiment) if args.experiment else None
    insets = (experiment.insets if experiment else ()) + _parse_insets(args.inset)
    lit_threshold = experiment.lit_threshold if experiment else DEFAULT_LIT_THRESHOLD
    status, results = measure_runs(_layout(args), args.runs, args.reference, insets, lit_threshold, sys.stderr)
    if args.json:
        json.dump(results, sys.stdout, indent=1)
        print()
    elif results:
        writer = csv.DictWriter(sys.stdout, fieldnames=list(results[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(results)
    return status


def cmd_query(args: argparse.Namespace) -> int:
    params: dict[str, float] = {}
    for name, text in _parse_sets(args.param, "--param").items():
        try:
            params[name] = float(text)
        except ValueError:
            raise ConfigError("--param", name, f"expected a number, got {text!r}") from None
    conn = index.connect(_layout(args).index_path)
    try:
        found = index.curves(conn, args.strategy, params, region=args.region, metric=args.metric)
        known = index.strategies(conn)
    finally:
        conn.close()
    print(f"key,time_s,{args.metric}")
    for key, points in found.items():
        for t, v in points:
            print(f"{key},{t},{v}")
    if args.strategy not in known:
        # Names are the renderer's; the index knows those it has runs of.
        print(
            f"no runs of strategy {args.strategy!r} in the index (it has {', '.join(known) or 'none'})", file=sys.stderr
        )
    return 0 if found else 1


def cmd_results_page(args: argparse.Namespace) -> int:
    from portal_harness.analysis import agreement, readme_table, results_page

    page = args.page or find_repo_root() / "docs" / "results.md"
    readme = args.readme or find_repo_root() / "README.md"
    experiments_dir = _layout(args).root / "experiments"

    def results(text: str) -> str:
        text = results_page.replace_block(
            text, results_page.generated_block(experiments_dir, args.experiments), str(page)
        )
        return agreement.replace(text, agreement.block(experiments_dir), str(page))

    def table(text: str) -> str:
        return readme_table.replace(text, readme_table.table(experiments_dir), str(readme))

    pages: tuple[tuple[Path, Callable[[str], str]], ...] = ((page, results), (readme, table))
    stale = 0
    for path, regenerate in pages:
        try:
            current = path.read_text()
        except OSError as e:
            raise HarnessError(f"{path}: cannot read ({e.strerror})") from None
        expected = regenerate(current)
        if args.check:
            if expected != current:
                print(f"{path}: stale; run `portal-harness results-page`", file=sys.stderr)
                stale = 1
            else:
                print(f"{path}: up to date")
            continue
        if expected != current:
            tmp = path.with_suffix(path.suffix + ".tmp")  # replaced atomically: a failure leaves the old file
            tmp.write_text(expected)
            tmp.replace(path)
        print(f"{path}: {'rewritten' if expected != current else 'unchanged'}")
    return stale


def cmd_reindex(args: argparse.Namespace) -> int:
    count = reindex(_layout(args))
    print(f"indexed {count} run folders")
    return 0


def cmd_import_mitsuba(args: argparse.Namespace) -> int:
    from portal_harness.mitsuba_import import SMOOTH_CONDUCTOR_ALPHA, import_scene

    alpha = SMOOTH_CONDUCTOR_ALPHA if args.smooth_alpha is None else args.smooth_alpha
    if not 0.001 <= alpha <= 1.0:
        raise ConfigError("--smooth-alpha", str(alpha), "expected a GGX roughness in [0.001, 1]")
    path, report = import_scene(
        args.scene,
        args.out,
        _parse_sets(args.define, "--define"),
        args.skip_missing,
        alpha,
        args.force,
        args.auto_portals,
    )
    for line in report.lines():
        print(line, file=sys.stderr)
    print(f"wrote {path} ({len(report.lines())} distinct warnings)")
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
    from portal_harness.core.paths import find_repo_root
    from portal_harness.service.server import serve, settings_from
    from portal_harness.service.store_lock import lock_store

    results = (args.results or default_results()).resolve()
    lock = lock_store(results)  # first: before the token file, the queue's recovery, the workers, the port
    renderer, _ = _renderer(args)
    settings = settings_from(
        results=results,
        renderer=Path(renderer),
        roots=args.roots or [find_repo_root() / "configs"],
        host=args.host,
        port=args.port,
        token_file=args.token_file,
        scheduler=args.scheduler,
        jobs=args.jobs,
        parallel=args.parallel,
        max_body_bytes=args.max_body,
        figures=not args.no_figures,
        nice=args.nice,
        limits=_limits(args) or Limits(),
    )
    try:
        return serve(settings)
    finally:
        os.close(lock)


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    handlers = {
        "run": cmd_run,
        "reference": lambda a: cmd_run(a, reference=True),
        "sweep": cmd_sweep,
        "metrics": cmd_metrics,
        "figures": cmd_figures,
        "report": cmd_report,
        "regress": cmd_regress,
        "query": cmd_query,
        "reindex": cmd_reindex,
        "results-page": cmd_results_page,
        "import-mitsuba": cmd_import_mitsuba,
        "serve": cmd_serve,
    }
    try:
        return int(handlers[args.command](args))
    except HarnessError as e:
        print(f"portal-harness {args.command}: {e}", file=sys.stderr)
        return e.exit_status
    except KeyboardInterrupt:
        print(f"portal-harness {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader of our stdout went away (e.g. `| head`): not an error.
        # Later writes (the flush at exit) go to /dev/null instead, as the
        # Python documentation of SIGPIPE suggests.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return 0
    except OSError as e:
        # A path the system refuses (a name too long, a folder we may not read) that no check named first:
        # one line, never a traceback.
        where = f"{e.filename}: " if e.filename else ""
        print(f"portal-harness {args.command}: {where}{e.strerror or e}", file=sys.stderr)
        return 1
