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

AUTO_PORTALS_NOTE = (
    "# portals: auto: the renderer finds every light's portals at scene build (a light that nothing "
    "encloses gets none);\n# a config that includes this file and lists portals replaces it "
    "(import with --no-auto-portals for none)."
)


def scene_document(out: Output, auto_portals: bool = True) -> dict[str, Any]:
    """The scene's YAML sections; with auto_portals (and a light), `portals:
    auto`, so that every imported emitter gets the portals the renderer finds."""
    doc: dict[str, Any] = {"camera": out.camera, "film": out.film, "materials": out.materials}
    if out.shapes:
        doc["shapes"] = out.shapes
    doc["lights"] = out.lights
    if auto_portals and out.lights:
        doc["portals"] = "auto"
    doc["render"] = out.render
    return doc


def scene_text(out: Output, report: Report, source: Path, auto_portals: bool = True) -> str:
    head = [f"# Imported from {source} by portal-harness import-mitsuba.", "# Warnings of the import:"]
    head += [f"#   {line}" for line in report.lines()] or ["#   none"]
    doc = scene_document(out, auto_portals)
    if "portals" in doc:
        head.append(AUTO_PORTALS_NOTE)
    body = yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120)
    return "\n".join(head) + "\n\n" + body


def write(
    out: Output, report: Report, source: Path, dest: Path, force: bool = False, auto_portals: bool = True
) -> Path:
    """Writes the import into dest (a new or empty folder, or any folder with
    force) and returns the path of scene.yaml; auto_portals: scene_document."""
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
        (tmp / "scene.yaml").write_text(scene_text(out, report, source, auto_portals))
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
