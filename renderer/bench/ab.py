#!/usr/bin/env python3
"""A/B throughput of two renderer builds in one run (`make bench-ab
BASE=path/to/old/render`): the lampshade (and the multi-lamp scene and the
Little Lamp) at each (integrator, strategy), one render thread, the two
binaries alternating so that drift of the machine hits both alike. Prints
samples per render-CPU second, the median and the best of ROUNDS runs per
binary, and new/base ratios.

With --instructions (`make bench-ab BASE=... INSTRUCTIONS=1`), each case
instead renders a fixed number of samples per pixel once per binary under
valgrind's callgrind and reports the instructions executed by the render
passes (the worker threads' `worker_main`, so scene loading is left out).
Instruction counts do not depend on the machine's load: on a virtual
machine whose speed drifts by tens of percent between identical runs they
resolve changes of a percent, which timings cannot. They are a proxy: a
division or a cache miss counts as one instruction, and valgrind runs the
AVX2 versions of the vectorised loops, not the AVX-512 ones.

usage: ab.py BASE_RENDER NEW_RENDER [--rounds N] [--time S] [--instructions [--spp N]]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CASES = [
    ("lampshade.yaml", "direct", "light"),
    ("lampshade.yaml", "direct", "antishadow_exact"),
    ("lampshade.yaml", "path", "light"),
    ("lampshade.yaml", "path", "antishadow_exact"),
    ("multi_lamp.yaml", "direct", "light"),
    ("multi_lamp.yaml", "direct", "antishadow_exact"),
    ("little_lamp.yaml", "direct", "light"),
    ("little_lamp.yaml", "direct", "antishadow_exact"),
]


def render_args(scene: str, integrator: str, strategy: str, out: str) -> list[str]:
    """The arguments of one case's render: one thread, seed 1, no snapshots."""
    return [
        str(ROOT / "configs" / "scenes" / scene),
        "--out",
        out,
        "--threads",
        "1",
        "--seed",
        "1",
        "--integrator",
        integrator,
        "--strategy",
        strategy,
        "--quiet",
        "--set",
        "render.snapshots.every=0",
    ]


def samples_per_cpu_s(render: Path, scene: str, integrator: str, strategy: str, time_s: float) -> float:
    with tempfile.TemporaryDirectory() as out:
        cmd = [str(render), *render_args(scene, integrator, strategy, out), "--time", str(time_s)]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    start = final = None
    for line in proc.stdout.splitlines():
        event = json.loads(line)
        if event["event"] == "start":
            start = event
        elif event["event"] == "final":
            final = event
    if start is None or final is None:
        raise RuntimeError(f"{render}: no start or final event")
    rate: float = float(final["spp"]) * start["width"] * start["height"] / float(final["render_cpu_s"])
    return rate


def render_instructions(render: Path, scene: str, integrator: str, strategy: str, spp: int) -> int:
    """Instructions executed in the render passes of one fixed-spp render."""
    with tempfile.TemporaryDirectory() as out:
        trace = Path(out) / "callgrind.out"
        cmd = [
            "valgrind",
            "--tool=callgrind",
            f"--callgrind-out-file={trace}",
            "--toggle-collect=worker_main",
            str(render),
            *render_args(scene, integrator, strategy, str(Path(out) / "render")),
            "--spp",
            str(spp),
        ]
        subprocess.run(cmd, capture_output=True, text=True, check=True)
        match = re.search(r"^(?:summary|totals):\s*(\d+)", trace.read_text(), re.MULTILINE)
    if match is None:
        raise RuntimeError(f"{render}: callgrind wrote no instruction total")
    return int(match.group(1))


def compare_instructions(base: Path, new: Path, spp: int) -> None:
    print(f"{'scene':16} {'integrator':10} {'strategy':17} {'base M instr':>13} {'new M instr':>12} {'new/base':>9}")
    for scene, integrator, strategy in CASES:
        b = render_instructions(base, scene, integrator, strategy, spp)
        n = render_instructions(new, scene, integrator, strategy, spp)
        print(f"{scene:16} {integrator:10} {strategy:17} {b / 1e6:13.1f} {n / 1e6:12.1f} {n / b:9.4f}")
        sys.stdout.flush()


def compare_times(base: Path, new: Path, rounds: int, time_s: float) -> None:
    print(
        f"{'scene':16} {'integrator':10} {'strategy':17} {'base M/s':>9} {'new M/s':>9} {'new/base':>9} {'range':>13}"
        f" {'best new/best base':>18}"
    )
    for scene, integrator, strategy in CASES:
        runs: dict[str, list[float]] = {"base": [], "new": []}
        for _ in range(rounds):
            for name, render in (("base", base), ("new", new)):
                runs[name].append(samples_per_cpu_s(render, scene, integrator, strategy, time_s))
        b, n = statistics.median(runs["base"]), statistics.median(runs["new"])
        ratios = [x / y for x, y in zip(runs["new"], runs["base"], strict=True)]
        # The best run of each: on a machine whose speed drifts downwards
        # (other work, a slower host), the fastest run is the least disturbed.
        best = max(runs["new"]) / max(runs["base"])
        print(
            f"{scene:16} {integrator:10} {strategy:17} {b / 1e6:9.3f} {n / 1e6:9.3f} {n / b:9.3f}"
            f" {min(ratios):6.3f}-{max(ratios):.3f} {best:18.3f}"
        )
        sys.stdout.flush()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("base", type=Path)
    ap.add_argument("new", type=Path)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--time", type=float, default=2.0)
    ap.add_argument("--instructions", action="store_true", help="count instructions under callgrind instead")
    ap.add_argument("--spp", type=int, default=2, help="samples per pixel of an --instructions render")
    args = ap.parse_args()
    for render in (args.base, args.new):
        if not (render.is_file() and render.stat().st_mode & 0o111):
            print(f"ab.py: {render}: not an executable file", file=sys.stderr)
            return 2
    if args.instructions:
        if shutil.which("valgrind") is None:
            print("ab.py: --instructions needs valgrind (apt-get install valgrind)", file=sys.stderr)
            return 2
        if args.spp < 1:
            print("ab.py: --spp must be at least 1", file=sys.stderr)
            return 2
        compare_instructions(args.base, args.new, args.spp)
    else:
        compare_times(args.base, args.new, args.rounds, args.time)
    return 0


if __name__ == "__main__":
    sys.exit(main())
