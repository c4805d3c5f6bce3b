"""Choosing the reference strategies of a sweep point by a short pilot.

Every candidate strategy renders the point for reference.pilot_time_s (the
region AOV on). Its own variance layer estimates the relMSE an unbiased
image of it would have, and time x that relMSE is its cost per unit of
precision (the inverse of its efficiency; no reference is needed):

    cost = t * mean_i Var_i / (m_i^2 + eps),

over the pilot's lit pixels that are not the emitter (where every strategy
is alike) nor a miss. The lowest cost makes the first reference; the second,
independent one uses `light` (the baseline every paper trusts), or the
runner-up when the best is `light` itself, so that the two differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from portal_harness import exr
from portal_harness.metrics import REL_EPSILON
from portal_harness.regions import EMITTER, class_map

BASELINE = "light"


@dataclass(frozen=True)
class PilotResult:
    strategy: str
    time_s: float
    cost: float          # time x expected relMSE over the scored pixels; lower is better


def scored_mask(pilots: list[exr.Snapshot], lit_threshold: float, fractions: np.ndarray | None) -> np.ndarray:
    """Pixels lit in some pilot, except those whose primary hits are mostly
    an emitter or nothing (`fractions`: the point's region AOV, if any)."""
    lit = np.max(np.stack([p.rgb.mean(axis=-1) for p in pilots]), axis=0) > lit_threshold
    if fractions is not None:
        classes = class_map(fractions)
        lit &= (classes != exr.REGION_CLASSES.index(EMITTER)) & (classes != exr.REGION_CLASSES.index("miss"))
    return lit


def cost_of(pilot: exr.Snapshot, mask: np.ndarray) -> float:
    if not mask.any() or pilot.header.spp < 2:
        return math.inf
    m = pilot.rgb[mask]
    rel = pilot.variance[mask] / (m * m + REL_EPSILON)
    return float(pilot.header.render_time_s * np.mean(rel))


def score(pilots: dict[str, exr.Snapshot], lit_threshold: float,
          fractions: np.ndarray | None = None) -> list[PilotResult]:
    """Candidates from the cheapest to the dearest."""
    mask = scored_mask(list(pilots.values()), lit_threshold, fractions)
    results = [PilotResult(s, p.header.render_time_s, cost_of(p, mask)) for s, p in pilots.items()]
    return sorted(results, key=lambda r: (r.cost, r.strategy))


def choose(ranked: list[PilotResult]) -> tuple[str, ...]:
    """The reference strategies: the cheapest, then light (or the runner-up)."""
    usable = [r.strategy for r in ranked if math.isfinite(r.cost)]
    if not usable:
        return (BASELINE,)
    best = usable[0]
    second = BASELINE if best != BASELINE else next(iter(usable[1:]), None)
    return (best,) if second is None else (best, second)
