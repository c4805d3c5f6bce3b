"""The region figure (figures/regions.py): the region classes of each point in
the experiment's view and in a section view (figures.region_sections),
rendered by the sweep with the renderer's region AOV, and what each
strategy's next-event samples became, read from the runs' final events
(counters.py). The figure reads stored runs only."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pytest
import yaml

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from fake_render import counters as fake_counters
from matplotlib.colors import to_rgba

from portal_harness.analysis import counters
from portal_harness.core import class_style, exr
from portal_harness.core.errors import ConfigError
from portal_harness.experiment.loader import load_experiment
from portal_harness.experiment.model import AOV_OVERRIDES

CliRunner = Callable[..., tuple[int, str, str]]
REPO = Path(__file__).resolve().parents[3]
SECTION = {"region_sections": {"scene": "../scenes/tiny_section.yaml"}}


@pytest.fixture
def section_scene(fake_scene: Path) -> Path:
    """The tiny lampshade's section: its include with the shapes replaced by the plane z = 0."""
    path = fake_scene.with_name("tiny_section.yaml")
    doc = {
        "include": fake_scene.name,
        "camera": {
            "position": [0, 2, 8],
            "look_at": [0, 2, 0],
            "up": [0, 1, 0],
            "fov_y": 42,
        },
        "shapes": [
            {
                "name": "section",
                "type": "quad",
                "material": "white",
                "vertices": [[-3, 0, 0], [3, 0, 0], [3, 4, 0], [-3, 4, 0]],
            }
        ],
    }
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_01_sweep_renders_sections_and_figures_draw_them(
    cli: CliRunner,
    write_experiment: Callable[..., Path],
    section_scene: Path,
    results: Path,
    render_log: Callable[[], list[str]],
) -> None:
    exp = write_experiment(figures=SECTION)
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    # two region maps, two sections, two references, two points x two strategies
    log = render_log()
    assert len(log) == 2 + 2 + 2 + 4, out
    conn = sqlite3.connect(results / "index.sqlite")
    rows = conn.execute(
        "SELECT e.point, r.run_dir, r.status FROM experiment_runs e JOIN runs r ON r.key = e.key "
        "WHERE e.experiment = 'tiny' AND e.role = 'region_section'"
    ).fetchall()
    conn.close()
    assert sorted(r[0] for r in rows) == ["s_L=0.15", "s_L=0.6"]
    for _, run_dir, run_status in rows:
        assert run_status == "done"
        manifest = json.loads((Path(run_dir) / "manifest.json").read_text())
        # the section scene, with the point's overrides and the region AOV
        assert manifest["spec"]["scene"] == str(section_scene.resolve())
        assert dict(manifest["spec"]["overrides"])["render.aov.region"] == "true"
        assert exr.read_snapshot(Path(run_dir) / "final.exr").regions is not None

    status, out, err = cli("figures", str(exp))
    assert status == 0, err
    for ext in ("png", "pdf"):
        path = results / "figures" / f"tiny_regions.{ext}"
        assert path.stat().st_size > 5000, path
        assert str(path) in out
    # figures never render
    assert len(render_log()) == len(log)
    # resuming renders no section again
    status, out, _ = cli("sweep", str(exp), "--no-progress")
    assert status == 0 and len(render_log()) == len(log)


def test_02_without_sections_the_figure_has_the_experiments_view_only(
    cli: CliRunner,
    write_experiment: Callable[..., Path],
    results: Path,
    render_log: Callable[[], list[str]],
) -> None:
    exp = write_experiment()
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    assert len(render_log()) == 2 + 2 + 4  # no section renders
    status, _, err = cli("figures", str(exp))
    assert status == 0, err
    assert (results / "figures" / "tiny_regions.png").stat().st_size > 5000


def test_03_counters_are_read_from_each_runs_final_event(
    cli: CliRunner,
    write_experiment: Callable[..., Path],
    results: Path,
    render_log: Callable[[], list[str]],
) -> None:
    exp = write_experiment()
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    conn = sqlite3.connect(results / "index.sqlite")
    runs = conn.execute(
        "SELECT e.strategy, r.run_dir, r.final_spp FROM experiment_runs e JOIN runs r ON r.key = e.key "
        "WHERE e.experiment = 'tiny' AND e.role = 'run'"
    ).fetchall()
    conn.close()
    assert len(runs) == 4
    for strategy, run_dir, spp in runs:
        got = counters.read_final_counters(Path(run_dir))
        assert got is not None
        # what the fake renderer wrote: its counters for this run's passes at 16x16
        assert got == counters.ShadowCounters(**fake_counters(strategy, spp, 16, 16), camera_samples=spp * 16 * 16)
        assert got.useful + got.shadow_blocked + got.light_missed + got.no_ray == got.light_samples


def _events(path: Path, events: list[Any]) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    (path / "events.jsonl").write_text("\n".join(e if isinstance(e, str) else json.dumps(e) for e in events) + "\n")
    return path


def test_04_counters_of_hand_written_events(tmp_path: Path) -> None:
    final = {
        "event": "final",
        "light_samples": 100,
        "light_missed": 30,
        "shadow_rays": 60,
        "shadow_blocked": 15,
    }
    start = {"event": "start", "width": 4, "height": 5}
    run = _events(tmp_path / "a", [start, "not json", {"event": "snapshot"}, {**final, "spp": 2}])
    c = counters.read_final_counters(run)
    assert c == counters.ShadowCounters(
        light_samples=100, light_missed=30, shadow_rays=60, shadow_blocked=15, camera_samples=2 * 4 * 5
    )
    assert c is not None and (c.useful, c.no_ray) == (45, 10)
    # without the start event (or the final spp) the camera samples are unknown: 0
    assert counters.read_final_counters(_events(tmp_path / "e", [final])) == counters.ShadowCounters(100, 30, 60, 15)
    # a renderer without the counters, no final event, no events file
    assert counters.read_final_counters(_events(tmp_path / "b", [{"event": "final", "spp": 4}])) is None
    assert counters.read_final_counters(_events(tmp_path / "c", [{"event": "start"}])) is None
    assert counters.read_final_counters(tmp_path / "none") is None
    bad = {**final, "shadow_rays": -1}
    assert counters.read_final_counters(_events(tmp_path / "d", [bad])) is None
    # summed over replicates, runs without counters left out
    assert counters.total([c, None, c]) == counters.ShadowCounters(200, 60, 120, 30, 80)
    assert counters.total([None]) is None


def test_05_class_map_colours_are_fixed_per_class() -> None:
    classes = exr.REGION_CLASSES
    f = np.zeros((2, len(classes), len(classes)))
    for i in range(len(classes)):
        f[0, i, i] = 1.0  # row 0: every class, pure
        f[1, i, :] = 1.0 / len(classes)  # row 1: no majority
    fig, ax = plt.subplots()
    class_style.draw_class_map(ax, f, classes)
    image = ax.images[0]
    data = image.get_array()
    assert data is not None
    rgba = np.asarray(image.cmap(image.norm(data)))
    plt.close(fig)
    for i, name in enumerate(classes):
        assert rgba[0, i] == pytest.approx(to_rgba(class_style.CLASS_COLOURS[name]))
        assert rgba[1, i] == pytest.approx(to_rgba(class_style.NO_MAJORITY_COLOUR))
    # every class has its own colour, and a legend entry
    assert len({class_style.class_colour(c, classes) for c in classes}) == len(classes)
    assert [h.get_label() for h in class_style.legend_handles(classes)][-1] == "no majority"
    # a class the renderer adds gets a spare colour, not black
    assert class_style.class_colour("penumbra_2", (*classes, "penumbra_2")) in class_style.SPARE_CLASS_COLOURS
    with pytest.raises(ValueError):
        class_style.draw_class_map(ax, f[..., :3], classes)


BAD: list[tuple[Any, str, str]] = [
    ({"region_sections": {}}, "figures.region_sections.scene", "missing required key"),
    (
        {"region_sections": "section.yaml"},
        "figures.region_sections",
        "expected a mapping",
    ),
    (
        {"region_sections": {"scene": "../scenes/nope.yaml"}},
        "figures.region_sections.scene",
        "not found",
    ),
    (
        {"region_sections": {**SECTION["region_sections"], "spp": 0}},
        "figures.region_sections.spp",
        ">= 1",
    ),
    (
        {"region_sections": {**SECTION["region_sections"], "spp": 8, "view": 1}},
        "figures.region_sections.view",
        "unknown key",
    ),
    (
        {"region_sections": {"scene": "../scenes/broken_section.yaml"}},
        "figures.region_sections.scene",
        "rejects the scene",
    ),
    (
        {"region_sections": {"scene": "../scenes/small_section.yaml"}},
        "figures.region_sections.scene",
        "at the point s_L=0.15",
    ),
]


@pytest.mark.parametrize("figures,key,message", BAD, ids=[f"{b[1]}:{b[2]}" for b in BAD])
def test_06_bad_region_sections_name_file_key_and_line(
    write_experiment: Callable[..., Path],
    section_scene: Path,
    real_renderer: Path,
    figures: Any,
    key: str,
    message: str,
) -> None:
    # a section scene the renderer refuses (unknown material), and one it refuses at s_L = 0.15 only
    doc = yaml.safe_load(section_scene.read_text())
    doc["shapes"][0]["material"] = "chalk"
    section_scene.with_name("broken_section.yaml").write_text(yaml.safe_dump(doc))
    doc["shapes"][0]["material"] = "white"
    doc["shapes"][0]["vertices"][3][0] = "=-3 + sqrt(s_L - 0.3)"
    section_scene.with_name("small_section.yaml").write_text(yaml.safe_dump(doc))
    path = write_experiment(figures=figures)
    with pytest.raises(ConfigError) as info:
        load_experiment(path, str(real_renderer))
    assert info.value.file == str(path)
    assert info.value.key == key
    assert message in info.value.message, info.value.message
    # the line of the key, or of the nearest key that encloses it
    assert info.value.line is not None
    line = path.read_text().splitlines()[info.value.line - 1]
    assert any(part in line for part in ("region_sections", key.split(".")[-1]))
    assert f"{path}:{info.value.line}:" in str(info.value)


def test_07_shipped_ratio_experiments_render_the_lamp_section(
    real_renderer: Path,
) -> None:
    for name in ("lampshade_ratio", "lampshade_ratio_full"):
        exp = load_experiment(REPO / "configs" / "experiments" / f"{name}.yaml", str(real_renderer))
        assert exp.region_sections is not None
        assert exp.region_sections.scene == (REPO / "configs" / "scenes" / "lampshade_section.yaml").resolve()
        assert exp.region_sections.label == "vertical section z = 0 through the lamp"
        # the classes are the renderer's (render --describe), the ones exr.py reads
        assert exp.region_classes == exr.REGION_CLASSES
        point = exp.reference_points()[0]
        spec = exp.region_section_spec(point)
        assert spec.scene == str(exp.region_sections.scene)
        assert set(AOV_OVERRIDES) <= set(spec.overrides)
        # the point's values and the fixed film size apply to the section too
        assert dict(spec.overrides)["params.s_L"] == dict(exp.region_map_spec(point).overrides)["params.s_L"]
        assert spec.key("v") != exp.region_map_spec(point).key("v")
