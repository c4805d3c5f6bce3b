"""Checks lampshade renders (direct integrator) against the closed form of the
floor, per pixel, and reports relMSE, efficiency and efficiency ratios vs
`light` without any rendered reference. See tools/closed_form/README.md.

    .venv/bin/python tools/closed_form/lampshade_floor.py RUN_OR_FOLDER... \
        [--n 16] [--inset NAME=X,Y,W,H]... [--snapshots] [--json OUT|-]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import TextIO

from floor_check import FLOOR_SET, Inset, Row, evaluate, find_runs
from floor_model import ModelMismatch

from portal_harness.execution.store import finite_or_none


def _fmt(v: float, spec: str = ".4g") -> str:
    return "-" if not math.isfinite(v) else format(v, spec)


def print_table(rows: list[Row], out: TextIO = sys.stdout) -> None:
    header = (
        "run",
        "image",
        "strategy",
        "spp",
        "set",
        "pixels",
        "time_s",
        "relMSE",
        "efficiency",
        "z(mean)",
        "eff/light",
    )
    table = [header]
    for r in rows:
        c = r.comparison
        table.append(
            (
                Path(r.run).name,
                r.image,
                r.strategy,
                str(r.spp),
                r.pixel_set,
                str(c.pixels),
                _fmt(c.time_s, ".3f"),
                _fmt(c.rel_mse, ".4e"),
                _fmt(c.efficiency, ".4e"),
                _fmt(c.z, "+.2f"),
                _fmt(r.ratio_vs_light, ".4g"),
            )
        )
    widths = [max(len(row[i]) for row in table) for i in range(len(header))]
    for row in table:
        print(
            "  ".join(
                cell.rjust(w) if i >= 3 else cell.ljust(w) for i, (cell, w) in enumerate(zip(row, widths, strict=True))
            ),
            file=out,
        )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", type=Path, help="run folders, or folders holding run folders")
    ap.add_argument("--n", type=int, default=16, help="sub-pixel grid n x n (midpoint rule; 2n estimates its error)")
    ap.add_argument(
        "--inset",
        action="append",
        default=[],
        type=Inset.parse,
        metavar="NAME=X,Y,W,H",
        help="also report this rectangle (pixels, row 0 at the top), intersected with the mask",
    )
    ap.add_argument("--snapshots", action="store_true", help="also report every snapshot_*.exr")
    ap.add_argument("--json", metavar="OUT", help="write the rows as JSON to OUT ('-': stdout, no table)")
    args = ap.parse_args(argv)
    if args.n < 1:
        ap.error("--n must be at least 1")
    skipped: list[str] = []
    try:
        rows, forms = evaluate(find_runs(args.runs), args.n, args.inset, args.snapshots, skipped)
    except (ModelMismatch, FileNotFoundError, ValueError) as e:
        print(f"lampshade_floor: {e}", file=sys.stderr)
        return 2
    for s in skipped:
        print(f"lampshade_floor: skipped {s}", file=sys.stderr)
    if not rows:
        print("lampshade_floor: no run of the lampshade with the direct integrator", file=sys.stderr)
        return 2
    info = sys.stdout if args.json != "-" else sys.stderr
    for key, form in forms.items():
        m = form.model
        err = form.integration_error(form.mask)
        print(
            f"scene {key}: s_L={m.s_light:g} s_P={m.s_portal:g} ratio={m.s_light / m.s_portal:g} "
            f"film {m.camera.width}x{m.camera.height}: mask {int(form.mask.sum())} pixels "
            f"({int(form.pixel_sets([])['lit'].sum())} lit); integration n={form.coarse.n} vs {form.fine.n}: "
            f"max pixel error {err['max_error_vs_peak']:.2e} of the peak, relMSE {err['rel_mse']:.2e}",
            file=info,
        )
        for r in rows:
            if r.scene == key and r.image == "final.exr" and r.pixel_set == FLOOR_SET and r.comparison.pixels:
                z_int = err["mean_difference"] / r.comparison.standard_error
                print(
                    f"  {Path(r.run).name}: integration error of the mean = {z_int:+.3f} standard errors of the "
                    f"render, {err['rel_mse'] / r.comparison.rel_mse:.1e} of its relMSE",
                    file=info,
                )
    if args.json != "-":
        print_table(rows)
    if args.json:
        doc = [
            {
                k: finite_or_none(v)  # strict JSON: NaN -> null
                for k, v in {**dataclasses.asdict(r), **dataclasses.asdict(r.comparison)}.items()
                if k != "comparison"
            }
            for r in rows
        ]
        text = json.dumps(doc, indent=1, allow_nan=False)
        if args.json == "-":
            print(text)
        else:
            Path(args.json).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
