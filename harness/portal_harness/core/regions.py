"""The regions every metric is computed on, as boolean pixel masks.

- `image`: every pixel;
- `lit`: pixels whose reference value (mean over channels) is above a small
  threshold and whose primary hits are not mostly on an emitter (the band
  where the camera sees the lamp through the opening is the same for every
  light strategy, and would otherwise dominate the error);
- each inset of the experiment (a rectangle);
- each antishadow region class of the renderer's region AOV
  (`region.<class>` channels, exr.REGION_CLASSES): the pixels where that
  class holds at least PURE (95%) of the pixel's samples, so that a class's
  error is that class's. Pixels on a boundary belong to no class (they are
  in image, lit and the insets). A class with fewer than CLASS_MIN_PIXELS
  pixels is left out (its mean says little), and so is a dark one, whose
  reference is below the lit threshold on average: no light reaches it, so
  there is no error to measure (e.g. `outside` with direct lighting).

The class map comes from a render with the region AOV (the renderer's own
classifier, not a re-implementation; the sweep makes one per point, see
config.region_map_spec). Without one there are no classes, and `lit` then
cannot leave out the emitter.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from portal_harness.core.exr import REGION_CLASSES, Snapshot
from portal_harness.core.metrics import WHOLE_IMAGE, Region

LIT = "lit"
EMITTER = "emitter"
CLASS_MIN_PIXELS = 16
MAJORITY = 0.5
PURE = 0.95
# Radiance (mean over R, G, B) above which a reference pixel counts as lit.
DEFAULT_LIT_THRESHOLD = 1e-3

KIND_IMAGE, KIND_LIT, KIND_INSET, KIND_CLASS = "image", "lit", "inset", "class"


@dataclass(frozen=True, eq=False)
class NamedRegion:
    name: str
    kind: str  # KIND_IMAGE | KIND_LIT | KIND_INSET | KIND_CLASS
    mask: np.ndarray  # bool, (height, width)

    @property
    def pixels(self) -> int:
        return int(self.mask.sum())


def _dominant(regions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel, the index of its largest class and that class's share."""
    best = np.argmax(regions, axis=-1)
    return best, np.take_along_axis(regions, best[..., None], axis=-1)[..., 0]


def class_map(regions: np.ndarray) -> np.ndarray:
    """Per pixel, the index into REGION_CLASSES of the class holding more
    than half of its samples, or -1 where none does."""
    best, share = _dominant(regions)
    return np.where(share > MAJORITY, best, -1)


def pure_class_map(regions: np.ndarray) -> np.ndarray:
    """The same, for the class holding at least PURE of the samples."""
    best, share = _dominant(regions)
    return np.where(share >= PURE, best, -1)


def inset_mask(region: Region, height: int, width: int) -> np.ndarray:
    mask = np.zeros((height, width), dtype=bool)
    mask[region.y : region.y + region.height, region.x : region.x + region.width] = True
    return mask


def regions_of(
    reference: Snapshot,
    insets: tuple[Region, ...],
    lit_threshold: float = DEFAULT_LIT_THRESHOLD,
    fractions: np.ndarray | None = None,
) -> list[NamedRegion]:
    """Every region of the experiment, in report order: image, lit, insets,
    classes. `fractions` is a region AOV (the reference's own if None)."""
    height, width = reference.rgb.shape[:2]
    out = [NamedRegion(WHOLE_IMAGE, KIND_IMAGE, np.ones((height, width), dtype=bool))]
    lit = reference.rgb.mean(axis=-1) > lit_threshold
    if fractions is None:
        fractions = reference.regions
    if fractions is not None and fractions.shape[:2] != (height, width):
        raise ValueError(f"region map of {fractions.shape[1]}x{fractions.shape[0]} for a {width}x{height} image")
    if fractions is not None:
        lit &= class_map(fractions) != REGION_CLASSES.index(EMITTER)
    out.append(NamedRegion(LIT, KIND_LIT, lit))
    out += [NamedRegion(r.name, KIND_INSET, inset_mask(r, height, width)) for r in insets]
    if fractions is not None:
        pure = pure_class_map(fractions)
        brightness = reference.rgb.mean(axis=-1)
        for i, name in enumerate(REGION_CLASSES):
            mask = pure == i
            if mask.sum() >= CLASS_MIN_PIXELS and brightness[mask].mean() > lit_threshold:
                out.append(NamedRegion(name, KIND_CLASS, mask))
    return out


def fingerprint(regions: list[NamedRegion]) -> str:
    """Identifies the masks, so that metrics computed on other masks are redone."""
    h = hashlib.sha256()
    for r in regions:
        h.update(f"{r.name}:{r.kind}:".encode())
        h.update(np.packbits(r.mask).tobytes())
    return h.hexdigest()[:16]
