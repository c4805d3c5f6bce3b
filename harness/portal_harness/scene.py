"""RunSpecs for single renders of a scene file (`run`, `reference`): every
setting not given comes from the scene's render section, so that the run key
covers everything that determines the image."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from portal_harness.errors import ConfigError
from portal_harness.schema import Reader, parse_threads, read_scene
from portal_harness.spec import (
    HARNESS_RENDER_KEYS,
    INTEGRATORS,
    SNAPSHOT_KEYS,
    STRATEGIES,
    RunSpec,
    format_value,
)


def spec_from_scene(
    scene: Path,
    overrides: dict[str, str],
    strategy: str | None = None,
    integrator: str | None = None,
    spp: int | None = None,
    time_s: float | None = None,
    seed: int | None = None,
    threads: int | str | None = None,
    snapshots: dict[str, str] | None = None,
    reference: bool = False,
) -> RunSpec:
    """A RunSpec for `run`/`reference` on a scene file: unset settings come
    from the scene's render section (with --set render.* applied), so the key
    covers everything."""
    scene = scene.resolve()
    info = read_scene(scene)
    r = Reader(str(scene))
    merged = dict(info.scalars)
    for k, v in overrides.items():
        try:
            merged[k] = yaml.safe_load(v) if v != "" else v
        except yaml.YAMLError:
            raise ConfigError("--set", k, f"value {v!r} is not a YAML scalar") from None

    def pick(given: Any, key: str, default: Any) -> Any:
        return given if given is not None else merged.get(key, default)

    chosen_strategy = r.choice(pick(strategy, "render.strategy", "light"), "render.strategy", STRATEGIES, "strategy")
    chosen_integrator = r.choice(pick(integrator, "render.integrator", "direct"), "render.integrator",
                                 INTEGRATORS, "integrator")
    chosen_spp = r.integer(pick(spp, "render.spp", 0), "render.spp")
    chosen_time = r.number(pick(time_s, "render.time", 0), "render.time")
    if chosen_spp == 0 and chosen_time == 0:
        raise r.fail("render", "expected spp > 0 or time > 0 (a run needs a limit)")
    passed = {k: v for k, v in overrides.items() if k not in HARNESS_RENDER_KEYS and not k.startswith("render.snapshots")}
    if snapshots is None:
        snapshots = {k.split(".")[-1]: format_value(v) for k, v in merged.items()
                     if k.startswith("render.snapshots.") and k.split(".")[-1] in SNAPSHOT_KEYS}
    return RunSpec(
        scene=str(scene),
        scene_sha256=info.sha256,
        strategy=chosen_strategy,
        integrator=chosen_integrator,
        spp=chosen_spp,
        time_s=chosen_time,
        seed=r.integer(pick(seed, "render.seed", 1), "render.seed"),
        threads=parse_threads(pick(threads, "render.threads", "auto"), r, "render.threads"),
        overrides=tuple(sorted(passed.items())),
        snapshots=tuple(sorted(snapshots.items())),
        reference=reference,
    )
