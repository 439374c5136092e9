#!/usr/bin/env python3
"""Paths/s of Blender Cycles (CPU) on an rtd scene, for comparison with `rtd render`.

Usage: python3 benches/cycles_compare.py scenes/cornell-box.gltf [WIDTH HEIGHT]
Needs `pip install bpy==5.0.1`. Renders at two sample counts and reports the marginal rate
(paths per second between them), so scene import, BVH build and kernel start-up cancel out.
Settings match rtd's defaults: max 12 bounces, no adaptive sampling, no denoising, 2 threads.
"""
import sys, time
import bpy

scene_path = sys.argv[1]
w, h = (int(sys.argv[2]), int(sys.argv[3])) if len(sys.argv) > 3 else (256, 256)
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=scene_path)
sc = bpy.context.scene
cams = [o for o in sc.objects if o.type == "CAMERA"]
sc.camera = cams[0]
sc.render.engine = "CYCLES"
cy = sc.cycles
cy.device = "CPU"
cy.use_adaptive_sampling = False
cy.use_denoising = False
cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = 12
cy.transparent_max_bounces = 12
sc.render.threads_mode = "FIXED"
sc.render.threads = 2
sc.render.resolution_x, sc.render.resolution_y = w, h
sc.render.resolution_percentage = 100
sc.render.filepath = "/tmp/cycles_compare.png"
times = {}
for spp in (16, 144):
    cy.samples = spp
    t = time.time()
    bpy.ops.render.render(write_still=True)
    times[spp] = time.time() - t
rate = w * h * (144 - 16) / (times[144] - times[16])
print(f"cycles {scene_path} {w}x{h}: 16 spp {times[16]:.2f} s, 144 spp {times[144]:.2f} s, marginal {rate/1e6:.3f} M paths/s")
