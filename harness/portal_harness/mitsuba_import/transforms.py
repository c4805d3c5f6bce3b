"""Mitsuba `<transform>` elements as the renderer's `transform:` list.

Mitsuba composes the operations of a transform in document order, each one
applied after the previous ones (M = op_n ... op_2 op_1), which is the
renderer's order too (first operation first), so each element becomes one
list item. `lookat` has no renderer operation and becomes a matrix.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from portal_harness.mitsuba_import.report import Report
from portal_harness.mitsuba_import.values import numbers, vec3
from portal_harness.mitsuba_import.xmltree import Element

Op = dict[str, Any]


def _rotation(axis: np.ndarray, degrees: float) -> np.ndarray:
    """Right-handed rotation about axis (Rodrigues), as Mitsuba's rotate."""
    k = axis / np.linalg.norm(axis)
    t = np.radians(degrees)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + np.sin(t) * kx + (1 - np.cos(t)) * (kx @ kx)
    return m


def look_at(origin: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray | None:
    """Mitsuba's lookat: local +z towards the target, +y up, +x left; None
    when the view direction is zero or parallel to up."""
    d = target - origin
    if np.linalg.norm(d) == 0:
        return None
    d = d / np.linalg.norm(d)
    left = np.cross(up, d)
    if np.linalg.norm(left) < 1e-12:
        return None
    left = left / np.linalg.norm(left)
    new_up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, origin
    return m


def _floats(m: np.ndarray) -> list[float]:
    return [float(v) for v in m.reshape(-1)]


def parse_transform(e: Element, report: Report) -> tuple[list[Op], np.ndarray]:
    """The renderer's operation list and the composed 4x4 matrix of a
    `<transform>` element. Bad operations and singular results are errors
    at their line; unknown child elements are warned about and skipped."""
    ops: list[Op] = []
    total = np.eye(4)
    for c in e.children:
        m = np.eye(4)
        if c.tag == "translate":
            t = vec3(c, report)
            ops.append({"translate": list(t)})
            m[:3, 3] = t
        elif c.tag == "scale":
            if "value" in c.attrs and len(numbers(c.attrs["value"], report, c.line)) == 1:
                s = numbers(c.attrs["value"], report, c.line)[0]
                ops.append({"scale": s})
                m[:3, :3] *= s
            else:
                sv = vec3(c, report, default=1.0)
                ops.append({"scale": list(sv)})
                m[:3, :3] = np.diag(sv)
        elif c.tag == "rotate":
            axis = np.array(vec3(c, report))
            if "angle" not in c.attrs:
                raise report.error(c.line, f"{c.describe()}: missing angle (degrees)")
            angle = numbers(c.attrs["angle"], report, c.line)
            if np.linalg.norm(axis) == 0 or len(angle) != 1:
                raise report.error(c.line, f"{c.describe()}: expected a non-zero axis and one angle")
            ops.append({"rotate": {"axis": [float(v) for v in axis], "angle": angle[0]}})
            m = _rotation(axis, angle[0])
        elif c.tag == "matrix":
            vals = numbers(c.attrs.get("value", ""), report, c.line)
            if len(vals) == 9:
                m[:3, :3] = np.array(vals).reshape(3, 3)
            elif len(vals) == 16:
                m = np.array(vals).reshape(4, 4)
            else:
                raise report.error(c.line, f"{c.describe()}: expected 9 or 16 numbers, got {len(vals)}")
            if not np.allclose(m[3], [0, 0, 0, 1]):
                raise report.error(c.line, f"{c.describe()}: projective matrix (expected the last row 0 0 0 1)")
            ops.append({"matrix": _floats(m)})
        elif c.tag == "lookat":
            origin, target = np.array(vec3(c, report, "origin")), np.array(vec3(c, report, "target"))
            if "up" not in c.attrs:
                report.warn(c.line, f"{c.describe()}: no up vector: (0, 1, 0) assumed")
            up = np.array(vec3(c, report, "up")) if "up" in c.attrs else np.array([0.0, 1.0, 0.0])
            la = look_at(origin, target, up)
            if la is None:
                raise report.error(c.line, f"{c.describe()}: target equals origin or up is parallel to the view")
            m = la
            ops.append({"matrix": _floats(m)})
        else:
            report.warn(c.line, f"{c.describe()} inside <transform>: unknown operation, skipped")
            continue
        total = m @ total
    if abs(np.linalg.det(total[:3, :3])) < 1e-300:
        raise report.error(e.line, f"{e.describe()}: singular transform (it would flatten the geometry)")
    return ops, total
