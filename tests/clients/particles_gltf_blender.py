"""Blender imports a glTF bake with particles (issue 20: "in glTF as ... small meshes with
animated transforms"): per emitter node, how many particle objects hang under it, and for the
named particles their world position and scale at the given frames. Prints one JSON line.

Usage: blender-python particles_gltf_blender.py GLB EMITTER,... PARTICLE@F1/F2/...,...
"""
import json
import sys

import bpy

path, emitters, particles = sys.argv[-3:]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=path)
scene = bpy.context.scene
out = {"children": {}, "particles": {}}
for name in emitters.split(","):
    out["children"][name] = len(bpy.data.objects[name].children)
for item in particles.split(","):
    name, frames = item.split("@")
    rows = []
    for f in frames.split("/"):
        scene.frame_set(int(f))
        world = bpy.data.objects[name].matrix_world
        rows.append(list(world.translation) + [world.to_scale()[0]])
    out["particles"][name] = rows
print(json.dumps(out))
