"""The check of a FULL run's stated precision (analysis/agreement.py): a
rerun with other seeds compared value by value, z from both standard
errors, bounds and `light` left out, the verdict counted against 2, and
the generated section and README line that `portal-harness results-page`
writes. Plus a Monte Carlo check that the verdict is calibrated: for
values drawn with the standard errors they state, about 95% lie within 2."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pytest
from test_results_page import _row, _summary

from portal_harness.analysis import agreement as ag
from portal_harness.analysis import readme_table
from portal_harness.core.errors import HarnessError


def _pair(experiments: Path, full: list[dict[str, str]], rerun: list[dict[str, str]]) -> None:
    _summary(experiments / "lampshade_ratio_full", full)
    _summary(experiments / "lampshade_ratio_full_rerun", rerun)


def test_values_are_compared_by_their_combined_standard_error(tmp_path: Path) -> None:
    exp = tmp_path / "experiments"
    _pair(
        exp,
        [
            _row("s_L=1.2", "light", "lit", "1.0", "0.04"),
            _row("s_L=1.2", "antishadow", "lit", "6.56", "0.43"),
            _row("s_L=1.2", "antishadow", "centre", "50.0", "3.0"),
            _row("s_L=1.2", "portal", "lit", "0.5", "0.1", bound="upper"),
            _row("s_L=0.3", "antishadow", "lit", "4.0", "0.2"),  # not rerun
            _row("s_L=1.2", "antishadow", "image", "6.0", "0.1"),
        ],
        [
            _row("s_L=1.2", "light", "lit", "1.0", "0.05"),
            _row("s_L=1.2", "antishadow", "lit", "7.16", "0.55"),
            _row("s_L=1.2", "antishadow", "centre", "62.0", "4.0"),
            _row("s_L=1.2", "portal", "lit", "0.6", "0.1"),  # a bound in the FULL run: not compared
            _row("s_L=1.2", "antishadow", "image", "9.0", "0.1"),  # not a headline region
        ],
    )
    cs = ag.comparisons(exp)
    assert [(c.point, c.strategy, c.region) for c in cs] == [
        ("s_L=1.2", "antishadow", "lit"),
        ("s_L=1.2", "antishadow", "centre"),
    ]
    assert cs[0].z == pytest.approx(0.60 / math.hypot(0.43, 0.55))
    assert cs[1].z == pytest.approx(12.0 / 5.0)
    assert ag.verdict(cs) == (
        "1 of 2 values within 2 combined standard errors (50%; a normal gives 95%); largest |z| 2.4"
    )
    block = ag.block(exp)
    assert "`lampshade_ratio_full_rerun`" in block
    assert "| `lampshade_ratio_full` | s_L=1.2 | `antishadow` | 6.56 +- 0.43 (5) | 7.16 +- 0.55 (5) | +0.9 |" in block
    assert "centre |" not in block  # the table shows the lit region; the verdict counts the insets too
    assert "1 of 2 values" in readme_table.table(exp)


def test_without_reruns_the_section_says_so_and_the_readme_says_nothing(tmp_path: Path) -> None:
    exp = tmp_path / "experiments"
    _summary(exp / "lampshade_ratio_full", [_row("s_L=1.2", "antishadow", "lit", "6.56", "0.43")])
    _summary(exp / "other_rerun", [_row("s_L=1.2", "antishadow", "lit", "6.0", "0.4")])  # no FULL of that name
    assert ag.comparisons(exp) == []
    assert "No FULL experiment has a stored rerun yet." in ag.block(exp)
    assert ag.sentence(exp) == ""
    with pytest.raises(HarnessError, match="no values to compare"):
        ag.verdict([])
    with pytest.raises(HarnessError, match="no generated rerun section"):
        ag.replace("# Results\n", ag.block(exp), "results.md")


def test_the_verdict_is_calibrated_for_honest_standard_errors() -> None:
    # 2,000 pairs drawn around one true value with the standard errors they
    # state: the fraction within 2 is 95.4% +- 0.5% (binomial), so 93.4% to
    # 97.4% holds at 4 sigma; errors understated by half fall to about 68%.
    rng = random.Random(20261207)

    def fraction(scale: float) -> float:
        cs = []
        for i in range(2000):
            sa, sb = rng.uniform(0.02, 0.2), rng.uniform(0.02, 0.2)
            a, b = rng.gauss(1.0, sa), rng.gauss(1.0, sb)
            cs.append(ag.Comparison("x_full", str(i), "antishadow", "lit", a, sa * scale, b, sb * scale, "24", "24"))
        return sum(abs(c.z) <= ag.Z_LIMIT for c in cs) / len(cs)

    assert 0.934 <= fraction(1.0) <= 0.974
    assert fraction(0.5) < 0.80
