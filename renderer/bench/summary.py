"""Turns results/bench/*.json into one readable table, results/bench/summary.md,
and prints it. Sections whose JSON is missing are listed as not run.

usage: summary.py [RESULTS_DIR]
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent.parent.parent / "results" / "bench"
SWEEP = ("portal", "projection", "antishadow", "antishadow_exact")


def f(x: Any, spec: str = ".3g") -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and not math.isfinite(x):
        return "inf" if x > 0 else ("nan" if x != x else "-inf")
    return format(x, spec)


def mega(x: float | None) -> str:
    return "-" if x is None else f"{x / 1e6:.2f}"


def pct(x: float | None) -> str:
    return "-" if x is None or x != x else f"{100 * x:.1f}%"


def table(header: list[str], rows: list[list[str]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return [*out, ""]


def verdict(ok: bool | None) -> str:
    return "n/a" if ok is None else ("PASS" if ok else "FAIL")


RAW_APIS = ("wrapper", "embree", "stream", "packet4", "packet8", "packet16")


def raw_embree(d: dict[str, Any]) -> list[str]:
    t = d["results"]["table"]
    best_api = d["results"].get("best_api", {})
    rows_cpu, rows_2t = [], []
    for kind in ("camera", "bounce", "shadow", "mix"):
        cells = [t.get(f"{kind}/{a}", {}) for a in RAW_APIS]
        e = t[f"{kind}/embree"]
        best = t.get(f"{kind}/best")
        rows_cpu.append(
            [
                kind,
                *(mega(c.get("rays_per_cpu_s_1t")) for c in cells),
                f"{best_api.get(kind, '-')} {mega(best['rays_per_cpu_s_1t'])}" if best else "n/a",
                f(best["rays_per_cpu_s_1t"] / e["rays_per_cpu_s_1t"], ".2f") if best else "n/a",
            ]
        )
        rows_2t.append(
            [
                kind,
                *(
                    f"{mega(c.get('per_thread_rays_per_s_1t'))} / {mega(c.get('per_thread_rays_per_s_2t'))}"
                    for c in cells
                ),
            ]
        )
    raw = d["results"]["raw"]
    b = raw["batches"]
    nr = t.get("mix/embree_without_robust_flag")
    note = []
    if nr:
        gain = nr["rays_per_cpu_s_1t"] / t["mix/embree"]["rays_per_cpu_s_1t"] - 1
        note = [
            f"The renderer's scene uses RTC_SCENE_FLAG_ROBUST; rebuilt without it, mix/embree 1T gives "
            f"{mega(nr['rays_per_cpu_s_1t'])} M rays/CPU-s ({pct(gain)} vs robust).",
            "",
        ]
    native = [f"{w}" for w in (4, 8, 16) if raw.get(f"native_ray{w}")]
    mismatch = [
        f"{k}/{a}"
        for k, v in b.items()
        for a, x in (v.get("hit_fraction_by_api") or {}).items()
        if abs(x - v["hit_fraction"]) > 1e-3
    ]
    return [
        f"Embree {raw['embree_version']}; batches: "
        + ", ".join(f"{k} {v['rays']} rays ({pct(v['hit_fraction'])} hit)" for k, v in b.items())
        + f". Native packet widths on this CPU: {', '.join(native) or 'none reported'}; every API found the "
        f"same hits: {'yes' if not mismatch else 'NO (' + ', '.join(mismatch) + ')'}.",
        "",
        "M rays per CPU-second, one thread:",
        "",
        *table([*("kind",), *RAW_APIS, "best", "best / embree"], rows_cpu),
        "M rays/s per thread, wall clock, 1 thread / 2 threads:",
        "",
        *table(["kind", *RAW_APIS], rows_2t),
        "wrapper = the renderer's scene_intersect/scene_occluded; embree = rtcIntersect1/rtcOccluded1; "
        "stream = rtcIntersect1M/rtcOccluded1M over chunks of 1024 rays split by kind, camera rays flagged "
        "coherent (the renderer traces each film row's camera rays as such a coherent stream, in Embree's "
        "SoA layout: rtcIntersectNp); packetW = "
        "rtcIntersectW/rtcOccludedW, W rays of one kind of the same chunks at a time, the copy into Embree's "
        "SoA layout timed. 'best' is the fastest of embree, stream and packets: the raw limit that '% raw' "
        "of section 2 divides by.",
        "",
        *note,
    ]


def throughput(d: dict[str, Any]) -> list[str]:
    t = d["results"]["table"]
    rows = []
    for key, r in t.items():
        rows.append(
            [
                key,
                mega(r["samples_per_s"]),
                mega(r["rays_per_s"]),
                mega(r["samples_per_cpu_s"]),
                mega(r["rays_per_cpu_s"]),
                f(r.get("rays_per_sample"), ".2f"),
                pct(r.get("raw_fraction_cpu")),
                pct(r.get("raw_fraction_cpu_best_of")),
                pct(r.get("raw_fraction_cpu_single")),
                f(r["cost_vs_light_cpu"]["median"], ".2f"),
                f(r["cost_vs_light_wall"]["median"], ".2f"),
            ]
        )
    light = t.get("direct/light", {})
    frac = light.get("raw_fraction_cpu")
    best = light.get("raw_fraction_cpu_best_of")
    p = d["params"]
    # raw_limit_per_round: results written before the limit was taken next to every run.
    lims = p.get("raw_limit_per_run", {}).get("direct/light") or p.get("raw_limit_per_round", [])
    lim_txt = ", ".join(f"{mega(lim['best'])} ({mega(lim['single'])} single)" for lim in lims)
    runs_txt = ", ".join(pct(x) for x in light.get("raw_fraction_cpu_runs", []))
    cpu = (
        "CPU-second of the render threads"
        if "render_cpu_s" in p.get("cpu_rates", "")
        else "CPU-second (process, differential)"
    )
    out = [
        f"Lampshade (s_L = 0.6), {p.get('threads', 2)} thread(s), spp {p['spp']}, {p['reps']} round(s), medians. "
        f"'% raw' = renderer rays per {cpu} / raw Embree rays per CPU-second of the renderer's ray mix "
        "(raw_embree mix batch, 1 thread), with the fastest of single rays, streams and packets of 4, 8 and 16 "
        "(runs of older results: single rays and streams only), measured just before "
        "and just after each render (their mean); '% raw single' uses rtcIntersect1/rtcOccluded1 "
        f"alone. Raw limit next to the `direct/light` runs, M rays/CPU-s: {lim_txt}; their % raw: "
        f"{runs_txt or 'n/a'}. '% raw best-of' = the fastest run's rate / the largest raw limit measured "
        "next to the runs: interference only slows a run, so the fastest of several is the closest to the "
        "machine's undisturbed speed (NOTEBOOK.md). "
        "Cost = time per sample / that of `light`, same integrator and round (section 5).",
        "",
    ]
    out += table(
        [
            "integrator/strategy",
            "M samples/s",
            "M rays/s",
            "M samples/CPU-s",
            "M rays/CPU-s",
            "rays/sample",
            "% raw",
            "% raw best-of",
            "% raw single",
            "cost vs light (CPU)",
            "cost vs light (wall)",
        ],
        rows,
    )
    met = None if best is None or best != best else best >= 0.7
    out.append(
        f"Target `light` >= 70% of raw: best-of {pct(best)} -> {verdict(met)} (median of the runs' ratios: {pct(frac)})"
    )
    out.append("")
    return out


def threads(d: dict[str, Any]) -> list[str]:
    rows = []
    for s, r in d["results"]["table"].items():
        cores = (
            f"{f(r['cores_1t'], '.2f')} / {f(r['cores_2t'], '.2f')}"
            if "cores_1t" in r
            else f"{f(r.get('cpu_share_1t'), '.2f')} / {f(r.get('cpu_share_2t'), '.2f')}"
        )
        rows.append(
            [
                s,
                f(r["speedup_wall"]["median"], ".2f") + f" ({f(r['speedup_wall']['min'], '.2f')}-"
                f"{f(r['speedup_wall']['max'], '.2f')})",
                f(r.get("speedup_wall_best_of"), ".2f"),
                f(r["cpu_efficiency_2t_vs_1t"]["median"], ".2f"),
                cores,
                f(2 * r["cpu_efficiency_2t_vs_1t"]["median"], ".2f"),
            ]
        )
    light = d["results"]["table"].get("light")
    best = None if not light else light.get("speedup_wall_best_of")
    ok = None if best is None else best >= 1.8
    p = d["params"]
    return [
        *table(
            [
                "strategy",
                "wall speedup 2T/1T, median (range)",
                "wall speedup, best-of",
                "CPU efficiency 2T/1T",
                "cores used 1T / 2T",
                "speedup if both cores were free",
            ],
            rows,
        ),
        f"{p.get('spp')} spp, {p.get('reps')} round(s). Target >= 1.8x (wall, `light`, best-of: the fastest run "
        f"at each thread count): {verdict(ok)}. 'Cores used' is the render threads' CPU time / render time: "
        "below 2.0 at two threads the threads waited at the per-pass barrier or the machine ran something else, "
        "and the wall speedup says little; 'speedup if free' = 2 x CPU efficiency (ignores idle time at the "
        "barrier).",
        "",
    ]


def snapshots(d: dict[str, Any]) -> list[str]:
    t, p = d["results"]["table"], d["params"]
    if "overhead_cpu_paired" not in t:  # results of an older bench
        return ["(old format; rerun `BENCH_ONLY=snapshots make bench`)", ""]
    oc, oi, cp, wp = (
        t["overhead_cpu"],
        t["overhead_idle_machine_estimate"],
        t["overhead_cpu_paired"],
        t["overhead_wall_paired"],
    )
    return [
        *table(
            ["", "overhead (median)", "range"],
            [
                [
                    "snapshot CPU / render-thread CPU, same run",
                    pct(oc["median"]),
                    f"{pct(oc['min'])} .. {pct(oc['max'])}",
                ],
                ["estimate for an idle machine (pauses + writer CPU / threads) / render time", pct(oi), ""],
                [
                    "cross-check, samples per CPU second vs a run without",
                    pct(cp["median"]),
                    f"{pct(cp['min'])} .. {pct(cp['max'])}",
                ],
                [
                    "cross-check, samples per render second vs a run without",
                    pct(wp["median"]),
                    f"{pct(wp['min'])} .. {pct(wp['max'])}",
                ],
            ],
        ),
        f"{p['time_s']} s renders, {p['threads']} threads, snapshots every {p['every_s']} s "
        f"({f(t['snapshots_written'], '.0f')} written), {p['reps']} round(s); per snapshot "
        f"{f(t['cpu_per_snapshot_ms'], '.1f')} ms CPU (EXR encoding on the writer thread, the film copy on the "
        f"main thread) and {f(t['pause_per_snapshot_ms'], '.2f')} ms with the render threads paused. "
        f"Target < 2%: {verdict(oc['median'] < 0.02)} (CPU, same run), "
        f"{verdict(oi < 0.02)} (idle-machine estimate). The cross-checks compare two runs made seconds apart "
        "and follow the machine's load.",
        "",
    ]


def scene_scaling(d: dict[str, Any]) -> list[str]:
    t = d["results"]["table"]
    ns = list(t["light"]["by_n"].keys())
    rows = []
    for n in ns:
        a, b = t["light"]["by_n"][n], t["antishadow_exact"]["by_n"][n]
        rows.append(
            [
                n,
                mega(a["samples_per_cpu_s"]),
                f(a["cpu_ns_per_sample"], ".0f"),
                f(a["cost_vs_n1"], ".2f"),
                pct(a["wasted_fraction"]),
                mega(b["samples_per_cpu_s"]),
                f(b["cpu_ns_per_sample"], ".0f"),
                f(b["cost_vs_n1"], ".2f"),
                pct(b["wasted_fraction"]),
                f(a["load_and_write_s"], ".2f"),
                f(a.get("fixed_cpu_s"), ".2f"),
            ]
        )
    fl, fa = t["light"]["fit_ns_per_sample"], t["antishadow_exact"]["fit_ns_per_sample"]
    return [
        *table(
            [
                "N lamps",
                "light M samples/CPU-s",
                "light CPU ns/sample",
                "light cost vs N=1",
                "light wasted",
                "ax_exact M samples/CPU-s",
                "ax_exact CPU ns/sample",
                "ax_exact cost vs N=1",
                "ax_exact wasted",
                "load+write wall s",
                "fixed CPU s",
            ],
            rows,
        ),
        f"Fit CPU ns/sample = a + b N: light a = {f(fl['a'], '.0f')}, b = {f(fl['b_per_lamp'], '.2f')} ns/lamp; "
        f"antishadow_exact a = {f(fa['a'], '.0f')}, b = {f(fa['b_per_lamp'], '.2f')} ns/lamp. Marginal cost per "
        f"lamp between the two largest N: light {f(t['light'].get('marginal_ns_per_lamp'), '.2f')} ns, "
        f"antishadow_exact {f(t['antishadow_exact'].get('marginal_ns_per_lamp'), '.2f')} ns. The portal "
        "strategies find the light/portal pairs that may reach a point through a BVH over the pairs' lit "
        "regions (pair_bvh.c, O(log N + k)) and, with the irradiance weight, clip the visible polygon of each "
        "candidate whose antishadow contains the point (k, a fixed number here, set by the grid spacing: the "
        "cost that grows up to N ~ 100 and is flat after). `light` picks "
        "lamps from a global power table (O(1)) and only pays for the deeper BVH, but wastes almost every "
        "shadow ray at large N.",
        "",
    ]


def harness(d: dict[str, Any]) -> list[str]:
    rows = [
        [
            f"{s}x{s}",
            f(r["read_two_exr_ms"], ".1f"),
            f(r["metrics_ms"], ".1f"),
            f(r["total_ms"], ".1f"),
            f(r.get("portal_harness_total_ms"), ".1f"),
        ]
        for s, r in d["results"].items()
        if s != "sweep"
    ]
    out = table(["image", "read 2 EXR ms", "MSE+relMSE+noise ms", "total ms", "portal_harness path ms"], rows)
    sw = d["results"].get("sweep")
    if sw:
        out += [
            f"A sweep through the harness (`portal-harness sweep`, fresh results folder, one job): "
            f"{sw['renders']} renders (2 strategies x 2 ratios at {f(sw['run_time_s'], 'g')} s, 2 references "
            f"at {f(sw['reference_time_s'], 'g')} s, 256x256, snapshots every 0.25 s) took "
            f"{f(sw['sweep_wall_s'], '.1f')} s of wall time, {f(sw['render_s'], '.1f')} s of it rendering: "
            f"**{pct(sw['not_rendering_share'])} not spent rendering**, of which "
            f"{pct(sw['renderer_overhead_share'])} in the renderer processes outside their render time (start, "
            f"load, BVH build, snapshot pauses, final EXR write) and {pct(sw['harness_share'])} in the harness "
            "(Python start, EXR reading, metrics, index, summary).",
            "",
        ]
    return out


def dask(d: dict[str, Any]) -> list[str]:
    r = d["results"]
    return [
        f"The runs of one sweep ({r['runs']} runs of one thread, {r['spp']} spp each; `portal-harness sweep "
        f"--scheduler`, references already made) on a local Dask cluster of 1 and of 2 one-thread workers "
        f"({r['cores']} cores): {f(r['runs_on_1_workers_s'], '.1f')} s and {f(r['runs_on_2_workers_s'], '.1f')} s, "
        f"**{f(r['wall_ratio_2_to_1'], '.2f')} of the time on 2 workers** (ideal 0.50). The references, made "
        f"first on the client, took part of {f(r['local_with_references_s'], '.1f')} s with the runs: their "
        "extension runs on the client whatever the cluster.",
        "",
    ]


def eff_cell(r: dict[str, Any]) -> tuple[str, bool]:
    """Reference-based efficiency vs light, or its lower bound when unresolved."""
    e = r["eff_vs_light_cpu"]
    if not r["resolved"] or not math.isfinite(e):
        return f">{f(r['eff_vs_light_cpu_low'], '.3g')}*", False
    return f"{f(e, '.3g')} ±{pct(r['eff_vs_light_rel_se'])}", True


def _vs(a: dict[str, Any], b: dict[str, Any] | float, var: bool) -> str:
    """Three-way test of a >= b (b a row or a threshold on eff_vs_light):
    'pass', 'fail' (below by more than 2 standard errors), 'noise' (below,
    within 2 SE) or 'unresolved' (an estimate the reference cannot resolve
    and whose lower bound does not settle it)."""
    key = "eff_vs_light_cpu_var" if var else "eff_vs_light_cpu"
    if isinstance(b, dict):
        va, vb = a[key], b[key]
        if var:
            return "pass" if va >= vb else "fail"
        if not (a["resolved"] and b["resolved"]):
            return "unresolved"
        # light cancels in the ratio a / b: only a's and b's own errors count.
        rel = math.hypot(a["rel_mse_est_se"] / a["rel_mse_est"], b["rel_mse_est_se"] / b["rel_mse_est"])
    else:
        va, vb = a[key], b
        if var:
            return "pass" if va >= vb else "fail"
        if not a["resolved"] or not math.isfinite(va):
            return "pass" if a.get("eff_vs_light_cpu_low", math.nan) >= vb else "unresolved"
        rel = a["eff_vs_light_rel_se"]
    if va >= vb:
        return "pass"
    return "noise" if va * (1 + 2 * rel) >= vb else "fail"


def _all(results: list[str]) -> str:
    if not results:
        return "n/a"
    for word in ("fail", "unresolved", "noise"):
        if word in results:
            return {"fail": "FAIL", "unresolved": "UNRESOLVED", "noise": "PASS within noise (below by < 2 SE)"}[word]
    return "PASS"


def _targets(by_ratio: dict[str, dict[str, Any]], var: bool) -> str:
    t10 = [_vs(st["antishadow_exact"], 10.0, var) for r, st in by_ratio.items() if r == "4"]
    t1 = [_vs(st["antishadow_exact"], 1.0, var) for st in by_ratio.values()]
    ta = [_vs(st["antishadow"], st[o], var) for st in by_ratio.values() for o in ("projection", "portal")]
    return (
        f"antishadow_exact >= 10x light at ratio 4: {_all(t10)}; >= 1x at every ratio: {_all(t1)}; "
        f"antishadow >= projection and >= portal at every ratio: {_all(ta)}"
    )


def eff_cells(st: dict[str, Any]) -> tuple[list[str], bool]:
    cells, all_ok = [], True
    for s in SWEEP:
        c, ok = eff_cell(st[s])
        all_ok &= ok
        cells.append(c)
    return cells, all_ok


def efficiency(d: dict[str, Any]) -> list[str]:
    res = d["results"]
    rows, rows_var, rows_room = [], [], []
    unresolved = False
    for ratio, t in res.items():
        st = t["strategies"]
        cells, ok = eff_cells(st)
        unresolved |= not ok
        light = st["light"]
        rows.append(
            [
                ratio,
                f"{light['rel_mse_est']:.3g}",
                f"{t['reference']['spp']}",
                pct(light["ref_noise"] / light["rel_mse"]),
                *cells,
            ]
        )
        rows_var.append(
            [ratio] + [f"{f(st[s]['eff_vs_light_cpu_var'], '.3g')} (z {f(st[s]['bias_z'], '+.1f')})" for s in SWEEP]
        )
        room = t.get("crops", {}).get("room")
        if room:
            cells, ok = eff_cells(room["strategies"])
            unresolved |= not ok
            rows_room.append(
                [ratio, pct(1 - st["light"]["room_share"]), pct(1 - st["antishadow_exact"]["room_share"]), *cells]
            )
    p = d["params"]
    out = [
        f"Direct integrator, {p['time_s']} s per render (2 threads), reference `light` >= "
        f"{p['reference']['time_s_min']} s. Efficiency = 1 / (relMSE_est x CPU seconds), relative to `light` "
        "at the same ratio; ± is the standard error from the pixel spread. relMSE_est = relMSE against the "
        "reference - the reference's own noise (its variance layer).",
        "",
    ]
    out += table(["ratio s_L/s_P", "light relMSE_est", "ref spp", "ref noise / light relMSE", *SWEEP], rows)
    out.append(
        "Same runs, efficiency from each render's own variance layer (mean var_x / (ref^2 + 0.01)): "
        "low noise but blind to bias; z = (relMSE_est - that) / standard error, large positive z "
        "means bias or rare high-value samples the render has not met yet."
    )
    out.append("")
    out += table(["ratio", *SWEEP], rows_var)
    if rows_room:
        r0, r1 = next(iter(res.values()))["crops"]["room"]["rows"]
        out.append(
            f"Same runs, image rows {r0}-{r1 - 1} only (the room below the lamp: floor, walls, box), i.e. "
            "without the band where the camera looks up through the opening into the shade. Points in "
            "that band lie on the light's side of the portal plane: the portal strategies give them no "
            "light sample (only BSDF sampling), which is where most of their whole-image error sits."
        )
        out.append("")
        out += table(["ratio", "light error in the band", "antishadow_exact error in the band", *SWEEP], rows_room)
    if unresolved:
        out.append(
            "\\* the estimate is within 2 standard errors of zero (the reference's noise dominates): "
            "a lower bound only; a longer reference would resolve it."
        )
        out.append("")
    whole = {r: t["strategies"] for r, t in res.items()}
    out.append(f"Targets, whole image (reference-based): {_targets(whole, False)}.")
    out.append(f"Targets, whole image (variance-layer based): {_targets(whole, True)}.")
    if rows_room:
        room_by = {r: t["crops"]["room"]["strategies"] for r, t in res.items()}
        out.append(f"Targets, room rows only (reference-based): {_targets(room_by, False)}.")
    out.append("")
    return out


def wasted_rays(d: dict[str, Any]) -> list[str]:
    res = d["results"]
    out = ["Wasted = (blocked + missed) / (shadow rays + missed): light samples that deliver nothing.", ""]
    rows = [
        [k.split("/")[1], pct(r["wasted_fraction"]), pct(r["blocked_fraction"]), pct(r["missed_fraction"])]
        for k, r in res["lampshade_default"].items()
    ]
    out += table(["strategy (s_L = 0.6)", "wasted", "blocked", "missed"], rows)
    if "sweep" in res:
        strategies = list(next(iter(res["sweep"].values())).keys())
        rows = [
            [ratio] + [f"{pct(t[s]['wasted_fraction'])} ({pct(t[s]['blocked_fraction'])} b)" for s in strategies]
            for ratio, t in res["sweep"].items()
        ]
        out += table(["ratio"] + [f"{s} wasted (blocked)" for s in strategies], rows)
    return out


def micro(d: dict[str, Any]) -> list[str]:
    t = d["results"]["table"]
    names = list(t["floor"].keys())
    rows = [
        [
            n,
            f(t["floor"][n]["ns"], ".0f"),
            f(t["floor"][n]["per_shadow_ray"], ".2f"),
            f(t["antishadow"][n]["ns"], ".0f"),
            f(t["antishadow"][n]["per_shadow_ray"], ".2f"),
        ]
        for n in names
    ]
    regions = d["results"]["raw"]["sets"]["floor"]["regions"]
    ngon_rows = [
        [
            str(g["n"]),
            g["variant"],
            f(g["sets"]["floor"]["classify_ns"], ".1f"),
            f(g["sets"]["floor"]["prepare_sample_ns"], ".0f"),
            f(g["sets"]["antishadow"]["classify_ns"], ".1f"),
            f(g["sets"]["antishadow"]["prepare_sample_ns"], ".0f"),
        ]
        for g in d["results"]["raw"].get("ngon", [])
    ]
    ngon = [
        "",
        "The same cells with the portal (or the light and the portal) replaced by a regular n-gon of the same "
        "area (micro.c, `ngon`): ns per `antishadow_classify` and per `antishadow_exact` prepare + sample.",
        "",
        *table(
            ["n", "replaced", "floor classify", "floor sample", "antishadow classify", "antishadow sample"],
            ngon_rows,
        ),
    ]
    return [
        f"Thread CPU ns per call; floor points uniform over the floor (regions: {regions}); antishadow points "
        "= floor points not outside.",
        "",
        *table(["cell", "floor ns", "floor x shadow ray", "antishadow ns", "antishadow x shadow ray"], rows),
        *(ngon if ngon_rows else []),
    ]


def portal_weights(d: dict[str, Any]) -> list[str]:
    r = d["results"]
    rows = []
    for name, v in r["variants"].items():
        cell, _ = eff_cell(v)
        rows.append(
            [
                name,
                f(v["rel_mse_est"], ".3g"),
                f(v["spp"], "d"),
                cell,
                f"{f(v['eff_vs_light_cpu_var'], '.3g')} (z {f(v['bias_z'], '+.1f')})",
                pct(v["wasted_fraction"]),
            ]
        )
    return [
        f"multi_lamp.yaml, direct, {d['params']['time_s']} s per render, reference `light` "
        f"{r['reference']['spp']} spp.",
        "",
        *table(
            [
                "variant",
                "relMSE_est",
                "spp",
                "eff vs light (reference)",
                "eff vs light (variance layer)",
                "wasted shadow rays",
            ],
            rows,
        ),
    ]


def mesh_load(d: dict[str, Any]) -> list[str]:
    p, r = d["params"], d["results"]
    pc, st = r["print_config"], r["stages"]
    rows = [
        ["render --print-config (whole)", f(pc["wall_s"], ".2f"), f(pc["cpu_s"], ".2f"), f(pc["max_rss_mb"], ".0f")],
        [
            "config_load (YAML + PLY via assimp + checks)",
            f(st["config_load"]["wall_s"], ".2f"),
            f(st["config_load"]["cpu_s"], ".2f"),
            f(st["peak_rss_mb_after_load"], ".0f"),
        ],
        ["watertight_stitch", f(st["watertight"]["wall_s"], ".2f"), f(st["watertight"]["cpu_s"], ".2f"), ""],
        [
            "scene_create (stitch + Embree BVH + lights)",
            f(st["scene_create"]["wall_s"], ".2f"),
            f(st["scene_create"]["cpu_s"], ".2f"),
            f(st["peak_rss_mb"], ".0f"),
        ],
    ]
    load_ok = st["config_load"]["cpu_s"] <= p["target_s"]
    return [
        f"{p['triangles']:,} triangles ({p['vertices']:,} vertices, {p['bytes'] / 1e6:.1f} MB), {p['mesh']}; "
        f"median of {p['rounds']}. Target: loading takes at most about {p['target_s']:g} s "
        f"(config_load CPU: {verdict(load_ok)}). Peak RSS is of the whole process up to that stage.",
        "",
        *table(["stage", "wall s", "CPU s", "peak RSS MB"], rows),
    ]


def mesh_lights(d: dict[str, Any]) -> list[str]:
    p, t = d["params"], d["results"]["table"]
    rows = [
        [
            key.split("/")[0],
            key.split("/")[1],
            f(row["ns_per_sample"], ".0f"),
            f(row["cost_vs_light_cpu"]["median"], ".2f"),
            f(row["wasted_fraction"], ".2f"),
        ]
        for key, row in t.items()
    ]
    return [
        f"{p['integrator']}, {p['spp']} spp, {p['threads']} thread, median of {p['reps']} rounds; "
        "bulb_N: the lampshade with an N-triangle sphere bulb behind its opening. "
        "The cost of a sample must not grow with the bulb's triangles.",
        "",
        *table(["scene", "strategy", "ns / sample (render CPU)", "cost vs light", "wasted shadow rays"], rows),
    ]


def _range(r: dict[str, Any], spec: str = ".2f") -> str:
    return f"{f(r['median'], spec)} ({f(r['min'], spec)}-{f(r['max'], spec)})"


def _spp(by_key: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in by_key.items()) + " spp"


def mitsuba(d: dict[str, Any]) -> list[str]:
    p, res = d["params"], d["results"]
    t, info = res["table"], res["mitsuba"]
    rows = [
        [
            integ,
            mega(r["ours_samples_per_s"]),
            mega(r.get("ours_steady_samples_per_s", r["ours_samples_per_s"])),
            mega(r["mitsuba_first_samples_per_s"]),
            f"{f(r['mitsuba_first_wall_s'], '.2f')} ({f(r['mitsuba_first_compile_s'], '.2f')})",
            mega(r["mitsuba_steady_samples_per_s"]),
            _range(r["ratio"]),
            _range(r.get("ratio_whole_render", r["ratio"])),
            _range(r["ratio_vs_first_pass"]),
            f"{mega(r.get('ours_steady_samples_per_cpu_s', r['ours_samples_per_cpu_s']))} / "
            f"{mega(r['mitsuba_steady_samples_per_cpu_s'])}",
            _range(r["ratio_cpu"]),
            f"{f(r.get('ours_steady_cores', r['ours_cores']), '.2f')} / {f(r['mitsuba_steady_cores'], '.2f')}",
        ]
        for integ, r in t.items()
    ]
    target = p["targets"]["light_vs_mitsuba"]
    cost_target = p["targets"]["antishadow_exact_cost"]
    verdicts = [
        f"Target `light` >= {target:g}x Mitsuba {info.get('variant')} (steady state, samples/s), {integ}: "
        f"{_range(r['ratio'])} -> {verdict(r['ratio']['median'] >= target)}"
        for integ, r in t.items()
    ]
    cost_rows = [
        [
            name,
            mega(c["light_samples_per_s"]),
            mega(c["antishadow_exact_samples_per_s"]),
            _range(c["cost_cpu"]),
            _range(c["cost_wall"]),
            verdict(c["cost_cpu"]["median"] <= cost_target),
        ]
        for name, c in res["cost"].items()
    ]
    # Mitsuba with its Embree scene robust too (ours always is): runs from
    # before that measurement have none.
    robust_rows = [
        f"{integ} {_range(r['ratio_vs_robust'])} (Mitsuba {mega(r['mitsuba_robust_steady_samples_per_s'])} M/s)"
        for integ, r in t.items()
        if "ratio_vs_robust" in r
    ]
    robust = (
        [
            "Against Mitsuba with `embree_use_robust_intersections` (RTC_SCENE_FLAG_ROBUST, the traversal our "
            "renderer always uses; Mitsuba's default is the faster, not watertight one), steady/steady, same "
            "rounds: " + "; ".join(robust_rows) + ".",
            "",
        ]
        if robust_rows
        else []
    )
    integs = info.get("integrators", {})
    busy_seen = sorted(
        {str(m.get("busy_threads")) for runs in res["runs"]["mitsuba"].values() for m in runs if "busy_threads" in m}
    )
    cores = [c for r in t.values() for c in (r["ours_cores"], r["mitsuba_steady_cores"])]
    busy = (
        [
            f"**Busy machine**: the renders got {f(min(cores), '.2f')}-{f(max(cores), '.2f')} of their 2 cores, "
            "so the wall-clock rates and ratios above are mostly the other work's; the ratio per CPU-second is "
            "the better estimate of the undisturbed ratio (it assumes both scale alike to 2 threads).",
            "",
        ]
        if cores and min(cores) < 1.5
        else []
    )
    return [
        f"Lampshade 256x256, 2 threads each, {p['rounds']} rounds alternating who goes first, medians (range "
        f"over rounds). Ours: `render` with `light`, {_spp(p['ours']['spp'])}, samples/s from its final JSON line "
        "(render time); steady = a second render with as many more samples as Mitsuba's steady passes draw, the "
        "extra samples over the extra time, so that what both renders share (the threads' start, the first "
        "passes, which run at about half speed here for ~0.1 s) drops out as Mitsuba's first pass does. "
        f"Mitsuba {info.get('mitsuba')} (Dr.Jit {info.get('drjit')}, {info.get('variant')}, "
        f"{info.get('threads')} threads"
        + (f", threads that ran the passes: {'/'.join(busy_seen)}" if busy_seen else "")
        + f", LLVM {info.get('libllvm')}): {p['mitsuba']['passes']} passes of "
        f"{_spp(p['mitsuba']['spp_per_pass'])} per round, each mi.render evaluated and synchronised; the first "
        "pass compiles its kernels into an empty cache (in brackets: Dr.Jit's codegen + LLVM time of it), "
        "steady = the later passes. Integrators: "
        + "; ".join(f"{k} {json.dumps(v)}" for k, v in integs.items())
        + " (ours: max_depth 8 bounces, the same Russian roulette).",
        "",
        *table(
            [
                "integrator",
                "ours M samples/s, whole render",
                "ours steady M samples/s",
                "Mitsuba first pass M samples/s",
                "first pass s (compile s)",
                "Mitsuba steady M samples/s",
                "ratio steady/steady",
                "ratio ours whole render/Mitsuba steady",
                "ratio ours whole render/Mitsuba first pass",
                "M samples/CPU-s steady, ours / Mitsuba",
                "ratio per CPU-s",
                "cores used steady, ours / Mitsuba",
            ],
            rows,
        ),
        *(v + "." for v in verdicts),
        "",
        *robust,
        f"`antishadow_exact` cost per sample relative to `light`, direct, 2 threads, {_spp(p['cost']['spp'])}, same "
        f"rounds (CPU = render threads' CPU time per sample; wall = render time per sample). Target <= "
        f"{cost_target:g}x (CPU):",
        "",
        *table(
            ["scene", "light M samples/s", "ax_exact M samples/s", "cost CPU", "cost wall", f"<= {cost_target:g}x"],
            cost_rows,
        ),
        "'Cores used' = CPU time / wall time of the passes: below 2 the machine ran other work as well. The "
        "ratios pair runs of the same round, made seconds apart, so load shared by both cancels.",
        "",
        *busy,
    ]


def time_split(d: dict[str, Any]) -> list[str]:
    p, t = d["params"], d["results"]["table"]
    rows = []
    for integ, r in t.items():
        for who in ("ours", "mitsuba"):
            x = r[who]
            rows.append(
                [
                    integ,
                    who,
                    f(x["cpu_ns_per_sample"], ".0f"),
                    f(x["embree_ns_per_sample"], ".0f"),
                    f(x["own_ns_per_sample"], ".0f"),
                    f"{f(x['embree_pct'], '.1f')} / {f(x['own_pct'], '.1f')} / {f(x['other_pct'], '.1f')}",
                ]
            )
        rows.append(
            [
                integ,
                "ours / Mitsuba",
                _range(r["ratio_cpu_ns_per_sample"]),
                _range(r["ratio_embree_ns_per_sample"]),
                _range(r["ratio_own_ns_per_sample"]),
                "",
            ]
        )
    return [
        f"Lampshade, 1 thread each, {_spp(p['spp'])} (Mitsuba: {p['mitsuba_passes']} passes of that, the first "
        f"compiling), {p['rounds']} round(s), medians (range over rounds); ours `light`. Each run is sampled by "
        "`perf record`, and its CPU time per sample (ours: the render threads'; Mitsuba: its steady passes') is "
        "split by the shares of the perf samples that fell in Embree and in the renderer's own code "
        "(renderer/bench/time_split.py; Mitsuba's own code is its JIT-compiled kernels and Dr.Jit). Both "
        "renderers trace with Embree 3, so the columns say on which side of the Embree call a gap is.",
        "",
        *table(
            [
                "integrator",
                "renderer",
                "CPU ns / sample",
                "in Embree",
                "in own code",
                "% of perf samples: Embree / own / other",
            ],
            rows,
        ),
        "'Other' (not rendering: Python and LLVM for Mitsuba, loading and EXR writing for ours) is left out of "
        "the split. One thread, so the numbers differ from section 14's two-thread rates.",
        "",
        "Our own code by function, CPU ns per sample (median over rounds; libc and libm, which count as own "
        "code above, are not in the list):",
        "",
        *table(["function", *t], fn_rows(t)),
        "",
        *time_split_cost(p, d["results"].get("cost")),
    ]


def time_split_cost(p: dict[str, Any], c: dict[str, Any] | None) -> list[str]:
    """time_split's multi_lamp part: antishadow_exact's extra time by function."""
    if c is None:
        return []
    by = c["by_strategy"]
    rows = [
        [s, f(x["cpu_ns_per_sample"], ".0f"), f(x["embree_ns_per_sample"], ".0f"), f(x["own_ns_per_sample"], ".0f")]
        for s, x in by.items()
    ]
    fn = [
        [f"`{n}`", f(v["light"], ".1f"), f(v["antishadow_exact"], ".1f"), f(v["antishadow_exact"] - v["light"], "+.1f")]
        for n, v in c["functions_ns_per_sample"].items()
    ]
    return [
        f"`multi_lamp`, direct, 1 thread, {c['spp']} spp, same rounds: `antishadow_exact` takes "
        f"{_range(c['ratio_cpu_ns_per_sample'])} of `light`'s CPU time per sample (issue 17's goal: <= 1.15x, "
        "section 14 measures it at two threads).",
        "",
        *table(["strategy", "CPU ns / sample", "in Embree", "in own code"], rows),
        "The functions that add the most to `antishadow_exact`'s sample, CPU ns per sample (median over rounds):",
        "",
        *table(["function", "light", "antishadow_exact", "difference"], fn),
        "",
    ]


def fn_rows(t: dict[str, Any]) -> list[list[str]]:
    """time_split's per-function table: one row per function in any
    integrator's list, then the rest of each list."""
    names: list[str] = []
    for r in t.values():
        names += [n for n in r.get("ours_functions_ns_per_sample", {}) if n not in names]
    rows = [[f"`{n}`", *(f(r["ours_functions_ns_per_sample"].get(n), ".1f") for r in t.values())] for n in names]
    rows.append(["(the others)", *(f(r.get("ours_other_functions_ns_per_sample"), ".1f") for r in t.values())])
    return rows


def _speedup(r: dict[str, Any]) -> str:
    """An equal-error speed-up over rounds: the median (range), or a lower
    bound where the reference did not resolve every round."""
    if not r["resolved"]:
        return f">= {f(r['low'], '.2f')}\\*"
    return _range(r)


def mitsuba_efficiency(d: dict[str, Any]) -> list[str]:
    p, res = d["params"], d["results"]
    info = res["mitsuba"]
    rows = []
    footnote = False
    for c in res["cases"].values():
        t = c["table"]
        m = t["mitsuba"]
        for s in p["ours"]["strategies"]:
            o = t[s]
            footnote |= not (o["vs_mitsuba_cpu"]["resolved"] and o["vs_mitsuba_wall"]["resolved"])
            rows.append(
                [
                    c["integrator"],
                    f"{c['ratio']:g}",
                    f"`{s}`",
                    f"{f(o['rel_mse_est'])} ({f(o['spp'], '.0f')} spp)",
                    f"{f(m['rel_mse_est'])} ({f(m['spp'], '.0f')} spp)",
                    _speedup(o["vs_mitsuba_cpu"]),
                    _speedup(o["vs_mitsuba_wall"]),
                    _speedup(o["vs_mitsuba_per_sample"]),
                    "yes" if m["consistent"] else "**no**",
                ]
            )
    header = [
        "integrator",
        "ratio s_L/s_P",
        "ours",
        "ours relMSE_est",
        "Mitsuba relMSE_est",
        "speed-up per CPU-s",
        "speed-up per wall-s",
        "per sample",
        "Mitsuba agrees with the reference",
    ]
    lines = [
        f"Lampshade 256x256, {p['time_s']:g} s per render on {p['threads']} threads, {p['rounds']} rounds (who goes "
        f"first rotating), medians (range over rounds). Mitsuba {info.get('mitsuba')} ({info.get('variant')}): its "
        "steady passes (after the compiling first one) until they took as long, their mean image. Both against one "
        f"reference, ours with `light` for >= {p['reference']['time_s_min']:g} s. Speed-up = (Mitsuba's relMSE_est "
        "x seconds) / ours: how many times less time ours needs for the same error (> 1: ours converges faster). "
        "Per sample: the same with samples per pixel for seconds. Mitsuba agrees: its error against our reference "
        "is its own noise in every round (bias_z <= 4).",
        "",
        *table(header, rows),
    ]
    if footnote:
        lines += [
            "\\* a round's error is within 2 standard errors of the reference's noise: a lower bound only.",
            "",
        ]
    return lines


SECTIONS: list[tuple[str, str, Callable[[dict[str, Any]], list[str]]]] = [
    ("raw_embree", "1. Raw Embree limit (lampshade)", raw_embree),
    ("throughput", "2, 5. Renderer throughput and strategy cost", throughput),
    ("threads", "3. Thread scaling", threads),
    ("snapshots", "4. Snapshot overhead", snapshots),
    ("scene_scaling", "6. Scaling with the number of lamps", scene_scaling),
    ("harness", "7. Harness overhead", harness),
    ("dask", "7b. A sweep on 1 and 2 Dask workers", dask),
    ("efficiency", "8. Efficiency on the lampshade sweep", efficiency),
    ("wasted_rays", "9. Wasted shadow rays", wasted_rays),
    ("micro", "10. Per-call cost vs one shadow ray (micro.c)", micro),
    ("portal_weights", "11. Portal weight heuristics (multi_lamp, antishadow_exact)", portal_weights),
    ("mesh_load", "12. Loading a 1M-triangle PLY (mesh_load.c)", mesh_load),
    ("mesh_lights", "13. Mesh lights: cost per sample (Little Lamp, 16 vs 1,000 triangles)", mesh_lights),
    ("mitsuba", "14. Against Mitsuba 3 (llvm_ad_rgb), and antishadow_exact's cost per sample", mitsuba),
    ("time_split", "15. Where the time goes: Embree vs the renderer's own code (perf, vs Mitsuba)", time_split),
    ("mitsuba_efficiency", "16. Equal-time error against Mitsuba 3 (llvm_ad_rgb)", mitsuba_efficiency),
]


def main() -> int:
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else RESULTS
    lines = ["# Benchmark summary", ""]
    meta = None
    for name, title, fn in SECTIONS:
        path = results / f"{name}.json"
        lines.append(f"## {title}")
        lines.append("")
        if not path.exists():
            lines += ["(not run)", ""]
            continue
        d = json.loads(path.read_text())
        meta = meta or d
        try:
            lines += fn(d)
        except (KeyError, TypeError, ValueError, StopIteration) as e:
            lines += [f"(cannot summarise {path.name}: {type(e).__name__} {e})", ""]
        lines.append(
            f"<sub>{path.name}: {d['date']}, {'quick' if d['quick'] else 'full'}, "
            f"load {d['machine'].get('loadavg_1_5_15')}</sub>"
        )
        lines.append("")
    if meta:
        m = meta["machine"]
        head = [
            f"Renderer {meta['renderer_version']} ({meta['renderer']}), suite started {meta['suite_started']}, "
            f"{'quick (BENCH_QUICK=1)' if meta['quick'] else 'full'} run.",
            f"Machine: {m['nproc']} CPUs, {m['cpu_model']}, Embree {m.get('embree_version', m['embree_package'])}, "
            f"load average at start {m['loadavg_1_5_15']}. See NOTEBOOK.md for how to read the numbers.",
            "",
        ]
        lines[2:2] = head
    text = "\n".join(lines)
    (results / "summary.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
