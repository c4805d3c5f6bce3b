"""Comparing renders of the lampshade with the closed form of its floor.

Reads run folders (the renderer's output: config.yaml, snapshot_*.exr,
final.exr), builds the closed form once per scene configuration, and gives
per pixel set the harness's relMSE, the efficiency 1 / (relMSE x time), and
the z-score of the mean difference (is the render's mean over the set
consistent with the closed form, given the EXR's variance layer?).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from floor_model import LampshadeModel, ModelMismatch, PixelModel, expected_pixels

from portal_harness.core import exr
from portal_harness.core.metrics import REL_EPSILON, efficiency

FLOOR_SET = "floor"  # every pixel of the mask
LIT_SET = "lit"  # the mask's pixels that receive light (closed form > 0)


@dataclass(frozen=True)
class Inset:
    """A rectangle in pixel coordinates, row 0 at the top: columns [x, x + width), rows [y, y + height)."""

    name: str
    x: int
    y: int
    width: int
    height: int

    @staticmethod
    def parse(text: str) -> Inset:
        """NAME=X,Y,W,H"""
        name, sep, rest = text.partition("=")
        fields = rest.split(",")
        if not sep or not name or len(fields) != 4:
            raise ValueError(f"inset {text!r}: expected NAME=X,Y,W,H")
        x, y, w, h = (int(f) for f in fields)
        if w <= 0 or h <= 0 or x < 0 or y < 0:
            raise ValueError(f"inset {text!r}: needs x, y >= 0 and w, h > 0")
        return Inset(name, x, y, w, h)

    def select(self, width: int, height: int) -> np.ndarray:
        if self.x + self.width > width or self.y + self.height > height:
            raise ValueError(f"inset {self.name} does not fit a {width}x{height} image")
        m = np.zeros((height, width), dtype=bool)
        m[self.y : self.y + self.height, self.x : self.x + self.width] = True
        return m


@dataclass(frozen=True)
class ClosedForm:
    """The closed form of one scene configuration, at n and 2n sub-pixel points."""

    model: LampshadeModel
    coarse: PixelModel  # n x n: the reference
    fine: PixelModel  # 2n x 2n: its integration error is estimated as |coarse - fine|

    @property
    def expected(self) -> np.ndarray:
        return self.coarse.expected

    @property
    def mask(self) -> np.ndarray:
        both: np.ndarray = self.coarse.mask & self.fine.mask
        return both

    def pixel_sets(self, insets: list[Inset]) -> dict[str, np.ndarray]:
        h, w = self.mask.shape
        sets = {FLOOR_SET: self.mask, LIT_SET: self.mask & np.any(self.expected > 0, axis=-1)}
        for inset in insets:
            sets[inset.name] = self.mask & inset.select(w, h)
        return sets

    def integration_error(self, select: np.ndarray) -> dict[str, float]:
        """Over a pixel set, r_n against r_2n: the largest pixel difference
        relative to the set's brightest pixel (a relative error per pixel
        means little where the light fades to 0), the relMSE of r_n against
        r_2n, and the mean difference."""
        r, f = self.coarse.expected[select], self.fine.expected[select]
        if r.size == 0:
            return {"max_error_vs_peak": 0.0, "rel_mse": math.nan, "mean_difference": math.nan}
        peak = float(f.max())
        return {
            "max_error_vs_peak": float(np.abs(r - f).max()) / peak if peak > 0 else 0.0,
            "rel_mse": float(np.mean((r - f) ** 2 / (f * f + REL_EPSILON))),
            "mean_difference": float(np.mean(r - f)),
        }


def closed_form_for(cfg: dict[str, Any], n: int) -> ClosedForm:
    model = LampshadeModel.from_config(cfg)
    return ClosedForm(model=model, coarse=expected_pixels(model, n), fine=expected_pixels(model, 2 * n))


def scene_key(cfg: dict[str, Any]) -> str:
    """Runs with the same key have the same closed form: everything but `render`."""
    scene = {k: v for k, v in cfg.items() if k != "render"}
    return hashlib.sha256(json.dumps(scene, sort_keys=True).encode()).hexdigest()[:16]


def load_config(run: Path) -> dict[str, Any]:
    cfg = yaml.safe_load((run / "config.yaml").read_text())
    if not isinstance(cfg, dict):
        raise ModelMismatch(f"{run / 'config.yaml'}: not a mapping")
    render = cfg.get("render") or {}
    direct = render.get("integrator") == "direct" or (
        render.get("integrator") == "path" and int(render.get("max_depth", 0)) == 1
    )
    if not direct:
        raise ModelMismatch(
            f"{run}: the closed form is for direct lighting only (integrator {render.get('integrator')})"
        )
    return cfg


def find_runs(paths: list[Path]) -> list[Path]:
    """Run folders: each path that holds final.exr, or the folders below it that do."""
    runs: list[Path] = []
    for p in paths:
        if (p / "final.exr").is_file():
            runs.append(p)
        else:
            found = sorted(f.parent for f in p.rglob("final.exr"))
            if not found:
                raise FileNotFoundError(f"{p}: no final.exr in or below it")
            runs.extend(found)
    return runs


@dataclass(frozen=True)
class Comparison:
    """One image against the closed form over one pixel set."""

    pixels: int
    rel_mse: float
    time_s: float
    efficiency: float
    mean_difference: float  # mean over pixels and channels of (x - r)
    standard_error: float  # of that mean, from the variance layer
    z: float


def compare(
    image: np.ndarray, variance: np.ndarray, expected: np.ndarray, select: np.ndarray, time_s: float
) -> Comparison:
    """relMSE = mean((x - r)^2 / (r^2 + 0.01)) over the set's pixels and
    channels (the harness's definition), and z of the mean difference.

    The mean difference D averages (x - r) over N pixels and 3 channels; the
    pixels are independent, the channels of one pixel are not (here they are
    exactly proportional per sample: white floor, one light), so its
    standard error is sqrt(sum_i (sum_c sd_ic)^2) / (3 N), the upper bound of
    Cauchy-Schwarz, which is exact for fully correlated channels."""
    x, r, v = image[select], expected[select], variance[select]
    n = int(select.sum())
    if n == 0:
        return Comparison(0, math.nan, time_s, math.nan, math.nan, math.nan, math.nan)
    d = x - r
    rel = float(np.mean(d * d / (r * r + REL_EPSILON)))
    se = math.sqrt(float(np.sum(np.sum(np.sqrt(v), axis=-1) ** 2))) / (3 * n)
    mean_d = float(np.mean(d))
    z = mean_d / se if se > 0 else (0.0 if mean_d == 0 else math.copysign(math.inf, mean_d))
    return Comparison(n, rel, time_s, efficiency(rel, time_s), mean_d, se, z)


@dataclass(frozen=True)
class Row:
    run: str
    image: str
    strategy: str
    spp: int
    scene: str
    pixel_set: str
    comparison: Comparison
    ratio_vs_light: float = math.nan


def evaluate(
    runs: list[Path], n: int, insets: list[Inset], snapshots: bool, skipped: list[str] | None = None
) -> tuple[list[Row], dict[str, ClosedForm]]:
    """Every run's final.exr (and its snapshots, if asked) against the closed
    form. Runs the model does not describe (another scene, the path
    integrator) raise ModelMismatch, or are listed in `skipped` if given."""
    forms: dict[str, ClosedForm] = {}
    rows: list[Row] = []
    for run in runs:
        try:
            cfg = load_config(run)
            key = scene_key(cfg)
            if key not in forms:
                forms[key] = closed_form_for(cfg, n)
        except ModelMismatch as e:
            if skipped is None:
                raise
            skipped.append(f"{run}: {e}")
            continue
        form = forms[key]
        sets = form.pixel_sets(insets)
        images = sorted(run.glob("snapshot_*.exr")) if snapshots else []
        for path in [*images, run / "final.exr"]:
            snap = exr.read_snapshot(path)
            if snap.rgb.shape != form.expected.shape:
                raise ModelMismatch(f"{path}: image {snap.rgb.shape} but config.yaml says {form.expected.shape}")
            for name, select in sets.items():
                c = compare(snap.rgb, snap.variance, form.expected, select, snap.header.render_time_s)
                rows.append(Row(str(run), path.name, snap.header.strategy, snap.header.spp, key, name, c))
    return _with_ratios(rows), forms


def _with_ratios(rows: list[Row]) -> list[Row]:
    """Efficiency of each strategy over that of `light`, per scene and pixel set,
    from the final images; several runs of a strategy pool as
    1 / (mean relMSE x mean time)."""
    finals = [r for r in rows if r.image == "final.exr"]
    pooled: dict[tuple[str, str, str], float] = {}
    groups: dict[tuple[str, str, str], list[Comparison]] = {}
    for r in finals:
        groups.setdefault((r.scene, r.pixel_set, r.strategy), []).append(r.comparison)
    for k, cs in groups.items():
        pooled[k] = efficiency(float(np.mean([c.rel_mse for c in cs])), float(np.mean([c.time_s for c in cs])))
    out = []
    for r in rows:
        base = pooled.get((r.scene, r.pixel_set, "light"), math.nan)
        ratio = pooled[(r.scene, r.pixel_set, r.strategy)] / base if r.image == "final.exr" and base > 0 else math.nan
        out.append(Row(r.run, r.image, r.strategy, r.spp, r.scene, r.pixel_set, r.comparison, ratio))
    return out


def pooled_ratios(rows: list[Row]) -> dict[tuple[str, str, str], float]:
    """(scene, pixel set, strategy) -> efficiency ratio vs light."""
    return {(r.scene, r.pixel_set, r.strategy): r.ratio_vs_light for r in rows if r.image == "final.exr"}
