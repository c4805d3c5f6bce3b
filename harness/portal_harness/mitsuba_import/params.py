"""The named parameters of one Mitsuba element, remembering which ones the
importer used so that every other one is warned about, once."""

from __future__ import annotations

from portal_harness.mitsuba_import.report import Report
from portal_harness.mitsuba_import.values import PARAM_TAGS
from portal_harness.mitsuba_import.xmltree import Element


class Params:
    def __init__(self, element: Element, report: Report) -> None:
        self.element = element
        self.report = report
        self.used: set[int] = set()

    def get(self, name: str) -> Element | None:
        """The child parameter called `name` (marked used), or None."""
        for i, c in enumerate(self.element.children):
            if c.name == name and (c.tag in PARAM_TAGS or c.tag == "transform"):
                self.used.add(i)
                return c
        return None

    def children(self, tag: str) -> list[Element]:
        """Children with this tag (bsdf, emitter, film ...), marked used."""
        out = []
        for i, c in enumerate(self.element.children):
            if c.tag == tag:
                self.used.add(i)
                out.append(c)
        return out

    def unnamed_refs(self) -> list[Element]:
        """`<ref id>` children without a parameter name (or named bsdf, as Mitsuba 3 allows), marked used."""
        out = []
        for i, c in enumerate(self.element.children):
            if c.tag == "ref" and c.name in ("", "bsdf", "emitter"):
                self.used.add(i)
                out.append(c)
        return out

    def use_all(self) -> None:
        self.used.update(range(len(self.element.children)))

    def warn_unused(self, what: str = "ignored (no equivalent in the renderer)") -> None:
        # The parent without its id, so that the same parameter ignored on
        # many shapes is one message listing its lines.
        parent = f'<{self.element.tag} type="{self.element.type}">' if self.element.type else f"<{self.element.tag}>"
        for i, c in enumerate(self.element.children):
            if i not in self.used:
                self.report.warn(c.line, f"{c.describe()} of {parent}: {what}")
