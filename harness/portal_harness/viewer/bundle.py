"""The data of one swept experiment for the comparison viewer
(static/viewer.html), written from stored runs only, never rendered.

The viewer must open from disk (file://), where Chrome forbids fetch() and
taints canvases drawn from file images, so every file is a script:

  bundle.js     window.PORTAL_BUNDLE = {...}: points, the images of each
                point (the reference, then each strategy), their relMSE per
                region, the region masks, the insets, the error curves and
                the tidy summary rows;
  img/N.js      PORTAL_IMAGE(N, {"width", "height", "channels", "values"}):
                image N's linear RGB (3 channels: the EXR's values, so that
                the browser's tone mapping can equal display.to_srgb8
                exactly) or a FLIP map (1 channel), base64 of little-endian
                float32, channels interleaved, row 0 at the top.

The same files serve the report (report.py) and the HTTP service. Every
fact comes from the module that owns it: the strategy images and their
per-image relMSE are the inset figure's (figures/data.py: choose_image at
equal_time), the curves the error figure's (figures/data.py: run_curve,
mean_curve), the regions regions.py's with the sweep's region map,
the exposure display.py's, the summary analysis/sweep_summary.py's summary.json.
"""

from __future__ import annotations

import base64
import json
import math
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps

from portal_harness import __version__
from portal_harness.core import class_style, display, exr
from portal_harness.core.errors import CorruptExrError
from portal_harness.core.metrics import REL_EPSILON, Region
from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.core.regions import NamedRegion, regions_of
from portal_harness.execution import index
from portal_harness.execution.index import ROLE_REGION_MAP
from portal_harness.experiment.model import Experiment, Point
from portal_harness.figures import data as figure_data
from portal_harness.figures import style as figure_style
from portal_harness.figures.regions import read_fractions, region_renders
from portal_harness.viewer import flip

FORMAT = 1
BUNDLE_SCRIPT = "bundle.js"
IMAGE_FOLDER = "img"
BUNDLE_GLOBAL = "PORTAL_BUNDLE"
IMAGE_CALLBACK = "PORTAL_IMAGE"
REFERENCE = "reference"
# The false-colour map of the relative-error view, sampled here so that the
# browser needs no colour tables of its own.
ERROR_COLORMAP = "inferno"
ERROR_COLORMAP_SIZE = 256


def image_script(number: int) -> str:
    """The path of image `number` inside a bundle folder."""
    return f"{IMAGE_FOLDER}/{number}.js"


def encode_rgb(rgb: np.ndarray) -> str:
    """Base64 of the (height, width[, channels]) image as little-endian float32."""
    return base64.b64encode(np.ascontiguousarray(rgb, dtype="<f4").tobytes()).decode("ascii")


def decode_rgb(text: str, width: int, height: int, channels: int = 3) -> np.ndarray:
    """The inverse of encode_rgb (the tests' reader); (height, width) for one channel."""
    values = np.frombuffer(base64.b64decode(text), dtype="<f4")
    return values.reshape(height, width) if channels == 1 else values.reshape(height, width, channels)


def encode_mask(mask: np.ndarray) -> str:
    """Base64 of the boolean mask's bits, row-major, most significant bit first."""
    return base64.b64encode(np.packbits(mask.reshape(-1)).tobytes()).decode("ascii")


def _finite(value: Any) -> Any:
    """A value for strict JSON: NaN and infinities become None, recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, np.generic):
        return _finite(value.item())
    return value


class _Images:
    """Numbers the images of a bundle and writes each as its script."""

    def __init__(self, out: Path) -> None:
        self.folder = out / IMAGE_FOLDER
        self.folder.mkdir(parents=True, exist_ok=True)
        self.count = 0

    def add(self, values: np.ndarray) -> int:
        """An RGB image (height, width, 3) or a map of one value per pixel (height, width)."""
        number = self.count
        self.count += 1
        height, width = values.shape[:2]
        channels = 1 if values.ndim == 2 else values.shape[2]
        payload = json.dumps({"width": width, "height": height, "channels": channels, "values": encode_rgb(values)})
        (self.folder / f"{number}.js").write_text(f"{IMAGE_CALLBACK}({number}, {payload});\n")
        return number


def _inset_entries(insets: tuple[Region, ...]) -> list[dict[str, Any]]:
    colours = figure_style.INSET_COLOURS
    return [
        {
            "name": r.name,
            "x": r.x,
            "y": r.y,
            "width": r.width,
            "height": r.height,
            "colour": colours[i % len(colours)],
        }
        for i, r in enumerate(insets)
    ]


def _point_images(
    experiment: Experiment,
    data: figure_data.ExperimentData,
    conn: sqlite3.Connection,
    point: Point,
    reference: exr.Snapshot,
    regions: list[NamedRegion],
    exposure: float,
    images: _Images,
) -> list[dict[str, Any]]:
    """The reference, then each strategy's image at the point's equal time
    (the inset figure's choice), with the image's relMSE per region (the
    index's) and its FLIP map and FLIP per region."""
    out: list[dict[str, Any]] = [
        {
            "name": REFERENCE,
            "label": REFERENCE,
            "status": "done",
            "image": images.add(reference.rgb),
            "spp": reference.header.spp,
            "time_s": reference.header.render_time_s,
            "rel_mse": {},
        }
    ]
    t_eq = figure_data.equal_time(experiment, conn, data, point)
    for strategy in experiment.strategies:
        cell = data.runs.get((point.id, strategy))
        entry: dict[str, Any] = {
            "name": strategy,
            "label": figure_style.strategy_label(strategy),
            "status": (cell.status if cell is not None else None) or "missing",
            "image": None,
            "rel_mse": {},
            "run": cell.key if cell is not None else None,  # the service's /api/runs/{run}/...
        }
        chosen = (
            figure_data.choose_image(conn, cell, t_eq) if cell is not None and figure_data.cell_done(cell) else None
        )
        if chosen is not None:
            try:
                snapshot = exr.read_snapshot(chosen.image)
            except CorruptExrError as e:
                entry["status"] = f"unreadable: {e.reason}"
            else:
                flipped = flip.flip_of(snapshot.rgb, reference.rgb, exposure, regions)
                entry.update(
                    {
                        "image": images.add(snapshot.rgb),
                        "spp": snapshot.header.spp,
                        "time_s": chosen.time_s,
                        "rel_mse": chosen.rel_mse,
                        "file": chosen.image.name,
                        "flip": flipped.by_region,
                        "flip_image": images.add(flipped.error),
                    }
                )
        out.append(entry)
    return out


def _region_entries(regions: list[NamedRegion]) -> list[dict[str, Any]]:
    return [
        {
            "name": r.name,
            "kind": r.kind,
            "title": figure_style.region_title(r.name),
            "pixels": r.pixels,
            "mask": encode_mask(r.mask),
        }
        for r in regions
    ]


def _point_curves(
    experiment: Experiment, data: figure_data.ExperimentData, conn: sqlite3.Connection, point: Point, regions: list[str]
) -> dict[str, Any]:
    """region -> {"floor", "strategies": strategy -> mean curve over replicates and its range}."""
    metric = experiment.curve_metric
    out: dict[str, Any] = {}
    for region in regions:
        floor: float | None = None
        lines: dict[str, Any] = {}
        for strategy in experiment.strategies:
            cells = [c for c in data.replicates.get((point.id, strategy), []) if figure_data.cell_done(c)]
            curves = [c for c in (figure_data.run_curve(conn, cell, region, metric) for cell in cells) if c]
            if not curves:
                continue
            t, v, lo, hi = figure_data.mean_curve(curves)
            lines[strategy] = {
                "t": t.tolist(),
                "v": v.tolist(),
                "lo": lo.tolist(),
                "hi": hi.tolist(),
                "replicates": len(curves),
            }
            floor = curves[0][0][2]
        if lines:
            out[region] = {"floor": floor if metric == "rel_mse" else None, "strategies": lines}
    return out


def _colormap() -> list[list[int]]:
    cmap = colormaps[ERROR_COLORMAP]
    rgba = cmap(np.linspace(0.0, 1.0, ERROR_COLORMAP_SIZE))
    return [[round(float(c) * 255) for c in row[:3]] for row in rgba]


def build(layout: ResultsLayout, experiment: Experiment, out: Path) -> dict[str, Any]:
    """Writes the images into out/img/ and returns the bundle's data."""
    conn = index.connect(layout.index_path)
    try:
        data = figure_data.load(experiment, conn, layout)
        maps = region_renders(conn, experiment)
        images = _Images(out)
        points: list[dict[str, Any]] = []
        curves: dict[str, Any] = {}
        for point in data.points:
            entry: dict[str, Any] = {
                "id": point.id,
                "title": figure_style.point_title(experiment, point),
                "axis": None if math.isnan(point.axis_value) else point.axis_value,
                "facets": [[k, v] for k, v in point.facets],
                "images": [],
                "regions": [],
            }
            points.append(entry)
            ref_cell = data.references.get(point.id)
            if not figure_data.cell_done(ref_cell):
                entry["missing"] = "reference missing"
                continue
            assert ref_cell is not None and ref_cell.run_dir is not None
            try:
                reference = exr.read_snapshot(RunLayout(ref_cell.run_dir).final)
            except CorruptExrError as e:
                entry["missing"] = f"reference unreadable: {e.reason}"
                continue
            t_eq = figure_data.equal_time(experiment, conn, data, point)
            exposure = display.exposure_from_reference(reference.rgb)
            # The point's regions as regions.py makes them for the sweep's metrics.
            fractions = read_fractions(maps.get((point.id, ROLE_REGION_MAP)))
            regions = regions_of(reference, experiment.insets, experiment.lit_threshold, fractions)
            entry["exposure"] = exposure
            entry["equal_time_s"] = t_eq if math.isfinite(t_eq) else None
            entry["images"] = _point_images(experiment, data, conn, point, reference, regions, exposure, images)
            entry["regions"] = _region_entries(regions)
            curves[point.id] = _point_curves(experiment, data, conn, point, [r["name"] for r in entry["regions"]])
    finally:
        conn.close()
    axis = experiment.axis
    bundle: dict[str, Any] = _finite(
        {
            "format": FORMAT,
            "harness_version": __version__,
            "experiment": experiment.name,
            "width": experiment.width,
            "height": experiment.height,
            "axis_label": axis.label if axis is not None else None,
            "curve_metric": experiment.curve_metric,
            "curve_metric_label": figure_style.METRIC_LABELS[experiment.curve_metric],
            "strategies": [
                {
                    "name": s,
                    "label": figure_style.strategy_label(s),
                    "colour": figure_style.strategy_colour(s, experiment.strategies),
                }
                for s in experiment.strategies
            ],
            "facet_keys": list(experiment.facets),
            # Without an axis, the efficiency figure colours each facet combination.
            "facet_colours": list(figure_style.FACET_COLOURS),
            "insets": _inset_entries(experiment.insets),
            "class_colours": {c: class_style.class_colour(c, exr.REGION_CLASSES) for c in exr.REGION_CLASSES},
            "luminance_weights": display.luminance(np.eye(3)).tolist(),
            "error_epsilon": REL_EPSILON,
            "flip": {"dynamic_range": flip.DYNAMIC_RANGE, "ppd": flip.PPD},
            "error_colormap": {"name": ERROR_COLORMAP, "colours": _colormap()},
            "points": points,
            "curves": curves,
            "summary": data.summary,
        }
    )
    return bundle


def write_bundle(layout: ResultsLayout, experiment: Experiment, out: Path) -> None:
    """Writes into `out/` (created if needed) every data file the viewer
    needs for one swept experiment: img/N.js, then bundle.js last, so that
    a folder without bundle.js is unfinished. Rewriting a folder that a
    browser may be reading mixes old and new files: write a fresh folder
    and rename it into place (report.py does). Raises HarnessError when
    the experiment has not been swept."""
    out.mkdir(parents=True, exist_ok=True)
    data = build(layout, experiment, out)
    text = json.dumps(data, allow_nan=False, separators=(",", ":"))
    tmp = out / f".{BUNDLE_SCRIPT}.tmp"
    tmp.write_text(f"window.{BUNDLE_GLOBAL} = {text};\n")
    tmp.replace(out / BUNDLE_SCRIPT)


def read_bundle(folder: Path) -> dict[str, Any]:
    """The data of a written bundle.js (for tests and tools)."""
    text = (folder / BUNDLE_SCRIPT).read_text()
    prefix = f"window.{BUNDLE_GLOBAL} = "
    if not text.startswith(prefix):
        raise ValueError(f"{folder / BUNDLE_SCRIPT}: not a viewer bundle")
    data: dict[str, Any] = json.loads(text[len(prefix) :].rstrip().rstrip(";"))
    return data


def read_image(folder: Path, number: int) -> np.ndarray:
    """Image `number` of a written bundle as float32 (height, width, 3)."""
    text = (folder / image_script(number)).read_text()
    prefix = f"{IMAGE_CALLBACK}({number}, "
    if not text.startswith(prefix):
        raise ValueError(f"{folder / image_script(number)}: not image {number} of a viewer bundle")
    payload = json.loads(text[len(prefix) :].rstrip().rstrip(";").rstrip(")"))
    return decode_rgb(payload["values"], payload["width"], payload["height"], payload["channels"])
