"""`summary.tex`: booktabs tables of an experiment's tidy summary, for a paper.

One table per (facet values, region): a row per (point, strategy) with
the efficiency 1/(relMSE x time), the efficiency relative to light
sampling and the equal-error speed-up, each as mean \\pm one standard error
over the replicates (summary.py). A value that is only a bound, as the
summary says (`bound`: the reference does not resolve the error, so the
efficiency is a lower bound; `speedup_bound`: the curves only bound the
time), is marked \\geq or \\leq (\\sim where replicates bound it from both
sides). Numbers keep two significant digits of their standard error and
the value is rounded to the same place; values beyond 10^4 or below
10^-3 share a power of ten with their error. In an experiment with
`precision:`, a headline value whose relative standard error did not reach
the target is marked \\dagger (precision.py).

Written by `portal-harness figures` next to summary.csv, from the stored
summary only (nothing is rendered). Needs \\usepackage{booktabs}.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from portal_harness.analysis import precision
from portal_harness.core.exr import REGION_CLASSES
from portal_harness.core.metrics import WHOLE_IMAGE
from portal_harness.core.regions import LIT
from portal_harness.experiment import facets
from portal_harness.experiment.spec import format_value

# (value column, standard error column, bound column, heading)
MEASURES = (
    ("efficiency", "efficiency_stderr", "bound", "efficiency"),
    ("efficiency_vs_light", "efficiency_vs_light_stderr", "bound", "rel.\\ to light"),
    ("speedup_equal_error", "speedup_equal_error_stderr", "speedup_bound", "speed-up"),
)
BOUND_MARKS = {"lower": "\\geq ", "upper": "\\leq ", "mixed": "\\sim "}
UNREACHED_MARK = "\\,\\dagger"  # a value short of its precision target
_SPECIAL = {
    "\\": "\\textbackslash{}",
    "&": "\\&",
    "%": "\\%",
    "$": "\\$",
    "#": "\\#",
    "_": "\\_",
    "{": "\\{",
    "}": "\\}",
    "~": "\\textasciitilde{}",
    "^": "\\textasciicircum{}",
}


def escape(text: str) -> str:
    """Text for LaTeX: underscores and the other special characters escaped."""
    return "".join(_SPECIAL.get(c, c) for c in text)


def _finite(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)


def format_measure(value: Any, stderr: Any = None, bound: str = "", unreached: bool = False) -> str:
    """`$2.31 \\pm 0.12$`, `$\\geq 40.1 \\pm 2.3$`, `$(1.23 \\pm 0.05) \\times 10^{4}$`; `--` when missing;
    `unreached`: `\\dagger` after it (its precision target not reached)."""
    v = _finite(value)
    mark = UNREACHED_MARK if unreached else ""
    if v is None:
        return f"--${mark}$" if mark else "--"
    s = _finite(stderr)
    exponent = math.floor(math.log10(abs(v))) if v != 0 else 0
    scale = exponent if exponent >= 4 or exponent <= -4 else 0
    v /= 10.0**scale
    if s is not None and s > 0:
        s /= 10.0**scale
        decimals = min(max(0, 1 - math.floor(math.log10(s))), 8)
        text = f"{v:.{decimals}f} \\pm {s:.{decimals}f}"
    else:
        decimals = min(max(0, 2 - math.floor(math.log10(abs(v)))) if v != 0 else 2, 8)
        text = f"{v:.{decimals}f}"
    if scale:
        text = f"({text}) \\times 10^{{{scale}}}"
    return f"${BOUND_MARKS.get(bound or '', '')}{text}{mark}$"


def region_title(region: str, kind: str = "") -> str:
    if region == WHOLE_IMAGE:
        return "whole image"
    if region == LIT:
        return "lit pixels"
    if region in REGION_CLASSES or kind == "class":
        return region.replace("_", "-")
    return f"inset {region}"


def _label(*parts: str) -> str:
    return "tab:" + "-".join(re.sub(r"[^A-Za-z0-9]+", "-", p).strip("-") for p in parts if p)


def _facet_groups(rows: Sequence[dict[str, Any]], facet_keys: Sequence[str]) -> list[tuple[tuple[str, str], ...]]:
    """The facet combinations of the rows (as --set text), in order of appearance."""
    out: list[tuple[tuple[str, str], ...]] = []
    for r in rows:
        combo = tuple((k, format_value(r.get(k))) for k in facet_keys)
        if combo not in out:
            out.append(combo)
    return out


def _point_label(row: dict[str, Any], by_axis: bool) -> str:
    axis = _finite(row.get("axis"))
    return f"{axis:g}" if by_axis and axis is not None else escape(str(row["point"]))


def table(
    name: str,
    rows: Sequence[dict[str, Any]],
    region: str,
    combo: tuple[tuple[str, str], ...],
    axis_label: str | None,
) -> str:
    """One booktabs table: the rows of one region and facet combination, one line per (point, strategy)."""
    mine = [r for r in rows if r["region"] == region and all(format_value(r.get(k)) == v for k, v in combo)]
    points: list[str] = []
    for r in mine:
        if r["point"] not in points:
            points.append(r["point"])
    # The axis value names a point when it tells the table's points apart.
    axis_values = {r["point"]: r.get("axis") for r in mine}
    by_axis = axis_label is not None and len({format_value(v) for v in axis_values.values()}) == len(points)
    point_heading = escape(axis_label) if by_axis and axis_label else "point"
    columns = "l" + "l" + "r" * len(MEASURES)
    lines = [
        "\\begin{table}[htbp]",
        "\\centering",
        "\\small",
        f"\\begin{{tabular}}{{{columns}}}",
        "\\toprule",
        " & ".join([point_heading, "strategy", *(m[3] for m in MEASURES)]) + " \\\\",
        "\\midrule",
    ]
    for p_i, point in enumerate(points):
        if p_i > 0:
            lines.append("\\addlinespace")
        for s_i, r in enumerate(x for x in mine if x["point"] == point):
            cells = [_point_label(r, by_axis) if s_i == 0 else "", escape(str(r["strategy"]))]
            cells += [
                format_measure(r.get(v), r.get(se), str(r.get(b) or ""), precision.unreached(r, v))
                for v, se, b, _ in MEASURES
            ]
            lines.append(" & ".join(cells) + " \\\\")
    reps = sorted({int(r["replicates"]) for r in mine if _finite(r.get("replicates"))})
    rep_text = "/".join(str(k) for k in reps) if reps else "0"
    kind = str(mine[0].get("region_kind") or "") if mine else ""
    facet_text = ", ".join(escape(facets.label(k, v)) for k, v in combo)
    caption = (
        f"{escape(name)}: {escape(region_title(region, kind))}{', ' + facet_text if facet_text else ''}. "
        "Efficiency $1/(\\mathrm{relMSE}\\times t)$ (reference noise removed), relative to light sampling, "
        "and speed-up at light's final error; mean $\\pm$ one standard error over "
        f"{rep_text} replicates. $\\geq$/$\\leq$: a lower/upper bound."
    )
    targets = {t for r in mine if (t := _finite(r.get("precision_target"))) is not None}
    if targets:
        missed = any(precision.unreached(r, v) for r in mine for v, _, _, _ in MEASURES)
        caption += f" Precision target: relative standard error {'/'.join(f'{t:g}' for t in sorted(targets))}" + (
            "; $\\dagger$: not reached." if missed else ", reached by every value."
        )
    lines += [
        "\\bottomrule",
        "\\end{tabular}",
        f"\\caption{{{caption}}}",
        f"\\label{{{_label(name, *(f'{facets.short_key(k)}-{v}' for k, v in combo), region)}}}",
        "\\end{table}",
    ]
    return "\n".join(lines) + "\n"


def document(name: str, rows: Sequence[dict[str, Any]], facet_keys: Sequence[str], axis_label: str | None) -> str:
    """Every table of an experiment: per facet combination, one per region (in the summary's order)."""
    regions: list[str] = []
    for r in rows:
        if r["region"] not in regions:
            regions.append(r["region"])
    parts = [
        f"% {name}: generated by `portal-harness figures` from summary.csv (the tidy summary); "
        "do not edit.\n% Needs \\usepackage{booktabs}.\n"
    ]
    for combo in _facet_groups(rows, facet_keys):
        parts += [table(name, rows, region, combo, axis_label) for region in regions]
    return "\n".join(parts)


def write(
    path: Path, name: str, rows: Sequence[dict[str, Any]], facet_keys: Sequence[str], axis_label: str | None
) -> Path:
    """Writes summary.tex atomically (a temporary name, then a rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(document(name, rows, facet_keys, axis_label))
    tmp.replace(path)
    return path
