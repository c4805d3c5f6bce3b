"""Every path of the harness: the repository, the renderer, the results tree
and the files inside one run folder. No other module builds a path by hand.

results/
  runs/<key>/            one folder per run (RunLayout below)
  runs/.attempts/        renders in progress, and folders being removed (store.py)
  references/<key>/      reference renders, same layout (and references/.attempts/)
  experiments/<name>/    summary.json, summary.csv of the last sweep
  figures/               <experiment>_<figure>.png and .pdf
  baselines/<name>.json  committed variance baselines of `regress`
  index.sqlite           the index of all runs and their metrics
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

RENDERER_ENV = "PORTAL_RENDERER"
RESULTS_ENV = "PORTAL_RESULTS"


def find_repo_root(start: Path | None = None) -> Path:
    """The nearest folder at or above `start` (default: the working folder)
    that holds both configs/ and renderer/; the working folder if none does."""
    here = (start or Path.cwd()).resolve()
    for folder in (here, *here.parents):
        if (folder / "configs").is_dir() and (folder / "renderer").is_dir():
            return folder
    return here


def default_renderer(root: Path | None = None) -> Path:
    """$PORTAL_RENDERER, else <repo>/renderer/build/render."""
    env = os.environ.get(RENDERER_ENV)
    if env:
        return Path(env)
    return (root or find_repo_root()) / "renderer" / "build" / "render"


def default_results(root: Path | None = None) -> Path:
    """$PORTAL_RESULTS, else <repo>/results."""
    env = os.environ.get(RESULTS_ENV)
    if env:
        return Path(env)
    return (root or find_repo_root()) / "results"


@dataclass(frozen=True)
class RunLayout:
    """The files of one run folder. The renderer writes config.yaml, the
    snapshots and final.exr; the harness writes the rest; manifest.json is
    written last and atomically."""

    dir: Path

    @property
    def manifest(self) -> Path:
        return self.dir / "manifest.json"

    @property
    def events(self) -> Path:
        return self.dir / "events.jsonl"

    @property
    def stderr(self) -> Path:
        return self.dir / "stderr.txt"

    @property
    def config(self) -> Path:
        return self.dir / "config.yaml"

    @property
    def final(self) -> Path:
        return self.dir / "final.exr"

    @property
    def metrics_csv(self) -> Path:
        return self.dir / "metrics.csv"

    @property
    def metrics_json(self) -> Path:
        return self.dir / "metrics.json"

    def relative(self, path: Path | str) -> str:
        """`path` relative to the run folder (manifests store only these, so a
        folder can be moved or shipped back from a Dask worker)."""
        p = Path(path)
        try:
            return str(p.resolve().relative_to(self.dir.resolve()))
        except ValueError:
            return p.name

    def resolve(self, relative: str) -> Path:
        return self.dir / relative


@dataclass(frozen=True)
class ResultsLayout:
    """The results tree rooted at `root`."""

    root: Path

    @property
    def runs_dir(self) -> Path:
        return self.root / "runs"

    @property
    def references_dir(self) -> Path:
        return self.root / "references"

    @property
    def figures_dir(self) -> Path:
        return self.root / "figures"

    @property
    def baselines_dir(self) -> Path:
        return self.root / "baselines"

    @property
    def index_path(self) -> Path:
        return self.root / "index.sqlite"

    def run(self, key: str, reference: bool = False) -> RunLayout:
        return RunLayout((self.references_dir if reference else self.runs_dir) / key)

    def attempts_dir(self, reference: bool = False) -> Path:
        """Where attempts of runs (or references) render before installation."""
        return (self.references_dir if reference else self.runs_dir) / ".attempts"

    def experiment_dir(self, name: str) -> Path:
        return self.root / "experiments" / name

    def summary_json(self, name: str) -> Path:
        return self.experiment_dir(name) / "summary.json"

    def summary_csv(self, name: str) -> Path:
        return self.experiment_dir(name) / "summary.csv"

    def figure(self, experiment: str, figure: str, extension: str) -> Path:
        return self.figures_dir / f"{experiment}_{figure}.{extension}"

    def baseline(self, name: str) -> Path:
        return self.baselines_dir / f"{name}.json"
