"""Writes an import: DIR/scene.yaml and DIR/meshes/, all or nothing (into a
temporary folder beside DIR, renamed at the end)."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import Any

import yaml

from portal_harness.mitsuba_import.output import MESH_DIR, Output
from portal_harness.mitsuba_import.report import MitsubaImportError, Report


def scene_document(out: Output) -> dict[str, Any]:
    doc: dict[str, Any] = {"camera": out.camera, "film": out.film, "materials": out.materials}
    if out.shapes:
        doc["shapes"] = out.shapes
    doc["lights"] = out.lights
    doc["render"] = out.render
    return doc


def scene_text(out: Output, report: Report, source: Path) -> str:
    head = [f"# Imported from {source} by portal-harness import-mitsuba.", "# Warnings of the import:"]
    head += [f"#   {line}" for line in report.lines()] or ["#   none"]
    body = yaml.safe_dump(scene_document(out), sort_keys=False, default_flow_style=None, width=120)
    return "\n".join(head) + "\n\n" + body


def write(out: Output, report: Report, source: Path, dest: Path, force: bool = False) -> Path:
    """Writes the import into dest (a new or empty folder, or any folder with
    force) and returns the path of scene.yaml."""
    if dest.exists() and (not dest.is_dir() or (any(dest.iterdir()) and not force)):
        raise MitsubaImportError(str(dest), 0, "exists and is not an empty folder (expected a new folder, or --force)")
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.", dir=dest.parent))
    try:
        if out.copies or out.texts:
            (tmp / MESH_DIR).mkdir()
        for rel, src in out.copies.items():
            shutil.copyfile(src, tmp / rel)
        for rel, text in out.texts.items():
            (tmp / rel).write_text(text)
        (tmp / "scene.yaml").write_text(scene_text(out, report, source))
        if dest.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{dest.name}.old.", dir=dest.parent))
            dest.rename(old / dest.name)
            tmp.rename(dest)
            shutil.rmtree(old)
        else:
            tmp.rename(dest)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return dest / "scene.yaml"
