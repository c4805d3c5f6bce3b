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


def _r(
    point: str, strategy: str, region: str, value: str, se: str, rel_mse: str, spp: str, **extra: str
) -> dict[str, str]:
    return (
        _row(point, strategy, region, value, se, rel_mse=rel_mse, rel_mse_stderr=str(float(rel_mse) / 10), spp=spp)
        | extra
    )


def test_values_are_compared_by_their_combined_standard_error(tmp_path: Path) -> None:
    exp = tmp_path / "experiments"
    _pair(
        exp,
        [
            _r("s_L=1.2", "light", "lit", "1.0", "0.04", "0.004", "500"),
            _r("s_L=1.2", "antishadow", "lit", "6.56", "0.43", "0.001", "400"),
            _r("s_L=1.2", "antishadow", "centre", "50.0", "3.0", "0.0001", "400"),
            _r("s_L=1.2", "portal", "lit", "0.5", "0.1", "0.01", "400", bound="upper"),
            _r("s_L=0.3", "antishadow", "lit", "4.0", "0.2", "0.001", "400"),  # not rerun
            _r("s_L=1.2", "antishadow", "image", "6.0", "0.1", "0.001", "400"),
        ],
        [
            _r("s_L=1.2", "light", "lit", "1.0", "0.05", "0.004", "250"),  # the machine ran at half speed
            _r("s_L=1.2", "antishadow", "lit", "7.16", "0.55", "0.002", "200"),
            _r("s_L=1.2", "antishadow", "centre", "62.0", "4.0", "0.0002", "200"),  # no light row: no per-sample z
            _r("s_L=1.2", "portal", "lit", "0.6", "0.1", "0.01", "200"),  # a bound in the FULL run: not compared
            _r("s_L=1.2", "antishadow", "image", "9.0", "0.1", "0.001", "200"),  # not a headline region
        ],
    )
    cs = ag.comparisons(exp)
    assert [(c.point, c.strategy, c.region) for c in cs] == [
        ("s_L=1.2", "antishadow", "lit"),
        ("s_L=1.2", "antishadow", "centre"),
    ]
    assert cs[0].z == pytest.approx(0.60 / math.hypot(0.43, 0.55))
    assert cs[1].z == pytest.approx(12.0 / 5.0)
    # per sample: (0.004 x 500) / (0.001 x 400) = 5 in the FULL run, (0.004 x 250) / (0.002 x 200) = 2.5 in the
    # rerun, each with a relative error of hypot(0.1, 0.1)
    assert cs[0].full_per_sample is not None and cs[0].full_per_sample.value == pytest.approx(5.0)
    assert cs[0].z_per_sample == pytest.approx(-2.5 / math.hypot(5.0, 2.5) / math.hypot(0.1, 0.1))
    assert cs[1].z_per_sample is None
    assert ag.verdict([c.z for c in cs]) == (
        "1 of 2 values within 2 combined standard errors (50%; a normal gives 95%); largest |z| 2.4"
    )
    block = ag.block(exp)
    assert "`lampshade_ratio_full_rerun`" in block
    row = "| `lampshade_ratio_full` | s_L=1.2 | `antishadow` | 6.56 +- 0.43 (5) | 7.16 +- 0.55 (5) | +0.9 | -3.2 |"
    assert row in block
    assert "centre |" not in block  # the table shows the lit region; the verdicts count the insets too
    assert "per sample (relMSE x spp" in block
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
            full, rerun = ag.Estimate(a, sa * scale), ag.Estimate(b, sb * scale)
            cs.append(ag.Comparison("x_full", str(i), "antishadow", "lit", full, rerun, None, None, "24", "24"))
        return sum(abs(c.z) <= ag.Z_LIMIT for c in cs) / len(cs)

    assert 0.934 <= fraction(1.0) <= 0.974
    assert fraction(0.5) < 0.80
