"""The figures of an experiment, one function each, from the index
(metrics), the tidy summary (summary.json) and the run folders (images
through exr.py):

1. error over time: log-log, one line per strategy (the mean over
   replicates, a band from the smallest to the largest replicate), one panel
   per sweep point, for the `lit` region and the whole image;
   with facets (categorical sweep keys, facets.py), one block of rows per
   facet value;
2. insets: per sweep point, the reference with the inset rectangles drawn
   and its antishadow region classes beside it, then each inset of the
   reference and of each strategy at equal render time (replicate 0), with
   its relMSE under it;
3. efficiency relative to light sampling against the swept axis (the
   light/portal ratio), one panel per region (image, lit, insets, region
   classes), error bars of one standard error over replicates, open
   triangles where the value is only a lower bound; below it, the
   equal-error speed-up in the same layout. Facets are line styles (a
   legend names each key=value); an experiment without an axis has the
   strategies along x and a colour per facet value;
4. the antishadow regions: the region classes of each point's region map
   and section view, and what each strategy's shadow rays were spent on
   (region_figures.py).

PNG and PDF go to results/figures/<experiment>_<figure>.{png,pdf}; the
tables of the summary (tables.py) to results/experiments/<experiment>/summary.tex.
"""

from __future__ import annotations

import json
import math
import sqlite3
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # pinned: figures are files, never windows

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axis import Axis as MplAxis
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.ticker import FuncFormatter, NullFormatter

from portal_harness import class_style, display, exr, facets, figure_layout, index, tables
from portal_harness.config import Experiment, Point
from portal_harness.errors import CorruptExrError, HarnessError
from portal_harness.index import ROLE_REFERENCE, ROLE_RUN
from portal_harness.metrics import WHOLE_IMAGE, Region, crop
from portal_harness.paths import ResultsLayout, RunLayout
from portal_harness.regions import LIT
from portal_harness.spec import format_value

# Display only: a colour and a label for the strategies drawn so far. The
# strategies themselves are the renderer's (render --describe); a name not
# listed here is drawn under its own name in a colour of its own.
STRATEGY_COLOURS = {
    "light_area": "#7f7f7f",
    "light": "#1f77b4",
    "portal": "#ff7f0e",
    "projection": "#2ca02c",
    "antishadow": "#d62728",
    "antishadow_exact": "#9467bd",
}
STRATEGY_LABELS = {"light_area": "light (area)", "antishadow_exact": "antishadow (exact)"}
SPARE_COLOURS = ("#8c564b", "#e377c2", "#bcbd22", "#17becf", "#393b79", "#637939")


def strategy_label(strategy: str) -> str:
    return STRATEGY_LABELS.get(strategy, strategy)


def strategy_colour(strategy: str, strategies: Sequence[str]) -> str:
    """The strategy's colour; unknown ones take the spare colours in the order of `strategies`."""
    if strategy in STRATEGY_COLOURS:
        return STRATEGY_COLOURS[strategy]
    unknown = [s for s in strategies if s not in STRATEGY_COLOURS]
    return SPARE_COLOURS[unknown.index(strategy) % len(SPARE_COLOURS)] if strategy in unknown else "#000000"


INSET_COLOURS = ("#ffd700", "#00e5ff", "#ff4fd8", "#7CFC00")
METRIC_LABELS = {"rel_mse": "relMSE", "mse": "MSE"}


@dataclass(frozen=True)
class Cell:
    """One (point, strategy) of an experiment as the index knows it."""

    key: str
    reference_key: str | None
    status: str | None
    run_dir: Path | None


@dataclass(frozen=True)
class ExperimentData:
    points: tuple[Point, ...]
    runs: dict[tuple[str, str], Cell]  # replicate 0 of (point, strategy)
    replicates: dict[tuple[str, str], list[Cell]]  # every replicate
    references: dict[str, Cell]
    summary: list[dict[str, Any]]  # summary.json's tidy rows


def load(experiment: Experiment, conn: sqlite3.Connection, layout: ResultsLayout) -> ExperimentData:
    rows = index.membership(conn, experiment.name)
    runs: dict[tuple[str, str], Cell] = {}
    replicates: dict[tuple[str, str], list[Cell]] = {}
    references: dict[str, Cell] = {}
    for r in rows:
        cell = Cell(r["key"], r["reference_key"], r["status"], Path(r["run_dir"]) if r["run_dir"] else None)
        if r["role"] == ROLE_REFERENCE:
            references[r["point"]] = cell
        elif r["role"] == ROLE_RUN:
            replicates.setdefault((r["point"], r["strategy"]), []).append(cell)
            if r["replicate"] == 0:
                runs[(r["point"], r["strategy"])] = cell
    points = tuple(p for p in experiment.points() if p.id in references)
    if not points:
        raise HarnessError(f"no runs of experiment {experiment.name!r} in the index: run `portal-harness sweep` first")
    try:
        summary = json.loads(layout.summary_json(experiment.name).read_text())["rows"]
    except (OSError, ValueError, KeyError):
        raise HarnessError(f"no summary of experiment {experiment.name!r}: run `portal-harness sweep` first") from None
    return ExperimentData(points, runs, replicates, references, summary)


def point_title(experiment: Experiment, point: Point) -> str:
    """The axis value and the facets of a point: `light/portal ratio = 2, portal_weight=area`."""
    parts = [] if experiment.axis is None else [f"{experiment.axis.label} = {point.axis_value:g}"]
    if point.facets:
        parts.append(facets.labels(point.facets))
    return ", ".join(parts) or point.id


FacetValues = tuple[tuple[str, Any], ...]
FACET_LINE_STYLES = ("-", "--", ":", "-.", (0, (5, 1, 1, 1, 1, 1)), (0, (1, 3)))
FACET_COLOURS = ("#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02", "#a6761d", "#666666")


def facet_groups(points: Sequence[Point]) -> list[tuple[FacetValues, list[Point]]]:
    """The points grouped by their facet values, groups and points in sweep order."""
    groups: dict[FacetValues, list[Point]] = {}
    for p in points:
        groups.setdefault(p.facets, []).append(p)
    return list(groups.items())


def _row_has_facets(row: dict[str, Any], values: FacetValues) -> bool:
    """A summary row of this facet combination (JSON numbers compared as --set text)."""
    return all(k in row and format_value(row[k]) == format_value(v) for k, v in values)


def save_figure(fig: Figure, layout: ResultsLayout, experiment: Experiment, name: str) -> list[Path]:
    layout.figures_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for ext in ("png", "pdf"):
        path = layout.figure(experiment.name, name, ext)
        fig.savefig(path, dpi=150 if ext == "png" else None, bbox_inches="tight")
        paths.append(path)
    plt.close(fig)
    return paths


def _plain_log_ticks(axis: MplAxis) -> None:
    """Log axis labelled with plain numbers (0.05, 1, 20); minor ticks are
    labelled too when the axis spans less than a decade."""
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    axis.set_major_formatter(plain)
    lo, hi = sorted(axis.get_view_interval())
    axis.set_minor_formatter(plain if lo > 0 and hi / lo < 10 else NullFormatter())


def cell_done(cell: Cell | None) -> bool:
    return cell is not None and cell.status == "done" and cell.run_dir is not None


def run_curve(conn: sqlite3.Connection, cell: Cell, region: str, metric: str) -> list[tuple[float, float, float]]:
    """(time_s, metric, reference noise) of a run's images in one region, in time order."""
    return sorted(
        (m["time_s"], m[metric], m["floor_rel"] or 0.0)
        for m in index.metrics_of(conn, cell.key, cell.reference_key)
        if m["region"] == region and m["error"] is None and m["time_s"] and m[metric]
    )


def mean_curve(
    curves: list[list[tuple[float, float, float]]],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Replicates aligned by image index (the same snapshot schedule): mean
    time, mean value, smallest and largest value."""
    n = min(len(c) for c in curves)
    t = np.array([[c[i][0] for i in range(n)] for c in curves])
    v = np.array([[c[i][1] for i in range(n)] for c in curves])
    return t.mean(axis=0), v.mean(axis=0), v.min(axis=0), v.max(axis=0)


ERROR_PANEL_IN = (1.75, 1.5)  # one error-over-time panel, inches
ERROR_MAX_COLUMNS = 6


@dataclass(frozen=True)
class ErrorLayout:
    """Where each (region, point) panel of the error figure goes: with a
    numeric axis, a row per region and a column per axis value, the facets
    drawn as line styles in the same panel; without one, a row per facet
    combination and a column per region (wrapped at ERROR_MAX_COLUMNS)."""

    grid: figure_layout.Grid
    panels: dict[tuple[str, str], int]  # (region, point id) -> index into grid.cells
    column_titles: tuple[str, ...]  # over the top row
    row_labels: tuple[str, ...]  # left of each row
    line_styles: dict[str, Any]  # point id -> its facet's line style


def error_layout(experiment: Experiment, points: Sequence[Point], regions: Sequence[str]) -> ErrorLayout:
    groups = facet_groups(points)
    by_axis = experiment.axis is not None and max(len(pts) for _, pts in groups) > 1
    styles: dict[str, Any] = {}
    panels: dict[tuple[str, str], int] = {}
    if by_axis:
        values = sorted({p.axis_value for p in points})
        assert experiment.axis is not None
        grid = figure_layout.Grid(
            len(regions), len(values), tuple((r, c) for r in range(len(regions)) for c in range(len(values)))
        )
        for g_i, (_, pts) in enumerate(groups):
            for p in pts:
                styles[p.id] = FACET_LINE_STYLES[g_i % len(FACET_LINE_STYLES)] if len(groups) > 1 else "-"
                for r_i, region in enumerate(regions):
                    panels[(region, p.id)] = r_i * len(values) + values.index(p.axis_value)
        titles = tuple(f"{experiment.axis.label} = {v:g}" for v in values)
        rows = tuple(region_title(r) for r in regions)
        return ErrorLayout(grid, panels, titles, rows, styles)
    flat = [p for _, pts in groups for p in pts]
    grid = figure_layout.blocks(len(flat), len(regions), ERROR_MAX_COLUMNS)
    for p_i, p in enumerate(flat):
        styles[p.id] = "-"
        for r_i, region in enumerate(regions):
            panels[(region, p.id)] = p_i * len(regions) + r_i
    per_block = grid.rows // max(len(flat), 1)
    rows = tuple(
        point_title(experiment, flat[row // per_block]) if row % per_block == 0 else "" for row in range(grid.rows)
    )
    titles = tuple(region_title(r) for r in regions[: grid.columns])
    return ErrorLayout(grid, panels, titles if per_block == 1 else (), rows, styles)


def build_error_curves(experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection) -> Figure:
    """Error against render time, log-log (error_layout places the panels):
    the mean over replicates with their range."""
    metric = experiment.curve_metric
    regions = [LIT, *(r.name for r in experiment.insets), WHOLE_IMAGE]
    lay = error_layout(experiment, data.points, regions)
    w, h = ERROR_PANEL_IN
    fig = plt.figure(figsize=(w * lay.grid.columns + 0.6, h * lay.grid.rows + 1.0), layout="constrained")
    axes: Any = fig.subplots(lay.grid.rows, lay.grid.columns, squeeze=False)
    used = {lay.grid.cells[i] for i in lay.panels.values()}
    for r, c in np.ndindex(lay.grid.rows, lay.grid.columns):
        axes[r, c].set_visible((r, c) in used)
    floors: dict[int, float] = {}
    for (region, pid), i in lay.panels.items():
        point = next(p for p in data.points if p.id == pid)
        row, col = lay.grid.cells[i]
        ax = axes[row][col]
        for strategy in experiment.strategies:
            cells = [c for c in data.replicates.get((point.id, strategy), []) if cell_done(c)]
            curves = [c for c in (run_curve(conn, cell, region, metric) for cell in cells) if c]
            if not curves:
                continue
            t, v, lo, hi = mean_curve(curves)
            colour_ = strategy_colour(strategy, experiment.strategies)
            ax.plot(t, v, marker=".", ms=2, lw=1.0, ls=lay.line_styles[pid], color=colour_)
            if len(curves) > 1:
                ax.fill_between(t, lo, hi, color=colour_, alpha=0.15, lw=0)
            floors[i] = curves[0][0][2]
        if metric == "rel_mse" and floors.get(i):
            ax.axhline(floors[i], color="k", ls=":", lw=0.7)
    for r, c in used:
        ax = axes[r][c]
        ax.set_xscale("log")
        ax.set_yscale("log")
        if not lay.column_titles:
            i = lay.grid.cells.index((r, c))
            ax.set_title(region_title(regions[i % len(regions)]), fontsize=7)
        elif r == 0:
            ax.set_title(lay.column_titles[c], fontsize=7)
        if r == lay.grid.rows - 1 or (r + 1, c) not in used:
            ax.set_xlabel("render time (s)", fontsize=7)
        if c == 0:
            label = lay.row_labels[r]
            text, size = figure_layout.fit_text(label, h * 72 * 0.95, 7, max_lines=3) if label else ("", 7)
            ax.set_ylabel(f"{text}\n{METRIC_LABELS[metric]}" if text else METRIC_LABELS[metric], fontsize=size)
        ax.grid(True, which="both", alpha=0.2)
        _plain_log_ticks(ax.xaxis)
        _plain_log_ticks(ax.yaxis)
        ax.tick_params(which="both", labelsize=6)
    handles = _strategy_handles(experiment, data)
    if metric == "rel_mse":
        handles.append((Line2D([], [], color="k", ls=":", lw=0.7), "reference noise"))
    groups = facet_groups(data.points)
    if experiment.axis is not None and len(groups) > 1 and any(len(pts) > 1 for _, pts in groups):
        for g_i, (values, _) in enumerate(groups):
            style = FACET_LINE_STYLES[g_i % len(FACET_LINE_STYLES)]
            handles.append((Line2D([], [], color="k", lw=1.0, ls=style), facets.labels(values)))
    fig.legend(
        [h_ for h_, _ in handles],
        [lab for _, lab in handles],
        loc="outside lower center",
        ncol=figure_layout.legend_columns([lab for _, lab in handles], fig.get_figwidth(), 7),
        fontsize=7,
        frameon=False,
    )
    reps = experiment.budget.replicates if experiment.budget else 1
    title = (
        f"{experiment.name}: {METRIC_LABELS[metric]} over time (mean of {reps} replicate"
        f"{'s' if reps > 1 else ''}{', band: their range' if reps > 1 else ''})"
    )
    text, size = figure_layout.fit_text(title, fig.get_figwidth() * 72 * 0.95, 9, max_lines=2)
    fig.suptitle(text, fontsize=size)
    return fig


def _strategy_handles(experiment: Experiment, data: ExperimentData) -> list[tuple[Any, str]]:
    """A legend entry (solid line in its colour) per strategy that has a run."""
    present = {s for _, s in data.replicates}
    return [
        (Line2D([], [], color=strategy_colour(s, experiment.strategies), lw=1.2, marker="."), strategy_label(s))
        for s in experiment.strategies
        if s in present
    ]


def figure_error_curves(
    experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection, layout: ResultsLayout
) -> list[Path]:
    return save_figure(build_error_curves(experiment, data, conn), layout, experiment, "error_time")


def _legend_below(fig: Figure, axes: Any, rows: int, extra: Sequence[tuple[Any, str]] = ()) -> None:
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    for h, lab in extra:
        handles.append(h)
        labels.append(lab)
    fig.legend(
        handles,
        labels,
        loc="lower center",
        ncol=min(len(labels), 7),
        fontsize=8,
        frameon=False,
        bbox_to_anchor=(0.5, -0.02 - 0.02 * rows),
    )


def region_title(region: str) -> str:
    if region == WHOLE_IMAGE:
        return "whole image"
    if region == LIT:
        return "lit pixels"
    if region in exr.REGION_CLASSES:
        return class_style.class_label(region)
    return f"inset {region}"


@dataclass(frozen=True)
class Chosen:
    image: Path
    time_s: float
    rel_mse: dict[str, float | None]


def choose_image(conn: sqlite3.Connection, cell: Cell, time_s: float) -> Chosen | None:
    """The run's last image rendered within `time_s` (the earliest if none is)."""
    assert cell.run_dir is not None
    rows = [m for m in index.metrics_of(conn, cell.key, cell.reference_key) if m["error"] is None]
    times = sorted({m["time_s"] for m in rows})
    if not times:
        return None
    within = [t for t in times if t <= time_s * (1 + 1e-6)]
    chosen_t = within[-1] if within else times[0]
    at = [m for m in rows if m["time_s"] == chosen_t]
    image = next((m["image"] for m in at if m["is_final"]), at[0]["image"])
    return Chosen(cell.run_dir / image, chosen_t, {m["region"]: m["rel_mse"] for m in at if m["image"] == image})


def equal_time(experiment: Experiment, conn: sqlite3.Connection, data: ExperimentData, point: Point) -> float:
    """The configured comparison time, else the shortest final time of the point's runs."""
    if experiment.equal_time_s is not None:
        return experiment.equal_time_s
    finals = []
    for strategy in experiment.strategies:
        cell = data.runs.get((point.id, strategy))
        if cell_done(cell):
            assert cell is not None
            row = index.run_row(conn, cell.key)
            if row is not None and row["final_time_s"]:
                finals.append(float(row["final_time_s"]))
    return min(finals) if finals else math.inf


def reference_groups(data: ExperimentData) -> list[list[Point]]:
    """Consecutive points measured against the same reference image (facets
    that only change how the image is sampled share one): the insets figure
    draws each such reference once."""
    groups: list[list[Point]] = []
    last: str | None = None
    for p in data.points:
        cell = data.references.get(p.id)
        key = cell.key if cell is not None else None
        if groups and key is not None and key == last:
            groups[-1].append(p)
        else:
            groups.append([p])
        last = key
    return groups


INSET_CELL_IN = 1.0  # width of one inset column, inches
INSET_LABEL_IN = 0.22  # the relMSE line under an inset


def build_insets(experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection) -> Figure:
    """Per reference (shared by the points of reference_groups): the image
    with the insets drawn and its region classes, once; beside it, per
    point, each inset of the reference and of every strategy at equal time,
    relMSE under it."""
    regions: tuple[Region, ...] = experiment.insets or (Region(WHOLE_IMAGE, 0, 0, experiment.width, experiment.height),)
    n_sub = len(regions)
    columns = ["reference", *experiment.strategies]
    cell_in, label_in = INSET_CELL_IN, INSET_LABEL_IN
    inset_h = cell_in * max(r.height / r.width for r in regions)
    block_h = n_sub * (inset_h + label_in)  # one point's insets
    ref_w = block_h * experiment.width / experiment.height
    gap_in, header_in, label_col_in = 0.3, 0.45, 0.35
    insets_w = cell_in * len(columns) * 1.06
    width = 2 * ref_w * 1.05 + label_col_in + insets_w + 0.2
    height = len(data.points) * (block_h + gap_in) + header_in + 0.6
    fig = plt.figure(figsize=(width, height))
    outer = fig.add_gridspec(
        len(data.points),
        3,
        width_ratios=[2 * ref_w * 1.05, label_col_in, insets_w],
        wspace=0.0,
        hspace=gap_in / block_h,
        left=0.1 / width,
        right=1 - 0.1 / width,
        top=1 - header_in / height,
        bottom=0.5 / height,
    )
    row_of = {p.id: i for i, p in enumerate(data.points)}
    headers_done = False
    for group in reference_groups(data):
        first, last = row_of[group[0].id], row_of[group[-1].id]
        ref_cell = data.references.get(group[0].id)
        if len(group) < 4:
            left = outer[first : last + 1, 0].subgridspec(1, 2, wspace=0.05)
            ref_ax, class_ax = fig.add_subplot(left[0, 0]), fig.add_subplot(left[0, 1])
        else:
            # Beside four or more points' insets: the two images stacked, larger, from the top.
            k = min(2, len(group) // 2)  # blocks per image: at most the column's width allows
            left = outer[first : last + 1, 0].subgridspec(len(group), 1, hspace=0.15)
            ref_ax, class_ax = fig.add_subplot(left[0:k, 0]), fig.add_subplot(left[k : 2 * k, 0])
        for ax_ in (ref_ax, class_ax):
            ax_.set_xticks([])
            ax_.set_yticks([])
            ax_.set_anchor("N")
        if len(group) > 1:
            ref_ax.set_ylabel(f"one reference for the {len(group)} points beside it", fontsize=7)
        if first == 0 or len(group) > 1:
            ref_ax.set_title("reference", fontsize=8)
            class_ax.set_title("antishadow region classes", fontsize=8)
        if not cell_done(ref_cell):
            ref_ax.text(0.5, 0.5, "reference\nmissing", ha="center", va="center", fontsize=8)
            continue
        assert ref_cell is not None and ref_cell.run_dir is not None
        try:
            reference = exr.read_snapshot(RunLayout(ref_cell.run_dir).final)
        except CorruptExrError as e:
            ref_ax.text(0.5, 0.5, f"reference\nunreadable\n{e.reason[:40]}", ha="center", va="center", fontsize=6)
            continue
        exposure = display.exposure_from_reference(reference.rgb)
        ref_ax.imshow(display.to_display(reference.rgb, exposure), interpolation="nearest")
        _draw_classes(class_ax, reference)
        for r_i, region in enumerate(regions):
            colour_ = INSET_COLOURS[r_i % len(INSET_COLOURS)]
            for ax_ in (ref_ax, class_ax):
                ax_.add_patch(
                    Rectangle(
                        (region.x - 0.5, region.y - 0.5), region.width, region.height, fill=False, ec=colour_, lw=1.2
                    )
                )
        for g_i, point in enumerate(group):
            grid = outer[row_of[point.id], 2].subgridspec(n_sub, len(columns), wspace=0.06, hspace=label_in / inset_h)
            t_eq = equal_time(experiment, conn, data, point)
            label = point_title(experiment, point) + (f" (strategies at {t_eq:.3g} s)" if math.isfinite(t_eq) else "")
            box = outer[row_of[point.id], 1].get_position(fig)
            text, size = figure_layout.fit_text(label, block_h * 72 * 0.95, 8, max_lines=2)
            fig.text(box.x1, (box.y0 + box.y1) / 2, text, rotation=90, ha="right", va="center", fontsize=size)
            for c_i, column in enumerate(columns):
                if column == "reference" and g_i > 0:
                    continue  # the same reference insets as the group's first point
                image, values, label_time, missing = _column_image(conn, data, point, column, t_eq, reference)
                for r_i, region in enumerate(regions):
                    ax = fig.add_subplot(grid[r_i, c_i])
                    ax.set_xticks([])
                    ax.set_yticks([])
                    for spine in ax.spines.values():
                        spine.set_edgecolor(INSET_COLOURS[r_i % len(INSET_COLOURS)])
                        spine.set_linewidth(1.2)
                    if image is None:
                        ax.set_facecolor("#dddddd")
                        ax.text(0.5, 0.5, missing, ha="center", va="center", fontsize=7, transform=ax.transAxes)
                        continue
                    ax.imshow(display.to_display(crop(image, region), exposure), interpolation="nearest")
                    value = values.get(region.name)
                    text_ = label_time if column == "reference" else (f"{value:.3g}" if value is not None else "-")
                    ax.set_xlabel(text_, fontsize=7, labelpad=1.5)
            if not headers_done:
                _column_headers(fig, grid, columns, height)
                headers_done = True
    fig.legend(
        handles=class_style.legend_handles(exr.REGION_CLASSES),
        loc="lower center",
        ncol=4,
        fontsize=7,
        frameon=False,
        bbox_to_anchor=(0.5, 0.0),
    )
    title = f"{experiment.name}: insets at equal render time (relMSE under each inset)"
    text, size = figure_layout.fit_text(title, width * 72 * 0.95, 10, max_lines=2)
    fig.suptitle(text, fontsize=size, y=1 - 0.05 / height, va="top")
    return fig


def _column_headers(fig: Figure, grid: Any, columns: Sequence[str], height_in: float) -> None:
    """The column names over the inset columns, each broken into lines (or
    made smaller) so that it fits its own column: long strategy names never
    run into their neighbours."""
    for c_i, column in enumerate(columns):
        box = grid[0, c_i].get_position(fig)
        width_pt = box.width * fig.get_figwidth() * 72 * 0.98
        text, size = figure_layout.fit_text(strategy_label(column), width_pt, 8, max_lines=3)
        fig.text((box.x0 + box.x1) / 2, box.y1 + 0.04 / height_in, text, ha="center", va="bottom", fontsize=size)


def _column_image(
    conn: sqlite3.Connection,
    data: ExperimentData,
    point: Point,
    column: str,
    t_eq: float,
    reference: exr.Snapshot,
) -> tuple[np.ndarray | None, dict[str, float | None], str, str]:
    """(image, relMSE by region, time label, why missing) of one inset column."""
    if column == "reference":
        return reference.rgb, {}, f"{reference.header.spp} spp", ""
    cell = data.runs.get((point.id, column))
    if not cell_done(cell):
        return None, {}, "", cell.status if cell and cell.status else "missing"
    assert cell is not None
    chosen = choose_image(conn, cell, t_eq)
    if chosen is None:
        return None, {}, "", "no image"
    try:
        return exr.read_snapshot(chosen.image).rgb, chosen.rel_mse, f"{chosen.time_s:.2g} s", ""
    except CorruptExrError:
        return None, {}, "", "unreadable"


def figure_insets(
    experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection, layout: ResultsLayout
) -> list[Path]:
    return save_figure(build_insets(experiment, data, conn), layout, experiment, "insets")


def _draw_classes(ax: Any, reference: exr.Snapshot) -> None:
    """The region class holding the majority of each pixel's primary hits (the renderer's AOV)."""
    if reference.regions is None:
        ax.text(0.5, 0.5, "no region AOV", ha="center", va="center", fontsize=7, transform=ax.transAxes)
        return
    class_style.draw_class_map(ax, reference.regions, exr.REGION_CLASSES)


def _summary_regions(data: ExperimentData) -> list[str]:
    """Regions in report order that the summary has rows for: image, lit, insets, classes."""
    found: list[str] = []
    for r in data.summary:
        if r["region"] not in found:
            found.append(r["region"])
    return found


def _draw_value(
    ax: Any, x: float, r: dict[str, Any], column: str, se_column: str, bound_column: str, colour_: str
) -> None:
    """One summary value: its error bar (one standard error) and a marker,
    open triangles where it is only a bound (up: lower, down: upper)."""
    se = r.get(se_column)
    bounded = bool(r.get(bound_column))
    if isinstance(se, (int, float)) and math.isfinite(se) and se > 0:
        lo = max(r[column] - se, r[column] * 1e-3)
        ax.errorbar([x], [r[column]], yerr=[[r[column] - lo], [se]], color=colour_, lw=0.9, capsize=2, ls="none")
    marker = {"lower": "^", "upper": "v"}.get(r.get(bound_column) or "", "D" if bounded else "o")
    ax.plot(
        [x],
        [r[column]],
        ls="none",
        marker=marker,
        ms=5 if bounded else 4,
        mfc="white" if bounded else colour_,
        color=colour_,
    )


EFFICIENCY_MAX_COLUMNS = 5


def build_efficiency(experiment: Experiment, data: ExperimentData) -> Figure:
    """Efficiency relative to light sampling (top row) and equal-error
    speed-up (bottom row) against the swept axis, one column per region,
    from the tidy summary; error bars of one standard error over replicates,
    open triangles for bounds. Facets: a line style each (colour: the
    strategy); without an axis, the strategies along x and a colour per
    facet value."""
    regions = _summary_regions(data)
    groups = [values for values, _ in facet_groups(data.points)]
    measures = (
        ("efficiency_vs_light", "efficiency_vs_light_stderr", "bound", "efficiency relative to light"),
        ("speedup_equal_error", "speedup_equal_error_stderr", "speedup_bound", "speed-up at light's final error"),
    )
    grid = figure_layout.blocks(len(measures), len(regions), EFFICIENCY_MAX_COLUMNS)
    _, h = figure_layout.panel_size(grid.columns, aspect=0.85)
    labels_in = 0.6 * len(measures) if experiment.axis is None else 0.0  # strategy names under the x axes
    fig = plt.figure(figsize=(figure_layout.PAGE_WIDTH_IN, h * grid.rows + 1.3 + labels_in), layout="constrained")
    axes: Any = fig.subplots(grid.rows, grid.columns, squeeze=False)
    for ax in axes.flat:
        ax.set_visible(False)
    for m_i, (column, se_column, bound_column, label) in enumerate(measures):
        for r_i, region in enumerate(regions):
            row, col = grid.cells[m_i * len(regions) + r_i]
            ax = axes[row][col]
            ax.set_visible(True)
            for s_i, strategy in enumerate(experiment.strategies):
                for g_i, values in enumerate(groups):
                    rows = sorted(
                        (
                            r
                            for r in data.summary
                            if r["region"] == region
                            and r["strategy"] == strategy
                            and _row_has_facets(r, values)
                            and isinstance(r.get(column), (int, float))
                            and r[column] > 0
                        ),
                        key=lambda r: r["axis"] if isinstance(r.get("axis"), (int, float)) else 0.0,
                    )
                    if not rows:
                        continue
                    if experiment.axis is None:
                        # Strategies along x, the facet values side by side in their colours.
                        colour_ = FACET_COLOURS[g_i % len(FACET_COLOURS)]
                        x = s_i + (g_i - (len(groups) - 1) / 2) * 0.7 / max(len(groups), 1)
                        for r in rows:
                            _draw_value(ax, x, r, column, se_column, bound_column, colour_)
                        continue
                    colour_ = strategy_colour(strategy, experiment.strategies)
                    style = FACET_LINE_STYLES[g_i % len(FACET_LINE_STYLES)]
                    ax.plot(
                        [r["axis"] for r in rows],
                        [r[column] for r in rows],
                        lw=1.0,
                        ls=style,
                        color=colour_,
                    )
                    for r in rows:
                        _draw_value(ax, r["axis"], r, column, se_column, bound_column, colour_)
            ax.set_yscale("log")
            # The x labels only under the last panel of each column of a measure's block.
            bottom = r_i >= len(regions) - grid.columns
            if experiment.axis is None:
                ax.set_xticks(range(len(experiment.strategies)))
                ax.set_xticklabels(
                    [strategy_label(s) for s in experiment.strategies] if bottom else [],
                    rotation=35,
                    ha="right",
                    fontsize=6,
                )
                ax.set_xlim(-0.6, len(experiment.strategies) - 0.4)
            else:
                ax.set_xscale("log")
                if bottom:
                    ax.set_xlabel(experiment.axis.label, fontsize=7)
                ax.set_xticks(sorted({p.axis_value for p in data.points}))
                ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
                ax.xaxis.set_minor_formatter(NullFormatter())
            if col == 0:
                text, size = figure_layout.fit_text(label, h * 72 * 0.9, 7, max_lines=2)
                ax.set_ylabel(text, fontsize=size)
            ax.set_title(region_title(region), fontsize=7)
            ax.grid(True, which="both", alpha=0.2)
            ax.axhline(1.0, color="k", lw=0.6, alpha=0.5)
            _plain_log_ticks(ax.yaxis)
            ax.tick_params(which="both", labelsize=6)
    extra: list[tuple[Any, str]] = []
    if len(groups) > 1 or (groups and groups[0]):
        for g_i, values in enumerate(groups):
            handle = (
                Line2D([], [], ls="none", marker="o", ms=6, color=FACET_COLOURS[g_i % len(FACET_COLOURS)])
                if experiment.axis is None
                else Line2D([], [], color="k", lw=1.3, ls=FACET_LINE_STYLES[g_i % len(FACET_LINE_STYLES)])
            )
            extra.append((handle, facets.labels(values)))
    extra += [
        (Line2D([], [], ls="none", marker="^", ms=6, mfc="white", color="k"), "lower bound"),
        (Line2D([], [], ls="none", marker="v", ms=6, mfc="white", color="k"), "upper bound"),
    ]
    handles = ([] if experiment.axis is None else _strategy_handles(experiment, data)) + extra
    fig.legend(
        [h_ for h_, _ in handles],
        [lab for _, lab in handles],
        loc="outside lower center",
        ncol=figure_layout.legend_columns([lab for _, lab in handles], figure_layout.PAGE_WIDTH_IN, 7),
        fontsize=7,
        frameon=False,
    )
    reps = experiment.budget.replicates if experiment.budget else 1
    title = (
        f"{experiment.name}: efficiency 1/(relMSE x time) and equal-error speed-up relative to light "
        f"sampling (reference noise removed; bars: one standard error over {reps} replicates)"
    )
    text, size = figure_layout.fit_text(title, figure_layout.PAGE_WIDTH_IN * 72 * 0.95, 8, max_lines=2)
    fig.suptitle(text, fontsize=size)
    return fig


def figure_efficiency(
    experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection, layout: ResultsLayout
) -> list[Path]:
    return save_figure(build_efficiency(experiment, data), layout, experiment, "efficiency")


def make_all(experiment: Experiment, layout: ResultsLayout) -> list[Path]:
    conn = index.connect(layout.index_path)
    try:
        data = load(experiment, conn, layout)
        # The tables first: they need no image and are the cheapest output.
        paths = [
            tables.write(
                layout.summary_csv(experiment.name).with_name("summary.tex"),
                experiment.name,
                data.summary,
                experiment.facets,
                experiment.axis.label if experiment.axis is not None else None,
            )
        ]
        paths += figure_error_curves(experiment, data, conn, layout)
        paths += figure_insets(experiment, data, conn, layout)
        paths += figure_efficiency(experiment, data, conn, layout)
        # Imported here: region_figures builds on this module's helpers.
        from portal_harness.region_figures import figure_regions

        paths += figure_regions(experiment, data, conn, layout)
        from portal_harness.gain_figure import figure as figure_gain

        paths += figure_gain(experiment, layout)
    finally:
        conn.close()
    return paths
