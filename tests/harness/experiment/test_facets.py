"""Categorical sweep keys (facets.py): validated against the renderer's
contract, facets of the figures and columns of the tidy summary, never the
axis; points that differ only in how they are sampled share a reference,
the integrator does not; experiments without facets keep their run keys."""

from __future__ import annotations

import json
import math
import sqlite3
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml

from portal_harness.core.errors import ConfigError
from portal_harness.experiment import contract
from portal_harness.experiment.loader import load_experiment
from portal_harness.experiment.model import point_overrides
from portal_harness.experiment.spec import RunSpec

REPO = Path(__file__).resolve().parents[3]
CliRunner = Callable[..., tuple[int, str, str]]
WEIGHTS = {"params.s_L": [0.15, 0.6], "render.portal_weight": ["area", "distance"]}


def test_01_portal_weight_is_a_facet_sharing_the_reference(
    write_experiment: Callable[..., Path], real_renderer: Path
) -> None:
    exp = load_experiment(write_experiment(sweep=WEIGHTS), str(real_renderer))
    assert exp.axis is not None and exp.axis.param == "params.s_L"
    assert exp.facets == ("render.portal_weight",)
    points = exp.points()
    assert [p.id for p in points] == [
        "s_L=0.15,portal_weight=area",
        "s_L=0.15,portal_weight=distance",
        "s_L=0.6,portal_weight=area",
        "s_L=0.6,portal_weight=distance",
    ]
    assert [p.axis_value for p in points] == pytest.approx([0.5, 0.5, 2.0, 2.0])
    assert [dict(p.facets) for p in points] == [{"render.portal_weight": w} for w in ("area", "distance") * 2]
    # the weight goes to the renderer as a --set, and each weight is its own run
    a, b = (exp.run_spec(p, "portal") for p in points[:2])
    assert ("render.portal_weight", "distance") in b.overrides and a.key("v") != b.key("v")
    # one reference point per s_L, whose renders do not carry the weight
    refs = exp.reference_points()
    assert [p.id for p in refs] == ["s_L=0.15", "s_L=0.6"]
    assert exp.reference_point(points[1]) == refs[0]
    ref_spec = exp.reference_spec(refs[0], "light")
    assert all(k != "render.portal_weight" for k, _ in ref_spec.overrides)
    # and the reference key would not depend on the weight anyway (the scene hash's rule)
    assert exp.reference_spec(points[0], "light").key("v") == exp.reference_spec(points[1], "light").key("v")


def test_02_integrator_is_a_facet_with_its_own_reference(
    write_experiment: Callable[..., Path], real_renderer: Path
) -> None:
    sweep = {"params.s_L": [0.6], "render.integrator": ["direct", "path"]}
    exp = load_experiment(write_experiment(sweep=sweep, integrator=None), str(real_renderer))
    direct, path = exp.points()
    assert exp.integrator_of(direct) == "direct" and exp.integrator_of(path) == "path"
    spec = exp.run_spec(path, "portal")
    # the integrator is the command line's --integrator, not an override
    assert spec.integrator == "path" and all(k != "render.integrator" for k, _ in spec.overrides)
    assert spec.command("render", "s.yaml", "o")[spec.command("render", "s.yaml", "o").index("--integrator") + 1] == (
        "path"
    )
    assert [p.id for p in exp.reference_points()] == [direct.id, path.id]
    assert exp.reference_spec(direct, "light").key("v") != exp.reference_spec(path, "light").key("v")
    assert exp.reference_spec(path, "light").integrator == "path"


def test_03_only_facets_no_axis(write_experiment: Callable[..., Path], real_renderer: Path) -> None:
    exp = load_experiment(
        write_experiment(sweep={"render.portal_weight": ["area", "irradiance"]}, axis=None),
        str(real_renderer),
    )
    assert exp.axis is None and exp.facets == ("render.portal_weight",)
    assert all(math.isnan(p.axis_value) for p in exp.points())
    assert len(exp.reference_points()) == 1
    # `axis: none` makes a numeric key a facet too (defensive at 0 and 0.1)
    exp = load_experiment(
        write_experiment(
            sweep={"render.defensive": [0, 0.1], "render.portal_weight": ["area"]},
            axis="none",
        ),
        str(real_renderer),
    )
    assert exp.axis is None and exp.facets == (
        "render.defensive",
        "render.portal_weight",
    )
    assert len(exp.reference_points()) == 1


def test_04_names_come_from_the_renderer(write_experiment: Callable[..., Path], real_renderer: Path) -> None:
    names = contract.describe(str(real_renderer))
    for key, listed in (
        ("render.portal_weight", names.portal_weights),
        ("render.sampler", names.samplers),
        ("render.integrator", names.integrators),
    ):
        good = write_experiment(sweep={"params.s_L": [0.6], key: list(listed)}, integrator=None)
        try:
            exp = load_experiment(good, str(real_renderer))
            assert [dict(p.values)[key] for p in exp.points()] == list(listed)
        except ConfigError as e:
            # render.sampler is being added to the renderer: until it reads the key, --describe
            # lists its one sampler and --print-config refuses the key (the harness passes it on).
            assert key == "render.sampler" and 'unknown key "sampler"' in e.message, e
        with pytest.raises(ConfigError) as info:
            load_experiment(
                write_experiment(
                    sweep={"params.s_L": [0.6], key: [listed[0], "no_such_name"]},
                    integrator=None,
                ),
                str(real_renderer),
            )
        assert info.value.key == f"sweep.{key}.1" and "no_such_name" in info.value.message
        assert "|".join(listed) in info.value.message  # the renderer's names, in its order


BAD = [
    (
        {"sweep": WEIGHTS, "axis": {"param": "render.portal_weight"}},
        "sweep.render.portal_weight.0",
        "needs numbers",
    ),
    (
        {"sweep": {"params.s_L": [0.6], "render.integrator": ["path"]}},
        "integrator",
        "render.integrator is swept",
    ),
    (
        {"fixed": {"render.integrator": "path"}},
        "fixed.render.integrator",
        "set by the harness",
    ),
    (
        {"fixed": {"params.s_P": 0.3, "render.portal_weight": "areal"}},
        "fixed.render.portal_weight",
        "unknown portal",
    ),
    (
        {"sweep": {"render.strategy": ["light"]}},
        "sweep.render.strategy",
        "set by the harness",
    ),
    (
        {"sweep": {"render.portal_weight": ["area"]}, "axis": {"label": "x"}},
        "axis",
        "no swept key has numbers",
    ),
    (
        {"sweep": {"params.s_L": [0.6], "render.portal_weight": [["area"]]}},
        "sweep.render.portal_weight.0",
        "scalar",
    ),
]


@pytest.mark.parametrize("change,key,message", BAD, ids=[b[1] for b in BAD])
def test_05_bad_facets_name_file_key_and_line(
    write_experiment: Callable[..., Path],
    real_renderer: Path,
    change: dict[str, object],
    key: str,
    message: str,
) -> None:
    path = write_experiment(**change)
    with pytest.raises(ConfigError) as info:
        load_experiment(path, str(real_renderer))
    assert info.value.file == str(path) and info.value.key == key
    assert message in info.value.message
    # the line of the offending key in the file
    assert info.value.line is not None
    line = path.read_text().splitlines()[info.value.line - 1]
    assert key.split(".")[-1] in line or key.split(".")[-1].isdigit(), (line, key)
    assert f"{path}:{info.value.line}:" in str(info.value)


def test_06_run_keys_without_facets_are_unchanged(real_renderer: Path) -> None:
    """The specs of an experiment without facets are those the harness made
    before facets existed: every override a --set, the experiment's integrator."""
    exp = load_experiment(REPO / "configs" / "experiments" / "lampshade_ratio.yaml", str(real_renderer))
    assert exp.facets == () and exp.reference_points() == exp.points()
    for point in exp.points():
        assert point.facets == ()
        spec = exp.run_spec(point, "portal", replicate=1)
        assert spec == RunSpec(
            scene=str(exp.scene),
            scene_sha256=exp.scene_sha256,
            strategy="portal",
            integrator=exp.integrator,
            spp=spec.spp,
            time_s=spec.time_s,
            seed=exp.replicate_seed("portal", 1),
            threads=spec.threads,
            overrides=point_overrides(exp.fixed, point.values),
            snapshots=spec.snapshots,
        )


def test_07_sweep_shares_references_across_weights(
    cli: CliRunner,
    write_experiment: Callable[..., Path],
    results: Path,
    render_log: Callable[[], list[str]],
) -> None:
    exp = write_experiment(sweep=WEIGHTS)
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    # two region maps and two references (one per s_L), 4 points x 2 strategies
    assert len(render_log()) == 2 + 2 + 8, out
    summary = json.loads((results / "experiments" / "tiny" / "summary.json").read_text())
    assert summary["columns"][:3] == ["point", "axis", "render.portal_weight"]
    assert len(summary["references"]) == 2
    rows = summary["rows"]
    assert {r["render.portal_weight"] for r in rows} == {"area", "distance"}
    assert len({(r["point"], r["strategy"]) for r in rows}) == 8
    csv_text = (results / "experiments" / "tiny" / "summary.csv").read_text()
    assert csv_text.startswith("point,axis,render.portal_weight,strategy,")
    # every point knows its reference, the shared one
    conn = sqlite3.connect(results / "index.sqlite")
    refs = dict(conn.execute("SELECT point, key FROM experiment_runs WHERE experiment = 'tiny' AND role = 'reference'"))
    conn.close()
    assert len(refs) == 4 and len(set(refs.values())) == 2
    assert refs["s_L=0.15,portal_weight=area"] == refs["s_L=0.15,portal_weight=distance"]
    status, out, err = cli("figures", str(exp))
    assert status == 0, err
    for name in ("error_time", "insets", "efficiency"):
        assert (results / "figures" / f"tiny_{name}.png").stat().st_size > 5000


def test_08_sweep_of_integrators_and_no_axis(
    cli: CliRunner,
    write_experiment: Callable[..., Path],
    results: Path,
    render_log: Callable[[], list[str]],
) -> None:
    exp = write_experiment(sweep={"render.integrator": ["direct", "path"]}, integrator=None, axis=None)
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    # a region map and a reference per integrator, 2 points x 2 strategies
    assert len(render_log()) == 2 + 2 + 4, out
    summary = json.loads((results / "experiments" / "tiny" / "summary.json").read_text())
    assert len(summary["references"]) == 2
    assert {r["render.integrator"] for r in summary["rows"]} == {"direct", "path"}
    assert all(r["axis"] is None for r in summary["rows"])
    conn = sqlite3.connect(results / "index.sqlite")
    integrators = dict(
        conn.execute(
            "SELECT e.point, r.integrator FROM experiment_runs e JOIN runs r ON r.key = e.key "
            "WHERE e.role = 'reference'"
        )
    )
    conn.close()
    assert integrators == {"integrator=direct": "direct", "integrator=path": "path"}
    status, out, err = cli("figures", str(exp))
    assert status == 0, err
    assert (results / "figures" / "tiny_efficiency.png").stat().st_size > 5000


@pytest.mark.real
def test_09_real_renderer_weights_and_integrators(
    real_renderer: Path, tmp_path: Path, results: Path, cli: CliRunner
) -> None:
    """The real renderer takes each weight and integrator: two references
    (one per integrator) for four points, and the path-traced runs are
    measured against the path-traced reference."""
    doc = {
        "name": "real_facets",
        "scene": str(REPO / "configs" / "scenes" / "lampshade.yaml"),
        "strategies": ["light", "portal"],
        "sweep": {"render.portal_weight": ["area", "irradiance"], "render.integrator": ["direct", "path"]},
        "fixed": {"params.s_P": 0.3, "params.s_L": 0.6, "film.width": 24, "film.height": 24},
        "budget": {"time_s": 0.2, "threads": 1, "seed": 1, "snapshots": {"every": 0.1}},
        "reference": {"strategy": "light", "spp": 64, "seed": 7},
    }
    path = tmp_path / "real_facets.yaml"
    path.write_text(yaml.safe_dump(doc))
    status, out, err = cli("sweep", str(path), "--no-progress", renderer=real_renderer)
    summary = json.loads((results / "experiments" / "real_facets" / "summary.json").read_text())
    assert len(summary["references"]) == 2, out + err
    rows = [r for r in summary["rows"] if r["region"] == "image"]
    assert {(r["render.portal_weight"], r["render.integrator"]) for r in rows} == {
        (w, i) for w in ("area", "irradiance") for i in ("direct", "path")
    }
    assert all(r["status"] == "done" and r["rel_mse"] is not None for r in rows), out + err
    assert status == 0, out + err
    conn = sqlite3.connect(results / "index.sqlite")
    pairs = conn.execute(
        "SELECT r.integrator, ref.integrator FROM experiment_runs e JOIN runs r ON r.key = e.key "
        "JOIN runs ref ON ref.key = e.reference_key WHERE e.role = 'run'"
    ).fetchall()
    conn.close()
    assert len(pairs) == 8 and all(a == b for a, b in pairs)
    status, out, err = cli("figures", str(path))
    assert status == 0, err
    assert (results / "experiments" / "real_facets" / "summary.tex").read_text().count("\\toprule") == 4 * len(
        {r["region"] for r in summary["rows"]}
    )
