"""A stand-in for renderer/build/render that obeys the command-line contract
(renderer/CONTRACT.md) in milliseconds, so that the harness's pipeline
tests do not depend on render time and can inject failures.

The contract itself is the real renderer's: `--describe` and
`--print-config` are forwarded to it (FAKE_RENDER_REAL, set by conftest.py),
and a render first asks it for the effective config, so that a config or
override the renderer rejects fails here with its message and exit status
2, and the fake renders what the renderer would read (includes, params,
defaults).

Images: the mean is a known function of the pixel and params.s_L (see
`true_mean`); each pass adds one sample per pixel, mean * (1 + sigma * z)
with z standard normal and sigma fixed per strategy, so the variance of the
mean falls as 1/spp. Time is virtual: each pass costs COST[strategy]
seconds of reported render time (and FAKE_RENDER_SLEEP real seconds per
virtual second, default 0).

Region AOV (render.aov.region: true): the left half of the image is
anti_umbra, the right half anti_antumbra, the top two rows emitter (every
sample of a pixel in one class). render.resumable: true keeps the film in
final.state (numpy), and `render --resume DIR --spp N` continues it; each
pass draws from its own generator (seed, strategy, s_L, pass), so a resumed
render equals an uninterrupted one.

The final event carries the shadow-ray counters of the contract
(`counters`: fixed shares per strategy, so that a figure's bars are known).

Environment knobs:
  FAKE_RENDER_REAL=path          the real renderer (required)
  FAKE_RENDER_LOG=path           append one line per render (strategy seed out)
  FAKE_RENDER_CRASH=s1,s2        these strategies die by SIGSEGV after the first snapshot
  FAKE_RENDER_UNIMPLEMENTED=s1   these strategies exit 1 with "not implemented"
  FAKE_RENDER_SLEEP=x            real seconds slept per virtual second
  PORTAL_LIGHTS_FAULT_BIAS=s:f   as the renderer: samples of strategy s are multiplied by f
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from exrwrite import write_snapshot

VERSION = "0.1.0-fake"
# The fake's noise model per strategy; a strategy it does not know gets DEFAULT_SIGMA and DEFAULT_COST.
SIGMA = {"light_area": 1.6, "light": 1.2, "portal": 0.7, "projection": 0.6, "antishadow": 0.45, "antishadow_exact": 0.4}
COST = {
    "light_area": 0.008,
    "light": 0.01,
    "portal": 0.011,
    "projection": 0.012,
    "antishadow": 0.013,
    "antishadow_exact": 0.016,
}
DEFAULT_SIGMA, DEFAULT_COST = 1.0, 0.01
# The final event's counters (see `counters`): per strategy, the share of next-event samples
# whose direction misses the light, and of shadow rays that are blocked.
MISSED = {"light_area": 0.0, "light": 0.0, "portal": 0.5, "projection": 0.25, "antishadow": 0.1}
BLOCKED = {"light_area": 0.9, "light": 0.9, "portal": 0.2, "projection": 0.1, "antishadow": 0.05}
COLOUR = np.array([1.0, 0.8, 0.6])


def true_mean(width: int, height: int, s_L: float) -> np.ndarray:
    x = (np.arange(width) + 0.5) / width
    y = (np.arange(height) + 0.5) / height
    shade = 0.2 + 0.6 * x[None, :] + 0.4 * y[:, None]
    mean: np.ndarray = shade[..., None] * COLOUR * (1.0 + 0.5 * s_L)
    return mean


def region_fractions(channels: list[str], width: int, height: int) -> dict[str, np.ndarray]:
    """`channels` are the renderer's region AOV channels, in its order (outside, anti_umbra,
    anti_penumbra, anti_antumbra, inside, emitter, miss)."""
    cls = np.where(np.arange(width)[None, :] < width // 2, 1, 3) * np.ones((height, 1), dtype=int)
    cls[:2, :] = 5
    return {name: (cls == i).astype(np.float32) for i, name in enumerate(channels)}


def counters(strategy: str, passes: int, width: int, height: int) -> dict[str, int]:
    """The final event's shadow-ray counters: one next-event sample per pixel
    and pass, a tenth of them with nothing to deliver (no ray)."""
    samples = passes * width * height
    missed = round(samples * MISSED.get(strategy, 0.0))
    shadow_rays = samples - missed - samples // 10
    return {
        "shadow_rays": shadow_rays,
        "shadow_blocked": round(shadow_rays * BLOCKED.get(strategy, 0.0)),
        "light_samples": samples,
        "light_missed": missed,
    }


def real_renderer() -> str:
    path = os.environ.get("FAKE_RENDER_REAL", "")
    if not path:
        print("render (fake): FAKE_RENDER_REAL is not set", file=sys.stderr)
        sys.exit(2)
    return path


def ask_real(args: list[str]) -> dict[str, Any]:
    """The real renderer's JSON answer to `args`; its stderr and exit status if it fails."""
    out = subprocess.run([real_renderer(), *args], capture_output=True, text=True, check=False)
    if out.returncode != 0:
        sys.stderr.write(out.stderr)
        sys.exit(out.returncode)
    data: dict[str, Any] = json.loads(out.stdout)
    return data


def main(argv: list[str]) -> int:
    if "--version" in argv:
        print(f"render {VERSION}")
        return 0
    if "--describe" in argv or "--print-config" in argv:
        os.execv(real_renderer(), [real_renderer(), *argv])
    if "--help" in argv or not argv:
        print("usage: render CONFIG [--set key=value]... [--out DIR] ...", file=sys.stderr)
        return 0 if argv else 2
    resume_dir: Path | None = None
    if argv[0] == "--resume":
        if len(argv) < 2:
            print("render: --resume needs a folder", file=sys.stderr)
            return 2
        resume_dir = Path(argv[1])
        config_path, rest = str(resume_dir / "config.yaml"), argv[2:]
        if not (resume_dir / "final.state.npz").exists():
            print(
                f"render: {resume_dir}/final.state: missing (render with render.resumable: true to resume)",
                file=sys.stderr,
            )
            return 2
    else:
        config_path, rest = argv[0], argv[1:]
    # What the renderer would read: it checks the config, the overrides and the options.
    printed = ask_real(["--print-config", config_path, *rest, "--format", "json"])
    tree, params = printed["config"], printed["params"]
    render = tree["render"]
    if resume_dir is not None:
        render["output"] = str(resume_dir)
    strategy = str(render["strategy"])
    if strategy in os.environ.get("FAKE_RENDER_UNIMPLEMENTED", "").split(","):
        print(f"render: strategy {strategy} is not implemented yet", file=sys.stderr)
        return 1
    region_channels = ask_real(["--describe"])["aov"]["region"]
    out = Path(str(render["output"]))
    out.mkdir(parents=True, exist_ok=True)
    width, height = int(tree["film"]["width"]), int(tree["film"]["height"])
    spp_target, time_target = int(render["spp"]), float(render["time"])
    seed = int(render["seed"])
    integrator = str(render["integrator"])
    snaps = render.get("snapshots", {}) or {}
    every, doubling, every_spp = (
        float(snaps.get("every", 0)),
        float(snaps.get("doubling", 0)),
        int(snaps.get("every_spp", 0)),
    )
    doubling_spp = int(snaps.get("doubling_spp", 0))
    if spp_target == 0 and time_target == 0:
        print(f"{config_path}:1:1: spp and time are both 0", file=sys.stderr)
        return 2
    aov = bool((render.get("aov") or {}).get("region", False))
    resumable = bool(render.get("resumable", False))
    state = np.load(resume_dir / "final.state.npz") if resume_dir is not None else None
    # The effective YAML has params substituted (no params section): a resumed render takes s_L from its state.
    s_L = float(state["s_L"]) if state is not None else float(params.get("s_L", 0.5))
    (out / "config.yaml").write_text(yaml.safe_dump(tree, sort_keys=True))
    config_hash = str(printed["hash"])
    bias_strategy, _, bias_factor = os.environ.get("PORTAL_LIGHTS_FAULT_BIAS", "").partition(":")
    bias = float(bias_factor) if bias_strategy == strategy else 1.0
    if log := os.environ.get("FAKE_RENDER_LOG"):
        with open(log, "a") as f:
            f.write(f"{strategy} {seed} {out}\n")

    stop = {"now": False}

    def on_signal(signum: int, frame: Any) -> None:
        stop["now"] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)

    def emit(event: dict[str, Any]) -> None:
        sys.stdout.write(json.dumps(event) + "\n")
        sys.stdout.flush()

    emit(
        {
            "event": "start",
            "out": str(out),
            "width": width,
            "height": height,
            "strategy": strategy,
            "integrator": integrator,
            "seed": seed,
            "config_hash": config_hash,
            "renderer_version": VERSION,
            "spp_target": spp_target,
            "time_target_s": time_target,
            "resumed_from_spp": int(state["passes"]) if state is not None else 0,
        }
    )
    mean = true_mean(width, height, s_L)
    sigma = SIGMA.get(strategy, DEFAULT_SIGMA)
    cost = COST.get(strategy, DEFAULT_COST)
    stream = list(SIGMA).index(strategy) if strategy in SIGMA else len(SIGMA)
    acc_mean = np.zeros_like(mean)
    acc_m2 = np.zeros_like(mean)
    passes = 0
    t = 0.0
    index = 0
    if state is not None:
        acc_mean, acc_m2 = state["mean"].copy(), state["m2"].copy()
        passes, t, index = int(state["passes"]), float(state["time"]), int(state["index"])
    sleep = float(os.environ.get("FAKE_RENDER_SLEEP", "0"))
    crash = strategy in os.environ.get("FAKE_RENDER_CRASH", "").split(",")
    next_every = every if every > 0 else float("inf")
    next_doubling = doubling if doubling > 0 else float("inf")
    while next_every <= t:
        next_every += every
    while next_doubling <= t:
        next_doubling *= 2
    next_spp = every_spp if every_spp > 0 else None

    def write(path: Path) -> None:
        var = acc_m2 / max(passes - 1, 1) / max(passes, 1) if passes >= 2 else np.zeros_like(acc_m2)
        write_snapshot(
            path,
            acc_mean,
            var,
            render_time_s=t,
            spp=passes,
            strategy=strategy,
            integrator=integrator,
            seed=seed,
            config_hash=config_hash,
            renderer_version=VERSION,
            rays=2.0 * passes * width * height,
            extra_channels=region_fractions(region_channels, width, height) if aov else None,
        )

    while not stop["now"]:
        if spp_target and passes >= spp_target:
            break
        if time_target and t >= time_target - 1e-12:
            break
        rng = np.random.default_rng([seed, stream, round(s_L * 1e6), passes])
        sample = bias * mean * (1.0 + sigma * rng.standard_normal(mean.shape))
        passes += 1
        d = sample - acc_mean
        acc_mean += d / passes
        acc_m2 += d * (sample - acc_mean)
        t += cost
        if sleep:
            time.sleep(cost * sleep)
        due = False
        while t >= next_every - 1e-12:
            due, next_every = True, next_every + every
        while t >= next_doubling - 1e-12:
            due, next_doubling = True, next_doubling * 2
        if next_spp is not None and passes % next_spp == 0:
            due = True
        k = passes // doubling_spp if doubling_spp > 0 and passes % doubling_spp == 0 else 0
        if k > 0 and k & (k - 1) == 0:  # doubling_spp x 1, 2, 4, ...
            due = True
        if due:
            index += 1
            path = out / f"snapshot_{index:04d}.exr"
            write(path)
            emit(
                {
                    "event": "snapshot",
                    "index": index,
                    "path": str(path),
                    "time_s": round(t, 6),
                    "spp": passes,
                    "rays": 2 * passes * width * height,
                    "nonfinite": 0,
                }
            )
            if crash:
                print("render: simulated crash in the fake renderer", file=sys.stderr)
                sys.stderr.flush()
                os.kill(os.getpid(), signal.SIGSEGV)
    final = out / "final.exr"
    if resumable:
        tmp = out / ".final.state.tmp.npz"
        np.savez(tmp, mean=acc_mean, m2=acc_m2, passes=passes, time=t, index=index, s_L=s_L)
        os.replace(tmp, out / "final.state.npz")
    write(final)
    emit(
        {
            "event": "final",
            "path": str(final),
            "time_s": round(t, 6),
            "spp": passes,
            "rays": 2 * passes * width * height,
            "nonfinite": 0,
            "interrupted": stop["now"],
            **counters(strategy, passes, width, height),
        }
    )
    return 3 if stop["now"] else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
