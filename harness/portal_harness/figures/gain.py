"""How much of a strategy's gain survives once indirect light is included:
the efficiency relative to light sampling of one strategy with the direct
integrator (another experiment's stored summary, figures.compare) and with
this experiment's (path), per ratio and region, and the surviving fraction

    survival = (E_path / E_light,path) / (E_direct / E_light,direct),

with its standard error propagated from the two summaries' standard errors
(independent runs: relative errors add in quadrature). Every number comes
from the two summary.json files; nothing is typed in.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, NullFormatter

from portal_harness.core.errors import HarnessError
from portal_harness.core.metrics import WHOLE_IMAGE
from portal_harness.core.paths import ResultsLayout
from portal_harness.core.regions import LIT
from portal_harness.experiment.model import Experiment
from portal_harness.figures import layout as figure_layout
from portal_harness.figures.style import save_figure


@dataclass(frozen=True)
class Gain:
    region: str
    axis: float
    direct: float
    direct_se: float
    path: float
    path_se: float

    @property
    def survival(self) -> float:
        return self.path / self.direct if self.direct > 0 else math.nan

    @property
    def survival_se(self) -> float:
        if not (self.direct > 0 and self.path > 0):
            return math.nan
        return self.survival * math.hypot(self.direct_se / self.direct, self.path_se / self.path)


def _values(rows: list[dict[str, Any]], strategy: str) -> dict[tuple[str, float], tuple[float, float]]:
    out = {}
    for r in rows:
        value, se, axis = r.get("efficiency_vs_light"), r.get("efficiency_vs_light_stderr"), r.get("axis")
        if r.get("strategy") != strategy or not isinstance(value, (int, float)) or not isinstance(axis, (int, float)):
            continue
        out[(str(r["region"]), round(float(axis), 9))] = (
            float(value),
            float(se) if isinstance(se, (int, float)) else math.nan,
        )
    return out


def gains(direct_rows: list[dict[str, Any]], path_rows: list[dict[str, Any]], strategy: str) -> list[Gain]:
    """The ratios and regions both summaries have, in the path summary's order."""
    direct, path = _values(direct_rows, strategy), _values(path_rows, strategy)
    return [
        Gain(region, axis, *direct[(region, axis)], *path[(region, axis)])
        for region, axis in path
        if (region, axis) in direct
    ]


# The summary.csv columns the comparison reads as numbers.
_NUMERIC = ("axis", "efficiency_vs_light", "efficiency_vs_light_stderr")


def _csv_rows(path: Path) -> list[dict[str, Any]]:
    """The rows of a summary.csv, the numeric columns as floats (empty
    cells stay strings, which _values skips)."""
    rows: list[dict[str, Any]] = []
    with path.open(newline="") as f:
        for row in csv.DictReader(f):
            out: dict[str, Any] = dict(row)
            for key in _NUMERIC:
                with contextlib.suppress(KeyError, TypeError, ValueError):
                    out[key] = float(row[key])
            rows.append(out)
    return rows


def _rows(layout: ResultsLayout, name: str) -> list[dict[str, Any]]:
    """The other experiment's summary rows: its summary.json, or, where only
    the committed summary.csv is there (a FULL experiment run alone in a
    fresh clone, whose partner ran on another machine), that."""
    try:
        rows: list[dict[str, Any]] = json.loads(layout.summary_json(name).read_text())["rows"]
        return rows
    except (OSError, ValueError, KeyError):
        pass
    try:
        return _csv_rows(layout.summary_csv(name))
    except (OSError, csv.Error, UnicodeDecodeError):
        raise HarnessError(f"figures.compare: no summary of experiment {name!r}: run its sweep first") from None


def caption(found: list[Gain], region: str, strategy: str, label: str) -> str:
    lines = [f"{strategy}, efficiency relative to light in {region}: direct -> path (share of the gain that survives)"]
    for g in sorted((g for g in found if g.region == region), key=lambda g: g.axis):
        lines.append(
            f"{label} {g.axis:g}: {g.direct:.3g} ± {g.direct_se:.2g} -> {g.path:.3g} ± {g.path_se:.2g} "
            f"({g.survival:.2g} ± {g.survival_se:.2g})"
        )
    return "\n".join(lines)


def build(experiment: Experiment, layout: ResultsLayout) -> Figure | None:
    if experiment.compare is None or experiment.axis is None:
        return None
    other, strategy = experiment.compare
    path_rows = json.loads(layout.summary_json(experiment.name).read_text())["rows"]
    found = gains(_rows(layout, other), path_rows, strategy)
    if not found:
        raise HarnessError(f"figures.compare: {other} and {experiment.name} share no ratio of {strategy}")
    regions = [r for r in [WHOLE_IMAGE, LIT, *(i.name for i in experiment.insets)] if any(g.region == r for g in found)]
    grid = figure_layout.wrapped(len(regions), 5)
    _, h = figure_layout.panel_size(grid.columns, aspect=0.9)
    text = caption(found, LIT, strategy, experiment.axis.label)
    fig = plt.figure(
        figsize=(figure_layout.PAGE_WIDTH_IN, h * grid.rows + 1.2 + 0.14 * text.count("\n")), layout="constrained"
    )
    axes: Any = fig.subplots(grid.rows, grid.columns, squeeze=False)
    for ax in axes.flat:
        ax.set_visible(False)
    for region, (row, col) in zip(regions, grid.cells, strict=False):
        ax = axes[row, col]
        ax.set_visible(True)
        mine = sorted((g for g in found if g.region == region), key=lambda g: g.axis)
        x = [g.axis for g in mine]
        for values, ses, name, style in (
            ([g.direct for g in mine], [g.direct_se for g in mine], f"direct ({other})", "o-"),
            ([g.path for g in mine], [g.path_se for g in mine], f"path ({experiment.name})", "s--"),
        ):
            yerr = [
                [min(s, v * 0.999) if math.isfinite(s) else 0 for v, s in zip(values, ses, strict=True)],
                [s if math.isfinite(s) else 0 for s in ses],
            ]
            ax.errorbar(
                x,
                values,
                yerr=yerr,
                fmt=style,
                ms=3,
                lw=1.0,
                capsize=2,
                color="#9467bd" if "o" in style else "#2ca02c",
                label=name,
            )
        ax.axhline(1.0, color="k", lw=0.6, alpha=0.5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(x)
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.set_title(
            region if region not in (WHOLE_IMAGE, LIT) else {WHOLE_IMAGE: "whole image", LIT: "lit pixels"}[region],
            fontsize=7,
        )
        ax.set_xlabel(experiment.axis.label, fontsize=7)
        if col == 0:
            ax.set_ylabel(f"{strategy}\nefficiency relative to light", fontsize=7)
        ax.tick_params(which="both", labelsize=6)
        ax.grid(True, which="both", alpha=0.2)
    title = f"{experiment.name}: how much of {strategy}'s gain over light survives with indirect light"
    t, size = figure_layout.fit_text(title, figure_layout.PAGE_WIDTH_IN * 72 * 0.95, 9, max_lines=2)
    fig.suptitle(t, fontsize=size)
    # Legend and caption below the canvas (the figure is saved with a tight
    # box), out of the layout: inside a panel the legend covered its curves.
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncols=2, fontsize=7, frameon=False)
    fig.text(0.01, -0.07, text, fontsize=6.5, family="monospace", va="top", ha="left", transform=fig.transFigure)
    return fig


def figure(experiment: Experiment, layout: ResultsLayout) -> list[Path]:
    fig = build(experiment, layout)
    return [] if fig is None else save_figure(fig, layout, experiment, "direct_vs_path")
