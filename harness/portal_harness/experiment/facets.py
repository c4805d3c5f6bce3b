"""Categorical sweep keys: the facets of an experiment.

A sweep may vary keys whose values are names (`render.portal_weight`,
`render.sampler`, `render.integrator`) or numbers that are not the x axis
(`render.defensive: [0, 0.1]`). Every swept key other than the axis (and
its divisor) is a facet: the figures draw each of its values as a row of
panels or a line style with a legend naming key=value, never as an x
axis, and the tidy summary gets one column per facet key.

Which names a key takes comes from the renderer's contract (`render
--describe`), never from a list kept here; only which contract list
belongs to which key is written down, so a name the renderer adds (a
sampler) is accepted the moment the binary has it.

References: a point's reference depends only on what changes the expected
image. A facet key that only changes how the image is sampled (`render.*`
outside spec.IMAGE_RENDER_KEYS: the portal weight, the sampler, the
defensive fraction, MIS) shares the reference of the point without it; one
that changes the image (`render.integrator`, `render.max_depth`, any key
outside `render.*`) has a reference per value. This is the same rule as
the reference key's scene hash (spec.RunSpec.scene_hash), applied to the
points, so that points that would compute the same reference key also
share its pilots, region map, bias test and extensions.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from portal_harness.experiment.contract import Contract
from portal_harness.experiment.spec import IMAGE_RENDER_KEYS, format_value

# The contract list each name-valued render key draws from (render --describe).
CONTRACT_LISTS: dict[str, tuple[str, Callable[[Contract], tuple[str, ...]]]] = {
    "render.integrator": ("integrator", lambda c: c.integrators),
    "render.portal_weight": ("portal weight", lambda c: c.portal_weights),
    "render.sampler": ("sampler", lambda c: c.samplers),
    "render.mis": ("MIS heuristic", lambda c: c.mis),
}
# Harness-set keys a sweep may still vary: the point's integrator replaces
# the experiment's (--integrator on the command line, not a --set).
SWEEPABLE_HARNESS_KEYS = frozenset({"render.integrator"})


def is_number(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float))


def is_categorical(values: tuple[Any, ...]) -> bool:
    """A swept key whose values are not all numbers (names, booleans)."""
    return not all(is_number(v) for v in values)


def contract_names(key: str, contract: Contract) -> tuple[str, tuple[str, ...]] | None:
    """(what, names) the renderer accepts at a name-valued key, None for any other key."""
    entry = CONTRACT_LISTS.get(key)
    return None if entry is None else (entry[0], entry[1](contract))


def shares_reference(key: str) -> bool:
    """True for a key that changes how the image is sampled, not what it converges to."""
    return key.startswith("render.") and key not in IMAGE_RENDER_KEYS


def short_key(key: str) -> str:
    """`render.portal_weight` -> `portal_weight` (the last part, as point ids use)."""
    return key.split(".")[-1]


def label(key: str, value: Any) -> str:
    """key=value, as legends and titles name a facet."""
    return f"{short_key(key)}={format_value(value)}"


def labels(values: tuple[tuple[str, Any], ...]) -> str:
    return ", ".join(label(k, v) for k, v in values)
