"""The benchmark suite behind `make bench` (run through renderer/bench/run.sh).

One function per section; each writes results/bench/<name>.json, and
summary.py turns them into results/bench/summary.md. Sections:

  raw_embree      raw Embree limit on the lampshade (C, raw_embree.c):
                  single rays, streams and packets of 4, 8 and 16
  micro           classification / projection / strategy cost per call vs a
                  shadow ray (C, micro.c)
  throughput      renderer rays/s and samples/s per strategy and integrator,
                  ratio to the raw limit; strategy cost relative to `light`;
                  wasted shadow rays
  threads         1 vs 2 render threads
  snapshots       snapshots every 0.25 s vs none
  scene_scaling   N = 1, 10, 100, 1000 lampshades (gen_lamps.py)
  harness         MSE / relMSE of a snapshot vs a reference, EXR read included
  efficiency      the lampshade ratio sweep at equal time vs a long reference
  portal_weights  area / distance / irradiance on multi_lamp.yaml
  mesh_load       load time and peak memory of a 1M-triangle binary PLY
                  (render --print-config; config_load, stitching and scene
                  build apart, C, mesh_load.c)
  portal_finder   `portals: auto` on a 100k-triangle shade: scene build
                  with auto less without (mesh_load.c)
  mesh_lights     light vs antishadow_exact per sample on the Little Lamp
                  (a 400-triangle bulb behind two 32-gon portals), and on
                  the lampshade with a 16- and a 1,000-triangle bulb behind
                  its opening: the per-sample cost must not grow with the
                  triangles
  mitsuba         `light` against Mitsuba 3 (llvm_ad_rgb) on the lampshade,
                  and antishadow_exact's cost per sample against `light`'s
  time_split      the same two renderers under perf, one thread: CPU time
                  per sample inside Embree and in the renderer's own code
  mitsuba_efficiency
                  equal-time error of `light` and `antishadow_exact` against
                  Mitsuba 3 (llvm_ad_rgb) on the lampshade: how many times
                  less time each needs for Mitsuba's error

usage: bench.py BUILD_DIR [--quick] [--only SECTION[,SECTION...]]
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import importlib.util
import json
import math
import os
import shutil
import subprocess
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import benchlib as bl
import dask_scaling
import equal_error as ee
import numpy as np
import time_split as ts
from benchlib import LAMPSHADE, MULTI_LAMP, TMP, Context, log, median

SWEEP_S_L = (0.075, 0.15, 0.3, 0.6, 1.2)
S_P = 0.3
SWEEP_STRATEGIES = ("light", "portal", "projection", "antishadow", "antishadow_exact")
WEIGHTS = ("area", "distance", "irradiance")
REF_SEED = 1000003
# Embree 3's packet widths (rtcIntersect4/8/16, rtcOccluded4/8/16).
PACKET_WIDTHS = (4, 8, 16)
# Image rows of the lampshade below the shade (floor, walls, box): everything
# lit except the band (rows ~95-105) where the camera looks up through the
# opening into the shade. Points in there lie on the light's side of the
# portal plane, where the portal strategies give the pair no weight and only
# BSDF sampling reaches the light.
ROOM_ROWS = (108, 256)


def ratio_stats(xs: list[float]) -> dict[str, float]:
    xs = [x for x in xs if x == x and math.isfinite(x)]
    if not xs:
        return {"median": float("nan"), "min": float("nan"), "max": float("nan"), "n": 0}
    return {"median": median(xs), "min": min(xs), "max": max(xs), "n": len(xs)}


# ---- 1. raw Embree limit --------------------------------------------------------


def section_raw_embree(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    params = {
        "config": str(LAMPSHADE.relative_to(bl.ROOT)),
        "seconds_per_cell": 0.1 if q else 0.3,
        "reps": 3 if q else 5,
        "spp": 1 if q else 2,
        "threads": [1, 2],
    }
    raw = bl.run_json(
        [
            str(ctx.bins["raw_embree"]),
            str(LAMPSHADE),
            "--seconds",
            str(params["seconds_per_cell"]),
            "--reps",
            str(params["reps"]),
            "--spp",
            str(params["spp"]),
            "--max-threads",
            "2",
        ]
    )
    table: dict[str, dict[str, float]] = {}
    for c in raw["cells"]:
        row = table.setdefault(f"{c['kind']}/{c['api']}", {})
        t = c["threads"]
        row[f"per_thread_rays_per_s_{t}t"] = c["median_rays_per_s_per_thread"]
        row[f"rays_per_cpu_s_{t}t"] = c["median_rays_per_cpu_s"]
    nr = raw.get("mix_embree_1t_without_robust_flag")
    if nr:
        table["mix/embree_without_robust_flag"] = {
            "rays_per_cpu_s_1t": nr["median_rays_per_cpu_s"],
            "per_thread_rays_per_s_1t": nr["median_rays_per_s"],
        }
    # The best API per kind: "% of raw" must be against the fastest way to
    # trace the same rays, single, stream or packet.
    best_api: dict[str, str] = {}
    for kind in ("camera", "bounce", "shadow", "mix"):
        apis = {a: table[f"{kind}/{a}"] for a in ("embree", "stream", *(f"packet{w}" for w in PACKET_WIDTHS))}
        best_api[kind] = max(apis, key=lambda a: apis[a]["rays_per_cpu_s_1t"])
        table[f"{kind}/best"] = dict(apis[best_api[kind]])
    ctx.machine["embree_version"] = raw["embree_version"]
    native = {f"ray{w}": raw.get(f"native_ray{w}") for w in PACKET_WIDTHS}
    bl.write_result(
        ctx, "raw_embree", params, {"table": table, "best_api": best_api, "native_packets": native, "raw": raw}
    )
    return table


def raw_limit_now(ctx: Context) -> dict[str, float]:
    """Rays per CPU second of one thread for the renderer's ray mix (lampshade),
    measured now, for a ratio taken right next to the renders it is compared
    with (the machine's speed drifts by tens of percent within seconds to
    minutes). 'packet' is the fastest packet width (4, 8, 16); 'best' the
    fastest of single rays, streams and packets."""
    raw = bl.run_json(
        [
            str(ctx.bins["raw_embree"]),
            str(LAMPSHADE),
            "--seconds",
            "0.15",
            "--reps",
            "1",
            "--spp",
            "1",
            "--max-threads",
            "1",
            "--mix-only",
        ]
    )
    cells = {c["api"]: c["median_rays_per_cpu_s"] for c in raw["cells"] if c["kind"] == "mix" and c["threads"] == 1}
    packet = max(cells.get(f"packet{w}", 0.0) for w in PACKET_WIDTHS)
    return {
        "single": cells["embree"],
        "stream": cells["stream"],
        "packet": packet,
        "best": max(cells["embree"], cells["stream"], packet),
    }


# ---- 10. micro-benchmark --------------------------------------------------------


def section_micro(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    params = {
        "config": str(LAMPSHADE.relative_to(bl.ROOT)),
        "reps": 3 if q else 7,
        "min_ms": 5 if q else 20,
        "floor": [-3, 3],
    }
    raw = bl.run_json(
        [str(ctx.bins["micro"]), str(LAMPSHADE), "--reps", str(params["reps"]), "--min-ms", str(params["min_ms"])]
    )
    table = {}
    for set_name, s in raw["sets"].items():
        shadow = s["cells"]["shadow_ray"]["median_ns"]
        table[set_name] = {
            name: {"ns": c["median_ns"], "per_shadow_ray": c["median_ns"] / shadow} for name, c in s["cells"].items()
        }
    bl.write_result(ctx, "micro", params, {"table": table, "raw": raw})
    return table


# ---- 2, 5, 9. renderer throughput -------------------------------------------------


def wasted(run: dict[str, Any]) -> dict[str, float]:
    sr, sb = run["shadow_rays"] or 0, run["shadow_blocked"] or 0
    ls, lm = run["light_samples"] or 0, run["light_missed"] or 0
    denom = sr + lm
    return {
        "wasted_fraction": (sb + lm) / denom if denom else float("nan"),
        "blocked_fraction": sb / denom if denom else float("nan"),
        "missed_fraction": lm / denom if denom else float("nan"),
        "shadow_rays": sr,
        "shadow_blocked": sb,
        "light_samples": ls,
        "light_missed": lm,
    }


def final_field(run: dict[str, Any], key: str) -> float:
    """A timing the renderer reports in its final JSON line (render_cpu_s,
    snapshot_cpu_s, snapshot_pause_s); a clear error for a build too old
    to report it."""
    if run.get(key) is None:
        raise RuntimeError(f"the renderer's final JSON line has no {key} (a build older than this bench)")
    return float(run[key])


def render_rates(run: dict[str, Any]) -> dict[str, float]:
    """Samples and rays per CPU second of the render threads (the renderer's
    render_cpu_s): pure rendering, without the process's load, BVH build and
    EXR write (whose CPU time varied by 0.01-0.07 s between identical runs,
    as much as a fifth of a short render)."""
    cpu = max(final_field(run, "render_cpu_s"), 1e-9)
    return {"samples_per_cpu_s": run["samples"] / cpu, "rays_per_cpu_s": run["rays"] / cpu}


def section_throughput(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    spp = {"direct": 4 if q else 16, "path": 2 if q else 8}
    reps = 1 if q else 7
    # One render thread: the raw limit is one thread's, and two threads on
    # this machine's two vCPUs slow each other (raw Embree by 3-36% per
    # thread over runs, the renderer by 4-8%); section 3 measures the scaling.
    params = {
        "config": str(LAMPSHADE.relative_to(bl.ROOT)),
        "spp": spp,
        "reps": reps,
        "threads": 1,
        "order": "round-robin over (integrator, strategy) per round; seed = round",
        "raw_limit": "raw_embree --mix-only measured before and after each (integrator, strategy) "
        "render; a run's ratio uses the mean of the two; 'best' is the fastest of single rays, streams "
        "and packets of 4, 8, 16",
        "best_of": "the fastest run's rate / the largest raw limit measured next to the key's runs",
        "cpu_rates": "per CPU second of the render threads in passes (render_cpu_s in the renderer's final JSON line)",
    }
    out = TMP / "runs" / "throughput"
    bl.run_render(ctx, LAMPSHADE, out / "warmup", "--spp", "1", "--threads", "1")
    runs: dict[str, list[dict[str, Any]]] = {}
    # The raw limit next to each render: the mean of the measurements just
    # before and just after it, per key and round.
    limits: dict[str, list[dict[str, float]]] = {}
    # Every raw measurement next to a key's renders (before and after each).
    adjacent: dict[str, list[dict[str, float]]] = {}
    for r in range(reps):
        log(f"throughput: round {r + 1}/{reps}")
        before = raw_limit_now(ctx)
        for integ in ("direct", "path"):
            for s in bl.strategies(ctx.render):
                common = ["--threads", "1", "--strategy", s, "--integrator", integ, "--seed", str(r + 1)]
                a = bl.run_render(ctx, LAMPSHADE, out / f"{integ}_{s}", "--spp", str(spp[integ]), *common).summary()
                after = raw_limit_now(ctx)
                limits.setdefault(f"{integ}/{s}", []).append(
                    {k: 0.5 * (before[k] + after[k]) for k in ("single", "stream", "packet", "best")}
                )
                adjacent.setdefault(f"{integ}/{s}", []).extend([before, after])
                before = after
                runs.setdefault(f"{integ}/{s}", []).append({**a, "render": render_rates(a)})
    table = {}
    for key, rs in runs.items():
        integ, s = key.split("/")
        row: dict[str, Any] = {k: median([x[k] for x in rs]) for k in ("samples_per_s", "rays_per_s", "cpu_share")}
        row.update({k: median([x["render"][k] for x in rs]) for k in ("samples_per_cpu_s", "rays_per_cpu_s")})
        row["rays_per_sample"] = median([x["rays"] / x["samples"] for x in rs])
        # Against the raw limit next to each run: the best Embree API, and
        # single rays (rtcIntersect1/rtcOccluded1) alone.
        row["raw_fraction_cpu_runs"] = [
            x["render"]["rays_per_cpu_s"] / lim["best"] for x, lim in zip(rs, limits[key], strict=True)
        ]
        row["raw_fraction_cpu"] = median(row["raw_fraction_cpu_runs"])
        row["raw_fraction_cpu_single"] = median(
            [x["render"]["rays_per_cpu_s"] / lim["single"] for x, lim in zip(rs, limits[key], strict=True)]
        )
        row["raw_limit_best"] = median([lim["best"] for lim in limits[key]])
        # Best of the rounds: interference from other work only ever slows a
        # run, so the fastest render against the fastest raw limit next to
        # the key's renders is the closest to the undisturbed ratio.
        row["rays_per_cpu_s_best_of"] = max(x["render"]["rays_per_cpu_s"] for x in rs)
        row["raw_limit_best_of"] = max(lim["best"] for lim in adjacent[key])
        row["raw_fraction_cpu_best_of"] = row["rays_per_cpu_s_best_of"] / row["raw_limit_best_of"]
        # Strategy cost: time per sample relative to `light`, same integrator, same round.
        light = runs[f"{integ}/light"]
        row["cost_vs_light_cpu"] = ratio_stats(
            [
                lt["render"]["samples_per_cpu_s"] / x["render"]["samples_per_cpu_s"]
                for x, lt in zip(rs, light, strict=True)
            ]
        )
        row["cost_vs_light_wall"] = ratio_stats(
            [(x["time_s"] / x["samples"]) / (lt["time_s"] / lt["samples"]) for x, lt in zip(rs, light, strict=True)]
        )
        row.update({k: v for k, v in wasted(rs[0]).items() if k.endswith("fraction")})
        table[key] = row
    bl.write_result(ctx, "throughput", {**params, "raw_limit_per_run": limits}, {"table": table, "runs": runs})
    # The wasted-ray table of section 9 at the default scene (s_L = 0.6); the
    # sweep's rows, which section_efficiency adds, stay when it is not rerun.
    wasted_rows = {key: wasted(rs[0]) for key, rs in runs.items() if key.startswith("direct/")}
    prev_path = bl.RESULTS / "wasted_rays.json"
    kept = json.loads(prev_path.read_text())["results"] if prev_path.exists() else {}
    bl.write_result(
        ctx,
        "wasted_rays",
        {
            "config": params["config"],
            "s_L": 0.6,
            "integrator": "direct",
            "definition": "(shadow_blocked + light_missed) / (shadow_rays + light_missed)",
        },
        {
            "lampshade_default": wasted_rows,
            **{k: v for k, v in kept.items() if k in ("sweep", "sweep_note")},
        },
    )
    return table


# ---- 3. thread scaling ------------------------------------------------------------


def section_threads(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    # Renders of ~1-2 s: the first ~0.1 s of a render runs at about half
    # speed on this machine whatever the renderer does (section 14's
    # steady state), which at 32 spp (0.15 s on 2 threads since 0.8.0's
    # successors) made the two-thread runs look 10% slower per CPU second.
    spp, reps = (4 if q else 256), (1 if q else 5)
    params = {
        "config": str(LAMPSHADE.relative_to(bl.ROOT)),
        "integrator": "direct",
        "spp": spp,
        "reps": reps,
        "clocks": "render time (time_s: passes only) and the render threads' CPU time (render_cpu_s)",
        "best_of": "least render time at 1 thread / least at 2 threads over the rounds",
    }
    out = TMP / "runs" / "threads"
    table, runs = {}, {}
    for s in ("light", "antishadow_exact"):
        pairs = []
        for r in range(reps):
            log(f"threads: {s} round {r + 1}/{reps}")
            common = ["--strategy", s, "--seed", str(r + 1)]
            one = bl.run_render(ctx, LAMPSHADE, out / f"{s}_1", "--spp", str(spp), "--threads", "1", *common).summary()
            two = bl.run_render(ctx, LAMPSHADE, out / f"{s}_2", "--spp", str(spp), "--threads", "2", *common).summary()
            one["render"], two["render"] = render_rates(one), render_rates(two)
            pairs.append((one, two))
        runs[s] = pairs
        table[s] = {
            "speedup_wall": ratio_stats([a["time_s"] / b["time_s"] for a, b in pairs]),
            # The fastest runs of each: interference only slows a run.
            "speedup_wall_best_of": min(a["time_s"] for a, _ in pairs) / min(b["time_s"] for _, b in pairs),
            # Samples per render-thread CPU second at 2 threads over 1: 1.0
            # means no per-thread slow-down (locks, memory, the other thread).
            "cpu_efficiency_2t_vs_1t": ratio_stats(
                [b["render"]["samples_per_cpu_s"] / a["render"]["samples_per_cpu_s"] for a, b in pairs]
            ),
            # Render-thread CPU time / render time: 2.0 at two threads when
            # both run all the time; less is idle time at the per-pass
            # barrier or time the machine gave to something else.
            "cores_1t": median([a["render_cpu_s"] / a["time_s"] for a, _ in pairs]),
            "cores_2t": median([b["render_cpu_s"] / b["time_s"] for _, b in pairs]),
            "samples_per_s_1t": median([a["samples_per_s"] for a, _ in pairs]),
            "samples_per_s_2t": median([b["samples_per_s"] for _, b in pairs]),
        }
    bl.write_result(ctx, "threads", params, {"table": table, "runs": runs})
    return table


# ---- 4. snapshot overhead -----------------------------------------------------------


def section_snapshots(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    secs, reps, every = (1.5 if q else 2.0), (1 if q else 5), 0.25
    threads = 2
    params = {
        "config": str(LAMPSHADE.relative_to(bl.ROOT)),
        "strategy": "light",
        "integrator": "direct",
        "time_s": secs,
        "reps": reps,
        "every_s": every,
        "threads": threads,
        "measured": "snapshot_cpu_s (writer thread + the main thread's copies) and snapshot_pause_s (render "
        "threads paused for the copies) from the renderer's final JSON line, per run",
    }
    out = TMP / "runs" / "snapshots"
    rounds = []
    for r in range(reps):
        log(f"snapshots: round {r + 1}/{reps}")
        common = ["--threads", str(threads), "--seed", str(r + 1), "--time", str(secs), "--spp", "0"]
        none = bl.run_render(ctx, LAMPSHADE, out / "none", *common).summary()
        snap = bl.run_render(
            ctx, LAMPSHADE, out / "every", *common, "--set", f"render.snapshots.every={every}", snapshots=True
        ).summary()
        snap_cpu, pause = final_field(snap, "snapshot_cpu_s"), final_field(snap, "snapshot_pause_s")
        render_cpu = final_field(snap, "render_cpu_s")
        n = max(snap["snapshots"], 1)
        rounds.append(
            {
                "none": none,
                "every": snap,
                # The snapshots' CPU time over the render threads' in the same run.
                "overhead_cpu": snap_cpu / render_cpu,
                # On an idle machine: the pauses stop the render, the writer's
                # CPU comes out of the render threads' cores (an upper bound: the
                # copies' CPU is counted in both terms).
                "overhead_idle_estimate": (pause + snap_cpu / threads) / snap["time_s"],
                # Cross-check from two runs seconds apart: samples per CPU second
                # (render threads + snapshots) with snapshots vs without.
                "overhead_cpu_paired": 1
                - (snap["samples"] / (render_cpu + snap_cpu)) / render_rates(none)["samples_per_cpu_s"],
                "overhead_wall_paired": 1 - snap["samples_per_s"] / none["samples_per_s"],
                "cpu_per_snapshot_s": snap_cpu / n,
                "pause_per_snapshot_s": pause / n,
            }
        )
    table = {
        "overhead_cpu": ratio_stats([x["overhead_cpu"] for x in rounds]),
        "overhead_idle_machine_estimate": median([x["overhead_idle_estimate"] for x in rounds]),
        "overhead_cpu_paired": ratio_stats([x["overhead_cpu_paired"] for x in rounds]),
        "overhead_wall_paired": ratio_stats([x["overhead_wall_paired"] for x in rounds]),
        "cpu_per_snapshot_ms": 1e3 * median([x["cpu_per_snapshot_s"] for x in rounds]),
        "pause_per_snapshot_ms": 1e3 * median([x["pause_per_snapshot_s"] for x in rounds]),
        "snapshots_written": median([x["every"]["snapshots"] for x in rounds]),
        "cpu_share_none": median([x["none"]["cpu_share"] for x in rounds]),
    }
    bl.write_result(ctx, "snapshots", params, {"table": table, "runs": rounds})
    return table


# ---- 6. scaling with the number of lamps ----------------------------------------------


def section_scene_scaling(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    ns, secs, reps, size = (1, 10, 100, 1000), (0.5 if q else 2.0), (1 if q else 2), 128
    params = {
        "generator": "renderer/bench/gen_lamps.py",
        "n_lamps": list(ns),
        "time_s": secs,
        "reps": reps,
        "film": size,
        "threads": 2,
        "integrator": "direct",
    }
    scenes = {}
    for n in ns:
        path = TMP / "scenes" / f"lamps_{n}.yaml"
        subprocess.run(
            [sys.executable, str(bl.BENCH_DIR / "gen_lamps.py"), str(n), str(path), "--size", str(size)], check=True
        )
        scenes[n] = path
    out = TMP / "runs" / "scaling"
    runs: dict[str, list[dict[str, Any]]] = {}
    for r in range(reps):
        for n in ns:
            for s in ("light", "antishadow_exact"):
                log(f"scene_scaling: round {r + 1}/{reps} N={n} {s}")
                common = ["--threads", "2", "--strategy", s, "--seed", str(r + 1)]
                a = bl.run_render(
                    ctx, scenes[n], out / f"{n}_{s}", "--time", str(secs), "--spp", "0", *common
                ).summary()
                b = bl.run_render(ctx, scenes[n], out / f"{n}_{s}_1", "--spp", "1", *common).summary()
                runs.setdefault(f"{n}/{s}", []).append({**a, "diff": bl.differential(a, b)})
    table: dict[str, Any] = {}
    for s in ("light", "antishadow_exact"):
        rows = {}
        for n in ns:
            rs = runs[f"{n}/{s}"]
            rows[str(n)] = {
                "samples_per_s": median([x["samples_per_s"] for x in rs]),
                "samples_per_cpu_s": median([x["diff"]["samples_per_cpu_s"] for x in rs]),
                "cpu_ns_per_sample": median([1e9 / x["diff"]["samples_per_cpu_s"] for x in rs]),
                "fixed_cpu_s": median([x["diff"]["fixed_cpu_s"] for x in rs]),
                "load_and_write_s": median([x["process_wall_s"] - x["time_s"] for x in rs]),
                **{k: v for k, v in wasted(rs[0]).items() if k.endswith("fraction")},
            }
        base = rows[str(ns[0])]["cpu_ns_per_sample"]
        for n in ns:
            rows[str(n)]["cost_vs_n1"] = rows[str(n)]["cpu_ns_per_sample"] / base
        # Least-squares fit cost = a + b N (CPU ns per sample).
        x = np.array(ns, dtype=float)
        y = np.array([rows[str(n)]["cpu_ns_per_sample"] for n in ns])
        b, a = np.polyfit(x, y, 1)
        # Marginal cost per added lamp between the two largest N: the
        # asymptotic slope, free of the near-lamp costs that saturate early.
        marginal = (y[-1] - y[-2]) / (x[-1] - x[-2])
        table[s] = {
            "by_n": rows,
            "fit_ns_per_sample": {"a": float(a), "b_per_lamp": float(b)},
            "marginal_ns_per_lamp": float(marginal),
        }
    bl.write_result(ctx, "scene_scaling", params, {"table": table, "runs": runs})
    return table


# ---- 7. harness overhead ---------------------------------------------------------------


def section_harness(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    reps = 3 if q else 7
    params = {
        "what": "read snapshot + reference EXR (openexr bindings), MSE and relMSE (+ reference noise)",
        "reps": reps,
        "sizes": [256, 1024],
    }
    out = TMP / "runs" / "harness"
    table = {}
    try:
        # The harness's own code path, if installed.
        from portal_harness.core import exr as hexr
        from portal_harness.core import metrics as hmet

        have_harness = True
    except ImportError:
        have_harness = False
    for size in (256, 1024):
        paths = []
        for seed in (1, 2):
            run = bl.run_render(
                ctx,
                LAMPSHADE,
                out / f"{size}_{seed}",
                "--spp",
                "2",
                "--threads",
                "2",
                "--seed",
                str(seed),
                "--set",
                f"film.width={size}",
                "--set",
                f"film.height={size}",
            )
            paths.append(Path(run.final["path"]))
        times_read, times_metric, times_harness = [], [], []
        for _ in range(reps):
            t0 = time.perf_counter()
            x, x_var, _ = bl.read_exr(paths[0])
            ref, ref_var, _ = bl.read_exr(paths[1])
            t1 = time.perf_counter()
            mse = float(np.mean((x - ref) ** 2))
            rel = bl.rel_error(x, x_var, ref, ref_var)
            t2 = time.perf_counter()
            times_read.append(t1 - t0)
            times_metric.append(t2 - t1)
            if have_harness:
                t3 = time.perf_counter()
                a, b = hexr.read_snapshot(paths[0]), hexr.read_snapshot(paths[1])
                hmet.mse(a.rgb, b.rgb)
                hmet.rel_mse(a.rgb, b.rgb)
                hmet.rel_variance_floor(b.rgb, b.variance)
                times_harness.append(time.perf_counter() - t3)
        table[str(size)] = {
            "read_two_exr_ms": 1e3 * median(times_read),
            "metrics_ms": 1e3 * median(times_metric),
            "total_ms": 1e3 * median([a + b for a, b in zip(times_read, times_metric, strict=True)]),
            "portal_harness_total_ms": 1e3 * median(times_harness) if times_harness else None,
            "exr_bytes": paths[0].stat().st_size,
            "check_mse": mse,
            "check_rel_mse": rel["rel_mse"],
        }
    table["sweep"] = sweep_overhead(ctx)
    bl.write_result(ctx, "harness", params, table)
    return table


SWEEP_EXPERIMENT = """\
# A small sweep for the bench (section 7): what share of its wall time is
# not spent rendering. Written by renderer/bench/bench.py.
name: bench_sweep
scene: {scene}
integrator: direct
strategies: [light, antishadow_exact]
sweep:
  params.s_L: [0.3, 0.6]
fixed:
  film.width: 256
  film.height: 256
budget:
  time_s: {time_s}
  spp: 0
  threads: 2
  snapshots: {{every: 0.25}}
reference:
  strategy: light
  time_s: {ref_s}
  threads: 2
"""


def sweep_overhead(ctx: Context) -> dict[str, Any]:
    """A small experiment run through the harness's `sweep` command into a
    fresh results folder: its wall time against the render time of its runs
    and references (their manifests). The rest is the renderer processes'
    own overhead (start, load, BVH build, snapshot pauses, final EXR write)
    and the harness's (Python start, EXR reading, metrics, index, summary)."""
    q = ctx.quick
    time_s, ref_s = (0.5, 1.0) if q else (2.0, 4.0)
    folder = bl.fresh_dir(TMP / "runs" / "harness_sweep")
    exp = folder / "bench_sweep.yaml"
    exp.write_text(SWEEP_EXPERIMENT.format(scene=LAMPSHADE, time_s=time_s, ref_s=ref_s))
    results = folder / "results"
    wall = bl.harness_sweep(exp, results, ctx.render)
    # The runs' and references' manifests (not the experiment's own, results/experiments/NAME/).
    found = [*results.glob("runs/*/manifest.json"), *results.glob("references/*/manifest.json")]
    manifests = [json.loads(m.read_text()) for m in found]
    if not manifests:
        raise RuntimeError(f"harness sweep left no manifests under {results}")
    render = sum(m["timings"]["render_time_s"] for m in manifests)
    process = sum(m["timings"]["wall_s"] for m in manifests)
    return {
        "renders": len(manifests),
        "run_time_s": time_s,
        "reference_time_s": ref_s,
        "sweep_wall_s": wall,
        "render_s": render,
        "renderer_process_s": process,
        # Shares of the sweep's wall time.
        "not_rendering_share": 1 - render / wall,
        "renderer_overhead_share": (process - render) / wall,
        "harness_share": (wall - process) / wall,
    }


# ---- 8, 11. efficiency at equal time against a cached reference --------------------------


def file_digest(path: Path) -> str:
    return hashlib.sha1(path.read_bytes()).hexdigest()[:12]


def reference(ctx: Context, config: Path, sets: list[str], secs: float, tag: str) -> tuple[Path, dict[str, Any]]:
    """A long `light` render, cached under results/bench/tmp/refs keyed by the
    scene file, the overrides and the renderer version; reused when it was
    rendered for at least `secs`."""
    key = hashlib.sha1(json.dumps([file_digest(config), sets, ctx.version, "light", REF_SEED]).encode()).hexdigest()[
        :12
    ]
    folder = TMP / "refs" / f"{tag}_v{ctx.version}_{key}"
    meta_path = folder / "meta.json"
    binary = file_digest(ctx.render)
    if meta_path.exists() and os.environ.get("BENCH_FRESH_REFS") != "1":
        meta = json.loads(meta_path.read_text())
        if meta.get("time_target_s", 0) >= secs and (folder / "final.exr").exists():
            log(f"reference {folder.name}: cached ({meta['time_target_s']} s, {meta['spp']} spp)")
            if meta.get("render_binary_sha1") != binary:
                log(
                    f"reference {folder.name}: note: rendered by another build of renderer {ctx.version}; "
                    "if images changed, bump RENDERER_VERSION or set BENCH_FRESH_REFS=1"
                )
            return folder / "final.exr", meta
    log(f"reference {folder.name}: rendering {secs} s")
    args = [a for s in sets for a in ("--set", s)]
    run = bl.run_render(
        ctx,
        config,
        folder,
        "--strategy",
        "light",
        "--time",
        str(secs),
        "--spp",
        "0",
        "--threads",
        "2",
        "--seed",
        str(REF_SEED),
        *args,
    )
    meta = {
        "config": str(config),
        "sets": sets,
        "renderer_version": ctx.version,
        "time_target_s": secs,
        "time_s": run.time_s,
        "cpu_s": run.cpu_s,
        "spp": run.final["spp"],
        "seed": REF_SEED,
        "render_binary_sha1": binary,
    }
    meta_path.write_text(json.dumps(meta, indent=1) + "\n")
    return folder / "final.exr", meta


def add_efficiency(rows: dict[str, Any]) -> None:
    """Efficiency of each row relative to rows['light'], from rel_mse_est (and
    its standard error) or rel_var, with CPU or render time."""
    base = rows["light"]
    for row in rows.values():
        for clock in ("cpu_s", "time_s"):
            suffix = "cpu" if clock == "cpu_s" else "wall"
            e_row = row["rel_mse_est"] * row[clock]
            e_base = base["rel_mse_est"] * base[clock]
            row[f"eff_vs_light_{suffix}"] = e_base / e_row if e_row > 0 else float("inf")
            # Lower bound when the estimate is unresolved: use est + 2 se.
            lo = (row["rel_mse_est"] + 2 * row["rel_mse_est_se"]) * row[clock]
            hi_base = max(base["rel_mse_est"] - 2 * base["rel_mse_est_se"], 0.0) * base[clock]
            row[f"eff_vs_light_{suffix}_low"] = hi_base / lo if lo > 0 else float("nan")
        e_row_var, e_base_var = row["rel_var"] * row["cpu_s"], base["rel_var"] * base["cpu_s"]
        row["eff_vs_light_cpu_var"] = e_base_var / e_row_var if e_row_var > 0 else float("inf")
        # Relative standard error of the ratio, from the two estimates' errors.
        if row["rel_mse_est"] > 0 and base["rel_mse_est"] > 0:
            row["eff_vs_light_rel_se"] = math.hypot(
                row["rel_mse_est_se"] / row["rel_mse_est"], base["rel_mse_est_se"] / base["rel_mse_est"]
            )
        else:
            row["eff_vs_light_rel_se"] = float("nan")


def measure_at_equal_time(
    ctx: Context,
    config: Path,
    sets: list[str],
    variants: dict[str, list[str]],
    secs: float,
    ref_exr: Path,
    out: Path,
    crops: dict[str, tuple[int, int]] | None = None,
) -> dict[str, Any]:
    """Renders each variant for `secs` (2 threads) and measures its error
    against the reference and its efficiency relative to the variant 'light',
    on the whole image and on each crop (name -> rows [r0, r1))."""
    ref, ref_var, _ = bl.read_exr(ref_exr)
    rows: dict[str, Any] = {}
    crop_rows: dict[str, dict[str, Any]] = {c: {} for c in (crops or {})}
    for name, extra in variants.items():
        args = [a for s in sets for a in ("--set", s)]
        run = bl.run_render(
            ctx, config, out / name, "--time", str(secs), "--spp", "0", "--threads", "2", "--seed", "1", *args, *extra
        )
        x, x_var, _ = bl.read_exr(Path(run.final["path"]))
        err = bl.rel_error(x, x_var, ref, ref_var)
        summ = run.summary()
        clocks = {"time_s": run.time_s, "cpu_s": run.cpu_s, "spp": run.final["spp"]}
        rows[name] = {**err, **clocks, **{k: v for k, v in wasted(summ).items()}}
        # Where the whole-image error sits: the share of each crop and of the 10 worst pixels.
        d = ref * ref + bl.REL_EPSILON
        per = (((x - ref) ** 2 - ref_var) / d).mean(axis=-1)
        total = per.sum()
        rows[name]["top10_pixel_share"] = float(np.sort(per.ravel())[-10:].sum() / total) if total > 0 else math.nan
        for c, (r0, r1) in (crops or {}).items():
            rows[name][f"{c}_share"] = float(per[r0:r1].sum() / total) if total > 0 else math.nan
            crop_rows[c][name] = {**bl.rel_error(x[r0:r1], x_var[r0:r1], ref[r0:r1], ref_var[r0:r1]), **clocks}
    add_efficiency(rows)
    for crop in crop_rows.values():
        add_efficiency(crop)
    if crops:
        rows["_crops"] = {c: {"rows": list(crops[c]), "strategies": crop_rows[c]} for c in crops}
    return rows


def section_efficiency(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    secs, ref_secs = (1.0 if q else 4.0), (6.0 if q else 60.0)
    params = {
        "config": str(LAMPSHADE.relative_to(bl.ROOT)),
        "s_L": list(SWEEP_S_L),
        "s_P": S_P,
        "strategies": list(SWEEP_STRATEGIES),
        "integrator": "direct",
        "time_s": secs,
        "threads": 2,
        "reference": {"strategy": "light", "time_s_min": ref_secs, "seed": REF_SEED},
        "rel_mse": "mean over pixels and channels of (x - ref)^2 / (ref^2 + 0.01)",
        "rel_mse_est": "rel_mse - mean(var_ref / (ref^2 + 0.01))",
        "crops": {
            "room": {
                "rows": list(ROOM_ROWS),
                "what": "rows below the lampshade (floor, walls, box): "
                "excludes the band where the camera sees into the shade through its opening",
            }
        },
        "efficiency": "1 / (rel_mse_est * cpu_s); eff_vs_light_wall uses render time_s instead; "
        "eff_vs_light_cpu_var uses rel_var (the render's own variance layer) instead of "
        "rel_mse_est",
    }
    table = {}
    for s_l in SWEEP_S_L:
        sets = [f"params.s_L={s_l}", f"params.s_P={S_P}"]
        ref_exr, meta = reference(ctx, LAMPSHADE, sets, ref_secs, f"lampshade_sL{s_l}")
        log(f"efficiency: s_L={s_l} (ratio {s_l / S_P:g})")
        rows = measure_at_equal_time(
            ctx,
            LAMPSHADE,
            sets,
            {s: ["--strategy", s] for s in SWEEP_STRATEGIES},
            secs,
            ref_exr,
            TMP / "runs" / "efficiency" / f"sL{s_l}",
            {"room": ROOM_ROWS},
        )
        crops = rows.pop("_crops")
        table[f"{s_l / S_P:g}"] = {"s_L": s_l, "reference": meta, "strategies": rows, "crops": crops}
    bl.write_result(ctx, "efficiency", params, table)
    # Wasted shadow rays per ratio (section 9) from the same runs.
    path = bl.RESULTS / "wasted_rays.json"
    if path.exists():
        data = json.loads(path.read_text())
        data["results"]["sweep"] = {
            ratio: {
                s: {
                    k: v
                    for k, v in row.items()
                    if k
                    in (
                        "wasted_fraction",
                        "blocked_fraction",
                        "missed_fraction",
                        "shadow_rays",
                        "shadow_blocked",
                        "light_samples",
                        "light_missed",
                    )
                }
                for s, row in t["strategies"].items()
            }
            for ratio, t in table.items()
        }
        data["results"]["sweep_note"] = "equal-time runs of efficiency.json (4 s full, 1 s quick)"
        path.write_text(json.dumps(data, indent=1) + "\n")
    return table


def section_portal_weights(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    secs, ref_secs = (1.0 if q else 4.0), (6.0 if q else 60.0)
    params = {
        "config": str(MULTI_LAMP.relative_to(bl.ROOT)),
        "strategy": "antishadow_exact",
        "weights": list(WEIGHTS),
        "integrator": "direct",
        "time_s": secs,
        "threads": 2,
        "reference": {"strategy": "light", "time_s_min": ref_secs, "seed": REF_SEED},
        "efficiency": "relative to `light` at equal time; see efficiency.json for the definitions",
    }
    ref_exr, meta = reference(ctx, MULTI_LAMP, [], ref_secs, "multi_lamp")
    variants = {"light": ["--strategy", "light"]}
    for w in WEIGHTS:
        variants[f"antishadow_exact/{w}"] = ["--strategy", "antishadow_exact", "--set", f"render.portal_weight={w}"]
    log("portal_weights: rendering")
    rows = measure_at_equal_time(ctx, MULTI_LAMP, [], variants, secs, ref_exr, TMP / "runs" / "weights")
    table = {"reference": meta, "variants": rows}
    bl.write_result(ctx, "portal_weights", params, table)
    return table


# ---- 12. loading a large mesh --------------------------------------------------

MESH_GRID_N = 708  # 2 x 708^2 = 1,002,528 triangles


def section_mesh_load(ctx: Context) -> dict[str, Any]:
    """A 1M-triangle binary PLY, generated here (not committed): the wall
    and CPU time and peak RSS of `render --print-config` on a scene holding
    it (load, stitching and scene build: what every render pays before its
    first pass), and the stages apart (mesh_load.c)."""
    rounds = 1 if ctx.quick else 3
    folder = TMP / "mesh_load"
    folder.mkdir(parents=True, exist_ok=True)
    ply = folder / "grid_1m.ply"
    n_vertices, n_triangles = bl.write_grid_ply(ply, MESH_GRID_N)
    scene = folder / "scene.yaml"
    scene.write_text(
        "# renderer/bench/bench.py section_mesh_load: one large mesh under a panel light\n"
        "camera: {position: [0, 3, 3], look_at: [0, 0, 0], up: [0, 1, 0], fov_y: 50}\n"
        "film: {width: 64, height: 64}\n"
        "materials:\n  grey: {type: diffuse, albedo: [0.6, 0.6, 0.6]}\n"
        "shapes:\n  - {name: grid, type: mesh, material: grey, file: grid_1m.ply}\n"
        "lights:\n  - name: panel\n"
        "    vertices: [[-0.5, 2, -0.5], [0.5, 2, -0.5], [0.5, 2, 0.5], [-0.5, 2, 0.5]]\n"
        "    radiance: [4, 4, 4]\n"
        "render: {spp: 1}\n"
    )
    params = {
        "mesh": f"{MESH_GRID_N}x{MESH_GRID_N} grid, binary little-endian PLY, float vertices",
        "vertices": n_vertices,
        "triangles": n_triangles,
        "bytes": ply.stat().st_size,
        "rounds": rounds,
        "target_s": 1.0,
    }
    runs = [bl.run_measured([str(ctx.render), "--print-config", str(scene)]) for _ in range(rounds)]
    print_config = {k: median([r[k] for r in runs]) for k in ("wall_s", "cpu_s", "max_rss_mb")}
    stages = bl.run_json([str(ctx.bins["mesh_load"]), str(scene), "--rounds", str(rounds)])
    results = {"print_config": print_config, "print_config_runs": runs, "stages": stages}
    bl.write_result(ctx, "mesh_load", params, results)
    return results


# ---- 12b. the auto portal finder -------------------------------------------------

FINDER_GRID_N = 92  # cells per shade face side: 6 faces, 2 triangles a cell, less the hole: 98,852 triangles


def write_shade_ply(path: Path, n: int) -> int:
    """A binary PLY of a box shade [-0.5, 0.5]^3, each face an n x n grid of
    cells split in two triangles, the bottom without the cells inside its
    0.4 x 0.4 hole. Returns the triangle count."""
    verts: list[np.ndarray] = []
    tris: list[np.ndarray] = []
    base = 0
    s = np.linspace(-0.5, 0.5, n + 1)
    u, w = np.meshgrid(s, s, indexing="ij")
    for axis in range(3):
        for side in (-0.5, 0.5):
            cols = [u, w]
            cols.insert(axis, np.full_like(u, side))
            v = np.stack(cols, -1).reshape(-1, 3)
            i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
            keep = np.ones((n, n), bool)
            if axis == 1 and side < 0:  # the bottom: the hole
                cu, cw = 0.5 * (s[:-1] + s[1:])[:, None], 0.5 * (s[:-1] + s[1:])[None, :]
                keep = ~((np.abs(cu) < 0.2) & (np.abs(cw) < 0.2))
            i = i[keep]
            a, b, c, d = i, i + n + 1, i + n + 2, i + 1
            tris.append(base + np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)]))
            verts.append(v)
            base += len(v)
    v_all = np.concatenate(verts).astype("<f4")
    t_all = np.concatenate(tris)
    faces = np.zeros(len(t_all), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"] = 3
    faces["i"] = t_all
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(v_all)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(t_all)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as out:
        out.write(header.encode())
        out.write(v_all.tobytes())
        out.write(faces.tobytes())
    return len(t_all)


def section_portal_finder(ctx: Context) -> dict[str, Any]:
    """`portals: auto` on a finely tessellated shade: a box of ~100k
    triangles (one binary PLY, generated here) with a 0.4 x 0.4 hole in its
    bottom, around a 0.2 x 0.2 light, over a floor. The finder's cost is
    scene_create with `portals: auto` less scene_create without (mesh_load.c,
    median of the rounds); the goal (issue 39) is under 1 s."""
    rounds = 1 if ctx.quick else 5
    folder = TMP / "portal_finder"
    folder.mkdir(parents=True, exist_ok=True)
    n_triangles = write_shade_ply(folder / "shade.ply", FINDER_GRID_N)
    head = (
        "# renderer/bench/bench.py section_portal_finder: a 100k-triangle shade around a light\n"
        "camera: {position: [0, 1, 5], look_at: [0, 0, 0], up: [0, 1, 0], fov_y: 50}\n"
        "film: {width: 32, height: 32}\n"
        "materials:\n  grey: {type: diffuse, albedo: [0.6, 0.6, 0.6]}\n"
        "shapes:\n  - {name: shade, type: mesh, material: grey, file: shade.ply}\n"
        "  - {name: floor, type: quad, material: grey,"
        " vertices: [[-10, -2, -10], [-10, -2, 10], [10, -2, 10], [10, -2, -10]]}\n"
        "lights:\n  - name: bulb\n"
        "    vertices: [[-0.1, 0.2, -0.1], [0.1, 0.2, -0.1], [0.1, 0.2, 0.1], [-0.1, 0.2, 0.1]]\n"
        "    radiance: [4, 4, 4]\n    two_sided: true\n"
        "render: {spp: 1}\n"
    )
    (folder / "plain.yaml").write_text(head)
    (folder / "auto.yaml").write_text(head + "portals: auto\n")
    stages = {
        name: bl.run_json([str(ctx.bins["mesh_load"]), str(folder / f"{name}.yaml"), "--rounds", str(rounds)])
        for name in ("plain", "auto")
    }
    out = subprocess.run(
        [str(ctx.render), "--print-config", str(folder / "auto.yaml")], stdout=subprocess.PIPE, text=True, check=True
    ).stdout
    summary = [line[4:] for line in out.splitlines() if line.startswith("#   bulb")]
    finder = {k: stages["auto"]["scene_create"][k] - stages["plain"]["scene_create"][k] for k in ("wall_s", "cpu_s")}
    params = {"triangles": n_triangles, "grid": FINDER_GRID_N, "rounds": rounds, "target_s": 1.0}
    results = {"finder": finder, "stages": stages, "print_config_summary": summary}
    bl.write_result(ctx, "portal_finder", params, results)
    log(f"portal finder: {n_triangles} triangles, {finder['wall_s']:.3f} s wall, {finder['cpu_s']:.3f} s CPU")
    log(f"portal finder found: {summary}")
    return results


# ---- 13. mesh lights ------------------------------------------------------------

LITTLE_LAMP = bl.ROOT / "configs" / "scenes" / "little_lamp.yaml"


def sphere_bulb_scene(folder: Path, segments: int, rings: int) -> Path:
    """The lampshade with a UV-sphere bulb of 2 segments (rings - 1)
    triangles behind its opening, made by the mesh fixtures' own generator."""
    spec = importlib.util.spec_from_file_location(
        "make_fixtures", bl.ROOT / "tests" / "configs" / "meshes" / "make_fixtures.py"
    )
    assert spec is not None and spec.loader is not None
    make_fixtures = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_fixtures)
    folder.mkdir(parents=True, exist_ok=True)
    obj = folder / f"bulb_{segments}x{rings}.obj"
    obj.write_text(make_fixtures.lamp_sphere_obj(segments, rings))
    scene = folder / f"bulb_{segments}x{rings}.yaml"
    scene.write_text(
        f"include: {LAMPSHADE}\n"
        f"lights:\n  - {{name: bulb, mesh: {{file: {obj.name}}}, radiance: [30, 25, 20]}}\n"
        "portals:\n  - {name: opening, light: bulb,\n"
        '     vertices: [["=-h", 2.2, "=-h"], ["=h", 2.2, "=-h"], ["=h", 2.2, "=h"], ["=-h", 2.2, "=h"]]}\n'
    )
    return scene


def section_mesh_lights(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    reps, spp = (1, 2) if q else (5, 8)
    scenes = {
        "little_lamp": LITTLE_LAMP,
        "bulb_16": sphere_bulb_scene(TMP / "mesh_lights", 4, 3),
        "bulb_1000": sphere_bulb_scene(TMP / "mesh_lights", 25, 21),
    }
    params = {
        "scenes": {k: str(v.relative_to(bl.ROOT)) if v.is_relative_to(bl.ROOT) else v.name for k, v in scenes.items()},
        "spp": spp,
        "reps": reps,
        "threads": 1,
        "integrator": "direct",
        "order": "round-robin over (scene, strategy) per round; seed = round",
        "cost": "render CPU ns per camera sample (render_cpu_s / samples), median over rounds",
    }
    out = TMP / "runs" / "mesh_lights"
    runs: dict[str, list[dict[str, Any]]] = {}
    for r in range(reps):
        log(f"mesh_lights: round {r + 1}/{reps}")
        for name, scene in scenes.items():
            for s in ("light", "antishadow_exact"):
                common = ["--threads", "1", "--strategy", s, "--seed", str(r + 1), "--spp", str(spp)]
                a = bl.run_render(ctx, scene, out / f"{name}_{s}", *common).summary()
                runs.setdefault(f"{name}/{s}", []).append({**a, "render": render_rates(a)})
    table: dict[str, Any] = {}
    for key, rs in runs.items():
        name, s = key.split("/")
        light = runs[f"{name}/light"]
        table[key] = {
            "ns_per_sample": median([1e9 / x["render"]["samples_per_cpu_s"] for x in rs]),
            "cost_vs_light_cpu": ratio_stats(
                [
                    lt["render"]["samples_per_cpu_s"] / x["render"]["samples_per_cpu_s"]
                    for x, lt in zip(rs, light, strict=True)
                ]
            ),
            **{k: v for k, v in wasted(rs[0]).items() if k.endswith("fraction")},
        }
    bl.write_result(ctx, "mesh_lights", params, {"table": table, "runs": runs})
    return table


# ---- 14. against Mitsuba 3 ------------------------------------------------------

MITSUBA_VARIANT = "llvm_ad_rgb"
# Dr.Jit's LLVM backend aborts with Debian 12's LLVM 14 and 15 ("Cannot
# select fminimum"); libllvm19 (apt) works (../shared/toolchain.md).
LIBLLVM_CANDIDATES = ("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")
COST_SCENES = {
    "lampshade": LAMPSHADE,
    "multi_lamp": MULTI_LAMP,
    "little_lamp": bl.ROOT / "configs" / "scenes" / "little_lamp.yaml",
}
MITSUBA_TARGET_RATIO = 1.0
COST_TARGET = 1.15


def mitsuba_env() -> tuple[Path, dict[str, str]]:
    """Mitsuba's python (.venv-xcheck, or BENCH_MITSUBA_PYTHON) and the
    environment that gives Dr.Jit a working LLVM (DRJIT_LIBLLVM_PATH, or
    Debian's libllvm19)."""
    python = Path(os.environ.get("BENCH_MITSUBA_PYTHON", str(bl.ROOT / ".venv-xcheck" / "bin" / "python")))
    if not python.exists():
        raise RuntimeError(f"{python} not found: make bench creates .venv-xcheck with Mitsuba (pip install mitsuba)")
    env = dict(os.environ)
    if "DRJIT_LIBLLVM_PATH" not in env:
        found = [c for c in LIBLLVM_CANDIDATES if Path(c).exists()]
        if not found:
            raise RuntimeError(
                f"no LLVM 19 for Dr.Jit ({', '.join(LIBLLVM_CANDIDATES)}): apt-get install libllvm19 "
                "(make bench does), or set DRJIT_LIBLLVM_PATH"
            )
        env["DRJIT_LIBLLVM_PATH"] = found[0]
    return python, env


def mitsuba_time(
    python: Path,
    env: dict[str, str],
    config: Path,
    integrator: str,
    spp: int,
    passes: int,
    seed: int,
    folder: Path,
    threads: int = 2,
    prefix: tuple[str, ...] = (),
    steady_time: float = 0.0,
    image: Path | None = None,
    robust: bool = False,
) -> dict[str, Any]:
    """One mitsuba_time.py process: `passes` passes of `spp`, the first one
    compiling its kernels into an empty cache (a new user's first render).
    `prefix` runs it under another program (perf record ... --).
    `steady_time` adds steady passes until they took that long together;
    `image` keeps their mean image and its variance (an .npz); `robust`
    builds Mitsuba's Embree scene in robust mode, as ours always is."""
    cache = folder / f"drjit_cache_{integrator}_{seed}"
    if cache.exists():
        shutil.rmtree(cache)
    cache.mkdir(parents=True)
    cmd = [
        *prefix,
        str(python),
        str(bl.BENCH_DIR / "mitsuba_time.py"),
        str(config),
        "--integrator",
        integrator,
        "--spp",
        str(spp),
        "--passes",
        str(passes),
        "--seed",
        str(seed),
        "--threads",
        str(threads),
        "--variant",
        MITSUBA_VARIANT,
        "--mesh-dir",
        str(folder / "meshes"),
    ]
    if steady_time > 0:
        cmd += ["--steady-time", str(steady_time)]
    if image is not None:
        cmd += ["--image", str(image)]
    if robust:
        cmd += ["--robust"]
    p = subprocess.run(cmd, stdout=subprocess.PIPE, text=True, env={**env, "DRJIT_CACHE_DIR": str(cache)})
    shutil.rmtree(cache, ignore_errors=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed with status {p.returncode} (its messages are above)")
    result: dict[str, Any] = json.loads(p.stdout)
    return result


def mitsuba_rates(m: dict[str, Any]) -> dict[str, Any]:
    """Samples/s of the first pass and of the steady state (the later
    passes together), per wall second and per CPU second of the process."""
    px = m["width"] * m["height"]
    first, rest = m["passes"][0], m["passes"][1:]
    samples = sum(px * p["spp"] for p in rest)
    wall, cpu = sum(p["wall_s"] for p in rest), sum(p["cpu_s"] for p in rest)
    return {
        "first_samples_per_s": px * first["spp"] / first["wall_s"],
        "first_wall_s": first["wall_s"],
        "first_compile_s": first["backend_s"] + first["codegen_s"],
        "steady_samples_per_s": samples / wall,
        "steady_samples_per_cpu_s": samples / max(cpu, 1e-9),
        "steady_cores": cpu / wall,
        "steady_cache_hits": sum(p["cache_hits"] for p in rest),
        "steady_kernels": sum(p["kernels"] for p in rest),
    }


def ours_steady(short: dict[str, Any], long: dict[str, Any], px: int) -> dict[str, float]:
    """Our steady state, as Mitsuba's: the samples the longer render drew
    beyond the shorter one, over the time (and render-thread CPU time) they
    took. What both renders share drops out: the start of the render
    threads and the first passes, which on this machine run at about half
    speed for ~0.1 s (the second vCPU waking; 1.0 core used over a 4 spp
    render, 1.9 over 3 s)."""
    extra = px * (long["spp"] - short["spp"])
    wall = max(long["time_s"] - short["time_s"], 1e-9)
    cpu = max(final_field(long, "render_cpu_s") - final_field(short, "render_cpu_s"), 1e-9)
    return {"samples_per_s": extra / wall, "samples_per_cpu_s": extra / cpu, "cores": cpu / wall}


def mitsuba_scene(
    ctx: Context, folder: Path, max_depth: int, sets: tuple[str, ...] = (), tag: str = "", scene: Path = LAMPSHADE
) -> Path:
    """A scene (the lampshade by default) as Mitsuba gets it: our effective
    config (render --print-config, with `sets` applied), which the
    cross-check's converter turns into Mitsuba's scene, written into `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    eff = folder / f"{scene.stem}{tag}.yaml"
    set_args = [a for x in sets for a in ("--set", x)]
    p = subprocess.run(
        [
            str(ctx.render),
            "--print-config",
            str(scene),
            "--set",
            f"render.max_depth={max_depth}",
            *set_args,
            "--format",
            "yaml",
        ],
        capture_output=True,
        text=True,
    )
    if p.returncode != 0:
        raise RuntimeError(f"render --print-config failed: {p.stderr.strip()}")
    eff.write_text(p.stdout)
    return eff


def section_mitsuba(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    rounds = 2 if q else 5
    ours_spp = {"direct": 16 if q else 64, "path": 8 if q else 32}
    mits_spp = dict(ours_spp)
    mits_passes = 3 if q else 4  # the first (compiling) one and the steady ones
    # 64 spp everywhere: at 16, the multi-lamp and Little Lamp renders took
    # 0.1-0.25 s on 2 threads, where the machine's slow first 0.1 s spread
    # the cost ratio's rounds by 0.3-0.9 (results/bench/NOTEBOOK.md, "Sixth pass").
    cost_spp = {"lampshade": 16 if q else 64, "multi_lamp": 4 if q else 64, "little_lamp": 4 if q else 64}
    max_depth = 8
    python, env = mitsuba_env()
    folder = TMP / "mitsuba"
    eff = mitsuba_scene(ctx, folder, max_depth)
    params = {
        "config": str(LAMPSHADE.relative_to(bl.ROOT)),
        "rounds": rounds,
        "threads": 2,
        "ours": {
            "strategy": "light",
            "spp": ours_spp,
            "max_depth": max_depth,
            "samples_per_s": "width x height x spp / time_s of the final JSON line (render time: passes only)",
            "steady": "a second render of spp + the steady passes' spp of Mitsuba: the extra samples over the "
            "extra render time (ours_steady); the ratio to Mitsuba's steady state uses it",
        },
        "mitsuba": {
            "variant": MITSUBA_VARIANT,
            "spp_per_pass": mits_spp,
            "passes": mits_passes,
            "first_pass": "traces the integrator and compiles its kernels (fresh DRJIT_CACHE_DIR per process)",
            "steady": "the passes after the first, together",
            "integrators": "direct: 1 emitter + 1 BSDF sample, MIS (our `light`); path: max_depth ours + 1, "
            "our rr_depth (tools/crosscheck/mitsuba_lampshade.py: mitsuba_integrator)",
            "embree": "Mitsuba's default (not robust) for the ratio; a third run per round and integrator "
            "with embree_use_robust_intersections (RTC_SCENE_FLAG_ROBUST, which our renderer always sets) "
            "for ratio_vs_robust",
        },
        "order": "per round and integrator, ours and Mitsuba one after the other, who goes first "
        "alternating by round; seed = round",
        "ratio": "ours samples/s / Mitsuba steady samples/s of the same round and integrator; median (range)",
        "cost": {
            "scenes": {k: str(v.relative_to(bl.ROOT)) for k, v in COST_SCENES.items()},
            "spp": cost_spp,
            "integrator": "direct",
            "threads": 2,
            "what": "antishadow_exact time per sample / light's, same scene and round (who goes first "
            "alternating); CPU = render_cpu_s, wall = time_s",
        },
        "targets": {"light_vs_mitsuba": MITSUBA_TARGET_RATIO, "antishadow_exact_cost": COST_TARGET},
    }
    out = TMP / "runs" / "mitsuba"
    bl.run_render(ctx, LAMPSHADE, out / "warmup", "--spp", "1", "--threads", "2")
    ours_runs: dict[str, list[dict[str, Any]]] = {"direct": [], "path": []}
    mits_runs: dict[str, list[dict[str, Any]]] = {"direct": [], "path": []}
    robust_runs: dict[str, list[dict[str, Any]]] = {"direct": [], "path": []}
    cost_runs: dict[str, list[dict[str, Any]]] = {}
    info: dict[str, Any] = {}
    for r in range(rounds):
        log(f"mitsuba: round {r + 1}/{rounds}")
        for integ in ("direct", "path"):

            def ours(integ: str = integ, r: int = r) -> None:
                args = ["--threads", "2", "--strategy", "light", "--integrator", integ, "--seed", str(r + 1)]
                args += ["--set", f"render.max_depth={max_depth}"]
                a = bl.run_render(ctx, LAMPSHADE, out / f"ours_{integ}", "--spp", str(ours_spp[integ]), *args)
                short = a.summary()
                # As many more samples as Mitsuba's steady passes draw.
                long_spp = ours_spp[integ] + (mits_passes - 1) * mits_spp[integ]
                b = bl.run_render(ctx, LAMPSHADE, out / f"ours_{integ}_long", "--spp", str(long_spp), *args)
                long = b.summary()
                px = short["samples"] // short["spp"]
                ours_runs[integ].append(
                    {**short, "render": render_rates(short), "long": long, "steady": ours_steady(short, long, px)}
                )

            def mitsuba(integ: str = integ, r: int = r, robust: bool = False) -> None:
                m = mitsuba_time(python, env, eff, integ, mits_spp[integ], mits_passes, r + 1, folder, robust=robust)
                info.update({k: m[k] for k in ("mitsuba", "drjit", "variant", "threads", "libllvm")})
                info.setdefault("integrators", {})[integ] = m["integrator"]
                (robust_runs if robust else mits_runs)[integ].append({**m, "rates": mitsuba_rates(m)})

            steps = (ours, mitsuba, functools.partial(mitsuba, robust=True))
            for step in steps if r % 2 == 0 else steps[::-1]:
                step()
        for name, scene in COST_SCENES.items():
            for s in ("light", "antishadow_exact") if r % 2 == 0 else ("antishadow_exact", "light"):
                args = ["--threads", "2", "--strategy", s, "--integrator", "direct", "--seed", str(r + 1)]
                a = bl.run_render(ctx, scene, out / f"cost_{name}_{s}", "--spp", str(cost_spp[name]), *args).summary()
                cost_runs.setdefault(f"{name}/{s}", []).append({**a, "render": render_rates(a)})
    table: dict[str, Any] = {}
    for integ in ("direct", "path"):
        o, m = ours_runs[integ], mits_runs[integ]
        rates = [x["rates"] for x in m]
        table[integ] = {
            "ours_samples_per_s": median([x["samples_per_s"] for x in o]),
            "ours_samples_per_cpu_s": median([x["render"]["samples_per_cpu_s"] for x in o]),
            "ours_cores": median([x["render_cpu_s"] / x["time_s"] for x in o]),
            "ours_steady_samples_per_s": median([x["steady"]["samples_per_s"] for x in o]),
            "ours_steady_samples_per_cpu_s": median([x["steady"]["samples_per_cpu_s"] for x in o]),
            "ours_steady_cores": median([x["steady"]["cores"] for x in o]),
            **{f"mitsuba_{k}": median([x[k] for x in rates]) for k in rates[0]},
            "ratio": ratio_stats(
                [a["steady"]["samples_per_s"] / b["steady_samples_per_s"] for a, b in zip(o, rates, strict=True)]
            ),
            "ratio_whole_render": ratio_stats(
                [a["samples_per_s"] / b["steady_samples_per_s"] for a, b in zip(o, rates, strict=True)]
            ),
            "ratio_cpu": ratio_stats(
                [
                    a["steady"]["samples_per_cpu_s"] / b["steady_samples_per_cpu_s"]
                    for a, b in zip(o, rates, strict=True)
                ]
            ),
            "ratio_vs_first_pass": ratio_stats(
                [a["samples_per_s"] / b["first_samples_per_s"] for a, b in zip(o, rates, strict=True)]
            ),
            # Both renderers' Embree scenes robust: how much of the ratio
            # is the traversal mode rather than the code around the rays.
            "mitsuba_robust_steady_samples_per_s": median(
                [x["rates"]["steady_samples_per_s"] for x in robust_runs[integ]]
            ),
            "ratio_vs_robust": ratio_stats(
                [
                    a["steady"]["samples_per_s"] / b["rates"]["steady_samples_per_s"]
                    for a, b in zip(o, robust_runs[integ], strict=True)
                ]
            ),
        }
    cost: dict[str, Any] = {}
    for name in COST_SCENES:
        lt, ax = cost_runs[f"{name}/light"], cost_runs[f"{name}/antishadow_exact"]
        cost[name] = {
            "light_samples_per_s": median([x["samples_per_s"] for x in lt]),
            "antishadow_exact_samples_per_s": median([x["samples_per_s"] for x in ax]),
            "cost_cpu": ratio_stats(
                [
                    a["render"]["samples_per_cpu_s"] / b["render"]["samples_per_cpu_s"]
                    for a, b in zip(lt, ax, strict=True)
                ]
            ),
            "cost_wall": ratio_stats([a["samples_per_s"] / b["samples_per_s"] for a, b in zip(lt, ax, strict=True)]),
        }
    results = {
        "mitsuba": info,
        "table": table,
        "cost": cost,
        "runs": {"ours": ours_runs, "mitsuba": mits_runs, "mitsuba_robust": robust_runs, "cost": cost_runs},
    }
    bl.write_result(ctx, "mitsuba", params, results)
    return results


# ---- 15. where the time goes: Embree vs the rest ----------------------------------


# Our functions listed by name in the section (the rest are summed).
TIME_SPLIT_TOP = 12


def time_split_run(
    perf: str, data: Path, run: Callable[[tuple[str, ...]], float], binary: str, functions: bool
) -> dict[str, Any]:
    """One profiled run: `run` renders under the perf prefix it is given and
    returns its CPU ns per sample; the profile splits that time (and, with
    `functions`, our binary's part by function)."""
    ns = run(ts.record_prefix(perf, data))
    shares = ts.report(perf, data)
    sp = ts.split(shares, binary)
    work = sp.embree + sp.own
    if not work > 0.0:
        raise RuntimeError(f"perf saw neither Embree nor the renderer's code: {shares}")
    per_function: dict[str, float] = {}
    if functions:
        # Shares of all samples, rescaled like the groups: ns per sample.
        total = sum(shares.values())
        for name, pct in ts.report_symbols(perf, data, binary).items():
            per_function[name] = ns * (100.0 * pct / total) / work
    data.unlink(missing_ok=True)
    return {
        "functions_ns_per_sample": per_function,
        "cpu_ns_per_sample": ns,
        "shares": {k: round(v, 3) for k, v in sorted(shares.items(), key=lambda kv: -kv[1])},
        "embree_pct": sp.embree,
        "own_pct": sp.own,
        "other_pct": sp.other,
        "embree_ns_per_sample": ns * sp.embree_fraction,
        "own_ns_per_sample": ns * (1.0 - sp.embree_fraction),
    }


def function_names(runs: list[dict[str, Any]]) -> set[str]:
    """Every function some profiled run (time_split_run) saw."""
    return {n for x in runs for n in x["functions_ns_per_sample"]}


def function_medians(runs: list[dict[str, Any]], names: set[str]) -> dict[str, float]:
    """Each function's ns per sample, median over the runs (0 in a run
    where perf saw none of it)."""
    return {n: median([x["functions_ns_per_sample"].get(n, 0.0) for x in runs]) for n in names}


WHITE_ROOM = bl.ROOT / "configs" / "scenes" / "white_room_night.yaml"


def peak_rss_mb(path: Path) -> float:
    """The peak resident memory that /usr/bin/time -f %M wrote (kB), in MB."""
    return int(path.read_text().split()[-1]) / 1024.0


def section_white_room(ctx: Context) -> dict[str, Any]:
    """The White Room at night (99k triangles in 7.7 MB of PLY, two mesh
    bulbs of 2,208 triangles each, 54 auto portals) in our renderer and in
    Mitsuba 3 (llvm_ad_rgb, its Embree in robust mode as ours always is, so
    that both do the same work): the time from start to the first sample
    (ours: the process's wall time less its render time; Mitsuba's:
    mi.load_dict), samples per second (ours: `light` and
    `antishadow_exact`; Mitsuba: its steady passes) and the peak resident
    memory of each process (/usr/bin/time). Issue 40."""
    q = ctx.quick
    rounds = 1 if q else 3
    spp = {"direct": 2 if q else 16, "path": 1 if q else 8}
    passes = 3
    max_depth = 8
    python, env = mitsuba_env()
    folder = TMP / "white_room"
    eff = mitsuba_scene(ctx, folder, max_depth, scene=WHITE_ROOM)
    out = TMP / "runs" / "white_room"
    rss = folder / "rss.txt"
    timed = ("/usr/bin/time", "-o", str(rss), "-f", "%M")
    runs: dict[str, list[dict[str, Any]]] = {}
    for r in range(rounds):
        log(f"white_room: round {r + 1}/{rounds}")
        for integ in ("direct", "path"):
            steps: list[Callable[[], None]] = []
            for strategy in ("light", "antishadow_exact"):

                def ours(integ: str = integ, strategy: str = strategy, r: int = r) -> None:
                    args = ["--threads", "2", "--strategy", strategy, "--integrator", integ, "--seed", str(r + 1)]
                    args += ["--set", f"render.max_depth={max_depth}", "--spp", str(spp[integ])]
                    a = bl.run_render(ctx, WHITE_ROOM, out / f"{integ}_{strategy}", *args, prefix=timed)
                    runs.setdefault(f"{integ}/{strategy}", []).append(
                        {
                            "load_s": a.process_wall_s - a.time_s,
                            "samples_per_s": a.samples / max(a.time_s, 1e-9),
                            "peak_rss_mb": peak_rss_mb(rss),
                            "run": a.summary(),
                        }
                    )

                steps.append(ours)

            def mitsuba(integ: str = integ, r: int = r) -> None:
                m = mitsuba_time(python, env, eff, integ, spp[integ], passes, r + 1, folder, prefix=timed, robust=True)
                rates = mitsuba_rates(m)
                runs.setdefault(f"{integ}/mitsuba", []).append(
                    {
                        "load_s": m["load_s"],
                        "samples_per_s": rates["steady_samples_per_s"],
                        "first_pass_s": rates["first_wall_s"],
                        "peak_rss_mb": peak_rss_mb(rss),
                        "mitsuba": m.get("mitsuba"),
                    }
                )

            steps.append(mitsuba)
            for step in steps if r % 2 == 0 else steps[::-1]:
                step()
    table: dict[str, Any] = {}
    for key, rs in runs.items():
        table[key] = {k: bl.median([float(x[k]) for x in rs]) for k in ("load_s", "samples_per_s", "peak_rss_mb")}
    ratios: dict[str, Any] = {}
    for integ in ("direct", "path"):
        m = table[f"{integ}/mitsuba"]
        for strategy in ("light", "antishadow_exact"):
            o = table[f"{integ}/{strategy}"]
            ratios[f"{integ}/{strategy}_vs_mitsuba"] = {
                "samples_per_s": o["samples_per_s"] / m["samples_per_s"],
                "load_s": o["load_s"] / m["load_s"],
                "peak_rss": o["peak_rss_mb"] / m["peak_rss_mb"],
            }
    params = {
        "config": str(WHITE_ROOM.relative_to(bl.ROOT)),
        "rounds": rounds,
        "threads": 2,
        "spp": spp,
        "max_depth": max_depth,
        "mitsuba": {"variant": MITSUBA_VARIANT, "passes": passes, "robust": True},
        "order": "per round and integrator: ours (light, antishadow_exact), then Mitsuba; reversed on odd rounds",
        "medians": "of the rounds",
    }
    results = {"table": table, "ratios": ratios, "runs": runs}
    bl.write_result(ctx, "white_room", params, results)
    for key, row in table.items():
        log(
            f"white_room {key}: load {row['load_s']:.2f} s, {row['samples_per_s']:.3g} samples/s, "
            f"peak {row['peak_rss_mb']:.0f} MB"
        )
    return results


def section_time_split(ctx: Context) -> dict[str, Any]:
    """Ours (`light`) and Mitsuba on the lampshade, one thread each, under
    perf: CPU time per sample split into Embree's and the renderer's own
    (time_split.py). Both trace with Embree 3, so this says which side of
    the Embree call a gap between them is on."""
    perf = ts.perf_path()
    if perf is None:
        raise RuntimeError(
            "perf is missing or may not record here: make bench installs linux-perf with apt-get; "
            "recording needs kernel.perf_event_paranoid <= 2"
        )
    q = ctx.quick
    rounds = 1 if q else 3
    spp = {"direct": 16 if q else 64, "path": 4 if q else 16}
    passes = 3  # Mitsuba: the compiling first pass and two steady ones
    max_depth = 8
    python, env = mitsuba_env()
    folder = TMP / "time_split"
    eff = mitsuba_scene(ctx, folder, max_depth)
    data = folder / "perf.data"
    out = TMP / "runs" / "time_split"
    params = {
        "config": str(LAMPSHADE.relative_to(bl.ROOT)),
        "threads": 1,
        "rounds": rounds,
        "spp": spp,
        "mitsuba_passes": passes,
        "ours": {"strategy": "light", "max_depth": max_depth, "ns_per_sample": "render_cpu_s / samples"},
        "mitsuba": {"variant": MITSUBA_VARIANT, "ns_per_sample": "the steady passes' CPU time / their samples"},
        "groups": "embree: libembree*; own: the renderer's code ([JIT] kernels, Dr.Jit and Mitsuba for "
        "Mitsuba), libc, libm; other: Python, LLVM, EXR and zlib, the kernel (time_split.py)",
        "split": "ns per sample x embree / (embree + own), and x own / (embree + own); our functions: "
        "ns per sample x their share / (embree + own)",
        "perf": perf,
        "order": "per round and integrator, ours and Mitsuba one after the other, who goes first alternating",
    }
    runs: dict[str, dict[str, list[dict[str, Any]]]] = {
        "direct": {"ours": [], "mitsuba": []},
        "path": {"ours": [], "mitsuba": []},
    }
    for r in range(rounds):
        log(f"time_split: round {r + 1}/{rounds}")
        for integ in ("direct", "path"):

            def ours(prefix: tuple[str, ...], integ: str = integ, r: int = r) -> float:
                args = ["--threads", "1", "--strategy", "light", "--integrator", integ, "--seed", str(r + 1)]
                args += ["--spp", str(spp[integ]), "--set", f"render.max_depth={max_depth}"]
                a = bl.run_render(ctx, LAMPSHADE, out / f"ours_{integ}", *args, prefix=prefix).summary()
                return 1e9 * float(a["render_cpu_s"]) / float(a["samples"])

            def mitsuba(prefix: tuple[str, ...], integ: str = integ, r: int = r) -> float:
                m = mitsuba_time(python, env, eff, integ, spp[integ], passes, r + 1, folder, threads=1, prefix=prefix)
                return 1e9 / float(mitsuba_rates(m)["steady_samples_per_cpu_s"])

            # Who goes first alternates by round, as in section 14.
            for who in ("ours", "mitsuba") if r % 2 == 0 else ("mitsuba", "ours"):
                run = ours if who == "ours" else mitsuba
                runs[integ][who].append(time_split_run(perf, data, run, ctx.render.name, who == "ours"))
    keys = ("cpu_ns_per_sample", "embree_ns_per_sample", "own_ns_per_sample", "embree_pct", "own_pct", "other_pct")
    table: dict[str, Any] = {}
    for integ, by in runs.items():
        row: dict[str, Any] = {who: {k: median([x[k] for x in xs]) for k in keys} for who, xs in by.items()}
        # ours / Mitsuba, run by run (same round), for the total and each part.
        for k in ("cpu_ns_per_sample", "embree_ns_per_sample", "own_ns_per_sample"):
            row[f"ratio_{k}"] = ratio_stats([a[k] / b[k] for a, b in zip(by["ours"], by["mitsuba"], strict=True)])
        # Our own code by function, the largest TIME_SPLIT_TOP by name.
        med = function_medians(by["ours"], function_names(by["ours"]))
        top = sorted(med.items(), key=lambda kv: -kv[1])[:TIME_SPLIT_TOP]
        row["ours_functions_ns_per_sample"] = dict(top)
        row["ours_other_functions_ns_per_sample"] = sum(med.values()) - sum(v for _, v in top)
        table[integ] = row
    cost = time_split_cost(ctx, perf, data, rounds, 4 if q else 16)
    params["cost"] = {
        "scene": str(MULTI_LAMP.relative_to(bl.ROOT)),
        "integrator": "direct",
        "spp": cost["spp"],
        "what": "light and antishadow_exact, 1 thread, under perf (who goes first alternating): "
        "where antishadow_exact's extra time per sample goes, by function",
    }
    results = {"table": table, "runs": runs, "cost": cost}
    bl.write_result(ctx, "time_split", params, results)
    return results


def time_split_cost(ctx: Context, perf: str, data: Path, rounds: int, spp: int) -> dict[str, Any]:
    """`light` and `antishadow_exact` on multi_lamp (direct, 1 thread) under
    perf: issue 17's cost goal (antishadow_exact <= 1.15x light per sample)
    fails there, and the by-function difference says where the extra time
    goes."""
    out = TMP / "runs" / "time_split"
    runs: dict[str, list[dict[str, Any]]] = {"light": [], "antishadow_exact": []}
    for r in range(rounds):
        for strategy in ("light", "antishadow_exact") if r % 2 == 0 else ("antishadow_exact", "light"):

            def render(prefix: tuple[str, ...], strategy: str = strategy, r: int = r) -> float:
                args = ["--threads", "1", "--strategy", strategy, "--integrator", "direct", "--seed", str(r + 1)]
                a = bl.run_render(
                    ctx, MULTI_LAMP, out / f"cost_{strategy}", *args, "--spp", str(spp), prefix=prefix
                ).summary()
                return 1e9 * float(a["render_cpu_s"]) / float(a["samples"])

            runs[strategy].append(time_split_run(perf, data, render, ctx.render.name, True))
    keys = ("cpu_ns_per_sample", "embree_ns_per_sample", "own_ns_per_sample")
    by = {s: {k: median([x[k] for x in xs]) for k in keys} for s, xs in runs.items()}
    names = function_names([x for xs in runs.values() for x in xs])
    med = {s: function_medians(xs, names) for s, xs in runs.items()}
    # The functions that add the most to antishadow_exact's sample.
    extra = sorted(names, key=lambda n: -(med["antishadow_exact"][n] - med["light"][n]))[:TIME_SPLIT_TOP]
    return {
        "spp": spp,
        "by_strategy": by,
        "ratio_cpu_ns_per_sample": ratio_stats(
            [
                a["cpu_ns_per_sample"] / b["cpu_ns_per_sample"]
                for a, b in zip(runs["antishadow_exact"], runs["light"], strict=True)
            ]
        ),
        "functions_ns_per_sample": {n: {s: med[s][n] for s in runs} for n in extra},
        "runs": runs,
    }


# ---- 16. equal-time error against Mitsuba ------------------------------------------

# (integrator, s_L) of the lampshade: three light/portal ratios with direct
# lighting, one with the path integrator.
MITSUBA_EFF_CASES = (("direct", 0.15), ("direct", 0.6), ("direct", 1.2), ("path", 0.6))
MITSUBA_EFF_STRATEGIES = ("light", "antishadow_exact")


def mitsuba_eff_sets(integ: str, s_l: float, max_depth: int) -> list[str]:
    """The --set overrides of one case, as both renderers and the reference
    get them (the direct cases' are section 8's, so that its cached
    references serve here too)."""
    sets = [f"params.s_L={s_l}", f"params.s_P={S_P}"]
    if integ == "path":
        sets += ["render.integrator=path", f"render.max_depth={max_depth}"]
    return sets


@dataclass(frozen=True)
class EffCase:
    """One case of the section: what each of its renders needs."""

    integ: str
    set_args: list[str]
    out: Path  # run folders
    scene: Path  # Mitsuba's scene (our effective config)
    folder: Path  # Mitsuba's working folder (meshes, kernel caches)
    ref: np.ndarray
    ref_var: np.ndarray
    secs: float
    mits_spp: int


def eff_ours(ctx: Context, c: EffCase, strategy: str, r: int) -> dict[str, Any]:
    """Ours with `strategy` for c.secs (seed r + 1): its error and clocks."""
    args = ["--time", str(c.secs), "--spp", "0", "--threads", "2", "--seed", str(r + 1)]
    run = bl.run_render(ctx, LAMPSHADE, c.out / strategy, *args, "--strategy", strategy, *c.set_args)
    x, x_var, _ = bl.read_exr(Path(run.final["path"]))
    return {
        **bl.rel_error(x, x_var, c.ref, c.ref_var),
        "time_s": run.time_s,
        "cpu_s": run.cpu_s,
        "spp": run.final["spp"],
    }


def eff_mitsuba(python: Path, env: dict[str, str], c: EffCase, r: int, info: dict[str, Any]) -> dict[str, Any]:
    """Mitsuba's steady passes for c.secs (seed r + 1): the error of their
    mean image and their clocks; `info` receives its versions."""
    npz = c.out / "mitsuba.npz"
    npz.parent.mkdir(parents=True, exist_ok=True)
    m = mitsuba_time(python, env, c.scene, c.integ, c.mits_spp, 2, r + 1, c.folder, steady_time=c.secs, image=npz)
    info.update({k: m[k] for k in ("mitsuba", "drjit", "variant", "threads", "libllvm")})
    with np.load(npz) as img:
        x, x_var, n_passes = img["mean"], img["var"], int(img["passes"])
    if x.shape != c.ref.shape:
        raise RuntimeError(f"Mitsuba's image is {x.shape}, the reference {c.ref.shape}")
    steady = m["passes"][1:]
    return {
        **bl.rel_error(x, x_var, c.ref, c.ref_var),
        "time_s": sum(p["wall_s"] for p in steady),
        "cpu_s": sum(p["cpu_s"] for p in steady),
        "spp": sum(p["spp"] for p in steady),
        "passes": n_passes,
    }


def eff_round(
    ctx: Context, python: Path, env: dict[str, str], c: EffCase, r: int, info: dict[str, Any]
) -> dict[str, Any]:
    """One round of a case: each of our strategies and Mitsuba, the order
    rotating with r, and each strategy's speed-up over Mitsuba."""
    names = [*MITSUBA_EFF_STRATEGIES, "mitsuba"]
    k = r % len(names)
    row: dict[str, Any] = {}
    for name in names[k:] + names[:k]:
        row[name] = eff_mitsuba(python, env, c, r, info) if name == "mitsuba" else eff_ours(ctx, c, name, r)
    m = row["mitsuba"]
    for s in MITSUBA_EFF_STRATEGIES:
        o = row[s]
        o["vs_mitsuba_cpu"] = ee.speedup(o, o["cpu_s"], m, m["cpu_s"])
        o["vs_mitsuba_wall"] = ee.speedup(o, o["time_s"], m, m["time_s"])
        o["vs_mitsuba_per_sample"] = ee.speedup(o, o["spp"], m, m["spp"])
    return row


def eff_table(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """A case's rounds summarised: speed-ups over rounds, and each
    renderer's median error and clocks."""
    table: dict[str, Any] = {
        s: {
            k: ee.over_rounds([row[s][k] for row in runs])
            for k in ("vs_mitsuba_cpu", "vs_mitsuba_wall", "vs_mitsuba_per_sample")
        }
        for s in MITSUBA_EFF_STRATEGIES
    }
    for name in (*MITSUBA_EFF_STRATEGIES, "mitsuba"):
        table.setdefault(name, {}).update(
            {
                k: median([row[name][k] for row in runs])
                for k in ("rel_mse_est", "rel_mse_est_se", "rel_var", "spp", "time_s", "cpu_s")
            }
        )
    table["mitsuba"]["consistent"] = all(ee.consistent(row["mitsuba"]) for row in runs)
    table["mitsuba"]["bias_z"] = [row["mitsuba"]["bias_z"] for row in runs]
    return table


def section_mitsuba_efficiency(ctx: Context) -> dict[str, Any]:
    q = ctx.quick
    rounds = 1 if q else 3
    secs, ref_secs = (1.0 if q else 4.0), (6.0 if q else 60.0)
    mits_spp = {"direct": 16 if q else 64, "path": 8 if q else 32}
    max_depth = 8
    python, env = mitsuba_env()
    params = {
        "config": str(LAMPSHADE.relative_to(bl.ROOT)),
        "cases": [{"integrator": i, "s_L": s, "ratio": s / S_P} for i, s in MITSUBA_EFF_CASES],
        "rounds": rounds,
        "time_s": secs,
        "threads": 2,
        "ours": {"strategies": list(MITSUBA_EFF_STRATEGIES), "time": "render --time (time_s, render_cpu_s)"},
        "mitsuba": {
            "variant": MITSUBA_VARIANT,
            "spp_per_pass": mits_spp,
            "time": "its steady passes (after the compiling first one) until they took time_s together; "
            "their wall and CPU seconds",
            "image": "the mean of the steady passes; its variance from their spread",
        },
        "reference": {"strategy": "light", "time_s_min": ref_secs, "seed": REF_SEED, "renderer": "ours"},
        "rel_mse_est": "mean over pixels and channels of ((x - ref)^2 - var_ref) / (ref^2 + 0.01)",
        "speedup": "(Mitsuba's rel_mse_est x seconds) / (ours): how many times less time ours needs for "
        "Mitsuba's error; per round, median and range over rounds; low = two standard errors of both "
        "estimates against ours (a bound where the reference does not resolve ours)",
        "per_sample": "the same with samples per pixel in place of seconds: the error of one sample",
        "consistent": "Mitsuba's bias_z against our reference <= 4 in every round: its error is its noise",
    }
    cases: dict[str, Any] = {}
    info: dict[str, Any] = {}
    folder = TMP / "mitsuba_efficiency"
    for integ, s_l in MITSUBA_EFF_CASES:
        sets = mitsuba_eff_sets(integ, s_l, max_depth)
        tag = f"{integ}_sL{s_l}"
        ref_name = f"lampshade_sL{s_l}" if integ == "direct" else f"lampshade_{integ}_sL{s_l}"
        ref_exr, meta = reference(ctx, LAMPSHADE, sets, ref_secs, ref_name)
        ref, ref_var, _ = bl.read_exr(ref_exr)
        case = EffCase(
            integ=integ,
            set_args=[a for x in sets for a in ("--set", x)],
            out=TMP / "runs" / "mitsuba_efficiency" / tag,
            scene=mitsuba_scene(ctx, folder, max_depth, tuple(sets), f"_{tag}"),
            folder=folder,
            ref=ref,
            ref_var=ref_var,
            secs=secs,
            mits_spp=mits_spp[integ],
        )
        runs = []
        for r in range(rounds):
            log(f"mitsuba_efficiency: {tag}, round {r + 1}/{rounds}")
            runs.append(eff_round(ctx, python, env, case, r, info))
        cases[tag] = {
            "integrator": integ,
            "s_L": s_l,
            "ratio": s_l / S_P,
            "reference": meta,
            "table": eff_table(runs),
            "runs": runs,
        }
    results = {"mitsuba": info, "cases": cases}
    bl.write_result(ctx, "mitsuba_efficiency", params, results)
    return results


def section_dask(ctx: Context) -> dict[str, Any]:
    """A sweep on 1 and 2 one-thread Dask workers (dask_scaling.py)."""
    params = {"what": "portal-harness sweep --scheduler on a LocalCluster of 1, then 2 worker processes"}
    results = dask_scaling.measure(TMP / "runs", LAMPSHADE, ctx.render, ctx.quick, ctx.machine["nproc"])
    bl.write_result(ctx, "dask", params, results)
    return results


SECTIONS: dict[str, Callable[[Context], Any]] = {
    "raw_embree": section_raw_embree,
    "micro": section_micro,
    "throughput": section_throughput,
    "threads": section_threads,
    "snapshots": section_snapshots,
    "scene_scaling": section_scene_scaling,
    "harness": section_harness,
    "dask": section_dask,
    "efficiency": section_efficiency,
    "portal_weights": section_portal_weights,
    "mesh_load": section_mesh_load,
    "portal_finder": section_portal_finder,
    "mesh_lights": section_mesh_lights,
    "mitsuba": section_mitsuba,
    "time_split": section_time_split,
    "mitsuba_efficiency": section_mitsuba_efficiency,
    "white_room": section_white_room,
}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("build", type=Path, help="build folder holding render (and the compiled benchmarks in bench/)")
    ap.add_argument("--quick", action="store_true", help="smoke version (~2 minutes)")
    ap.add_argument("--only", default="", help="comma-separated sections (default: all): " + ", ".join(SECTIONS))
    args = ap.parse_args()
    only = [s for s in args.only.split(",") if s]
    unknown = [s for s in only if s not in SECTIONS]
    if unknown:
        ap.error(f"unknown section(s) {unknown}; expected some of {list(SECTIONS)}")
    ctx = bl.make_context(args.build.resolve(), args.quick)
    for name in ("raw_embree", "micro", "mesh_load"):
        ctx.bins[name] = ctx.build / "bench" / name
    log(
        f"renderer {ctx.version} at {ctx.render}; {'quick' if ctx.quick else 'full'} run; "
        f"{ctx.machine['nproc']} CPUs ({ctx.machine['cpu_model']}), load {ctx.machine['loadavg_1_5_15']}"
    )
    failed = []
    for name, fn in SECTIONS.items():
        if only and name not in only:
            continue
        t0 = time.monotonic()
        log(f"== {name}")
        try:
            fn(ctx)
        except Exception:  # one failing section must not lose the others
            failed.append(name)
            log(f"section {name} FAILED:\n{traceback.format_exc()}")
        log(f"== {name} done in {time.monotonic() - t0:.1f} s")
    if failed:
        log(f"failed sections: {', '.join(failed)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
