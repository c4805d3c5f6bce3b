"""Scene files with `include:` as the renderer reads them (README, config
reference): the included files load first, in order, each merged over the
ones before, then the including file over them; mappings merge key by key,
sequences and scalars are replaced whole. The harness needs the merged tree
to check sweep keys against it, and the content of every file involved to
key its caches: a change in an included file must change the run key."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

from portal_harness.errors import ConfigError
from portal_harness.schema import kind_of, read_yaml

# The renderer's limit (CONFIG_INCLUDE_DEPTH_MAX).
MAX_DEPTH = 16


def merge(base: Any, over: Any) -> Any:
    """`over` merged over `base`: mappings key by key (first-seen key order),
    anything else replaced whole."""
    if isinstance(base, dict) and isinstance(over, dict):
        out = dict(base)
        for key, value in over.items():
            out[key] = merge(base[key], value) if key in base else value
        return out
    return over


def _include_paths(path: Path, tree: Any) -> list[Path]:
    if not isinstance(tree, dict) or tree.get("include") is None:
        return []
    node = tree["include"]
    items = node if isinstance(node, list) else [node]
    out = []
    for item in items:
        if not isinstance(item, str) or not item:
            raise ConfigError(str(path), "include", f"expected a path or a list of paths, got {kind_of(item)}")
        p = Path(item)
        out.append(p if p.is_absolute() else path.parent / p)
    return out


def _load(path: Path, chain: tuple[Path, ...], files: list[Path]) -> Any:
    real = Path(os.path.realpath(path))
    if real in chain:
        names = " -> ".join(str(p) for p in (*chain, real))
        raise ConfigError(str(path), "include", f"include cycle: {names}")
    if len(chain) > MAX_DEPTH:
        raise ConfigError(str(path), "include", f"includes nested deeper than {MAX_DEPTH} levels")
    tree = read_yaml(path, "scene file" if not chain else "included file")
    files.append(path)
    merged: Any = None
    for inc in _include_paths(path, tree):
        merged = merge(merged, _load(inc, (*chain, real), files))
    if isinstance(tree, dict):
        tree = {k: v for k, v in tree.items() if k != "include"}
    return tree if merged is None else merge(merged, tree)


def load_merged(path: Path) -> tuple[Any, list[Path]]:
    """The merged tree of a scene file and the files it was built from, in load order."""
    files: list[Path] = []
    return _load(path, (), files), files


def files_sha256(files: list[Path]) -> str:
    """Digest of the files a scene was built from (content and order): what
    the harness's run keys use for the scene."""
    if len(files) == 1:
        # Unchanged for self-contained scenes, so existing run keys stay valid.
        return hashlib.sha256(files[0].read_bytes()).hexdigest()
    h = hashlib.sha256()
    for f in files:
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()

