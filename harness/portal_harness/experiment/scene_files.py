"""The files a scene is built from (the scene, every file it includes,
every mesh file it reads, as `render --print-config` lists them): their
digest, the scene part of the run keys, and their pack.

A scene travels as a `ScenePack` (the Dask path): those files' bytes by
their paths relative to the folder that holds them all, so that a worker
can rebuild the folder elsewhere and the relative `include:` and `file:`
paths resolve there as they do here.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path


def contents_sha256(contents: Sequence[bytes]) -> str:
    """Digest of the contents of a scene's files, in load order."""
    if len(contents) == 1:
        # A self-contained scene keeps its plain file digest, so that its run keys stay valid.
        return hashlib.sha256(contents[0]).hexdigest()
    h = hashlib.sha256()
    for data in contents:
        h.update(hashlib.sha256(data).digest())
    return h.hexdigest()


def files_sha256(files: Sequence[Path]) -> str:
    """Digest of the files a scene was built from (content and order)."""
    if len(files) == 1:
        return contents_sha256([files[0].read_bytes()])
    h = hashlib.sha256()
    for f in files:  # one file in memory at a time: meshes can be large
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()


@dataclass(frozen=True)
class ScenePack:
    """The files of one scene, to rebuild it in another folder. Paths are
    relative to `root`, the deepest folder that holds every file (on the
    machine that packed it): the scene's relative `include:` and `file:`
    paths then resolve in the copy as they do in the original."""

    root: str
    scene: str  # the scene file, relative to root
    order: tuple[str, ...]  # the files in load order (the digest's order), relative to root
    contents: tuple[tuple[str, bytes], ...]  # each distinct file once: (relative path, bytes)
    sha256: str  # files_sha256 of the files in `order`


def pack_scene(files: Sequence[Path]) -> ScenePack:
    """A pack of `files` (the renderer's `files`: the scene first, then what
    it reads), read once, with their digest."""
    if not files:
        raise ValueError("a scene pack needs at least the scene file")
    paths = [os.path.abspath(f) for f in files]
    root = os.path.commonpath([os.path.dirname(p) for p in paths])
    order = tuple(os.path.relpath(p, root) for p in paths)
    data: dict[str, bytes] = {}
    for rel, path in zip(order, paths, strict=True):
        if rel not in data:
            data[rel] = Path(path).read_bytes()
    return ScenePack(
        root=root,
        scene=order[0],
        order=order,
        contents=tuple(data.items()),
        sha256=contents_sha256([data[rel] for rel in order]),
    )


def unpack_scene(pack: ScenePack, folder: Path) -> Path:
    """Writes the pack's files under `folder` (created if missing) and
    returns the scene file's path there. ValueError if the bytes are not the
    ones the pack's digest names, or a path would leave `folder`."""
    data = dict(pack.contents)
    if set(data) != set(pack.order) or pack.scene != pack.order[0]:
        raise ValueError("scene pack: its file list and its contents disagree")
    if contents_sha256([data[rel] for rel in pack.order]) != pack.sha256:
        raise ValueError(f"scene pack of {pack.root}/{pack.scene}: the files' bytes do not have its digest")
    for rel, content in data.items():
        if os.path.isabs(rel) or ".." in Path(rel).parts:
            raise ValueError(f"scene pack: refusing to write {rel!r} outside {folder}")
        dest = folder / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_bytes(content)
    return folder / pack.scene
