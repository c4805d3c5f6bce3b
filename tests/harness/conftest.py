"""Shared, seeded fixtures of the harness tests.

Most tests drive the harness with tests/support/fake_render.py (the renderer
contract in milliseconds); tests marked `real` use renderer/build/render at a
tiny resolution and are skipped until it exists.
"""

from __future__ import annotations

import os
import stat
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
# The real renderer: $PORTAL_RENDERER if set (as for the harness), else the build's.
REAL_RENDERER = Path(os.environ.get("PORTAL_RENDERER") or REPO / "renderer" / "build" / "render")
# The test helpers (exrwrite.py, fake_render.py, browser.py, viewer_sweep.py).
SUPPORT = REPO / "tests" / "support"
sys.path.insert(0, str(SUPPORT))

from exrwrite import write_snapshot  # noqa: E402

SEED = 20240611


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "real: needs the real renderer (renderer/build/render)")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(SEED)


@pytest.fixture
def write_exr() -> Callable[..., None]:
    return write_snapshot


def _real_renderer_built() -> bool:
    return REAL_RENDERER.is_file() and os.access(REAL_RENDERER, os.X_OK)


@pytest.fixture(scope="session")
def fake_renderer(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An executable that runs fake_render.py with this interpreter; it
    forwards --describe and --print-config to the real renderer, so the
    contract under test is the real one."""
    if not _real_renderer_built():
        pytest.skip("renderer/build/render not built yet (the fake renderer asks it for the contract)")
    folder = tmp_path_factory.mktemp("fake-renderer")
    path = folder / "render"
    path.write_text(
        f'#!/bin/sh\nFAKE_RENDER_REAL="{REAL_RENDERER}" exec "{sys.executable}" "{SUPPORT / "fake_render.py"}" "$@"\n'
    )
    path.chmod(path.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    return path


@pytest.fixture
def render_log(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Callable[[], list[str]]:
    """Makes the fake renderer log each render; returns a reader of the log."""
    log = tmp_path / "renders.log"
    monkeypatch.setenv("FAKE_RENDER_LOG", str(log))
    for name in ("FAKE_RENDER_CRASH", "FAKE_RENDER_UNIMPLEMENTED", "FAKE_RENDER_SLEEP"):
        monkeypatch.delenv(name, raising=False)

    def read() -> list[str]:
        return log.read_text().splitlines() if log.exists() else []

    return read


@pytest.fixture
def results(tmp_path: Path) -> Path:
    return tmp_path / "results"


def tiny_experiment(name: str = "tiny", sections: dict[str, Any] | None = None) -> dict[str, Any]:
    """The small default experiment over ../scenes/tiny.yaml (tiny_scene_tree):
    two ratios, light and portal, 0.2 s runs; `sections` replace its
    top-level sections (None removes one)."""
    doc: dict[str, Any] = {
        "name": name,
        "scene": "../scenes/tiny.yaml",
        "integrator": "direct",
        "strategies": ["light", "portal"],
        "sweep": {"params.s_L": [0.15, 0.6]},
        "fixed": {"params.s_P": 0.3},
        "budget": {"time_s": 0.2, "threads": 1, "seed": 1, "snapshots": {"every": 0.05}},
        "reference": {"strategy": "light", "spp": 2000, "seed": 99},
        "insets": [
            {"name": "left", "x": 0, "y": 4, "width": 4, "height": 6},
            {"name": "right", "x": 10, "y": 2, "width": 5, "height": 5},
        ],
        "axis": {"param": "params.s_L", "divide_by": "params.s_P", "label": "light/portal ratio"},
    }
    for key, value in (sections or {}).items():
        if value is None:
            doc.pop(key, None)
        else:
            doc[key] = value
    return doc


def tiny_scene_tree() -> dict[str, Any]:
    """The lampshade at 16x16 with light sampling: the scene of the small sweeps."""
    tree: dict[str, Any] = yaml.safe_load((REPO / "configs" / "scenes" / "lampshade.yaml").read_text())
    tree["film"] = {"width": 16, "height": 16}
    tree["render"] = {
        "integrator": "direct",
        "strategy": "light",
        "spp": 16,
        "seed": 1,
        "threads": 1,
        "snapshots": {"every": 0.5},
        "output": "unused",
    }
    return tree


@pytest.fixture
def fake_scene(tmp_path: Path) -> Path:
    """The lampshade at 16x16, self-contained: a scene the real renderer
    accepts (the fake asks it for the effective config)."""
    tree = tiny_scene_tree()
    path = tmp_path / "scenes" / "tiny.yaml"
    path.parent.mkdir(parents=True)
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    return path


@pytest.fixture
def write_experiment(tmp_path: Path, fake_scene: Path) -> Callable[..., Path]:
    """Writes an experiment file next to the fake scene; keyword arguments
    replace top-level sections of a small default."""

    def write(name: str = "tiny", **sections: Any) -> Path:
        doc = tiny_experiment(name, sections)
        path = tmp_path / "experiments" / f"{name}.yaml"
        path.parent.mkdir(exist_ok=True)
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        return path

    return write


@pytest.fixture(scope="session")
def real_renderer() -> Path:
    if not _real_renderer_built():
        pytest.skip("renderer/build/render not built yet")
    return REAL_RENDERER


@pytest.fixture
def cli(results: Path, fake_renderer: Path, capsys: pytest.CaptureFixture[str]) -> Callable[..., tuple[int, str, str]]:
    """Runs `portal-harness ARGS --results <tmp> --renderer <fake>` in-process;
    returns (status, stdout, stderr)."""
    from portal_harness.cli import main

    def run(*args: str, renderer: Path | None = None) -> tuple[int, str, str]:
        argv = [*args, "--results", str(results), "--renderer", str(renderer or fake_renderer)]
        if args and args[0] in ("query", "reindex", "figures", "metrics"):
            argv = [*args, "--results", str(results)]
        capsys.readouterr()
        status = main(argv)
        out, err = capsys.readouterr()
        return status, out, err

    return run
