"""The live progress bar of one render (`portal-harness run`, `reference`),
driven by the renderer's JSON event stream."""

from __future__ import annotations

import sys
from typing import Any

from tqdm import tqdm


class RunProgress:
    """Live bar of one render: render time (or spp) against the target, with
    spp and the current snapshot as postfix. Created on the renderer's start
    event, so a cached run shows no bar."""

    def __init__(self, time_s: float, spp: int, enabled: bool = True) -> None:
        self.by_time = time_s > 0
        self.total = time_s if self.by_time else float(spp)
        self.enabled = enabled
        self.bar: tqdm[Any] | None = None

    def __call__(self, event: dict[str, Any]) -> None:
        kind = event.get("event")
        if kind == "start":
            self.bar = tqdm(
                total=self.total,
                unit="s" if self.by_time else "spp",
                disable=not self.enabled,
                file=sys.stderr,
                dynamic_ncols=True,
                bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} {unit} [{elapsed}<{remaining}{postfix}]",
            )
            self.bar.set_description(f"{event.get('strategy')} {event.get('width')}x{event.get('height')}")
            return
        if kind not in ("snapshot", "final") or self.bar is None:
            return
        value = float(event.get("time_s", 0.0)) if self.by_time else float(event.get("spp", 0))
        self.bar.n = min(value, self.total) if kind == "snapshot" else self.total
        snap = f"snapshot {event.get('index')}" if kind == "snapshot" else "final"
        self.bar.set_postfix_str(f"t={float(event.get('time_s', 0)):.2f}s spp={event.get('spp')} {snap}", refresh=False)
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
