"""The viewer's data (viewer/bundle.py) and `portal-harness report`
(viewer/report.py), on a tiny swept experiment: the bundle holds the very
images, exposures, regions, per-image relMSE and curves that the figures
and the summary use; the report is a self-contained folder, written
whole or not at all."""

from __future__ import annotations

import base64
import json
import math
import re
import shutil
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from viewer_sweep import Swept, swept_once

from portal_harness.cli import main
from portal_harness.core import display, exr
from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.core.regions import NamedRegion
from portal_harness.execution import index
from portal_harness.experiment.loader import load_experiment
from portal_harness.experiment.model import Experiment
from portal_harness.figures import data as figure_data
from portal_harness.figures import style as figure_style
from portal_harness.viewer import bundle as vb
from portal_harness.viewer import flip
from portal_harness.viewer.report import MARKER, STATIC


@pytest.fixture(scope="module")
def swept(tmp_path_factory: pytest.TempPathFactory, fake_renderer: Path) -> Swept:
    return swept_once(tmp_path_factory, fake_renderer)


@pytest.fixture(scope="module")
def experiment(swept: Swept) -> Experiment:
    return load_experiment(swept.experiment, str(swept.renderer))


@pytest.fixture(scope="module")
def written(swept: Swept, experiment: Experiment, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bundle")
    vb.write_bundle(ResultsLayout(swept.results), experiment, out)
    return out


def _strict(text: str) -> Any:
    def refuse(name: str) -> None:
        raise ValueError(f"{name} in the bundle")

    return json.loads(text, parse_constant=refuse)


def _run(swept: Swept, *args: str) -> int:
    return main([*args, "--results", str(swept.results), "--renderer", str(swept.renderer)])


def test_01_images_are_the_exr_values_and_the_figures_choice(
    swept: Swept, experiment: Experiment, written: Path
) -> None:
    data = vb.read_bundle(written)
    assert data["experiment"] == "tiny" and (data["width"], data["height"]) == (16, 16)
    assert [s["name"] for s in data["strategies"]] == ["light", "portal"]
    layout = ResultsLayout(swept.results)
    conn = index.connect(layout.index_path)
    try:
        fig_data = figure_data.load(experiment, conn, layout)
        numbers: list[int] = []
        assert [p["id"] for p in data["points"]] == [p.id for p in fig_data.points]
        for point, entry in zip(fig_data.points, data["points"], strict=True):
            ref_cell = fig_data.references[point.id]
            assert ref_cell.run_dir is not None
            reference = exr.read_snapshot(RunLayout(ref_cell.run_dir).final)
            images = entry["images"]
            assert [e["name"] for e in images] == ["reference", "light", "portal"]
            # the reference as float32, bit for bit, and the exposure display.py gives it
            assert np.array_equal(vb.read_image(written, images[0]["image"]), reference.rgb.astype(np.float32))
            assert entry["exposure"] == display.exposure_from_reference(reference.rgb)
            t_eq = figure_data.equal_time(experiment, conn, fig_data, point)
            assert entry["equal_time_s"] == pytest.approx(t_eq)
            for e in images[1:]:
                cell = fig_data.runs[(point.id, e["name"])]
                chosen = figure_data.choose_image(conn, cell, t_eq)
                assert chosen is not None and e["status"] == "done"
                assert e["file"] == chosen.image.name and e["time_s"] == chosen.time_s
                assert chosen.time_s <= t_eq * (1 + figure_data.EQUAL_TIME_TOLERANCE)
                shown = vb.read_image(written, e["image"])
                assert np.array_equal(shown, exr.read_snapshot(chosen.image).rgb.astype(np.float32))
                # its relMSE per region is the index's for that very image
                rows = index.metrics_of(conn, cell.key, cell.reference_key)
                mine = {m["region"]: m["rel_mse"] for m in rows if m["image"] == chosen.image.name}
                assert e["rel_mse"] == mine and len(mine) == len(entry["regions"])
            numbers += [e["image"] for e in images] + [e["flip_image"] for e in images[1:]]
        assert sorted(numbers) == list(range(len(numbers)))  # every image and FLIP map once
        assert sorted(p.name for p in (written / "img").iterdir()) == sorted(f"{n}.js" for n in numbers)
    finally:
        conn.close()


def test_02_flip_maps_and_their_means_per_region(written: Path, rng: np.random.Generator) -> None:
    data = vb.read_bundle(written)
    assert data["flip"] == {"dynamic_range": "LDR", "ppd": flip.PPD}
    for point in data["points"]:
        masks = {r["name"]: _mask(r["mask"]) for r in point["regions"]}
        for e in point["images"][1:]:
            error = vb.read_image(written, e["flip_image"])
            assert error.shape == (16, 16) and error.min() >= 0 and error.max() <= 1
            assert e["flip"] == pytest.approx({name: float(error[m].mean()) for name, m in masks.items()}, rel=1e-6)
    # FLIP is zero for the reference itself and grows with the noise
    reference = rng.uniform(0.05, 1.0, (16, 16, 3))
    region = [NamedRegion("image", "image", np.ones((16, 16), dtype=bool))]
    found = [
        flip.flip_of(reference * (1 + sigma * rng.standard_normal(reference.shape)), reference, 1.0, region)
        for sigma in (0.0, 0.05, 0.3)
    ]
    values = [f.by_region["image"] for f in found]
    assert values[0] == 0 and 0 < values[1] < values[2]  # type: ignore[operator]


def _mask(text: str) -> np.ndarray:
    bits = np.unpackbits(np.frombuffer(base64.b64decode(text), dtype=np.uint8))
    return bits[: 16 * 16].reshape(16, 16).astype(bool)


def test_03_regions_are_the_summary_regions_with_their_masks(
    swept: Swept, experiment: Experiment, written: Path
) -> None:
    data = vb.read_bundle(written)
    summary = json.loads(ResultsLayout(swept.results).summary_json("tiny").read_text())["rows"]
    assert data["summary"] == summary
    for point in data["points"]:
        rows = {r["region"]: r for r in summary if r["point"] == point["id"] and r["strategy"] == "light"}
        assert [r["name"] for r in point["regions"]] == list(rows)  # report order: image, lit, insets, classes
        for region in point["regions"]:
            mask = _mask(region["mask"])
            assert int(mask.sum()) == region["pixels"] == rows[region["name"]]["pixels"]
        insets = {r["name"]: r for r in point["regions"] if r["kind"] == "inset"}
        for rect in data["insets"]:
            # the inset figure's rectangles and colours
            assert insets[rect["name"]]["pixels"] == rect["width"] * rect["height"]
        assert [r["colour"] for r in data["insets"]] == list(figure_style.INSET_COLOURS[:2])


def test_04_curves_are_the_mean_of_the_replicates(swept: Swept, experiment: Experiment, written: Path) -> None:
    data = vb.read_bundle(written)
    conn = sqlite3.connect(ResultsLayout(swept.results).index_path)
    conn.row_factory = sqlite3.Row
    try:
        for point in data["points"]:
            for strategy in ("light", "portal"):
                curve = data["curves"][point["id"]]["lit"]["strategies"][strategy]
                keys = conn.execute(
                    "SELECT key, reference_key FROM experiment_runs WHERE experiment = 'tiny' AND point = ? "
                    "AND strategy = ? AND role = 'run' ORDER BY replicate",
                    (point["id"], strategy),
                ).fetchall()
                assert curve["replicates"] == len(keys) == 2
                per_run = [
                    sorted(
                        (m["time_s"], m["rel_mse"])
                        for m in index.metrics_of(conn, k["key"], k["reference_key"])
                        if m["region"] == "lit" and m["time_s"]
                    )
                    for k in keys
                ]
                n = min(len(c) for c in per_run)
                assert len(curve["t"]) == n >= 3
                for i in range(n):
                    values = [c[i][1] for c in per_run]
                    assert curve["t"][i] == pytest.approx(sum(c[i][0] for c in per_run) / 2)
                    assert curve["v"][i] == pytest.approx(sum(values) / 2)
                    assert (curve["lo"][i], curve["hi"][i]) == (min(values), max(values))
            floor = data["curves"][point["id"]]["lit"]["floor"]
            assert floor is not None and 0 < floor < min(curve["v"])
    finally:
        conn.close()


def test_05_bundle_is_strict_json_with_the_display_constants(written: Path) -> None:
    text = (written / vb.BUNDLE_SCRIPT).read_text()
    assert text.startswith(f"window.{vb.BUNDLE_GLOBAL} = ") and text.endswith(";\n")
    data = _strict(text[len(f"window.{vb.BUNDLE_GLOBAL} = ") : -2])
    assert data["format"] == vb.FORMAT
    assert data["luminance_weights"] == pytest.approx(display.luminance(np.eye(3)).tolist())
    assert data["error_epsilon"] == 0.01
    colours = data["error_colormap"]["colours"]
    assert len(colours) == 256 and all(len(c) == 3 and all(0 <= v <= 255 for v in c) for c in colours)
    for point in data["points"]:
        assert math.isfinite(point["exposure"]) and point["exposure"] > 0


def test_06_report_is_a_self_contained_folder(swept: Swept, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "report"
    assert _run(swept, "report", str(swept.experiment), "--out", str(out)) == 0
    assert capsys.readouterr().out.strip() == str(out / "viewer.html")
    page = (out / "viewer.html").read_text()
    sources = re.findall(r'(?:src|href)="([^"]+)"', page)
    assert sources and all((out / s).is_file() for s in sources)
    assert (out / "data" / "bundle.js").is_file() and (out / "data" / "img" / "0.js").is_file()
    assert json.loads((out / MARKER).read_text())["experiment"] == "tiny"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]  # no temporary folder left


def test_07_a_folder_that_is_not_a_report_is_refused(
    swept: Swept, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "paper"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert _run(swept, "report", str(swept.experiment), "--out", str(out)) == 2
    err = capsys.readouterr().err
    assert f"{out}: not empty and not an earlier report" in err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["paper"]
    (tmp_path / "file").write_text("x")
    assert _run(swept, "report", str(swept.experiment), "--out", str(tmp_path / "file")) == 2
    assert "exists and is not a folder" in capsys.readouterr().err


def test_08_an_earlier_report_is_replaced_whole(swept: Swept, tmp_path: Path) -> None:
    out = tmp_path / "report"
    assert _run(swept, "report", str(swept.experiment), "--out", str(out)) == 0
    (out / "data" / "img" / "99.js").write_text("stale")
    assert _run(swept, "report", str(swept.experiment), "--out", str(out)) == 0
    assert not (out / "data" / "img" / "99.js").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _run(swept, "report", str(swept.experiment), "--out", str(empty)) == 0


def test_09_an_unswept_experiment_writes_nothing(
    swept: Swept, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = swept.experiment.with_name("other.yaml")
    other.write_text(swept.experiment.read_text().replace("name: tiny", "name: other"))
    out = tmp_path / "report"
    assert _run(swept, "report", str(other), "--out", str(out)) == 1
    assert "no runs of experiment 'other'" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    bad = swept.experiment.with_name("bad.yaml")
    bad.write_text(swept.experiment.read_text().replace("strategies:", "strategiez:"))
    assert _run(swept, "report", str(bad), "--out", str(out)) == 2
    assert re.search(r"bad\.yaml:\d+:\d+: ", capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


def test_10_failed_runs_and_missing_references_are_shown_as_such(
    swept: Swept, experiment: Experiment, tmp_path: Path
) -> None:
    # The index as a sweep leaves it when every portal run crashed (test_sweep.py makes real crashes).
    results = tmp_path / "results"
    shutil.copytree(swept.results, results)
    conn = sqlite3.connect(results / "index.sqlite")
    conn.execute("UPDATE runs SET status = 'failed' WHERE strategy = 'portal' AND kind != 'reference'")
    # and the second point's reference
    conn.execute(
        "UPDATE runs SET status = 'failed' WHERE key = (SELECT key FROM experiment_runs WHERE role = 'reference' "
        "ORDER BY axis_value DESC LIMIT 1)"
    )
    conn.commit()
    conn.close()
    vb.write_bundle(ResultsLayout(results), experiment, tmp_path / "bundle")
    data = vb.read_bundle(tmp_path / "bundle")
    last = data["points"][-1]
    assert last["missing"] == "reference missing" and last["images"] == [] and last["regions"] == []
    for point in data["points"][:-1]:
        light, portal = point["images"][1:]
        assert light["status"] == "done" and light["image"] is not None
        assert portal["status"] == "failed" and portal["image"] is None and portal["rel_mse"] == {}
        assert data["curves"][point["id"]]["lit"]["strategies"].keys() == {"light"}


def test_11_the_page_loads_nothing_from_the_network() -> None:
    files = [p for p in STATIC.rglob("*") if p.is_file()]
    assert {p.suffix for p in files} == {".html", ".css", ".js"}
    for path in files:
        text = path.read_text()
        # the SVG namespace is a name, never fetched
        assert not re.search(r"(https?|wss?|ftp)://(?!www\.w3\.org/2000/svg\b)", text), path
        assert not re.search(r"""(src|href)=["']//""", text), path
        assert not re.search(r"\bfetch\(\s*[^)]|XMLHttpRequest|import\(", text), path
