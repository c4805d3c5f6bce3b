"""Where renders run: a local process pool (the default) or a Dask
distributed cluster (--scheduler ADDRESS).

Local: at most cores // threads renders at once, so that renders x renderer
threads <= cores; workers write straight into the results folder.

Dask: each task runs the renderer on a worker in a private temporary folder
and *returns the run folder's contents* (bytes); the client writes them into
its own results folder, manifest last. Workers therefore need the renderer
binary at the same path (and its libraries), but no shared file system:
every file the scene uses (the scene, its includes, its meshes) travels as
a ScenePack, rebuilt in the worker's temporary folder with the same
relative layout. Before rendering, the worker asks its renderer which files
the render reads and checks that they are the shipped ones, with the digest
the run key names, so a worker never renders other bytes than the key says.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import ctypes
import multiprocessing
import os
import signal
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from portal_harness.core.cores import available_cores
from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.execution import runs, store
from portal_harness.experiment import contract
from portal_harness.experiment.scene_files import ScenePack, files_sha256, pack_scene, unpack_scene
from portal_harness.experiment.spec import RunSpec

DoneCallback = Callable[[RunSpec, dict[str, Any]], None]


def plan_jobs(threads_per_run: int, requested: int | None = None, cores: int | None = None) -> int:
    """Concurrent renders: the most that keeps renders x threads <= cores
    (at least one), or fewer if asked."""
    limit = max(1, (cores or available_cores()) // max(1, threads_per_run))
    return limit if requested is None else max(1, min(requested, limit))


@dataclass(frozen=True)
class Target:
    """What every task needs to know besides its spec."""

    layout: ResultsLayout
    renderer: str
    renderer_version: str
    retry_failed: bool = True
    force: bool = False


def _worker_init() -> None:
    """Pool workers die with the harness (and their renders with them)."""
    with contextlib.suppress(OSError):  # not glibc: no parent-death signal
        ctypes.CDLL("libc.so.6").prctl(1, int(signal.SIGTERM), 0, 0, 0)
    # Ctrl-C reaches the whole process group: let the renderer stop itself
    # (it writes final.exr and exits 3) and the main process decide.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _task(spec: RunSpec, target: Target) -> dict[str, Any]:
    return runs.execute(
        spec,
        target.layout,
        target.renderer,
        target.renderer_version,
        force=target.force,
        retry_failed=target.retry_failed,
    )


def _failure(spec: RunSpec, target: Target, error: BaseException) -> dict[str, Any]:
    """A manifest-like record of a task that failed outside the renderer; not installed."""
    return {
        "key": spec.key(target.renderer_version),
        "status": store.STATUS_FAILED,
        "cached": False,
        "error": f"harness error: {type(error).__name__}: {error}",
        "spec": spec.to_dict(),
        "installed": False,
    }


def run_local(specs: list[RunSpec], target: Target, jobs: int, on_done: DoneCallback) -> None:
    """Runs `specs` with `jobs` renders at a time; calls on_done in the main
    process as each finishes. One job runs in-process."""
    if jobs <= 1:
        for spec in specs:
            try:
                manifest = _task(spec, target)
            except (OSError, ValueError) as e:
                manifest = _failure(spec, target, e)
            on_done(spec, manifest)
        return
    context = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_worker_init) as pool:
        futures = {pool.submit(_task, spec, target): spec for spec in specs}
        try:
            for future in cf.as_completed(futures):
                spec = futures[future]
                try:
                    manifest = future.result()
                except Exception as e:  # a worker crash must not stop the sweep
                    manifest = _failure(spec, target, e)
                on_done(spec, manifest)
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)
            raise


def _check_shipped(renderer: str, scene: Path, spec: RunSpec, folder: Path) -> None:
    """The render of `spec` from the rebuilt `scene` reads only files under
    `folder`, and their bytes have the digest of the run key. ValueError if not."""
    effective = contract.print_config(renderer, scene, spec.overrides)
    inside = str(folder.resolve())
    for f in effective.files:
        if os.path.commonpath([inside, os.path.realpath(f)]) != inside:
            raise ValueError(
                f"the scene reads {f}, which was not shipped to the worker (an absolute path, or one that an "
                "override changes?): name it relative to the file that uses it"
            )
    digest = files_sha256(effective.files)
    if digest != spec.scene_sha256:
        raise ValueError(f"the worker's copy of the scene has digest {digest}, the run key says {spec.scene_sha256}")


def _relocate_config(text: bytes, folder: Path, root: str) -> bytes:
    """config.yaml as a render of the original scene writes it: the mesh
    paths the renderer made absolute in the worker's copy name the client's
    files again (the same bytes: the digest was checked), so that the
    installed run folder can be resumed and rendered again here."""

    def quoted(path: str) -> bytes:  # the renderer's YAML string, as config_emit.c writes it
        return ('"' + path.replace("\\", "\\\\").replace('"', '\\"')).encode()

    return text.replace(quoted(str(folder).rstrip("/") + "/"), quoted(root.rstrip("/") + "/"))


def render_shipped(
    spec: RunSpec, pack: ScenePack, renderer: str, renderer_version: str, final_dir: str | None = None
) -> tuple[str, dict[str, bytes]]:
    """The Dask task: rebuilds the scene's files in a private temporary
    folder on the worker, checks them, renders there and returns the run
    folder's files."""
    key = spec.key(renderer_version)
    with tempfile.TemporaryDirectory(prefix="portal-harness-") as tmp:
        folder = Path(tmp) / "scene"
        scene = unpack_scene(pack, folder)
        _check_shipped(renderer, scene, spec, folder)
        run = RunLayout(Path(tmp) / "run")
        run.dir.mkdir()
        runs.execute_in(spec, run, renderer, renderer_version, key, scene_path=str(scene), final_dir=final_dir)
        files = store.pack_files(run)
        if "config.yaml" in files:
            files["config.yaml"] = _relocate_config(files["config.yaml"], folder, pack.root)
        return key, files


def run_dask(specs: list[RunSpec], target: Target, address: str, on_done: DoneCallback) -> None:
    """Runs `specs` as tasks of the Dask scheduler at `address`; each returns
    its run folder's files, installed here as each finishes."""
    from distributed import Client, as_completed

    packs: dict[str, tuple[str, Any]] = {}  # scene -> (digest, the pack scattered to the cluster)
    with Client(address, timeout="30s") as client:  # type: ignore[no-untyped-call]
        futures = {}
        for spec in specs:
            if spec.scene not in packs:
                pack = pack_scene(contract.print_config(target.renderer, Path(spec.scene)).files)
                packs[spec.scene] = (pack.sha256, client.scatter(pack))
            digest, shipped = packs[spec.scene]
            if digest != spec.scene_sha256:
                changed = ValueError(f"{spec.scene} or a file it reads changed since the run was planned")
                on_done(spec, _failure(spec, target, changed))
                continue
            key = spec.key(target.renderer_version)
            final_dir = str(target.layout.run(key, spec.reference).dir)
            future = client.submit(
                render_shipped,
                spec,
                shipped,
                target.renderer,
                target.renderer_version,
                final_dir,
                key=f"render-{key}-{os.getpid()}",
                pure=False,
                retries=0,
            )
            futures[future] = spec
        for future in as_completed(list(futures)):  # type: ignore[no-untyped-call]
            spec = futures[future]
            try:
                key, files = future.result()
                run = store.install_files(target.layout, key, spec.reference, files)
                manifest = store.read_manifest(run) or _failure(spec, target, ValueError("no manifest returned"))
                manifest = {**manifest, "cached": False}
            except Exception as e:  # a lost worker or task error must not stop the sweep
                manifest = _failure(spec, target, e)
            on_done(spec, manifest)
