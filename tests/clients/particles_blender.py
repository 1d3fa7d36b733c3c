"""Imports a USD stage with springbake's particle effects in Blender and counts each point
cloud's points over time.

Usage: python particles_blender.py STAGE.usda FRAME...
Prints one JSON line: {object name: [points at each FRAME]}, and per object its type.
"""

import json
import sys

import bpy

path, frames = sys.argv[1], [int(f) for f in sys.argv[2:]]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=path)
scene = bpy.context.scene
clouds = [o for o in scene.objects if o.type == "POINTCLOUD"]
counts = {o.name: [] for o in clouds}
lowest = {o.name: [] for o in clouds}
for f in frames:
    scene.frame_set(f)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for o in clouds:
        data = o.evaluated_get(depsgraph).data
        counts[o.name].append(len(data.points))
        zs = [(o.matrix_world @ p.co).z for p in data.points]
        lowest[o.name].append(min(zs) if zs else None)
print(json.dumps({"counts": counts, "lowest": lowest, "types": sorted({o.type for o in scene.objects})}))
