"""Where a renderer's CPU time goes, split by shared object with `perf`:
the time inside Embree against the time in the renderer's own code, for
the `time_split` section of bench.py.

Both renderers of the `mitsuba` section trace their rays with Embree 3
(Mitsuba 3 ships its own libembree3.so), so the split says whether a gap
between them lies in the ray tracing or in everything around it: shading,
sampling, random numbers, film. `perf record` samples the whole process;
`perf report --sort dso` gives each shared object's share of the samples.
Each object is put in one of three groups:

  embree  libembree*
  own     the renderer's own code: our `render` binary; Mitsuba's kernels
          compiled at run time ("[JIT] tid N" in perf), Dr.Jit's and
          Mitsuba's libraries; libc and libm for both (memcpy, sqrt)
  other   what is not rendering: the Python interpreter, LLVM compiling
          Mitsuba's kernels, EXR and zlib writing our image, the kernel

Only embree and own count: their shares, scaled to 100%, split the CPU time
per sample that the run measured by itself (our render threads' CPU time;
Mitsuba's steady passes). perf's sampling (4 kHz by default) costs both
renderers about alike, a percent or two.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

# One row of `perf report --stdio --sort dso`: "    65.85%  libembree3.so".
_ROW = re.compile(r"^\s*(\d+(?:\.\d+)?)%\s+(\S.*?)\s*$")
# One user-space row ([.]) of `perf report --stdio --sort sym`:
# "    16.79%  [.] sphrect_sample_many.arch_x86_64_v4".
_SYM_ROW = re.compile(r"^\s*(\d+(?:\.\d+)?)%\s+\[\.\]\s+(\S.*?)\s*$")
# GCC's target_clones suffixes (fastmath.h: FM_SIMD_CLONES): one function
# whichever clone the CPU runs.
_CLONE = re.compile(r"\.(arch_x86_64_v\d|avx2|avx512f|default)$")

_OWN_LIBS = ("libc.so", "libm.so", "libdrjit", "libmitsuba", "libnanobind", "_drjit_ext", "_mitsuba_ext")


@dataclass(frozen=True)
class Split:
    """Shares of the perf samples, percent of all: embree + own + other = 100."""

    embree: float
    own: float
    other: float

    @property
    def embree_fraction(self) -> float:
        """Embree's part of the rendering work (embree + own)."""
        work = self.embree + self.own
        return self.embree / work if work > 0 else float("nan")


def group_of(dso: str, renderer_binary: str) -> str:
    """embree, own or other for one shared object name of perf's report."""
    if dso.startswith("libembree"):
        return "embree"
    if dso == renderer_binary or dso.startswith("[JIT]") or dso.startswith(_OWN_LIBS):
        return "own"
    return "other"


def parse_report(text: str) -> dict[str, float]:
    """{shared object: percent} from `perf report --stdio --sort dso`
    (comment lines and anything else skipped). Raises when no row is found:
    an empty profile is an error, not a split of nothing."""
    shares: dict[str, float] = {}
    for line in text.splitlines():
        if line.startswith("#"):
            continue
        m = _ROW.match(line)
        if m:
            shares[m.group(2)] = shares.get(m.group(2), 0.0) + float(m.group(1))
    if not shares:
        raise ValueError("perf report gave no shared-object rows")
    return shares


def parse_symbols(text: str) -> dict[str, float]:
    """{function: percent of all samples} from `perf report --stdio --sort
    sym`, the clones of a function (name.avx2, name.arch_x86_64_v4) as one."""
    shares: dict[str, float] = {}
    for line in text.splitlines():
        m = _SYM_ROW.match(line)
        if m:
            name = _CLONE.sub("", m.group(2))
            shares[name] = shares.get(name, 0.0) + float(m.group(1))
    return shares


def split(shares: dict[str, float], renderer_binary: str) -> Split:
    """The three groups' shares of all samples."""
    acc = {"embree": 0.0, "own": 0.0, "other": 0.0}
    for dso, pct in shares.items():
        acc[group_of(dso, renderer_binary)] += pct
    total = sum(acc.values())
    return Split(*(100.0 * acc[k] / total for k in ("embree", "own", "other")))


def perf_path() -> str | None:
    """The perf program, when there is one that can record this user's
    processes (kernel.perf_event_paranoid <= 2, no seccomp block)."""
    perf = shutil.which("perf")
    if perf is None:
        return None
    probe = subprocess.run([perf, "stat", "-e", "task-clock", "--", "true"], capture_output=True, text=True)
    return perf if probe.returncode == 0 else None


def record_prefix(perf: str, data: Path) -> tuple[str, ...]:
    """The words that run a command under `perf record` into `data`."""
    return (perf, "record", "-q", "-o", str(data), "--")


def report(perf: str, data: Path) -> dict[str, float]:
    """Shares by shared object of a perf.data file."""
    p = subprocess.run(
        [perf, "report", "-i", str(data), "--stdio", "--no-children", "--sort", "dso"],
        capture_output=True,
        text=True,
    )
    if p.returncode != 0:
        raise RuntimeError(f"perf report -i {data} failed: {p.stderr.strip()}")
    return parse_report(p.stdout)


def report_symbols(perf: str, data: Path, dso: str) -> dict[str, float]:
    """Shares by function, of all samples, of the functions in one shared
    object (our `render`: Mitsuba's kernels have no names)."""
    p = subprocess.run(
        [perf, "report", "-i", str(data), "--stdio", "--no-children", "--sort", "sym", "--dsos", dso],
        capture_output=True,
        text=True,
    )
    if p.returncode != 0:
        raise RuntimeError(f"perf report -i {data} --dsos {dso} failed: {p.stderr.strip()}")
    return parse_symbols(p.stdout)
