"""How a sweep's wall time scales with the Dask workers it runs on, for the
`dask` section of bench.py: the same small experiment's runs through
`portal-harness sweep --scheduler` on a local cluster of k = 1 and k = 2
worker processes (one thread each, renders with one thread: a worker per
core), each into a fresh results folder that holds its references.

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
from pathlib import Path
from typing import Any

import benchlib as bl

DASK_EXPERIMENT = """\
# A small sweep for the bench's `dask` section: one-thread renders of a
# fixed sample count (the same images on every cluster, so the cached
# references are never extended), so that a worker per core renders in
# parallel. Written by renderer/bench/dask_scaling.py.
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
  time_s: 0
  spp: {spp}
  threads: 1
  replicates: {replicates}
reference:
  strategy: light
  time_s: 4
  threads: 2
"""


def measure(tmp: Path, scene: Path, render: Path, quick: bool, cores: int) -> dict[str, Any]:
    """The experiment once locally (references and runs), then its runs again
    on 1 and on 2 workers, each in a fresh results folder holding only the
    references: the runs' wall time, which is what workers divide. The
    references' own cost is reported apart: their extension (`render
    --resume`) runs on the client whatever the cluster."""
    from distributed import LocalCluster

    spp, replicates = (16, 2) if quick else (64, 3)
    folder = bl.fresh_dir(tmp / "dask")
    exp = folder / "bench_dask.yaml"
    exp.write_text(DASK_EXPERIMENT.format(scene=scene, spp=spp, replicates=replicates))
    base = folder / "local"
    local_wall = bl.harness_sweep(exp, base, render)
    runs = len(list((base / "runs").glob("*/manifest.json")))
    out: dict[str, Any] = {"cores": cores, "runs": runs, "spp": spp, "local_with_references_s": local_wall}
    for workers in (1, 2):
        results = folder / f"workers_{workers}"
        shutil.copytree(base / "references", results / "references")
        # (distributed's LocalCluster is not typed)
        cluster_of = LocalCluster(  # type: ignore[no-untyped-call]
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        )
        with cluster_of as cluster:
            out[f"runs_on_{workers}_workers_s"] = bl.harness_sweep(exp, results, render, str(cluster.scheduler_address))
        rendered = len(list((results / "runs").glob("*/manifest.json")))
        if rendered != runs:
            raise RuntimeError(f"{workers} worker(s) rendered {rendered} runs, not {runs}")
    # 0.5 is the ideal; the rest is the harness's serial work (planning, shipping, metrics, the index).
    out["wall_ratio_2_to_1"] = out["runs_on_2_workers_s"] / out["runs_on_1_workers_s"]
    return out
