"""One frame of a particle cache, and how it is written as PLY and as VTK XML PolyData (.vtp, with a .pvd collection).

A `CacheFrame` is what every format carries: the particles' positions (always 3 components: a 2D scene has z = 0)
and their point data (velocity, temperature in degrees C (`temp_c` in USD and PLY: FILM_NAMES), melt fraction,
phase, material, body, id), optionally the live springs as pairs of row indices, and optionally a triangle surface
with its own vertex data; the scene's walls, plates and lid, and its camera. Lengths are in the
scene's unit (one particle spacing = 1 mm: `METERS_PER_UNIT`), times in simulated seconds.

Both writers are plain NumPy: PLY is a text header and one binary table per element; VTP is XML whose arrays follow
as raw little-endian blocks in one appended section (`format="appended"`, `encoding="raw"`, UInt64 block sizes), the
form ParaView and VTK's own XML readers read fastest. Neither needs VTK or plyfile to write; the tests read the
files back with those independent readers.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from xml.sax.saxutils import quoteattr

import numpy as np

METERS_PER_UNIT = 0.001  # one particle spacing is 1 mm (README, "Units")
PHASES = ("solid", "liquid", "gas")  # the `phase` codes 0, 1, 2
# Names renderers reserve, as the formats Blender and Houdini read write them: Cycles takes an attribute named
# `temperature` for the smoke simulation's and shades it flat, so USD and PLY carry the temperature as `temp_c`; VTK
# (ParaView, which reserves no name) keeps `temperature`.
FILM_NAMES = {"temperature": "temp_c"}
COLOR_COLUMNS = ("red", "green", "blue")  # a colour's bytes as PLY columns (MeshLab, Blender and Houdini read them)
SURFACE_VELOCITY = ("vx", "vy", "vz")  # a surface's velocity as vertex data (PLY's names; USD and VTK take a vector)


def film_name(name: str) -> str:
    """The attribute name a USD or PLY cache gives the point data `name`."""
    return FILM_NAMES.get(name, name)


def color_columns(colors: np.ndarray) -> dict[str, np.ndarray]:
    """(N, 3) uint8 colours as the PLY columns red, green, blue."""
    return {c: colors[:, k] for k, c in enumerate(COLOR_COLUMNS)}


@dataclass
class Surface:
    """A triangle mesh: `vertices` (V, 3) float, `triangles` (T, 3) int indices, `vertex_data` name -> (V,) array,
    `colors` (V, 3) uint8 sRGB or None."""

    vertices: np.ndarray
    triangles: np.ndarray
    vertex_data: dict[str, np.ndarray] = field(default_factory=dict)
    colors: np.ndarray | None = None

    def velocity(self) -> np.ndarray | None:
        """(V, 3) the velocity at the vertices (their SURFACE_VELOCITY data), or None where the surface has none."""
        if SURFACE_VELOCITY[0] not in self.vertex_data:
            return None
        return np.stack([self.vertex_data[k] for k in SURFACE_VELOCITY], axis=1)


@dataclass
class CacheFrame:
    """One cached frame: `frame` its number (frames done), `time` simulated seconds, `points` (N, 3) positions,
    `point_data` name -> (N,) or (N, 3) arrays (velocity in length per simulated second), `widths` (N,) particle
    diameters, `bonds` (M, 2) row indices of the springs' ends (or None), `surface` (or None), `up` the scene's up
    axis ("Y" or "Z"), `frame_seconds` the simulated seconds one frame spans (0: not known), `parts` the scene's
    walls, plates and lid (files/cache_parts.py), `camera` the pictures' camera (render/camera.py's Camera)."""

    frame: int
    time: float
    points: np.ndarray
    point_data: dict[str, np.ndarray]
    widths: np.ndarray
    bonds: np.ndarray | None = None
    surface: Surface | None = None
    up: str = "Y"
    frame_seconds: float = 0.0
    velocity_note: str = ""  # how the velocity is written (a PLY comment)
    colors: np.ndarray | None = None  # (N, 3) uint8 sRGB: the sandbox's own colour of each particle
    parts: list = field(default_factory=list)
    camera: object | None = None


# ---------------------------------------------------------------------------------------------------------- PLY
_PLY_TYPES = {"f4": "float", "f8": "double", "i4": "int", "u4": "uint", "i1": "char", "u1": "uchar", "i8": "int"}


def _ply_column(array: np.ndarray) -> np.ndarray:
    """`array` as a PLY property column: 64-bit integers narrowed to int (PLY has no 64-bit integer type)."""
    if array.dtype.kind in "iu" and array.dtype.itemsize == 8:
        return array.astype("<i4")
    if array.dtype.kind == "f":
        return array.astype("<f4")
    return array.astype(array.dtype.newbyteorder("<"))


def _ply_table(columns: dict[str, np.ndarray]) -> np.ndarray:
    """A structured array of the named (N,) columns, little-endian."""
    arrays = {name: _ply_column(np.asarray(values)) for name, values in columns.items()}
    n = len(next(iter(arrays.values())))
    table = np.empty(n, dtype=[(name, a.dtype.str) for name, a in arrays.items()])
    for name, values in arrays.items():
        table[name] = values
    return table


def _properties(table: np.ndarray) -> list[str]:
    return [f"property {_PLY_TYPES[table.dtype[p].str[1:]]} {p}" for p in table.dtype.names]


def _ply(frame: CacheFrame, elements: list[tuple[str, int, list[str], bytes]], comments: tuple = ()) -> bytes:
    """A binary PLY: (element name, count, property lines, the element's bytes) in order; `comments` more header
    comments."""
    lines = ["ply", "format binary_little_endian 1.0", f"comment sandbox frame {frame.frame} time {frame.time:.9g} s"]
    lines.append(f"comment unit {METERS_PER_UNIT} m up {frame.up}")
    lines += [f"comment {line}" for line in comments]
    for name, count, properties, _ in elements:
        lines += [f"element {name} {count}", *properties]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode() + b"".join(data for *_, data in elements)


def ply_bytes(frame: CacheFrame) -> bytes:
    """The particles of `frame` as a binary PLY: a `vertex` element (x, y, z, vx, vy, vz, width and every scalar
    point data column) and, where there are springs, an `edge` element (vertex1, vertex2)."""
    columns = {"x": frame.points[:, 0], "y": frame.points[:, 1], "z": frame.points[:, 2]}
    for name, values in frame.point_data.items():
        if values.ndim == 2:
            columns.update({f"{name[0]}{axis}": a for axis, a in zip("xyz", values.T)})
        else:
            columns[film_name(name)] = values
    columns["width"] = frame.widths
    if frame.colors is not None:  # read as the vertex colour by MeshLab, Blender and Houdini
        columns.update(color_columns(frame.colors))
    vertex = _ply_table(columns)
    elements = [("vertex", len(vertex), _properties(vertex), vertex.tobytes())]
    if frame.bonds is not None and len(frame.bonds):
        edge = _ply_table({"vertex1": frame.bonds[:, 0], "vertex2": frame.bonds[:, 1]})
        elements.append(("edge", len(edge), _properties(edge), edge.tobytes()))
    comments = [frame.velocity_note] if frame.velocity_note else []
    comments += [frame.camera.words()] if frame.camera is not None else []
    return _ply(frame, elements, tuple(comments))


def surface_ply_bytes(frame: CacheFrame, mesh: Surface | None = None, comments: tuple = ()) -> bytes:
    """The surface of `frame` (or `mesh`: the parts) as a binary PLY mesh: `vertex` (x, y, z, the vertex data and
    any colours) and `face` (a list of three vertex indices each)."""
    s = mesh if mesh is not None else frame.surface
    data = {film_name(name): values for name, values in s.vertex_data.items()}
    if s.colors is not None:
        data.update(color_columns(s.colors))
    vertex = _ply_table({"x": s.vertices[:, 0], "y": s.vertices[:, 1], "z": s.vertices[:, 2], **data})
    faces = np.empty(len(s.triangles), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    faces["n"], faces["v"] = 3, s.triangles
    return _ply(
        frame,
        [
            ("vertex", len(vertex), _properties(vertex), vertex.tobytes()),
            ("face", len(faces), ["property list uchar int vertex_indices"], faces.tobytes()),
        ],
        comments,
    )


# ---------------------------------------------------------------------------------------------------------- VTK
_VTK_TYPES = {"f4": "Float32", "f8": "Float64", "i4": "Int32", "i8": "Int64", "u1": "UInt8", "i1": "Int8"}


class _Appended:
    """The appended-data section of a VTK XML file: each array as a UInt64 byte count and its raw bytes."""

    def __init__(self) -> None:
        self.blocks: list[bytes] = []
        self.offset = 0

    def add(self, name: str, array: np.ndarray, components: int = 1) -> str:
        data = np.ascontiguousarray(array)
        data = data.astype(data.dtype.newbyteorder("<"))
        raw = data.tobytes()
        header = (
            f'<DataArray type="{_VTK_TYPES[data.dtype.str[1:]]}" Name={quoteattr(name)} '
            f'NumberOfComponents="{components}" format="appended" offset="{self.offset}"/>'
        )
        self.blocks.append(np.uint64(len(raw)).tobytes() + raw)
        self.offset += 8 + len(raw)
        return header


def _cells(appended: _Appended, connectivity: np.ndarray, per_cell: int) -> str:
    offsets = np.arange(1, len(connectivity) // per_cell + 1, dtype="<i8") * per_cell
    return appended.add("connectivity", connectivity.astype("<i8")) + appended.add("offsets", offsets)


def _vtp(points: np.ndarray, point_data: dict, cells: dict[str, np.ndarray | None]) -> bytes:
    """A PolyData file: `points` (N, 3), `point_data` name -> (N,) or (N, C), `cells` "Verts"/"Lines"/"Polys" ->
    flat connectivity (or None)."""
    appended = _Appended()
    arrays = ""
    for name, values in point_data.items():
        values = values.astype("<f4") if values.dtype.kind == "f" else values
        arrays += appended.add(name, values, values.shape[1] if values.ndim == 2 else 1)
    per_cell = {"Verts": 1, "Lines": 2, "Polys": 3}
    counts = {kind: 0 if cells.get(kind) is None else len(cells[kind]) // k for kind, k in per_cell.items()}
    xml = io.StringIO()
    xml.write('<?xml version="1.0"?>\n<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" ')
    xml.write('header_type="UInt64">\n<PolyData>\n')
    xml.write(
        f'<Piece NumberOfPoints="{len(points)}" NumberOfVerts="{counts["Verts"]}" NumberOfLines="{counts["Lines"]}" '
        f'NumberOfStrips="0" NumberOfPolys="{counts["Polys"]}">\n'
    )
    xml.write(f"<PointData>{arrays}</PointData>\n")
    xml.write(f"<Points>{appended.add('Points', points.astype('<f4'), 3)}</Points>\n")
    for kind, k in per_cell.items():
        if cells.get(kind) is not None:
            xml.write(f"<{kind}>{_cells(appended, cells[kind], k)}</{kind}>\n")
    xml.write('</Piece>\n</PolyData>\n<AppendedData encoding="raw">\n_')
    return xml.getvalue().encode() + b"".join(appended.blocks) + b"\n</AppendedData>\n</VTKFile>\n"


def vtp_bytes(frame: CacheFrame, lines: bool = True) -> bytes:
    """The particles of `frame` as VTK XML PolyData: each particle a vertex cell, the point data as arrays (widths
    as `width`), and the springs as line cells where `lines` and the frame has them."""
    data = {**frame.point_data, "width": frame.widths}
    bonds = frame.bonds.reshape(-1) if lines and frame.bonds is not None and len(frame.bonds) else None
    return _vtp(frame.points, data, {"Verts": np.arange(len(frame.points)), "Lines": bonds})


def surface_vtp_bytes(frame: CacheFrame, mesh: Surface | None = None) -> bytes:
    """The surface of `frame` (or `mesh`: the parts) as VTK XML PolyData: triangles as polygon cells, the vertex data
    as point data, any colours as `color` (3 bytes a point: ParaView draws them as they are with Map Scalars off)."""
    s = mesh if mesh is not None else frame.surface
    data = {k: v for k, v in s.vertex_data.items() if k not in SURFACE_VELOCITY}
    velocity = s.velocity()
    if velocity is not None:  # one vector array, as the particles' velocity
        data["velocity"] = velocity
    if s.colors is not None:
        data["color"] = s.colors
    return _vtp(s.vertices, data, {"Polys": s.triangles.reshape(-1)})


def pvd_text(entries: list[tuple[float, int, str]]) -> str:
    """A ParaView collection: (time, part, file name) per dataset; part 0 the particles, 1 the surface, 2 the
    walls, plates and lid."""
    rows = "".join(
        f'<DataSet timestep="{t:.9g}" group="" part="{part}" file={quoteattr(name)}/>\n' for t, part, name in entries
    )
    return (
        '<?xml version="1.0"?>\n<VTKFile type="Collection" version="1.0" byte_order="LittleEndian">\n'
        f"<Collection>\n{rows}</Collection>\n</VTKFile>\n"
    )
