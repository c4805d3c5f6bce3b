"""The sweep's console report: the references, and the tidy summary's table
of its `lit` (or whole-image) region."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, TextIO

from portal_harness.analysis import summary
from portal_harness.core.metrics import WHOLE_IMAGE
from portal_harness.core.regions import LIT


def fmt(v: Any, spec: str) -> str:
    return format(v, spec) if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def print_table(rows: list[dict[str, Any]], out: TextIO) -> None:
    """The tidy summary's `lit` region (the whole image if there is none), one line per (point, strategy)."""
    region = LIT if any(r["region"] == LIT for r in rows) else WHOLE_IMAGE
    width = max([22, *(len(str(r["point"])) for r in rows)])  # facets make point names longer
    header = (
        f"{'point':<{width}} {'strategy':<17} {'reps':>4} {'time_s':>7} {'relMSE':>10} {'eff/light':>16} "
        f"{'speed-up':>10} {'ref/err':>7}"
    )
    print(f"region {region}:", file=out)
    print(header, file=out)
    print("-" * len(header), file=out)
    for r in summary.wide(rows, region):
        eff = f"{'>' if r.get('bound') else ' '}{fmt(r.get('efficiency_vs_light'), '.3g')}"
        se = fmt(r.get("efficiency_vs_light_stderr"), ".2g")
        if se != "-":
            eff += f" ±{se}"
        mark = {"lower": ">", "upper": "<", "mixed": "~"}.get(r.get("speedup_bound") or "", " ")
        print(
            f"{r['point']:<{width}} {r['strategy']:<17} {r.get('replicates', 0):>4} {fmt(r.get('time_s'), '7.2f'):>7} "
            f"{fmt(r.get('rel_mse'), '10.3e'):>10} {eff:>16} {mark}{fmt(r.get('speedup_equal_error'), '.3g'):>9} "
            f"{fmt(r.get('reference_noise_ratio'), '7.3f'):>7}",
            file=out,
        )
    print(
        "(eff/light: efficiency relative to light sampling, reference noise removed, ± a standard error over "
        "replicates; '>' a lower bound where the reference does not resolve the error; speed-up: light's time "
        "over the time to reach light's final error, '>'/'<' where the curve only bounds it; ref/err: reference "
        "noise over the run's error)",
        file=out,
    )


def print_references(info: list[dict[str, Any]], out: TextIO) -> None:
    for ref in info:
        parts = ", ".join(f"{p['strategy']} {fmt(p['time_s'], '.1f')} s/{p['spp']} spp" for p in ref["parts"])
        worst = max((c for c in ref["noise"] if c["ratio"] is not None), key=lambda c: c["ratio"], default=None)
        noise = f"worst noise ratio {worst['ratio']:.3f} ({worst['region']})" if worst else "noise ratio -"
        capped = ", capped: values there are bounds" if ref["capped"] else ""
        print(
            f"reference {ref['point']}: {parts}; bias |z| max {fmt(ref['bias_max_abs_z'], '.2f')}; {noise}{capped}",
            file=out,
        )


def print_report(
    name: str,
    runs: int,
    reference_renders: int,
    manifests: dict[str, dict[str, Any]],
    info: list[dict[str, Any]],
    rows: list[dict[str, Any]],
    summary_path: Path,
    problems: list[str],
    failures: list[str],
    out: TextIO,
) -> None:
    """The end of a sweep: what was rendered, the references, the table, the problems and failures."""
    # Combined references are computed, not rendered: they have no command.
    rendered = sum(1 for m in manifests.values() if not m.get("cached") and m.get("command"))
    cached = sum(1 for m in manifests.values() if m.get("cached") and m.get("command"))
    print(
        f"sweep {name}: {runs} runs, {reference_renders} reference renders, {rendered} rendered now, {cached} cached",
        file=out,
    )
    print_references(info, out)
    print_table(rows, out)
    print(f"summary: {summary_path} (and .csv: one row per point, strategy and region)", file=out)
    for p in problems:
        print(f"problem: {p}", file=out)
    if failures:
        print(f"{len(failures)} failed:", file=out)
        for f in failures:
            print(f"  {f}", file=out)
