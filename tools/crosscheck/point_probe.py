#!/usr/bin/env python3
"""Direct light at the surface point seen through one pixel: an independent
quadrature, our renderer and Mitsuba, each zoomed onto that point.

For a run folder of mitsuba_lampshade.py (OUT, with OUT/ours/config.yaml), the
camera ray through the centre of pixel (X, Y) finds a surface point p (with
Mitsuba's ray caster, on the scene the cross-check gives Mitsuba). Then:

- quadrature: the direct light reflected at p towards the camera, from every
  polygon light, by stratified uniform area sampling of each light (N x N
  jittered samples per fan triangle) and a shadow ray each, traced by
  Mitsuba. The shadow ray's origin follows one of three models:
  `exact` (1e-6 along the normal: only true occluders count), `mitsuba`
  (Mitsuba 3's spawn_ray_to: 8.9e-5 (1 + max |p|) along the normal, the far
  end shortened by 8.9e-4 of the length) and `ours` (our
  scene_offset_step: moved along the ray by eps / max(|cos|, 1e-3),
  eps = 1e-5 x scene diagonal + 1e-6 max |p|, at both ends);
- ours and Mitsuba: each renders a 4x4 film with a 0.002 degree field of
  view looking at p from our camera position (a footprint of about 0.1 mm),
  with the strategy and spp given.

Used to find out which renderer is right where the cross-check shows a
difference (tools/crosscheck/README.md, "The mesh scene"). Polygon lights and
diffuse materials only; the direct integrator.

    .venv-xcheck/bin/python tools/crosscheck/point_probe.py results/tmp/crosscheck/close_light --pixel 130 40
"""

from __future__ import annotations

import argparse
import copy
import math
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import mitsuba_lampshade as xcheck

MODELS = ("exact", "mitsuba", "ours")
Vec = tuple[float, float, float]


def _sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _madd(a: Vec, d: Vec, t: float) -> Vec:
    return (a[0] + d[0] * t, a[1] + d[1] * t, a[2] + d[2] * t)


def _norm(a: Vec) -> float:
    return math.sqrt(_dot(a, a))


def scene_diagonal(cfg: dict[str, Any]) -> float:
    """Our scene's `scale` (scene.c): the diagonal of the bounding box of the
    inline shapes' and lights' points (file meshes are inside the room here)."""
    pts = [v for s in cfg.get("shapes") or [] for v in s.get("vertices") or []]
    pts += [v for light in cfg.get("lights") or [] for v in light.get("vertices") or []]
    lo = [min(float(p[i]) for p in pts) for i in range(3)]
    hi = [max(float(p[i]) for p in pts) for i in range(3)]
    return math.sqrt(sum((h - lo_) ** 2 for h, lo_ in zip(hi, lo, strict=True)))


def quadrature(
    scene: Any, cfg: dict[str, Any], offset: list[float], p: Vec, n: Vec, albedo: list[float], model: str, k: int
) -> list[float]:
    """Reflected radiance at p (Mitsuba coordinates, n towards the camera)
    from all polygon lights, k x k jittered samples per fan triangle."""
    import mitsuba as mi
    import numpy as np

    rng = np.random.default_rng(7)
    eps_ours = 1e-5 * scene_diagonal(cfg)
    out = [0.0, 0.0, 0.0]
    off: Vec = (offset[0], offset[1], offset[2])
    pw = _madd(p, off, 1.0)
    for light in cfg.get("lights") or []:
        verts: list[Vec] = [
            (float(v[0]) - off[0], float(v[1]) - off[1], float(v[2]) - off[2]) for v in light["vertices"]
        ]
        radiance = [float(x) for x in light["radiance"]]
        for t in range(1, len(verts) - 1):
            a, b, c = verts[0], verts[t], verts[t + 1]
            cr = _cross(_sub(b, a), _sub(c, a))
            area = 0.5 * _norm(cr)
            nl: Vec = (cr[0] / (2 * area), cr[1] / (2 * area), cr[2] / (2 * area))
            jit = rng.random((k, k, 2))
            total = 0.0
            for i in range(k):
                for j in range(k):
                    u1, u2 = (i + jit[i, j, 0]) / k, (j + jit[i, j, 1]) / k
                    su = math.sqrt(u1)  # uniform on the triangle
                    q = _madd(_madd(a, _sub(b, a), su * (1 - u2)), _sub(c, a), su * u2)
                    e = _sub(q, p)
                    r = _norm(e)
                    d: Vec = (e[0] / r, e[1] / r, e[2] / r)
                    cos_p, cos_l = _dot(n, d), -_dot(nl, d)
                    if cos_p <= 0.0 or cos_l <= 0.0:
                        continue
                    if model == "ours":
                        qw = _madd(q, off, 1.0)
                        s0 = (eps_ours + 1e-6 * max(abs(x) for x in pw)) / max(cos_p, 1e-3)
                        s1 = (eps_ours + 1e-6 * max(abs(x) for x in qw)) / max(cos_l, 1e-3)
                        o, dd, tmax = _madd(p, d, s0), d, r - s0 - s1
                    else:
                        lift = 1e-6 if model == "exact" else 8.9e-5 * (1 + max(abs(x) for x in p))
                        o = _madd(p, n, lift)
                        e2 = _sub(q, o)
                        r2 = _norm(e2)
                        dd = (e2[0] / r2, e2[1] / r2, e2[2] / r2)
                        tmax = r2 * (1 - 1e-5 if model == "exact" else 1 - 8.9e-4)
                    if tmax <= 0.0:
                        continue
                    ray = mi.Ray3f(o, dd)
                    ray.maxt = tmax  # Ray3f(o, d, x) would take x as the time
                    if not scene.ray_test(ray):
                        total += cos_p * cos_l / (r * r)
            for ch in range(3):
                out[ch] += radiance[ch] * albedo[ch] / math.pi * total * area / (k * k)
    return out


def zoom_cfg_sets(p_world: Vec) -> list[str]:
    sets = [f"camera.look_at.{i}={p_world[i]!r}" for i in range(3)]
    return [*sets, "camera.fov_y=0.002", "film.width=4", "film.height=4"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run", type=Path, help="a mitsuba_lampshade.py output folder (OUT)")
    p.add_argument("--pixel", type=int, nargs=2, required=True, metavar=("X", "Y"), help="row 0 at the top")
    p.add_argument("--samples", type=int, default=300, help="k: k x k quadrature samples per light triangle")
    p.add_argument("--models", nargs="+", choices=MODELS, default=list(MODELS))
    p.add_argument("--spp", type=int, default=65536, help="spp of the zoomed renders (0: none)")
    p.add_argument("--strategy", default="light", help="our strategy for the zoomed render")
    args = p.parse_args(argv)
    xcheck.ensure_mitsuba()
    import mitsuba as mi
    import numpy as np
    import yaml

    from portal_harness.core import exr

    mi.set_variant("scalar_rgb")
    ours_dir = args.run / "ours"
    cfg = yaml.safe_load((ours_dir / "config.yaml").read_text())
    offset = xcheck.recentre_offset(cfg)
    tmp = Path(tempfile.mkdtemp(prefix="point_probe_"))
    scene_dict = xcheck.build_scene_dict(cfg, {"type": "direct"}, tmp / "meshes", 1, offset)
    scene = mi.load_dict(scene_dict, optimize=False)
    sensor = scene.sensors()[0]
    w, h = (int(v) for v in sensor.film().size())
    x, y = args.pixel
    ray, _ = sensor.sample_ray(0.0, 0.0, mi.Point2f((x + 0.5) / w, (y + 0.5) / h), mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    if not si.is_valid():
        print(f"pixel {x} {y}: the camera ray leaves the scene", file=sys.stderr)
        return 2
    pt: Vec = (float(si.p[0]), float(si.p[1]), float(si.p[2]))
    nrm: Vec = (float(si.n[0]), float(si.n[1]), float(si.n[2]))
    if _dot(nrm, (float(ray.d[0]), float(ray.d[1]), float(ray.d[2]))) > 0:
        nrm = (-nrm[0], -nrm[1], -nrm[2])
    key = si.shape.id()
    names = {f"shape_{i:02d}_{s['name']}": s for i, s in enumerate(cfg.get("shapes") or [])}
    if key not in names:
        print(f"pixel {x} {y}: sees {key}, not a shape", file=sys.stderr)
        return 2
    albedo = [float(v) for v in cfg["materials"][names[key]["material"]]["albedo"]]
    p_world = _madd(pt, (offset[0], offset[1], offset[2]), 1.0)
    print(f"pixel ({x}, {y}): {names[key]['name']} at {tuple(round(v, 5) for v in p_world)}, normal {nrm}")
    for model in args.models:
        value = quadrature(scene, cfg, offset, pt, nrm, albedo, model, args.samples)
        print(f"  quadrature, shadow-ray origin '{model}': " + " ".join(f"{v:.6g}" for v in value))
    if args.spp > 0:
        cmd = [str(xcheck.ROOT / "renderer" / "build" / "render"), str(ours_dir / "config.yaml")]
        cmd += ["--out", str(tmp / "ours"), "--spp", str(args.spp), "--strategy", args.strategy, "--quiet"]
        cmd += ["--set", "render.time=0", "--set", "render.snapshots.every=1e9"]
        for s in zoom_cfg_sets(p_world):
            cmd += ["--set", s]
        subprocess.run(cmd, check=True, capture_output=True)
        snap = exr.read_snapshot(tmp / "ours" / "final.exr")
        mean, sigma = snap.rgb.mean(axis=(0, 1)), np.sqrt(snap.variance.sum(axis=(0, 1))) / 16
        print(
            f"  ours ({args.strategy}, {args.spp} spp): "
            + " ".join(f"{m:.6g}+-{s:.2g}" for m, s in zip(mean, sigma, strict=True))
        )
        zoomed = copy.deepcopy(cfg)
        zoomed["camera"]["look_at"] = list(p_world)
        zoomed["camera"]["fov_y"] = 0.002
        zoomed["film"] = {"width": 4, "height": 4}
        runs, each = 16, max(args.spp // 16, 1)
        integ = {"type": "direct", "emitter_samples": 1, "bsdf_samples": 1}
        sd = xcheck.build_scene_dict(zoomed, integ, tmp / "meshes_zoom", each, offset)
        imgs, _, _ = xcheck.render_mitsuba(sd, runs, each, 1000)
        per_run = imgs.mean(axis=(1, 2))
        mean, sigma = per_run.mean(axis=0), per_run.std(axis=0, ddof=1) / math.sqrt(runs)
        print(
            f"  mitsuba ({runs} x {each} spp): "
            + " ".join(f"{m:.6g}+-{s:.2g}" for m, s in zip(mean, sigma, strict=True))
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
