"""Blender's import of a skinned glTF source against its import of springbake's bake of it
(issue 19 item 4).

Usage: skinned_roundtrip.py SOURCE.glb BAKED.glb
At the first frame, the baked mesh must sit where the source renders (skin and shape keys
applied). Prints one JSON line: vertex counts, the largest distance at the first frame, the
baked file's armatures and skinned objects, and the lowest point of the baked mesh at the first
and last keys.
"""
import json
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(__file__))
from bpy_points import evaluated_world  # noqa: E402

source, baked = sys.argv[1], sys.argv[2]


def load(path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    return meshes


report = {}
src = load(source)
bpy.context.scene.frame_set(0)
a = evaluated_world(src[0])
report["source_meshes"] = len(src)
report["source_vertices"] = len(a)
report["source_lowest"] = float(a[:, 2].min())
report["source_highest"] = float(a[:, 2].max())

out = load(baked)
report["baked_meshes"] = len(out)
report["baked_armatures"] = sum(1 for o in bpy.context.scene.objects if o.type == "ARMATURE")
report["baked_armature_modifiers"] = sum(
    1 for o in out for m in o.modifiers if m.type == "ARMATURE")
bpy.context.scene.frame_set(0)
b = evaluated_world(out[0])
report["baked_vertices"] = len(b)
if len(a) == len(b):
    report["max_distance_first_frame"] = float(((a - b) ** 2).sum(axis=1).max() ** 0.5)
report["baked_lowest_first"] = float(b[:, 2].min())
action_end = max(int(bpy.context.scene.frame_end), 1)
lows = []
for f in range(0, action_end + 1):
    bpy.context.scene.frame_set(f)
    lows.append(float(evaluated_world(out[0])[:, 2].min()))
report["baked_lowest_ever"] = min(lows)
print(json.dumps(report))
