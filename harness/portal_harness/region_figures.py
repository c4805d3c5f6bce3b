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

from portal_harness import class_style, counters, exr, index
from portal_harness.config import Experiment
from portal_harness.errors import CorruptExrError, HarnessError
from portal_harness.figures import ExperimentData, _done, _point_title, _save, strategy_colour, strategy_label
from portal_harness.index import ROLE_REGION_MAP, ROLE_REGION_SECTION
from portal_harness.paths import ResultsLayout, RunLayout

# The parts of a strategy's next-event samples, bottom to top: (label, colour, ShadowCounters attribute).
SAMPLE_FATES = (
    ("useful: reached the light", "#2ca02c", "useful"),
    ("blocked (shadow ray occluded)", "#d62728", "shadow_blocked"),
    ("missed the light (no ray)", "#ff7f0e", "light_missed"),
    ("nothing to deliver (no ray)", "#c7c7c7", "no_ray"),
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
        cells = [c for c in data.replicates.get((point_id, strategy), []) if _done(c)]
        found = counters.total(counters.read_final_counters(c.run_dir) for c in cells if c.run_dir is not None)
        if found is None or found.light_samples == 0:
            ax.text(s_i, 0.5, "no\ncounters", ha="center", va="center", fontsize=6, rotation=90)
            continue
        bottom = 0.0
        for _, colour, attribute in SAMPLE_FATES:
            share = getattr(found, attribute) / found.light_samples
            ax.bar(s_i, share, bottom=bottom, width=0.7, color=colour, edgecolor="k", lw=0.4)
            bottom += share
        ax.text(s_i, 1.02, f"{found.useful / found.light_samples:.0%}", ha="center", va="bottom", fontsize=6.5)
    ax.set_xticks(range(len(strategies)))
    ax.set_xticklabels([strategy_label(s) for s in strategies], rotation=35, ha="right", fontsize=7)
    for label, strategy in zip(ax.get_xticklabels(), strategies, strict=True):
        label.set_color(strategy_colour(strategy, strategies))
    ax.set_xlim(-0.6, len(strategies) - 0.4)
    ax.set_ylim(0, 1.12)
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
    rows: list[tuple[str, str | None]] = [("region classes, experiment's view", ROLE_REGION_MAP)]
    if experiment.region_sections is not None:
        section_name = experiment.region_sections.scene.stem
        rows.append((f"region classes, {section_name}", ROLE_REGION_SECTION))
    rows.append(("fraction of next-event samples", None))
    col_in = 3.0
    image_h = col_in * experiment.height / experiment.width
    heights = [image_h if role else 2.4 for _, role in rows]
    fig, axes = plt.subplots(
        len(rows),
        len(points),
        figsize=(col_in * len(points) + 0.6, sum(heights) + 2.4),
        squeeze=False,
        gridspec_kw={"height_ratios": heights},
    )
    for p_i, point in enumerate(points):
        for r_i, (label, role) in enumerate(rows):
            ax = axes[r_i][p_i]
            if role is None:
                draw_sample_fates(ax, experiment, data, point.id)
            else:
                fractions = read_fractions(renders.get((point.id, role)))
                _draw_view(ax, fractions, classes, "no region AOV\n(run the sweep)")
            if r_i == 0:
                ax.set_title(_point_title(experiment, point), fontsize=9)
            if p_i == 0:
                ax.set_ylabel(label, fontsize=8)
    class_handles = class_style.legend_handles(classes)
    fate_handles = [Patch(fc=colour, ec="k", lw=0.4, label=label) for label, colour, _ in SAMPLE_FATES]
    fig.legend(
        handles=class_handles + fate_handles,
        loc="lower center",
        ncol=min(6, len(class_handles)),
        fontsize=7.5,
        frameon=False,
        bbox_to_anchor=(0.5, 0.0),
    )
    reps = experiment.budget.replicates if experiment.budget else 1
    caption = (
        f"{experiment.name}: the antishadow region classes of the renderer's classifier (its region AOV; "
        "each pixel in the class of most of its camera samples)"
        + (
            f"; second row: the plane of {experiment.region_sections.scene.name}, in which the camera sees only "
            "that plane, the light and its portal (the classes are geometric: the classifier uses unoccluded "
            "irradiance, so the removed shapes do not change them)"
            if experiment.region_sections is not None
            else ""
        )
        + f". Bottom: what each strategy's next-event samples became, over {reps} replicate"
        f"{'s' if reps > 1 else ''}; on top, the useful share."
    )
    fig.suptitle("\n".join(textwrap.wrap(caption, width=int(22 * col_in * len(points)) or 80)), fontsize=9)
    n_caption = len(textwrap.wrap(caption, width=int(22 * col_in * len(points)) or 80))
    height = fig.get_figheight()
    fig.tight_layout(rect=(0, 1.0 / height, 1, 1 - (0.2 * n_caption + 0.1) / height))
    return _save(fig, layout, experiment, "regions")
