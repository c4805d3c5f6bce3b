"""Shared pieces of the benchmark suite: paths, machine description, running
the renderer and the C benchmarks, reading EXR, the relMSE estimator and
writing results/bench/<name>.json.

Timing policy (the machine is shared): every renderer run records its own
render time (time_s of the final JSON line, wall clock) and the CPU time the
process consumed (user + sys, from the rusage of the reaped child). Rates per
CPU second do not depend on how much of the machine other work took;
rates per wall second do. Comparisons are ratios of runs made in the same
round, and medians over rounds.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

BENCH_DIR = Path(__file__).resolve().parent
ROOT = BENCH_DIR.parent.parent
RESULTS = ROOT / "results" / "bench"
TMP = RESULTS / "tmp"
LAMPSHADE = ROOT / "configs" / "scenes" / "lampshade.yaml"
MULTI_LAMP = ROOT / "configs" / "scenes" / "multi_lamp.yaml"
REL_EPSILON = 0.01
# A scalar schedule of 0 is off (renderer/CONTRACT.md); the scenes' own
# `every` is turned off so that only the final image is written.
NO_SNAPSHOTS = ("--set", "render.snapshots.every=0")


def strategies(render: Path) -> tuple[str, ...]:
    """The renderer's strategies, in its order, from `render --describe`
    (the one list of them)."""
    proc = subprocess.run([str(render), "--describe"], capture_output=True, text=True, check=True, timeout=30)
    names: list[str] = json.loads(proc.stdout)["strategies"]
    return tuple(names)


_T0 = time.monotonic()


def log(msg: str) -> None:
    print(f"[bench {time.monotonic() - _T0:6.1f}s] {msg}", file=sys.stderr, flush=True)


def median(xs: list[float]) -> float:
    xs = [x for x in xs if x == x]
    return statistics.median(xs) if xs else float("nan")


def loadavg() -> list[float]:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return []


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def embree_version() -> str:
    """From the Debian package, if there is one (raw_embree.json has the
    version the library itself reports)."""
    if shutil.which("dpkg-query"):
        for pkg in ("libembree3-3", "libembree-dev"):
            r = subprocess.run(["dpkg-query", "-W", "-f=${Version}", pkg], capture_output=True, text=True)
            if r.returncode == 0 and r.stdout.strip():
                return r.stdout.strip()
    return "unknown"


def machine_info() -> dict[str, Any]:
    return {
        "nproc": os.cpu_count(),
        "nproc_affinity": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "cpu_model": cpu_model(),
        "embree_package": embree_version(),
        "kernel": platform.release(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "loadavg_1_5_15": loadavg(),
    }


@dataclass
class Context:
    """What every section needs: the build, the mode and shared metadata."""

    build: Path
    quick: bool
    render: Path
    version: str
    started: str
    machine: dict[str, Any]
    bins: dict[str, Path] = field(default_factory=dict)

    def meta(self) -> dict[str, Any]:
        return {
            "date": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            "suite_started": self.started,
            "quick": self.quick,
            "renderer": str(self.render),
            "renderer_version": self.version,
            "machine": {**self.machine, "loadavg_1_5_15": loadavg()},
        }


def make_context(build: Path, quick: bool) -> Context:
    render = build / "render"
    if not (render.is_file() and os.access(render, os.X_OK)):
        raise SystemExit(f"bench: renderer not found at {render} (build it with make)")
    r = subprocess.run([str(render), "--version"], capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"bench: {render} --version failed: {r.stderr.strip()}")
    version = r.stdout.strip().split()[-1]
    return Context(
        build=build,
        quick=quick,
        render=render,
        version=version,
        started=_dt.datetime.now().astimezone().isoformat(timespec="seconds"),
        machine=machine_info(),
    )


def children_cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


@dataclass
class RenderRun:
    """One renderer process: its JSON lines, render time and CPU time."""

    args: list[str]
    out: Path
    start: dict[str, Any]
    final: dict[str, Any]
    snapshots: list[dict[str, Any]]
    process_wall_s: float
    cpu_s: float

    @property
    def time_s(self) -> float:
        return float(self.final["time_s"])

    @property
    def samples(self) -> float:
        samples: float = float(self.final["spp"]) * self.start["width"] * self.start["height"]
        return samples

    def summary(self) -> dict[str, Any]:
        f = self.final
        return {
            "spp": f["spp"],
            "time_s": f["time_s"],
            "cpu_s": round(self.cpu_s, 4),
            "process_wall_s": round(self.process_wall_s, 4),
            "threads": self.start.get("threads"),
            "rays": f["rays"],
            "samples": self.samples,
            "samples_per_s": self.samples / max(self.time_s, 1e-9),
            "rays_per_s": f["rays"] / max(self.time_s, 1e-9),
            "samples_per_cpu_s": self.samples / max(self.cpu_s, 1e-9),
            "rays_per_cpu_s": f["rays"] / max(self.cpu_s, 1e-9),
            # CPU time of the render threads in passes: no load, BVH build
            # or EXR write in it.
            "render_cpu_s": f.get("render_cpu_s"),
            # The timed snapshots' CPU time (writer and copies) and the wall
            # time the render threads were paused for the copies.
            "snapshot_cpu_s": f.get("snapshot_cpu_s"),
            "snapshot_pause_s": f.get("snapshot_pause_s"),
            "cpu_share": self.cpu_s / max(self.process_wall_s, 1e-9),
            "shadow_rays": f.get("shadow_rays"),
            "shadow_blocked": f.get("shadow_blocked"),
            "light_samples": f.get("light_samples"),
            "light_missed": f.get("light_missed"),
            "nonfinite": f.get("nonfinite"),
            "snapshots": len(self.snapshots),
        }


def differential(a: dict[str, Any], b: dict[str, Any]) -> dict[str, float]:
    """CPU rates of run `a` with the fixed costs (config and scene load, thread
    start, final EXR write) removed, using run `b`: the same configuration
    stopped after one pass. The difference of the two is pure rendering.
    Falls back to a's totals when b rendered as many samples as a."""
    ds, dr, dc = a["samples"] - b["samples"], a["rays"] - b["rays"], a["cpu_s"] - b["cpu_s"]
    if ds <= 0 or dc <= 0:
        return {
            "samples_per_cpu_s": a["samples_per_cpu_s"],
            "rays_per_cpu_s": a["rays_per_cpu_s"],
            "fixed_cpu_s": float("nan"),
            "differential": False,
        }
    per_sample = dc / ds
    return {
        "samples_per_cpu_s": ds / dc,
        "rays_per_cpu_s": dr / dc,
        "fixed_cpu_s": b["cpu_s"] - b["samples"] * per_sample,
        "differential": True,
    }


def run_render(
    ctx: Context, config: Path, out: Path, *args: str, snapshots: bool = False, prefix: tuple[str, ...] = ()
) -> RenderRun:
    """Runs the renderer to completion; raises with its stderr on failure.
    `prefix` runs it under another program (perf record ... --): the CPU
    time is then that program's too, the JSON lines' render_cpu_s not."""
    if out.exists():
        shutil.rmtree(out)
    cmd = [
        *prefix,
        str(ctx.render),
        str(config),
        "--out",
        str(out),
        "--quiet",
        *([] if snapshots else NO_SNAPSHOTS),
        *args,
    ]
    c0, w0 = children_cpu_s(), time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall, cpu = time.monotonic() - w0, children_cpu_s() - c0
    if p.returncode != 0:
        raise RuntimeError(f"render failed ({p.returncode}): {' '.join(cmd)}\n{p.stderr.strip()}")
    events = [json.loads(line) for line in p.stdout.splitlines() if line.strip()]
    start = next(e for e in events if e.get("event") == "start")
    final = next(e for e in events if e.get("event") == "final")
    snaps = [e for e in events if e.get("event") == "snapshot"]
    return RenderRun(cmd, out, start, final, snaps, wall, cpu)


def fresh_dir(path: Path) -> Path:
    """path as an empty folder (what a run before left there removed)."""
    if path.exists():
        shutil.rmtree(path)
    path.mkdir(parents=True)
    return path


def harness_sweep(experiment: Path, results: Path, render: Path, scheduler: str | None = None) -> float:
    """`portal-harness sweep` of an experiment into a results folder, one
    job locally or on the Dask scheduler given: its wall time in seconds."""
    cmd = [sys.executable, "-m", "portal_harness", "sweep", str(experiment), "--results", str(results)]
    cmd += ["--renderer", str(render), "--no-progress"]
    cmd += ["--scheduler", scheduler] if scheduler else ["--jobs", "1"]
    w0 = time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.monotonic() - w0
    if p.returncode != 0:
        raise RuntimeError(f"harness sweep failed ({p.returncode}): {' '.join(cmd)}\n{p.stderr.strip()[-2000:]}")
    return wall


def run_json(cmd: list[str]) -> dict[str, Any]:
    """Runs a C benchmark that prints one JSON object; its stderr passes through."""
    p = subprocess.run(cmd, stdout=subprocess.PIPE, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed with status {p.returncode}")
    result: dict[str, Any] = json.loads(p.stdout)
    return result


# ---- EXR and the error metric -------------------------------------------------


def read_exr(path: Path) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """(rgb, variance, header attributes) as float64 (H, W, 3) arrays, through
    portal_harness.core.exr, the project's one EXR reader (the bench runs in the
    harness venv)."""
    import dataclasses

    from portal_harness.core import exr

    snap = exr.read_snapshot(path)
    return snap.rgb, snap.variance, dataclasses.asdict(snap.header)


def rel_error(x: np.ndarray, x_var: np.ndarray, ref: np.ndarray, ref_var: np.ndarray) -> dict[str, Any]:
    """relMSE of x against an independent reference, with the reference's own
    noise removed:
      rel_mse      = mean over pixels and channels of (x - ref)^2 / (ref^2 + eps)
      ref_noise    = mean of var_ref / (ref^2 + eps)  (var_ref: variance of the
                     reference's mean, from its variance layer)
      rel_mse_est  = rel_mse - ref_noise
    since E[(x - ref)^2] = MSE(x) + Var(ref) for independent renders. Its
    standard error is that of a mean over pixels of the per-pixel difference
    (pixels are independent given the reference). `resolved` is False when
    the estimate is within two standard errors of zero: the reference is then
    too noisy to measure x.

    rel_var is the same quantity from x's own variance layer,
    mean of var_x / (ref^2 + eps): far less noisy, but blind to bias. The
    z-score (rel_mse_est - rel_var) / se flags a bias (or a variance layer
    that misses rare events) when large and positive."""
    d = ref * ref + REL_EPSILON
    per = ((x - ref) ** 2 - ref_var) / d
    raw = float(np.mean((x - ref) ** 2 / d))
    noise = float(np.mean(ref_var / d))
    est = float(np.mean(per))
    pix = per.mean(axis=-1).ravel()
    se = float(pix.std(ddof=1) / np.sqrt(pix.size))
    rel_var = float(np.mean(x_var / d))
    return {
        "rel_mse": raw,
        "ref_noise": noise,
        "rel_mse_est": est,
        "rel_mse_est_se": se,
        "resolved": est > 2 * se,
        "rel_var": rel_var,
        "bias_z": (est - rel_var) / se if se > 0 else float("nan"),
    }


def write_result(ctx: Context, name: str, params: dict[str, Any], results: Any) -> Path:
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / f"{name}.json"
    payload = {"name": name, **ctx.meta(), "params": params, "results": results}
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(payload, indent=1, sort_keys=False) + "\n")
    tmp.replace(path)
    log(f"wrote {path.relative_to(ROOT)}")
    return path


# ---- a large mesh -------------------------------------------------------------


def write_grid_ply(path: Path, n: int) -> tuple[int, int]:
    """A binary little-endian PLY of an n x n grid of quads over [-1, 1]^2,
    each split in two triangles, rippled in y so that it is not planar:
    (n + 1)^2 float vertices, 2 n^2 triangles (n = 708: 1,002,528).
    Returns (vertices, triangles)."""
    x, z = np.meshgrid(np.linspace(-1.0, 1.0, n + 1), np.linspace(-1.0, 1.0, n + 1))
    y = 0.1 * np.sin(6.0 * x) * np.cos(5.0 * z)
    v = np.stack([x, y, z], -1).reshape(-1, 3).astype("<f4")
    i = np.arange(n)[None, :] + (n + 1) * np.arange(n)[:, None]
    a, b, c, d = i, i + 1, i + n + 2, i + n + 1
    tris = np.concatenate([np.stack([a, d, c], -1).reshape(-1, 3), np.stack([a, c, b], -1).reshape(-1, 3)])
    faces = np.zeros(len(tris), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"] = 3
    faces["i"] = tris
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as out:
        out.write(header.encode())
        out.write(v.tobytes())
        out.write(faces.tobytes())
    tmp.replace(path)
    return len(v), len(tris)


def run_measured(cmd: list[str]) -> dict[str, float]:
    """Runs cmd (output discarded); its wall time, CPU time (user + sys) and
    peak resident set size, from the kernel's accounting of that child."""
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.monotonic() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.stderr:
        proc.stderr.close()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed with status {proc.returncode}: {err.strip()}")
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime, "max_rss_mb": usage.ru_maxrss / 1024.0}
