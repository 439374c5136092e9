#!/usr/bin/env python3
"""A 4M-triangle scene as Blender exports it, for the memory and load figures of a large mesh.

Usage: python3 benches/blender_big_mesh.py OUT.glb [--smooth] [--levels N]
Needs `pip install bpy==5.0.1`. Suzanne subdivided N times (default 6: 4,030,464 triangles),
a smart UV projection, a floor, a point light and a camera, written by Blender's glTF exporter.
Flat shading (the default) shares no vertex between faces, which gives a 306 MB GLB at level 6;
--smooth shares them (114 MB). Then, for example:
    /usr/bin/time -v rtd render OUT.glb --width 1920 --height 1080 --spp 1 -o x.exr --report r.json
"""
import argparse

import bpy

parser = argparse.ArgumentParser(description="A subdivided Suzanne as Blender exports it, as GLB.")
parser.add_argument("out", help="the GLB file to write")
parser.add_argument("--smooth", action="store_true", help="smooth shading: vertices shared between faces")
parser.add_argument("--levels", type=int, default=6, help="subdivision levels (6: 4,030,464 triangles)")
args = parser.parse_args()
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_monkey_add(size=2)
mesh = bpy.context.active_object
if args.smooth:
    bpy.ops.object.shade_smooth()
else:
    bpy.ops.object.shade_flat()
subsurf = mesh.modifiers.new("subdivision", "SUBSURF")
subsurf.levels = subsurf.render_levels = args.levels
bpy.ops.object.modifier_apply(modifier="subdivision")
bpy.ops.object.mode_set(mode="EDIT")
bpy.ops.uv.smart_project()
bpy.ops.object.mode_set(mode="OBJECT")
bpy.ops.mesh.primitive_plane_add(size=20, location=(0, 0, -1.2))
bpy.ops.object.light_add(type="POINT", location=(2, -2, 4))
bpy.context.active_object.data.energy = 800
bpy.ops.object.camera_add(location=(0, -6, 1.5), rotation=(1.35, 0, 0))
bpy.context.scene.camera = bpy.context.active_object
mesh.data.calc_loop_triangles()
print(f"{len(mesh.data.loop_triangles)} triangles in the subdivided mesh, 2 in the floor")
bpy.ops.export_scene.gltf(filepath=args.out, export_format="GLB", export_lights=True, export_cameras=True)
