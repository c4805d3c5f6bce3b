"""Safe parsing of a Mitsuba XML file into elements that know their line.

The parser is the stdlib expat, configured to refuse what makes XML
dangerous: any document type declaration (so no entity can be declared, which
rules out entity expansion bombs) and any external entity or parameter
entity. Mitsuba scenes never need a DTD.
"""

from __future__ import annotations

import re
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path

from portal_harness.mitsuba_import.report import MitsubaImportError

# Mitsuba 0.5/0.6 spell parameters in camelCase; Mitsuba 2 and 3 in snake_case.
LEGACY_NAMES = {
    "toWorld": "to_world",
    "fovAxis": "fov_axis",
    "focalLength": "focal_length",
    "sampleCount": "sample_count",
    "maxDepth": "max_depth",
    "rrDepth": "rr_depth",
    "diffuseReflectance": "diffuse_reflectance",
    "specularReflectance": "specular_reflectance",
    "flipNormals": "flip_normals",
    "faceNormals": "face_normals",
    "shapeIndex": "shape_index",
    "intIOR": "int_ior",
    "extIOR": "ext_ior",
}


@dataclass
class Element:
    """One XML element: its tag, attributes (parameters substituted), line and children."""

    tag: str
    attrs: dict[str, str]
    line: int
    children: list[Element] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.attrs.get("name", "")

    @property
    def type(self) -> str:
        return self.attrs.get("type", "")

    def describe(self) -> str:
        """`<tag type="..." name="...">` as written, for messages."""
        parts = [self.tag] + [f'{k}="{self.attrs[k]}"' for k in ("type", "name", "id") if k in self.attrs]
        return "<" + " ".join(parts) + ">"


class _Refused(Exception):
    def __init__(self, line: int, message: str) -> None:
        self.line = line
        self.message = message


def parse_file(path: Path) -> Element:
    """The root element of the XML file; raises MitsubaImportError at the
    offending line for malformed XML, a DTD or an entity."""
    file = str(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise MitsubaImportError(file, 0, f"cannot read: {e.strerror or e}") from None
    parser = xml.parsers.expat.ParserCreate()
    parser.SetParamEntityParsing(xml.parsers.expat.XML_PARAM_ENTITY_PARSING_NEVER)
    stack: list[Element] = []
    roots: list[Element] = []

    def refuse(what: str) -> None:
        raise _Refused(parser.CurrentLineNumber, f"{what} refused (a Mitsuba scene needs none; they could expand)")

    def start(tag: str, attrs: dict[str, str]) -> None:
        e = Element(tag, dict(attrs), parser.CurrentLineNumber)
        (stack[-1].children if stack else roots).append(e)
        stack.append(e)

    def end(tag: str) -> None:
        stack.pop()

    def doctype(*_: object) -> None:
        refuse("document type declaration (DOCTYPE)")

    def entity(*_: object) -> None:
        refuse("entity declaration")

    def external(*_: object) -> int:
        refuse("external entity")
        return 0

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = entity
    parser.UnparsedEntityDeclHandler = entity
    parser.ExternalEntityRefHandler = external
    try:
        parser.Parse(data, True)
    except _Refused as e:
        raise MitsubaImportError(file, e.line, e.message) from None
    except xml.parsers.expat.ExpatError as e:
        raise MitsubaImportError(
            file, e.lineno, f"malformed XML: {xml.parsers.expat.ErrorString(e.code)} (column {e.offset + 1})"
        ) from None
    if not roots or roots[0].tag != "scene":
        raise MitsubaImportError(file, roots[0].line if roots else 1, "expected a <scene> root element")
    return roots[0]


_PARAM = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")


def substitute(root: Element, defines: dict[str, str], file: str) -> None:
    """Applies `<default name value>` (unless given in `defines`, as
    Mitsuba's -D does) and replaces `$name` in every attribute, in document
    order; renames legacy camelCase parameter names. An undefined `$name` is
    an error at its line."""
    values = dict(defines)

    def visit(e: Element) -> None:
        for key, text in e.attrs.items():
            if "$" in text:

                def repl(m: re.Match[str], e: Element = e) -> str:
                    if m.group(1) not in values:
                        raise MitsubaImportError(
                            file, e.line, f"undefined parameter ${m.group(1)} (expected a <default> or --define)"
                        )
                    return values[m.group(1)]

                e.attrs[key] = _PARAM.sub(repl, text)
        if e.tag == "default":
            if "name" not in e.attrs or "value" not in e.attrs:
                raise MitsubaImportError(file, e.line, '<default> needs name="..." and value="..."')
            values.setdefault(e.attrs["name"], e.attrs["value"])
        if e.attrs.get("name") in LEGACY_NAMES:
            e.attrs["name"] = LEGACY_NAMES[e.attrs["name"]]
        for child in e.children:
            visit(child)

    visit(root)
