"""Times Mitsuba 3 on one of our scenes, for the `mitsuba` section of
renderer/bench/bench.py. Runs in Mitsuba's own venv (.venv-xcheck, as make
crosscheck does) and prints one JSON object on stdout.

The scene is our renderer's effective config (`render --print-config
SCENE --format yaml`), turned into a Mitsuba scene by the cross-check's own
converter (tools/crosscheck/mitsuba_lampshade.py: build_scene_dict,
mitsuba_integrator), so both renderers see the same geometry, camera, film
and integrator settings:

  direct  Mitsuba's `direct` with one emitter and one BSDF sample, combined
          by the power heuristic: ours is one light sample and one BSDF
          sample with MIS (power), i.e. our `light` strategy.
  path    Mitsuba's `path` with max_depth = ours + 1 (Mitsuba counts the
          camera segment) and our rr_depth: both continue a path with
          probability min(0.95, max throughput) from that depth on.

Each pass is one mi.render(scene, spp, seed) call, evaluated and
synchronised before the clock stops (llvm variants run asynchronously).
The first pass traces the integrator and compiles its kernels with LLVM;
the later ones reuse them: bench.py reports the first pass and the steady
state (the later passes) apart. The kernel cache on disk is DRJIT_CACHE_DIR,
which bench.py points at a fresh folder per call, so every first pass
compiles as a new user's first render does.

With --image OUT.npz the steady passes' images are kept as well: their
mean (`mean`, height x width x RGB, float64), the variance of that mean
estimated from the passes (`var`), and the pass count, for the equal-time
error section (`mitsuba_efficiency`). With --steady-time T the steady
passes go on until they have taken T seconds together (at least
--passes - 1 of them), so that Mitsuba renders for as long as ours does.

usage: mitsuba_time.py CONFIG.yaml --integrator direct|path --spp N --passes K
           [--seed S] [--threads T] [--variant llvm_ad_rgb] [--mesh-dir DIR]
           [--steady-time T] [--image OUT.npz] [--robust]
Exit status: 0 measured, 2 setup error (message on stderr).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools" / "crosscheck"))

import mitsuba_lampshade as xc  # noqa: E402  (the cross-check's scene converter, found through sys.path)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("config", type=Path, help="our effective config (render --print-config --format yaml)")
    p.add_argument("--integrator", choices=("direct", "path"), required=True)
    p.add_argument("--spp", type=int, required=True, help="samples per pixel of each pass")
    p.add_argument("--passes", type=int, required=True, help="passes, the first included (>= 2)")
    p.add_argument("--seed", type=int, default=1, help="pass k renders with seed SEED * 1000 + k")
    p.add_argument("--threads", type=int, default=2, help="Dr.Jit's worker threads")
    p.add_argument("--variant", default="llvm_ad_rgb")
    p.add_argument("--mesh-dir", type=Path, default=None, help="where the converted meshes go (default: a temp dir)")
    p.add_argument("--steady-time", type=float, default=0.0, help="steady passes until they took this long (s)")
    p.add_argument("--image", type=Path, default=None, help="keep the steady passes' mean image and its variance")
    p.add_argument(
        "--robust",
        action="store_true",
        help="Embree's robust mode (embree_use_robust_intersections), the mode our renderer always uses",
    )
    args = p.parse_args(argv)
    if args.spp < 1 or args.passes < 2 or args.threads < 1:
        p.error("--spp and --threads must be >= 1 and --passes >= 2")
    if not args.steady_time >= 0.0 or args.steady_time > 3600.0:
        p.error("--steady-time must be between 0 and 3600 s")
    return args


def kernel_stats(history: list[dict[str, Any]]) -> dict[str, Any]:
    """What Dr.Jit did in one pass (its kernel history): kernels launched,
    how many came from its caches, and the time spent generating IR and in
    LLVM (the compilation a first pass pays)."""
    kernels = [k for k in history if str(k.get("type", "")).endswith("JIT")]
    return {
        "kernels": len(kernels),
        "cache_hits": sum(1 for k in kernels if k.get("cache_hit")),
        "disk_hits": sum(1 for k in kernels if k.get("cache_disk")),
        "codegen_s": sum(float(k.get("codegen_time", 0.0)) for k in kernels) / 1e3,
        "backend_s": sum(float(k.get("backend_time", 0.0)) for k in kernels) / 1e3,
    }


def thread_cpu_ticks() -> dict[str, int]:
    """CPU time (user + system, clock ticks) of each of this process's
    threads, from /proc (empty elsewhere)."""
    ticks: dict[str, int] = {}
    task = Path("/proc/self/task")
    if not task.is_dir():
        return ticks
    for t in os.listdir(task):
        try:
            fields = (task / t / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended meanwhile
            continue
        ticks[t] = int(fields[11]) + int(fields[12])
    return ticks


def busy_threads(before: dict[str, int], after: dict[str, int]) -> int:
    """Threads that did at least a tenth of the work between the two
    readings: how many threads the passes really ran on (Dr.Jit's pool of
    size N is N - 1 workers plus the thread that waits for the kernels)."""
    used = [after[t] - before.get(t, 0) for t in after]
    total = sum(used)
    return sum(1 for u in used if total > 0 and u >= 0.1 * total)


class PassImages:
    """Running sums of the steady passes' images (Welford's update, float64):
    their mean, and the variance of that mean from the spread between
    passes (each pass is an independent estimate with the same spp)."""

    def __init__(self) -> None:
        self.n = 0
        self.mean: Any = None
        self.m2: Any = None

    def add(self, img: Any) -> None:
        import numpy as np

        x = np.asarray(img, dtype=np.float64)
        self.n += 1
        if self.mean is None:
            self.mean, self.m2 = x.copy(), np.zeros_like(x)
            return
        d = x - self.mean
        self.mean += d / self.n
        self.m2 += d * (x - self.mean)

    def var_of_mean(self) -> Any:
        if self.n < 2:
            raise ValueError("the variance of the mean needs two passes or more")
        return self.m2 / (self.n - 1) / self.n

    def save(self, path: Path) -> None:
        import numpy as np

        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez(tmp, mean=self.mean, var=self.var_of_mean(), passes=self.n)
        tmp.replace(path)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    # The JSON result owns stdout: whatever Mitsuba or Dr.Jit print goes to stderr.
    result_fd = os.dup(1)
    os.dup2(2, 1)
    try:
        import drjit as dr
        import mitsuba as mi
        import yaml
    except ImportError as e:
        print(f"mitsuba_time: {e} (run it with .venv-xcheck/bin/python; make bench installs it)", file=sys.stderr)
        return 2
    try:
        mi.set_variant(args.variant)
    except Exception as e:  # drjit raises plain exceptions when LLVM cannot be loaded
        print(
            f"mitsuba_time: variant {args.variant} unavailable: {e} (DRJIT_LIBLLVM_PATH="
            f"{os.environ.get('DRJIT_LIBLLVM_PATH', 'unset')}; Debian 12: apt-get install libllvm19)",
            file=sys.stderr,
        )
        return 2
    mi.set_log_level(mi.LogLevel.Warn)
    dr.set_thread_count(args.threads)
    dr.set_flag(dr.JitFlag.KernelHistory, True)

    cfg = yaml.safe_load(args.config.read_text())
    render = cfg["render"]
    integ = xc.mitsuba_integrator(
        argparse.Namespace(
            integrator=args.integrator, max_depth=int(render["max_depth"]), rr_depth=int(render["rr_depth"])
        )
    )
    mesh_dir = args.mesh_dir or Path(os.environ.get("TMPDIR", "/tmp")) / f"mitsuba_time_{os.getpid()}"
    try:
        scene_dict = xc.build_scene_dict(cfg, integ, mesh_dir, args.spp, xc.recentre_offset(cfg))
    except xc.SetupError as e:
        print(f"mitsuba_time: {args.config}: {e}", file=sys.stderr)
        return 2
    if args.robust:
        # Mitsuba builds its Embree scene without RTC_SCENE_FLAG_ROBUST
        # unless asked; ours always sets it (watertight seams).
        scene_dict["embree_use_robust_intersections"] = True
    t0 = time.perf_counter()
    scene = mi.load_dict(scene_dict)
    load_s = time.perf_counter() - t0
    w, h = (int(x) for x in scene.sensors()[0].film().size())

    passes = []
    ticks: dict[str, int] = {}
    images = PassImages() if args.image else None
    steady_wall = 0.0
    k = 0
    while k < args.passes or steady_wall < args.steady_time:
        if k >= 1000:
            print("mitsuba_time: more than 1000 passes (seeds would repeat); raise --spp", file=sys.stderr)
            return 2
        if k == 1:
            ticks = thread_cpu_ticks()
        dr.kernel_history_clear()
        c0, t0 = time.process_time(), time.perf_counter()
        img = mi.render(scene, seed=args.seed * 1000 + k, spp=args.spp)
        dr.eval(img)
        dr.sync_thread()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        # Read one value back so that a lazily skipped render cannot pass unnoticed.
        mean = float(dr.mean(img).array[0])
        passes.append(
            {"spp": args.spp, "wall_s": wall, "cpu_s": cpu, "mean": mean, **kernel_stats(dr.kernel_history())}
        )
        if k > 0:
            steady_wall += wall
            if images is not None:
                # Outside the clock: the copy to numpy is not rendering.
                images.add(img.numpy())
        k += 1
    if args.image is not None and images is not None:
        images.save(args.image)
    # Threads that ran the steady passes (None without /proc).
    busy = busy_threads(ticks, thread_cpu_ticks()) if ticks else None
    out = {
        "mitsuba": mi.__version__,
        "drjit": dr.__version__,
        "variant": mi.variant(),
        "threads": dr.thread_count(),
        # The process's threads after the passes, and those that did at
        # least a tenth of the steady passes' work: what says Mitsuba ran
        # on the threads it was given.
        "os_threads": len(os.listdir("/proc/self/task")) if Path("/proc/self/task").is_dir() else None,
        "busy_threads": busy,
        "libllvm": os.environ.get("DRJIT_LIBLLVM_PATH"),
        "drjit_cache_dir": os.environ.get("DRJIT_CACHE_DIR"),
        "integrator": integ,
        "robust": args.robust,
        "width": w,
        "height": h,
        "load_s": load_s,
        "passes": passes,
    }
    with os.fdopen(result_fd, "w") as f:
        f.write(json.dumps(out) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
