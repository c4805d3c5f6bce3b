"""exr.py reads the renderer's snapshot format, header included, and refuses
anything incomplete."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from portal_harness.core import exr
from portal_harness.core.errors import CorruptExrError


def test_01_reads_channels_by_name_and_typed_header(
    tmp_path: Path, rng: np.random.Generator, write_exr: Callable[..., None]
) -> None:
    rgb = rng.random((5, 7, 3)).astype(np.float32)
    var = rng.random((5, 7, 3)).astype(np.float32) * 1e-3
    path = tmp_path / "s.exr"
    write_exr(
        path,
        rgb,
        var,
        render_time_s=1.234567890123,
        spp=48,
        strategy="portal",
        integrator="path",
        seed=18446744073709551615,
        config_hash="00ff00ff00ff00ff",
        renderer_version="9.9.9",
        rays=12345678901.0,
        nonfinite_samples=3.0,
    )
    snap = exr.read_snapshot(path)
    np.testing.assert_array_equal(snap.rgb, rgb.astype(np.float64))
    np.testing.assert_array_equal(snap.variance, var.astype(np.float64))
    h = snap.header
    assert (h.width, h.height) == (7, 5)
    assert h.render_time_s == 1.234567890123  # a double survives exactly
    assert h.spp == 48 and h.strategy == "portal" and h.integrator == "path"
    assert h.seed == 18446744073709551615  # a 64-bit seed travels as a decimal string
    assert h.config_hash == "00ff00ff00ff00ff" and h.renderer_version == "9.9.9"
    assert h.rays == 12345678901.0 and h.nonfinite_samples == 3.0
    assert exr.read_header(path) == h


def test_02_row_zero_is_the_top_of_the_image(tmp_path: Path, write_exr: Callable[..., None]) -> None:
    rgb = np.zeros((4, 3, 3), np.float32)
    rgb[0, 2] = (1, 2, 3)
    write_exr(tmp_path / "a.exr", rgb, np.zeros_like(rgb))
    snap = exr.read_snapshot(tmp_path / "a.exr")
    assert tuple(snap.rgb[0, 2]) == (1.0, 2.0, 3.0)


@pytest.mark.parametrize("keep_fraction", [0.05, 0.5, 0.97])
def test_03_truncated_file_is_corrupt(
    tmp_path: Path, rng: np.random.Generator, write_exr: Callable[..., None], keep_fraction: float
) -> None:
    rgb = rng.random((64, 64, 3)).astype(np.float32)
    path = tmp_path / "full.exr"
    write_exr(path, rgb, rgb * 0.01)
    data = path.read_bytes()
    cut = tmp_path / "cut.exr"
    cut.write_bytes(data[: int(len(data) * keep_fraction)])
    with pytest.raises(CorruptExrError) as info:
        exr.read_snapshot(cut)
    assert str(cut) in str(info.value)


@pytest.mark.parametrize("missing", ["variance.G", "R", "render_time_s", "spp", "config_hash"])
def test_04_missing_channel_or_attribute_is_reported(
    tmp_path: Path, write_exr: Callable[..., None], missing: str
) -> None:
    rgb = np.ones((2, 2, 3), np.float32)
    write_exr(tmp_path / "m.exr", rgb, rgb, omit=(missing,))
    with pytest.raises(CorruptExrError, match=missing.replace(".", r"\.")):
        exr.read_snapshot(tmp_path / "m.exr")


def test_05_non_finite_pixels_are_corrupt(tmp_path: Path, write_exr: Callable[..., None]) -> None:
    rgb = np.ones((2, 2, 3), np.float32)
    rgb[1, 1, 2] = np.nan
    write_exr(tmp_path / "n.exr", rgb, np.zeros_like(rgb))
    with pytest.raises(CorruptExrError, match="non-finite"):
        exr.read_snapshot(tmp_path / "n.exr")


def test_06_not_an_exr(tmp_path: Path) -> None:
    (tmp_path / "x.exr").write_text("hello")
    with pytest.raises(CorruptExrError):
        exr.read_header(tmp_path / "x.exr")
    with pytest.raises(CorruptExrError):
        exr.read_snapshot(tmp_path / "missing.exr")
