"""Render a sandbox surface cache frame in Blender, headless, with temperature as a colour ramp.

    blender -b --factory-startup -P examples/blender_render.py -- out/wax.ply.surface.00120.ply out/wax.png [HEIGHT]

The PLY is one frame of `sandbox run SCENE --cache out/wax.ply --cache-surface` (or `sandbox.Cache`): a triangle mesh
with a `temperature` value (degrees C) per vertex. Blender's own PLY importer keeps only colours, so this script
reads the file (with the standard library only), builds the mesh with a `temperature` point attribute, and shades it
through an Attribute node and a colour ramp (blue 20 C, pale yellow 110 C, red 200 C: the sandbox's own scale).
Cycles on the CPU renders it, lit by a sun and a sky, seen by a camera framed on the mesh. Runs inside Blender's
Python (bpy), not the sandbox's.
"""

from __future__ import annotations

import math
import struct
import sys

import bpy
from mathutils import Vector

PLY_TYPES = {"float": "f", "double": "d", "int": "i", "uint": "I", "uchar": "B", "char": "b"}
RAMP = [(0.0, (0.13, 0.32, 0.86)), (0.5, (0.98, 0.95, 0.72)), (1.0, (0.86, 0.12, 0.08))]  # 20, 110, 200 C
T_LO, T_HI = 20.0, 200.0


def read_surface(path: str) -> tuple[list, list, list]:
    """(vertices [(x, y, z)], triangles [(a, b, c)], temperature [t]) of a binary little-endian PLY the sandbox
    wrote (standard library only: Blender's Python may have no NumPy)."""
    with open(path, "rb") as f:
        elements, current, up = [], None, "Y"
        while (line := f.readline().decode().strip()) != "end_header":
            words = line.split()
            if words[:2] == ["comment", "unit"]:
                up = words[-1]
            elif words[0] == "element":
                current = [words[1], int(words[2]), []]
                elements.append(current)
            elif words[0] == "property" and words[1] != "list":
                current[2].append((words[2], PLY_TYPES[words[1]]))
        _, count, props = elements[0]
        row = struct.Struct("<" + "".join(kind for _, kind in props))
        names = [name for name, _ in props]
        x, y, z, t = (names.index(n) for n in ("x", "y", "z", "temperature"))
        rows = list(row.iter_unpack(f.read(count * row.size)))
        faces = elements[1][1]
        triangles = [v[1:] for v in struct.iter_unpack("<Biii", f.read(faces * 13))]
    if up == "Y":  # the sandbox's y is up (a 2D scene's plane is x-y): Blender's z is up
        vertices = [(r[x], -r[z], r[y]) for r in rows]
    else:
        vertices = [(r[x], r[y], r[z]) for r in rows]
    return vertices, triangles, [r[t] for r in rows]


def build(vertices, triangles, temperature):
    mesh = bpy.data.meshes.new("surface")
    mesh.from_pydata(vertices, [], triangles)
    mesh.attributes.new("temperature", "FLOAT", "POINT").data.foreach_set("value", temperature)  # degrees C
    # Cycles reads colour attributes in every Blender 3.x build (Debian's skips float ones): the shader's ramp
    # position, (T - 20) / 180, in all three channels
    fac = mesh.color_attributes.new("temperature_fac", "FLOAT_COLOR", "POINT")
    fac.data.foreach_set("color", [c for t in temperature for c in (*((t - T_LO) / (T_HI - T_LO),) * 3, 1.0)])
    for polygon in mesh.polygons:
        polygon.use_smooth = True
    mesh.update()
    obj = bpy.data.objects.new("surface", mesh)
    bpy.context.scene.collection.objects.link(obj)
    material = bpy.data.materials.new("temperature")
    material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    shader = nodes["Principled BSDF"]
    shader.inputs["Roughness"].default_value = 0.45
    attr = nodes.new("ShaderNodeAttribute")
    attr.attribute_name = "temperature_fac"
    ramp = nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position, ramp.color_ramp.elements[0].color = RAMP[0][0], (*RAMP[0][1], 1)
    ramp.color_ramp.elements[1].position, ramp.color_ramp.elements[1].color = RAMP[2][0], (*RAMP[2][1], 1)
    middle = ramp.color_ramp.elements.new(RAMP[1][0])
    middle.color = (*RAMP[1][1], 1)
    links.new(attr.outputs["Fac"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], shader.inputs["Base Color"])
    obj.data.materials.append(material)
    return obj


def frame_scene(obj, height: int) -> None:
    scene = bpy.context.scene
    corners = [v.co for v in obj.data.vertices]
    lo = Vector([min(c[a] for c in corners) for a in range(3)])
    hi = Vector([max(c[a] for c in corners) for a in range(3)])
    centre, size = (lo + hi) / 2, max((hi - lo).length, 1e-6)
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    camera.location = centre + Vector((0.25, -1.35, 0.4)) * size
    camera.rotation_euler = (centre - camera.location).to_track_quat("-Z", "Y").to_euler()
    camera.data.lens = 40
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(50), math.radians(10), math.radians(30))
    scene.collection.objects.link(sun)
    world = scene.world or bpy.data.worlds.new("world")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.55, 0.6, 0.68, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False  # Debian's Blender is built without OpenImageDenoise
    scene.render.resolution_y = height
    scene.render.resolution_x = int(height * 16 / 9)
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"  # the ramp's colours as the sandbox draws them (not Filmic's)


def main(argv: list[str]) -> None:
    surface, picture = argv[0], argv[1]
    height = int(argv[2]) if len(argv) > 2 else 540
    bpy.ops.wm.read_factory_settings(use_empty=True)
    obj = build(*read_surface(surface))
    frame_scene(obj, height)
    bpy.context.scene.render.filepath = picture
    bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else [])
