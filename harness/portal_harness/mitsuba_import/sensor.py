"""The perspective sensor (camera, film, sampler) and the integrator."""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from portal_harness.mitsuba_import.params import Params
from portal_harness.mitsuba_import.report import Report
from portal_harness.mitsuba_import.transforms import parse_transform
from portal_harness.mitsuba_import.values import number
from portal_harness.mitsuba_import.xmltree import Element

FILM_DEFAULT = (768, 576)  # Mitsuba's hdrfilm default size
DEFAULT_SPP = 64  # when the scene has no sampler (Mitsuba's own default, 4, is too noisy to be useful)
# Mitsuba's path tracer defaults to unbounded paths (max_depth -1); the
# renderer needs a bound, and Russian roulette makes deeper paths rare.
UNBOUNDED_DEPTH = 64


def fov_y(fov: float, axis: str, width: int, height: int) -> float:
    """The vertical field of view (degrees) of a Mitsuba fov measured along
    `axis` (x, y, diagonal, smaller or larger) for a width x height film."""
    aspect = width / height
    if axis == "smaller":
        axis = "y" if aspect > 1 else "x"
    elif axis == "larger":
        axis = "x" if aspect > 1 else "y"
    t = math.tan(math.radians(fov) / 2)
    if axis == "x":
        t /= aspect
    elif axis == "diagonal":
        t /= math.sqrt(1 + aspect * aspect)
    return math.degrees(2 * math.atan(t))


def _focal_fov(text: str, e: Element, report: Report) -> float:
    """Mitsuba's focal_length ("50mm"): the diagonal fov of a 36 x 24 mm film."""
    m = re.fullmatch(r"\s*([0-9.eE+-]+)\s*(mm)?\s*", text)
    if not m:
        raise report.error(e.line, f"{e.describe()}: expected a focal length like 50mm, got {text!r}")
    return math.degrees(2 * math.atan(math.hypot(36, 24) / (2 * float(m.group(1)))))


def convert_film(e: Element | None, report: Report) -> tuple[int, int]:
    if e is None:
        return FILM_DEFAULT
    p = Params(e, report)
    size = []
    for key, default in zip(("width", "height"), FILM_DEFAULT, strict=True):
        c = p.get(key)
        v = number(c, report) if c is not None else default
        if v != int(v) or v < 1:
            raise report.error(c.line if c is not None else e.line, f"film {key} {v:g}: expected a positive integer")
        size.append(int(v))
    width, height = size
    crop = {k: p.get(f"crop_{k}") for k in ("offset_x", "offset_y", "width", "height")}
    vals = {k: number(c, report) for k, c in crop.items() if c is not None}
    full = {"offset_x": 0, "offset_y": 0, "width": width, "height": height}
    if any(vals[k] != full[k] for k in vals):
        line = next(c.line for c in crop.values() if c is not None)
        report.warn(line, f"{e.describe()}: crop window {vals} ignored: the whole {width}x{height} image is rendered")
    for rf in p.children("rfilter"):
        if rf.type != "box":
            report.warn(
                rf.line, f"{rf.describe()}: reconstruction filter ignored: each pixel averages its own samples (box)"
            )
    if e.type not in ("hdrfilm", "ldrfilm", ""):
        report.warn(e.line, f"{e.describe()}: film type {e.type!r}: only its size is used")
    p.warn_unused()
    return width, height


def convert_sensor(e: Element, report: Report) -> tuple[dict[str, Any], tuple[int, int], dict[str, Any]]:
    """(camera, (width, height), render keys from the sampler) of a perspective sensor."""
    p = Params(e, report)
    if e.type == "thinlens":
        report.warn(e.line, f"{e.describe()}: thin lens approximated by a pinhole (no depth of field)")
        p.get("aperture_radius")
        p.get("focus_distance")
    films = p.children("film")
    width, height = convert_film(films[0] if films else None, report)
    fov_el, axis_el, focal_el = p.get("fov"), p.get("fov_axis"), p.get("focal_length")
    axis = axis_el.attrs.get("value", "x").lower() if axis_el is not None else "x"
    if axis not in ("x", "y", "diagonal", "smaller", "larger"):
        raise report.error(
            axis_el.line if axis_el else e.line, f"fov_axis {axis!r}: expected x, y, diagonal, smaller or larger"
        )
    if fov_el is not None:
        fov = number(fov_el, report)
    else:
        fov = _focal_fov(focal_el.attrs.get("value", "50mm") if focal_el is not None else "50mm", e, report)
        axis = "diagonal"
    fy = fov_y(fov, axis, width, height)
    if not 0 < fy < 180:
        raise report.error(
            fov_el.line if fov_el else e.line,
            f"field of view {fov:g} gives fov_y {fy:g} (expected between 0 and 180 degrees)",
        )

    tr = p.get("to_world")
    m = parse_transform(tr, report)[1] if tr is not None else np.eye(4)
    cols = m[:3, :3]
    position = m[:3, 3]
    forward, up = cols[:, 2], cols[:, 1]
    if not np.allclose(cols.T @ cols, np.diag(np.diag(cols.T @ cols)), atol=1e-6) or not np.allclose(
        np.linalg.norm(cols, axis=0), 1.0, atol=1e-6
    ):
        report.warn(
            tr.line if tr is not None else e.line,
            f"{e.describe()}: scale or shear in the camera's "
            "to_world dropped (only its position and orientation are kept)",
        )
    if np.linalg.det(cols) < 0:
        report.warn(
            tr.line if tr is not None else e.line,
            f"{e.describe()}: the camera's to_world mirrors the "
            "image; the renderer's camera does not: the image is mirrored left-right relative to Mitsuba's",
        )
    forward = forward / np.linalg.norm(forward)
    up = up - np.dot(up, forward) * forward
    up = up / np.linalg.norm(up)
    camera = {
        "position": [float(v) for v in position],
        "look_at": [float(v) for v in position + forward],
        "up": [float(v) for v in up],
        "fov_y": round(fy, 10),
    }
    render: dict[str, Any] = {}
    for s in p.children("sampler"):
        sp = Params(s, report)
        count = sp.get("sample_count")
        if count is not None:
            render["spp"] = int(number(count, report))
        seed = sp.get("seed")
        if seed is not None:
            render["seed"] = int(number(seed, report))
        if s.type != "independent":
            report.warn(s.line, f"{s.describe()}: sampler replaced by the renderer's own (independent)")
        sp.warn_unused()
    p.warn_unused()
    return camera, (width, height), render


def convert_integrator(e: Element, report: Report) -> dict[str, Any]:
    """render.integrator / max_depth / rr_depth of a direct or path integrator.
    Mitsuba counts path segments from the camera (2 = direct lighting); the
    renderer counts bounces (1 = direct lighting), so depths shift by one."""
    p = Params(e, report)
    if e.type not in ("direct", "path"):
        p.use_all()
        report.warn(e.line, f"{e.describe()}: integrator {e.type!r} ignored: the renderer's default (direct) applies")
        return {}
    out: dict[str, Any] = {"integrator": e.type}
    if e.type == "path":
        md = p.get("max_depth")
        depth = int(number(md, report)) if md is not None else -1
        if depth < 0:
            report.warn(
                md.line if md is not None else e.line,
                f"{e.describe()}: unbounded max_depth approximated by "
                f"{UNBOUNDED_DEPTH} bounces (Russian roulette ends most paths long before)",
            )
            out["max_depth"] = UNBOUNDED_DEPTH
        else:
            if depth < 2:
                report.warn(
                    md.line if md is not None else e.line,
                    f"{e.describe()}: max_depth {depth} (no "
                    "reflected light in Mitsuba) raised to the renderer's minimum, one bounce",
                )
            out["max_depth"] = max(1, depth - 1)
        rr = p.get("rr_depth")
        if rr is not None:
            out["rr_depth"] = max(1, int(number(rr, report)) - 1)
    p.warn_unused()
    return out
