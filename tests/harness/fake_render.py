"""A stand-in for renderer/build/render that obeys the command-line contract
(notes/renderer_contract.md) in milliseconds, so that the harness's pipeline
tests do not depend on render time and can inject failures.

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

Environment knobs:
  FAKE_RENDER_LOG=path           append one line per render (strategy seed out)
  FAKE_RENDER_CRASH=s1,s2        these strategies die by SIGSEGV after the first snapshot
  FAKE_RENDER_UNIMPLEMENTED=s1   these strategies exit 1 with "not implemented"
  FAKE_RENDER_SLEEP=x            real seconds slept per virtual second
  PORTAL_LIGHTS_FAULT_BIAS=s:f   as the renderer: samples of strategy s are multiplied by f
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from exrwrite import write_snapshot  # noqa: E402

VERSION = "0.1.0-fake"
STRATEGIES = ("light_area", "light", "portal", "projection", "antishadow", "antishadow_exact")
SIGMA = {"light_area": 1.6, "light": 1.2, "portal": 0.7, "projection": 0.6, "antishadow": 0.45,
         "antishadow_exact": 0.4}
COST = {"light_area": 0.008, "light": 0.01, "portal": 0.011, "projection": 0.012, "antishadow": 0.013,
        "antishadow_exact": 0.016}
COLOUR = np.array([1.0, 0.8, 0.6])


def true_mean(width: int, height: int, s_L: float) -> np.ndarray:
    x = (np.arange(width) + 0.5) / width
    y = (np.arange(height) + 0.5) / height
    shade = 0.2 + 0.6 * x[None, :] + 0.4 * y[:, None]
    return shade[..., None] * COLOUR * (1.0 + 0.5 * s_L)


REGION_CLASSES = ("outside", "anti_umbra", "anti_penumbra", "anti_antumbra", "inside", "emitter", "miss")


def region_fractions(width: int, height: int) -> dict[str, np.ndarray]:
    cls = np.where(np.arange(width)[None, :] < width // 2, 1, 3) * np.ones((height, 1), dtype=int)
    cls[:2, :] = 5
    return {f"region.{name}": (cls == i).astype(np.float32) for i, name in enumerate(REGION_CLASSES)}


def usage(message: str) -> None:
    print(f"render: {message}", file=sys.stderr)
    sys.exit(2)


def set_path(tree: dict[str, Any], dotted: str, value: Any) -> None:
    parts = dotted.split(".")
    node: Any = tree
    for part in parts[:-1]:
        if isinstance(node, list):
            node = node[int(part)]
        else:
            node = node.setdefault(part, {})
    if isinstance(node, list):
        node[int(parts[-1])] = value
    else:
        node[parts[-1]] = value


def main(argv: list[str]) -> int:
    if "--version" in argv:
        print(f"render {VERSION}")
        return 0
    if "--help" in argv or not argv:
        print("usage: render CONFIG [--set key=value]... [--out DIR] ...", file=sys.stderr)
        return 0 if argv else 2
    resume_dir: Path | None = None
    if argv[0] == "--resume":
        if len(argv) < 2:
            usage("--resume needs a folder")
        resume_dir = Path(argv[1])
        config_path, rest = str(resume_dir / "config.yaml"), argv[2:]
        if not (resume_dir / "final.state.npz").exists():
            print(f"render: {resume_dir}/final.state: missing (render with render.resumable: true to resume)",
                  file=sys.stderr)
            return 2
    else:
        config_path, rest = argv[0], argv[1:]
    sets: list[tuple[str, str]] = []
    flags = {"--out": "render.output", "--spp": "render.spp", "--time": "render.time", "--seed": "render.seed",
             "--threads": "render.threads", "--strategy": "render.strategy", "--integrator": "render.integrator"}
    i = 0
    while i < len(rest):
        arg = rest[i]
        if arg == "--quiet":
            i += 1
            continue
        if i + 1 >= len(rest):
            usage(f"{arg} needs a value")
        if arg == "--set":
            key, _, value = rest[i + 1].partition("=")
            sets.append((key, value))
        elif arg in flags:
            sets.append((flags[arg], rest[i + 1]))
        else:
            usage(f"unknown option {arg}")
        i += 2
    try:
        tree = yaml.safe_load(Path(config_path).read_text())
    except OSError as e:
        print(f"{config_path}:1:1: cannot read: {e.strerror}", file=sys.stderr)
        return 2
    for key, value in sets:
        set_path(tree, key, yaml.safe_load(value))
    render = tree.setdefault("render", {})
    if resume_dir is not None:
        render["output"] = str(resume_dir)
    strategy = str(render.get("strategy", "light"))
    if strategy not in STRATEGIES:
        print(f"{config_path}:1:1: unknown strategy \"{strategy}\" (expected {'|'.join(STRATEGIES)})", file=sys.stderr)
        return 2
    if strategy in os.environ.get("FAKE_RENDER_UNIMPLEMENTED", "").split(","):
        print(f"render: strategy {strategy} is not implemented yet", file=sys.stderr)
        return 1
    out = Path(str(render.get("output", "out")))
    out.mkdir(parents=True, exist_ok=True)
    width, height = int(tree["film"]["width"]), int(tree["film"]["height"])
    spp_target, time_target = int(render.get("spp", 0)), float(render.get("time", 0))
    seed = int(render.get("seed", 1))
    integrator = str(render.get("integrator", "direct"))
    snaps = render.get("snapshots", {}) or {}
    every, doubling, every_spp = float(snaps.get("every", 0)), float(snaps.get("doubling", 0)), int(snaps.get("every_spp", 0))
    doubling_spp = int(snaps.get("doubling_spp", 0))
    if every < 0 or doubling < 0 or every_spp < 0 or doubling_spp < 0:
        print(f"{config_path}:1:1: bad snapshot schedule {snaps} (expected numbers >= 0; 0 is off)", file=sys.stderr)
        return 2
    if spp_target == 0 and time_target == 0:
        print(f"{config_path}:1:1: spp and time are both 0", file=sys.stderr)
        return 2
    s_L = float(tree.get("params", {}).get("s_L", 0.5))
    aov = bool((render.get("aov") or {}).get("region", False))
    resumable = bool(render.get("resumable", False))
    effective = yaml.safe_dump(tree, sort_keys=True)
    (out / "config.yaml").write_text(effective)
    image_tree = {k: v for k, v in tree.items() if k != "render"}
    config_hash = hashlib.sha256(yaml.safe_dump(image_tree, sort_keys=True).encode()).hexdigest()[:16]
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

    emit({"event": "start", "out": str(out), "width": width, "height": height, "strategy": strategy,
          "integrator": integrator, "seed": seed, "config_hash": config_hash, "renderer_version": VERSION,
          "spp_target": spp_target, "time_target_s": time_target,
          "resumed_from_spp": int(np.load(resume_dir / "final.state.npz")["passes"]) if resume_dir else 0})
    mean = true_mean(width, height, s_L)
    sigma = SIGMA[strategy]
    cost = COST[strategy]
    acc_mean = np.zeros_like(mean)
    acc_m2 = np.zeros_like(mean)
    passes = 0
    t = 0.0
    index = 0
    if resume_dir is not None:
        state = np.load(resume_dir / "final.state.npz")
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
        write_snapshot(path, acc_mean, var, render_time_s=t, spp=passes, strategy=strategy, integrator=integrator,
                       seed=seed, config_hash=config_hash, renderer_version=VERSION, rays=2.0 * passes * width * height,
                       extra_channels=region_fractions(width, height) if aov else None)

    while not stop["now"]:
        if spp_target and passes >= spp_target:
            break
        if time_target and t >= time_target - 1e-12:
            break
        rng = np.random.default_rng([seed, STRATEGIES.index(strategy), int(round(s_L * 1e6)), passes])
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
            emit({"event": "snapshot", "index": index, "path": str(path), "time_s": round(t, 6), "spp": passes,
                  "rays": 2 * passes * width * height, "nonfinite": 0})
            if crash:
                print("render: simulated crash in the fake renderer", file=sys.stderr)
                sys.stderr.flush()
                os.kill(os.getpid(), signal.SIGSEGV)
    final = out / "final.exr"
    if resumable:
        tmp = out / ".final.state.tmp.npz"
        np.savez(tmp, mean=acc_mean, m2=acc_m2, passes=passes, time=t, index=index)
        os.replace(tmp, out / "final.state.npz")
    write(final)
    emit({"event": "final", "path": str(final), "time_s": round(t, 6), "spp": passes,
          "rays": 2 * passes * width * height, "nonfinite": 0, "interrupted": stop["now"]})
    return 3 if stop["now"] else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
