"""Plays PC2 caches baked from a glTF on Blender's own import of that glTF, and compares them
with Blender's import of the same bake written as glTF morph targets.

Usage: python pointcache_gltf_blender.py SOURCE.glb BAKED.glb PC2_PREFIX FRAMES
PC2_PREFIX_<object>.pc2 is the cache of each imported object (springbake names per-mesh caches
after the glTF node). For every scene frame in 1..FRAMES: the Mesh Cache modifier (default
axes, frame_start 1) on the source's objects against the baked glTF's evaluated objects (the
best of frame offsets -1, 0, 1, since importers may start an action at frame 0 or 1). Prints one
JSON line: the worst distance per object.
"""

import json
import os
import sys

import bpy
import numpy as np

from bpy_points import evaluated_world

source, baked, prefix, frames = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])


def positions(path, with_cache):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    scene = bpy.context.scene
    objects = {o.name: o for o in scene.objects if o.type == "MESH" and o.visible_get()}
    if with_cache:
        for name, ob in objects.items():
            mod = ob.modifiers.new("cache", "MESH_CACHE")
            mod.cache_format = "PC2"
            mod.filepath = f"{prefix}_{name}.pc2"
            mod.frame_start = 1
    out = {}
    for f in range(0, frames + 2):
        scene.frame_set(f)
        out[f] = {name: evaluated_world(ob) for name, ob in objects.items()}
    return out


cached = positions(source, True)
reference = positions(baked, False)
worst = {}
for name in cached[1]:
    best = None
    for offset in (-1, 0, 1):
        err = 0.0
        for f in range(1, frames + 1):
            a, b = cached[f][name], reference[f + offset].get(name)
            if b is None or a.shape != b.shape:
                err = float("inf")
                break
            err = max(err, float(np.abs(a - b).max()))
        best = err if best is None else min(best, err)
    worst[name] = best
print(json.dumps({"worst": worst, "objects": sorted(cached[1])}))
