"""The command line: --help everywhere, exit statuses, the live progress bar."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from portal_harness.cli import build_parser, main

CliRunner = Callable[..., tuple[int, str, str]]
COMMANDS = (
    "run",
    "reference",
    "sweep",
    "metrics",
    "figures",
    "regress",
    "query",
    "reindex",
    "import-mitsuba",
    "report",
    "serve",
    "results-page",
)


@pytest.mark.parametrize("command", COMMANDS)
def test_01_every_subcommand_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: portal-harness {command}")
    # import-mitsuba neither renders nor touches the results folder.
    assert ("--results" in out) == (command != "import-mitsuba")


def test_02_console_script_is_installed() -> None:
    exe = Path(sys.executable).parent / "portal-harness"
    out = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0
    for command in COMMANDS:
        assert command in out.stdout
    subparsers = build_parser()._subparsers
    assert subparsers is not None
    choices = subparsers._group_actions[0].choices
    assert choices is not None and set(choices) == set(COMMANDS)


def test_03_run_shows_progress_and_reports(cli: CliRunner, fake_scene: Path) -> None:
    status, out, err = cli(
        "run", str(fake_scene), "--strategy", "portal", "--time", "0.3", "--spp", "0", "--snapshot-every", "0.1"
    )
    assert status == 0, err
    assert out.startswith("run ") and ": done" in out and "folder:" in out
    assert "portal 16x16" in err and "snapshot 2" in err and "final" in err  # the live bar's text
    status, out, err = cli(
        "run", str(fake_scene), "--strategy", "portal", "--time", "0.3", "--spp", "0", "--snapshot-every", "0.1"
    )
    assert status == 0 and "cached: nothing rendered" in out and "16x16" not in err


def test_04_failed_run_exits_1_with_renderer_stderr(
    cli: CliRunner, fake_scene: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("FAKE_RENDER_UNIMPLEMENTED", "antishadow")
    status, out, err = cli("run", str(fake_scene), "--strategy", "antishadow")
    assert status == 1 and ": failed" in out
    assert "exited with status 1" in err and "not implemented" in err


def test_05_missing_renderer_and_bad_arguments_exit_2(cli: CliRunner, fake_scene: Path, tmp_path: Path) -> None:
    status, _, err = cli("run", str(fake_scene), renderer=tmp_path / "no-render")
    assert status == 2 and "renderer not found" in err
    status, _, err = cli("run", str(fake_scene), "--set", "params.s_L")
    assert status == 2 and "expected KEY=VALUE" in err
    # the renderer reads the scene, and its message is the error
    status, _, err = cli("run", str(tmp_path / "nope.yaml"))
    assert status == 2 and f"{tmp_path / 'nope.yaml'}: No such file or directory" in err
    status, _, err = cli("figures", str(tmp_path / "nope.yaml"))
    assert status == 2
    # A name the system refuses (longer than NAME_MAX): one located line, no traceback.
    too_long = tmp_path / ("a" * 300 + ".yaml")
    for command in ("sweep", "figures"):
        status, _, err = cli(command, str(too_long))
        assert status == 2 and "File name too long" in err and "Traceback" not in err, err


def test_06_figures_before_sweep_is_a_clear_error(cli: CliRunner, write_experiment: Callable[..., Path]) -> None:
    status, _, err = cli("figures", str(write_experiment()))
    assert status == 1 and "run `portal-harness sweep` first" in err


def test_07_reindex_rebuilds_the_index(cli: CliRunner, write_experiment: Callable[..., Path], results: Path) -> None:
    exp = write_experiment(strategies=["light"], sweep={"params.s_L": [0.3]})
    assert cli("sweep", str(exp), "--no-progress")[0] == 0
    (results / "index.sqlite").unlink()
    for extra in ("index.sqlite-wal", "index.sqlite-shm"):
        (results / extra).unlink(missing_ok=True)
    status, out, _ = cli("reindex")
    assert status == 0 and "indexed 3 run folders" in out  # region map, reference, run
    status, out, _ = cli("query", "--strategy", "light", "--param", "params.s_L=0.3")
    assert status == 0 and len(out.strip().splitlines()) > 2
