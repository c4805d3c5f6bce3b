"""Extending a finished reference with more samples (`render --resume`).

The renderer continues the reference's running mean and variance with
passes it had not drawn, bit-identical to an uninterrupted render of the
total spp (docs/rendering.md, "Resuming a render"). The harness does it in
a copy: the installed folder is copied to an attempt folder, resumed there,
checked like any run, given its new manifest (the old one with the new
final image and an `extensions` entry) and installed in place of the old
folder. A failed or killed extension leaves the installed reference as it
was. Extensions run on the local machine (they need the reference's film
state), also when the sweep's renders go to Dask.
"""

from __future__ import annotations

import shutil
from dataclasses import replace
from typing import Any

from portal_harness.core import exr
from portal_harness.core.errors import CorruptExrError
from portal_harness.core.paths import ResultsLayout, RunLayout
from portal_harness.execution import store
from portal_harness.execution.renderer import EXIT_OK, render
from portal_harness.execution.runs import file_tail, final_record, now
from portal_harness.experiment.spec import RunSpec


def extension_timeout(manifest: dict[str, Any], total_spp: int) -> float:
    """Wall seconds after which an extension counts as hung: three times the
    render time it should take at the rate the reference has rendered so
    far, plus a minute (like runs.default_timeout for a first render)."""
    final = manifest["final"]
    done, time_s = max(int(final["spp"]), 1), float(final["time_s"])
    return 3.0 * time_s * max(total_spp - done, 1) / done + 60.0


def resume_command(renderer: str, run_dir: str, total_spp: int, threads: int) -> list[str]:
    """The renderer contract's resume call: totals, not increments."""
    return [renderer, "--resume", run_dir, "--spp", str(total_spp), "--time", "0", "--threads", str(threads), "--quiet"]


def extend(layout: ResultsLayout, key: str, total_spp: int, renderer: str, threads: int) -> dict[str, Any]:
    """Resumes reference `key` to `total_spp` samples per pixel; returns its
    new manifest (status failed, and the old folder untouched, on failure)."""
    target = layout.run(key, True)
    old = store.read_manifest(target)
    if old is None or old.get("status") != store.STATUS_DONE:
        raise ValueError(f"reference {key} is not a finished run")
    attempt = store.new_attempt(layout, key, True)
    for item in target.dir.iterdir():
        if item.is_file() and item.name != target.manifest.name:
            shutil.copy2(item, attempt.dir / item.name)
    before = int(old["final"]["spp"])
    command = resume_command(renderer, str(attempt.dir), total_spp, threads)
    started = now()
    result = render(command, attempt.events, attempt.stderr, timeout_s=extension_timeout(old, total_spp))
    entry: dict[str, Any] = {
        "from_spp": before,
        "to_spp": total_spp,
        "from_time_s": float(old["final"]["time_s"]),
        "started": started,
        "finished": now(),
        "wall_s": round(result.wall_s, 3),
        "exit_status": result.exit_status,
        "command": resume_command(renderer, str(target.dir), total_spp, threads),
    }
    error = None
    final = None
    if result.exit_status != EXIT_OK or result.signal_name is not None:
        error = f"render --resume exited with status {result.exit_status} {result.signal_name or ''}".rstrip()
    else:
        try:
            snap = exr.read_snapshot(attempt.final)
            if snap.header.spp != total_spp:
                error = f"resumed reference has {snap.header.spp} spp, expected {total_spp}"
            final = final_record(attempt.relative(attempt.final), snap.header)
        except CorruptExrError as e:
            error = str(e)
    if error is not None:
        tail = file_tail(attempt.stderr)
        shutil.rmtree(attempt.dir, ignore_errors=True)
        return {**old, "status": store.STATUS_FAILED, "error": f"extension failed: {error}", "stderr_tail": tail}
    manifest = {
        **old,
        "final": final,
        "extensions": [*old.get("extensions", []), entry],
        "timings": {**old.get("timings", {}), "render_time_s": final["time_s"] if final else None},
    }
    store.write_json_atomic(attempt.manifest, manifest)
    store.install(layout, key, True, attempt)
    return manifest


def stored_stream(layout: ResultsLayout, spec: RunSpec, renderer_version: str) -> RunSpec | None:
    """`spec` with the length of the longest finished stored reference that
    differs from it in nothing but its length (spp, time_s: another
    experiment's, whose pilot predicted another first time), so that it
    has that reference's key; None when `spec`'s own folder is finished or
    no such reference is stored. The sweep then continues what is stored
    instead of rendering the same reference again from its first pass.
    Measured: multi_lamp's and multi_lamp_weights' antishadow_exact parts
    were planned at 25 s and 23 s, two keys for one reference."""
    if store.is_done(layout.run(spec.key(renderer_version), True)):
        return None
    best: tuple[int, RunSpec] | None = None
    for folder in sorted(layout.references_dir.glob("*/manifest.json")):
        m = store.read_manifest(RunLayout(folder.parent))
        stored = (m or {}).get("spec") or {}
        if not m or m.get("status") != store.STATUS_DONE or m.get("parts") or stored.get("strategy") != spec.strategy:
            continue
        # The reference key says which renders are one stream (spec.RunSpec.key: the
        # image's scene hash, strategy, seed); with the stored length it must be the stored key.
        candidate = replace(spec, spp=int(stored.get("spp", 0)), time_s=float(stored.get("time_s", 0.0)))
        spp = int((m.get("final") or {}).get("spp", 0))
        if candidate.key(renderer_version) == m.get("key") and (best is None or spp > best[0]):
            best = (spp, candidate)
    return best[1] if best else None
