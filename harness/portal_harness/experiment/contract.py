"""The renderer's contract, asked of the renderer: `render --describe` (its
names: strategies, integrators, snapshot keys, EXR channels, exit codes...)
and `render --print-config` (a scene's effective config: includes merged,
params evaluated, overrides applied, defaults filled, and the files it was
built from). The harness keeps no copy of either: a strategy the renderer
adds is known here the moment the binary has it.

Both answers are cached per process: --describe per renderer binary (path,
modification time and size), --print-config per (binary, scene, overrides,
flags) for as long as none of the files it was built from changes.
"""

from __future__ import annotations

import json
import os
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from portal_harness.core.errors import ConfigError, RendererError

TIMEOUT_S = 30

# (path, st_mtime_ns, st_size): a rebuilt binary is asked again.
BinaryStamp = tuple[str, int, int]
FileStamps = tuple[tuple[str, int, int], ...]


@dataclass(frozen=True)
class Contract:
    """`render --describe`, typed. Lists keep the renderer's order."""

    program: str
    version: str
    strategies: tuple[str, ...]
    integrators: tuple[str, ...]
    materials: tuple[str, ...]
    mis: tuple[str, ...]
    portal_weights: tuple[str, ...]
    samplers: tuple[str, ...]
    region_channels: tuple[str, ...]  # aov.region: the region AOV's EXR channels
    exr_channels: tuple[str, ...]
    exr_attributes: tuple[str, ...]
    snapshot_units: tuple[tuple[str, str], ...]  # render.snapshots key -> "s" or "spp"
    exit_codes: tuple[tuple[str, int], ...]  # name -> status
    json_events: tuple[str, ...]

    def snapshot_unit(self, key: str) -> str | None:
        """The unit of render.snapshots.<key> ("s" or "spp"), None for a key the renderer lacks."""
        return dict(self.snapshot_units).get(key)


@dataclass(frozen=True)
class EffectiveConfig:
    """`render --print-config SCENE [--set K=V]... --format json`: what a
    render of SCENE with these overrides would use."""

    scene: Path
    config: dict[str, Any]  # the effective tree
    params: dict[str, float]  # params, evaluated, after the overrides
    files: tuple[Path, ...]  # the scene file, then every included file in load order
    hash: str  # the renderer's config hash (16 hex digits)
    image_hash: str  # the same over what changes the expected image

    def get(self, dotted: str) -> Any:
        """The value at a dotted key (sequence items by index); KeyError if absent."""
        node: Any = self.config
        for part in dotted.split("."):
            if isinstance(node, dict) and part in node:
                node = node[part]
            elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
                node = node[int(part)]
            else:
                raise KeyError(dotted)
        return node

    @property
    def render(self) -> dict[str, Any]:
        section = self.config.get("render")
        return section if isinstance(section, dict) else {}

    @property
    def width(self) -> int:
        return int(self.get("film.width"))

    @property
    def height(self) -> int:
        return int(self.get("film.height"))


def _binary_stamp(renderer: str | Path) -> BinaryStamp:
    path = os.path.abspath(renderer)
    try:
        st = os.stat(path)
    except OSError:
        raise RendererError(f"renderer not found at {path} (build it with `make`, or pass --renderer)") from None
    return path, st.st_mtime_ns, st.st_size


def _run(stamp: BinaryStamp, args: list[str]) -> subprocess.CompletedProcess[str]:
    path = stamp[0]
    try:
        return subprocess.run([path, *args], capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    except OSError as e:
        raise RendererError(f"cannot run renderer {path}: {e.strerror}") from None
    except subprocess.TimeoutExpired:
        raise RendererError(f"renderer {path} did not answer {args[0]} within {TIMEOUT_S} s") from None


def _strings(data: dict[str, Any], key: str, path: str) -> tuple[str, ...]:
    value = data.get(key)
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise RendererError(f"renderer {path} --describe: {key!r} is not a list of names")
    return tuple(value)


def _parse_describe(path: str, text: str) -> Contract:
    try:
        data = json.loads(text)
        if not isinstance(data, dict):
            raise ValueError("not a JSON object")
        aov = data.get("aov")
        units = data.get("snapshot_keys")
        codes = data.get("exit_codes")
        if not isinstance(aov, dict) or not isinstance(units, dict) or not isinstance(codes, dict):
            raise ValueError("aov, snapshot_keys and exit_codes must be objects")
        return Contract(
            program=str(data["program"]),
            version=str(data["version"]),
            strategies=_strings(data, "strategies", path),
            integrators=_strings(data, "integrators", path),
            materials=_strings(data, "materials", path),
            mis=_strings(data, "mis", path),
            portal_weights=_strings(data, "portal_weights", path),
            samplers=_strings(data, "samplers", path),
            region_channels=_strings(aov, "region", path),
            exr_channels=_strings(data, "exr_channels", path),
            exr_attributes=_strings(data, "exr_attributes", path),
            snapshot_units=tuple((str(k), str(v)) for k, v in units.items()),
            exit_codes=tuple((str(k), int(v)) for k, v in codes.items()),
            json_events=_strings(data, "json_events", path),
        )
    except (ValueError, KeyError, TypeError) as e:
        raise RendererError(f"renderer {path} --describe: unexpected answer ({e})") from None


_contracts: dict[BinaryStamp, Contract] = {}


def describe(renderer: str | Path) -> Contract:
    """The contract of the renderer binary at `renderer`; RendererError if it
    is missing or does not describe itself."""
    stamp = _binary_stamp(renderer)
    found = _contracts.get(stamp)
    if found is None:
        out = _run(stamp, ["--describe"])
        if out.returncode != 0:
            raise RendererError(
                f"renderer {stamp[0]} --describe failed (exit {out.returncode}): {out.stderr.strip()[:200]}"
            )
        found = _contracts[stamp] = _parse_describe(stamp[0], out.stdout)
    return found


def _file_stamps(files: Sequence[Path]) -> FileStamps | None:
    out = []
    for f in files:
        try:
            st = os.stat(f)
        except OSError:
            return None
        out.append((str(f), st.st_mtime_ns, st.st_size))
    return tuple(out)


def _config_error(text: str, scene: Path) -> ConfigError:
    """The renderer's `file:line:column: message` (or `render: message`) as a ConfigError with that text."""
    lines = [line for line in text.strip().splitlines() if line.strip()]
    message = lines[0] if lines else f"{scene}: rejected by the renderer (no message)"
    where, sep, rest = message.partition(": ")
    return ConfigError(where, "", rest) if sep else ConfigError(str(scene), "", message)


_configs: dict[
    tuple[BinaryStamp, str, tuple[tuple[str, str], ...], tuple[str, ...]], tuple[EffectiveConfig, FileStamps]
] = {}


def print_config(
    renderer: str | Path, scene: Path, overrides: Sequence[tuple[str, str]] = (), flags: Sequence[str] = ()
) -> EffectiveConfig:
    """The effective config of `scene` with `--set K=V` for each override
    and the renderer options `flags` (e.g. ["--strategy", "portal"]). A
    config the renderer rejects raises ConfigError with the renderer's own
    message (file:line:column: ...)."""
    stamp = _binary_stamp(renderer)
    scene = Path(os.path.abspath(scene))
    key = (stamp, str(scene), tuple((str(k), str(v)) for k, v in overrides), tuple(flags))
    cached = _configs.get(key)
    if cached is not None and _file_stamps(cached[0].files) == cached[1]:
        return cached[0]
    args = ["--print-config", str(scene)]
    for k, v in key[2]:
        args += ["--set", f"{k}={v}"]
    args += [*key[3], "--format", "json"]
    out = _run(stamp, args)
    if out.returncode != 0:
        raise _config_error(out.stderr, scene)
    try:
        data = json.loads(out.stdout)
        effective = EffectiveConfig(
            scene=scene,
            config=dict(data["config"]),
            params={str(k): float(v) for k, v in dict(data["params"]).items()},
            files=tuple(Path(os.path.abspath(str(f))) for f in data["files"]),
            hash=str(data["hash"]),
            image_hash=str(data["image_hash"]),
        )
    except (ValueError, KeyError, TypeError) as e:
        raise RendererError(f"renderer {stamp[0]} --print-config {scene}: unexpected answer ({e})") from None
    stamps = _file_stamps(effective.files)
    if stamps is not None:
        _configs[key] = (effective, stamps)
    return effective
