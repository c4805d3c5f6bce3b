"""Experiment configs (configs/experiments/*.yaml): loading and validation.

Everything is checked before any render starts; each error names the file,
the key and what was expected (errors.ConfigError). Relative paths are
relative to the experiment file's folder. The schema is in harness/README.md.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from portal_harness import contract, facets
from portal_harness.errors import ConfigError
from portal_harness.exr import REGION_CLASSES
from portal_harness.metrics import WHOLE_IMAGE, Region
from portal_harness.paths import ResultsLayout
from portal_harness.scene import read_scene
from portal_harness.schema import Reader, kind_of, parse_threads, read_yaml_lines
from portal_harness.spec import (
    HARNESS_RENDER_KEYS,
    NO_SNAPSHOTS,
    SNAPSHOT_KEYS,
    Overrides,
    RunSpec,
    format_value,
)

CURVE_METRICS = ("rel_mse", "mse")
# Every reference render keeps its film state (so it can be extended with
# render --resume).
REFERENCE_RENDER_OVERRIDES: Overrides = (("render.resumable", "true"),)
# The region map of a point: a render with the region AOV, whose class
# fractions do not depend on the strategy; the AOV costs about as much as a
# sample, so it gets its own short render instead of riding on the references.
REGION_MAP_SPP = 64
AOV_OVERRIDES: Overrides = (("render.aov.region", "true"),)
# Region names the harness gives itself (regions.py); insets may not take them.
RESERVED_REGION_NAMES = frozenset({WHOLE_IMAGE, "lit", *REGION_CLASSES})


@dataclass(frozen=True)
class Budget:
    """Per-run limits of a sweep: render time (s) and/or samples per pixel (0: none)."""

    time_s: float
    spp: int
    threads: int
    seed: int
    snapshots: Overrides
    replicates: int = 1


@dataclass(frozen=True)
class ReferenceSettings:
    """How each point's reference is made (references.py): `strategies` are
    the one or two independent renders combined into it, or empty to let a
    pilot choose (the lowest-variance strategy, plus `light` or the runner-up
    as the second, independent one)."""

    strategies: tuple[str, ...]
    spp: int
    time_s: float
    seed: int
    threads: int
    noise_ratio: float = 0.1  # reference noise / smallest error compared, at most
    max_time_s: float = 0.0  # cap on one reference's extended render time (0: none)
    pilot_time_s: float = 0.5  # per candidate strategy
    bias_z: float = 4.0  # the two references may disagree by at most this many sigma


@dataclass(frozen=True)
class Axis:
    """The x axis of the figures: a swept parameter, optionally divided by another."""

    param: str
    divide_by: str | None
    label: str


@dataclass(frozen=True)
class RegressSettings:
    spp: int
    seeds: tuple[int, ...]
    z_max: float
    baseline: Path


@dataclass(frozen=True)
class RegionSections:
    """figures.region_sections: a second view of each reference point for
    the region figures (region_figures.py), e.g. a vertical section through
    the lamp: a render of `scene` with the region AOV and the point's
    overrides. Its classes come from the renderer's classifier, so the view
    is any scene the renderer reads with the same lights and portals."""

    scene: Path
    scene_sha256: str  # of the scene and its includes, read once at load
    spp: int = 64
    label: str = ""  # the figure's name of the view (default: the scene file's stem)


@dataclass(frozen=True)
class Point:
    """One point of the sweep's cross product. `facets` are its values of
    the swept keys that are not the axis (facets.py); `axis_value` is NaN
    when the experiment has no axis."""

    values: tuple[tuple[str, Any], ...]
    axis_value: float
    facets: tuple[tuple[str, Any], ...] = ()

    @property
    def id(self) -> str:
        return ",".join(f"{k.split('.')[-1]}={format_value(v)}" for k, v in self.values)


@dataclass(frozen=True)
class Experiment:
    name: str
    path: Path
    scene: Path
    integrator: str
    strategies: tuple[str, ...]
    # Every strategy of the renderer, in its order (render --describe): seeds are counted over them.
    all_strategies: tuple[str, ...]
    sweep: tuple[tuple[str, tuple[Any, ...]], ...]
    fixed: Overrides
    budget: Budget | None
    reference: ReferenceSettings
    insets: tuple[Region, ...]
    axis: Axis | None  # None: every swept key is a facet
    regress: RegressSettings | None
    width: int
    height: int
    equal_time_s: float | None
    curve_metric: str
    scene_sha256: str  # of the scene and its includes, read once at load
    # The cross product, each point with its axis value from the renderer's
    # effective config of it (evaluated params).
    point_list: tuple[Point, ...]
    lit_threshold: float = 0.001  # regions.lit_threshold: reference radiance above which a pixel is lit
    facets: tuple[str, ...] = ()  # swept keys that are not the axis, in sweep order (facets.py)
    region_sections: RegionSections | None = None  # figures.region_sections
    # figures.compare: (the direct-lighting experiment, the strategy) whose
    # gain over light this experiment's is set against (gain_figure.py).
    compare: tuple[str, str] | None = None
    # The region AOV's classes, in the renderer's order (render --describe: aov.region).
    region_classes: tuple[str, ...] = REGION_CLASSES

    def points(self) -> list[Point]:
        return list(self.point_list)

    def reference_point(self, point: Point) -> Point:
        """The point whose reference `point` uses: without its values of the
        keys that only change how the image is sampled (facets.shares_reference)."""
        kept = tuple((k, v) for k, v in point.values if not facets.shares_reference(k))
        if len(kept) == len(point.values):
            return point
        return Point(kept, point.axis_value, tuple((k, v) for k, v in point.facets if not facets.shares_reference(k)))

    def reference_points(self) -> list[Point]:
        """The distinct reference points, in the order of the points."""
        out: dict[str, Point] = {}
        for p in self.point_list:
            ref = self.reference_point(p)
            out.setdefault(ref.id, ref)
        return list(out.values())

    def integrator_of(self, point: Point) -> str:
        """The point's integrator: its swept render.integrator, else the experiment's."""
        return str(dict(point.values).get("render.integrator", self.integrator))

    def _overrides(self, point: Point) -> Overrides:
        # A swept integrator goes to the command line's --integrator, like the experiment's.
        values = tuple((k, v) for k, v in point.values if k not in facets.SWEEPABLE_HARNESS_KEYS)
        return point_overrides(self.fixed, values)

    def _labels(self, point: Point) -> tuple[tuple[str, float], ...]:
        return (("ratio", point.axis_value),) if self.axis is not None and self.axis.divide_by is not None else ()

    def replicate_seed(self, strategy: str, replicate: int) -> int:
        """Seed of replicate k of a strategy: one per (replicate, strategy)
        counted from budget.seed, so that no two runs of a point share random
        streams (the replicates' spread and the ratios between strategies are
        then of independent estimates; equal seeds would share, e.g., the
        camera jitter)."""
        assert self.budget is not None
        return self.budget.seed + replicate * len(self.all_strategies) + self.all_strategies.index(strategy)

    def _spec(
        self,
        point: Point,
        strategy: str,
        spp: int,
        time_s: float,
        seed: int,
        threads: int,
        snapshots: Overrides = NO_SNAPSHOTS,
        extra: Overrides = (),
        reference: bool = False,
        label: str | None = None,
    ) -> RunSpec:
        """A render of this experiment's scene at `point`; `label` tags an
        auxiliary render (pilot, region map) in the index."""
        labels = self._labels(point) + (((label, 1.0),) if label else ())
        return RunSpec(
            scene=str(self.scene),
            scene_sha256=self.scene_sha256,
            strategy=strategy,
            integrator=self.integrator_of(point),
            spp=spp,
            time_s=time_s,
            seed=seed,
            threads=threads,
            overrides=self._overrides(point) + extra,
            snapshots=snapshots,
            reference=reference,
            labels=labels,
        )

    def run_spec(
        self, point: Point, strategy: str, seed: int | None = None, spp: int | None = None, replicate: int = 0
    ) -> RunSpec:
        if self.budget is None:
            raise ConfigError(str(self.path), "budget", "required to run a sweep")
        if seed is None:
            seed = self.replicate_seed(strategy, replicate)
        return self._spec(
            point,
            strategy,
            spp=self.budget.spp if spp is None else spp,
            time_s=self.budget.time_s if spp is None else 0.0,
            seed=seed,
            threads=self.budget.threads,
            snapshots=self.budget.snapshots,
        )

    def regress_spec(self, point: Point, strategy: str, seed: int) -> RunSpec:
        """A fixed-seed, fixed-sample run of `regress` (no time limit, no snapshots asked for)."""
        if self.regress is None:
            raise ConfigError(str(self.path), "regress", "required by the regress command")
        return self._spec(
            point,
            strategy,
            spp=self.regress.spp,
            time_s=0.0,
            seed=seed,
            threads=self.budget.threads if self.budget else 1,
        )

    def baseline_path(self, layout: ResultsLayout) -> Path:
        """regress.baseline if given, else results/baselines/<name>.json."""
        if self.regress is not None and self.regress.baseline != Path():
            return self.regress.baseline
        return layout.baseline(self.name)

    def reference_spec(self, point: Point, strategy: str, part: int = 0, time_s: float | None = None) -> RunSpec:
        """Reference render `part` (0 or 1) of a point with `strategy`: its
        own seed, and resumable, so that it can be extended (references.py).
        `time_s` replaces reference.time_s (the pilot's prediction)."""
        r = self.reference
        return self._spec(
            point,
            strategy,
            spp=r.spp,
            time_s=r.time_s if time_s is None else time_s,
            seed=r.seed + 7 * part,
            threads=r.threads,
            extra=REFERENCE_RENDER_OVERRIDES,
            reference=True,
        )

    def pilot_spec(self, point: Point, strategy: str, spp: int = 0) -> RunSpec:
        """A short render of a candidate reference strategy: its own
        variance layer says how efficient the strategy is here. It lasts
        reference.pilot_time_s, or `spp` samples when given (pilot.MIN_SPP
        for a pilot whose time drew too few to test for fireflies)."""
        r = self.reference
        return self._spec(
            point,
            strategy,
            spp=spp,
            time_s=0.0 if spp else r.pilot_time_s,
            seed=r.seed + 1000,
            threads=r.threads,
            label="pilot",
        )

    def region_map_spec(self, point: Point) -> RunSpec:
        """The render whose region AOV gives the point's region classes."""
        r = self.reference
        return self._spec(
            point,
            "light",
            spp=REGION_MAP_SPP,
            time_s=0.0,
            seed=r.seed + 2000,
            threads=r.threads,
            extra=AOV_OVERRIDES,
            label="region_map",
        )

    def region_section_spec(self, point: Point) -> RunSpec:
        """The render of figures.region_sections.scene whose region AOV gives
        the point's classes in that view (region_figures.py)."""
        sections = self.region_sections
        if sections is None:
            raise ConfigError(str(self.path), "figures.region_sections", "required by the region figures")
        r = self.reference
        spec = self._spec(
            point,
            "light",
            spp=sections.spp,
            time_s=0.0,
            seed=r.seed + 3000,
            threads=r.threads,
            extra=AOV_OVERRIDES,
            label="region_section",
        )
        return replace(spec, scene=str(sections.scene), scene_sha256=sections.scene_sha256)


def point_overrides(fixed: Overrides, values: tuple[tuple[str, Any], ...]) -> Overrides:
    """The --set overrides of a point: the fixed ones and the point's values."""
    merged = dict(fixed)
    merged.update({k: format_value(v) for k, v in values})
    return tuple(sorted(merged.items()))


def _check_override_key(reader: Reader, key: str, where: str, params: dict[str, float], swept: bool = False) -> None:
    """Keys the harness sets itself are refused (a swept render.integrator
    excepted: each point's integrator); params.NAME must name a
    parameter of the scene (the renderer would take an unknown one
    silently, as a new parameter nothing reads). Any other key is checked
    by the renderer, with the overrides."""
    if not key or any(not part for part in key.split(".")):
        raise reader.fail(where, f"expected a dotted key path such as params.s_L, got {key!r}")
    allowed = swept and key in facets.SWEEPABLE_HARNESS_KEYS
    if (key in HARNESS_RENDER_KEYS and not allowed) or key.startswith("render.snapshots"):
        raise reader.fail(where, f"{key} is set by the harness (use strategies, integrator, budget or reference)")
    name = key.removeprefix("params.")
    if key.startswith("params.") and name not in params:
        raise reader.fail(where, f"the scene has no parameter {name!r} (it has {', '.join(sorted(params))})")


def _numeric(effective: contract.EffectiveConfig, key: str) -> float | None:
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


def load_experiment(path: Path | str, renderer: str, relative_to: Path | None = None) -> Experiment:
    """Reads and validates an experiment against the renderer at `renderer`
    (its strategies and integrators, and its effective config of the scene
    at every point); raises ConfigError on the first problem. Relative paths
    in it are relative to `relative_to` (default: the file's folder; the service
    stores submitted files apart from the root folder their paths name)."""
    p = Path(path).resolve() if Path(path).exists() else Path(path)
    folder = relative_to if relative_to is not None else p.parent
    data, lines = read_yaml_lines(p, "experiment file")
    r = Reader(str(path), lines)
    root = r.mapping(
        data,
        "",
        allowed={
            "name",
            "scene",
            "integrator",
            "strategies",
            "sweep",
            "fixed",
            "budget",
            "reference",
            "insets",
            "axis",
            "regress",
            "figures",
            "description",
            "regions",
        },
        required={"scene", "strategies", "sweep"},
    )
    name = r.string(root.get("name", p.stem), "name")
    if "/" in name or name.startswith("."):
        raise r.fail("name", f"expected a plain name usable as a file name, got {name!r}")

    scene = (folder / r.string(root["scene"], "scene")).resolve()
    if not scene.is_file():
        raise r.fail("scene", f"scene file {scene} not found")
    names = contract.describe(renderer)
    scene_info = read_scene(renderer, scene)
    params = scene_info.effective.params

    sweep_node = root["sweep"]
    if isinstance(sweep_node, dict) and "render.integrator" in sweep_node and "integrator" in root:
        raise r.fail("integrator", "render.integrator is swept: give the integrators there only")
    integrator = r.choice(
        root.get("integrator", scene_info.effective.render.get("integrator")),
        "integrator",
        names.integrators,
        "integrator",
    )

    strategies_node = r.sequence(root["strategies"], "strategies")
    strategies = tuple(
        r.choice(s, f"strategies.{i}", names.strategies, "strategy") for i, s in enumerate(strategies_node)
    )
    if len(set(strategies)) != len(strategies):
        raise r.fail("strategies", "a strategy is listed twice")

    if sweep_node is None or sweep_node == {}:
        raise r.fail(
            "sweep", "empty sweep (expected a mapping from a parameter such as params.s_L to a list of values)"
        )
    if not isinstance(sweep_node, dict):
        raise r.fail("sweep", f"expected a mapping from parameter to list of values, got {kind_of(sweep_node)}")
    sweep: list[tuple[str, tuple[Any, ...]]] = []
    for k, values in sweep_node.items():
        key = str(k)
        _check_override_key(r, key, f"sweep.{key}", params, swept=True)
        items = r.sequence(values, f"sweep.{key}")
        sweep.append((key, tuple(_value(r, names, key, v, f"sweep.{key}.{i}") for i, v in enumerate(items))))
        if len(set(map(format_value, sweep[-1][1]))) != len(items):
            raise r.fail(f"sweep.{key}", "a value is listed twice")

    fixed_node = root.get("fixed", {}) or {}
    if not isinstance(fixed_node, dict):
        raise r.fail("fixed", f"expected a mapping from parameter to value, got {kind_of(fixed_node)}")
    fixed: dict[str, str] = {}
    for k, v in fixed_node.items():
        key = str(k)
        _check_override_key(r, key, f"fixed.{key}", params)
        if key in dict(sweep):
            raise r.fail(f"fixed.{key}", "also swept (a parameter is either fixed or swept)")
        fixed[key] = format_value(_value(r, names, key, v, f"fixed.{key}"))

    fixed_overrides = tuple(sorted(fixed.items()))
    try:
        base = contract.print_config(renderer, scene, fixed_overrides)
    except ConfigError as e:
        raise r.fail("fixed", f"the renderer rejects the scene with these values: {e}") from None
    width, height = base.width, base.height

    budget = None
    if "budget" in root:
        b = r.mapping(root["budget"], "budget", {"time_s", "spp", "threads", "seed", "snapshots", "replicates"})
        time_s = r.number(b.get("time_s", 0), "budget.time_s")
        spp = r.integer(b.get("spp", 0), "budget.spp")
        if time_s == 0 and spp == 0:
            raise r.fail("budget", "expected time_s > 0 or spp > 0 (a run needs a limit)")
        snaps_node = r.mapping(b.get("snapshots", {}) or {}, "budget.snapshots", set(SNAPSHOT_KEYS))
        # Counted in samples (integers) or seconds, as the renderer says.
        snapshots = tuple(
            (
                k,
                format_value(
                    r.integer(v, f"budget.snapshots.{k}", minimum=1)
                    if names.snapshot_unit(k) == "spp"
                    else r.number(v, f"budget.snapshots.{k}", positive=True)
                ),
            )
            for k, v in sorted(snaps_node.items())
        )
        budget = Budget(
            time_s=time_s,
            spp=spp,
            threads=parse_threads(b.get("threads", 1), r, "budget.threads"),
            seed=r.integer(b.get("seed", 1), "budget.seed"),
            snapshots=snapshots,
            replicates=r.integer(b.get("replicates", 1), "budget.replicates", minimum=1),
        )

    reference = _reference_settings(r, root.get("reference", {}) or {}, budget, names.strategies)

    insets: list[Region] = []
    for i, node in enumerate(r.sequence(root.get("insets", []) or [], "insets", non_empty=False)):
        key = f"insets.{i}"
        m = r.mapping(node, key, {"name", "x", "y", "width", "height"}, {"name", "x", "y", "width", "height"})
        region = Region(
            name=r.string(m["name"], f"{key}.name"),
            x=r.integer(m["x"], f"{key}.x"),
            y=r.integer(m["y"], f"{key}.y"),
            width=r.integer(m["width"], f"{key}.width", minimum=1),
            height=r.integer(m["height"], f"{key}.height", minimum=1),
        )
        if region.name in RESERVED_REGION_NAMES or region.name in {x.name for x in insets}:
            raise r.fail(f"{key}.name", f"inset name {region.name!r} is reserved or used twice")
        if not region.fits(width, height):
            raise r.fail(
                key,
                f"rectangle x={region.x} y={region.y} {region.width}x{region.height} "
                f"does not fit the {width}x{height} image",
            )
        insets.append(region)

    axis = _axis(r, root.get("axis"), tuple(sweep))
    facet_keys = tuple(k for k, _ in sweep if axis is None or k not in (axis.param, axis.divide_by))

    regress = None
    if "regress" in root:
        g = r.mapping(root["regress"], "regress", {"spp", "seeds", "z_max", "baseline"}, {"spp"})
        seeds = tuple(
            r.integer(s, f"regress.seeds.{i}")
            for i, s in enumerate(r.sequence(g.get("seeds", [1, 2]), "regress.seeds"))
        )
        if len(seeds) < 2 or len(set(seeds)) != len(seeds):
            raise r.fail("regress.seeds", "expected at least two different seeds (the standard error needs them)")
        baseline = g.get("baseline")
        regress = RegressSettings(
            spp=r.integer(g["spp"], "regress.spp", minimum=1),
            seeds=seeds,
            z_max=r.number(g.get("z_max", 4.0), "regress.z_max", positive=True),
            baseline=(folder / r.string(baseline, "regress.baseline")).resolve() if baseline else Path(),
        )

    points = _points(r, renderer, scene, tuple(sweep), fixed_overrides, axis, facet_keys)

    regions_node = r.mapping(root.get("regions", {}) or {}, "regions", {"lit_threshold"})
    lit_threshold = r.number(regions_node.get("lit_threshold", 0.001), "regions.lit_threshold", positive=True)

    fig = r.mapping(
        root.get("figures", {}) or {}, "figures", {"equal_time_s", "curve_metric", "region_sections", "compare"}
    )
    compare = None
    if "compare" in fig:
        c = r.mapping(fig["compare"], "figures.compare", {"experiment", "strategy"}, {"experiment", "strategy"})
        compare = (
            r.string(c["experiment"], "figures.compare.experiment"),
            r.choice(c["strategy"], "figures.compare.strategy", strategies, "strategy"),
        )
    equal_time = fig.get("equal_time_s")
    sections = (
        _region_sections(r, folder, renderer, fig["region_sections"], fixed_overrides, points)
        if "region_sections" in fig
        else None
    )
    return Experiment(
        name=name,
        path=p,
        scene=scene,
        integrator=integrator,
        strategies=strategies,
        all_strategies=names.strategies,
        sweep=tuple(sweep),
        fixed=fixed_overrides,
        budget=budget,
        reference=reference,
        insets=tuple(insets),
        axis=axis,
        regress=regress,
        width=width,
        height=height,
        equal_time_s=None if equal_time is None else r.number(equal_time, "figures.equal_time_s", positive=True),
        curve_metric=r.choice(fig.get("curve_metric", "rel_mse"), "figures.curve_metric", CURVE_METRICS, "metric"),
        scene_sha256=scene_info.sha256,
        point_list=points,
        lit_threshold=lit_threshold,
        facets=facet_keys,
        region_sections=sections,
        compare=compare,
        region_classes=tuple(c.removeprefix("region.") for c in names.region_channels),
    )


REGION_SECTION_KEYS = {"scene", "spp", "label"}


def _region_sections(
    r: Reader, folder: Path, renderer: str, node: Any, fixed: Overrides, points: tuple[Point, ...]
) -> RegionSections:
    """figures.region_sections: {scene, spp, label}; the scene must exist and the
    renderer must accept it with every point's overrides (it is rendered
    at each reference point, like the region map)."""
    m = r.mapping(node, "figures.region_sections", REGION_SECTION_KEYS, {"scene"})
    scene = (folder / r.string(m["scene"], "figures.region_sections.scene")).resolve()
    if not scene.is_file():
        raise r.fail("figures.region_sections.scene", f"scene file {scene} not found")
    spp = r.integer(m.get("spp", REGION_MAP_SPP), "figures.region_sections.spp", minimum=1)
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


def _value(r: Reader, names: contract.Contract, key: str, node: Any, where: str) -> Any:
    """A swept or fixed value; a name-valued render key's names are the renderer's (facets.CONTRACT_LISTS)."""
    value = r.scalar(node, where)
    known = facets.contract_names(key, names)
    if known is not None:
        what, choices = known
        return r.choice(value, where, choices, what)
    return value


def _axis(r: Reader, node: Any, sweep: tuple[tuple[str, tuple[Any, ...]], ...]) -> Axis | None:
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


def _points(
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
        x = _numeric(effective, axis.param)
        if x is None:
            raise r.fail("axis.param", f"{axis.param!r} has no numeric value at the point {name}")
        if axis.divide_by is not None:
            d = _numeric(effective, axis.divide_by)
            if d is None or d == 0:
                raise r.fail(
                    "axis.divide_by",
                    f"{axis.divide_by!r} has no non-zero numeric value in the sweep, "
                    f"fixed or scene (at the point {name})",
                )
            x /= d
        out.append(Point(values=values, axis_value=x, facets=point_facets))
    return tuple(out)


def _reference_settings(r: Reader, node: Any, budget: Budget | None, known: tuple[str, ...]) -> ReferenceSettings:
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
    spp = r.integer(m.get("spp", 0 if time_s > 0 else 1024), "reference.spp")
    if spp == 0 and time_s == 0:
        raise r.fail("reference", "expected spp > 0 or time_s > 0")
    noise_ratio = r.number(m.get("noise_ratio", 0.1), "reference.noise_ratio", positive=True)
    if noise_ratio >= 1:
        raise r.fail("reference.noise_ratio", f"expected a ratio below 1, got {noise_ratio:g}")
    return ReferenceSettings(
        strategies=strategies,
        spp=spp,
        time_s=time_s,
        seed=r.integer(m.get("seed", 7919), "reference.seed"),
        threads=parse_threads(m.get("threads", budget.threads if budget else 1), r, "reference.threads"),
        noise_ratio=noise_ratio,
        max_time_s=r.number(m.get("max_time_s", 0), "reference.max_time_s"),
        pilot_time_s=r.number(m.get("pilot_time_s", 0.5), "reference.pilot_time_s", positive=True),
        bias_z=r.number(m.get("bias_z", 4.0), "reference.bias_z", positive=True),
    )
