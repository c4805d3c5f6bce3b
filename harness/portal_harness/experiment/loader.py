"""Loading an experiment config (configs/experiments/*.yaml) into the model
(model.py): every key checked before any render starts, each error naming the
file, the key and what was expected (errors.ConfigError). Relative paths are
relative to the experiment file's folder. The schema is in harness/README.md;
the sections' readers are in sections.py."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from portal_harness.core.errors import ConfigError
from portal_harness.core.exr import REGION_CLASSES
from portal_harness.core.metrics import WHOLE_IMAGE, Region
from portal_harness.experiment import contract
from portal_harness.experiment.limits import Limits, check_points, limit_work
from portal_harness.experiment.model import Budget, Experiment, RegressSettings
from portal_harness.experiment.precision import read_precision
from portal_harness.experiment.scene import read_scene
from portal_harness.experiment.schema import SEED_MAX, SPP_MAX, Reader, kind_of, parse_threads, read_yaml_lines
from portal_harness.experiment.sections import (
    check_override_key,
    read_axis,
    read_points,
    read_reference_settings,
    read_region_sections,
    read_value,
)
from portal_harness.experiment.spec import (
    SNAPSHOT_KEYS,
    format_value,
)

CURVE_METRICS = ("rel_mse", "mse")
MAX_INSETS = 64  # each is measured in every run: a bound on the work of a sweep's metrics


# Region names the harness gives itself (regions.py); insets may not take them.
RESERVED_REGION_NAMES = frozenset({WHOLE_IMAGE, "lit", *REGION_CLASSES})


def load_experiment(
    path: Path | str, renderer: str, relative_to: Path | None = None, limits: Limits | None = None
) -> Experiment:
    """Reads and validates an experiment against the renderer at `renderer`
    (its strategies and integrators, and its effective config of the scene
    at every point); raises ConfigError on the first problem. Relative paths
    in it are relative to `relative_to` (default: the file's folder; the service
    stores submitted files apart from the root folder their paths name).
    With `limits`, the work it asks for is checked (limits.py) before any
    point is asked of the renderer."""
    try:
        p = Path(path).resolve() if Path(path).exists() else Path(path)
    except OSError:  # no such file can exist (a name too long): read_yaml_lines says so, located
        p = Path(path)
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
            "precision",
        },
        required={"scene", "strategies", "sweep"},
    )
    name = r.name(root.get("name", p.stem), "name")

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
        check_override_key(r, key, f"sweep.{key}", params, swept=True)
        items = r.sequence(values, f"sweep.{key}")
        sweep.append((key, tuple(read_value(r, names, key, v, f"sweep.{key}.{i}") for i, v in enumerate(items))))
        if len(set(map(format_value, sweep[-1][1]))) != len(items):
            raise r.fail(f"sweep.{key}", "a value is listed twice")

    fixed_node = root.get("fixed", {}) or {}
    if not isinstance(fixed_node, dict):
        raise r.fail("fixed", f"expected a mapping from parameter to value, got {kind_of(fixed_node)}")
    fixed: dict[str, str] = {}
    for k, v in fixed_node.items():
        key = str(k)
        check_override_key(r, key, f"fixed.{key}", params)
        if key in dict(sweep):
            raise r.fail(f"fixed.{key}", "also swept (a parameter is either fixed or swept)")
        fixed[key] = format_value(read_value(r, names, key, v, f"fixed.{key}"))

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
        spp = r.integer(b.get("spp", 0), "budget.spp", maximum=SPP_MAX)
        if time_s == 0 and spp == 0:
            raise r.fail("budget", "expected time_s > 0 or spp > 0 (a run needs a limit)")
        snaps_node = r.mapping(b.get("snapshots", {}) or {}, "budget.snapshots", set(SNAPSHOT_KEYS))
        # Counted in samples (integers) or seconds, as the renderer says.
        snapshots = tuple(
            (
                k,
                format_value(
                    r.integer(v, f"budget.snapshots.{k}", minimum=1, maximum=SPP_MAX)
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
            seed=r.integer(b.get("seed", 1), "budget.seed", maximum=SEED_MAX),
            snapshots=snapshots,
            replicates=r.integer(b.get("replicates", 1), "budget.replicates", minimum=1, maximum=SEED_MAX),
        )
        if budget.seed + budget.replicates * len(names.strategies) > SEED_MAX:
            raise r.fail(
                "budget.seed", f"the replicates' seeds (budget.seed + one per replicate and strategy) pass {SEED_MAX}"
            )

    reference = read_reference_settings(r, root.get("reference", {}) or {}, budget, names.strategies)

    insets: list[Region] = []
    inset_nodes = r.sequence(root.get("insets", []) or [], "insets", non_empty=False)
    if len(inset_nodes) > MAX_INSETS:
        raise r.fail("insets", f"expected at most {MAX_INSETS} insets, got {len(inset_nodes)}")
    for i, node in enumerate(inset_nodes):
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

    region_classes = tuple(c.removeprefix("region.") for c in names.region_channels)
    precision = (
        read_precision(r, root["precision"], budget, tuple(insets), region_classes, len(names.strategies))
        if "precision" in root
        else None
    )

    axis = read_axis(r, root.get("axis"), tuple(sweep))
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
            spp=r.integer(g["spp"], "regress.spp", minimum=1, maximum=SPP_MAX),
            seeds=seeds,
            z_max=r.number(g.get("z_max", 4.0), "regress.z_max", positive=True),
            baseline=(folder / r.string(baseline, "regress.baseline")).resolve() if baseline else Path(),
        )

    if limits is not None and budget is not None:
        limit_work(r, limits, names, tuple(sweep), strategies, budget, reference, width * height, precision)
    elif limits is not None:
        check_points(r, limits, tuple(sweep))
    points = read_points(r, renderer, scene, tuple(sweep), fixed_overrides, axis, facet_keys)

    regions_node = r.mapping(root.get("regions", {}) or {}, "regions", {"lit_threshold"})
    lit_threshold = r.number(regions_node.get("lit_threshold", 0.001), "regions.lit_threshold", positive=True)

    fig = r.mapping(
        root.get("figures", {}) or {}, "figures", {"equal_time_s", "curve_metric", "region_sections", "compare"}
    )
    compare = None
    if "compare" in fig:
        c = r.mapping(fig["compare"], "figures.compare", {"experiment", "strategy"}, {"experiment", "strategy"})
        # A name of an experiment in this results folder, never a path: the
        # error says the same whether or not anything of that name exists.
        compare = (
            r.name(c["experiment"], "figures.compare.experiment"),
            r.choice(c["strategy"], "figures.compare.strategy", strategies, "strategy"),
        )
    equal_time = fig.get("equal_time_s")
    sections = (
        read_region_sections(r, folder, renderer, fig["region_sections"], fixed_overrides, points)
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
        region_classes=region_classes,
        precision=precision,
    )
