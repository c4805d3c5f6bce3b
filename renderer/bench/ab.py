#!/usr/bin/env python3
"""A/B throughput of two renderer builds in one run (`make bench-ab
BASE=path/to/old/render`): the lampshade (and the multi-lamp scene) at each
(integrator, strategy), one render thread, the two binaries alternating so
that drift of the machine hits both alike. Prints samples per render-CPU
second, the median of ROUNDS runs per binary, and new/base ratios.

usage: ab.py BASE_RENDER NEW_RENDER [--rounds N] [--time S]
"""

from __future__ import annotations

import argparse
import json
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
]


def samples_per_cpu_s(render: Path, scene: str, integrator: str, strategy: str, time_s: float) -> float:
    with tempfile.TemporaryDirectory() as out:
        cmd = [
            str(render),
            str(ROOT / "configs" / "scenes" / scene),
            "--out",
            out,
            "--time",
            str(time_s),
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("base", type=Path)
    ap.add_argument("new", type=Path)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--time", type=float, default=2.0)
    args = ap.parse_args()
    print(
        f"{'scene':16} {'integrator':10} {'strategy':17} {'base M/s':>9} {'new M/s':>9} {'new/base':>9} {'range':>13}"
    )
    for scene, integrator, strategy in CASES:
        runs: dict[str, list[float]] = {"base": [], "new": []}
        for _ in range(args.rounds):
            for name in ("base", "new"):
                runs[name].append(samples_per_cpu_s(getattr(args, name), scene, integrator, strategy, args.time))
        b, n = statistics.median(runs["base"]), statistics.median(runs["new"])
        ratios = [x / y for x, y in zip(runs["new"], runs["base"], strict=True)]
        print(
            f"{scene:16} {integrator:10} {strategy:17} {b / 1e6:9.3f} {n / 1e6:9.3f} {n / b:9.3f}"
            f" {min(ratios):6.3f}-{max(ratios):.3f}"
        )
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
