"""Triangle meshes of Mitsuba's analytic shapes, wound counter-clockwise
seen from the side of Mitsuba's normal (outwards for sphere and cylinder,
+z for disk), and written as OBJ files."""

from __future__ import annotations

import numpy as np

Faces = list[tuple[int, int, int]]
SPHERE_RINGS, SPHERE_SEGMENTS = 24, 48  # 2,208 triangles
CYLINDER_SEGMENTS = 64
DISK_SEGMENTS = 64


def sphere(
    center: np.ndarray, radius: float, rings: int = SPHERE_RINGS, segments: int = SPHERE_SEGMENTS
) -> tuple[np.ndarray, Faces]:
    """A UV sphere inscribed in the true one (vertices on it)."""
    verts = [[0.0, 0.0, 1.0]]
    for i in range(1, rings):
        th = np.pi * i / rings
        for j in range(segments):
            ph = 2 * np.pi * j / segments
            verts.append([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    verts.append([0.0, 0.0, -1.0])
    south = len(verts) - 1

    def at(i: int, j: int) -> int:  # ring i in 1..rings-1
        return 1 + (i - 1) * segments + j % segments

    faces: Faces = []
    for j in range(segments):
        # Outward normal = d/dtheta x d/dphi: down the meridian, then east.
        faces.append((0, at(1, j), at(1, j + 1)))
        for i in range(1, rings - 1):
            faces.append((at(i, j), at(i + 1, j), at(i + 1, j + 1)))
            faces.append((at(i, j), at(i + 1, j + 1), at(i, j + 1)))
        faces.append((at(rings - 1, j), south, at(rings - 1, j + 1)))
    return center + radius * np.array(verts), faces


def cylinder(
    p0: np.ndarray, p1: np.ndarray, radius: float, segments: int = CYLINDER_SEGMENTS
) -> tuple[np.ndarray, Faces]:
    """Mitsuba's cylinder: an open tube from p0 to p1, normals outwards."""
    w = p1 - p0
    axis = w / np.linalg.norm(w)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)  # (u, v, axis) right-handed
    verts = []
    for end in (p0, p1):
        for j in range(segments):
            ph = 2 * np.pi * j / segments
            verts.append(end + radius * (np.cos(ph) * u + np.sin(ph) * v))
    faces: Faces = []
    for j in range(segments):
        a, b = j, (j + 1) % segments
        # Outward = d/dphi x d/dz: around, then along the axis.
        faces.append((a, b, b + segments))
        faces.append((a, b + segments, a + segments))
    return np.array(verts), faces


def disk(segments: int = DISK_SEGMENTS) -> tuple[np.ndarray, Faces]:
    """The unit disk in z = 0, normal +z."""
    verts = [[0.0, 0.0, 0.0]] + [
        [np.cos(2 * np.pi * j / segments), np.sin(2 * np.pi * j / segments), 0.0] for j in range(segments)
    ]
    faces: Faces = [(0, 1 + j, 1 + (j + 1) % segments) for j in range(segments)]
    return np.array(verts), faces


def cube() -> tuple[np.ndarray, Faces]:
    """Mitsuba's cube [-1, 1]^3, normals outwards (for emitters; other cubes are boxes)."""
    verts = np.array([[x, y, z] for z in (-1.0, 1.0) for y in (-1.0, 1.0) for x in (-1.0, 1.0)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces: Faces = []
    for a, b, c, d in quads:
        faces += [(a, b, c), (a, c, d)]
    return verts, faces


def rectangle() -> tuple[np.ndarray, Faces]:
    """Mitsuba's rectangle [-1, 1]^2 in z = 0, normal +z."""
    verts = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    return verts, [(0, 1, 2), (0, 2, 3)]


def flipped(faces: Faces) -> Faces:
    return [(a, c, b) for a, b, c in faces]


def obj_text(verts: np.ndarray, faces: Faces, comment: str) -> str:
    lines = [f"# {comment}"]
    lines += [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in verts]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return "\n".join(lines) + "\n"


def flip_obj_text(text: str) -> str:
    """An OBJ file with every face's vertex order reversed (its winding, so
    its emitting side), everything else as it is."""
    out = []
    for line in text.splitlines():
        parts = line.split()
        if parts and parts[0] == "f":
            line = " ".join([parts[0], parts[1], *reversed(parts[2:])])
        out.append(line)
    return "\n".join(out) + "\n"
