"""How the region AOV's classes are drawn: one fixed colour and label per
class name, the same in every figure. The class names themselves are the
renderer's (`render --describe`: aov.region, see Experiment.region_classes);
a class it adds later is drawn in a spare colour under its own name.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.patches import Patch

from portal_harness.core.regions import class_map

CLASS_COLOURS = {
    "outside": "#3b3b3b",
    "anti_umbra": "#f5d142",
    "anti_penumbra": "#e8743b",
    "anti_antumbra": "#4a90d9",
    "inside": "#9b59b6",
    "emitter": "#ffffff",
    "miss": "#bfe3d0",
}
CLASS_LABELS = {"inside": "inside shade"}
SPARE_CLASS_COLOURS = ("#17becf", "#bcbd22", "#e377c2", "#8c564b")
# Pixels where no class holds more than half of the samples (a boundary).
NO_MAJORITY_COLOUR = "#9a9a9a"


def class_colour(name: str, classes: Sequence[str]) -> str:
    """The class's colour; an unknown one takes a spare colour by its place in `classes`."""
    if name in CLASS_COLOURS:
        return CLASS_COLOURS[name]
    unknown = [c for c in classes if c not in CLASS_COLOURS]
    return SPARE_CLASS_COLOURS[unknown.index(name) % len(SPARE_CLASS_COLOURS)] if name in unknown else "#000000"


def class_label(name: str) -> str:
    """anti_umbra -> anti-umbra."""
    return CLASS_LABELS.get(name, name.replace("_", "-"))


def draw_class_map(ax: Any, fractions: np.ndarray, classes: Sequence[str]) -> None:
    """Each pixel in the colour of the class holding the majority of its
    samples (grey where none does); `classes` name the last axis of
    `fractions` (the region AOV's channels, in order)."""
    if fractions.shape[-1] != len(classes):
        raise ValueError(f"{fractions.shape[-1]} region channels for {len(classes)} classes")
    cmap = ListedColormap([NO_MAJORITY_COLOUR, *(class_colour(c, classes) for c in classes)])
    ax.imshow(class_map(fractions) + 1, cmap=cmap, vmin=-0.5, vmax=len(classes) + 0.5, interpolation="nearest")


def legend_handles(classes: Sequence[str]) -> list[Patch]:
    """A patch per class, then "no majority"."""
    return [Patch(fc=class_colour(c, classes), ec="k", lw=0.5, label=class_label(c)) for c in classes] + [
        Patch(fc=NO_MAJORITY_COLOUR, ec="k", lw=0.5, label="no majority")
    ]
