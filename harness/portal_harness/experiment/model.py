"""The experiment model: an experiment config as loaded (loader.py) and the
RunSpecs of its renders: runs, references, pilots, region maps, regress runs."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from portal_harness.core.errors import ConfigError
from portal_harness.core.exr import REGION_CLASSES
from portal_harness.core.metrics import Region
from portal_harness.core.paths import ResultsLayout
from portal_harness.experiment import facets
from portal_harness.experiment.spec import (
    NO_SNAPSHOTS,
    Overrides,
    RunSpec,
    format_value,
)

# Every reference render keeps its film state (so it can be extended with
# render --resume).
REFERENCE_RENDER_OVERRIDES: Overrides = (("render.resumable", "true"),)


# The region map of a point: a render with the region AOV, whose class
# fractions do not depend on the strategy; the AOV costs about as much as a
# sample, so it gets its own short render instead of riding on the references.
REGION_MAP_SPP = 64


AOV_OVERRIDES: Overrides = (("render.aov.region", "true"),)


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
class Precision:
    """precision: the relative standard error every headline value (each
    strategy's efficiency relative to light and equal-error speed-up in the
    `regions`) is to reach; the sweep adds replicates until it does, or
    until a cap (analysis/precision.py)."""

    rel_se: float
    regions: tuple[str, ...]  # region names as the summary has them; "insets": every inset
    max_replicates: int  # per (point, strategy)
    max_time_s: float  # wall time of the sweep after which no round is started (0: none)


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
    the region figures (figures/regions.py), e.g. a vertical section through
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
    # gain over light this experiment's is set against (figures/gain.py).
    compare: tuple[str, str] | None = None
    # The region AOV's classes, in the renderer's order (render --describe: aov.region).
    region_classes: tuple[str, ...] = REGION_CLASSES
    precision: Precision | None = None  # precision: replicates until the headline values are known

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
        the point's classes in that view (figures/regions.py)."""
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
