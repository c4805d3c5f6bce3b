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
zero density) and traced no ray either. A shading point where the
strategy knows that no direction reaches the light (outside every
antishadow, for the antishadow strategies; behind a one-sided light or
with the whole light below its horizon, for the light-only strategies
from renderer 0.11.4 on) draws no sample and is not counted at all;
`camera_samples` (the final spp times the image's pixels, from the `start`
event) says how many samples were drawn per camera sample.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from portal_harness.core.paths import RunLayout
from portal_harness.execution.renderer import parse_events

COUNTER_FIELDS = ("light_samples", "light_missed", "shadow_rays", "shadow_blocked")


@dataclass(frozen=True)
class ShadowCounters:
    light_samples: int
    light_missed: int
    shadow_rays: int
    shadow_blocked: int
    camera_samples: int = 0  # spp x width x height; 0 when the events do not say

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
            self.camera_samples + other.camera_samples,
        )


def _events(run_dir: Path) -> list[dict[str, Any]]:
    try:
        lines = RunLayout(run_dir).events.read_text().splitlines()
    except OSError:
        return []
    return parse_events(lines)


def _count(value: Any) -> int | None:
    return int(value) if isinstance(value, int) and not isinstance(value, bool) and value >= 0 else None


def read_final_counters(run_dir: Path) -> ShadowCounters | None:
    """The counters of the run's `final` event; None when the run has no
    final event or it lacks a counter (a renderer older than the counters)."""
    events = _events(run_dir)
    final = next((e for e in reversed(events) if e.get("event") == "final"), None)
    if final is None:
        return None
    values = {k: _count(final.get(k)) for k in COUNTER_FIELDS}
    counts = {k: v for k, v in values.items() if v is not None}
    if len(counts) != len(COUNTER_FIELDS):
        return None
    start = next((e for e in events if e.get("event") == "start"), {})
    camera = 1
    for factor in (_count(final.get("spp")), _count(start.get("width")), _count(start.get("height"))):
        camera = camera * factor if factor is not None else 0
    return ShadowCounters(**counts, camera_samples=camera)


def total(counters: Iterable[ShadowCounters | None]) -> ShadowCounters | None:
    """The sum over runs (replicates) that have counters; None if none has."""
    found = [c for c in counters if c is not None]
    if not found:
        return None
    out = found[0]
    for c in found[1:]:
        out = out + c
    return out
