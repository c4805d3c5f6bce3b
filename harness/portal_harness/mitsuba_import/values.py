"""Scalar, vector and colour parameters of Mitsuba elements, textures
reduced to their mean colour."""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from portal_harness.mitsuba_import.report import Report
from portal_harness.mitsuba_import.xmltree import Element

RGB = tuple[float, float, float]
# What a texture stands for when its image cannot be read: Mitsuba's own
# default reflectance, so a scene without its textures looks as Mitsuba's
# untextured preview would.
MISSING_TEXTURE_GREY = 0.5
PARAM_TAGS = ("float", "integer", "boolean", "string", "rgb", "srgb", "spectrum", "vector", "point", "texture", "ref")


def numbers(text: str, report: Report, line: int) -> list[float]:
    """The numbers of a comma- and/or space-separated list."""
    try:
        return [float(t) for t in re.split(r"[,\s]+", text.strip()) if t]
    except ValueError:
        raise report.error(line, f"expected numbers, got {text!r}") from None


def number(e: Element, report: Report) -> float:
    vals = numbers(e.attrs.get("value", ""), report, e.line)
    if len(vals) != 1:
        raise report.error(e.line, f"{e.describe()}: expected one number, got {e.attrs.get('value', '')!r}")
    return vals[0]


def boolean(e: Element, report: Report) -> bool:
    text = e.attrs.get("value", "").strip().lower()
    if text not in ("true", "false"):
        raise report.error(e.line, f"{e.describe()}: expected true or false, got {text!r}")
    return text == "true"


def vec3(e: Element, report: Report, key: str = "value", default: float = 0.0) -> tuple[float, float, float]:
    """A point or vector: `value="x, y, z"` or x/y/z attributes (missing ones `default`)."""
    if key in e.attrs:
        vals = numbers(e.attrs[key], report, e.line)
        if len(vals) == 1:
            vals = vals * 3
        if len(vals) != 3:
            raise report.error(e.line, f"{e.describe()}: expected 3 numbers in {key}, got {e.attrs[key]!r}")
        return (vals[0], vals[1], vals[2])
    try:
        xyz = [float(e.attrs.get(k, default)) for k in ("x", "y", "z")]
    except ValueError:
        raise report.error(e.line, f"{e.describe()}: expected numbers in x, y, z") from None
    return (xyz[0], xyz[1], xyz[2])


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


@dataclass
class Colours:
    """Resolves colour-valued parameters; `lookup` finds `<ref id>` targets,
    `base` is the folder that texture file names are relative to."""

    report: Report
    base: Path
    lookup: Callable[[Element], Element]

    def of(self, e: Element) -> RGB:
        """The linear RGB of a colour parameter (rgb, srgb, float, spectrum,
        texture or a ref to a texture); approximations are warned about."""
        if e.tag == "ref":
            return self.of(self.lookup(e))
        if e.tag == "rgb":
            return _triple(numbers(e.attrs.get("value", ""), self.report, e.line), e, self.report)
        if e.tag == "srgb":
            lin = srgb_to_linear(
                np.array(_triple(numbers(e.attrs.get("value", ""), self.report, e.line), e, self.report))
            )
            return (float(lin[0]), float(lin[1]), float(lin[2]))
        if e.tag in ("float", "integer"):
            v = number(e, self.report)
            return (v, v, v)
        if e.tag == "spectrum" and "value" in e.attrs and e.type == "":
            return self._spectrum(e)
        if e.tag in ("texture", "spectrum"):
            return self.texture(e)
        raise self.report.error(e.line, f"{e.describe()}: expected a colour (rgb, srgb, float, spectrum or texture)")

    def _spectrum(self, e: Element) -> RGB:
        text = e.attrs["value"]
        if ":" not in text:
            v = number(e, self.report)
            return (v, v, v)
        pairs = [p.split(":") for p in re.split(r"[,\s]+", text.strip()) if p]
        try:
            values = [float(v) for _, v in pairs]
        except ValueError:
            raise self.report.error(e.line, f"{e.describe()}: expected wavelength:value pairs, got {text!r}") from None
        mean = float(np.mean(values))
        self.report.warn(e.line, f"{e.describe()}: spectrum approximated by the grey of its mean value {mean:g}")
        return (mean, mean, mean)

    def texture(self, e: Element) -> RGB:
        """A texture's mean colour: the image's for a readable bitmap, the
        two colours' for a checkerboard, else the documented grey."""
        if e.type == "checkerboard":
            c0, c1 = (0.4, 0.4, 0.4), (0.2, 0.2, 0.2)
            for child in e.children:
                if child.name == "color0":
                    c0 = self.of(child)
                elif child.name == "color1":
                    c1 = self.of(child)
            mean = _mean(c0, c1)
            self.report.warn(e.line, f"{e.describe()}: checkerboard texture replaced by its mean colour {_fmt(mean)}")
            return mean
        if e.type == "bitmap":
            filename = next((c.attrs.get("value", "") for c in e.children if c.name == "filename"), "")
            raw = any(c.name == "raw" and boolean(c, self.report) for c in e.children)
            path = self.base / filename
            mean_or_why = image_mean(path, raw)
            if isinstance(mean_or_why, tuple):
                self.report.warn(
                    e.line, f"{e.describe()}: bitmap {filename} replaced by its mean colour {_fmt(mean_or_why)}"
                )
                return mean_or_why
            g = MISSING_TEXTURE_GREY
            self.report.warn(
                e.line,
                f"{e.describe()}: bitmap {filename} {mean_or_why}: replaced by the grey {g:g} (Mitsuba's default)",
            )
            return (g, g, g)
        g = MISSING_TEXTURE_GREY
        self.report.warn(e.line, f"{e.describe()}: texture type {e.type!r} not supported: replaced by the grey {g:g}")
        return (g, g, g)


def _triple(vals: list[float], e: Element, report: Report) -> RGB:
    if len(vals) == 1:
        vals = vals * 3
    if len(vals) != 3:
        raise report.error(e.line, f"{e.describe()}: expected 1 or 3 numbers, got {e.attrs.get('value', '')!r}")
    return (vals[0], vals[1], vals[2])


def _mean(a: RGB, b: RGB) -> RGB:
    return ((a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2)


def _fmt(c: RGB) -> str:
    return "[" + ", ".join(f"{v:.4g}" for v in c) + "]"


def image_mean(path: Path, raw: bool) -> RGB | str:
    """The mean linear RGB of an image file, or why it could not be read.
    EXR is linear; 8-bit PNG and JPEG are sRGB-encoded (Mitsuba decodes them
    unless raw="true")."""
    if not path.is_file():
        return "is missing"
    try:
        if path.suffix.lower() == ".exr":
            import OpenEXR

            with OpenEXR.File(str(path), separate_channels=True) as f:
                ch = dict(f.channels())
                names = [n for n in ("R", "G", "B") if n in ch] or [next(iter(ch))]
                planes = [np.asarray(ch[n].pixels, dtype=np.float64) for n in names]
            rgb = np.stack(planes * (3 if len(planes) == 1 else 1), axis=-1)[..., :3]
        else:
            import matplotlib.image

            decoded = np.asarray(matplotlib.image.imread(str(path)))
            img = decoded.astype(np.float64)
            if decoded.dtype.kind != "f":
                img = img / float(np.iinfo(decoded.dtype).max)
            if img.ndim == 2:
                img = np.stack([img] * 3, axis=-1)
            rgb = img[..., :3]
            if not raw:
                rgb = srgb_to_linear(rgb)
    except Exception as e:  # any decoder failure: the texture falls back to grey, with the reason
        return f"cannot be read ({type(e).__name__}: {e})"
    m = rgb.reshape(-1, 3).mean(axis=0)
    return (float(m[0]), float(m[1]), float(m[2]))
