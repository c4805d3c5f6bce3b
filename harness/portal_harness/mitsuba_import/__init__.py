"""`portal-harness import-mitsuba`: a Mitsuba 3 (or 2) XML scene as the
renderer's YAML with its meshes. Modules: xmltree (safe parsing, lines,
$params), transforms, values (colours, textures), bsdfs, shapes (and
tessellate), sensor, scene (the walk), output and writer."""

from __future__ import annotations

from pathlib import Path

from portal_harness.mitsuba_import.bsdfs import SMOOTH_CONDUCTOR_ALPHA
from portal_harness.mitsuba_import.report import MitsubaImportError, Report
from portal_harness.mitsuba_import.scene import convert
from portal_harness.mitsuba_import.writer import write

__all__ = ["SMOOTH_CONDUCTOR_ALPHA", "MitsubaImportError", "Report", "import_scene"]


def import_scene(
    xml_path: Path,
    dest: Path,
    defines: dict[str, str] | None = None,
    skip_missing: bool = False,
    smooth_alpha: float = SMOOTH_CONDUCTOR_ALPHA,
    force: bool = False,
    auto_portals: bool = True,
) -> tuple[Path, Report]:
    """Converts xml_path into dest/scene.yaml (and dest/meshes/); returns
    the YAML's path and the report of warnings. Nothing is written on error.
    With auto_portals (the default) the scene has `portals: auto`: the
    renderer finds every imported emitter's portals at scene build."""
    out, report = convert(xml_path, defines, skip_missing, smooth_alpha)
    return write(out, report, xml_path, dest, force, auto_portals), report
