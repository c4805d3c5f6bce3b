"""Issue 42, items 2, 4, 5: every input that asks for too much work, names
a path outside the roots or holds a value no experiment can have is
refused with a located 4xx (file, key, line) before anything is made: no
folder under results/service/, no queue row, no render, and at once (no
plan of a billion runs is built first)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from service_client import (
    TINY,
    experiment_text,
    make_client_fixture,
    refused,
    root_fixture,
    submit,
    tmp_results,
    with_line,
)

from portal_harness.experiment.limits import Limits

FIXTURES = (make_client_fixture, root_fixture)

# Item 5: each of these answered 500, or 202 then failed in the worker.
BAD_VALUES = [
    (
        "python_tag",
        with_line(TINY, "name: svc_tiny", "name: !!python/object/apply:os.system ['touch /tmp/pwned']"),
        "name",
        "tag",
    ),
    ("5000_digits", with_line(TINY, "seed: 1\n", f"seed: {'7' * 5000}\n"), "budget.seed", "5000"),
    ("nan", with_line(TINY, "time_s: 0.2", "time_s: .nan"), "budget.time_s", "finite"),
    ("inf", with_line(TINY, "time_s: 0.2", "time_s: .inf"), "budget.time_s", "finite"),
    ("spp_1e20", with_line(TINY, "time_s: 0.2", "time_s: 0.2\n  spp: 100000000000000000000"), "budget.spp", "<="),
    ("threads", with_line(TINY, "threads: 1", "threads: 100000"), "budget.threads", "<= 256"),
    ("seed_1e23", with_line(TINY, "seed: 1\n", "seed: 100000000000000000000000\n"), "budget.seed", "<="),
    ("seed_1e23_exp", with_line(TINY, "seed: 1\n", "seed: 1e23\n"), "budget.seed", "<="),
    ("name_300", with_line(TINY, "name: svc_tiny", "name: " + "n" * 300), "name", "at most 100"),
    ("name_nul", with_line(TINY, "name: svc_tiny", 'name: "svc\\0tiny"'), "name", "control"),
]


@pytest.mark.parametrize(("case", "text", "key", "words"), BAD_VALUES, ids=[c[0] for c in BAD_VALUES])
def test_01_bad_values_are_located_422_and_leave_nothing(
    make_client: Callable[..., TestClient], case: str, text: str, key: str, words: str
) -> None:
    body = refused(make_client(parallel=0), text)
    assert body["key"] == key and words in body["message"], body
    assert not Path("/tmp/pwned").exists()


# Item 2: work beyond the limits, each answered with the limit's name and the value.
def _big(**budget: Any) -> str:
    base = {"time_s": 0.2, "threads": 1, "seed": 1, "snapshots": {"every": 0.05}}
    return experiment_text(budget={**base, **budget})


OVER_LIMITS = [
    ("replicates", _big(replicates=1_000_000_000), "max_runs", 4_000_000_000),
    ("time_1e12", _big(time_s=1_000_000_000_000), "max_total_time_s", None),
    ("time_1e12_exponent", with_line(TINY, "time_s: 0.2", "time_s: 1e12"), "max_total_time_s", None),
    ("every_spp_1", _big(time_s=2, snapshots={"every_spp": 1}), "max_snapshots", None),
]


@pytest.mark.parametrize(("case", "text", "limit", "value"), OVER_LIMITS, ids=[c[0] for c in OVER_LIMITS])
def test_02_work_over_a_limit_is_refused_at_once_naming_the_limit(
    make_client: Callable[..., TestClient], case: str, text: str, limit: str, value: float | None
) -> None:
    body = refused(make_client(parallel=0), text)
    assert body["limit"]["name"] == limit and limit in body["message"], body
    assert float(body["limit"]["value"]) > body["limit"]["maximum"]
    if value is not None:
        assert body["limit"]["value"] == value and str(value) in body["message"]


def test_03_spp_of_10_18_is_over_the_renderers_bound(make_client: Callable[..., TestClient]) -> None:
    body = refused(make_client(parallel=0), with_line(TINY, "time_s: 0.2", "spp: 1000000000000000000"))
    assert body["key"] == "budget.spp" and str(2**31 - 1) in body["message"]


def test_04_the_bytes_of_a_large_film_and_the_configured_limits(make_client: Callable[..., TestClient]) -> None:
    big_film = experiment_text(
        fixed={"params.s_P": 0.3, "film.width": 4096, "film.height": 4096},
        insets=None,
        budget={"time_s": 60, "threads": 1, "seed": 1, "snapshots": {"every": 0.5}},
        reference={"strategy": "light", "time_s": 10, "seed": 99},
    )
    body = refused(make_client(parallel=0), big_film)
    assert body["limit"]["name"] == "max_bytes", body
    # Limits are the service's settings: a lower bound refuses the tiny experiment (4 runs) ...
    client = make_client(parallel=0, limits=Limits(max_runs=3))
    body = refused(client, TINY)
    assert body["limit"] == {"name": "max_runs", "value": 4, "maximum": 3}
    assert "--max-runs" in body["message"]
    # ... and the defaults let it through.
    experiment_id = submit(make_client(parallel=0), TINY)
    assert (tmp_results(client) / "service" / experiment_id / "experiment.yaml").is_file()


def test_05_figures_compare_names_an_experiment_never_a_path(
    make_client: Callable[..., TestClient], tmp_path: Path
) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "summary.json").write_text(json.dumps({"rows": []}))
    client = make_client(parallel=0)
    answers = []
    for target in ("../../../outside", "../../../nowhere", str(outside), "/etc"):
        body = refused(client, experiment_text(figures={"compare": {"experiment": target, "strategy": "light"}}))
        assert body["key"] == "figures.compare.experiment" and body["line"] is not None
        answers.append(body["message"].split(", got ")[0])  # what is said, but the value given
    # Whether a file exists there or not, the answer is the same.
    assert len(set(answers)) == 1, answers
    assert "summary" not in answers[0] and "exist" not in answers[0]
