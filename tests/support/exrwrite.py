"""Writes snapshots in the renderer's format for the tests and the fake
renderer, through portal_harness.core.exr (the one EXR writer). The reader is
checked against the real renderer's files in test_real_renderer.py and
against --describe's channel and attribute lists in test_contract.py; this
helper only adds the knobs the tests need: any header values, omitted
channels or attributes, extra channels."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from portal_harness.core import exr


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
    header = exr.SnapshotHeader(
        width=rgb.shape[1],
        height=rgb.shape[0],
        render_time_s=render_time_s,
        spp=spp,
        strategy=strategy,
        integrator=integrator,
        seed=seed,
        config_hash=config_hash,
        renderer_version=renderer_version,
        rays=rays,
        nonfinite_samples=nonfinite_samples,
    )
    channels = exr.snapshot_channels(exr.Snapshot(path=Path(path), header=header, rgb=rgb, variance=variance))
    channels.update(extra_channels or {})
    attributes = exr.snapshot_attributes(header)
    for name in omit:
        channels.pop(name, None)
        attributes.pop(name, None)
    exr.write_exr(path, channels, attributes)
