"""Readers of the experiment config's sections for loader.py: override keys,
sweep values, the axis, the cross product's points, the reference settings and
figures.region_sections; each checked against the renderer's contract."""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path
from typing import Any

from portal_harness.core.errors import ConfigError
from portal_harness.experiment import contract, facets
from portal_harness.experiment.model import (
    REGION_MAP_SPP,
    Axis,
    Budget,
    Point,
    ReferenceSettings,
    RegionSections,
    point_overrides,
)
from portal_harness.experiment.scene import read_scene
from portal_harness.experiment.schema import SEED_MAX, SPP_MAX, Reader, exponent_number, kind_of, parse_threads
from portal_harness.experiment.spec import (
    HARNESS_RENDER_KEYS,
    Overrides,
    format_value,
)


def check_override_key(reader: Reader, key: str, where: str, params: dict[str, float], swept: bool = False) -> None:
    """Keys the harness sets itself are refused (a swept render.integrator
    excepted: each point's integrator); params.NAME must name a
    parameter of the scene (the renderer would take an unknown one
    silently, as a new parameter nothing reads). Any other key is checked
    by the renderer, with the overrides."""
    if not _KEY.fullmatch(key):
        raise reader.fail(where, f"expected a dotted key path such as params.s_L, got {kind_of(key)}")
    allowed = swept and key in facets.SWEEPABLE_HARNESS_KEYS
    if (key in HARNESS_RENDER_KEYS and not allowed) or key.startswith("render.snapshots"):
        raise reader.fail(where, f"{key} is set by the harness (use strategies, integrator, budget or reference)")
    name = key.removeprefix("params.")
    if key.startswith("params.") and name not in params:
        raise reader.fail(where, f"the scene has no parameter {name!r} (it has {', '.join(sorted(params))})")


def numeric_at(effective: contract.EffectiveConfig, key: str) -> float | None:
    """The number at `key` of an effective config (params evaluated), or None."""
    if key.startswith("params.") and key.removeprefix("params.") in effective.params:
        return effective.params[key.removeprefix("params.")]
    try:
        value = effective.get(key)
    except KeyError:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


REGION_SECTION_KEYS = {"scene", "spp", "label"}


def read_region_sections(
    r: Reader, folder: Path, renderer: str, node: Any, fixed: Overrides, points: tuple[Point, ...]
) -> RegionSections:
    """figures.region_sections: {scene, spp, label}; the scene must exist and the
    renderer must accept it with every point's overrides (it is rendered
    at each reference point, like the region map)."""
    m = r.mapping(node, "figures.region_sections", REGION_SECTION_KEYS, {"scene"})
    scene = (folder / r.string(m["scene"], "figures.region_sections.scene")).resolve()
    if not scene.is_file():
        raise r.fail("figures.region_sections.scene", f"scene file {scene} not found")
    spp = r.integer(m.get("spp", REGION_MAP_SPP), "figures.region_sections.spp", minimum=1, maximum=SPP_MAX)
    label = r.string(m.get("label", scene.stem), "figures.region_sections.label")
    try:
        info = read_scene(renderer, scene, fixed)
    except ConfigError as e:
        raise r.fail("figures.region_sections.scene", f"the renderer rejects the scene: {e}") from None
    for point in points:
        values = tuple((k, v) for k, v in point.values if k not in facets.SWEEPABLE_HARNESS_KEYS)
        try:
            contract.print_config(renderer, scene, point_overrides(fixed, values))
        except ConfigError as e:
            raise r.fail(
                "figures.region_sections.scene", f"the renderer rejects the scene at the point {point.id}: {e}"
            ) from None
    return RegionSections(scene=scene, scene_sha256=info.sha256, spp=spp, label=label)


def read_value(r: Reader, names: contract.Contract, key: str, node: Any, where: str) -> Any:
    """A swept or fixed value; a name-valued render key's names are the renderer's (facets.CONTRACT_LISTS).
    A number in exponent form without a dot (`1e12`) is that number, as in budget; a number is
    finite and fits 64 bits; a string has no control characters."""
    value = exponent_number(r.scalar(node, where))
    if isinstance(value, str):
        r.string(value, where)
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        r.number(value, where, minimum=-math.inf)
    known = facets.contract_names(key, names)
    if known is not None:
        what, choices = known
        return r.choice(value, where, choices, what)
    return value


def read_axis(r: Reader, node: Any, sweep: tuple[tuple[str, tuple[Any, ...]], ...]) -> Axis | None:
    """The figures' x axis: axis.param (default: the first swept key whose
    values are all numbers), or none (`axis: none`, or no numeric key):
    then every swept key is a facet."""
    if node == "none":
        return None
    axis_node = r.mapping(node or {}, "axis", {"param", "divide_by", "label"})
    swept = [k for k, _ in sweep]
    numeric = [k for k, values in sweep if not facets.is_categorical(values)]
    if "param" not in axis_node and not numeric:
        if axis_node:
            raise r.fail("axis", "no swept key has numbers, so there is no axis: give axis: none or remove axis")
        return None
    axis_param = r.string(axis_node.get("param", numeric[0] if numeric else None), "axis.param")
    if axis_param not in swept:
        raise r.fail("axis.param", f"{axis_param!r} is not swept (expected one of {', '.join(swept)})")
    divide_by = axis_node.get("divide_by")
    if divide_by is not None:
        divide_by = r.string(divide_by, "axis.divide_by")
    for i, v in enumerate(dict(sweep)[axis_param]):
        if not facets.is_number(v):
            raise r.fail(
                f"sweep.{axis_param}.{i}",
                f"the axis parameter needs numbers, got {kind_of(v)} (a key of names is a facet of the "
                "figures: make a numeric key the axis.param, or give axis: none)",
            )
    default_label = (
        f"{facets.short_key(axis_param)} / {facets.short_key(divide_by)}" if divide_by else facets.short_key(axis_param)
    )
    return Axis(
        param=axis_param, divide_by=divide_by, label=r.string(axis_node.get("label", default_label), "axis.label")
    )


# Seeds a reference point derives from reference.seed (parts, pilots, region maps: model.py).
REFERENCE_SEED_SPAN = 10000
_KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*(\.[A-Za-z0-9_-]+){0,15}", re.ASCII)

REFERENCE_KEYS = {
    "strategy",
    "strategies",
    "spp",
    "time_s",
    "seed",
    "threads",
    "noise_ratio",
    "max_time_s",
    "pilot_time_s",
    "bias_z",
}


def read_points(
    r: Reader,
    renderer: str,
    scene: Path,
    sweep: tuple[tuple[str, tuple[Any, ...]], ...],
    fixed: Overrides,
    axis: Axis | None,
    facet_keys: tuple[str, ...],
) -> tuple[Point, ...]:
    """Every point of the cross product, checked by the renderer (its
    effective config with the point's overrides), with its axis value from
    that config: a divisor that is an expression of a swept parameter is
    evaluated at each point."""
    keys = [k for k, _ in sweep]
    out = []
    for combo in itertools.product(*(values for _, values in sweep)):
        values = tuple(zip(keys, combo, strict=True))
        name = ",".join(f"{k}={format_value(v)}" for k, v in values)
        try:
            effective = contract.print_config(renderer, scene, point_overrides(fixed, values))
        except ConfigError as e:
            raise r.fail("sweep", f"the renderer rejects the point {name}: {e}") from None
        point_facets = tuple((k, v) for k, v in values if k in facet_keys)
        if axis is None:
            out.append(Point(values=values, axis_value=math.nan, facets=point_facets))
            continue
        x = numeric_at(effective, axis.param)
        if x is None:
            raise r.fail("axis.param", f"{axis.param!r} has no numeric value at the point {name}")
        if axis.divide_by is not None:
            d = numeric_at(effective, axis.divide_by)
            if d is None or d == 0:
                raise r.fail(
                    "axis.divide_by",
                    f"{axis.divide_by!r} has no non-zero numeric value in the sweep, "
                    f"fixed or scene (at the point {name})",
                )
            x /= d
        out.append(Point(values=values, axis_value=x, facets=point_facets))
    return tuple(out)


def read_reference_settings(r: Reader, node: Any, budget: Budget | None, known: tuple[str, ...]) -> ReferenceSettings:
    m = r.mapping(node, "reference", REFERENCE_KEYS)
    if "strategy" in m and "strategies" in m:
        raise r.fail("reference", "give strategy (one reference) or strategies (one or two), not both")
    if "strategy" in m:
        strategies: tuple[str, ...] = (r.choice(m["strategy"], "reference.strategy", known, "strategy"),)
    elif m.get("strategies", "auto") == "auto":
        strategies = ()
    else:
        items = r.sequence(m["strategies"], "reference.strategies")
        strategies = tuple(r.choice(s, f"reference.strategies.{i}", known, "strategy") for i, s in enumerate(items))
        if len(strategies) > 2 or len(set(strategies)) != len(strategies):
            raise r.fail("reference.strategies", "expected auto, or one or two different strategies")
    time_s = r.number(m.get("time_s", 0), "reference.time_s")
    # Exactly the limits given: 1024 spp only when no time is given.
    spp = r.integer(m.get("spp", 0 if time_s > 0 else 1024), "reference.spp", maximum=SPP_MAX)
    if spp == 0 and time_s == 0:
        raise r.fail("reference", "expected spp > 0 or time_s > 0")
    noise_ratio = r.number(m.get("noise_ratio", 0.1), "reference.noise_ratio", positive=True)
    if noise_ratio >= 1:
        raise r.fail("reference.noise_ratio", f"expected a ratio below 1, got {noise_ratio:g}")
    return ReferenceSettings(
        strategies=strategies,
        spp=spp,
        time_s=time_s,
        seed=r.integer(m.get("seed", 7919), "reference.seed", maximum=SEED_MAX - REFERENCE_SEED_SPAN),
        threads=parse_threads(m.get("threads", budget.threads if budget else 1), r, "reference.threads"),
        noise_ratio=noise_ratio,
        max_time_s=r.number(m.get("max_time_s", 0), "reference.max_time_s"),
        pilot_time_s=r.number(m.get("pilot_time_s", 0.5), "reference.pilot_time_s", positive=True),
        bias_z=r.number(m.get("bias_z", 4.0), "reference.bias_z", positive=True),
    )
