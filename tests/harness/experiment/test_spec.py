"""Run keys and scene hashes: stable, and sensitive to exactly what they should be."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from portal_harness.experiment.spec import RunSpec, format_value


def _spec(**changes: Any) -> RunSpec:
    base = RunSpec(
        scene="/s.yaml",
        scene_sha256="ab" * 32,
        strategy="light",
        integrator="direct",
        spp=0,
        time_s=5.0,
        seed=1,
        threads=2,
        overrides=(("params.s_L", "0.3"),),
        snapshots=(("every", "0.5"),),
    )
    return dataclasses.replace(base, **changes)


def test_01_key_is_stable_and_depends_on_every_input() -> None:
    k = _spec().key("0.1.0")
    assert k == _spec().key("0.1.0") and len(k) == 16
    assert _spec(scene="/elsewhere.yaml").key("0.1.0") == k  # content, not the path
    assert _spec(labels=(("ratio", 1.0),)).key("0.1.0") == k  # derived labels do not count
    for change in (
        {"strategy": "portal"},
        {"seed": 2},
        {"threads": 1},
        {"time_s": 4.0},
        {"spp": 8},
        {"overrides": (("params.s_L", "0.6"),)},
        {"snapshots": (("every", "0.25"),)},
        {"scene_sha256": "cd" * 32},
    ):
        assert _spec(**change).key("0.1.0") != k, change
    assert _spec().key("0.2.0") != k


def test_02_scene_hash_ignores_sampling_settings() -> None:
    h = _spec().scene_hash()
    same: list[dict[str, Any]] = [
        {"strategy": "portal"},
        {"seed": 9},
        {"spp": 64},
        {"threads": 1},
        {"overrides": (("params.s_L", "0.3"), ("render.mis", "balance"))},
    ]
    for change in same:
        assert _spec(**change).scene_hash() == h, change
    different: list[dict[str, Any]] = [
        {"integrator": "path"},
        {"overrides": (("params.s_L", "0.6"),)},
        {"overrides": (("params.s_L", "0.3"), ("render.max_depth", "3"))},
    ]
    for change in different:
        assert _spec(**change).scene_hash() != h, change


def test_03_reference_key_follows_scene_hash_and_reference_settings() -> None:
    a = _spec(reference=True, spp=1024, time_s=0.0)
    assert a.key("v") == _spec(reference=True, spp=1024, time_s=0.0, threads=8).key("v")  # spp-limited
    assert a.key("v") == _spec(reference=True, spp=1024, time_s=0.0, snapshots=()).key("v")
    assert a.key("v") != _spec(reference=True, spp=2048, time_s=0.0).key("v")
    assert a.key("v") != a.key("w")
    t = _spec(reference=True, spp=0, time_s=60.0)
    assert t.key("v") != _spec(reference=True, spp=0, time_s=60.0, threads=1).key("v")  # time-limited


def test_04_command_line_follows_the_contract() -> None:
    cmd = _spec().command("/bin/render", "/s.yaml", "/out")
    assert cmd[:4] == ["/bin/render", "/s.yaml", "--out", "/out"]
    joined = " ".join(cmd)
    for part in (
        "--strategy light",
        "--integrator direct",
        "--spp 0",
        "--time 5",
        "--seed 1",
        "--threads 2",
        "--set params.s_L=0.3",
        "--set render.snapshots.every=0.5",
    ):
        assert part in joined


def test_05_round_trip_and_formatting(tmp_path: Path) -> None:
    s = _spec(labels=(("ratio", 0.25),))
    assert RunSpec.from_dict(s.to_dict()) == s
    assert [format_value(v) for v in (0.075, 1.0, 3, True, "x", 1e-7)] == ["0.075", "1", "3", "true", "x", "1e-07"]
