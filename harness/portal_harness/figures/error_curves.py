"""Figure: error over time, log-log, one line per strategy (the mean over
replicates, a band from the smallest to the largest replicate), one panel per
sweep point, for the `lit` region, the insets and the whole image; with facets
(categorical sweep keys, facets.py), one block of rows per facet value."""

from __future__ import annotations

import sqlite3
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from portal_harness.core.metrics import WHOLE_IMAGE
from portal_harness.core.paths import ResultsLayout
from portal_harness.core.regions import LIT
from portal_harness.experiment import facets
from portal_harness.experiment.model import Experiment, Point
from portal_harness.figures import layout as figure_layout
from portal_harness.figures.data import ExperimentData, cell_done, mean_curve, run_curve
from portal_harness.figures.style import (
    FACET_LINE_STYLES,
    METRIC_LABELS,
    facet_groups,
    plain_log_ticks,
    point_title,
    region_title,
    save_figure,
    strategy_colour,
    strategy_handles,
)

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
        plain_log_ticks(ax.xaxis)
        plain_log_ticks(ax.yaxis)
        ax.tick_params(which="both", labelsize=6)
    handles = strategy_handles(experiment, data)
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


def figure_error_curves(
    experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection, layout: ResultsLayout
) -> list[Path]:
    return save_figure(build_error_curves(experiment, data, conn), layout, experiment, "error_time")
