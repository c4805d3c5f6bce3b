"""What every figure draws alike: strategy colours and labels, facet line
styles, point and region titles, log ticks, the legend below, and saving a
figure as PNG and PDF in results/figures/."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
from matplotlib.axis import Axis as MplAxis
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, NullFormatter

from portal_harness.core import class_style, exr
from portal_harness.core.metrics import WHOLE_IMAGE
from portal_harness.core.paths import ResultsLayout
from portal_harness.core.regions import LIT
from portal_harness.experiment import facets
from portal_harness.experiment.model import Experiment, Point
from portal_harness.experiment.spec import format_value
from portal_harness.figures.data import ExperimentData

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


def row_has_facets(row: dict[str, Any], values: FacetValues) -> bool:
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


def plain_log_ticks(axis: MplAxis) -> None:
    """Log axis labelled with plain numbers (0.05, 1, 20); minor ticks are
    labelled too when the axis spans less than a decade."""
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    axis.set_major_formatter(plain)
    lo, hi = sorted(axis.get_view_interval())
    axis.set_minor_formatter(plain if lo > 0 and hi / lo < 10 else NullFormatter())


def strategy_handles(experiment: Experiment, data: ExperimentData) -> list[tuple[Any, str]]:
    """A legend entry (solid line in its colour) per strategy that has a run."""
    present = {s for _, s in data.replicates}
    return [
        (Line2D([], [], color=strategy_colour(s, experiment.strategies), lw=1.2, marker="."), strategy_label(s))
        for s in experiment.strategies
        if s in present
    ]


def legend_below(fig: Figure, axes: Any, rows: int, extra: Sequence[tuple[Any, str]] = ()) -> None:
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
