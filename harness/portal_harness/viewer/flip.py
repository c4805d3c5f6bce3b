"""FLIP (Andersson et al. 2020, "FLIP: A Difference Evaluator for
Alternating Images"; NVIDIA's flip-evaluator) of an image the viewer shows
against its reference: LDR-FLIP of the two as display.to_display encodes
them at the point's exposure, so that the map and its means per region
describe the pixels on screen."""

from __future__ import annotations

from dataclasses import dataclass

import flip_evaluator
import numpy as np

from portal_harness.core import display
from portal_harness.core.regions import NamedRegion

DYNAMIC_RANGE = "LDR"
# Pixels per degree of visual angle: FLIP's default viewing conditions
# (0.7 m from a 0.7 m wide 3840-pixel display), rounded.
PPD = 67.0


@dataclass(frozen=True, eq=False)
class Flip:
    error: np.ndarray  # (height, width) float32 in [0, 1]
    by_region: dict[str, float | None]  # mean over each region's pixels (None for an empty one)


def flip_of(image: np.ndarray, reference: np.ndarray, exposure: float, regions: list[NamedRegion]) -> Flip:
    test = display.to_display(image, exposure).astype(np.float32)
    ref = display.to_display(reference, exposure).astype(np.float32)
    error_map, _, _ = flip_evaluator.evaluate(ref, test, DYNAMIC_RANGE, applyMagma=False, parameters={"ppd": PPD})
    error = np.asarray(error_map, dtype=np.float32).reshape(image.shape[:2])
    by_region = {r.name: float(error[r.mask].mean()) if r.pixels else None for r in regions}
    return Flip(error, by_region)
