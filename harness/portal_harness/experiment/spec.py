"""RunSpec: everything that determines one render, its command line and its keys.

Keys (16 hex digits of SHA-256 over canonical JSON):
- run key: the bytes of the scene file and of every file it includes
  (scene.files_sha256), every --set override, strategy,
  integrator, spp, time, seed, threads, snapshot schedule and the renderer
  version. These inputs determine the renderer's effective config
  (DIR/config.yaml) completely, so the key can be known before the render
  starts, which is what resuming needs.
- scene hash: the scene's files' bytes, the integrator and the overrides
  outside render.* plus render.max_depth and render.rr_depth: what changes
  the expected image, not how it is sampled.
- reference key: the scene hash, the reference strategy, spp, time, seed
  (and threads when time-limited, since they change the sample count) and
  the renderer version.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any

# The renderer's scalar snapshot schedules (render.snapshots.*), the ones
# --set can reach; their units come from `render --describe`.
SNAPSHOT_KEYS: tuple[str, ...] = ("every", "doubling", "every_spp", "doubling_spp")
# render.* keys that change the expected image (all others only change the noise).
IMAGE_RENDER_KEYS: frozenset[str] = frozenset({"render.integrator", "render.max_depth", "render.rr_depth"})
# render.* keys the harness sets itself through flags; an override may not set them.
HARNESS_RENDER_KEYS: frozenset[str] = frozenset(
    {
        "render.output",
        "render.spp",
        "render.time",
        "render.seed",
        "render.threads",
        "render.strategy",
        "render.integrator",
    }
)

Overrides = tuple[tuple[str, str], ...]
# Runs that need only final.exr (references, pilots, region maps, regress):
# 0 turns each of the renderer's scalar schedules off (renderer/src/config/config.c,
# load_snapshots; render.c: a period of 0 never comes due), whatever the
# scene sets. A scene's `times:` or `spp:` lists cannot be overridden by
# --set and still apply.
NO_SNAPSHOTS: Overrides = tuple((k, "0") for k in SNAPSHOT_KEYS)


def format_value(value: Any) -> str:
    """A YAML scalar as the renderer's --set expects it; floats keep their
    shortest round-trip form so that equal numbers give equal keys."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if value.is_integer() and abs(value) < 1e15:
            return str(int(value)) if not math.isnan(value) else "nan"
        return repr(value)
    return str(value)


def short_hash(payload: Any) -> str:
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class RunSpec:
    """One render. `scene` is an absolute path; `scene_sha256` fixes its content."""

    scene: str
    scene_sha256: str
    strategy: str
    integrator: str
    spp: int
    time_s: float
    seed: int
    threads: int
    overrides: Overrides = ()
    snapshots: Overrides = ()
    reference: bool = False
    labels: tuple[tuple[str, float], ...] = field(default=(), compare=False)

    def scene_hash(self) -> str:
        image_overrides = [(k, v) for k, v in self.overrides if not k.startswith("render.") or k in IMAGE_RENDER_KEYS]
        return short_hash({"scene": self.scene_sha256, "integrator": self.integrator, "overrides": image_overrides})

    def key(self, renderer_version: str) -> str:
        if self.reference:
            payload: dict[str, Any] = {
                "kind": "reference",
                "scene_hash": self.scene_hash(),
                "strategy": self.strategy,
                "spp": self.spp,
                "time_s": self.time_s,
                "seed": self.seed,
                "renderer": renderer_version,
            }
            if self.time_s > 0:
                payload["threads"] = self.threads
            return short_hash(payload)
        return short_hash(
            {
                "kind": "run",
                "scene": self.scene_sha256,
                "overrides": list(self.overrides),
                "strategy": self.strategy,
                "integrator": self.integrator,
                "spp": self.spp,
                "time_s": self.time_s,
                "seed": self.seed,
                "threads": self.threads,
                "snapshots": list(self.snapshots),
                "renderer": renderer_version,
            }
        )

    def command(self, renderer: str, scene_path: str, out_dir: str) -> list[str]:
        """The renderer's command line (renderer contract)."""
        cmd = [
            renderer,
            scene_path,
            "--out",
            out_dir,
            "--strategy",
            self.strategy,
            "--integrator",
            self.integrator,
            "--spp",
            str(self.spp),
            "--time",
            format_value(float(self.time_s)),
            "--seed",
            str(self.seed),
            "--threads",
            str(self.threads),
        ]
        for k, v in self.overrides:
            cmd += ["--set", f"{k}={v}"]
        for k, v in self.snapshots:
            cmd += ["--set", f"render.snapshots.{k}={v}"]
        return cmd

    def params(self) -> dict[str, Any]:
        """Overrides and labels as typed values, for the index."""
        out: dict[str, Any] = {}
        for k, v in self.overrides:
            try:
                out[k] = float(v)
            except ValueError:
                out[k] = v
        out.update(dict(self.labels))
        return out

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["overrides"] = [list(p) for p in self.overrides]
        d["snapshots"] = [list(p) for p in self.snapshots]
        d["labels"] = [list(p) for p in self.labels]
        return d

    @staticmethod
    def from_dict(d: dict[str, Any]) -> RunSpec:
        return RunSpec(
            scene=str(d["scene"]),
            scene_sha256=str(d["scene_sha256"]),
            strategy=str(d["strategy"]),
            integrator=str(d["integrator"]),
            spp=int(d["spp"]),
            time_s=float(d["time_s"]),
            seed=int(d["seed"]),
            threads=int(d["threads"]),
            overrides=tuple((str(k), str(v)) for k, v in d.get("overrides", [])),
            snapshots=tuple((str(k), str(v)) for k, v in d.get("snapshots", [])),
            reference=bool(d.get("reference", False)),
            labels=tuple((str(k), float(v)) for k, v in d.get("labels", [])),
        )
