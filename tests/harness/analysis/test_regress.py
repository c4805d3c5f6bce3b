"""`regress`: passes against its own baseline, fails with a readable table
when a strategy's variance rises (a config with half the samples)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import REPO

CliRunner = Callable[..., tuple[int, str, str]]


def _regress_experiment(write_experiment: Callable[..., Path], spp: int, baseline: Path, name: str) -> Path:
    return write_experiment(
        name=name,
        strategies=["light", "portal"],
        sweep={"params.s_L": [0.15]},
        fixed={"params.s_P": 0.3, "film.width": 16, "film.height": 16},
        regress={"spp": spp, "seeds": [1, 2], "z_max": 4, "baseline": str(baseline)},
    )


def test_01_update_then_pass_then_fail_on_halved_samples(
    cli: CliRunner, write_experiment: Callable[..., Path], tmp_path: Path
) -> None:
    baseline = tmp_path / "baselines" / "tiny.json"
    good = _regress_experiment(write_experiment, 32, baseline, "tiny")
    status, out, err = cli("regress", str(good), "--no-progress")
    assert status == 1 and "no baseline" in out  # nothing to compare with yet

    status, out, err = cli("regress", str(good), "--update", "--no-progress")
    assert status == 0, out + err
    data = json.loads(baseline.read_text())
    assert set(data["entries"]) == {"s_L=0.15/light", "s_L=0.15/portal"}
    assert data["settings"]["spp"] == 32 and data["renderer_version"] == "0.1.0-fake"
    # the fake's per-sample sigma is 1.2 (light) and 0.7 (portal): relative variance ~ sigma^2 / spp
    light = data["entries"]["s_L=0.15/light"]
    assert light["value"] == pytest.approx(1.2**2 / 32, rel=0.25)
    assert light["standard_error"] < 0.05 * light["value"]

    status, out, err = cli("regress", str(good), "--no-progress")
    assert status == 0, out
    assert "regress passed" in out and out.count(" ok") == 2

    worse = _regress_experiment(write_experiment, 16, baseline, "tiny_half")
    status, out, err = cli("regress", str(worse), "--no-progress")
    assert status == 1
    assert "settings differ" in out
    header = next(line for line in out.splitlines() if line.startswith("point/strategy"))
    for column in ("baseline", "current", "ratio", "bound", "z", "verdict"):
        assert column in header
    rows = [line for line in out.splitlines() if line.startswith("s_L=")]
    assert len(rows) == 2 and all(line.rstrip().endswith("RISE") for line in rows)
    # Half the samples double the variance of the mean; the per-render
    # relative variance v / (m^2 + 0.01) also divides by a noisier m^2, so
    # the ratio is 2 or somewhat more.
    ratios = [float(line.split()[3]) for line in rows]
    assert all(1.8 < r < 3.5 for r in ratios)
    assert "regress FAILED" in out


def test_02_a_failing_strategy_fails_regress(
    cli: CliRunner, write_experiment: Callable[..., Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    baseline = tmp_path / "b.json"
    exp = _regress_experiment(write_experiment, 8, baseline, "tiny")
    assert cli("regress", str(exp), "--update", "--no-progress")[0] == 0
    monkeypatch.setenv("FAKE_RENDER_UNIMPLEMENTED", "portal")
    status, out, _ = cli("regress", str(exp), "--no-progress")
    assert status == 1 and "FAILED" in out and "s_L=0.15/portal" in out


@pytest.mark.real
def test_03_real_renderer_passes_the_committed_baseline_and_catches_halved_samples(
    real_renderer: Path, results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from portal_harness.cli import main

    config = REPO / "configs" / "experiments" / "lampshade_regress.yaml"
    baseline = REPO / "results" / "baselines" / "lampshade_regress.json"
    if not baseline.exists():
        pytest.skip("no committed baseline yet (portal-harness regress --update)")
    status = main(
        ["regress", str(config), "--results", str(results), "--renderer", str(real_renderer), "--no-progress"]
    )
    out = capsys.readouterr().out
    assert status == 0, out
    worse = tmp_path / "lampshade_regress_half.yaml"
    text = config.read_text().replace("spp: 32", "spp: 16")
    text = text.replace("../scenes/lampshade.yaml", str(REPO / "configs" / "scenes" / "lampshade.yaml"))
    text = text.replace("../../results/baselines/lampshade_regress.json", str(baseline))
    worse.write_text(text)
    status = main(["regress", str(worse), "--results", str(results), "--renderer", str(real_renderer), "--no-progress"])
    out = capsys.readouterr().out
    assert status == 1, out
    rows = [line for line in out.splitlines() if line.startswith("s_L=")]
    assert len(rows) == 12 and all(line.rstrip().endswith("RISE") for line in rows), out
    assert "regress FAILED" in out
