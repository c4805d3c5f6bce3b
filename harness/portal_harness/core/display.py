"""Display encoding of linear radiance: one exposure per reference image,
then clipping and the sRGB transfer function of colour-science. Strategies
are always shown with their reference's exposure, never their own."""

from __future__ import annotations

import io
import warnings

import numpy as np
from PIL import Image

# colour-science warns at import that its SciPy features are missing (they
# are not used here): that warning only is silenced, and only for the import.
with warnings.catch_warnings():
    warnings.filterwarnings("ignore", message=r'"SciPy" related API features are not available')
    import colour

_SRGB = colour.RGB_COLOURSPACES["sRGB"]
# Rec.709/sRGB luminance weights: the Y row of the RGB -> XYZ matrix.
_LUMINANCE_WEIGHTS = np.asarray(_SRGB.matrix_RGB_to_XYZ)[1]


def luminance(rgb: np.ndarray) -> np.ndarray:
    y: np.ndarray = np.asarray(rgb, dtype=np.float64) @ _LUMINANCE_WEIGHTS
    return y


def exposure_from_reference(reference: np.ndarray, percentile: float = 99.0, white: float = 0.9) -> float:
    """The scale that maps the reference's `percentile` luminance to `white`;
    1 for a black image. Bright highlights above it clip, as in a photograph."""
    y = luminance(reference)
    level = float(np.percentile(y, percentile))
    return white / level if level > 0 and np.isfinite(level) else 1.0


def to_display(rgb: np.ndarray, exposure: float) -> np.ndarray:
    """Linear radiance -> sRGB-encoded values in [0, 1], shape (H, W, 3)."""
    linear = np.clip(np.asarray(rgb, dtype=np.float64) * exposure, 0.0, 1.0)
    return np.clip(np.asarray(colour.cctf_encoding(linear, function="sRGB")), 0.0, 1.0)


def to_srgb8(rgb: np.ndarray, exposure: float) -> np.ndarray:
    """`to_display` quantised to 8 bits, rounding to nearest: the pixels of
    every PNG the harness writes (service, report, viewer), so that a viewer
    that redoes the transform in the browser can be checked against them."""
    out: np.ndarray = np.floor(to_display(rgb, exposure) * 255.0 + 0.5).astype(np.uint8)
    return out


def to_png(rgb: np.ndarray, exposure: float) -> bytes:
    """A tone-mapped image as PNG bytes (8-bit sRGB, no alpha)."""
    buffer = io.BytesIO()
    Image.fromarray(to_srgb8(rgb, exposure)).save(buffer, format="PNG")
    return buffer.getvalue()
