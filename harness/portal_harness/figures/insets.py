"""Figure: insets. Per sweep point, the reference with the inset rectangles
drawn and its antishadow region classes beside it, then each inset of the
reference and of each strategy at equal render time (replicate 0), with its
relMSE under it."""

from __future__ import annotations

import math
import sqlite3
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from portal_harness.core import class_style, display, exr
from portal_harness.core.errors import CorruptExrError
from portal_harness.core.metrics import WHOLE_IMAGE, Region, crop
from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.experiment.model import Experiment, Point
from portal_harness.figures import layout as figure_layout
from portal_harness.figures.data import (
    ExperimentData,
    cell_done,
    choose_image,
    equal_time,
    reference_groups,
    times_agree,
)
from portal_harness.figures.style import INSET_COLOURS, point_title, save_figure, strategy_label

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
            shown = {c: _column_image(conn, data, point, c, t_eq, reference) for c in columns}
            times = [t for c, (_, _, t, _) in shown.items() if c != "reference" and t is not None]
            label = point_title(experiment, point) + (f" (strategies at {t_eq:.2f} s)" if math.isfinite(t_eq) else "")
            if not times_agree(times):
                label += f" UNEQUAL TIMES {min(times):.2f}-{max(times):.2f} s"
            box = outer[row_of[point.id], 1].get_position(fig)
            text, size = figure_layout.fit_text(label, block_h * 72 * 0.95, 8, max_lines=2)
            fig.text(box.x1, (box.y0 + box.y1) / 2, text, rotation=90, ha="right", va="center", fontsize=size)
            for c_i, column in enumerate(columns):
                if column == "reference" and g_i > 0:
                    continue  # the same reference insets as the group's first point
                image, values, time_s, missing = shown[column]
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
                    if column == "reference":
                        text_ = f"{reference.header.spp} spp"
                    else:
                        text_ = f"{value:.3g}" if value is not None else "-"
                        if r_i == len(regions) - 1 and time_s is not None:
                            text_ += f" at {time_s:.2f} s"  # the time of the image the column shows
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
) -> tuple[np.ndarray | None, dict[str, float | None], float | None, str]:
    """(image, relMSE by region, the image's render time, why missing) of one inset column."""
    if column == "reference":
        return reference.rgb, {}, None, ""
    cell = data.runs.get((point.id, column))
    if not cell_done(cell):
        return None, {}, None, cell.status if cell and cell.status else "missing"
    assert cell is not None
    chosen = choose_image(conn, cell, t_eq)
    if chosen is None:
        return None, {}, None, "no image"
    try:
        return exr.read_snapshot(chosen.image).rgb, chosen.rel_mse, chosen.time_s, ""
    except CorruptExrError:
        return None, {}, chosen.time_s, "unreadable"


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
