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

from portal_harness import class_style, display, exr, facets, index, tables
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


def figure_error_curves(
    experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection, layout: ResultsLayout
) -> list[Path]:
    """Error against render time, log-log: one column per sweep point, one
    row per region (lit, each inset, whole image); mean over replicates with
    their range."""
    metric = experiment.curve_metric
    regions = [LIT, *(r.name for r in experiment.insets), WHOLE_IMAGE]
    groups = facet_groups(data.points)
    # One block of rows (one per region) per facet combination, its points across.
    panels = [(region, point, i) for _, pts in groups for region in regions for i, point in enumerate(pts)]
    n = max(len(pts) for _, pts in groups)
    n_rows = len(regions) * len(groups)
    fig, axes = plt.subplots(n_rows, n, figsize=(3.2 * n, 2.9 * n_rows), squeeze=False)
    row_of = {(g, region): g * len(regions) + r_i for g in range(len(groups)) for r_i, region in enumerate(regions)}
    group_of = {p.id: g for g, (_, pts) in enumerate(groups) for p in pts}
    for ax in axes.flat:
        ax.set_visible(False)
    for region, point, i in panels:
        row = row_of[(group_of[point.id], region)]
        ax = axes[row][i]
        ax.set_visible(True)
        floor: float | None = None
        for strategy in experiment.strategies:
            cells = [c for c in data.replicates.get((point.id, strategy), []) if cell_done(c)]
            curves = [c for c in (run_curve(conn, cell, region, metric) for cell in cells) if c]
            if not curves:
                continue
            t, v, lo, hi = mean_curve(curves)
            colour_ = strategy_colour(strategy, experiment.strategies)
            ax.plot(t, v, marker=".", ms=3, lw=1.2, color=colour_, label=strategy_label(strategy))
            if len(curves) > 1:
                ax.fill_between(t, lo, hi, color=colour_, alpha=0.2, lw=0)
            floor = curves[0][0][2]
        if metric == "rel_mse" and floor:
            ax.axhline(floor, color="k", ls=":", lw=0.8, label="reference noise")
        ax.set_xscale("log")
        ax.set_yscale("log")
        sep = "\n" if point.facets else ": "  # facets make the title long: the region on a line of its own
        ax.set_title(f"{point_title(experiment, point)}{sep}{region_title(region)}", fontsize=8)
        ax.set_xlabel("render time (s)", fontsize=8)
        if i == 0:
            ax.set_ylabel(METRIC_LABELS[metric], fontsize=8)
        ax.grid(True, which="both", alpha=0.2)
        _plain_log_ticks(ax.xaxis)
        _plain_log_ticks(ax.yaxis)
        ax.tick_params(which="both", labelsize=7)
    _legend_below(fig, axes, 2)
    reps = experiment.budget.replicates if experiment.budget else 1
    fig.suptitle(
        f"{experiment.name}: {METRIC_LABELS[metric]} over time (mean of {reps} replicate"
        f"{'s' if reps > 1 else ''}{', band: their range' if reps > 1 else ''})",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.12 / fig.get_figheight()))  # room for the title
    return save_figure(fig, layout, experiment, "error_time")


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


def figure_insets(
    experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection, layout: ResultsLayout
) -> list[Path]:
    """Per sweep point: the reference with the insets drawn on it, then each
    inset of the reference and of every strategy at equal time, relMSE under it."""
    regions: tuple[Region, ...] = experiment.insets or (Region(WHOLE_IMAGE, 0, 0, experiment.width, experiment.height),)
    n_sub = len(regions)
    columns = ["reference", *experiment.strategies]
    # Sizes in inches: every inset column is cell_in wide; a block (one sweep
    # point) is as tall as its insets plus their labels, and the reference
    # beside it keeps the image's aspect ratio.
    cell_in, label_in = 1.25, 0.24
    inset_h = cell_in * max(r.height / r.width for r in regions)
    block_h = n_sub * (inset_h + label_in)
    ref_w = block_h * experiment.width / experiment.height
    height = len(data.points) * block_h * 1.1 + 0.8
    fig = plt.figure(figsize=(ref_w + cell_in * len(columns) * 1.08 + 0.5, height))
    outer = fig.add_gridspec(len(data.points), 1, hspace=0.1, top=1 - 0.55 / height, bottom=0.25 / height)
    for p_i, point in enumerate(data.points):
        ref_cell = data.references.get(point.id)
        grid = outer[p_i].subgridspec(
            n_sub,
            2 + len(columns),
            width_ratios=[ref_w / cell_in] * 2 + [1] * len(columns),
            wspace=0.06,
            hspace=label_in / inset_h * 1.1,
        )
        ref_ax = fig.add_subplot(grid[:, 0])
        class_ax = fig.add_subplot(grid[:, 1])
        class_ax.set_xticks([])
        class_ax.set_yticks([])
        ref_ax.set_xticks([])
        ref_ax.set_yticks([])
        ref_ax.set_ylabel(point_title(experiment, point), fontsize=8)
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
        if p_i == 0:
            ref_ax.set_title("reference", fontsize=8)
            class_ax.set_title("antishadow region classes", fontsize=8)
        t_eq = equal_time(experiment, conn, data, point)
        if math.isfinite(t_eq):
            ref_ax.set_ylabel(f"{point_title(experiment, point)}\n(strategies at {t_eq:.3g} s)", fontsize=8)
        for c_i, column in enumerate(columns):
            image: np.ndarray | None = None
            label = ""
            if column == "reference":
                image = reference.rgb
                values: dict[str, float | None] = {}
                label_time = f"{reference.header.spp} spp"
            else:
                cell = data.runs.get((point.id, column))
                values = {}
                label_time = ""
                if cell_done(cell):
                    assert cell is not None
                    chosen = choose_image(conn, cell, t_eq)
                    if chosen is not None:
                        try:
                            image = exr.read_snapshot(chosen.image).rgb
                            values = chosen.rel_mse
                            label_time = f"{chosen.time_s:.2g} s"
                        except CorruptExrError:
                            label = "unreadable"
                else:
                    label = cell.status if cell and cell.status else "missing"
            for r_i, region in enumerate(regions):
                ax = fig.add_subplot(grid[r_i, 2 + c_i])
                ax.set_xticks([])
                ax.set_yticks([])
                for spine in ax.spines.values():
                    spine.set_edgecolor(INSET_COLOURS[r_i % len(INSET_COLOURS)])
                    spine.set_linewidth(1.2)
                if p_i == 0 and r_i == 0:
                    ax.set_title(strategy_label(column), fontsize=8)
                if image is None:
                    ax.set_facecolor("#dddddd")
                    ax.text(0.5, 0.5, label, ha="center", va="center", fontsize=7, transform=ax.transAxes)
                    continue
                ax.imshow(display.to_display(crop(image, region), exposure), interpolation="nearest")
                value = values.get(region.name)
                text = label_time if column == "reference" else (f"{value:.3g}" if value is not None else "-")
                ax.set_xlabel(text, fontsize=7, labelpad=1.5)
    fig.legend(
        handles=class_style.legend_handles(exr.REGION_CLASSES),
        loc="lower center",
        ncol=8,
        fontsize=7,
        frameon=False,
        bbox_to_anchor=(0.5, -0.01),
    )
    fig.suptitle(f"{experiment.name}: insets at equal render time (relMSE under each inset)", fontsize=10, y=0.995)
    return save_figure(fig, layout, experiment, "insets")


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


def figure_efficiency(
    experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection, layout: ResultsLayout
) -> list[Path]:
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
    fig, axes = plt.subplots(
        len(measures), len(regions), figsize=(3.3 * len(regions), 3.0 * len(measures)), squeeze=False
    )
    for m_i, (column, se_column, bound_column, label) in enumerate(measures):
        for r_i, region in enumerate(regions):
            ax = axes[m_i][r_i]
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
                        lw=1.3,
                        ls=style,
                        color=colour_,
                        label=strategy_label(strategy),
                    )
                    for r in rows:
                        _draw_value(ax, r["axis"], r, column, se_column, bound_column, colour_)
            ax.set_yscale("log")
            if experiment.axis is None:
                ax.set_xticks(range(len(experiment.strategies)))
                ax.set_xticklabels([strategy_label(s) for s in experiment.strategies], rotation=30, ha="right")
                ax.set_xlim(-0.6, len(experiment.strategies) - 0.4)
            else:
                ax.set_xscale("log")
                ax.set_xlabel(experiment.axis.label, fontsize=8)
                ax.set_xticks(sorted({p.axis_value for p in data.points}))
                ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
                ax.xaxis.set_minor_formatter(NullFormatter())
            if r_i == 0:
                ax.set_ylabel(label, fontsize=8)
            ax.set_title(region_title(region), fontsize=9)
            ax.grid(True, which="both", alpha=0.2)
            ax.axhline(1.0, color="k", lw=0.6, alpha=0.5)
            ax.tick_params(which="both", labelsize=7)
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
    _legend_below(fig, axes, len(measures) + (len(extra) > 7), extra)
    reps = experiment.budget.replicates if experiment.budget else 1
    fig.suptitle(
        f"{experiment.name}: efficiency 1/(relMSE x time) and equal-error speed-up relative to light "
        f"sampling (reference noise removed; bars: one standard error over {reps} replicates)",
        fontsize=10,
    )
    fig.tight_layout()
    return save_figure(fig, layout, experiment, "efficiency")


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
    finally:
        conn.close()
    return paths
