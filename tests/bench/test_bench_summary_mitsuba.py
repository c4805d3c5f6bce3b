"""The bench's Mitsuba comparison as summary.md reports it
(renderer/bench/summary.py: mitsuba), and the robust-mode switch of
renderer/bench/mitsuba_time.py that its third run per round uses. The
committed results/bench/mitsuba.json stands in for a run."""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))  # repo_paths.py
from repo_paths import REPO

sys.path.insert(0, str(REPO / "renderer" / "bench"))

import summary
from mitsuba_time import parse_args

RESULT = REPO / "results" / "bench" / "mitsuba.json"


def committed() -> dict[str, Any]:
    d: dict[str, Any] = json.loads(RESULT.read_text())
    return d


def without_robust(d: dict[str, Any]) -> dict[str, Any]:
    d = copy.deepcopy(d)
    for row in d["results"]["table"].values():
        row.pop("ratio_vs_robust", None)
        row.pop("mitsuba_robust_steady_samples_per_s", None)
    return d


def test_robust_ratios_are_reported_per_integrator() -> None:
    d = without_robust(committed())
    t = d["results"]["table"]
    t["direct"]["ratio_vs_robust"] = {"median": 1.234, "min": 1.1, "max": 1.3, "n": 5}
    t["direct"]["mitsuba_robust_steady_samples_per_s"] = 4.5e6
    t["path"]["ratio_vs_robust"] = {"median": 0.876, "min": 0.81, "max": 0.9, "n": 5}
    t["path"]["mitsuba_robust_steady_samples_per_s"] = 5.25e6
    text = "\n".join(summary.mitsuba(d))
    line = next(x for x in text.splitlines() if "embree_use_robust_intersections" in x)
    assert "direct 1.23 (1.10-1.30)" in line
    assert "path 0.88 (0.81-0.90)" in line
    # Each integrator's Mitsuba rate goes with its own ratio.
    assert line.index("4.5") < line.index("path")


def test_runs_from_before_the_robust_measurement_still_summarise() -> None:
    text = "\n".join(summary.mitsuba(without_robust(committed())))
    assert "embree_use_robust_intersections" not in text
    assert "Target `light` >= 1x Mitsuba" in text


@pytest.mark.parametrize(("extra", "robust"), [([], False), (["--robust"], True)])
def test_mitsuba_time_robust_switch(extra: list[str], robust: bool) -> None:
    args = parse_args(["scene.yaml", "--integrator", "path", "--spp", "4", "--passes", "2", *extra])
    assert args.robust is robust
