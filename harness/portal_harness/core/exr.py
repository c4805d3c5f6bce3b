"""Reading and writing the renderer's EXR snapshots: the only module that
opens EXR files (the tests' writer and tools/ use it too).

The format (renderer contract): float channels R, G, B (running mean of
radiance) and variance.R/G/B (variance of that mean), with the header
attributes render_time_s, spp, strategy, integrator, sampler, seed, config_hash,
renderer_version, rays and nonfinite_samples (sampler may be absent: files
written before it existed are independent); optionally (render.aov.region)
the region AOV: one float channel per antishadow region class
(REGION_CLASSES, `region.<class>`), the fraction of the pixel's samples whose
primary hit fell in that class. A file that cannot be read
completely, lacks a channel or attribute, or holds non-finite pixels raises
CorruptExrError, so that it is reported and never averaged into a metric.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import OpenEXR

from portal_harness.core.errors import CorruptExrError

RGB_CHANNELS = ("R", "G", "B")
VARIANCE_CHANNELS = ("variance.R", "variance.G", "variance.B")
# The renderer's region classes, in its order (renderer/src/render/aov.h).
REGION_CLASSES = ("outside", "anti_umbra", "anti_penumbra", "anti_antumbra", "inside", "emitter", "miss")
REGION_CHANNELS = tuple(f"region.{c}" for c in REGION_CLASSES)


@dataclass(frozen=True)
class SnapshotHeader:
    """The header attributes of one snapshot, typed."""

    width: int
    height: int
    render_time_s: float
    spp: int
    strategy: str
    integrator: str
    seed: int
    config_hash: str
    renderer_version: str
    rays: float
    nonfinite_samples: float
    # render.sampler; files written before the attribute existed are independent.
    sampler: str = "independent"


@dataclass(frozen=True, eq=False)
class Snapshot:
    """One snapshot: rgb and variance are float64 arrays of shape (height, width, 3),
    row 0 at the top of the image."""

    path: Path
    header: SnapshotHeader
    rgb: np.ndarray
    variance: np.ndarray
    # (height, width, len(REGION_CLASSES)) fractions, or None without the AOV.
    regions: np.ndarray | None = None


def _scalar(value: Any) -> float:
    """A C double attribute arrives as a one-element float64 array."""
    return float(np.asarray(value, dtype=np.float64).reshape(-1)[0])


def _header_from(path: Path, raw: dict[str, Any]) -> SnapshotHeader:
    try:
        lo, hi = raw["dataWindow"]
        width = int(hi[0]) - int(lo[0]) + 1
        height = int(hi[1]) - int(lo[1]) + 1
        return SnapshotHeader(
            width=width,
            height=height,
            render_time_s=_scalar(raw["render_time_s"]),
            spp=int(raw["spp"]),
            strategy=str(raw["strategy"]),
            integrator=str(raw["integrator"]),
            seed=int(str(raw["seed"])),
            config_hash=str(raw["config_hash"]),
            renderer_version=str(raw["renderer_version"]),
            rays=_scalar(raw["rays"]),
            nonfinite_samples=_scalar(raw["nonfinite_samples"]),
            sampler=str(raw.get("sampler", "independent")),
        )
    except KeyError as missing:
        raise CorruptExrError(str(path), f"missing header attribute {missing}") from None
    except (TypeError, ValueError, IndexError) as bad:
        raise CorruptExrError(str(path), f"malformed header attribute ({bad})") from None


def _raw_header(p: Path) -> dict[str, Any]:
    try:
        with OpenEXR.File(str(p), header_only=True) as f:
            return dict(f.header())
    except (RuntimeError, ValueError, OSError) as e:
        raise CorruptExrError(str(p), str(e) or type(e).__name__) from None


def read_header(path: Path | str) -> SnapshotHeader:
    """The header of a snapshot, without reading its pixels."""
    p = Path(path)
    return _header_from(p, _raw_header(p))


# Attributes every OpenEXR file has, whoever wrote it.
STANDARD_ATTRIBUTES = frozenset(
    {
        "channels",
        "compression",
        "dataWindow",
        "displayWindow",
        "lineOrder",
        "pixelAspectRatio",
        "screenWindowCenter",
        "screenWindowWidth",
        "type",
    }
)


def read_names(path: Path | str) -> tuple[list[str], list[str]]:
    """The channel names and the non-standard header attribute names of an
    EXR file, sorted, without reading its pixels (for contract checks)."""
    raw = _raw_header(Path(path))
    channels = sorted(c.name for c in raw.get("channels", []))
    return channels, sorted(set(raw) - STANDARD_ATTRIBUTES)


def _stack(path: Path, channels: dict[str, Any], names: tuple[str, ...], height: int, width: int) -> np.ndarray:
    planes = []
    for name in names:
        if name not in channels:
            raise CorruptExrError(str(path), f"missing channel {name!r} (has {sorted(channels)})")
        plane = np.asarray(channels[name].pixels, dtype=np.float64)
        if plane.shape != (height, width):
            raise CorruptExrError(str(path), f"channel {name!r} has shape {plane.shape}, expected {(height, width)}")
        planes.append(plane)
    return np.stack(planes, axis=-1)


def read_snapshot(path: Path | str) -> Snapshot:
    """Reads a whole snapshot; raises CorruptExrError if anything is missing or unreadable."""
    p = Path(path)
    try:
        with OpenEXR.File(str(p), separate_channels=True) as f:
            raw = dict(f.header())
            channels = dict(f.channels())
            header = _header_from(p, raw)
            rgb = _stack(p, channels, RGB_CHANNELS, header.height, header.width)
            variance = _stack(p, channels, VARIANCE_CHANNELS, header.height, header.width)
            regions = (
                _stack(p, channels, REGION_CHANNELS, header.height, header.width)
                if any(name in channels for name in REGION_CHANNELS)
                else None
            )
    except CorruptExrError:
        raise
    except (RuntimeError, ValueError, OSError, IndexError, KeyError) as e:
        raise CorruptExrError(str(p), str(e) or type(e).__name__) from None
    if not (np.all(np.isfinite(rgb)) and np.all(np.isfinite(variance))):
        raise CorruptExrError(str(p), "non-finite pixel values")
    if regions is not None and not np.all(np.isfinite(regions)):
        raise CorruptExrError(str(p), "non-finite region fractions")
    return Snapshot(path=p, header=header, rgb=rgb, variance=variance, regions=regions)


def snapshot_attributes(header: SnapshotHeader) -> dict[str, Any]:
    """The header attributes of a snapshot as the renderer writes them."""
    return {
        # C doubles arrive and must leave as one-element float64 arrays (a
        # Python float would be stored as a 32-bit float).
        "render_time_s": np.array([header.render_time_s], dtype=np.float64),
        "spp": int(min(header.spp, 2**31 - 1)),
        "strategy": header.strategy,
        "integrator": header.integrator,
        "sampler": header.sampler,
        "seed": str(header.seed),
        "config_hash": header.config_hash,
        "renderer_version": header.renderer_version,
        "rays": np.array([header.rays], dtype=np.float64),
        "nonfinite_samples": np.array([header.nonfinite_samples], dtype=np.float64),
    }


def write_exr(path: Path | str, channels: dict[str, np.ndarray], attributes: dict[str, Any]) -> None:
    """Writes float channels (2-D arrays, row 0 at the top) and header
    attributes as a ZIP-compressed scanline EXR: to a temporary name,
    fsynced, then renamed, so that a reader never sees a partial file."""
    planes = {name: np.ascontiguousarray(plane, dtype=np.float32) for name, plane in channels.items()}
    header: dict[str, Any] = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **attributes}
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        OpenEXR.File(header, planes).write(str(tmp))
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def snapshot_channels(snapshot: Snapshot) -> dict[str, np.ndarray]:
    """The channels of a snapshot by EXR name: RGB, variance and (if present) the region AOV."""
    channels: dict[str, np.ndarray] = {}
    for names, planes in (
        (RGB_CHANNELS, snapshot.rgb),
        (VARIANCE_CHANNELS, snapshot.variance),
        (REGION_CHANNELS, snapshot.regions),
    ):
        if planes is None:
            continue
        for i, name in enumerate(names):
            channels[name] = planes[..., i]
    return channels


def write_snapshot(path: Path | str, snapshot: Snapshot) -> None:
    """Writes `snapshot` in the renderer's format (used for the combined
    reference, which no single render produced)."""
    write_exr(path, snapshot_channels(snapshot), snapshot_attributes(snapshot.header))
