"""Experiment configs: a good one expands as documented; every bad one fails
before any render with the file and the key in the message."""

from __future__ import annotations

import re
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from portal_harness.core.errors import ConfigError
from portal_harness.experiment.loader import load_experiment
from portal_harness.experiment.scene import spec_from_scene

REPO = Path(__file__).resolve().parents[3]


def test_01_expands_the_cross_product(write_experiment: Callable[..., Path], real_renderer: Path) -> None:
    path = write_experiment(
        sweep={"params.s_L": [0.15, 0.6], "params.s_P": [0.3, 0.6]},
        fixed={"film.width": 16},
        axis={"param": "params.s_L", "divide_by": "params.s_P"},
    )
    exp = load_experiment(path, str(real_renderer))
    points = exp.points()
    assert [p.id for p in points] == ["s_L=0.15,s_P=0.3", "s_L=0.15,s_P=0.6", "s_L=0.6,s_P=0.3", "s_L=0.6,s_P=0.6"]
    assert [p.axis_value for p in points] == pytest.approx([0.5, 0.25, 2.0, 1.0])
    spec = exp.run_spec(points[0], "portal")
    assert dict(spec.overrides) == {"film.width": "16", "params.s_L": "0.15", "params.s_P": "0.3"}
    assert spec.time_s == 0.2 and spec.strategy == "portal" and spec.threads == 1
    ref = exp.reference_spec(points[0], "light")
    assert ref.reference and ref.strategy == "light" and ref.spp == 2000
    # every reference render keeps its film state (to be extended); the region map render has the AOV
    assert ("render.resumable", "true") in ref.overrides and ("render.aov.region", "true") not in ref.overrides
    region_map = exp.region_map_spec(points[0])
    assert ("render.aov.region", "true") in region_map.overrides and region_map.spp > 0
    # the second, independent part of a reference has its own seed
    assert exp.reference_spec(points[0], "portal", part=1).seed != ref.seed
    # replicates: every (strategy, replicate) its own seed
    seeds = {exp.run_spec(points[0], s, replicate=k).seed for s in ("light", "portal") for k in range(3)}
    assert len(seeds) == 6


def test_02_shipped_experiments_load(real_renderer: Path) -> None:
    for name in ("lampshade_ratio", "lampshade_ratio_full", "lampshade_regress"):
        exp = load_experiment(REPO / "configs" / "experiments" / f"{name}.yaml", str(real_renderer))
        assert len(exp.points()) >= 1
        assert exp.scene == (REPO / "configs" / "scenes" / "lampshade.yaml").resolve()
    ratio = load_experiment(REPO / "configs" / "experiments" / "lampshade_ratio.yaml", str(real_renderer))
    assert [p.axis_value for p in ratio.points()] == pytest.approx([0.25, 0.5, 1, 2, 4])


def figure_experiments() -> list[str]:
    """The Makefile's FIGURE_EXPERIMENTS, in order."""
    makefile = (REPO / "Makefile").read_text()
    assignment = re.search(r"^FIGURE_EXPERIMENTS :=((?:.*\\\n)*.*)$", makefile, re.M)
    assert assignment is not None
    return assignment.group(1).replace("\\", " ").split()


def test_02b_every_shipped_experiment_and_its_full_version_load(real_renderer: Path) -> None:
    # make figures runs FIGURE_EXPERIMENTS, FULL=1 their NAME_full.yaml: all must load, or a run of
    # hours stops at its first file.
    listed = figure_experiments()
    assert "lampshade_ratio" in listed
    folder = REPO / "configs" / "experiments"
    for name in listed:
        assert (folder / f"{name}_full.yaml").is_file(), f"{name} has no {name}_full.yaml for FULL=1"
    for path in sorted(folder.glob("*.yaml")):
        exp = load_experiment(path, str(real_renderer))
        assert len(exp.points()) >= 1, path.name


@pytest.mark.parametrize("full", [False, True])
def test_02c_make_figures_sweeps_all_then_measures_and_draws_each(
    tmp_path: Path, real_renderer: Path, full: bool
) -> None:
    # The Makefile's loop itself, with a fake portal-harness that logs its arguments: FULL=1 once
    # swept files named "configs/experiments/.yaml" (the shell read $e_full as one variable).
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    log = tmp_path / "calls"
    fake = venv / "bin" / "portal-harness"
    fake.write_text(f'#!/bin/sh\necho "$@" >> {log}\n')
    fake.chmod(0o755)
    (venv / ".installed").touch()  # newer than harness/pyproject.toml: make does not reinstall
    args = ["make", "--no-print-directory", "figures", f"VENV={venv}", *(["FULL=1"] if full else [])]
    done = subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    suffix = "_full" if full else ""
    files = [f"configs/experiments/{name}{suffix}.yaml" for name in figure_experiments()]
    # every sweep first, then each measured again against the final references and drawn
    expected = [f"sweep {file}" for file in files]
    expected += [f"{command} {file}" for file in files for command in ("sweep --no-progress", "figures")]
    assert log.read_text().splitlines() == expected


BAD: list[tuple[dict[str, Any], str, str]] = [
    ({"strategies": ["light", "prtal"]}, "strategies.1", "unknown strategy 'prtal'"),
    ({"scene": "../scenes/nope.yaml"}, "scene", "not found"),
    ({"sweep": {}}, "sweep", "empty sweep"),
    ({"sweep": {"params.s_L": []}}, "sweep.params.s_L", "non-empty list"),
    ({"sweep": {"params.s_L": "0.3"}}, "sweep.params.s_L", "expected a list"),
    ({"budget": {"time_s": "fast"}}, "budget.time_s", "expected a number"),
    ({"budget": {"time_s": 0, "spp": 0}}, "budget", "needs a limit"),
    ({"budget": {"time_s": 1, "threads": 1.5}}, "budget.threads", "expected an integer"),
    ({"budget": {"time_s": 1, "snapshots": {"every": 0}}}, "budget.snapshots.every", "> 0"),
    ({"budget": {"time_s": 1, "tim_s": 2}}, "budget.tim_s", "unknown key"),
    ({"insets": [{"name": "a", "x": 10, "y": 10, "width": 10, "height": 2}]}, "insets.0", "does not fit"),
    ({"insets": [{"name": "image", "x": 0, "y": 0, "width": 1, "height": 1}]}, "insets.0.name", "reserved"),
    ({"fixed": {"render.spp": 4}}, "fixed.render.spp", "set by the harness"),
    ({"integrator": "bidir"}, "integrator", "unknown integrator"),
    ({"axis": {"param": "params.s_P"}}, "axis.param", "not swept"),
    ({"regress": {"spp": 8, "seeds": [1]}}, "regress.seeds", "two different seeds"),
    ({"colour": "blue"}, "colour", "unknown key"),
    # checked against the renderer: its parameters, and its own messages for what it refuses
    ({"sweep": {"params.s_X": [1, 2]}, "axis": {"param": "params.s_X"}}, "sweep.params.s_X", "no parameter 's_X'"),
    ({"fixed": {"params.s_P": 0.3, "film.width": -3}}, "fixed", "--set film.width=-3: "),
    (
        {"sweep": {"params.s_L": [0.15], "film.height": [16, 0]}},
        "sweep",
        "rejects the point params.s_L=0.15,film.height=0: --set film.height=0: ",
    ),
]


@pytest.mark.parametrize("change,key,message", BAD, ids=[b[1] for b in BAD])
def test_03_bad_configs_name_file_and_key(
    write_experiment: Callable[..., Path], real_renderer: Path, change: dict[str, Any], key: str, message: str
) -> None:
    path = write_experiment(**change)
    with pytest.raises(ConfigError) as info:
        load_experiment(path, str(real_renderer))
    assert info.value.file == str(path)
    assert info.value.key == key
    assert message in info.value.message
    assert str(path) in str(info.value) and key in str(info.value)


def test_04_yaml_syntax_error_has_line_and_column(tmp_path: Path, real_renderer: Path) -> None:
    path = tmp_path / "broken.yaml"
    path.write_text("name: x\nsweep: {params.s_L: [1, 2}\n")
    with pytest.raises(ConfigError, match=r"broken\.yaml:2:\d+: .*YAML syntax error"):
        load_experiment(path, str(real_renderer))


def test_05_missing_experiment_file(tmp_path: Path, real_renderer: Path) -> None:
    with pytest.raises(ConfigError, match="experiment file not found"):
        load_experiment(tmp_path / "nothing.yaml", str(real_renderer))


def test_06_run_spec_from_scene_defaults(fake_scene: Path, real_renderer: Path) -> None:
    spec = spec_from_scene(fake_scene, {"params.s_L": "0.3", "render.mis": "balance"}, str(real_renderer))
    assert (spec.strategy, spec.integrator, spec.spp, spec.time_s, spec.seed, spec.threads) == (
        "light",
        "direct",
        16,
        0.0,
        1,
        1,
    )
    assert dict(spec.overrides) == {"params.s_L": "0.3", "render.mis": "balance"}
    assert dict(spec.snapshots) == {"every": "0.5"}
    with pytest.raises(ConfigError, match="unknown strategy"):
        spec_from_scene(fake_scene, {"render.strategy": "nope"}, str(real_renderer))


def test_snapshots_in_spp_are_integers(write_experiment: Callable[..., Path], real_renderer: Path) -> None:
    budget = {"time_s": 1, "threads": 1, "snapshots": {"doubling_spp": 1, "every": 0.5}}
    exp = load_experiment(write_experiment(budget=budget), str(real_renderer))
    spec = exp.run_spec(exp.points()[0], "light")
    assert ("doubling_spp", "1") in spec.snapshots
    assert "render.snapshots.doubling_spp=1" in spec.command("render", "scene.yaml", "out")
    for bad in (0, 1.5):
        with pytest.raises(ConfigError) as e:
            load_experiment(write_experiment(budget={**budget, "snapshots": {"doubling_spp": bad}}), str(real_renderer))
        assert "budget.snapshots.doubling_spp" in str(e.value)


def test_axis_divisor_is_evaluated_at_each_point(write_experiment: Callable[..., Path], real_renderer: Path) -> None:
    # the lampshade's h is "=s_P / 2": the renderer evaluates it with each point's s_P
    exp = load_experiment(
        write_experiment(
            sweep={"params.s_P": [0.3, 0.6]}, fixed={}, axis={"param": "params.s_P", "divide_by": "params.h"}
        ),
        str(real_renderer),
    )
    assert [p.axis_value for p in exp.points()] == pytest.approx([2.0, 2.0])
