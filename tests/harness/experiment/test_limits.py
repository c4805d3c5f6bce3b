"""The limits on one experiment's work (experiment/limits.py), as the
command line checks them: `portal-harness sweep` refuses before any render,
--no-limits lifts them, and every experiment of configs/experiments/ (the
`_full` ones included) is within the defaults. Numbers in exponent form
without a dot (`1e12`, a string for YAML 1.1) are numbers, as in the
service."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import REPO

from portal_harness.core.errors import ConfigError
from portal_harness.experiment.limits import LimitError, Limits, snapshot_count
from portal_harness.experiment.loader import load_experiment

BUDGET = {"time_s": 0.2, "threads": 1, "seed": 1, "snapshots": {"every": 0.05}}


def test_01_sweep_refuses_work_over_a_limit_and_no_limits_lifts_it(
    cli: Callable[..., tuple[int, str, str]],
    write_experiment: Callable[..., Path],
    results: Path,
    render_log: Callable[[], list[str]],
) -> None:
    path = write_experiment(sweep={"params.s_L": [0.6]})  # 1 point x 2 strategies: 2 runs
    status, _, err = cli("sweep", str(path), "--max-runs", "1", "--no-progress")
    assert status == 2 and "max_runs" in err and "--max-runs" in err and "2" in err, err
    assert render_log() == [] and not (results / "runs").exists()
    huge = write_experiment("huge", budget={**BUDGET, "replicates": 1_000_000_000})
    status, _, err = cli("sweep", str(huge), "--no-progress")
    assert status == 2 and "max_runs" in err and "4000000000" in err, err  # 2 points
    status, _, err = cli("sweep", str(path), "--max-runs", "1", "--no-limits", "--no-progress")
    assert status == 0, err
    assert len(render_log()) >= 2


def test_02_exponent_numbers_are_numbers_in_every_number_key(
    write_experiment: Callable[..., Path], fake_renderer: Path
) -> None:
    path = write_experiment(budget={**BUDGET, "time_s": "2e-1", "seed": "1e3"})
    experiment = load_experiment(path, str(fake_renderer), limits=Limits())
    assert experiment.budget is not None
    assert experiment.budget.time_s == 0.2 and experiment.budget.seed == 1000
    path = write_experiment("big", budget={**BUDGET, "time_s": "1e12"})
    with pytest.raises(LimitError, match="max_total_time_s") as e:
        load_experiment(path, str(fake_renderer), limits=Limits())
    assert e.value.key == "budget.time_s" and e.value.line is not None
    for bad, words in (("1.5e0", "integer"), ("nan", "number"), ("1e400", "finite")):
        with pytest.raises(ConfigError, match=words):
            load_experiment(
                write_experiment("bad", budget={**BUDGET, "seed" if words == "integer" else "time_s": bad}),
                str(fake_renderer),
            )


def test_03_snapshot_counts_follow_the_schedule() -> None:
    units = {"every": "s", "doubling": "s", "every_spp": "spp", "doubling_spp": "spp"}
    assert snapshot_count((("every", "0.5"),), units, 2.0, 0, 256) == 4
    assert snapshot_count((("doubling", "0.25"),), units, 2.0, 0, 256) == 4  # 0.25 0.5 1 2
    assert snapshot_count((("every_spp", "16"),), units, 0.0, 64, 256) == 4
    assert snapshot_count((("doubling_spp", "1"),), units, 0.0, 64, 256) == 7
    # every_spp: 1 over a 2 s run of 256x256: thousands (the renderer wrote 175 in issue 42).
    assert snapshot_count((("every_spp", "1"),), units, 2.0, 0, 256 * 256) > Limits().max_snapshots


@pytest.mark.real
@pytest.mark.parametrize("path", sorted((REPO / "configs" / "experiments").glob("*.yaml")), ids=lambda p: p.stem)
def test_04_every_experiment_of_the_repository_is_within_the_defaults(path: Path, real_renderer: Path) -> None:
    load_experiment(path, str(real_renderer), limits=Limits())


def test_05_precision_is_counted_at_its_max_replicates(
    write_experiment: Callable[..., Path], fake_renderer: Path
) -> None:
    # 2 points x 2 strategies x 3 replicates = 12 runs; precision may run 2 x 2 x 40 = 160
    budget = {**BUDGET, "replicates": 3}
    plain = write_experiment("plain", budget=budget)
    load_experiment(plain, str(fake_renderer), limits=Limits(max_runs=100))
    path = write_experiment("precise", budget=budget, precision={"rel_se": 0.05, "of": ["lit"], "max_replicates": 40})
    with pytest.raises(LimitError, match="max_runs") as e:
        load_experiment(path, str(fake_renderer), limits=Limits(max_runs=100))
    assert e.value.value == 160 and e.value.key == "precision.max_replicates" and e.value.line is not None
    assert "precision.max_replicates" in str(e.value)
    load_experiment(path, str(fake_renderer), limits=Limits(max_runs=160))
    # the time budget counts them too: 160 runs of at most 0.2 s, plus the references
    with pytest.raises(LimitError, match="max_total_time_s"):
        load_experiment(path, str(fake_renderer), limits=Limits(max_total_time_s=160 * 0.2))
    load_experiment(plain, str(fake_renderer), limits=Limits(max_total_time_s=160 * 0.2))
