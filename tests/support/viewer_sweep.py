"""A tiny swept experiment for the viewer's tests: the lampshade at 16x16,
two ratios x two strategies x two replicates, rendered by the fake renderer
(conftest.fake_renderer) in a few seconds."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml
from conftest import tiny_experiment, tiny_scene_tree

REPO = Path(__file__).resolve().parent.parent.parent


@dataclass(frozen=True)
class Swept:
    experiment: Path
    results: Path
    renderer: Path


def write_experiment(folder: Path, name: str = "tiny", replicates: int = 2) -> Path:
    tree = tiny_scene_tree()
    (folder / "scenes").mkdir(parents=True, exist_ok=True)
    (folder / "scenes" / "tiny.yaml").write_text(yaml.safe_dump(tree, sort_keys=False))
    doc = tiny_experiment(name)
    doc["budget"]["replicates"] = replicates
    (folder / "experiments").mkdir(exist_ok=True)
    path = folder / "experiments" / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def sweep_tiny(folder: Path, renderer: Path, replicates: int = 2, status: int = 0) -> Swept:
    """Writes and sweeps the experiment under `folder`; fails unless the
    sweep exits with `status`."""
    from portal_harness.cli import main

    experiment = write_experiment(folder, replicates=replicates)
    results = folder / "results"
    args = ["--results", str(results), "--renderer", str(renderer)]
    found = main(["sweep", str(experiment), "--no-progress", *args])
    if found != status:
        raise RuntimeError(f"the viewer tests' sweep exited with status {found}, not {status}")
    return Swept(experiment, results, renderer)


_SWEPT: dict[Path, Swept] = {}


def swept_once(tmp_path_factory: pytest.TempPathFactory, renderer: Path) -> Swept:
    """sweep_tiny, once per test session and renderer: the viewer's test
    modules only read it (reports go to their own folders)."""
    if renderer not in _SWEPT:
        _SWEPT[renderer] = sweep_tiny(tmp_path_factory.mktemp("viewer-sweep"), renderer)
    return _SWEPT[renderer]
