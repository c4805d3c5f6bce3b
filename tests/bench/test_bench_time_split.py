"""The bench's time split (renderer/bench/time_split.py): perf's report
parsed into shares, shared objects grouped, and (where perf may record) a
real profile of the renderer split."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))  # repo_paths.py
from repo_paths import REPO, real_renderer_fixture  # noqa: F401 (pytest finds it as `real_renderer`)

sys.path.insert(0, str(REPO / "renderer" / "bench"))

from time_split import (
    Split,
    group_of,
    parse_report,
    parse_symbols,
    perf_path,
    record_prefix,
    report,
    report_symbols,
    split,
)

# The shape of `perf report --stdio --no-children --sort dso` (Mitsuba's
# path integrator, 1 thread, trimmed).
MITSUBA_REPORT = """\
# To display the perf.data header info, please use --header/--header-only options.
#
#
# Total Lost Samples: 0
#
# Samples: 20K of event 'cpu-clock:uhppp'
# Event count (approx.): 5000000000
#
# Overhead  Shared Object
# ........  ......................
#
    65.85%  libembree3.so
    29.20%  [JIT] tid 24857
     3.66%  libpython3.11.so.1.0
     0.44%  [kernel.kallsyms]
     0.28%  libc.so.6
     0.23%  libdrjit-core.so
     0.02%  libLLVM.so.19.1
     0.02%  libmitsuba.so


#
# (Tip: ...)
#
"""


def test_parse_report_reads_every_row_and_skips_comments() -> None:
    shares = parse_report(MITSUBA_REPORT)
    assert shares["libembree3.so"] == pytest.approx(65.85)
    assert shares["[JIT] tid 24857"] == pytest.approx(29.20)
    assert len(shares) == 8
    assert sum(shares.values()) == pytest.approx(99.7)


def test_parse_report_refuses_an_empty_profile() -> None:
    with pytest.raises(ValueError, match="no shared-object rows"):
        parse_report("# Samples: 0\n#\n")


@pytest.mark.parametrize(
    ("dso", "group"),
    [
        ("libembree3.so.3.13.5", "embree"),
        ("libembree4.so.4", "embree"),
        ("render", "own"),
        ("[JIT] tid 7", "own"),
        ("libdrjit-core.so", "own"),
        ("libmitsuba.so", "own"),
        ("libm.so.6", "own"),
        ("libc.so.6", "own"),
        ("libpython3.11.so.1.0", "other"),
        ("libLLVM.so.19.1", "other"),
        ("libOpenEXRCore-3_1.so.30", "other"),
        ("[kernel.kallsyms]", "other"),
        ("renderer", "other"),  # only the binary's exact name is ours
    ],
)
def test_group_of(dso: str, group: str) -> None:
    assert group_of(dso, "render") == group


def test_split_scales_the_groups_to_all_samples() -> None:
    sp = split(parse_report(MITSUBA_REPORT), "render")
    assert sp.embree == pytest.approx(100 * 65.85 / 99.7)
    assert sp.own == pytest.approx(100 * (29.20 + 0.28 + 0.23 + 0.02) / 99.7)
    assert sp.embree + sp.own + sp.other == pytest.approx(100.0)
    assert sp.embree_fraction == pytest.approx(65.85 / (65.85 + 29.73))


def test_parse_symbols_merges_a_function_s_clones() -> None:
    text = """\
# Overhead  Symbol
# ........  ......
#
    16.79%  [.] sphrect_sample_many.arch_x86_64_v4
     0.50%  [.] sphrect_sample_many.avx2
     9.48%  [.] integrator_radiance_row
     2.71%  [.] hit_at.isra.0
     0.46%  [k] exc_page_fault
"""
    shares = parse_symbols(text)
    assert shares == pytest.approx(
        {"sphrect_sample_many": 17.29, "integrator_radiance_row": 9.48, "hit_at.isra.0": 2.71}
    )


def test_embree_fraction_of_no_work_is_nan() -> None:
    assert Split(0.0, 0.0, 100.0).embree_fraction != Split(0.0, 0.0, 100.0).embree_fraction


def test_real_profile_of_the_renderer(real_renderer: Path, tmp_path: Path) -> None:
    """The renderer under perf: its own code and Embree both take a real
    share of a render (a lampshade render traces ~2.4 rays a sample)."""
    perf = perf_path()
    if perf is None:
        pytest.skip("perf is missing or may not record here")
    data = tmp_path / "perf.data"
    cmd = [str(real_renderer), str(REPO / "configs" / "scenes" / "lampshade.yaml"), "--out", str(tmp_path / "o")]
    cmd += ["--quiet", "--spp", "32", "--threads", "1", "--set", "render.snapshots.every=0"]
    subprocess.run([*record_prefix(perf, data), *cmd], check=True, stdout=subprocess.DEVNULL)
    sp = split(report(perf, data), real_renderer.name)
    assert 5.0 < sp.embree < 80.0
    assert 15.0 < sp.own < 95.0
    assert sp.other < 25.0
    # By function: the row's integrator and the light sampler are among
    # them, and together they cannot exceed the binary's share.
    functions = report_symbols(perf, data, real_renderer.name)
    assert "integrator_radiance_row" in functions
    assert "sphrect_sample_many" in functions
    assert sum(functions.values()) <= sp.own + 1e-6
