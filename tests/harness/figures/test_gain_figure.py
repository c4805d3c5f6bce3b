"""figures/gain.py: the share of a strategy's gain over light that survives
with path tracing, computed from two stored summaries, never typed in."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from portal_harness.core.paths import ResultsLayout
from portal_harness.figures import gain as gain_figure


def _row(strategy: str, axis: float, region: str, value: float, se: float) -> dict[str, object]:
    return {
        "strategy": strategy,
        "axis": axis,
        "region": region,
        "efficiency_vs_light": value,
        "efficiency_vs_light_stderr": se,
    }


def test_01_survival_and_its_standard_error() -> None:
    direct = [_row("antishadow_exact", 1.0, "lit", 4.0, 0.4), _row("antishadow_exact", 4.0, "lit", 8.0, 0.8)]
    path = [_row("antishadow_exact", 1.0, "lit", 1.0, 0.1), _row("light", 1.0, "lit", 1.0, 0.0)]
    (g,) = gain_figure.gains(direct, path, "antishadow_exact")
    assert (g.axis, g.direct, g.path) == (1.0, 4.0, 1.0)
    assert g.survival == pytest.approx(0.25)
    # independent relative errors of 10 % each add in quadrature
    assert g.survival_se == pytest.approx(0.25 * math.sqrt(0.1**2 + 0.1**2))
    text = gain_figure.caption([g], "lit", "antishadow_exact", "ratio")
    assert "ratio 1: 4 ± 0.4 -> 1 ± 0.1 (0.25 ± 0.035)" in text


def test_02_the_numbers_come_from_the_stored_summaries(tmp_path: Path) -> None:
    layout = ResultsLayout(tmp_path)
    for name, value in (("direct", 5.0), ("path", 2.0)):
        path = layout.summary_json(name)
        path.parent.mkdir(parents=True)
        path.write_text(json.dumps({"rows": [_row("antishadow_exact", 0.25, "lit", value, 0.5)]}))
    rows = gain_figure._rows(layout, "direct")
    (g,) = gain_figure.gains(rows, gain_figure._rows(layout, "path"), "antishadow_exact")
    assert g.survival == pytest.approx(0.4)
    from portal_harness.core.errors import HarnessError

    with pytest.raises(HarnessError, match="no summary of experiment 'missing'"):
        gain_figure._rows(layout, "missing")


def test_03_a_committed_summary_csv_stands_in_for_a_missing_json(tmp_path: Path) -> None:
    # A FULL experiment run alone in a fresh clone: its partner's summary.json
    # was never written here, only the committed summary.csv is.
    layout = ResultsLayout(tmp_path)
    csv_path = layout.summary_csv("direct")
    csv_path.parent.mkdir(parents=True)
    csv_path.write_text(
        "point,axis,strategy,region,efficiency_vs_light,efficiency_vs_light_stderr\n"
        "s_L=0.075,0.25,antishadow_exact,lit,5.0,0.5\n"
        "s_L=0.075,0.25,light,lit,1.0,\n"
    )
    path_json = layout.summary_json("path")
    path_json.parent.mkdir(parents=True)
    path_json.write_text(json.dumps({"rows": [_row("antishadow_exact", 0.25, "lit", 2.0, 0.5)]}))
    (g,) = gain_figure.gains(gain_figure._rows(layout, "direct"), gain_figure._rows(layout, "path"), "antishadow_exact")
    assert (g.axis, g.direct, g.direct_se, g.path) == (0.25, 5.0, 0.5, 2.0)
    # The JSON wins where both exist.
    layout.summary_json("direct").write_text(json.dumps({"rows": [_row("antishadow_exact", 0.25, "lit", 8.0, 0.5)]}))
    (g,) = gain_figure.gains(gain_figure._rows(layout, "direct"), gain_figure._rows(layout, "path"), "antishadow_exact")
    assert g.direct == 8.0
