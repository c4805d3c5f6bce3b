"""Figure: efficiency relative to light sampling against the swept axis (the
light/portal ratio), one panel per region (image, lit, insets, region classes),
error bars of one standard error over replicates, open triangles where the value
is only a lower bound; below it, the equal-error speed-up in the same layout.
With `precision:`, a headline value short of its precision target is
circled in grey (analysis/precision.py).
Facets are line styles; an experiment without an axis has the strategies along
x and a colour per facet value."""

from __future__ import annotations

import math
import sqlite3
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, NullFormatter

from portal_harness.analysis import precision
from portal_harness.core.paths import ResultsLayout
from portal_harness.experiment import facets
from portal_harness.experiment.model import Experiment
from portal_harness.figures import layout as figure_layout
from portal_harness.figures.data import ExperimentData
from portal_harness.figures.style import (
    FACET_COLOURS,
    FACET_LINE_STYLES,
    facet_groups,
    plain_log_ticks,
    region_title,
    row_has_facets,
    save_figure,
    strategy_colour,
    strategy_handles,
    strategy_label,
)


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
    if precision.unreached(r, column):
        ax.plot([x], [r[column]], ls="none", marker="o", ms=10, mfc="none", mec=UNREACHED_COLOUR, mew=1.2)


UNREACHED_COLOUR = "0.45"
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
                            and row_has_facets(r, values)
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
            plain_log_ticks(ax.yaxis)
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
    if any(precision.unreached(r, m[0]) for r in data.summary for m in measures):
        target = next(r["precision_target"] for r in data.summary if r.get("precision_target") is not None)
        extra.append(
            (
                Line2D([], [], ls="none", marker="o", ms=9, mfc="none", mec=UNREACHED_COLOUR, mew=1.2),
                f"rel. SE above its target {target:g}",
            )
        )
    handles = ([] if experiment.axis is None else strategy_handles(experiment, data)) + extra
    fig.legend(
        [h_ for h_, _ in handles],
        [lab for _, lab in handles],
        loc="outside lower center",
        ncol=figure_layout.legend_columns([lab for _, lab in handles], figure_layout.PAGE_WIDTH_IN, 7),
        fontsize=7,
        frameon=False,
    )
    counts = sorted({int(r["replicates"]) for r in data.summary if isinstance(r.get("replicates"), int)})
    if experiment.precision is not None and counts:
        reps_text = f"{counts[0]}" if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
    else:
        reps_text = str(experiment.budget.replicates if experiment.budget else 1)
    title = (
        f"{experiment.name}: efficiency 1/(relMSE x time) and equal-error speed-up relative to light "
        f"sampling (reference noise removed; bars: one standard error over {reps_text} replicates)"
    )
    text, size = figure_layout.fit_text(title, figure_layout.PAGE_WIDTH_IN * 72 * 0.95, 8, max_lines=2)
    fig.suptitle(text, fontsize=size)
    return fig


def figure_efficiency(
    experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection, layout: ResultsLayout
) -> list[Path]:
    return save_figure(build_efficiency(experiment, data), layout, experiment, "efficiency")
