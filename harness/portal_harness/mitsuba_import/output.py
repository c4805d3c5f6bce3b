"""What an import produces before it is written: the YAML sections and the
mesh files to copy or write next to scene.yaml."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

MESH_DIR = "meshes"


@dataclass
class Output:
    camera: dict[str, Any] = field(default_factory=dict)
    film: dict[str, Any] = field(default_factory=dict)
    render: dict[str, Any] = field(default_factory=dict)
    materials: dict[str, Any] = field(default_factory=dict)
    shapes: list[dict[str, Any]] = field(default_factory=list)
    lights: list[dict[str, Any]] = field(default_factory=list)
    copies: dict[str, Path] = field(default_factory=dict)  # meshes/NAME -> source file
    texts: dict[str, str] = field(default_factory=dict)  # meshes/NAME -> content
    names: set[str] = field(default_factory=set)

    def unique(self, wanted: str) -> str:
        """A shape or light name not used yet (the renderer wants unique light names; 63 characters at most)."""
        base = re.sub(r"[^A-Za-z0-9_.-]", "_", wanted)[:56] or "shape"
        name, n = base, 2
        while name in self.names:
            name, n = f"{base}_{n}", n + 1
        self.names.add(name)
        return name

    def _mesh_path(self, filename: str) -> str:
        stem, dot, ext = filename.rpartition(".")
        if not dot:
            stem, ext = filename, ""
        rel, n = f"{MESH_DIR}/{filename}", 2
        while rel in self.copies or rel in self.texts:
            rel, n = f"{MESH_DIR}/{stem}_{n}.{ext}", n + 1
        return rel

    def copy_mesh(self, source: Path) -> str:
        """The path relative to scene.yaml of a copy of `source` (one copy per source file)."""
        for rel, src in self.copies.items():
            if src == source:
                return rel
        rel = self._mesh_path(source.name)
        self.copies[rel] = source
        return rel

    def mesh_text(self, filename: str, text: str) -> str:
        rel = self._mesh_path(filename)
        self.texts[rel] = text
        return rel
