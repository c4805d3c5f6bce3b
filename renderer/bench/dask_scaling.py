"""How a sweep's wall time scales with the Dask workers it runs on, for the
`dask` section of bench.py: the same small experiment through `portal-harness
sweep --scheduler` on a local cluster of k = 1 and k = 2 worker processes
(one thread each, renders with one thread: a worker per core), each into a
fresh results folder, references included.

The FULL budgets (docs/experiments.md) are stated for 2 cores and "about
1/k of that on k workers": a worker renders one run at a time, and the
harness's own work (planning, shipping the scene to the workers, metrics,
the index, reference extensions, which run on the client) is what keeps
the ratio from 1/k. The ratio wall(k=2) / wall(k=1) is measured in one run
of the bench, so a machine's speed cancels; on a machine with fewer than two
free cores it says nothing, and the section records the cores it had.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

DASK_EXPERIMENT = """\
# A small sweep for the bench's `dask` section: one-thread renders, so that
# a worker per core renders in parallel. Written by renderer/bench/dask_scaling.py.
name: bench_dask
scene: {scene}
integrator: direct
strategies: [light, antishadow_exact]
sweep:
  params.s_L: [0.15, 0.3, 0.6, 1.2]
fixed:
  film.width: 128
  film.height: 128
budget:
  time_s: {time_s}
  spp: 0
  threads: 1
  replicates: {replicates}
reference:
  strategy: light
  time_s: {ref_s}
  threads: 1
"""


def sweep_on_cluster(workers: int, folder: Path, scene: Path, render: Path, quick: bool) -> dict[str, Any]:
    """One sweep of DASK_EXPERIMENT on a fresh LocalCluster of `workers`
    one-thread worker processes: its wall time and its renders."""
    from distributed import LocalCluster

    time_s, ref_s, replicates = (0.5, 1.0, 2) if quick else (2.0, 4.0, 3)
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    exp = folder / "bench_dask.yaml"
    exp.write_text(DASK_EXPERIMENT.format(scene=scene, time_s=time_s, ref_s=ref_s, replicates=replicates))
    results = folder / "results"
    # (distributed's LocalCluster is not typed)
    cluster_of = LocalCluster(  # type: ignore[no-untyped-call]
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    )
    with cluster_of as cluster:
        cmd = [
            sys.executable,
            "-m",
            "portal_harness",
            "sweep",
            str(exp),
            "--results",
            str(results),
            "--renderer",
            str(render),
            "--scheduler",
            str(cluster.scheduler_address),
            "--no-progress",
        ]
        w0 = time.monotonic()
        p = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.monotonic() - w0
    if p.returncode != 0:
        raise RuntimeError(f"sweep on {workers} Dask worker(s) failed ({p.returncode}):\n{p.stderr.strip()[-2000:]}")
    manifests = list(results.glob("*/*/manifest.json"))
    return {"workers": workers, "wall_s": wall, "renders": len(manifests), "run_time_s": time_s}


def measure(tmp: Path, scene: Path, render: Path, quick: bool, cores: int) -> dict[str, Any]:
    one = sweep_on_cluster(1, tmp / "dask_1", scene, render, quick)
    two = sweep_on_cluster(2, tmp / "dask_2", scene, render, quick)
    return {
        "cores": cores,
        "one_worker": one,
        "two_workers": two,
        # 0.5 is the ideal; the rest is the harness's serial work.
        "wall_ratio_2_to_1": two["wall_s"] / one["wall_s"],
    }
