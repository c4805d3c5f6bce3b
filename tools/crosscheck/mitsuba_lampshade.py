#!/usr/bin/env python3
"""Independent-renderer cross-check: our renderer against Mitsuba 3.

Renders the lampshade scene (configs/scenes/lampshade.yaml, or --scene, e.g.
lampshade_mesh.yaml with a mesh from a PLY file, or
tests/configs/good/mesh_light_sphere.yaml with a mesh light) with our
renderer, rebuilds the same scene for Mitsuba 3 (variant scalar_rgb) from
the EFFECTIVE config our renderer wrote (OUT/ours/config.yaml), renders it
K times with independent seeds, and compares the two images block by block:

    z = (ours_block - mitsuba_block) / sqrt(var_ours_block + var_mitsuba_block)

over 8x8 pixel blocks and the three channels. var_ours comes from our EXR's
variance layer (variance of the pixel mean); var_mitsuba from the spread of the
K independent Mitsuba renders. The run fails (exit 1) when max |z| exceeds the
two-sided Bonferroni bound for an overall false-alarm rate --alpha over all
block-channel tests.
Each mesh shape read from a file is also reported on its own (the blocks it
covers, and the ratio ours/Mitsuba over the pixels that see it).

Mitsuba lives in its own venv (.venv-xcheck at the repository root); when the
running interpreter cannot import it, the script re-executes itself there.

Exit status: 0 agreement within noise, 1 disagreement, 2 usage/setup error.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import struct
import subprocess
import sys
import time
import zlib
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from obj_to_ply import write_ply  # the same directory: a script's sys.path[0]

if TYPE_CHECKING:  # annotations only: the module imports the standard library alone
    import numpy as np

    from portal_harness.core.exr import Snapshot

ROOT = Path(__file__).resolve().parents[2]
XCHECK_VENV = ROOT / ".venv-xcheck"
DEFAULT_SCENE = ROOT / "configs" / "scenes" / "lampshade.yaml"
REEXEC_GUARD = "PORTAL_XCHECK_REEXEC"


def ensure_mitsuba() -> None:
    """Import mitsuba here, or re-run this script with the .venv-xcheck python."""
    if importlib.util.find_spec("mitsuba") is not None:
        return
    python = XCHECK_VENV / "bin" / "python"
    if python.exists() and os.environ.get(REEXEC_GUARD) != "1":
        env = dict(os.environ, **{REEXEC_GUARD: "1"})
        os.execve(str(python), [str(python), str(Path(__file__).resolve()), *sys.argv[1:]], env)
    sys.stderr.write(
        f"mitsuba is not importable and {XCHECK_VENV} has no working python with it.\n"
        f"Create it with:  python3 -m venv {XCHECK_VENV} && {XCHECK_VENV}/bin/pip install mitsuba pytest -e harness\n"
    )
    sys.exit(2)


FLOAT_REL_TOL = 1e-5


class SetupError(Exception):
    """Anything that prevents the comparison from being made (exit 2)."""


# ---------------------------------------------------------------------------
# Command line


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    default_renderer = ROOT / "renderer" / "build" / "render"
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", type=Path, default=DEFAULT_SCENE, help="scene YAML (default: lampshade)")
    p.add_argument("--renderer", type=Path, default=default_renderer, help="our render binary")
    p.add_argument("--integrator", choices=("direct", "path"), default="direct")
    p.add_argument(
        "--s-L", dest="s_L", type=float, default=None, help="params.s_L override (default: the scene's value)"
    )
    p.add_argument("--ours-spp", type=int, default=1024)
    p.add_argument("--mitsuba-spp", type=int, default=1024, help="total Mitsuba spp over all runs")
    p.add_argument(
        "--mitsuba-runs",
        type=int,
        default=32,
        help="K independent Mitsuba renders of mitsuba-spp/K spp each (variance estimate)",
    )
    p.add_argument(
        "--max-depth",
        type=int,
        default=3,
        help="path only: our render.max_depth N (bounces); Mitsuba gets max_depth N+1",
    )
    p.add_argument(
        "--rr-depth",
        type=int,
        default=5,
        help="path only: Russian roulette depth, ours render.rr_depth and Mitsuba rr_depth",
    )
    p.add_argument("--strategy", default="light", help="our sampling strategy")
    p.add_argument("--threads", default="2", help="our render threads")
    p.add_argument("--seed", type=int, default=1, help="our seed; Mitsuba uses seed*1000+k")
    p.add_argument("--block", type=int, default=8, help="block side in pixels")
    p.add_argument("--alpha", type=float, default=1e-3, help="overall false-alarm rate of the bound")
    p.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="extra --set override for our renderer (e.g. film.width=64); Mitsuba follows through the effective config",
    )
    p.add_argument(
        "--reuse-ours", action="store_true", help="reuse OUT/ours/final.exr if present instead of rendering again"
    )
    p.add_argument(
        "--no-recentre",
        action="store_true",
        help="render Mitsuba's scene at our coordinates instead of moved so that the "
        "lights' centroid is at the origin (float32 ray offsets; see README)",
    )
    p.add_argument(
        "--mitsuba-cache",
        type=Path,
        default=None,
        metavar="FILE.npz",
        help="reuse Mitsuba's K renders from this file when scene, integrator, spp, runs "
        "and seed match (e.g. to compare several of our strategies); else render "
        "and store them there",
    )
    p.add_argument(
        "--out", type=Path, default=None, help="output folder (default results/tmp/crosscheck/<integrator>_sL<s_L>)"
    )
    args = p.parse_args(argv)
    if args.mitsuba_runs < 2 or args.mitsuba_spp % args.mitsuba_runs != 0:
        p.error("--mitsuba-runs must be >= 2 and divide --mitsuba-spp")
    if args.ours_spp < 2:
        p.error("--ours-spp must be >= 2 (the variance layer needs two samples)")
    if args.max_depth < 1:
        p.error("--max-depth must be >= 1")
    if args.out is None:
        tag = "scene" if args.s_L is None else f"sL{args.s_L:g}"
        args.out = ROOT / "results" / "tmp" / "crosscheck" / (f"{args.integrator}_{tag}")
    return args


# ---------------------------------------------------------------------------
# Our renderer


def ours_command(args: argparse.Namespace, out_dir: Path) -> list[str]:
    """Our renderer's command line for these options (also the key of --reuse-ours)."""
    cmd = [
        str(args.renderer),
        str(args.scene),
        "--out",
        str(out_dir),
        "--spp",
        str(args.ours_spp),
        "--seed",
        str(args.seed),
        "--threads",
        str(args.threads),
        "--strategy",
        args.strategy,
        "--integrator",
        args.integrator,
        "--quiet",
        "--set",
        "render.time=0",
        "--set",
        "render.snapshots.every=1e9",
    ]  # no snapshots: 0 is refused
    if args.s_L is not None:
        cmd += ["--set", f"params.s_L={args.s_L!r}"]
    if args.integrator == "path":
        cmd += ["--set", f"render.max_depth={args.max_depth}", "--set", f"render.rr_depth={args.rr_depth}"]
    for s in args.sets:
        cmd += ["--set", s]
    return cmd


def run_ours(args: argparse.Namespace, out_dir: Path) -> dict[str, Any]:
    """Renders with our binary; returns its final JSON event plus wall time."""
    if not args.renderer.exists():
        raise SetupError(
            f"renderer binary {args.renderer} not found (build it: make BUILD=renderer/build-xcheck "
            "renderer/build-xcheck/render)"
        )
    cmd = ours_command(args, out_dir)
    t0 = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.monotonic() - t0
    if proc.returncode != 0:
        raise SetupError(f"our renderer failed (exit {proc.returncode}): {' '.join(cmd)}\n{proc.stderr}")
    final: dict[str, Any] | None = None
    for line in proc.stdout.splitlines():
        ev = json.loads(line)
        if ev.get("event") == "final":
            final = ev
    if final is None:
        raise SetupError("our renderer printed no final event")
    final["wall_s"] = wall
    final["command"] = cmd
    return final


def read_ours(path: Path) -> Snapshot:
    """Our EXR through the harness's reader (portal_harness.core.exr, the one
    EXR reader): the snapshot, whose rgb and variance (of the mean) are
    (H, W, 3) float64."""
    from portal_harness.core import exr
    from portal_harness.core.errors import CorruptExrError

    try:
        return exr.read_snapshot(path)
    except CorruptExrError as e:
        raise SetupError(str(e)) from None


def write_exr(path: Path, mean: np.ndarray, var: np.ndarray) -> None:
    """Same channel layout as our renderer's EXR (R, G, B, variance.*), no attributes."""
    from portal_harness.core import exr

    channels: dict[str, np.ndarray] = {}
    for i, c in enumerate(exr.RGB_CHANNELS):
        channels[c] = mean[..., i]
    for i, c in enumerate(exr.VARIANCE_CHANNELS):
        channels[c] = var[..., i]
    exr.write_exr(path, channels, {})


# ---------------------------------------------------------------------------
# Effective config -> Mitsuba scene


def _triangles(vertices: list[Any], quads: list[list[int]], triangles: list[list[int]]) -> list[tuple[int, ...]]:
    """Splits planar convex quads into two triangles, keeping the winding."""
    tris = [tuple(t) for t in triangles]
    for q in quads:
        tris.append((q[0], q[1], q[2]))
        tris.append((q[0], q[2], q[3]))
    for t in tris:
        if any(not 0 <= i < len(vertices) for i in t):
            raise SetupError(f"face index out of range: {t!r}")
    return tris


MESH_FILE_TYPES = {".ply": "ply", ".obj": "obj"}


def fnv1a64(path: Path) -> str:
    """FNV-1a 64 of a file's bytes as 16 hex digits: our config's `digest`."""
    h = 0xCBF29CE484222325
    for byte in path.read_bytes():
        h = ((h ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return f"{h:016x}"


def _matmul(a: list[list[float]], b: list[list[float]]) -> list[list[float]]:
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def file_mesh_to_world(transform: list[Any] | None, offset: list[float]) -> list[list[float]]:
    """The 4x4 row-major matrix that takes a mesh file's points to Mitsuba's
    world: our `transform` (in the effective config a list of `{matrix: 16
    numbers, row-major}` applied in order, so M = M_n ... M_1), then the move
    by -offset (recentring)."""
    m = [[float(i == j) for j in range(4)] for i in range(4)]
    for op in transform or []:
        if not isinstance(op, dict) or set(op) != {"matrix"} or len(op["matrix"]) != 16:
            raise SetupError(f"mesh transform: expected {{matrix: 16 numbers}} (effective config), got {op!r}")
        rows = [[float(x) for x in op["matrix"][4 * r : 4 * r + 4]] for r in range(4)]
        m = _matmul(rows, m)
    move = [[float(i == j) for j in range(4)] for i in range(4)]
    for i in range(3):
        move[i][3] = -float(offset[i])
    return _matmul(move, m)


def _det3(m: list[list[float]]) -> float:
    return (
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    )


def file_mesh_shape(entry: dict[str, Any], offset: list[float], what: str) -> dict[str, Any]:
    """Mitsuba `ply`/`obj` shape of an effective-config `{file, transform,
    digest}` (a file mesh shape, or a mesh light's `mesh`), without BSDF.

    Mitsuba reads the same file our renderer read (the digest is checked,
    so an edit since our render is an error) with the same to_world. Flat
    shading (`face_normals`): our renderer shades with the geometric normal;
    without it Mitsuba would interpolate smooth vertex normals it computes
    from the file. Mitsuba's face normal is cross(p1 - p0, p2 - p0) of the
    transformed points, so a mirroring to_world (det < 0) turns it over,
    while ours reverses the triangles there and keeps the normal along the
    inverse transpose (config_scene.c): `flip_normals` undoes the difference
    (it matters for a mesh light's emitting side only; surfaces are
    two-sided)."""
    path = Path(str(entry.get("file")))
    kind = MESH_FILE_TYPES.get(path.suffix.lower())
    if kind is None:
        raise SetupError(f"{what}: mesh file {path} is neither .ply nor .obj")
    if not path.is_file():
        raise SetupError(f"{what}: mesh file {path} not found")
    digest = entry.get("digest")
    if isinstance(digest, dict) and "fnv1a64" in digest and fnv1a64(path) != str(digest["fnv1a64"]):
        raise SetupError(f"{what}: mesh file {path} changed since our render (digest {digest['fnv1a64']})")
    to_world = file_mesh_to_world(entry.get("transform"), offset)
    return {
        "type": kind,
        "filename": str(path),
        "to_world": to_world,
        "face_normals": True,
        "flip_normals": _det3(to_world) < 0.0,
    }


def _rgb(value: Iterable[Any]) -> dict[str, Any]:
    return {"type": "rgb", "value": [float(x) for x in value]}


def _bsdf(material: dict[str, Any], name: str) -> dict[str, Any]:
    if material.get("type") == "ggx":
        # Our ggx: GGX reflection, Schlick's Fresnel with the albedo as F0.
        # Mitsuba's nearest: principled with metallic 1 (its metallic lobe
        # is GGX with Schlick's Fresnel on base_color, alpha = roughness^2,
        # no diffuse, sheen or clearcoat). Its Smith G is the separable
        # G1 G1, ours the height-correlated one: they differ at grazing
        # angles only (README, "What is converted").
        lobe = {
            "type": "principled",
            "base_color": _rgb(material["albedo"]),
            "metallic": 1.0,
            "roughness": float(material["roughness"]) ** 0.5,
        }
        return {"type": "twosided", "material": lobe}
    if material.get("type") != "diffuse":
        raise SetupError(
            "material {!r}: only diffuse and ggx are converted (got {!r})".format(name, material.get("type"))
        )
    # Our surfaces are two-sided; Mitsuba's diffuse is black from the back.
    return {"type": "twosided", "material": {"type": "diffuse", "reflectance": _rgb(material["albedo"])}}


def recentre_offset(cfg: dict[str, Any]) -> list[float]:
    """Centroid of the lights' vertices: the point to move to Mitsuba's origin.

    Mitsuba (float32) offsets every spawned ray by about 9e-5 (1 + max |p|)
    along the normal. Near a light that offset is not negligible: on the
    shade's back wall just below the lamp it made BSDF-sampled direct light
    0.2-0.6% too bright at the scene's own position (lamp at y = 2.6), 0.0%
    with the lamp moved to the origin and 3% at y = 22 (measured against
    Lambert's closed form, see README). A rigid translation changes no
    radiance, so Mitsuba renders the scene moved by -centroid. A mesh light
    counts as one point, the centre of its bounding box (read by Mitsuba).
    """
    verts: list[list[float]] = []
    for light in cfg.get("lights") or []:
        if "mesh" in light:
            verts.append(mesh_bbox_centre(light["mesh"], f"light {light.get('name')!r}"))
        else:
            verts.extend([float(x) for x in v] for v in light["vertices"])
    if not verts:
        return [0.0, 0.0, 0.0]
    return [sum(v[i] for v in verts) / len(verts) for i in range(3)]


def mesh_bbox_centre(entry: dict[str, Any], what: str) -> list[float]:
    """Centre of a file mesh's world-space bounding box, as Mitsuba loads it."""
    import mitsuba as mi

    shape = file_mesh_shape(entry, [0.0, 0.0, 0.0], what)
    shape["to_world"] = mi.ScalarTransform4f(shape["to_world"])
    c = mi.load_dict(shape).bbox().center()
    return [float(c[i]) for i in range(3)]


def build_scene_dict(
    cfg: dict[str, Any], integrator: dict[str, Any], mesh_dir: Path, spp: int, offset: list[float] | None = None
) -> dict[str, Any]:
    """Mitsuba load_dict() description of our effective config, every
    position moved by -offset (default none)."""
    import mitsuba as mi

    off = [0.0, 0.0, 0.0] if offset is None else [float(x) for x in offset]

    def moved(points: list[Any]) -> list[list[float]]:
        return [[float(p[i]) - off[i] for i in range(3)] for p in points]

    mesh_dir.mkdir(parents=True, exist_ok=True)
    cam = cfg["camera"]
    origin, target = moved([cam["position"], cam["look_at"]])
    look_at = mi.ScalarTransform4f().look_at(origin=origin, target=target, up=[float(x) for x in cam["up"]])
    scene: dict[str, Any] = {
        "type": "scene",
        "integrator": integrator,
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": float(cam["fov_y"]),
            "to_world": look_at,
            "film": {
                "type": "hdrfilm",
                "width": int(cfg["film"]["width"]),
                "height": int(cfg["film"]["height"]),
                "pixel_format": "rgb",
                "component_format": "float32",
                # Our film: one-pixel box filter, i.e. the plain mean of the
                # samples drawn uniformly inside the pixel.
                "rfilter": {"type": "box"},
            },
            "sampler": {"type": "independent", "sample_count": spp},
        },
    }
    materials = cfg["materials"]
    for i, shape in enumerate(cfg.get("shapes") or []):
        if shape.get("type") == "mesh" and "file" in shape:
            entry = file_mesh_shape(shape, off, f"shape {shape.get('name')!r}")
            entry["to_world"] = mi.ScalarTransform4f(entry["to_world"])
            entry["bsdf"] = _bsdf(materials[shape["material"]], shape["material"])
            scene[f"shape_{i:02d}_{shape['name']}"] = entry
            continue
        if shape.get("type") != "mesh":
            raise SetupError(
                "shape {!r}: effective configs hold meshes only (got {!r})".format(shape.get("name"), shape.get("type"))
            )
        tris = _triangles(shape["vertices"], shape.get("quads") or [], shape.get("triangles") or [])
        ply = mesh_dir / f"shape_{i:02d}.ply"
        write_ply(ply, moved(shape["vertices"]), tris)
        scene[f"shape_{i:02d}_{shape['name']}"] = {
            "type": "ply",
            "filename": str(ply),
            # Flat shading: without this Mitsuba would smooth the normals of
            # meshes that share vertices between faces (the box).
            "face_normals": True,
            "bsdf": _bsdf(materials[shape["material"]], shape["material"]),
        }
    for i, light in enumerate(cfg.get("lights") or []):
        if light.get("two_sided"):
            raise SetupError(
                "light {!r}: two-sided lights are not converted (Mitsuba's area emitter is one-sided)".format(
                    light["name"]
                )
            )
        # Our lights reflect nothing; Mitsuba's default BSDF would be a 0.5
        # diffuse.
        black = {"type": "twosided", "material": {"type": "diffuse", "reflectance": _rgb([0, 0, 0])}}
        emitter = {"type": "area", "radiance": _rgb(light["radiance"])}
        if "mesh" in light:
            # A mesh light: every triangle emits on the side its winding
            # faces, as Mitsuba's area emitter on the same file does with
            # face normals (file_mesh_shape keeps the side under mirroring
            # transforms). Checked per triangle and end to end in
            # tests/crosscheck/test_mitsuba_mesh_light.py.
            entry = file_mesh_shape(light["mesh"], off, f"light {light['name']!r}")
            entry["to_world"] = mi.ScalarTransform4f(entry["to_world"])
            scene[f"light_{i:02d}_{light['name']}"] = {**entry, "bsdf": black, "emitter": emitter}
            continue
        verts = light["vertices"]
        # Fan triangulation of the convex polygon keeps its winding. Mitsuba's
        # triangle normal is cross(p1 - p0, p2 - p0), the right-hand rule of the
        # vertex order, as our polygon_normal; its area emitter emits on the
        # normal's side, as our one-sided light does.
        tris = [(0, k, k + 1) for k in range(1, len(verts) - 1)]
        ply = mesh_dir / f"light_{i:02d}.ply"
        write_ply(ply, moved(verts), tris)
        scene[f"light_{i:02d}_{light['name']}"] = {
            "type": "ply",
            "filename": str(ply),
            "face_normals": True,
            "bsdf": black,
            "emitter": emitter,
        }
    # Portals are sampling aids, not geometry: nothing to convert.
    return scene


def mitsuba_integrator(args: argparse.Namespace) -> dict[str, Any]:
    if args.integrator == "direct":
        # Ours: emission seen by the camera + one light sample and one BSDF
        # sample at the first hit, combined by MIS.
        return {"type": "direct", "emitter_samples": 1, "bsdf_samples": 1}
    # Our max_depth counts bounces (vertices that gather light); Mitsuba's
    # counts path segments including the camera ray: N bounces = N + 1.
    return {"type": "path", "max_depth": args.max_depth + 1, "rr_depth": args.rr_depth}


def render_mitsuba(
    scene_dict: dict[str, Any], runs: int, spp_each: int, seed_base: int
) -> tuple[np.ndarray, float, float]:
    """K independent renders; returns (K, H, W, 3) float64 and timings."""
    import mitsuba as mi
    import numpy as np

    t0 = time.monotonic()
    scene = mi.load_dict(scene_dict)
    load_s = time.monotonic() - t0
    images = []
    t1 = time.monotonic()
    for k in range(runs):
        # Mitsuba multiplies the seed by the pixel count and adds the pixel
        # index: distinct seeds give disjoint per-pixel streams.
        img = mi.render(scene, seed=seed_base + k, spp=spp_each)
        images.append(np.array(img, dtype=np.float64))
    render_s = time.monotonic() - t1
    return np.stack(images), load_s, render_s


# ---------------------------------------------------------------------------
# Statistics


def normal_two_sided_quantile(p_tail: float) -> float:
    """z with P(|Z| > z) = p_tail for a standard normal (bisection on erfc)."""
    lo, hi = 0.0, 40.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if math.erfc(mid / math.sqrt(2.0)) > p_tail:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def block_mean(a: np.ndarray, b: int) -> np.ndarray:
    """Means over b x b blocks of (..., H, W, C); a partial border is dropped."""
    h, w = a.shape[-3] // b * b, a.shape[-2] // b * b
    a = a[..., :h, :w, :]
    shape = (*a.shape[:-3], h // b, b, w // b, b, a.shape[-1])
    means: np.ndarray = a.reshape(shape).mean(axis=(-4, -2))
    return means


def one_hit_scale(img: np.ndarray, var: np.ndarray) -> np.ndarray:
    """Per channel: the size of one nonzero sample, bounded from above by the
    99th percentile of the pixel means that have noise (emitters excluded).

    A sample that finds light through a sliver of a penumbra is worth about
    what a fully lit neighbour's samples are worth, so this is generous."""
    import numpy as np

    out = []
    for c in range(img.shape[-1]):
        v = img[..., c][var[..., c] > 0]
        out.append(float(np.percentile(v, 99.0)) if v.size else 0.0)
    return np.array(out)


def compare(
    ours: np.ndarray,
    ours_var: np.ndarray,
    mits_runs: np.ndarray,
    b: int,
    alpha: float,
    ours_spp: int | None = None,
    mits_spp: int | None = None,
) -> dict[str, Any]:
    import numpy as np

    k = mits_runs.shape[0]
    mits = mits_runs.mean(axis=0)
    # Per-pixel variance of the K-run mean: sample variance over runs / K.
    mits_var = mits_runs.var(axis=0, ddof=1) / k

    # Block means and their variances. Pixels are independent in both
    # renderers (per-pixel seeding), so Var(block mean) = mean(pixel var) / b^2;
    # pooling 64 pixels gives the Mitsuba variance 64 (K-1) degrees of
    # freedom, so z is close to normal even in the far tail.
    ob, mb = block_mean(ours, b), block_mean(mits, b)
    ovb = block_mean(ours_var, b) / (b * b)
    mvb = block_mean(mits_var, b) / (b * b)
    # The brief's estimator, no pixel independence assumed: the spread of the
    # K runs' block means (K-1 degrees of freedom). Reported as a check of
    # the pooled one.
    mvb_runs = block_mean(mits_runs, b).var(axis=0, ddof=1) / k

    diff = ob - mb
    # Rounding floor: both renderers store float32 and Mitsuba accumulates in
    # float32, so noiseless blocks (the emitter seen directly) still differ
    # by ~1e-7 relative; 1e-5 of the value absorbs that without hiding any
    # real bias.
    rounding_var = (FLOAT_REL_TOL * np.maximum(np.abs(ob), np.abs(mb))) ** 2
    ovb = ovb + rounding_var
    # Zero-hit floor: a block whose every sample was 0 reports variance 0,
    # yet a light seen through a thin sliver (the outer edge of a penumbra)
    # can be missed by N samples when its hit rate is below ~1/N. Such a
    # block is given the variance of one hit among its N samples, (h / N)^2,
    # so a few hits' worth of light in the other image is not a failure.
    # Only where the other image has light: blocks black in both stay z = 0.
    mvb_sampled = mvb.copy()
    zero_hit_tests = 0
    for spp, img, var_px, blk, other, vbs in (
        (ours_spp, ours, ours_var, ob, mb, (ovb,)),
        (mits_spp, mits, mits_var, mb, ob, (mvb, mvb_runs)),
    ):
        if spp is None:
            continue
        empty = (blk == 0) & (vbs[0] == 0) & (other != 0)
        floor = np.where(empty, (one_hit_scale(img, var_px) / (spp * b * b)) ** 2, 0.0)
        for vb in vbs:
            vb += floor
        zero_hit_tests += int(np.count_nonzero(empty))
    var = ovb + mvb
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(
            var > 0, diff / np.sqrt(np.where(var > 0, var, 1.0)), np.where(diff == 0, 0.0, np.inf * np.sign(diff))
        )
        var_runs = ovb + mvb_runs
        z_runs = np.where(
            var_runs > 0,
            diff / np.sqrt(np.where(var_runs > 0, var_runs, 1.0)),
            np.where(diff == 0, 0.0, np.inf * np.sign(diff)),
        )
    n_tests = z.size
    bound = normal_two_sided_quantile(alpha / n_tests)
    absz = np.abs(z)

    # Whole-image quantities.
    sum_o, sum_m = ours.sum(axis=(0, 1)), mits.sum(axis=(0, 1))
    ratio = sum_o / sum_m
    ratio_sigma = np.sqrt(ours_var.sum(axis=(0, 1)) + mits_var.sum(axis=(0, 1))) / sum_m
    # relMSE with the usual 1e-2 guard in the denominator; it holds both
    # images' noise, so compare it with its expectation from the variances.
    denom = mits**2 + 1e-2
    relmse = float(np.mean((ours - mits) ** 2 / denom))
    relmse_noise = float(np.mean((ours_var + mits_var) / denom))

    top = []
    order = np.argsort(absz, axis=None)[::-1][:10]
    for flat in order:
        by, bx, c = np.unravel_index(flat, z.shape)
        top.append(
            {
                "block": [int(bx), int(by)],
                "pixels_x": [int(bx * b), int(bx * b + b - 1)],
                "pixels_y": [int(by * b), int(by * b + b - 1)],
                "channel": "RGB"[c],
                "ours": float(ob[by, bx, c]),
                "mitsuba": float(mb[by, bx, c]),
                "sigma_ours": float(math.sqrt(ovb[by, bx, c])),
                "sigma_mitsuba": float(math.sqrt(mvb[by, bx, c])),
                "z": float(z[by, bx, c]),
            }
        )
    pos = mvb_sampled > 0
    return {
        "mitsuba_mean": mits,
        "mitsuba_var": mits_var,
        "z": z,
        "stats": {
            "blocks": int(z.shape[0] * z.shape[1]),
            "tests": int(n_tests),
            "zero_hit_tests": zero_hit_tests,
            "block_px": b,
            "max_abs_z": float(absz.max()),
            "bound": bound,
            "alpha": alpha,
            "frac_gt_3": float(np.mean(absz > 3)),
            "frac_gt_4": float(np.mean(absz > 4)),
            "frac_gt_5": float(np.mean(absz > 5)),
            "expected_frac_gt_3": math.erfc(3 / math.sqrt(2)),
            "expected_frac_gt_4": math.erfc(4 / math.sqrt(2)),
            # Over the tests with some variance (black blocks give z = 0).
            "tests_with_variance": int(np.count_nonzero(var > 0)),
            "mean_z": float(z[var > 0].mean()) if (var > 0).any() else 0.0,
            "mean_z2": float(np.mean(z[var > 0] ** 2)) if (var > 0).any() else 0.0,
            "max_abs_z_runs_variance": float(np.abs(z_runs).max()),
            "median_var_ratio_runs_over_pooled": (
                float(np.median(mvb_runs[pos] / mvb_sampled[pos])) if pos.any() else None
            ),
            "median_var_ratio_ours_over_mitsuba": (
                float(np.median(ovb[pos] / mvb_sampled[pos])) if pos.any() else None
            ),
            "mean_ratio_ours_over_mitsuba": [float(x) for x in ratio],
            "mean_ratio_sigma": [float(x) for x in ratio_sigma],
            "relmse": relmse,
            "relmse_expected_from_noise": relmse_noise,
            "top_blocks": top,
        },
    }


FOCUS_COVER = 0.25


def file_mesh_keys(cfg: dict[str, Any]) -> dict[str, str]:
    """Scene-dict keys of the file-mesh shapes (build_scene_dict's names) ->
    our shape names: the parts of the image reported on their own."""
    return {
        f"shape_{i:02d}_{shape['name']}": str(shape["name"])
        for i, shape in enumerate(cfg.get("shapes") or [])
        if shape.get("type") == "mesh" and "file" in shape
    }


def shape_masks(scene_dict: dict[str, Any], keys: dict[str, str], sub: int = 2) -> dict[str, np.ndarray]:
    """Per shape, the (H, W) fraction of each pixel that the camera sees of
    it: Mitsuba's first hit of sub x sub rays per pixel (pixel-centred grid,
    pinhole). Geometry only, no light is sampled."""
    import mitsuba as mi
    import numpy as np

    # optimize=False: Mitsuba would otherwise merge the meshes that share a
    # BSDF into one shape without our ids (it changes no image).
    scene = mi.load_dict(scene_dict, optimize=False)
    sensor = scene.sensors()[0]
    w, h = (int(x) for x in sensor.film().size())
    masks = {name: np.zeros((h, w)) for name in keys.values()}
    offsets = [(k + 0.5) / sub for k in range(sub)]
    for y in range(h):
        for x in range(w):
            for oy in offsets:
                for ox in offsets:
                    pos = mi.Point2f((x + ox) / w, (y + oy) / h)
                    ray, _ = sensor.sample_ray(0.0, 0.0, pos, mi.Point2f(0.5, 0.5))
                    si = scene.ray_intersect(ray)
                    if si.is_valid():
                        name = keys.get(si.shape.id())
                        if name is not None:
                            masks[name][y, x] += 1.0 / (sub * sub)
    return masks


def focus_stats(
    result: dict[str, Any], ours: np.ndarray, ours_var: np.ndarray, mask: np.ndarray, b: int
) -> dict[str, Any]:
    """The agreement on one part of the image (a shape's mask): the block
    tests of the blocks it covers by at least FOCUS_COVER, and the ratio of
    the mask-weighted sums ours / Mitsuba with its standard error (the
    sensitive test of a bias on that part). The pass/fail bound stays the
    whole image's: these tests are among its tests."""
    import numpy as np

    mits, mits_var, z = result["mitsuba_mean"], result["mitsuba_var"], result["z"]
    cover = block_mean(mask[..., None], b)[..., 0]
    zs = z[cover >= FOCUS_COVER]
    w = mask[..., None]
    sum_m = (w * mits).sum(axis=(0, 1))
    ratio = (w * ours).sum(axis=(0, 1)) / sum_m
    sigma = np.sqrt((w**2 * (ours_var + mits_var)).sum(axis=(0, 1))) / sum_m
    return {
        "pixels": float(mask.sum()),
        "blocks": int(np.count_nonzero(cover >= FOCUS_COVER)),
        "tests": int(zs.size),
        "max_abs_z": float(np.abs(zs).max()) if zs.size else 0.0,
        "mean_z": float(zs.mean()) if zs.size else 0.0,
        "mean_z2": float(np.mean(zs**2)) if zs.size else 0.0,
        "ratio_ours_over_mitsuba": [float(x) for x in ratio],
        "ratio_sigma": [float(x) for x in sigma],
        "rel_sigma_ours": [float(x) for x in np.sqrt((w**2 * ours_var).sum(axis=(0, 1))) / sum_m],
        "rel_sigma_mitsuba": [float(x) for x in np.sqrt((w**2 * mits_var).sum(axis=(0, 1))) / sum_m],
    }


# ---------------------------------------------------------------------------
# Images


def write_png(path: Path, rgb8: np.ndarray) -> None:
    """Minimal 8-bit RGB PNG writer (zlib only)."""
    import numpy as np

    h, w, _ = rgb8.shape
    raw = b"".join(b"\x00" + np.ascontiguousarray(rgb8[y]).tobytes() for y in range(h))

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    path.write_bytes(png)


def _srgb8(x: np.ndarray) -> np.ndarray:
    import numpy as np

    x = np.clip(x, 0.0, 1.0)
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (y * 255 + 0.5).astype(np.uint8)


def _luminance(img: np.ndarray) -> np.ndarray:
    lum: np.ndarray = 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]
    return lum


def _diverging(v: np.ndarray) -> np.ndarray:
    """v in [-1, 1]: blue (negative) - white - red (positive), as uint8."""
    import numpy as np

    v = np.clip(v, -1.0, 1.0)
    r = 1.0 - np.maximum(-v, 0.0)
    g = 1.0 - np.abs(v)
    bl = 1.0 - np.maximum(v, 0.0)
    return (np.stack([r, g, bl], axis=-1) * 255 + 0.5).astype(np.uint8)


def write_images(out: Path, ours: np.ndarray, mits: np.ndarray, z: np.ndarray, b: int, bound: float) -> dict[str, Any]:
    """Tone-mapped side by side (same exposure), signed difference, z map."""
    import numpy as np

    # One exposure for both: the 99th percentile of Mitsuba's luminance -> 1.
    lum = _luminance(mits)
    scale = 1.0 / max(float(np.percentile(lum, 99.0)), 1e-6)
    gap = np.full((ours.shape[0], 4, 3), 255, np.uint8)
    side = np.concatenate([_srgb8(ours * scale), gap, _srgb8(mits * scale)], axis=1)
    write_png(out / "ours.png", _srgb8(ours * scale))
    write_png(out / "mitsuba.png", _srgb8(mits * scale))
    write_png(out / "side_by_side.png", side)
    # Signed luminance difference, block-averaged to see past the per-pixel
    # noise, relative to the exposure white: full colour at 5% of white.
    d = block_mean(_luminance(ours - mits)[..., None], b)[..., 0]
    d_img = _diverging(d * scale / 0.05)
    write_png(out / "diff.png", np.kron(d_img, np.ones((b, b, 1), np.uint8)))
    # Block z: the channel with the largest |z|, saturating at the bound;
    # blocks beyond the bound are drawn black.
    idx = np.argmax(np.abs(z), axis=-1)
    zsel = np.take_along_axis(z, idx[..., None], axis=-1)[..., 0]
    z_img = _diverging(zsel / bound)
    z_img[np.abs(zsel) > bound] = 0
    write_png(out / "zmap.png", np.kron(z_img, np.ones((b, b, 1), np.uint8)))
    return {"exposure_scale": scale}


# ---------------------------------------------------------------------------


def format_table(s: dict[str, Any], info: dict[str, Any]) -> str:
    def row(label: str, value: str) -> str:
        return f"  {label:<34} {value}"

    ratios = "  ".join(
        f"{r:.4f}+-{e:.4f}" for r, e in zip(s["mean_ratio_ours_over_mitsuba"], s["mean_ratio_sigma"], strict=True)
    )
    runs = info["mitsuba_runs"]
    lines = [
        f"cross-check ours vs Mitsuba {info['mitsuba_version']}: integrator {info['integrator']}, "
        f"s_L {info['s_L']}, {info['mitsuba_integrator']}",
        f"  ours    : {info['ours_spp']} spp, strategy {info['strategy']}, render {info['ours_time_s']:.1f} s "
        f"(wall {info['ours_wall_s']:.1f} s)",
        f"  mitsuba : {info['mitsuba_spp']} spp = {runs} runs x {info['mitsuba_spp'] // runs} spp, "
        f"render {info['mitsuba_render_s']:.1f} s (+ load {info['mitsuba_load_s']:.1f} s)",
        row("blocks x channels", f"{s['blocks']} x 3 = {s['tests']} ({s['block_px']}x{s['block_px']} px)"),
        row("max |z|", f"{s['max_abs_z']:.3f}   (bound {s['bound']:.3f}: Bonferroni, alpha {s['alpha']:g})"),
        row("max |z| (variance from run spread)", f"{s['max_abs_z_runs_variance']:.3f}"),
        row("tests where one side had no hit", f"{s['zero_hit_tests']}"),
        row("fraction |z| > 3", f"{s['frac_gt_3']:.4f} (normal: {s['expected_frac_gt_3']:.4f})"),
        row("fraction |z| > 4", f"{s['frac_gt_4']:.5f} (normal: {s['expected_frac_gt_4']:.5f})"),
        row("fraction |z| > 5", f"{s['frac_gt_5']:.5f}"),
        row(
            "mean z / mean z^2",
            f"{s['mean_z']:+.3f} / {s['mean_z2']:.3f} (normal: 0 / 1; over "
            f"{s['tests_with_variance']} tests with variance)",
        ),
        row("mean ratio ours/mitsuba R G B", ratios),
        row("relMSE", f"{s['relmse']:.3e} (noise alone: {s['relmse_expected_from_noise']:.3e})"),
    ]
    if s["median_var_ratio_runs_over_pooled"] is not None:
        lines.append(
            row(
                "median var ratio runs/pooled",
                f"{s['median_var_ratio_runs_over_pooled']:.3f} (1 if pixels independent)",
            )
        )
    for name, f in (s.get("focus") or {}).items():
        ratios = "  ".join(
            f"{r:.4f}+-{e:.4f}" for r, e in zip(f["ratio_ours_over_mitsuba"], f["ratio_sigma"], strict=True)
        )
        lines.append(
            row(
                f"{name}: blocks covered",
                f"{f['blocks']} ({f['tests']} tests, {f['pixels']:.0f} px seen; >= {FOCUS_COVER:g} of a block)",
            )
        )
        lines.append(
            row(
                f"{name}: max |z| / mean z / z^2",
                f"{f['max_abs_z']:.3f} / {f['mean_z']:+.3f} / {f['mean_z2']:.3f}",
            )
        )
        lines.append(row(f"{name}: ratio ours/mitsuba", ratios))
    lines.append("  largest |z| blocks (x0-x1, y0-y1 pixels, row 0 at the top):")
    for t in s["top_blocks"][:5]:
        lines.append(
            f"    x {t['pixels_x'][0]:3d}-{t['pixels_x'][1]:3d} y {t['pixels_y'][0]:3d}-{t['pixels_y'][1]:3d} "
            f"{t['channel']}  ours {t['ours']:.5g} +- {t['sigma_ours']:.2g}  "
            f"mitsuba {t['mitsuba']:.5g} +- {t['sigma_mitsuba']:.2g}  z {t['z']:+.2f}"
        )
    lines.append(f"  result: {'AGREE within noise' if s['max_abs_z'] <= s['bound'] else 'DISAGREE'}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    ensure_mitsuba()
    import mitsuba as mi
    import numpy as np
    import yaml

    mi.set_variant("scalar_rgb")
    out: Path = args.out
    ours_dir = out / "ours"
    out.mkdir(parents=True, exist_ok=True)
    try:
        final_exr = ours_dir / "final.exr"
        ours_run = None
        if args.reuse_ours and final_exr.exists() and (ours_dir / "ours_run.json").exists():
            ours_run = json.loads((ours_dir / "ours_run.json").read_text())
            if ours_run.get("command") != ours_command(args, ours_dir):
                print(f"not reusing {final_exr}: rendered with other options", file=sys.stderr)
                ours_run = None
            else:
                print(f"reusing {final_exr}", file=sys.stderr)
        if ours_run is None:
            print(f"rendering ours: {args.ours_spp} spp ...", file=sys.stderr)
            ours_run = run_ours(args, ours_dir)
            (ours_dir / "ours_run.json").write_text(json.dumps(ours_run, indent=1))
        snapshot = read_ours(final_exr)
        ours, ours_var, ours_header = snapshot.rgb, snapshot.variance, snapshot.header
        cfg = yaml.safe_load((ours_dir / "config.yaml").read_text())

        spp_each = args.mitsuba_spp // args.mitsuba_runs
        integ = mitsuba_integrator(args)
        offset = [0.0, 0.0, 0.0] if args.no_recentre else recentre_offset(cfg)
        scene_dict = build_scene_dict(cfg, integ, out / "mitsuba" / "meshes", spp_each, offset)
        # What determines Mitsuba's images: the scene (our render settings
        # and portals aside: they guide our sampling only), its integrator,
        # spp, runs and seeds.
        key = json.dumps(
            {
                "scene": {k: v for k, v in cfg.items() if k not in ("render", "portals")},
                "integrator": integ,
                "offset": offset,
                "spp_each": spp_each,
                "runs": args.mitsuba_runs,
                "seed": args.seed,
                "mitsuba": mi.__version__,
            },
            sort_keys=True,
        )
        cache = args.mitsuba_cache
        cached = None
        if cache is not None and cache.exists():
            with np.load(cache) as z:
                if str(z["key"]) == key:
                    cached = (z["runs"].astype(np.float64), float(z["load_s"]), float(z["render_s"]))
        if cached is not None:
            runs, load_s, render_s = cached
            print(f"reusing Mitsuba renders from {cache}", file=sys.stderr)
        else:
            print(f"rendering Mitsuba: {args.mitsuba_runs} runs x {spp_each} spp ...", file=sys.stderr)
            runs, load_s, render_s = render_mitsuba(scene_dict, args.mitsuba_runs, spp_each, args.seed * 1000)
            if cache is not None:
                cache.parent.mkdir(parents=True, exist_ok=True)
                np.savez_compressed(cache, key=key, runs=runs.astype(np.float32), load_s=load_s, render_s=render_s)
        if runs.shape[1:] != ours.shape:
            raise SetupError(f"image sizes differ: ours {ours.shape!r}, Mitsuba {runs.shape[1:]!r}")
    except SetupError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2

    result = compare(ours, ours_var, runs, args.block, args.alpha, ours_spp=ours_header.spp, mits_spp=args.mitsuba_spp)
    focus_keys = file_mesh_keys(cfg)
    if focus_keys:
        masks = shape_masks(scene_dict, focus_keys)
        result["stats"]["focus"] = {
            name: focus_stats(result, ours, ours_var, mask, args.block) for name, mask in masks.items()
        }
    write_exr(out / "mitsuba" / "mitsuba.exr", result["mitsuba_mean"], result["mitsuba_var"])
    img_info = write_images(out, ours, result["mitsuba_mean"], result["z"], args.block, result["stats"]["bound"])

    s_L = cfg.get("params", {}).get("s_L") if isinstance(cfg.get("params"), dict) else None
    info = {
        "mitsuba_version": mi.__version__,
        "variant": mi.variant(),
        "integrator": args.integrator,
        "mitsuba_integrator": json.dumps(integ),
        "s_L": args.s_L if args.s_L is not None else (s_L if s_L is not None else "scene default"),
        "strategy": args.strategy,
        "ours_spp": ours_header.spp,
        "ours_time_s": float(ours_run["time_s"]),
        "ours_wall_s": float(ours_run["wall_s"]),
        "ours_config_hash": ours_header.config_hash,
        "mitsuba_spp": args.mitsuba_spp,
        "mitsuba_runs": args.mitsuba_runs,
        "mitsuba_load_s": load_s,
        "mitsuba_render_s": render_s,
        "mitsuba_offset": offset,
        "max_depth_ours": args.max_depth if args.integrator == "path" else 1,
        **img_info,
    }
    table = format_table(result["stats"], info)
    print(table)
    (out / "report.txt").write_text(table + "\n")
    (out / "summary.json").write_text(json.dumps({"info": info, "stats": result["stats"]}, indent=1))
    return 0 if result["stats"]["max_abs_z"] <= result["stats"]["bound"] else 1


if __name__ == "__main__":
    sys.exit(main())
