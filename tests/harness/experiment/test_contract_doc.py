"""renderer/CONTRACT.md pinned to the renderer: every table of the page is
compared with what `render --describe`, `render --help` and a real render
say, both ways, so that neither can change without the other."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path
from typing import Any

import pytest
from conftest import REPO

from portal_harness.core import exr

pytestmark = pytest.mark.real
CONTRACT = REPO / "renderer" / "CONTRACT.md"
SCENE = REPO / "configs" / "scenes" / "lampshade.yaml"
TINY = ["--set", "film.width=16", "--set", "film.height=12"]


def section(heading: str) -> str:
    """The text under a markdown heading (any level), up to the next heading."""
    text = CONTRACT.read_text()
    m = re.search(rf"^#+ {re.escape(heading)}\n(.*?)(?=^#+ |\Z)", text, re.S | re.M)
    assert m, f"CONTRACT.md has no section {heading!r}"
    return m.group(1)


def tables(heading: str) -> list[list[list[str]]]:
    """The tables of a section, each as rows of stripped cells, header and rule dropped."""
    out: list[list[list[str]]] = []
    current: list[str] = []
    for line in [*section(heading).splitlines(), ""]:
        if line.startswith("|"):
            current.append(line)
        elif current:
            assert len(current) >= 3, f"a table under {heading!r} has no rows"
            out.append([[c.strip() for c in row.strip("|").split("|")] for row in current[2:]])
            current = []
    assert out, f"no table under {heading!r}"
    return out


def table(heading: str) -> list[list[str]]:
    """The rows of the first table of a section."""
    return tables(heading)[0]


def names(heading: str, column: int = 0) -> list[str]:
    """The backquoted names in one column of every table of a section, in order."""
    out = []
    for rows in tables(heading):
        for row in rows:
            out.extend(re.findall(r"`([^`]+)`", row[column]))
    return out


@pytest.fixture(scope="module")
def describe(real_renderer: Path) -> dict[str, Any]:
    proc = subprocess.run([str(real_renderer), "--describe"], capture_output=True, text=True, timeout=30, check=True)
    out: dict[str, Any] = json.loads(proc.stdout)
    return out


@pytest.fixture(scope="module")
def rendered(real_renderer: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[dict[str, Any]]]:
    out = tmp_path_factory.mktemp("contract") / "out"
    proc = subprocess.run(
        [
            str(real_renderer),
            str(SCENE),
            *TINY,
            "--out",
            str(out),
            "--spp",
            "4",
            "--seed",
            "2",
            "--threads",
            "1",
            "--resumable",
            "--set",
            "render.aov.region=true",
            "--set",
            "render.snapshots.every_spp=2",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    return out, [json.loads(line) for line in proc.stdout.splitlines()]


@pytest.mark.parametrize(
    ("heading", "key"),
    [
        ("Strategies", "strategies"),
        ("Integrators", "integrators"),
        ("Materials", "materials"),
        ("MIS heuristics", "mis"),
        ("Portal weights", "portal_weights"),
        ("Samplers", "samplers"),
    ],
)
def test_01_vocabulary_tables_are_the_renderers_lists(describe: dict[str, Any], heading: str, key: str) -> None:
    assert names(heading) == describe[key]


def test_02_exit_codes(describe: dict[str, Any]) -> None:
    rows = {re.sub("`", "", r[0]): int(r[1]) for r in table("Exit codes")}
    assert rows == describe["exit_codes"]


def test_03_every_option_of_help_is_documented_and_no_other(real_renderer: Path) -> None:
    usage = subprocess.run([str(real_renderer), "--help"], capture_output=True, text=True, check=True).stdout
    in_help = set(re.findall(r"(?<![\w-])(--[a-z][a-z-]*)", usage))
    documented = {n.split()[0] for row in table("Command line") for n in re.findall(r"`([^`]+)`", row[0])}
    assert in_help == documented


def test_04_json_events_and_their_fields(describe: dict[str, Any], rendered: tuple[Path, list[dict[str, Any]]]) -> None:
    rows = table("JSON events (stdout)")
    documented = {re.sub("`", "", r[0]): re.findall(r"`([^`]+)`", r[2]) for r in rows}
    assert list(documented) == describe["json_events"]
    _, events = rendered
    seen = {e["event"] for e in events}
    assert seen == set(documented), "a render with snapshots prints every documented event"
    for e in events:
        fields = [k for k in e if k != "event"]
        assert fields == documented[e["event"]], e["event"]


def test_05_output_folder(rendered: tuple[Path, list[dict[str, Any]]]) -> None:
    out, _ = rendered
    patterns = [re.escape(n).replace("NNNN", r"\d{4}") for n in names("Output folder")]
    files = sorted(p.name for p in out.iterdir())
    for f in files:
        assert any(re.fullmatch(p, f) for p in patterns), f"{f} is not in CONTRACT.md"
    for p in patterns:
        assert any(re.fullmatch(p, f) for f in files), f"no file matches {p}"


def test_06_exr_channels_and_attributes(describe: dict[str, Any], rendered: tuple[Path, list[dict[str, Any]]]) -> None:
    out, _ = rendered
    base, aov = table("EXR channels"), names("EXR channels")
    assert [re.sub("`", "", r[0]) for r in base] == describe["exr_channels"]
    region = [n for n in aov if n.startswith("region.")]
    assert region == describe["aov"]["region"]
    channels, header = exr.read_names(out / "final.exr")
    assert channels == sorted(describe["exr_channels"] + region)
    attributes = names("EXR attributes")
    assert attributes[: len(describe["exr_attributes"])] == describe["exr_attributes"]
    assert header == sorted(attributes)


def test_07_print_config_json_keys(real_renderer: Path) -> None:
    proc = subprocess.run(
        [str(real_renderer), "--print-config", str(SCENE), "--format", "json"],
        capture_output=True,
        text=True,
        timeout=30,
        check=True,
    )
    assert list(json.loads(proc.stdout)) == [re.sub("`", "", row[0]) for row in tables("Command line")[1]]


def test_08_snapshot_keys_and_units(describe: dict[str, Any]) -> None:
    rows = {re.sub("`", "", r[0]): r[1] for r in table("Snapshot keys")}
    assert rows == describe["snapshot_keys"]
