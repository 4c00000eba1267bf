"""A particle cache as USD (the `usd-core` package): one crate layer per frame, joined by value clips.

    NAME.usd (or .usda/.usdc)   the stage: units (metersPerUnit 0.001), up axis, time codes (one per frame, at the
                                run's frame rate), /World with a Points prim /World/particles (and a Mesh
                                /World/surface where surfaces are cached) whose attributes are declared here and
                                whose values come from the clips; the scene's walls, plates and lid as Mesh prims
                                /World/parts/NAME; the pictures' camera /World/camera
    NAME.00012.usdc             frame 12: the points, widths, velocities and primvars (temp_c, the temperature in
                                degrees C, melt_fraction, phase, material, body, id) at time code 12; the surface
                                mesh and the parts too

A frame is written and closed on its own, so a run of a million particles streams to disk a frame at a time (a
single layer holding every time sample would keep them all in memory until it is saved). USD resolves the clips when
the stage is read (Blender, Houdini, Omniverse, usdview, or `pxr.Usd.Stage.Open`), so `attr.Get(time)` reads frame
`time` from its own file.
"""

from __future__ import annotations

import errno
import math
import re
from pathlib import Path

import numpy as np

from ..errors import SandboxError
from .cache_formats import METERS_PER_UNIT, SURFACE_VELOCITY, CacheFrame, film_name
from .cache_parts import Part, box_faces

USD_HINT = "install the export extra: python3 -m pip install -e '.[export]'"
PRIMVARS = {"temperature": "Float", "melt_fraction": "Float", "phase": "Int", "material": "Int", "body": "Int"}


def pxr():
    """The pxr modules (Usd, UsdGeom, Sdf, Vt, Gf); a SandboxError naming the extra where usd-core is missing."""
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, Vt
    except ImportError as exc:
        raise SandboxError(f"a .usd cache needs usd-core; {USD_HINT}") from exc
    return Usd, UsdGeom, Sdf, Vt, Gf


def write_frame_layer(path: Path, frame: CacheFrame) -> None:
    """Write frame `frame` as the crate layer `path` (its values at time code frame.frame)."""
    Usd, UsdGeom, Sdf, Vt, _ = pxr()
    layer = Sdf.Layer.CreateAnonymous(".usdc")
    stage = Usd.Stage.Open(layer)
    t = Usd.TimeCode(frame.frame)
    points = UsdGeom.Points.Define(stage, "/World/particles")
    points.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(frame.points.astype(np.float32)), t)
    points.GetWidthsAttr().Set(Vt.FloatArray.FromNumpy(frame.widths.astype(np.float32)), t)
    velocity = frame.point_data.get("velocity")
    if velocity is not None:
        points.GetVelocitiesAttr().Set(Vt.Vec3fArray.FromNumpy(velocity.astype(np.float32)), t)
    points.GetIdsAttr().Set(Vt.Int64Array.FromNumpy(frame.point_data["id"].astype(np.int64)), t)
    half = 0.5 * float(frame.widths.max(initial=0.0))
    points.GetExtentAttr().Set(_extent(frame.points, half), t)
    if frame.colors is not None:  # USD's displayColor is linear: the sandbox's sRGB colours, decoded
        colors = Vt.Vec3fArray.FromNumpy(srgb_to_linear(frame.colors).astype(np.float32))
        points.GetDisplayColorPrimvar().Set(colors, t)
    points.GetPrim().CreateAttribute("sandbox:time", Sdf.ValueTypeNames.Double).Set(float(frame.time), t)
    api = UsdGeom.PrimvarsAPI(points.GetPrim())
    for name, kind in PRIMVARS.items():
        if name in frame.point_data:
            values = frame.point_data[name]
            array = (
                Vt.FloatArray.FromNumpy(values.astype(np.float32))
                if kind == "Float"
                else Vt.IntArray.FromNumpy(values.astype(np.int32))
            )
            primvar = api.CreatePrimvar(
                film_name(name), getattr(Sdf.ValueTypeNames, f"{kind}Array"), UsdGeom.Tokens.vertex
            )
            primvar.Set(array, t)
    if frame.surface is not None:
        s = frame.surface
        mesh = UsdGeom.Mesh.Define(stage, "/World/surface")
        mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(s.vertices.astype(np.float32)), t)
        mesh.GetFaceVertexCountsAttr().Set(Vt.IntArray.FromNumpy(np.full(len(s.triangles), 3, np.int32)), t)
        mesh.GetFaceVertexIndicesAttr().Set(Vt.IntArray.FromNumpy(s.triangles.reshape(-1).astype(np.int32)), t)
        mesh.GetExtentAttr().Set(_extent(s.vertices, 0.0), t)
        mesh.GetNormalsAttr().Set(Vt.Vec3fArray.FromNumpy(vertex_normals(s.vertices, s.triangles)), t)
        if s.colors is not None:
            mesh.GetDisplayColorPrimvar().Set(Vt.Vec3fArray.FromNumpy(srgb_to_linear(s.colors).astype(np.float32)), t)
        velocity = s.velocity()
        if velocity is not None:
            mesh.GetVelocitiesAttr().Set(Vt.Vec3fArray.FromNumpy(velocity.astype(np.float32)), t)
        for name, values in s.vertex_data.items():
            if name in SURFACE_VELOCITY:
                continue
            UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar(
                film_name(name), Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex
            ).Set(Vt.FloatArray.FromNumpy(values.astype(np.float32)), t)
    for part in frame.parts:
        vertices, _ = box_faces(part)
        mesh = UsdGeom.Mesh.Define(stage, part_path(part))
        mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(vertices), t)
        mesh.GetExtentAttr().Set(_extent(vertices, 0.0), t)
        color = srgb_to_linear(np.asarray([part.color], np.uint8)).astype(np.float32)
        mesh.GetDisplayColorPrimvar().Set(Vt.Vec3fArray.FromNumpy(color), t)
        temperature = Vt.FloatArray([float(part.temperature)])
        UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar(
            film_name("temperature"), Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.constant
        ).Set(temperature, t)
    _export(layer, path)


def part_path(part: Part) -> str:
    """The prim path of a part of the scene (files/cache_parts.py): /World/parts/NAME."""
    return f"/World/parts/{part.name}"


def _declare_parts(stage, parts: list[Part]) -> None:
    """The parts' Mesh prims on the stage: their topology (each a box, fixed), and the attributes the clips give
    values."""
    _, UsdGeom, Sdf, Vt, _ = pxr()
    UsdGeom.Scope.Define(stage, "/World/parts")
    for part in parts:
        vertices, triangles = box_faces(part)
        mesh = UsdGeom.Mesh.Define(stage, part_path(part))
        mesh.CreatePointsAttr(), mesh.CreateExtentAttr()
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(triangles), 3, np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(triangles.reshape(-1)))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateDoubleSidedAttr(True)
        mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant)
        UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar(
            film_name("temperature"), Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.constant
        )


def _declare_camera(stage, camera) -> None:
    """The pictures' camera as /World/camera: placed at its eye looking at its target, world y up; perspective
    with its vertical field of view, or orthographic over a 2D scene's view. USD's apertures are in tenths of a
    scene length."""
    _, UsdGeom, _, _, Gf = pxr()
    prim = UsdGeom.Camera.Define(stage, "/World/camera")
    right, up, forward = camera.axes()
    rows = [(*right, 0.0), (*up, 0.0), (*(-forward), 0.0), (*camera.eye, 1.0)]  # a camera looks down its -z
    prim.AddTransformOp().Set(Gf.Matrix4d(*[float(v) for row in rows for v in row]))
    if camera.ortho_height:
        prim.CreateProjectionAttr(UsdGeom.Tokens.orthographic)
        prim.CreateVerticalApertureAttr(10.0 * camera.ortho_height)
        prim.CreateHorizontalApertureAttr(10.0 * camera.ortho_height * camera.aspect)
    else:
        vertical = 24.0  # the focal length follows from it and the field of view; only their ratio matters
        prim.CreateVerticalApertureAttr(vertical)
        prim.CreateHorizontalApertureAttr(vertical * camera.aspect)
        prim.CreateFocalLengthAttr(0.5 * vertical / math.tan(math.radians(camera.fov) / 2))
    distance = float(np.linalg.norm(np.asarray(camera.eye) - np.asarray(camera.target)))
    prim.CreateClippingRangeAttr(Gf.Vec2f(0.001 * distance, 100.0 * distance))


def write_stage(
    path: Path, clips: list[tuple[int, str]], fps: float, up: str, surface: bool, parts=(), camera=None
) -> None:
    """Write the stage `path` over the frame layers `clips` ((frame, file name beside it), in order), with the
    scene's `parts` and its `camera` where given."""
    Usd, UsdGeom, Sdf, Vt, Gf = pxr()
    layer = Sdf.Layer.CreateAnonymous(path.suffix if path.suffix in (".usda", ".usdc") else ".usda")
    stage = Usd.Stage.Open(layer)
    UsdGeom.SetStageMetersPerUnit(stage, METERS_PER_UNIT)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up == "Z" else UsdGeom.Tokens.y)
    frames = [f for f, _ in clips] or [0]
    stage.SetStartTimeCode(frames[0])
    stage.SetEndTimeCode(frames[-1])
    stage.SetTimeCodesPerSecond(fps)
    stage.SetFramesPerSecond(fps)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    points = UsdGeom.Points.Define(stage, "/World/particles")
    declared = (points.CreatePointsAttr(), points.CreateWidthsAttr(), points.CreateVelocitiesAttr())
    for attr in (*declared, points.CreateExtentAttr()):
        attr.SetCustomDataByKey("sandbox", "values in the clips")
    points.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)
    points.CreateIdsAttr()
    points.GetPrim().CreateAttribute("sandbox:time", Sdf.ValueTypeNames.Double)  # simulated seconds at each frame
    api = UsdGeom.PrimvarsAPI(points.GetPrim())
    for name, kind in PRIMVARS.items():
        api.CreatePrimvar(film_name(name), getattr(Sdf.ValueTypeNames, f"{kind}Array"), UsdGeom.Tokens.vertex)
    if surface:
        mesh = UsdGeom.Mesh.Define(stage, "/World/surface")
        mesh.CreatePointsAttr(), mesh.CreateFaceVertexCountsAttr(), mesh.CreateFaceVertexIndicesAttr()
        mesh.CreateExtentAttr(), mesh.CreateNormalsAttr(), mesh.CreateVelocitiesAttr()
        mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)  # triangles as they are, not Catmull-Clark
        UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar(
            film_name("temperature"), Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex
        )
    if parts:
        _declare_parts(stage, list(parts))
    if camera is not None:
        _declare_camera(stage, camera)
    del stage  # the clips are authored on the layer alone: composing them here would look for the frame files
    if clips:
        layer.GetPrimAtPath("/World").SetInfo(
            "clips",
            {
                "default": {
                    "assetPaths": Sdf.AssetPathArray([f"./{name}" for _, name in clips]),
                    "primPath": "/World",
                    "active": Vt.Vec2dArray([Gf.Vec2d(f, k) for k, (f, _) in enumerate(clips)]),
                    "times": Vt.Vec2dArray([Gf.Vec2d(f, f) for f, _ in clips]),
                }
            },
        )
    text = layer.ExportToString() if layer.GetFileFormat().formatId == "usda" else None
    if text is not None:
        path.write_text(text)
    else:
        _export(layer, path)


def _export(layer, path: Path) -> None:
    """Save `layer` to `path`; an OSError (as every other writer's) when USD cannot: a full disk, a size limit, a
    folder it may not write to. USD reports those as a Tf.ErrorException whose text names the system's reason."""
    from pxr import Tf

    try:
        ok = layer.Export(str(path))
    except Tf.ErrorException as exc:
        found = re.search(r"writing file: ([^'\n]+)", str(exc))
        raise OSError(errno.EIO, found.group(1) if found else "USD could not write the layer") from None
    if not ok:
        raise OSError(errno.EIO, "USD could not write the layer")


def _extent(points: np.ndarray, pad: float):
    """The box around `points` (N, 3), widened by `pad`, as USD's extent ([min, max])."""
    from pxr import Gf, Vt

    lo = points.min(axis=0) - pad if len(points) else np.zeros(3)
    hi = points.max(axis=0) + pad if len(points) else np.zeros(3)
    return Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))])


def srgb_to_linear(colors: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 sRGB colours as linear floats in [0, 1] (the sRGB transfer function inverted)."""
    c = colors.astype(np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(V, 3) float32 unit normals at the vertices: the sum of the adjacent triangles' area-weighted normals."""
    v = vertices.astype(np.float64)
    a, b, c = (v[triangles[:, k]] for k in range(3))
    face = np.cross(b - a, c - a)  # twice the area, along the normal
    normals = np.zeros_like(v)
    for k in range(3):
        np.add.at(normals, triangles[:, k], face)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return (normals / np.where(length > 0, length, 1.0)).astype(np.float32)
