"""The antishadow regions, drawn (the thesis's figures 1, 3 and 4), and
what each strategy's shadow rays were spent on: results/figures/<experiment>_regions.{png,pdf}.

One column per sweep point:
1. the region classes in the experiment's own view (the canonical lampshade
   view: the floor below the lamp), from the point's region map (the sweep's
   region-AOV render of the point, config.region_map_spec);
2. with figures.region_sections, the region classes in that view (e.g. the
   vertical section z = 0 through the lamp, configs/scenes/lampshade_section.yaml),
   from the sweep's render of it at the point (config.region_section_spec);
3. per strategy, what its next-event samples became (counters.py): useful
   shadow rays, blocked ones, directions that missed the light, samples
   with nothing to deliver; fractions of all its samples, summed over
   replicates.

Classes are the renderer's (its region AOV: the class of most of each
pixel's samples), never recomputed here; the figure reads stored runs only.
"""

from __future__ import annotations

import contextlib
import sqlite3
import textwrap
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Patch

from portal_harness.analysis import counters
from portal_harness.core import class_style, exr
from portal_harness.core.errors import CorruptExrError, HarnessError
from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.execution import index
from portal_harness.execution.index import ROLE_REGION_MAP, ROLE_REGION_SECTION
from portal_harness.experiment.model import Experiment
from portal_harness.figures.data import ExperimentData, cell_done
from portal_harness.figures.style import point_title, save_figure, strategy_colour, strategy_label

# The parts of a strategy's next-event samples, bottom to top: (label, colour, ShadowCounters attribute).
SAMPLE_FATES = (
    ("useful: unoccluded shadow ray", "#2ca02c", "useful"),
    ("blocked: occluded shadow ray", "#d62728", "shadow_blocked"),
    ("missed the light: no ray traced", "#ff7f0e", "light_missed"),
    ("nothing to deliver (below the horizon, light's back): no ray", "#c7c7c7", "no_ray"),
)


def region_renders(conn: sqlite3.Connection, experiment: Experiment) -> dict[tuple[str, str], Path | None]:
    """(point, role) -> run folder of the point's finished region map and
    region section (None where the render did not finish)."""
    out: dict[tuple[str, str], Path | None] = {}
    for r in index.membership(conn, experiment.name):
        if r["role"] in (ROLE_REGION_MAP, ROLE_REGION_SECTION):
            done = r["status"] == "done" and r["run_dir"]
            out[(r["point"], r["role"])] = Path(r["run_dir"]) if done else None
    return out


def read_fractions(run_dir: Path | None) -> np.ndarray | None:
    """The region AOV of a finished render's final image, or None."""
    if run_dir is None:
        return None
    with contextlib.suppress(CorruptExrError):
        return exr.read_snapshot(RunLayout(run_dir).final).regions
    return None


def _classes(experiment: Experiment) -> tuple[str, ...]:
    """The renderer's classes, which must be the region channels exr.py reads."""
    if tuple(experiment.region_classes) != exr.REGION_CLASSES:
        raise HarnessError(
            f"the renderer's region classes ({', '.join(experiment.region_classes)}) are not the ones "
            f"exr.py reads ({', '.join(exr.REGION_CLASSES)}): update exr.REGION_CLASSES"
        )
    return experiment.region_classes


def _draw_view(ax: Any, fractions: np.ndarray | None, classes: tuple[str, ...], missing: str) -> None:
    ax.set_xticks([])
    ax.set_yticks([])
    if fractions is None:
        ax.set_facecolor("#eeeeee")
        ax.text(0.5, 0.5, missing, ha="center", va="center", fontsize=8, transform=ax.transAxes)
        return
    class_style.draw_class_map(ax, fractions, classes)


def draw_sample_fates(ax: Any, experiment: Experiment, data: ExperimentData, point_id: str) -> None:
    """Stacked bars, one per strategy: the fractions of its next-event
    samples (all replicates) that each fate took; the useful share printed on top."""
    strategies = experiment.strategies
    for s_i, strategy in enumerate(strategies):
        cells = [c for c in data.replicates.get((point_id, strategy), []) if cell_done(c)]
        found = counters.total(counters.read_final_counters(c.run_dir) for c in cells if c.run_dir is not None)
        if found is None or found.light_samples == 0:
            ax.text(s_i, 0.5, "no\ncounters", ha="center", va="center", fontsize=6, rotation=90)
            continue
        bottom = 0.0
        for _, colour, attribute in SAMPLE_FATES:
            share = getattr(found, attribute) / found.light_samples
            ax.bar(s_i, share, bottom=bottom, width=0.7, color=colour, edgecolor="k", lw=0.4)
            bottom += share
        note = f"{found.useful / found.light_samples:.0%}"
        if found.camera_samples > 0:
            note += f"\n{found.light_samples / found.camera_samples:.2f}"
        ax.text(s_i, 1.02, note, ha="center", va="bottom", fontsize=6.5, linespacing=1.1)
    ax.set_xticks(range(len(strategies)))
    ax.set_xticklabels([strategy_label(s) for s in strategies], rotation=35, ha="right", fontsize=7)
    for label, strategy in zip(ax.get_xticklabels(), strategies, strict=True):
        label.set_color(strategy_colour(strategy, strategies))
    ax.set_xlim(-0.6, len(strategies) - 0.4)
    ax.set_ylim(0, 1.2)
    ax.set_yticks([0, 0.25, 0.5, 0.75, 1.0])
    ax.tick_params(axis="y", labelsize=7)
    ax.grid(True, axis="y", alpha=0.2)


def figure_regions(
    experiment: Experiment, data: ExperimentData, conn: sqlite3.Connection, layout: ResultsLayout
) -> list[Path]:
    """One column per sweep point: its region classes in the experiment's
    view and in the section view (figures.region_sections), and the fates
    of each strategy's next-event samples."""
    classes = _classes(experiment)
    renders = region_renders(conn, experiment)
    points = data.points
    rows: list[tuple[str, str | None]] = [(f"{experiment.scene.stem}: camera view", ROLE_REGION_MAP)]
    if experiment.region_sections is not None:
        rows.append((experiment.region_sections.label, ROLE_REGION_SECTION))
    rows.append(("fraction of next-event samples", None))
    reps = experiment.budget.replicates if experiment.budget else 1
    caption = (
        "Antishadow region classes from the renderer's classifier (its region AOV: each pixel in the class of "
        "most of its camera samples)"
        + (
            f"; row 2: {experiment.region_sections.label}, rendered with only that plane, the light and its "
            "portal (the classes are geometric, from unoccluded irradiance: removing the other shapes does not "
            "change them)"
            if experiment.region_sections is not None
            else ""
        )
        + ". Bottom: what the next-event samples each strategy drew became"
        + (f" (its {reps} replicates together)" if reps > 1 else "")
        + "; above each bar, the useful share and the samples drawn per camera sample (where no direction "
        "reaches the light, e.g. outside every antishadow for the antishadow strategies, a strategy that knows it "
        "draws none: such points are neither counted nor wasted)."
    )
    # Sizes in inches: columns of col_in, image rows at the image's aspect,
    # the caption above, the bars' labels and the legend below.
    col_in = 3.0
    image_h = col_in * experiment.height / experiment.width
    heights = [image_h if role else 2.2 for _, role in rows]
    width = col_in * len(points) + 0.8
    lines = textwrap.wrap(caption, width=max(60, int(width * 15)))
    # The legends: classes above the sample fates, on one row each when the figure is wide enough.
    class_handles = class_style.legend_handles(classes)
    fate_handles = [Patch(fc=colour, ec="k", lw=0.4, label=label) for label, colour, _ in SAMPLE_FATES]
    legend_rows = 1 if width > 9 else 2
    line_in = 0.19
    top_in, gap_in = 0.5 + 0.14 * len(lines), 0.35
    bottom_in = 1.05 + 2 * legend_rows * line_in + 0.2
    height = sum(heights) + gap_in * (len(rows) - 1) + top_in + bottom_in
    fig = plt.figure(figsize=(width, height))
    grid = fig.add_gridspec(
        len(rows),
        len(points),
        height_ratios=heights,
        top=1 - top_in / height,
        bottom=bottom_in / height,
        left=0.6 / width,
        right=1 - 0.2 / width,
        hspace=gap_in / (sum(heights) / len(rows)),
        wspace=0.08,
    )
    for p_i, point in enumerate(points):
        for r_i, (label, role) in enumerate(rows):
            ax = fig.add_subplot(grid[r_i, p_i])
            if role is None:
                draw_sample_fates(ax, experiment, data, point.id)
            else:
                fractions = read_fractions(renders.get((point.id, role)))
                _draw_view(ax, fractions, classes, "no region AOV\n(run the sweep)")
            if r_i == 0:
                ax.set_title(point_title(experiment, point), fontsize=9)
            if p_i == 0:
                ax.set_ylabel(label, fontsize=8)
            elif role is None:
                ax.set_yticklabels([])
    fate_y = 0.1 + legend_rows * line_in / 2
    class_y = fate_y + legend_rows * line_in + 0.08
    for handles, y_in in ((class_handles, class_y), (fate_handles, fate_y)):
        fig.legend(
            handles=handles,
            loc="center",
            ncol=-(-len(handles) // legend_rows),
            fontsize=7.5,
            frameon=False,
            bbox_to_anchor=(0.5, y_in / height),
        )
    fig.suptitle(
        f"{experiment.name}: the antishadow regions, and what the shadow rays were spent on",
        fontsize=10,
        y=1 - 0.08 / height,
        va="top",
    )
    fig.text(0.5, 1 - 0.34 / height, "\n".join(lines), ha="center", va="top", fontsize=7.5)
    return save_figure(fig, layout, experiment, "regions")
