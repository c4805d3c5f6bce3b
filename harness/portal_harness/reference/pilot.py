"""Choosing the reference strategies of a sweep point, and the first
reference's length, by a short pilot.

Every candidate strategy renders the point for reference.pilot_time_s. Its
own variance layer estimates the relMSE an unbiased image of it would have,
and time x that relMSE is its cost per unit of precision in a region R (the
inverse of its efficiency; no reference is needed):

    cost_s(R) = t * mean_{i in R} Var_i / (m_i^2 + eps).

The reference must resolve, in every region, the error of the best strategy
there (noise_check.py). A reference made with s for time T has noise
cost_s(R) / T, and the best run of time t has error min_s' cost_s'(R) / t,
so the reference time R needs grows with the ratio

    need_s(R) = cost_s(R) / min_s' cost_s'(R)

and the first reference is the strategy with the smallest worst ratio over
the regions (image, lit, insets, classes: regions.py): a strategy very good
on average but poor in one inset would make that inset's reference very
long. The second, independent part uses `light` (the baseline every paper
trusts), or the runner-up when the best is `light` itself, so that the two
differ.

A candidate whose pilot shows fireflies (noise_check.firefly_share over
the image above FIREFLY_SHARE_MAX) is not chosen while another is: its
variance, and so its cost, is underestimated until its rare large samples
have been drawn many times, and a short pilot makes it look best. The
path-traced lampshade's pilots at ratio 0.25 and 1 measured `projection`
at a tenth of every other candidate's cost with 0.79 and 0.95 of the
image's noise in fireflies; it was chosen, and its references were full
of them (169 firefly pixels holding 0.60 of the noise at 0.25).

The firefly test needs samples. A pixel-channel is a firefly when at most
a handful (1 / FIREFLY_REL_SE^2 = 4) of its samples carry its value; after
n samples, a pixel whose samples are either 0 or x (an edge, a shadow's
border: a fraction p of them x) has relative standard error
sqrt((1 - p) / (n p)) and is flagged when p <= 4 / (n + 4): a third of the
pixel at n = 9, 6% at n = 64. A strategy whose image is otherwise nearly
noise-free then holds most of its noise in such pixels. The 512x512
multi_lamp_full pilots drew 9 samples of `antishadow_exact` in 0.5 s (3
with path tracing), and its direct pilot held 0.56 of its noise in
"fireflies"; rendered on, the same strategy holds 0.42 at 20 samples,
0.25 at 64 and 0 at 320, where real fireflies grow: the path-traced
lampshade's `projection` (ratio 0.25, 128x128) holds 0.65 at 64 and 0.92
at 256. So a pilot whose time drew fewer than MIN_SPP samples is drawn
again for MIN_SPP samples (choice.py), and that one is scored. Without it
the direct multi_lamp_full reference fell to `light`, whose worst region
needs 1,800 times the best strategy's time.

The first part's render time is then predicted: the noise limit q of the
error gives T = t * max_R need(R) * (1 - q) / q * margin (noise_check.py's
extension formula with the pilot's costs), between reference.time_s and the
cap. The noise check still measures the result and extends it if needed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from portal_harness.core import exr
from portal_harness.core.metrics import rel_variance_floor
from portal_harness.core.regions import NamedRegion
from portal_harness.reference.noise_check import FIREFLY_SHARE_MAX, firefly_share

BASELINE = "light"
# The fewest samples a pilot's firefly test is trusted on (above).
MIN_SPP = 64


@dataclass(frozen=True)
class PilotResult:
    strategy: str
    time_s: float
    worst_need: float  # max over regions of cost / best cost there; lower is better
    needs: dict[str, float]  # by region
    firefly_share: float = 0.0  # of the pilot's image noise (noise_check.firefly_share)

    @property
    def trusted(self) -> bool:
        return math.isfinite(self.worst_need) and self.firefly_share <= FIREFLY_SHARE_MAX


def region_costs(pilot: exr.Snapshot, regions: list[NamedRegion]) -> dict[str, float]:
    out: dict[str, float] = {}
    if pilot.header.spp < 2:
        return out
    for r in regions:
        if r.pixels:
            out[r.name] = pilot.header.render_time_s * rel_variance_floor(pilot.rgb, pilot.variance, r.mask)
    return out


def score(pilots: dict[str, exr.Snapshot], regions: list[NamedRegion]) -> list[PilotResult]:
    """Candidates from the best reference strategy to the worst."""
    costs = {s: region_costs(p, regions) for s, p in pilots.items()}
    names = [r.name for r in regions]
    best = {n: min((c[n] for c in costs.values() if c.get(n, 0) > 0), default=0.0) for n in names}
    results = []
    for s, p in pilots.items():
        needs = {n: costs[s][n] / best[n] for n in names if best[n] > 0 and n in costs[s]}
        complete = len(needs) == sum(1 for n in names if best[n] > 0)
        worst = max(needs.values(), default=math.inf) if complete else math.inf
        share = firefly_share(p.rgb, p.variance, np.ones(p.rgb.shape[:2], dtype=bool))
        results.append(PilotResult(s, p.header.render_time_s, worst, needs, share))
    return sorted(results, key=lambda r: (r.worst_need, r.strategy))


def choose(ranked: list[PilotResult]) -> tuple[str, ...]:
    """The reference strategies: the best without fireflies, then light (or
    the runner-up); candidates with fireflies only when no other is left."""
    usable = [r.strategy for r in ranked if r.trusted]
    usable += [r.strategy for r in ranked if math.isfinite(r.worst_need) and not r.trusted]
    if not usable:
        return (BASELINE,)
    best = usable[0]
    second = BASELINE if best != BASELINE else next(iter(usable[1:]), None)
    return (best,) if second is None else (best, second)


def first_time(ranked: list[PilotResult], run_time_s: float, noise_ratio: float, margin: float) -> float | None:
    """The predicted render time of the first reference part (None without a prediction)."""
    usable = [r for r in ranked if r.trusted] or [r for r in ranked if math.isfinite(r.worst_need)]
    if not usable or run_time_s <= 0:
        return None
    return run_time_s * usable[0].worst_need * (1 - noise_ratio) / noise_ratio * margin
