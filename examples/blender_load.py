"""Load a sandbox cache into Blender as an animation, with the sandbox's colours, and optionally render a frame.

    blender -b --factory-startup -P examples/blender_load.py -- out/wax.ply [options]    # Blender 3.x to 5.x
    python examples/blender_load.py out/wax.usd [options]                                  # PyPI's bpy

    --render PICTURE.png   render a frame (Cycles on the CPU) to PICTURE.png
    --frame N              the frame to render (default: the last cached)
    --height H             the picture's height in pixels (default 540; its width from the run's aspect)
    --look lit|flat        lit: a principled surface in the sandbox's colours under a sun and sky (default);
                           flat: each particle in its colour exactly as the sandbox draws it (emission, no light)
    --save FILE.blend      save the loaded scene

A PLY cache (`sandbox run SCENE --cache out/wax.ply`) is read by this script itself, with the standard library only
(Blender's own PLY importer keeps neither the sandbox's attributes nor a sequence): each cached frame becomes three
objects, the particles (a point cloud, each point its particle's width and colour), the surface where it was cached,
and the scene's walls, plates and lid, shown at their frame and hidden at the next cached one; the frame numbers
are the run's, at its frame rate; the run's camera comes from the particle files' header. A USD stage is imported
with Blender's own importer (Blender's official builds and PyPI's bpy; Debian's Blender is built without USD), and
given the same material. Every object shades its `Col` (PLY) or `displayColor` (USD) attribute, the sandbox's sRGB
colours made linear; `temp_c` (degrees C) is there too for your own materials.
"""

from __future__ import annotations

import argparse
import math
import re
import struct
import sys
from pathlib import Path

import bpy
from mathutils import Vector

PLY_TYPES = {"float": "f", "double": "d", "int": "i", "uint": "I", "uchar": "B", "char": "b"}
KINDS = ("particles", "surface", "parts")  # a frame's files: NAME.NNNNN.ply, NAME.surface.NNNNN.ply, ...
COLOR = "Col"


def srgb_to_linear(byte: int) -> float:
    """One sRGB byte as a linear value in [0, 1] (what Blender's float colours hold)."""
    c = byte / 255.0
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def read_ply(path: Path) -> dict:
    """A binary little-endian PLY the sandbox wrote: {"comments": [...], "vertex": {name: [values]}, "faces":
    [(a, b, c)]}."""
    with open(path, "rb") as f:
        comments, elements = [], []
        while (line := f.readline().decode().strip()) != "end_header":
            words = line.split()
            if words[0] == "comment":
                comments.append(line[len("comment ") :])
            elif words[0] == "element":
                elements.append([words[1], int(words[2]), []])
            elif words[0] == "property" and words[1] != "list":
                elements[-1][2].append((words[2], PLY_TYPES[words[1]]))
        out = {"comments": comments, "vertex": {}, "faces": []}
        for name, count, props in elements:
            if name == "face":
                out["faces"] = [v[1:] for v in struct.iter_unpack("<Biii", f.read(count * 13))]
                continue
            row = struct.Struct("<" + "".join(kind for _, kind in props))
            rows = list(row.iter_unpack(f.read(count * row.size)))
            if name == "vertex":
                out["vertex"] = {p: [r[k] for r in rows] for k, (p, _) in enumerate(props)}
    return out


def to_blender(x: float, y: float, z: float, up: str) -> tuple[float, float, float]:
    """A sandbox point in Blender's axes (z up): a y-up scene's (x, y, z) is Blender's (x, -z, y)."""
    return (x, -z, y) if up == "Y" else (x, y, z)


def sequence(cache: Path) -> dict[int, dict[str, Path]]:
    """The frames of the PLY cache named `cache`: frame number -> {kind: file}."""
    pattern = re.compile(rf"{re.escape(cache.name)}(\.surface|\.parts)?\.(\d{{5,}})\.ply")
    frames: dict[int, dict[str, Path]] = {}
    for path in cache.parent.iterdir():
        found = pattern.fullmatch(path.name)
        if found:
            kind = {None: "particles", ".surface": "surface", ".parts": "parts"}[found.group(1)]
            frames.setdefault(int(found.group(2)), {})[kind] = path
    if not frames:
        sys.exit(f"error: {cache}: no cached frames beside it (expected {cache.name}.00000.ply, ...)")
    return dict(sorted(frames.items()))


def material(look: str, attribute: str) -> bpy.types.Material:
    """The sandbox's material: the colour attribute `attribute` as a principled surface's base colour (lit) or as
    emission at strength 1 (flat: the colour itself in the picture)."""
    mat = bpy.data.materials.new(f"sandbox {look} {attribute}")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for node in list(nodes):
        nodes.remove(node)
    color = nodes.new("ShaderNodeAttribute")
    color.attribute_name = attribute
    out = nodes.new("ShaderNodeOutputMaterial")
    if look == "flat":
        shader = nodes.new("ShaderNodeEmission")
        shader.inputs["Strength"].default_value = 1.0
        links.new(color.outputs["Color"], shader.inputs["Color"])
        links.new(shader.outputs["Emission"], out.inputs["Surface"])
    else:
        shader = nodes.new("ShaderNodeBsdfPrincipled")
        shader.inputs["Roughness"].default_value = 0.45
        links.new(color.outputs["Color"], shader.inputs["Base Color"])
        links.new(shader.outputs["BSDF"], out.inputs["Surface"])
    return mat


def points_modifier(obj, mat) -> None:
    """Geometry nodes that draw the mesh's vertices as a point cloud, each point its `radius`, in `mat`."""
    group = bpy.data.node_groups.new("sandbox points", "GeometryNodeTree")
    if hasattr(group, "interface"):  # Blender 4 and later
        group.interface.new_socket(name="Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        group.interface.new_socket(name="Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    else:
        group.inputs.new("NodeSocketGeometry", "Geometry")
        group.outputs.new("NodeSocketGeometry", "Geometry")
    nodes, links = group.nodes, group.links
    given, result = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    to_points = nodes.new("GeometryNodeMeshToPoints")
    radius = nodes.new("GeometryNodeInputNamedAttribute")
    radius.data_type = "FLOAT"
    radius.inputs["Name"].default_value = "radius"
    paint = nodes.new("GeometryNodeSetMaterial")
    paint.inputs["Material"].default_value = mat
    links.new(given.outputs[0], to_points.inputs["Mesh"])
    links.new(radius.outputs["Attribute"], to_points.inputs["Radius"])
    links.new(to_points.outputs["Points"], paint.inputs["Geometry"])
    links.new(paint.outputs["Geometry"], result.inputs[0])
    obj.modifiers.new("sandbox points", "NODES").node_group = group


def build(name: str, ply: dict, up: str, kind: str, mat) -> bpy.types.Object:
    """One frame's object of `kind` from its PLY, with its attributes: `Col` (linear colour), `temp_c`, and for the
    particles `radius` (half the width)."""
    v = ply["vertex"]
    mesh = bpy.data.meshes.new(name)
    vertices = [to_blender(*p, up) for p in zip(v["x"], v["y"], v["z"])]
    mesh.from_pydata(vertices, [], ply["faces"] if kind != "particles" else [])
    if "red" in v:
        colors = mesh.attributes.new(COLOR, "FLOAT_COLOR", "POINT")
        rgba = [c for r, g, b in zip(v["red"], v["green"], v["blue"]) for c in (*map(srgb_to_linear, (r, g, b)), 1.0)]
        colors.data.foreach_set("color", rgba)
    if "temp_c" in v:
        mesh.attributes.new("temp_c", "FLOAT", "POINT").data.foreach_set("value", v["temp_c"])
    if kind == "particles":
        mesh.attributes.new("radius", "FLOAT", "POINT").data.foreach_set("value", [w / 2 for w in v["width"]])
    for polygon in mesh.polygons:
        polygon.use_smooth = kind == "surface"
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    if kind == "particles":
        points_modifier(obj, mat)
    else:
        obj.data.materials.append(mat)
    return obj


def show_between(obj, start: int, end: int | None, first: int) -> None:
    """Keyframe `obj` visible from frame `start` until `end` (None: the end), hidden before and after."""
    keys = [(first - 1, True)] if start > first else []  # hidden from the sequence's start
    keys += [(start, False)] + ([(end, True)] if end is not None else [])
    for frame, hidden in keys:
        obj.hide_render = obj.hide_viewport = hidden
        obj.keyframe_insert("hide_render", frame=frame)
        obj.keyframe_insert("hide_viewport", frame=frame)


def camera_from(comments: list[str], up: str):
    """The run's camera from a particle file's `camera ...` comment: (object, aspect), or None."""
    line = next((c for c in comments if c.startswith("camera ")), None)
    if line is None:
        return None
    words = line.split()
    eye = Vector(to_blender(*map(float, words[2:5]), up))
    target = Vector(to_blender(*map(float, words[6:9]), up))
    data = bpy.data.cameras.new("sandbox camera")
    data.sensor_fit = "VERTICAL"
    if words[9] == "ortho_height":
        data.type, data.ortho_scale = "ORTHO", float(words[10])
    else:
        data.angle_y = math.radians(float(words[10]))
    data.clip_start, data.clip_end = 0.001 * (eye - target).length, 100.0 * (eye - target).length
    obj = bpy.data.objects.new("sandbox camera", data)
    obj.location = eye
    obj.rotation_euler = (target - eye).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(obj)
    return obj, float(words[12])


def load_ply(cache: Path, look: str) -> tuple[int, int, float]:
    """Every frame of the PLY cache `cache` into the scene; (first frame, last frame, the camera's aspect)."""
    frames = sequence(cache)
    numbers = list(frames)
    scene = bpy.context.scene
    mat = material(look, COLOR)
    collections = {}
    for kind in KINDS:
        collections[kind] = bpy.data.collections.new(f"sandbox {kind}")
        scene.collection.children.link(collections[kind])
    aspect, up, fps = 16 / 9, "Y", 30.0
    for k, number in enumerate(numbers):
        for kind, path in sorted(frames[number].items()):
            ply = read_ply(path)
            for comment in ply["comments"]:
                if comment.startswith("unit "):
                    up = comment.split()[-1]
                rate = re.search(r"at ([\d.]+) frames a second", comment)
                fps = float(rate.group(1)) if rate else fps
            obj = build(f"{kind} {number:05d}", ply, up, kind, mat)
            collections[kind].objects.link(obj)
            show_between(obj, number, numbers[k + 1] if k + 1 < len(numbers) else None, numbers[0])
            if kind == "particles" and scene.camera is None:
                found = camera_from(ply["comments"], up)
                if found is not None:
                    scene.camera, aspect = found
    scene.frame_start, scene.frame_end = numbers[0], numbers[-1]
    scene.render.fps, scene.render.fps_base = round(fps), round(fps) / fps
    return numbers[0], numbers[-1], aspect


def load_usd(stage: Path, look: str) -> tuple[int, int, float]:
    """The USD stage `stage` through Blender's importer, every object given the sandbox's material; (first frame,
    last frame, aspect)."""
    if not hasattr(bpy.ops.wm, "usd_import") or not bpy.ops.wm.usd_import.poll():
        sys.exit("error: this Blender has no USD importer (Debian's is built without USD): load the PLY cache instead")
    bpy.ops.wm.usd_import(filepath=str(stage))
    scene = bpy.context.scene
    mat = material(look, "displayColor")
    aspect = 16 / 9
    for obj in scene.objects:
        if obj.type == "CAMERA":
            scene.camera = obj
            aspect = obj.data.sensor_width / obj.data.sensor_height
            if obj.data.type == "ORTHO":  # read as whole scene units, not USD's tenths, and not scaled to metres
                obj.data.ortho_scale *= 0.1 * obj.matrix_world.to_scale()[0]
        elif obj.type in ("MESH", "POINTCLOUD"):
            obj.data.materials.clear()
            obj.data.materials.append(mat)
    return scene.frame_start, scene.frame_end, aspect


def light(look: str) -> None:
    """A sun and a sky for the lit look; a black world for the flat one (the colours alone)."""
    scene = bpy.context.scene
    world = scene.world or bpy.data.worlds.new("world")
    scene.world = world
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    if look == "flat":
        background.inputs["Strength"].default_value = 0.0
        return
    background.inputs["Color"].default_value = (0.55, 0.6, 0.68, 1)
    background.inputs["Strength"].default_value = 0.6
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(50), math.radians(10), math.radians(30))
    scene.collection.objects.link(sun)


def render(picture: Path, frame: int, height: int, aspect: float, look: str) -> None:
    """Render `frame` with Cycles on the CPU, colours as the sandbox's (the Standard view transform)."""
    scene = bpy.context.scene
    scene.frame_set(frame)
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 4 if look == "flat" else 16
    scene.cycles.use_denoising = False  # Debian's Blender is built without OpenImageDenoise
    scene.render.resolution_y, scene.render.resolution_x = height, round(height * aspect)
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure, scene.view_settings.gamma = 0.0, 1.0
    scene.render.filepath = str(picture)
    bpy.ops.render.render(write_still=True)


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(prog="blender_load.py", description=__doc__.split("\n")[0])
    parser.add_argument("cache", type=Path, help="out/NAME.ply (the frames beside it) or out/NAME.usd")
    parser.add_argument("--render", type=Path, metavar="PICTURE")
    parser.add_argument("--frame", type=int)
    parser.add_argument("--height", type=int, default=540)
    parser.add_argument("--look", choices=("lit", "flat"), default="lit")
    parser.add_argument("--save", type=Path, metavar="FILE.blend")
    args = parser.parse_args(argv)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if args.cache.suffix.lower() in (".usd", ".usda", ".usdc"):
        first, last, aspect = load_usd(args.cache.resolve(), args.look)
    else:
        first, last, aspect = load_ply(args.cache, args.look)
    light(args.look)
    print(f"loaded {args.cache}: frames {first} to {last}")
    if args.save:
        bpy.ops.wm.save_as_mainfile(filepath=str(args.save.resolve()))
    if args.render:
        render(args.render.resolve(), last if args.frame is None else args.frame, args.height, aspect, args.look)


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:])
