"""What a run's next-event samples became: the counters of the renderer's
`final` JSON event (renderer/CONTRACT.md), read from the run folder's
events.jsonl (the renderer's stdout, kept with every run; the manifest and
the index keep only the final image's time, spp and rays).

Of `light_samples` next-event samples (one per shading point and bounce):
`light_missed` drew a direction that does not reach the light (no ray is
traced); `shadow_rays` set up a shadow ray, of which `shadow_blocked` were
occluded; the rest of the shadow rays delivered light (`useful`). The
remainder, light_samples - light_missed - shadow_rays, reached the light
with nothing to deliver (below the point's horizon, the light's back, a
zero density) and traced no ray either.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from portal_harness.paths import RunLayout

COUNTER_FIELDS = ("light_samples", "light_missed", "shadow_rays", "shadow_blocked")


@dataclass(frozen=True)
class ShadowCounters:
    light_samples: int
    light_missed: int
    shadow_rays: int
    shadow_blocked: int

    @property
    def useful(self) -> int:
        """Shadow rays that reached the light unoccluded."""
        return self.shadow_rays - self.shadow_blocked

    @property
    def no_ray(self) -> int:
        """Samples that reached the light but had nothing to deliver (no ray traced)."""
        return self.light_samples - self.light_missed - self.shadow_rays

    def __add__(self, other: ShadowCounters) -> ShadowCounters:
        return ShadowCounters(
            self.light_samples + other.light_samples,
            self.light_missed + other.light_missed,
            self.shadow_rays + other.shadow_rays,
            self.shadow_blocked + other.shadow_blocked,
        )


def read_final_counters(run_dir: Path) -> ShadowCounters | None:
    """The counters of the run's `final` event; None when the run has no
    final event or it lacks a counter (a renderer older than the counters)."""
    try:
        lines = RunLayout(run_dir).events.read_text().splitlines()
    except OSError:
        return None
    for line in reversed(lines):
        try:
            event = json.loads(line)
        except ValueError:
            continue
        if not isinstance(event, dict) or event.get("event") != "final":
            continue
        values = [event.get(k) for k in COUNTER_FIELDS]
        if not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in values):
            return None
        return ShadowCounters(*(int(v) for v in values if isinstance(v, int)))
    return None


def total(counters: Iterable[ShadowCounters | None]) -> ShadowCounters | None:
    """The sum over runs (replicates) that have counters; None if none has."""
    found = [c for c in counters if c is not None]
    if not found:
        return None
    out = found[0]
    for c in found[1:]:
        out = out + c
    return out
