"""The region renders of a sweep's reference points: the region map (the
region AOV's class fractions, the regions of the metrics) and the section view
of figures.region_sections."""

from __future__ import annotations

import contextlib
import sqlite3
from typing import Any

from portal_harness.core import exr
from portal_harness.core.errors import CorruptExrError
from portal_harness.execution import store
from portal_harness.execution.batch import SweepOptions, execute_specs
from portal_harness.experiment.model import Experiment


def region_sections(
    experiment: Experiment, options: SweepOptions, conn: sqlite3.Connection, manifests: dict[str, dict[str, Any]]
) -> dict[str, str]:
    """Per reference point, the key of its render of figures.region_sections
    (none without the key): the figures read its region AOV, and nothing
    else uses it, so a failed one is only listed with the failures."""
    if experiment.region_sections is None:
        return {}
    specs = {p.id: experiment.region_section_spec(p) for p in experiment.reference_points()}
    manifests.update(execute_specs(list(specs.values()), options, conn, desc="region sections"))
    return {pid: spec.key(options.renderer_version) for pid, spec in specs.items()}


def region_maps(
    experiment: Experiment, options: SweepOptions, conn: sqlite3.Connection, manifests: dict[str, dict[str, Any]]
) -> dict[str, tuple[str, Any]]:
    """Per reference point, (key, fractions) of its region-map render (fractions None if it failed)."""
    specs = {p.id: experiment.region_map_spec(p) for p in experiment.reference_points()}
    manifests.update(execute_specs(list(specs.values()), options, conn, desc="region maps"))
    out: dict[str, tuple[str, Any]] = {}
    for pid, spec in specs.items():
        key = spec.key(options.renderer_version)
        fractions = None
        if (manifests.get(key) or {}).get("status") == store.STATUS_DONE:
            with contextlib.suppress(CorruptExrError):
                fractions = exr.read_snapshot(options.layout.run(key).final).regions
        out[pid] = (key, fractions)
    return out
