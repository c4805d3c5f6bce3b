"""A stored render's final image for the API: the EXR itself, or a PNG
tone-mapped with the exposure of the reference it is measured against
(display.py: strategies are shown with their reference's exposure, never
their own), so that PNGs of one point compare pixel for pixel."""

from __future__ import annotations

import re
import threading
from collections import OrderedDict
from pathlib import Path

from portal_harness.core import display, exr
from portal_harness.core.paths import ResultsLayout, RunLayout

_KEY = re.compile(r"^[A-Za-z0-9_]{1,64}$")
CACHE_ENTRIES = 64


def valid_key(key: str) -> bool:
    """A run key as the store names folders: letters, digits, underscores (never a path)."""
    return bool(_KEY.match(key))


def find_run(layout: ResultsLayout, key: str) -> RunLayout | None:
    """The installed folder of a run or reference with this key and a final image."""
    if not valid_key(key):
        return None
    for reference in (False, True):
        run = layout.run(key, reference)
        if run.final.is_file():
            return run
    return None


_IMAGE = re.compile(r"^[A-Za-z0-9_.-]{1,128}\.exr$")


def image_of(run: RunLayout, name: str | None) -> Path | None:
    """The run's final image, or the snapshot of its folder named `name`
    (a file name such as the viewer's bundle gives, never a path)."""
    if name is None:
        return run.final
    if not _IMAGE.match(name) or name.startswith("."):
        return None
    path = run.dir / name
    return path if path.is_file() else None


class PngCache:
    """PNGs by (final image, its mtime, the reference's), at most CACHE_ENTRIES."""

    def __init__(self) -> None:
        self._by: OrderedDict[tuple[str, int, str, int], bytes] = OrderedDict()
        self._lock = threading.Lock()

    def png(self, image: Path, reference: Path | None) -> bytes:
        ref = reference if reference is not None and reference.is_file() else image
        cache_key = (str(image), image.stat().st_mtime_ns, str(ref), ref.stat().st_mtime_ns)
        with self._lock:
            found = self._by.get(cache_key)
            if found is not None:
                self._by.move_to_end(cache_key)
                return found
        rgb = exr.read_snapshot(image).rgb
        exposure = display.exposure_from_reference(rgb if ref == image else exr.read_snapshot(ref).rgb)
        data = display.to_png(rgb, exposure)
        with self._lock:
            self._by[cache_key] = data
            while len(self._by) > CACHE_ENTRIES:
                self._by.popitem(last=False)
        return data
