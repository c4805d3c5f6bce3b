"""Mitsuba shapes as the renderer's shapes and lights: obj, ply and
serialized files copied next to scene.yaml (a serialized shape keeps its
shape_index: the renderer reads Mitsuba's serialized format itself),
rectangles as quads, cubes as boxes, disks, spheres and cylinders
tessellated into OBJ files; area emitters as polygon lights (rectangles) or
mesh lights (every other shape)."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from portal_harness.mitsuba_import import tessellate
from portal_harness.mitsuba_import.bsdfs import Bsdfs, Material
from portal_harness.mitsuba_import.output import Output
from portal_harness.mitsuba_import.params import Params
from portal_harness.mitsuba_import.report import Report
from portal_harness.mitsuba_import.transforms import Op, parse_transform
from portal_harness.mitsuba_import.values import Colours, boolean, number, vec3
from portal_harness.mitsuba_import.xmltree import Element

DEFAULT_MATERIAL = "mitsuba_default"  # Mitsuba's BSDF of a shape without one: diffuse 0.5
FILE_SHAPES = ("obj", "ply", "serialized")
TESSELLATED = ("sphere", "cylinder", "disk")
SKIPPED_SHAPES = {
    "shapegroup": "shape groups are not supported",
    "instance": "instances are not supported",
    "heightfield": "heightfields are not supported",
    "bsplinecurve": "curves are not supported",
    "linearcurve": "curves are not supported",
}


@dataclass
class ShapeImporter:
    report: Report
    base: Path  # folder that file names are relative to
    bsdfs: Bsdfs
    colours: Colours
    lookup: Callable[[Element], Element]
    out: Output
    skip_missing: bool

    def convert(self, e: Element) -> None:
        t = e.type
        if t in SKIPPED_SHAPES:
            self.report.warn(e.line, f"{e.describe()}: skipped: {SKIPPED_SHAPES[t]}")
            return
        if t not in (*FILE_SHAPES, "rectangle", "cube", *TESSELLATED):
            self.report.warn(e.line, f"{e.describe()}: skipped: shape type {t!r} is not supported")
            return
        p = Params(e, self.report)
        name = self.out.unique(e.attrs.get("id") or f"{t}_line{e.line}")
        tr = p.get("to_world")
        ops: list[Op] = []
        np.eye(4)
        if tr is not None:
            ops, _matrix = parse_transform(tr, self.report)
        flip_el = p.get("flip_normals")
        flip = flip_el is not None and boolean(flip_el, self.report)
        emitters = p.children("emitter")
        bsdf_els = p.children("bsdf")
        for ref in p.unnamed_refs():
            target = self.lookup(ref)
            if target.tag == "emitter":
                emitters.append(target)
            else:
                bsdf_els.append(ref)
        area = [m for m in emitters if m.type == "area"]
        for m in emitters:
            if m.type != "area":
                self.report.warn(m.line, f"{m.describe()} on a shape: skipped (only area emitters are supported)")
        if len(area) > 1:
            self.report.warn(area[1].line, f"{area[1].describe()}: a second emitter on one shape: skipped")

        source = self._file(p, e) if t in FILE_SHAPES else None
        if t in FILE_SHAPES and source is None:
            p.use_all()
            return
        self._mesh_options(p, e, t, bool(area))
        if area:
            self._light(e, p, name, t, ops, flip, area[0], bsdf_els, source)
        else:
            self._surface(e, p, name, t, ops, flip, bsdf_els, source)
        p.warn_unused()

    def _file(self, p: Params, e: Element) -> Path | None:
        fn = p.get("filename")
        if fn is None:
            raise self.report.error(e.line, f'{e.describe()}: missing <string name="filename">')
        path = self.base / fn.attrs.get("value", "")
        if not path.is_file():
            # Relative to the working directory, as the XML's own path was given:
            # the message (kept in scene.yaml's header) says the same on every machine.
            msg = f"mesh file {fn.attrs.get('value', '')} not found ({os.path.relpath(path)})"
            if not self.skip_missing:
                raise self.report.error(fn.line, f"{msg} (--skip-missing skips such shapes)")
            self.report.warn(fn.line, f"{e.describe()}: {msg}: shape skipped (--skip-missing)")
            return None
        if path.suffix.lower() != f".{e.type}":
            self.report.warn(
                fn.line,
                f"{e.describe()}: file {path.name} does not end in .{e.type}; "
                "the renderer picks the format from the extension",
            )
        return path

    def _file_keys(self, p: Params, t: str, source: Path) -> dict[str, Any]:
        """The mesh entry's `file` (a copy of the source, one per source
        file) and, for a serialized file, the `shape_index` of the shape in
        it (Mitsuba's default 0). The renderer checks the index against the
        file's dictionary and reports a bad one at its line in scene.yaml."""
        keys: dict[str, Any] = {"file": self.out.copy_mesh(source)}
        if t == "serialized":
            el = p.get("shape_index")
            index = number(el, self.report) if el is not None else 0.0
            if el is not None and (index != int(index) or index < 0):
                raise self.report.error(el.line, f"{el.describe()}: expected a non-negative integer, got {index:g}")
            keys["shape_index"] = int(index)
        return keys

    def _mesh_options(self, p: Params, e: Element, t: str, emitter: bool) -> None:
        fn = p.get("face_normals")
        if fn is not None and not boolean(fn, self.report):
            self.report.warn(fn.line, f"{fn.describe()}: the renderer always shades with face normals")

    def _analytic(self, p: Params, e: Element, t: str) -> tuple[np.ndarray, tessellate.Faces]:
        verts, faces = self._tessellate(p, e, t)
        if t in TESSELLATED:
            self.report.warn(
                e.line, f"{e.describe()}: tessellated into {len(faces)} triangles (vertices on the exact surface)"
            )
        return verts, faces

    def _tessellate(self, p: Params, e: Element, t: str) -> tuple[np.ndarray, tessellate.Faces]:
        if t == "sphere":
            c = p.get("center")
            r = p.get("radius")
            center = np.array(vec3(c, self.report) if c is not None else (0.0, 0.0, 0.0))
            radius = number(r, self.report) if r is not None else 1.0
            return tessellate.sphere(center, radius)
        if t == "cylinder":
            a, b, r = p.get("p0"), p.get("p1"), p.get("radius")
            p0 = np.array(vec3(a, self.report) if a is not None else (0.0, 0.0, 0.0))
            p1 = np.array(vec3(b, self.report) if b is not None else (0.0, 0.0, 1.0))
            if np.linalg.norm(p1 - p0) == 0:
                raise self.report.error(e.line, f"{e.describe()}: p0 equals p1")
            return tessellate.cylinder(p0, p1, number(r, self.report) if r is not None else 1.0)
        if t == "disk":
            return tessellate.disk()
        if t == "cube":
            return tessellate.cube()
        return tessellate.rectangle()

    def _material(self, e: Element, bsdf_els: list[Element]) -> tuple[str, Material | None, str]:
        if len(bsdf_els) > 1:
            self.report.warn(bsdf_els[1].line, f"{bsdf_els[1].describe()}: a second BSDF on one shape: dropped")
        if not bsdf_els:
            if DEFAULT_MATERIAL not in self.out.materials:
                self.out.materials[DEFAULT_MATERIAL] = Material("diffuse", (0.5, 0.5, 0.5)).to_yaml()
                self.report.warn(
                    e.line,
                    f"{e.describe()}: no BSDF: Mitsuba's default diffuse 0.5 used "
                    f"(material {DEFAULT_MATERIAL}), shaded on both sides",
                )
            return DEFAULT_MATERIAL, Material("diffuse", (0.5, 0.5, 0.5)), ""
        r = self.bsdfs.resolve(bsdf_els[0])
        if r.material is not None:
            self.out.materials.setdefault(r.name, r.material.to_yaml())
        return r.name, r.material, r.skip_reason

    def _surface(
        self,
        e: Element,
        p: Params,
        name: str,
        t: str,
        ops: list[Op],
        flip: bool,
        bsdf_els: list[Element],
        source: Path | None,
    ) -> None:
        mat_name, mat, why = self._material(e, bsdf_els)
        if mat is None:
            self.report.warn(e.line, f"{e.describe()}: skipped: {why}")
            return
        if flip:
            self.report.warn(e.line, f"{e.describe()}: flip_normals ignored (surfaces are two-sided here)")
        shape: dict[str, Any] = {"name": name, "material": mat_name}
        if source is not None:
            shape.update(type="mesh", **self._file_keys(p, t, source))
        elif t == "rectangle":
            verts, _ = tessellate.rectangle()
            shape.update(type="quad", vertices=verts.tolist())
        elif t == "cube":
            shape.update(type="box", min=[-1.0, -1.0, -1.0], max=[1.0, 1.0, 1.0])
        else:
            verts, faces = self._analytic(p, e, t)
            text = tessellate.obj_text(verts, faces, f"{t} of {self.report.file}:{e.line}")
            shape.update(type="mesh", file=self.out.mesh_text(f"{name}.obj", text))
        if ops:
            shape["transform"] = ops
        self.out.shapes.append(shape)

    def _light(
        self,
        e: Element,
        p: Params,
        name: str,
        t: str,
        ops: list[Op],
        flip: bool,
        emitter: Element,
        bsdf_els: list[Element],
        source: Path | None,
    ) -> None:
        ep = Params(emitter, self.report)
        rad_el = ep.get("radiance")
        radiance = self.colours.of(rad_el) if rad_el is not None else (1.0, 1.0, 1.0)
        ep.warn_unused()
        if bsdf_els:
            mat = self.bsdfs.resolve(bsdf_els[0]).material
            if mat is None or mat.kind != "diffuse" or any(mat.albedo):
                self.report.warn(
                    bsdf_els[0].line,
                    f"{bsdf_els[0].describe()} of an emitter: dropped (the renderer's lights reflect nothing)",
                )
        else:
            self.report.warn(
                e.line,
                f"{e.describe()}: Mitsuba's default diffuse BSDF of this emitter dropped "
                "(the renderer's lights reflect nothing)",
            )
        if not any(v > 0 for v in radiance) or any(v < 0 for v in radiance):
            self.report.warn(emitter.line, f"{emitter.describe()}: radiance {list(radiance)} is not positive: skipped")
            return
        light: dict[str, Any] = {"name": name}
        if t == "rectangle":
            verts, _ = tessellate.rectangle()
            order = verts[::-1] if flip else verts
            light["vertices"] = order.tolist()
            if ops:
                light["transform"] = ops
        else:
            mesh: dict[str, Any] = {}
            if source is not None:
                if flip and source.suffix.lower() == ".obj":
                    mesh["file"] = self.out.mesh_text(source.name, tessellate.flip_obj_text(source.read_text()))
                    self.report.warn(
                        e.line,
                        f"{e.describe()}: flip_normals: written as a copy of {source.name} with every face reversed",
                    )
                else:
                    if flip:
                        self.report.warn(
                            e.line,
                            f"{e.describe()}: flip_normals on a {'PLY' if t == 'ply' else t} emitter not "
                            "applied: it emits on the side its winding faces",
                        )
                    mesh.update(self._file_keys(p, t, source))
            else:
                verts, faces = self._analytic(p, e, t)
                if flip:
                    faces = tessellate.flipped(faces)
                text = tessellate.obj_text(verts, faces, f"{t} emitter of {self.report.file}:{e.line}")
                mesh["file"] = self.out.mesh_text(f"{name}.obj", text)
            if ops:
                mesh["transform"] = ops
            light["mesh"] = mesh
        light["radiance"] = [float(v) for v in radiance]
        light["two_sided"] = False
        self.out.lights.append(light)
