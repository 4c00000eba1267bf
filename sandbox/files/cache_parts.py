"""The solids a scene holds besides its particles, as a cache carries them: the walls, the heat plates and the lid.

Each part is an axis-aligned box in scene lengths (a 2D scene's parts are one spacing deep, centred on z = 0, as its
particles are); the walls are the domain's box open at the top and the front (+y and +z), so a camera in front of it
sees in. Every face has its own four corners, so a renderer shades the boxes flat. A USD stage gives each part its
own Mesh prim; PLY and VTK caches write all of them as one mesh a frame, the `part` number on each corner.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cache_formats import Surface

# the faces of a box: (axis, side (0 low, 1 high)), named as `open` names them
FACES = {"-x": (0, 0), "+x": (0, 1), "-y": (1, 0), "+y": (1, 1), "-z": (2, 0), "+z": (2, 1)}


@dataclass(frozen=True)
class Part:
    """One solid: `name` (walls, lid, plate_0, ...), `lo` and `hi` its box's corners (3,), `color` its sRGB colour
    (3 bytes, as the sandbox draws it), `temperature` degrees C (NaN: it has none, as a power source or the walls),
    `open` the faces left out (FACES' names)."""

    name: str
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    color: tuple[int, int, int]
    temperature: float = float("nan")
    open: tuple[str, ...] = ()


def box_faces(part: Part) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (4F, 3) float32, triangles (2F, 3) int32) of the part's F closed faces, each face's corners its own
    and its triangles wound with the normal pointing out of the box."""
    lo, hi = np.asarray(part.lo, float), np.asarray(part.hi, float)
    vertices, triangles = [], []
    for name, (axis, side) in FACES.items():
        if name in part.open:
            continue
        u, v = (axis + 1) % 3, (axis + 2) % 3  # u x v = the axis: counter-clockwise seen from +axis
        corners = []
        for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
            corner = np.empty(3)
            corner[axis] = hi[axis] if side else lo[axis]
            corner[u] = hi[u] if a else lo[u]
            corner[v] = hi[v] if b else lo[v]
            corners.append(corner)
        k = 4 * len(vertices)
        quad = [(k, k + 1, k + 2), (k, k + 2, k + 3)] if side else [(k, k + 2, k + 1), (k, k + 3, k + 2)]
        vertices.append(corners)
        triangles += quad
    if not vertices:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
    return np.asarray(vertices, np.float32).reshape(-1, 3), np.asarray(triangles, np.int32)


def parts_surface(parts: list[Part]) -> Surface:
    """All `parts` as one triangle mesh: vertex data `part` (the part's index in `parts`) and `temperature`, and
    each corner's colour the part's."""
    vertices, triangles, index, temperature, colors = [], [], [], [], []
    offset = 0
    for k, part in enumerate(parts):
        v, t = box_faces(part)
        vertices.append(v)
        triangles.append(t + offset)
        offset += len(v)
        index.append(np.full(len(v), k, np.int32))
        temperature.append(np.full(len(v), part.temperature, np.float32))
        colors.append(np.tile(np.asarray(part.color, np.uint8), (len(v), 1)))
    if not parts:
        return Surface(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), {}, np.zeros((0, 3), np.uint8))
    data = {"part": np.concatenate(index), "temperature": np.concatenate(temperature)}
    return Surface(np.concatenate(vertices), np.concatenate(triangles), data, np.concatenate(colors))


def parts_comment(parts: list[Part]) -> str:
    """The parts' numbers and names as one line of text (a PLY comment): `parts 0 walls 1 plate_0`."""
    return "parts " + " ".join(f"{k} {p.name}" for k, p in enumerate(parts))
