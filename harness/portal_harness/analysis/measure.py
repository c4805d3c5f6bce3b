"""Metrics of runs against references: reads snapshots through exr.py,
computes with metrics.py, writes metrics.csv / metrics.json into the run
folder and rows into the index. A corrupt snapshot gives a row with its
error and no values: it is reported, never averaged in."""

from __future__ import annotations

import csv
import io
import json
from dataclasses import asdict
from typing import Any

from portal_harness.core import exr, metrics
from portal_harness.core.errors import CorruptExrError
from portal_harness.core.metrics import WHOLE_IMAGE
from portal_harness.core.paths import RunLayout
from portal_harness.core.regions import NamedRegion, fingerprint
from portal_harness.execution import store
from portal_harness.execution.index import MetricRow


def images_of(run: RunLayout, manifest: dict[str, Any]) -> list[tuple[str, bool, float, int]]:
    """(file, is_final, time_s, spp) of every snapshot then final.exr, as recorded in the manifest."""
    out = [(s["file"], False, float(s["time_s"]), int(s["spp"])) for s in manifest.get("snapshots", [])]
    final = manifest.get("final")
    if final:
        out.append((final["file"], True, float(final["time_s"]), int(final["spp"])))
    return out


def compute(
    run: RunLayout, manifest: dict[str, Any], reference: exr.Snapshot, regions: list[NamedRegion]
) -> list[MetricRow]:
    """One row per image and region (regions.regions_of: image, lit, insets, classes)."""
    named = [(r.name, r.mask) for r in regions]
    floors = {name: metrics.rel_variance_floor(reference.rgb, reference.variance, mask) for name, mask in named}
    rows: list[MetricRow] = []
    for file, is_final, time_s, spp in images_of(run, manifest):
        try:
            snap = exr.read_snapshot(run.resolve(file))
            if snap.rgb.shape != reference.rgb.shape:
                raise CorruptExrError(
                    str(run.resolve(file)),
                    f"size {snap.rgb.shape[1]}x{snap.rgb.shape[0]} differs from the reference's "
                    f"{reference.rgb.shape[1]}x{reference.rgb.shape[0]}",
                )
        except CorruptExrError as e:
            rows.append(MetricRow(file, is_final, time_s, spp, WHOLE_IMAGE, None, None, None, str(e)))
            continue
        for name, mask in named:
            rows.append(
                MetricRow(
                    image=file,
                    is_final=is_final,
                    time_s=snap.header.render_time_s,
                    spp=snap.header.spp,
                    region=name,
                    mse=metrics.mse(snap.rgb, reference.rgb, mask),
                    rel_mse=metrics.rel_mse(snap.rgb, reference.rgb, mask),
                    floor_rel=floors[name],
                    error=None,
                )
            )
    return rows


def _regions_json(regions: list[NamedRegion]) -> dict[str, Any]:
    return {
        "names": [r.name for r in regions],
        "pixels": [r.pixels for r in regions],
        "fingerprint": fingerprint(regions),
    }


def up_to_date(run: RunLayout, reference_key: str, regions: list[NamedRegion]) -> bool:
    """True if the run's metrics files were computed against this reference and these region masks."""
    try:
        with open(run.metrics_json) as f:
            data = json.load(f)
    except (OSError, json.JSONDecodeError):
        return False
    return bool(data.get("reference_key") == reference_key and data.get("regions") == _regions_json(regions))


def write_files(
    run: RunLayout, key: str, reference_key: str, regions: list[NamedRegion], rows: list[MetricRow]
) -> None:
    """metrics.csv (one line per image and region) and metrics.json (the same plus context)."""
    fields = list(MetricRow.__dataclass_fields__)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({k: ("" if v is None else v) for k, v in asdict(r).items()})
    tmp = run.metrics_csv.with_name(".metrics.csv.tmp")
    tmp.write_text(buffer.getvalue())
    tmp.replace(run.metrics_csv)
    store.write_json_atomic(
        run.metrics_json,
        {
            "key": key,
            "reference_key": reference_key,
            "regions": _regions_json(regions),
            "epsilon": metrics.REL_EPSILON,
            "rows": [{k: store.finite_or_none(v) for k, v in asdict(r).items()} for r in rows],
        },
    )


def read_rows(run: RunLayout) -> list[MetricRow]:
    with open(run.metrics_json) as f:
        data = json.load(f)
    return [MetricRow(**row) for row in data["rows"]]
