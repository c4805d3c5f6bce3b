"""Scene files as the renderer reads them, and RunSpecs of single renders
of one (`run`, `reference`).

The harness does not parse scenes itself: `render --print-config` gives
the effective config (includes merged, params evaluated, overrides
applied, defaults filled) and the files it was built from: the scene, every
file it includes and every mesh file it reads. The harness adds only the
digest of those files' contents (scene_files.py), the scene part of its
run keys: a change in an included file or a mesh changes the key.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from portal_harness.core.errors import ConfigError
from portal_harness.experiment import contract
from portal_harness.experiment.scene_files import files_sha256
from portal_harness.experiment.schema import Reader, parse_threads
from portal_harness.experiment.spec import HARNESS_RENDER_KEYS, SNAPSHOT_KEYS, RunSpec, format_value


@dataclass(frozen=True)
class SceneInfo:
    """What the harness knows of a scene file: the renderer's effective
    config of it, and the digest of every file it was built from."""

    path: Path
    effective: contract.EffectiveConfig
    sha256: str

    @property
    def files(self) -> tuple[Path, ...]:
        return self.effective.files

    @property
    def width(self) -> int:
        return self.effective.width

    @property
    def height(self) -> int:
        return self.effective.height


def read_scene(renderer: str, path: Path, overrides: Sequence[tuple[str, str]] = ()) -> SceneInfo:
    """The scene at `path` with `overrides` applied, as the renderer reads it;
    ConfigError with the renderer's message if it rejects either."""
    effective = contract.print_config(renderer, path, overrides)
    return SceneInfo(path=path, effective=effective, sha256=files_sha256(effective.files))


def spec_from_scene(
    scene: Path,
    overrides: dict[str, str],
    renderer: str,
    strategy: str | None = None,
    integrator: str | None = None,
    spp: int | None = None,
    time_s: float | None = None,
    seed: int | None = None,
    threads: int | str | None = None,
    snapshots: dict[str, str] | None = None,
    reference: bool = False,
) -> RunSpec:
    """A RunSpec for `run`/`reference` on a scene file. Settings not given
    come from the scene's render section as the renderer fills it (with the
    --set overrides applied), so that the key covers everything; the
    renderer validates the overrides and the settings."""
    scene = scene.resolve()
    flags: list[str] = []
    for flag, value in (
        ("--strategy", strategy),
        ("--integrator", integrator),
        ("--spp", spp),
        ("--time", None if time_s is None else float(time_s)),
        ("--seed", seed),
        ("--threads", threads),
    ):
        if value is not None:
            flags += [flag, format_value(value)]
    asked = [*overrides.items(), *((f"render.snapshots.{k}", v) for k, v in (snapshots or {}).items())]
    effective = contract.print_config(renderer, scene, asked, flags)
    render = effective.render
    r = Reader(str(scene))
    chosen_spp = r.integer(render.get("spp"), "render.spp")
    chosen_time = r.number(render.get("time"), "render.time")
    if chosen_spp == 0 and chosen_time == 0:
        raise r.fail("render", "expected spp > 0 or time > 0 (a run needs a limit)")
    if snapshots is None:
        schedule = render.get("snapshots") or {}
        snapshots = {k: format_value(v) for k, v in schedule.items() if k in SNAPSHOT_KEYS}
    passed = {
        k: v for k, v in overrides.items() if k not in HARNESS_RENDER_KEYS and not k.startswith("render.snapshots")
    }
    if not isinstance(render.get("strategy"), str) or not isinstance(render.get("integrator"), str):
        raise ConfigError(str(scene), "render", "the renderer's effective config names no strategy or integrator")
    return RunSpec(
        scene=str(scene),
        scene_sha256=files_sha256(effective.files),
        strategy=render["strategy"],
        integrator=render["integrator"],
        spp=chosen_spp,
        time_s=chosen_time,
        seed=r.integer(render.get("seed"), "render.seed"),
        threads=parse_threads(render.get("threads"), r, "render.threads"),
        overrides=tuple(sorted(passed.items())),
        snapshots=tuple(sorted(snapshots.items())),
        reference=reference,
    )
