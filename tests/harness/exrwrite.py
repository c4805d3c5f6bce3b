"""Writes EXRs in the renderer's exact format (renderer contract), for the
tests and the fake renderer. Independent of portal_harness.exr on purpose:
the reader is tested against this writer and against the real renderer."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import OpenEXR


def write_snapshot(
    path: Path | str,
    rgb: np.ndarray,
    variance: np.ndarray,
    render_time_s: float = 1.0,
    spp: int = 16,
    strategy: str = "light",
    integrator: str = "direct",
    seed: int = 1,
    config_hash: str = "0123456789abcdef",
    renderer_version: str = "0.1.0-fake",
    rays: float = 1000.0,
    nonfinite_samples: float = 0.0,
    omit: tuple[str, ...] = (),
    extra_channels: dict[str, np.ndarray] | None = None,
) -> None:
    """Writes atomically (temporary name, then rename), like the renderer."""
    rgb = np.asarray(rgb, dtype=np.float32)
    variance = np.asarray(variance, dtype=np.float32)
    channels = {
        "R": rgb[..., 0].copy(), "G": rgb[..., 1].copy(), "B": rgb[..., 2].copy(),
        "variance.R": variance[..., 0].copy(), "variance.G": variance[..., 1].copy(),
        "variance.B": variance[..., 2].copy(),
    }
    for name, plane in (extra_channels or {}).items():
        channels[name] = np.asarray(plane, dtype=np.float32).copy()
    header: dict[str, Any] = {
        "compression": OpenEXR.ZIP_COMPRESSION,
        "type": OpenEXR.scanlineimage,
        # C doubles: one-element float64 arrays (a Python float would be stored as a 32-bit float).
        "render_time_s": np.array([render_time_s], dtype=np.float64),
        "spp": int(spp),
        "strategy": strategy,
        "integrator": integrator,
        "seed": str(seed),
        "config_hash": config_hash,
        "renderer_version": renderer_version,
        "rays": np.array([rays], dtype=np.float64),
        "nonfinite_samples": np.array([nonfinite_samples], dtype=np.float64),
    }
    for name in omit:
        channels.pop(name, None)
        header.pop(name, None)
    p = Path(path)
    tmp = p.with_name(f"{p.name}.tmp-{os.getpid()}")
    OpenEXR.File(header, channels).write(str(tmp))
    os.replace(tmp, p)
