"""A triangle surface around a cloud of particles, for the caches that renderers and ParaView open.

splashsurf (the `pysplashsurf` package) evaluates an SPH colour field of the particles on a grid and extracts its
iso-surface by marching cubes, interpolating the particles' values (temperature) onto the vertices. A 2D scene's
particles lie in z = 0: they are extruded into a slab three spacings thick (copies at z = -s, 0, +s), so the surface
is a closed solid that a renderer lights like any other.
"""

from __future__ import annotations

import numpy as np

from ..errors import SandboxError
from ..files.cache_formats import Surface

EXPORT_HINT = "install the export extra: python3 -m pip install -e '.[export]'"


def reconstruct(
    points: np.ndarray,
    values: dict[str, np.ndarray],
    radius: float,
    smoothing: float = 2.0,
    iso: float = 0.6,
    cell: float = 0.5,
    dim: int = 3,
) -> Surface | None:
    """The surface around `points` (N, 3), with `values` (name -> (N,)) interpolated onto its vertices; `radius`:
    the particles' radius (length), `smoothing` and `cell` in radii, `iso` the colour field's level. None when there
    are too few particles for a surface."""
    try:
        import pysplashsurf
    except ImportError as exc:
        raise SandboxError(f"surfaces need pysplashsurf; {EXPORT_HINT}") from exc
    if len(points) < 4:
        return None
    points = np.ascontiguousarray(points, dtype=np.float64)  # splashsurf refuses strided arrays
    if dim == 2:
        layers = [points + np.array([0.0, 0.0, dz]) for dz in (-2 * radius, 0.0, 2 * radius)]
        points = np.concatenate(layers)
        values = {name: np.tile(np.asarray(v, dtype=np.float64), 3) for name, v in values.items()}
    else:
        values = {name: np.ascontiguousarray(v, dtype=np.float64) for name, v in values.items()}
    mesh, _ = pysplashsurf.reconstruction_pipeline(
        points,
        attributes_to_interpolate=values,
        particle_radius=radius,
        smoothing_length=smoothing,
        cube_size=cell,
        iso_surface_threshold=iso,
        multi_threading=True,
    )
    vertices = np.asarray(mesh.mesh.vertices, dtype=np.float32)
    triangles = np.asarray(mesh.mesh.triangles, dtype=np.int64)
    if not len(triangles):
        return None
    data = {name: np.asarray(mesh.point_attributes[name], dtype=np.float32) for name in values}
    return canonical(Surface(vertices, triangles, data))


def canonical(surface: Surface) -> Surface:
    """`surface` in one order whatever order its builder emitted it in (splashsurf's threads may emit the same mesh
    in another order from run to run): vertices sorted by position, each triangle starting at its least vertex (its
    orientation kept), triangles sorted. Two runs that build the same mesh write the same bytes."""
    v = surface.vertices
    order = np.lexsort(v.T[::-1])  # by x, then y, then z
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    tri = rank[surface.triangles]
    turn = (np.arange(3)[None, :] + tri.argmin(axis=1)[:, None]) % 3
    tri = np.take_along_axis(tri, turn, axis=1)
    tri = tri[np.lexsort(tri.T[::-1])]
    return Surface(v[order], tri, {name: values[order] for name, values in surface.vertex_data.items()})


def area_and_volume(surface: Surface) -> tuple[float, float]:
    """The mesh's area (length^2) and enclosed volume (length^3, by the divergence theorem; a closed, outward-
    oriented mesh)."""
    v = surface.vertices.astype(np.float64)
    a, b, c = (v[surface.triangles[:, k]] for k in range(3))
    area = 0.5 * float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
    volume = float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0
    return area, volume
