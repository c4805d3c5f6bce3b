"""The walk over a Mitsuba scene's top level: ids, refs, and which module
converts each element."""

from __future__ import annotations

from pathlib import Path

from portal_harness.mitsuba_import.bsdfs import SMOOTH_CONDUCTOR_ALPHA, Bsdfs
from portal_harness.mitsuba_import.output import Output
from portal_harness.mitsuba_import.report import Report
from portal_harness.mitsuba_import.sensor import DEFAULT_SPP, convert_integrator, convert_sensor, fov_y
from portal_harness.mitsuba_import.shapes import ShapeImporter
from portal_harness.mitsuba_import.values import Colours
from portal_harness.mitsuba_import.xmltree import Element, parse_file, substitute

SKIPPED_EMITTERS = ("point", "spot", "envmap", "constant", "directional", "sunsky", "sky", "sun", "projector")


def _index(root: Element, report: Report) -> dict[str, Element]:
    ids: dict[str, Element] = {}

    def visit(e: Element) -> None:
        if "id" in e.attrs and e.tag != "ref":
            if e.attrs["id"] in ids:
                raise report.error(e.line, f"duplicate id {e.attrs['id']!r} (first at line {ids[e.attrs['id']].line})")
            ids[e.attrs["id"]] = e
        for c in e.children:
            visit(c)

    visit(root)
    return ids


def convert(
    xml_path: Path,
    defines: dict[str, str] | None = None,
    skip_missing: bool = False,
    smooth_alpha: float = SMOOTH_CONDUCTOR_ALPHA,
) -> tuple[Output, Report]:
    """Reads and converts a scene; nothing is written. Raises
    MitsubaImportError (file:line) on what cannot be imported."""
    report = Report(str(xml_path))
    root = parse_file(xml_path)
    substitute(root, defines or {}, report.file)
    ids = _index(root, report)

    def lookup(ref: Element) -> Element:
        target = ids.get(ref.attrs.get("id", ""))
        if target is None:
            raise report.error(ref.line, f'<ref id="{ref.attrs.get("id", "")}">: no element has this id')
        return target

    # absolute(), not resolve(): a symlinked folder stays as the user named it,
    # so messages that name files relative to the working directory keep it.
    base = xml_path.absolute().parent
    colours = Colours(report, base, lookup)
    bsdfs = Bsdfs(report, colours, lookup, smooth_alpha)
    out = Output()
    shapes = ShapeImporter(report, base, bsdfs, colours, lookup, out, skip_missing)
    sensor_seen = False
    for e in root.children:
        if e.tag == "default":
            continue
        if e.tag == "integrator":
            out.render.update(convert_integrator(e, report))
        elif e.tag == "sensor":
            if e.type not in ("perspective", "thinlens"):
                report.warn(e.line, f"{e.describe()}: sensor type {e.type!r} not supported: skipped")
            elif sensor_seen:
                report.warn(e.line, f"{e.describe()}: a second sensor: skipped (the renderer has one camera)")
            else:
                sensor_seen = True
                out.camera, (w, h), render = convert_sensor(e, report)
                out.film = {"width": w, "height": h}
                out.render.update(render)
        elif e.tag == "shape":
            shapes.convert(e)
        elif e.tag == "emitter":
            if e.type == "area":
                report.warn(e.line, f"{e.describe()}: an area emitter outside a shape emits nothing: skipped")
            else:
                what = "not supported" if e.type not in SKIPPED_EMITTERS else "the renderer has only area lights"
                report.warn(e.line, f"{e.describe()}: {e.type} emitter skipped ({what})")
        elif e.tag in ("bsdf", "texture", "spectrum", "rgb") and "id" in e.attrs:
            continue  # converted where it is referenced
        elif e.tag == "include":
            report.warn(e.line, f"{e.describe()}: include not followed (import the included file on its own)")
        else:
            report.warn(e.line, f"{e.describe()}: not supported: skipped")
    if not sensor_seen:
        report.warn(
            root.line,
            "no perspective sensor: Mitsuba's default camera used (at the origin, looking along "
            "+z, fov 45 along x, 768x576)",
        )
        w, h = 768, 576
        out.camera = {
            "position": [0.0, 0.0, 0.0],
            "look_at": [0.0, 0.0, 1.0],
            "up": [0.0, 1.0, 0.0],
            "fov_y": round(fov_y(45.0, "x", w, h), 10),
        }
        out.film = {"width": w, "height": h}
    if "integrator" not in out.render and not any(e.tag == "integrator" for e in root.children):
        report.warn(root.line, "no integrator: Mitsuba's default (path, unbounded) mapped to path with max_depth 64")
        out.render.update({"integrator": "path", "max_depth": 64})
    out.render.setdefault("spp", DEFAULT_SPP)
    out.render["output"] = f"results/renders/{xml_path.stem}"
    if not out.lights:
        report.warn(root.line, "no area light was imported: the renderer refuses a scene without lights")
    return out, report
