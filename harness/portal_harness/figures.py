"""The three figures of an experiment, one function each, from the index
(metrics) and the run folders (images through exr.py):

1. error over time: log-log, one line per strategy, one panel per sweep point;
2. insets: per sweep point, the reference with the inset rectangles drawn,
   then each inset of the reference and of each strategy at equal render
   time, with its relMSE under it;
3. efficiency 1 / (relMSE x time) relative to light sampling against the
   swept axis (the light/portal ratio), one panel per region.

PNG and PDF go to results/figures/<experiment>_<figure>.{png,pdf}.
"""

from __future__ import annotations

import math
import sqlite3
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # pinned: figures are files, never windows

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402
from matplotlib.axis import Axis as MplAxis  # noqa: E402
from matplotlib.ticker import FuncFormatter, NullFormatter  # noqa: E402

from portal_harness import display, exr, index  # noqa: E402
from portal_harness.config import Experiment, Point  # noqa: E402
from portal_harness.errors import CorruptExrError, HarnessError  # noqa: E402
from portal_harness.metrics import WHOLE_IMAGE, Region, crop, floor_corrected_efficiency  # noqa: E402
from portal_harness.paths import ResultsLayout  # noqa: E402
from portal_harness.spec import STRATEGIES  # noqa: E402

STRATEGY_COLOURS = dict(zip(STRATEGIES, ("#7f7f7f", "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd")))
STRATEGY_LABELS = {
    "light_area": "light (area)", "light": "light", "portal": "portal", "projection": "projection",
    "antishadow": "antishadow", "antishadow_exact": "antishadow (exact)",
}
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
    runs: dict[tuple[str, str], Cell]
    references: dict[str, Cell]


def load(experiment: Experiment, conn: sqlite3.Connection) -> ExperimentData:
    rows = index.membership(conn, experiment.name)
    runs: dict[tuple[str, str], Cell] = {}
    references: dict[str, Cell] = {}
    for r in rows:
        cell = Cell(r["key"], r["reference_key"], r["status"], Path(r["run_dir"]) if r["run_dir"] else None)
        if r["role"] == "reference":
            references[r["point"]] = cell
        else:
            runs[(r["point"], r["strategy"])] = cell
    points = tuple(p for p in experiment.points() if p.id in references)
    if not points:
        raise HarnessError(f"no runs of experiment {experiment.name!r} in the index: run `portal-harness sweep` first")
    return ExperimentData(points, runs, references)


def _point_title(experiment: Experiment, point: Point) -> str:
    return f"{experiment.axis.label} = {point.axis_value:g}"


def _save(fig: Figure, layout: ResultsLayout, experiment: Experiment, name: str) -> list[Path]:
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


def _done(cell: Cell | None) -> bool:
    return cell is not None and cell.status == "done" and cell.run_dir is not None


def figure_error_curves(experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection,
                        layout: ResultsLayout) -> list[Path]:
    """Error against render time, log-log, one panel per sweep point."""
    metric = experiment.curve_metric
    n = len(data.points)
    cols = min(n, 5)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.9 * rows), squeeze=False, sharey=True)
    for i, point in enumerate(data.points):
        ax = axes[i // cols][i % cols]
        floor: float | None = None
        for strategy in experiment.strategies:
            cell = data.runs.get((point.id, strategy))
            if not _done(cell):
                continue
            assert cell is not None
            pts = [(m["time_s"], m[metric], m["floor_rel"]) for m in index.metrics_of(conn, cell.key, cell.reference_key)
                   if m["region"] == WHOLE_IMAGE and m["error"] is None and m["time_s"] and m[metric]]
            pts.sort()
            if not pts:
                continue
            t, v, f = zip(*pts)
            ax.plot(t, v, marker=".", ms=3, lw=1.2, color=STRATEGY_COLOURS[strategy], label=STRATEGY_LABELS[strategy])
            floor = f[0]
        if metric == "rel_mse" and floor:
            ax.axhline(floor, color="k", ls=":", lw=0.8, label="reference noise")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(_point_title(experiment, point), fontsize=9)
        ax.set_xlabel("render time (s)", fontsize=8)
        if i % cols == 0:
            ax.set_ylabel(METRIC_LABELS[metric], fontsize=8)
        ax.grid(True, which="both", alpha=0.2)
    for j in range(n, rows * cols):
        axes[j // cols][j % cols].set_visible(False)
    for ax in axes.flat[:n]:
        _plain_log_ticks(ax.xaxis)
        _plain_log_ticks(ax.yaxis)
        ax.tick_params(which="both", labelsize=7)
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 7), fontsize=8, frameon=False,
               bbox_to_anchor=(0.5, -0.02 - 0.02 * rows))
    fig.suptitle(f"{experiment.name}: {METRIC_LABELS[metric]} of the whole image over time", fontsize=10)
    fig.tight_layout()
    return _save(fig, layout, experiment, "error_time")


@dataclass(frozen=True)
class _Chosen:
    image: Path
    time_s: float
    rel_mse: dict[str, float | None]


def _choose_image(conn: sqlite3.Connection, cell: Cell, time_s: float) -> _Chosen | None:
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
    return _Chosen(cell.run_dir / image, chosen_t, {m["region"]: m["rel_mse"] for m in at if m["image"] == image})


def equal_time(experiment: Experiment, conn: sqlite3.Connection, data: ExperimentData, point: Point) -> float:
    """The configured comparison time, else the shortest final time of the point's runs."""
    if experiment.equal_time_s is not None:
        return experiment.equal_time_s
    finals = []
    for strategy in experiment.strategies:
        cell = data.runs.get((point.id, strategy))
        if _done(cell):
            assert cell is not None
            row = index.run_row(conn, cell.key)
            if row is not None and row["final_time_s"]:
                finals.append(float(row["final_time_s"]))
    return min(finals) if finals else math.inf


def figure_insets(experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection,
                  layout: ResultsLayout) -> list[Path]:
    """Per sweep point: the reference with the insets drawn on it, then each
    inset of the reference and of every strategy at equal time, relMSE under it."""
    regions: tuple[Region, ...] = experiment.insets or (
        Region(WHOLE_IMAGE, 0, 0, experiment.width, experiment.height),)
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
        grid = outer[p_i].subgridspec(n_sub, 1 + len(columns), width_ratios=[ref_w / cell_in] + [1] * len(columns),
                                      wspace=0.06, hspace=label_in / inset_h * 1.1)
        ref_ax = fig.add_subplot(grid[:, 0])
        ref_ax.set_xticks([])
        ref_ax.set_yticks([])
        ref_ax.set_ylabel(_point_title(experiment, point), fontsize=8)
        if not _done(ref_cell):
            ref_ax.text(0.5, 0.5, "reference\nmissing", ha="center", va="center", fontsize=8)
            continue
        assert ref_cell is not None and ref_cell.run_dir is not None
        try:
            reference = exr.read_snapshot(ref_cell.run_dir / "final.exr")
        except CorruptExrError as e:
            ref_ax.text(0.5, 0.5, f"reference\nunreadable\n{e.reason[:40]}", ha="center", va="center", fontsize=6)
            continue
        exposure = display.exposure_from_reference(reference.rgb)
        ref_ax.imshow(display.to_display(reference.rgb, exposure), interpolation="nearest")
        for r_i, region in enumerate(regions):
            colour_ = INSET_COLOURS[r_i % len(INSET_COLOURS)]
            ref_ax.add_patch(Rectangle((region.x - 0.5, region.y - 0.5), region.width, region.height,
                                       fill=False, ec=colour_, lw=1.2))
        if p_i == 0:
            ref_ax.set_title("reference", fontsize=8)
        t_eq = equal_time(experiment, conn, data, point)
        if math.isfinite(t_eq):
            ref_ax.set_ylabel(f"{_point_title(experiment, point)}\n(strategies at {t_eq:.3g} s)", fontsize=8)
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
                if _done(cell):
                    assert cell is not None
                    chosen = _choose_image(conn, cell, t_eq)
                    if chosen is not None:
                        try:
                            image = exr.read_snapshot(chosen.image).rgb
                            values = chosen.rel_mse
                            label_time = f"{chosen.time_s:.2g} s"
                        except CorruptExrError:
                            label = "unreadable"
                else:
                    label = (cell.status if cell and cell.status else "missing")
            for r_i, region in enumerate(regions):
                ax = fig.add_subplot(grid[r_i, 1 + c_i])
                ax.set_xticks([])
                ax.set_yticks([])
                for spine in ax.spines.values():
                    spine.set_edgecolor(INSET_COLOURS[r_i % len(INSET_COLOURS)])
                    spine.set_linewidth(1.2)
                if p_i == 0 and r_i == 0:
                    ax.set_title(STRATEGY_LABELS.get(column, column), fontsize=8)
                if image is None:
                    ax.set_facecolor("#dddddd")
                    ax.text(0.5, 0.5, label, ha="center", va="center", fontsize=7, transform=ax.transAxes)
                    continue
                ax.imshow(display.to_display(crop(image, region), exposure), interpolation="nearest")
                value = values.get(region.name)
                text = label_time if column == "reference" else (
                    f"{value:.3g}" if value is not None else "-")
                ax.set_xlabel(text, fontsize=7, labelpad=1.5)
    fig.suptitle(f"{experiment.name}: insets at equal render time (relMSE under each inset)", fontsize=10,
                 y=0.995)
    return _save(fig, layout, experiment, "insets")


def figure_efficiency(experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection,
                      layout: ResultsLayout) -> list[Path]:
    """Efficiency 1 / (relMSE x time) of the final images relative to light
    sampling against the swept axis; one panel per region."""
    regions = [WHOLE_IMAGE, *(r.name for r in experiment.insets)]
    fig, axes = plt.subplots(1, len(regions), figsize=(3.6 * len(regions), 3.2), squeeze=False)
    for r_i, region in enumerate(regions):
        ax = axes[0][r_i]
        for strategy in experiment.strategies:
            xs, ys, bounds = [], [], []
            for point in data.points:
                eff = _efficiency(conn, data.runs.get((point.id, strategy)), region)
                base = _efficiency(conn, data.runs.get((point.id, "light")), region)
                if eff is not None and base is not None and base[0] > 0:
                    xs.append(point.axis_value)
                    ys.append(eff[0] / base[0])
                    bounds.append(eff[1] or base[1])
            if not xs:
                continue
            colour_ = STRATEGY_COLOURS[strategy]
            ax.plot(xs, ys, lw=1.3, color=colour_, label=STRATEGY_LABELS[strategy])
            ax.plot([x for x, b in zip(xs, bounds) if not b], [y for y, b in zip(ys, bounds) if not b],
                    ls="none", marker="o", ms=4, color=colour_)
            ax.plot([x for x, b in zip(xs, bounds) if b], [y for y, b in zip(ys, bounds) if b],
                    ls="none", marker="^", ms=6, mfc="white", color=colour_)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(experiment.axis.label, fontsize=8)
        if r_i == 0:
            ax.set_ylabel("efficiency relative to light sampling", fontsize=8)
        ax.set_title("whole image" if region == WHOLE_IMAGE else f"inset {region}", fontsize=9)
        ax.grid(True, which="both", alpha=0.2)
        ax.set_xticks(sorted({p.axis_value for p in data.points}))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
        _plain_log_ticks(ax.yaxis)
        ax.axhline(1.0, color="k", lw=0.6, alpha=0.5)
        ax.tick_params(which="both", labelsize=7)
    handles, labels = axes[0][0].get_legend_handles_labels()
    handles.append(Line2D([], [], ls="none", marker="^", ms=6, mfc="white", color="k"))
    labels.append("lower bound (error within 2x the reference's noise)")
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 7), fontsize=8, frameon=False,
               bbox_to_anchor=(0.5, -0.08))
    fig.suptitle(f"{experiment.name}: efficiency 1/(relMSE x time) relative to light sampling "
                 "(reference noise removed)", fontsize=10)
    fig.tight_layout()
    return _save(fig, layout, experiment, "efficiency")


def _efficiency(conn: sqlite3.Connection, cell: Cell | None, region: str) -> tuple[float, bool] | None:
    """(efficiency of the final image with the reference noise removed, whether it is only a lower bound)."""
    if not _done(cell):
        return None
    assert cell is not None
    final = [m for m in index.metrics_of(conn, cell.key, cell.reference_key)
             if m["is_final"] and m["region"] == region and m["error"] is None]
    if not final or final[0]["rel_mse"] is None or final[0]["time_s"] is None:
        return None
    value, bound = floor_corrected_efficiency(final[0]["rel_mse"], final[0]["floor_rel"] or 0.0, final[0]["time_s"])
    return (value, bound) if math.isfinite(value) else None


def make_all(experiment: Experiment, layout: ResultsLayout) -> list[Path]:
    conn = index.connect(layout.index_path)
    try:
        data = load(experiment, conn)
        paths = figure_error_curves(experiment, data, conn, layout)
        paths += figure_insets(experiment, data, conn, layout)
        paths += figure_efficiency(experiment, data, conn, layout)
    finally:
        conn.close()
    return paths
