"""summary.tex (tables.py): booktabs tables of the tidy summary. Checked
for structure and against summary.csv, number by number; no LaTeX
install needed."""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from portal_harness.analysis import tables

CliRunner = Callable[..., tuple[int, str, str]]
# A cell: optional bound mark, value, optional error, optional shared power of ten.
CELL = re.compile(
    r"^\$(?P<mark>\\geq |\\leq |\\sim )?\(?(?P<value>-?\d+(?:\.\d+)?)(?: \\pm (?P<se>\d+(?:\.\d+)?))?\)?"
    r"(?: \\times 10\^\{(?P<exp>-?\d+)\})?\$$"
)


def parse_cell(cell: str) -> tuple[str, float, float | None, float]:
    """(bound mark, value, standard error, half a unit in the last place), powers of ten applied."""
    m = CELL.match(cell.strip())
    assert m is not None, cell
    scale = 10.0 ** int(m["exp"] or 0)
    decimals = len(m["value"].partition(".")[2])
    se = float(m["se"]) * scale if m["se"] else None
    return (m["mark"] or "").strip(), float(m["value"]) * scale, se, 0.5 * 10.0**-decimals * scale


def test_01_numbers_with_their_standard_error() -> None:
    assert tables.format_measure(2.3149, 0.1234) == "$2.31 \\pm 0.12$"
    assert tables.format_measure(23.449, 1.26) == "$23.4 \\pm 1.3$"
    assert tables.format_measure(2345.6, 123.0) == "$2346 \\pm 123$"
    assert tables.format_measure(12345.0, 230.0) == "$(1.234 \\pm 0.023) \\times 10^{4}$"
    assert tables.format_measure(0.0001234, 0.0000056) == "$(1.234 \\pm 0.056) \\times 10^{-4}$"
    assert tables.format_measure(40.12, 2.3, "lower") == "$\\geq 40.1 \\pm 2.3$"
    assert tables.format_measure(0.5, None, "upper") == "$\\leq 0.500$"
    assert tables.format_measure(1.0, 0.0) == "$1.00$"  # light's own speed-up: exact
    assert tables.format_measure(None) == "--" and tables.format_measure(math.nan, 1.0) == "--"
    assert tables.escape("antishadow_exact & 50%") == "antishadow\\_exact \\& 50\\%"


def _row(point: str, axis: float, strategy: str, region: str, **values: Any) -> dict[str, Any]:
    return {"point": point, "axis": axis, "strategy": strategy, "region": region, "replicates": 3, **values}


def test_02_bounds_are_marked_and_points_named() -> None:
    rows = [
        _row("s_L=0.15", 0.5, "light", "lit", efficiency=10.0, efficiency_stderr=1.0, speedup_equal_error=1.0),
        _row(
            "s_L=0.15",
            0.5,
            "antishadow_exact",
            "lit",
            efficiency=250.0,
            efficiency_stderr=12.0,
            bound="lower",
            efficiency_vs_light=25.0,
            efficiency_vs_light_stderr=3.0,
            speedup_equal_error=0.4,
            speedup_bound="upper",
        ),
    ]
    text = tables.table("exp_name", rows, "lit", (), "light/portal ratio")
    body = text.split("\\midrule\n")[1].split("\\bottomrule")[0].strip().splitlines()
    assert body[0].startswith("0.5 & light & $10.0 \\pm 1.0$ & -- & $1.00$")
    assert body[1] == " & antishadow\\_exact & $\\geq 250 \\pm 12$ & $\\geq 25.0 \\pm 3.0$ & $\\leq 0.400$ \\\\"
    assert "exp\\_name: lit pixels." in text and "\\label{tab:exp-name-lit}" in text


def _tables(text: str) -> list[str]:
    return text.split("\\begin{table}")[1:]


def _body(table: str) -> list[list[str]]:
    assert table.count("\\toprule") == table.count("\\midrule") == table.count("\\bottomrule") == 1
    body = table.split("\\midrule\n")[1].split("\\bottomrule")[0]
    lines = [line for line in body.strip().splitlines() if line != "\\addlinespace"]
    assert all(line.endswith(" \\\\") for line in lines)
    return [line.removesuffix(" \\\\").split(" & ") for line in lines]


@pytest.mark.parametrize("with_facets", [False, True], ids=["plain", "facets"])
def test_03_figures_writes_tables_equal_to_the_csv(
    cli: CliRunner, write_experiment: Callable[..., Path], results: Path, with_facets: bool
) -> None:
    sweep: dict[str, list[Any]] = {"params.s_L": [0.15, 0.6]}
    if with_facets:
        sweep["render.portal_weight"] = ["area", "irradiance"]
    strategies = ["light", "portal", "antishadow_exact"]
    budget = {"time_s": 0.2, "threads": 1, "seed": 1, "snapshots": {"every": 0.05}, "replicates": 2}
    exp = write_experiment(sweep=sweep, strategies=strategies, budget=budget)
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    status, out, err = cli("figures", str(exp))
    assert status == 0, err
    tex_path = results / "experiments" / "tiny" / "summary.tex"
    assert str(tex_path) in out
    text = tex_path.read_text()
    with open(results / "experiments" / "tiny" / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    regions = list(dict.fromkeys(r["region"] for r in rows))
    combos = list(dict.fromkeys(r.get("render.portal_weight", "") for r in rows))
    found = _tables(text)
    assert len(found) == len(regions) * len(combos)
    assert text.count("\\begin{table}") == text.count("\\end{table}") == len(found)
    assert "_" not in re.sub(r"\\_|\\label\{[^}]*\}", "", text)  # every underscore escaped
    checked = 0
    for t_i, table in enumerate(found):
        combo, region = combos[t_i // len(regions)], regions[t_i % len(regions)]
        if with_facets:
            assert f"portal\\_weight={combo}" in table
        mine = [r for r in rows if r["region"] == region and r.get("render.portal_weight", "") == combo]
        body = _body(table)
        assert len(body) == len(mine) == 2 * len(strategies)  # one row per point and strategy
        for cells, row in zip(body, mine, strict=True):
            assert cells[1] == tables.escape(row["strategy"])
            if row["strategy"] == "light":
                assert cells[0] == f"{float(row['axis']):g}"
            for cell, (column, se_column, bound_column, _) in zip(cells[2:], tables.MEASURES, strict=True):
                if row[column] == "":
                    assert cell == "--"
                    continue
                mark, value, se, tolerance = parse_cell(cell)
                assert value == pytest.approx(float(row[column]), abs=tolerance * 1.0001), (cell, row[column])
                if row[se_column] not in ("", "0.0"):
                    assert se is not None and se == pytest.approx(float(row[se_column]), abs=tolerance * 1.0001)
                assert mark == {"lower": "\\geq", "upper": "\\leq", "mixed": "\\sim", "": ""}[row[bound_column]]
                checked += 1
    assert checked >= len(found) * 2 * len(strategies) * 2
