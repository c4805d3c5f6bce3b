"""docs/results.md's generated tables (analysis/results_page.py and
`portal-harness results-page`): read from the stored summaries only, values
with their standard errors and bound marks, FULL runs marked, the page's
prose kept, and the committed page current with the committed summaries."""

from __future__ import annotations

import csv
import re
import shutil
from pathlib import Path

import pytest
from conftest import REPO

from portal_harness.analysis import results_page as rp
from portal_harness.cli import main
from portal_harness.core.errors import HarnessError

FIELDS = ["point", "strategy", "status", "region", "region_kind", "replicates"]
FIELDS += [
    "efficiency_vs_light",
    "efficiency_vs_light_stderr",
    "bound",
    "precision_target",
    "efficiency_vs_light_rel_se",
    "rel_mse",
    "rel_mse_stderr",
    "spp",
]


def _summary(folder: Path, rows: list[dict[str, str]]) -> None:
    folder.mkdir(parents=True)
    with (folder / "summary.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in FIELDS})


def _row(point: str, strategy: str, region: str, value: str, stderr: str, **extra: str) -> dict[str, str]:
    kind = "inset" if region not in ("lit", "image") else region
    row = {"point": point, "strategy": strategy, "status": "done", "region": region, "region_kind": kind}
    row |= {"replicates": "5", "efficiency_vs_light": value, "efficiency_vs_light_stderr": stderr}
    return row | extra


@pytest.mark.parametrize(
    ("value", "stderr", "bound", "text"),
    [
        ("2.3147", "0.4012", "", "2.31 +- 0.40"),
        ("6.27", "1.04", "lower", ">= 6.3 +- 1.0"),
        ("0.0000525", "0.0000024", "", "0.0000525 +- 0.0000024"),
        ("11.0", "", "upper", "<= 11.0"),
        ("nan", "0.1", "", "-"),
        ("", "", "", "-"),
    ],
)
def test_01_values_keep_two_digits_of_their_error_and_their_bound(
    value: str, stderr: str, bound: str, text: str
) -> None:
    assert rp.format_value(value, stderr, bound) == text


def test_02_a_table_per_experiment_lit_then_insets_light_left_out(tmp_path: Path) -> None:
    rows = [
        _row("s_L=0.075", "light", "lit", "1.0", "0.01"),
        _row("s_L=0.075", "antishadow", "lit", "2.58", "0.35"),
        _row("s_L=0.075", "antishadow", "floor", "3.1", "0.2", bound="lower"),
        _row("s_L=0.075", "antishadow", "image", "9.9", "0.1"),  # not a headline region
        _row("s_L=1.2", "antishadow", "lit", "6.27", "1.0") | {"status": "failed"},
    ]
    text = rp.experiment_table("lampshade_ratio_full", rows)
    assert "### `lampshade_ratio_full`: FULL (paper quality)" in text
    assert "| point | region | `antishadow` |" in text and "| `light`" not in text
    assert "| s_L=0.075 | lit | 2.58 +- 0.35 |" in text
    assert "| s_L=0.075 | inset floor | >= 3.10 +- 0.20 |" in text
    assert "9.9" not in text and "s_L=1.2" not in text  # whole image, failed runs
    assert "small default" in rp.experiment_table("lampshade_ratio", rows)


def test_03_the_block_is_replaced_and_the_prose_kept(tmp_path: Path) -> None:
    experiments = tmp_path / "experiments"
    _summary(experiments / "a_full", [_row("p", "antishadow", "lit", "2.0", "0.1")])
    _summary(experiments / "b", [_row("p", "antishadow", "lit", "5.0", "0.1")])
    page = tmp_path / "results.md"
    page.write_text(f"# Results\n\nProse before.\n\n{rp.BEGIN}\nold table\n{rp.END}\n\nProse after.\n")
    assert rp.write_page(page, experiments)
    text = page.read_text()
    assert text.startswith("# Results\n\nProse before.\n\n") and text.endswith("\n\nProse after.\n")
    assert "old table" not in text and "2.00 +- 0.10" in text
    assert "`b`" not in text  # by default only FULL summaries: those are committed
    assert not rp.write_page(page, experiments)  # regenerated: unchanged
    rp.write_page(page, experiments, ["b", "a_full"])
    assert text.index("`a_full`") < page.read_text().index("`b`")  # FULL first


def test_04_a_page_without_the_block_or_summaries_is_an_error(tmp_path: Path) -> None:
    page = tmp_path / "results.md"
    page.write_text("# Results\n")
    (tmp_path / "experiments").mkdir()
    with pytest.raises(HarnessError, match="no experiment summaries"):
        rp.write_page(page, tmp_path / "experiments")
    _summary(tmp_path / "experiments" / "a_full", [_row("p", "antishadow", "lit", "2.0", "0.1")])
    with pytest.raises(HarnessError, match="no generated block"):
        rp.write_page(page, tmp_path / "experiments")
    assert page.read_text() == "# Results\n"


def test_05_the_committed_page_is_current_and_check_sees_a_stale_one(tmp_path: Path) -> None:
    results = ["--results", str(REPO / "results")]
    assert main(["results-page", "--check", *results]) == 0
    stale = tmp_path / "results.md"
    shutil.copy(REPO / "docs" / "results.md", stale)
    # One value of the generated block changed, whichever the summaries hold today.
    text = stale.read_text()
    value = re.search(r"\| ([0-9.]+) \+- [0-9.]+", text[text.index("results-page: begin") :])
    assert value is not None
    start = text.index("results-page: begin") + value.start(1)
    stale.write_text(text[:start] + "9" + text[start:])
    assert main(["results-page", "--check", "--page", str(stale), *results]) == 1


def test_values_short_of_their_precision_target_are_marked() -> None:
    target = {"precision_target": "0.1"}
    rows = [
        _row("s_L=0.3", "light", "lit", "1.0", "0.01", **target),
        _row("s_L=0.3", "portal", "lit", "0.162", "0.019", efficiency_vs_light_rel_se="0.116", **target),
        _row("s_L=0.3", "antishadow", "lit", "4.38", "0.37", efficiency_vs_light_rel_se="0.085", **target),
    ]
    text = rp.experiment_table("x_full", rows)
    assert "| s_L=0.3 | lit | 0.162 +- 0.019 (\\*) | 4.38 +- 0.37 |" in text
    assert "relative standard error of at most 0.1" in text
    # without precision: no target line, no mark
    plain = rp.experiment_table("x", [{k: v for k, v in r.items() if "precision" not in k} for r in rows])
    assert "(\\*)" not in plain and "Precision target" not in plain


def test_the_readme_table_comes_from_the_full_summaries(tmp_path: Path) -> None:
    from portal_harness.analysis import readme_table as rt

    experiments = tmp_path / "experiments"
    target = {"precision_target": "0.1", "efficiency_vs_light_rel_se": "0.05"}
    _summary(
        experiments / "lampshade_ratio_full",
        [
            _row("s_L=1.2", "light", "lit", "1.0", "0.04", **target),
            _row("s_L=1.2", "antishadow", "lit", "6.56", "0.43", **target),
            _row(
                "s_L=1.2", "antishadow_exact", "lit", "6.96", "0.53", **(target | {"efficiency_vs_light_rel_se": "0.2"})
            ),
        ],
    )
    block = rt.table(experiments)
    assert "| lampshade, ratio 4, direct | 6.56 ± 0.43 | 6.96 ± 0.53 (\\*) | 5 |" in block
    assert "ratio 0.25" not in block  # no such point in the summary
    assert "`white_room_night_full`" in block.split("Not run at paper quality yet:")[1]
    # --check sees a stale README, and the command rewrites only the block
    readme = tmp_path / "README.md"
    readme.write_text(f"# Title\n\nbefore\n\n{rt.BEGIN}\nold\n{rt.END}\n\nafter\n")
    args = ["--results", str(tmp_path), "--page", str(REPO / "docs" / "results.md"), "--readme", str(readme)]
    shutil.copytree(REPO / "results" / "experiments", experiments, dirs_exist_ok=True)  # the page's summaries too
    _summary(experiments / "lampshade_ratio_full2", [])  # not named by any row: ignored
    assert main(["results-page", "--check", *args]) == 1
    text = readme.read_text()
    assert "old" in text
    assert main(["results-page", *args]) == 0
    text = readme.read_text()
    assert text.startswith("# Title\n\nbefore\n\n") and text.endswith("\n\nafter\n") and "old" not in text
    assert main(["results-page", "--check", *args]) == 0
