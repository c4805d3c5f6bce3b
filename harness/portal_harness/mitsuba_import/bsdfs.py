"""Mitsuba BSDFs as the renderer's materials (diffuse, or ggx with Schlick
Fresnel on the albedo as F0)."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from portal_harness.mitsuba_import.params import Params
from portal_harness.mitsuba_import.report import Report
from portal_harness.mitsuba_import.values import RGB, Colours, number
from portal_harness.mitsuba_import.xmltree import Element

# The renderer has no delta (mirror) lobe. A smooth conductor becomes GGX
# with the smallest alpha the renderer accepts (config_scene.c: roughness in
# [0.001, 1]): the closest lobe to Mitsuba's mirror, so reflections keep
# their shape; --smooth-alpha trades that for less variance.
SMOOTH_CONDUCTOR_ALPHA = 0.001
ALPHA_MIN, ALPHA_MAX = 0.001, 1.0
DEFAULT_REFLECTANCE = 0.5  # Mitsuba's default diffuse reflectance

# Normal-incidence reflectance (linear RGB) of Mitsuba's named conductors,
# from published n, k data (Hoffman, "Physics and Math of Shading", 2015,
# table of F0 in linear values); the renderer's GGX uses Schlick's Fresnel
# with the albedo as F0. "none" is Mitsuba's perfect reflector.
CONDUCTOR_F0: dict[str, RGB] = {
    "none": (1.0, 1.0, 1.0),
    "Ag": (0.972, 0.960, 0.915),
    "Al": (0.913, 0.922, 0.924),
    "Au": (1.000, 0.782, 0.344),
    "Cr": (0.549, 0.556, 0.554),
    "Cu": (0.955, 0.638, 0.538),
    "Hg": (0.781, 0.780, 0.778),
    "Ni_palik": (0.660, 0.609, 0.526),
}
UNKNOWN_CONDUCTOR_F0 = 0.9
SKIP_TYPES = ("dielectric", "thindielectric", "roughdielectric", "null")
WRAPPER_TYPES = ("mask", "bumpmap", "normalmap")


@dataclass(frozen=True)
class Material:
    kind: str  # "diffuse" or "ggx"
    albedo: RGB
    roughness: float | None = None

    def to_yaml(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": self.kind, "albedo": [round(v, 6) for v in self.albedo]}
        if self.roughness is not None:
            out["roughness"] = self.roughness
        return out


@dataclass(frozen=True)
class Resolved:
    """A BSDF's material, or why shapes with it are skipped (material None)."""

    name: str
    material: Material | None
    skip_reason: str = ""


def f0_from_ior(eta: RGB, k: RGB) -> RGB:
    """Fresnel reflectance of a conductor at normal incidence, per channel."""
    f = [((n - 1) ** 2 + kk**2) / ((n + 1) ** 2 + kk**2) for n, kk in zip(eta, k, strict=True)]
    return (f[0], f[1], f[2])


def _clamp01(c: RGB, e: Element, report: Report) -> RGB:
    if all(0.0 <= v <= 1.0 for v in c):
        return c
    clamped = (min(max(c[0], 0.0), 1.0), min(max(c[1], 0.0), 1.0), min(max(c[2], 0.0), 1.0))
    report.warn(e.line, f"{e.describe()}: albedo {list(c)} clamped to [0, 1] (the renderer's range)")
    return clamped


def _mul(a: RGB, b: RGB) -> RGB:
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


class Bsdfs:
    """Converts BSDF elements once each (so each warning is given once,
    however many shapes share the BSDF) and names their materials."""

    def __init__(
        self, report: Report, colours: Colours, lookup: Callable[[Element], Element], smooth_alpha: float
    ) -> None:
        self.report = report
        self.colours = colours
        self.lookup = lookup
        self.smooth_alpha = smooth_alpha
        self.done: dict[int, Resolved] = {}
        self.names: set[str] = set()

    def _name(self, e: Element) -> str:
        base = re.sub(r"[^A-Za-z0-9_.-]", "_", e.attrs.get("id") or f"bsdf_line{e.line}")[:56] or "bsdf"
        name, n = base, 2
        while name in self.names:
            name, n = f"{base}_{n}", n + 1
        self.names.add(name)
        return name

    def resolve(self, e: Element) -> Resolved:
        if e.tag == "ref":
            e = self.lookup(e)
        if id(e) not in self.done:
            mat, why = self._convert(e, one_sided=True)
            self.done[id(e)] = Resolved(self._name(e), mat, why)
        return self.done[id(e)]

    def _colour(self, p: Params, name: str, default: float) -> RGB:
        c = p.get(name)
        return self.colours.of(c) if c is not None else (default, default, default)

    def _scalar(self, p: Params, name: str, default: float) -> float:
        c = p.get(name)
        if c is None:
            return default
        if c.tag in ("float", "integer"):
            return number(c, self.report)
        rgb = self.colours.of(c)
        return sum(rgb) / 3

    def _convert(self, e: Element, one_sided: bool) -> tuple[Material | None, str]:
        if e.tag == "ref":
            e = self.lookup(e)
        if e.tag != "bsdf":
            raise self.report.error(e.line, f"{e.describe()}: expected a <bsdf>")
        p = Params(e, self.report)
        t = e.type
        if t == "twosided":
            inner = p.children("bsdf") + p.unnamed_refs()
            p.warn_unused()
            if not inner:
                return Material("diffuse", (DEFAULT_REFLECTANCE,) * 3), ""
            if len(inner) > 1:
                self.report.warn(
                    inner[1].line,
                    f"{inner[1].describe()}: the back side's BSDF of a twosided is dropped "
                    "(the renderer uses the front one on both sides)",
                )
            return self._convert(inner[0], one_sided=False)
        if t in WRAPPER_TYPES:
            inner = p.children("bsdf") + p.unnamed_refs()
            p.use_all()
            self.report.warn(e.line, f"{e.describe()}: {t} dropped, its nested BSDF used as it is")
            if not inner:
                return Material("diffuse", (DEFAULT_REFLECTANCE,) * 3), ""
            return self._convert(inner[0], one_sided)
        if t in SKIP_TYPES:
            p.use_all()
            why = (
                "a null BSDF (invisible surface)"
                if t == "null"
                else f"a {t} BSDF (the renderer has no transmission: the surface would block every shadow ray)"
            )
            return None, why
        if one_sided:
            self.report.warn(
                e.line, f"{e.describe()}: one-sided in Mitsuba (black from behind); the renderer shades both sides"
            )
        if t == "diffuse":
            albedo = self._colour(p, "reflectance", DEFAULT_REFLECTANCE)
            p.warn_unused()
            return Material("diffuse", _clamp01(albedo, e, self.report)), ""
        if t in ("plastic", "roughplastic"):
            albedo = self._colour(p, "diffuse_reflectance", DEFAULT_REFLECTANCE)
            p.use_all()
            self.report.warn(
                e.line,
                f"{e.describe()}: {t} approximated by a diffuse material with its "
                f"diffuse_reflectance {[round(v, 6) for v in albedo]}; the specular coat is dropped",
            )
            return Material("diffuse", _clamp01(albedo, e, self.report)), ""
        if t in ("conductor", "roughconductor"):
            return self._conductor(e, p, t == "roughconductor"), ""
        p.use_all()
        g = DEFAULT_REFLECTANCE
        self.report.warn(e.line, f"{e.describe()}: BSDF type {t!r} not supported: replaced by a diffuse grey {g:g}")
        return Material("diffuse", (g, g, g)), ""

    def _conductor(self, e: Element, p: Params, rough: bool) -> Material:
        spec = self._colour(p, "specular_reflectance", 1.0)
        eta, k, named = p.get("eta"), p.get("k"), p.get("material")
        if eta is not None or k is not None:
            f0 = f0_from_ior(
                self.colours.of(eta) if eta is not None else (0.0, 0.0, 0.0),
                self.colours.of(k) if k is not None else (1.0, 1.0, 1.0),
            )
            how = "eta and k"
        else:
            metal = named.attrs.get("value", "none") if named is not None else "none"
            if metal in CONDUCTOR_F0:
                f0 = CONDUCTOR_F0[metal]
            else:
                f0 = (UNKNOWN_CONDUCTOR_F0,) * 3
                self.report.warn(
                    named.line if named is not None else e.line,
                    f"conductor material {metal!r} not in the importer's table: F0 grey {UNKNOWN_CONDUCTOR_F0} used",
                )
            how = f"material {metal}"
        albedo = _clamp01(_mul(f0, spec), e, self.report)
        if not rough:
            alpha = self.smooth_alpha
            self.report.warn(
                e.line,
                f"{e.describe()}: smooth conductor approximated by ggx with roughness {alpha:g} (the renderer has no "
                f"mirror lobe) and Schlick Fresnel with F0 {[round(v, 4) for v in albedo]} from its {how}",
            )
        else:
            au, av = p.get("alpha_u"), p.get("alpha_v")
            if au is not None or av is not None:
                a_u = self._scalar_of(au, 0.1)
                a_v = self._scalar_of(av, 0.1)
                alpha = math.sqrt(a_u * a_v)
                self.report.warn(
                    e.line,
                    f"{e.describe()}: anisotropic alpha_u {a_u:g}, alpha_v {a_v:g} approximated "
                    f"by the isotropic alpha {alpha:g}",
                )
            else:
                alpha = self._scalar(p, "alpha", 0.1)
            dist = p.get("distribution")
            dist_name = dist.attrs.get("value", "beckmann") if dist is not None else "beckmann"
            if dist_name != "ggx":
                self.report.warn(
                    dist.line if dist is not None else e.line,
                    f"{e.describe()}: {dist_name} distribution (Mitsuba's default when none is given) "
                    "approximated by ggx with the same alpha",
                )
            if not ALPHA_MIN <= alpha <= ALPHA_MAX:
                clamped = min(max(alpha, ALPHA_MIN), ALPHA_MAX)
                self.report.warn(
                    e.line,
                    f"{e.describe()}: alpha {alpha:g} clamped to {clamped:g} (the renderer's "
                    f"range is [{ALPHA_MIN:g}, {ALPHA_MAX:g}])",
                )
                alpha = clamped
            self.report.warn(
                e.line,
                f"{e.describe()}: conductor Fresnel approximated by Schlick's with F0 "
                f"{[round(v, 4) for v in albedo]} from its {how}",
            )
        p.warn_unused()
        return Material("ggx", albedo, round(alpha, 6))

    def _scalar_of(self, c: Element | None, default: float) -> float:
        if c is None:
            return default
        if c.tag in ("float", "integer"):
            return number(c, self.report)
        return sum(self.colours.of(c)) / 3
