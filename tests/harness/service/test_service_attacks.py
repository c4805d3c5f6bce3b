"""Issue 42, the attacker's second pass: inputs that the item tests do not
name, each refused with a located 4xx (or a 404 for a read) and leaving
nothing behind; no 500 anywhere."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from fastapi.testclient import TestClient
from service_client import AUTH, TINY, experiment_text, make_client_fixture, refused, root_fixture, with_line

FIXTURES = (make_client_fixture, root_fixture)
BUDGET = {"time_s": 0.2, "threads": 1, "seed": 1, "snapshots": {"every": 0.05}}


def deep(levels: int) -> str:
    return with_line(TINY, "name: svc_tiny", "name: svc_tiny\ndescription: " + "[" * levels + "]" * levels)


ATTACKS = [
    # A snapshot period so small that the count overflows (T / 5e-324 is inf).
    ("denormal_period", experiment_text(budget={**BUDGET, "snapshots": {"every": 5e-324}}), "max_snapshots"),
    ("nano_period", experiment_text(budget={**BUDGET, "snapshots": {"every": 1e-9}}), "max_snapshots"),
    ("every_spp_huge_spp", experiment_text(budget={**BUDGET, "spp": 2**31 - 1, "snapshots": {"every_spp": 1}}), "max"),
    ("deep_nesting", deep(5000), "syntax"),
    ("fullwidth_name", experiment_text(name="\uff53\uff56\uff43"), "plain name"),
    ("rtl_override_name", experiment_text(name="svc\u202egpj.exe"), "plain name"),
    ("cyrillic_a_name", experiment_text(name="svc_tiny_\u0430"), "plain name"),
    ("dotdot_name", experiment_text(name=".."), "plain name"),
    ("negative_time", experiment_text(budget={**BUDGET, "time_s": -1}), ">= 0"),
    ("zero_budget", experiment_text(budget={**BUDGET, "time_s": 0}), "time_s > 0 or spp > 0"),
    ("zero_replicates", experiment_text(budget={**BUDGET, "replicates": 0}), ">= 1"),
    ("negative_seed", experiment_text(budget={**BUDGET, "seed": -1}), ">= 0"),
    ("zero_threads", experiment_text(budget={**BUDGET, "threads": 0}), ">= 1"),
    ("huge_film", experiment_text(fixed={"params.s_P": 0.3, "film.width": 16384, "film.height": 16384}), "max_pixels"),
    ("film_past_renderer", experiment_text(fixed={"params.s_P": 0.3, "film.width": 100000}), "width"),
    (
        "reference_forever",
        experiment_text(reference={"strategy": "light", "time_s": 1, "max_time_s": 1e300}),
        "max_total",
    ),
    ("reference_inf", experiment_text(reference={"strategy": "light", "time_s": float("inf")}), "finite"),
    ("many_points", experiment_text(sweep={"params.s_L": [round(0.01 * i, 2) for i in range(1, 1001)]}), "max_points"),
    (
        "cross_product",
        experiment_text(sweep={"params.s_L": [0.1, 0.2, 0.3], "film.width": list(range(8, 3008))}),
        "max_points",
    ),
    ("key_with_newline", experiment_text(fixed={"params.s_P\nx": 0.3}), "dotted key"),
    ("value_with_nul", experiment_text(fixed={"params.s_P": 0.3, "film.width": "16\x00"}), "control"),
    (
        "many_insets",
        experiment_text(insets=[{"name": f"i{i}", "x": 0, "y": 0, "width": 1, "height": 1} for i in range(65)]),
        "at most 64",
    ),
    ("huge_inset", experiment_text(insets=[{"name": "a", "x": 0, "y": 0, "width": 10**30, "height": 1}]), "<="),
    ("nan_lit_threshold", experiment_text(regions={"lit_threshold": float("nan")}), "finite"),
    # Names too long for the file system (ENAMETOOLONG was a 500).
    ("long_scene_name", experiment_text(scene="scenes/" + "a" * 5000 + ".yaml"), "at most 1024"),
    ("deep_scene_path", experiment_text(scene="scenes/" + "/".join(["a"] * 400)), "no such file"),
    ("scene_is_a_folder", experiment_text(scene="scenes"), "not a file (a folder)"),
    (
        "long_section_name",
        experiment_text(figures={"region_sections": {"scene": "scenes/" + "b" * 300}}),
        "no such file",
    ),
    ("python_tag_deep", with_line(TINY, "seed: 1\n", "seed: !!python/name:os.system\n"), "tag"),
    ("binary_tag", with_line(TINY, "name: svc_tiny", "name: !!binary aGVsbG8="), "tag"),
]


@pytest.mark.parametrize(("case", "text", "words"), ATTACKS, ids=[a[0] for a in ATTACKS])
def test_01_attacks_are_located_4xx_and_leave_nothing(
    make_client: Callable[..., TestClient], case: str, text: str, words: str
) -> None:
    body = refused(make_client(parallel=0), text)
    assert words in body["message"], body


def test_02_reads_with_odd_paths_are_404_never_500(make_client: Callable[..., TestClient]) -> None:
    client = make_client(parallel=0)
    for path in (
        "/api/experiments/%00",
        "/api/experiments/..%2F..%2Findex.sqlite",
        "/api/experiments/" + "x" * 5000,
        "/api/experiments/%00/events",
        "/api/experiments/%00/viewer/%00",
        "/api/runs/%00/image.png",
        "/api/runs/%00/image.exr?image=%00",
    ):
        assert client.get(path).status_code == 404, path
    assert client.get("/api/experiments/x?runs=maybe").status_code == 422
    assert client.delete("/api/experiments/%00", headers=AUTH).status_code == 404
