#!/usr/bin/env python3
"""Blender round trip: a room built in Blender, exported by Blender's own glTF exporter, rendered
by Cycles from the .blend and by rtd from the .glb; the two compared.

Usage: python3 benches/blender_roundtrip.py OUT_DIR [--rtd target/release/rtd] [--spp 256]
       [--size 320x180] [--lights point,spot,sun,emissive,all]
Needs `pip install bpy==5.0.1 OpenEXR` (Blender 5.0 as a module: Cycles and the glTF exporter).

The room: rough dielectric walls and box (Principled BSDF, roughness 0.6-0.8), a rough metal
sphere, a glass sphere, a 16:9 camera, and one lighting variant at a time: a 300 W point light,
a 500 W spot (60 degrees, blend 0.3), a strength-3 sun, or an emissive ceiling panel of strength
10 W/m2-sr-ish (Blender's Emission Strength). The world is black (glTF carries no world).
The exporter runs at its defaults (Lighting Mode "Standard") with lights and cameras ticked,
since Blender leaves both off by default. Cycles renders with rtd's defaults: 12 bounces, no
adaptive sampling, no denoising, no clamping, 2 threads.

Printed for each variant: the image means (rtd / Cycles) and the mean relative difference of
8x8 block means (blocks darker than 1% of the image mean are left out). A JSON file with the
table goes to OUT_DIR/roundtrip.json.
"""
import argparse, json, math, os, subprocess, sys, time

import bpy
import numpy as np


def principled(name, color, rough, metal=0.0, transmission=0.0, emission=None, strength=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Base Color"].default_value = (*color, 1.0)
    b.inputs["Roughness"].default_value = rough
    b.inputs["Metallic"].default_value = metal
    b.inputs["Transmission Weight"].default_value = transmission
    b.inputs["IOR"].default_value = 1.5
    if emission is not None:
        b.inputs["Emission Color"].default_value = (*emission, 1.0)
        b.inputs["Emission Strength"].default_value = strength
    return m


def add(obj, mat):
    obj.data.materials.append(mat)
    return obj


def build(lights):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    sc.world = world
    wall = principled("wall", (0.8, 0.8, 0.75), 0.7)
    red = principled("red", (0.7, 0.15, 0.1), 0.6)
    box = principled("box", (0.3, 0.5, 0.7), 0.8)
    metal = principled("metal", (0.9, 0.6, 0.3), 0.3, metal=1.0)
    glass = principled("glass", (1.0, 1.0, 1.0), 0.0, transmission=1.0)
    # A 6 x 6 m room, 3 m high, open towards the camera (Blender is Z-up).
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 0, 0))
    add(bpy.context.object, wall)
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 3, 3), rotation=(math.pi / 2, 0, 0))
    add(bpy.context.object, wall)
    bpy.ops.mesh.primitive_plane_add(size=6, location=(-3, 0, 3), rotation=(0, math.pi / 2, 0))
    add(bpy.context.object, red)
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 0, 6), rotation=(math.pi, 0, 0))
    add(bpy.context.object, wall)
    bpy.ops.mesh.primitive_cube_add(size=1.2, location=(-1.2, 1.0, 0.6), rotation=(0, 0, 0.4))
    add(bpy.context.object, box)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, location=(0.4, 0.8, 0.6), segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    add(bpy.context.object, metal)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(1.6, -0.2, 0.5), segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    add(bpy.context.object, glass)
    if "point" in lights:
        bpy.ops.object.light_add(type="POINT", location=(0.5, -0.5, 4.0))
        bpy.context.object.data.energy = 300.0
        bpy.context.object.data.shadow_soft_size = 0.0
    if "spot" in lights:
        bpy.ops.object.light_add(type="SPOT", location=(1.5, -2.0, 4.5))
        l = bpy.context.object
        l.data.energy = 500.0
        l.data.spot_size = math.radians(60)
        l.data.spot_blend = 0.3
        l.data.shadow_soft_size = 0.0
        # Aim at the box's side of the room.
        d = np.array((-0.6, 1.0, 0.6)) - np.array(l.location)
        l.rotation_euler = (-d[0:3] * 0).tolist()
        l.rotation_mode = "QUATERNION"
        from mathutils import Vector
        l.rotation_quaternion = Vector(d.tolist()).to_track_quat("-Z", "Y")
    if "sun" in lights:
        bpy.ops.object.light_add(type="SUN", rotation=(math.radians(40), math.radians(-20), math.radians(30)))
        bpy.context.object.data.energy = 3.0
        bpy.context.object.data.angle = 0.0
    if "emissive" in lights:
        panel = principled("panel", (0.0, 0.0, 0.0), 1.0, emission=(1.0, 0.95, 0.85), strength=10.0)
        bpy.ops.mesh.primitive_plane_add(size=1.5, location=(0, 0.5, 5.99), rotation=(math.pi, 0, 0))
        add(bpy.context.object, panel)
    # A 16:9 camera looking into the room.
    bpy.ops.object.camera_add(location=(0.2, -6.5, 2.2), rotation=(math.radians(84), 0, 0))
    sc.camera = bpy.context.object
    sc.camera.data.lens = 24
    return sc


def render_cycles(sc, w, h, spp, path):
    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    cy.samples = spp
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = 12
    cy.transparent_max_bounces = 12
    cy.sample_clamp_direct = cy.sample_clamp_indirect = 0.0
    cy.caustics_reflective = cy.caustics_refractive = True
    cy.blur_glossy = 0.0
    sc.render.threads_mode = "FIXED"
    sc.render.threads = 2
    sc.render.resolution_x, sc.render.resolution_y = w, h
    sc.render.resolution_percentage = 100
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.filepath = path
    t = time.time()
    bpy.ops.render.render(write_still=True)
    return time.time() - t


def read_exr_rgb(path):
    """The beauty (R,G,B) of an EXR, through the OpenEXR package (`pip install OpenEXR`)."""
    import OpenEXR
    channels = OpenEXR.File(path).channels()
    for name in ("RGB", "RGBA"):
        if name in channels:
            return np.asarray(channels[name].pixels, dtype=np.float64)[:, :, :3]
    raise SystemExit(f"{path}: no RGB channels (has {list(channels)})")


def compare(a, b):
    """rtd's image a against Cycles' b: means and the mean relative 8x8 block difference."""
    h, w = (a.shape[0] // 8) * 8, (a.shape[1] // 8) * 8
    la = a[:h, :w].mean(axis=2)
    lb = b[:h, :w].mean(axis=2)
    ba = la.reshape(h // 8, 8, w // 8, 8).mean(axis=(1, 3))
    bb = lb.reshape(h // 8, 8, w // 8, 8).mean(axis=(1, 3))
    keep = bb > 0.01 * lb.mean()
    rel = np.abs(ba[keep] - bb[keep]) / bb[keep]
    return {"rtd_mean": float(la.mean()), "cycles_mean": float(lb.mean()),
            "mean_ratio": float(la.mean() / lb.mean()), "block_rel_diff": float(rel.mean()),
            "blocks": int(keep.sum())}


def store_reference(out, variant, base, w, h, spp):
    """Keeps the .glb and Cycles' numbers for the test that needs no Blender."""
    import shutil
    os.makedirs(out, exist_ok=True)
    shutil.copy(base + ".glb", os.path.join(out, variant + ".glb"))
    img = read_exr_rgb(base + "-cycles.exr")
    hh, ww = (h // 8) * 8, (w // 8) * 8
    lum = img[:hh, :ww].mean(axis=2)
    blocks = lum.reshape(hh // 8, 8, ww // 8, 8).mean(axis=(1, 3))
    ref = {"variant": variant, "size": [w, h], "cycles_spp": spp, "blender": bpy.app.version_string,
           "mean_rgb": [float(x) for x in img.reshape(-1, 3).mean(axis=0)],
           "blocks": [[float(x) for x in row] for row in blocks]}
    with open(os.path.join(out, variant + "-cycles.json"), "w") as f:
        json.dump(ref, f, indent=1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--rtd", default="target/release/rtd")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--lights", default="point,spot,sun,emissive,all")
    ap.add_argument("--store-reference", metavar="DIR",
                    help="also keep each variant's .glb and Cycles' image mean and 8x8 block means "
                         "(mean of R,G,B) in DIR, for tests/blender_roundtrip.rs")
    args = ap.parse_args()
    w, h = map(int, args.size.split("x"))
    os.makedirs(args.out, exist_ok=True)
    table = {}
    for variant in args.lights.split(","):
        lights = {"point", "spot", "sun", "emissive"} if variant == "all" else {variant}
        sc = build(lights)
        base = os.path.abspath(os.path.join(args.out, variant))
        bpy.ops.wm.save_as_mainfile(filepath=base + ".blend")
        bpy.ops.export_scene.gltf(filepath=base + ".glb", export_format="GLB", export_lights=True,
                                  export_cameras=True)
        cycles_s = render_cycles(sc, w, h, args.spp, base + "-cycles.exr")
        t = time.time()
        subprocess.run([args.rtd, "render", base + ".glb", "-o", base + "-rtd.exr", "--spp", str(args.spp),
                        "--width", str(w), "--height", str(h), "-q"], check=True)
        rtd_s = time.time() - t
        row = compare(read_exr_rgb(base + "-rtd.exr"), read_exr_rgb(base + "-cycles.exr"))
        row.update({"cycles_s": cycles_s, "rtd_s": rtd_s})
        table[variant] = row
        if args.store_reference:
            store_reference(args.store_reference, variant, base, w, h, args.spp)
        print(f"{variant:9s} mean rtd/cycles {row['mean_ratio']:.3f}  8x8 blocks {100 * row['block_rel_diff']:.1f}% "
              f"({row['blocks']} blocks)  cycles {cycles_s:.0f} s, rtd {rtd_s:.0f} s", flush=True)
    with open(os.path.join(args.out, "roundtrip.json"), "w") as f:
        json.dump({"spp": args.spp, "size": [w, h], "variants": table}, f, indent=2)


if __name__ == "__main__":
    main()
