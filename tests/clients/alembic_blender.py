"""Imports a baked Alembic archive in Blender (bpy.ops.wm.alembic_import) and compares it,
frame by frame, with Blender's import of the same bake in another format (a glTF morph cache
or a USD stage).

Usage: python alembic_blender.py BAKED.abc REFERENCE.(glb|usda) FRAMES
Objects are matched by name, vertices by their nearest neighbour at the first frame (the
importers number and split vertices differently). Reference frames are tried at offsets -1, 0
and 1 (an importer may start an action at frame 0 or 1). Prints one JSON line: per object the
worst distance, the vertex counts, whether the faces face outward, the UV layers, and the
lowest point of every frame of the Alembic import; the scene's frame range.
"""

import json
import sys

import bpy
import numpy as np

from bpy_points import evaluated_world

abc_path, reference_path, frames = sys.argv[1], sys.argv[2], int(sys.argv[3])


def load(path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if path.endswith(".abc"):
        bpy.ops.wm.alembic_import(filepath=path)
    elif path.endswith((".usda", ".usdc", ".usd")):
        bpy.ops.wm.usd_import(filepath=path)
    else:
        bpy.ops.import_scene.gltf(filepath=path)
    scene = bpy.context.scene
    objects = {o.name: o for o in scene.objects if o.type == "MESH"}
    out = {}
    for f in range(0, frames + 2):
        scene.frame_set(f)
        out[f] = {name: evaluated_world(ob) for name, ob in objects.items()}
    info = {}
    for name, ob in objects.items():
        scene.frame_set(1)
        ev = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = ev.to_mesh()
        m = ob.matrix_world
        centre = sum((m @ v.co for v in mesh.vertices), m.translation * 0) / len(mesh.vertices)
        outward = sum(
            (m.to_3x3() @ p.normal).dot((m @ p.center) - centre) > 0 for p in mesh.polygons
        ) / max(len(mesh.polygons), 1)
        info[name] = {
            "vertices": len(mesh.vertices),
            "outward": outward,
            "uv_layers": list(mesh.uv_layers.keys()),
        }
        ev.to_mesh_clear()
    return out, info, (scene.frame_start, scene.frame_end)


abc, abc_info, frame_range = load(abc_path)
reference, reference_info, _ = load(reference_path)
report = {"frame_range": frame_range, "objects": {}}
for name, first in abc[1].items():
    ref_name = name if name in reference[1] else None
    entry = dict(abc_info[name])
    entry["lowest"] = [float(abc[f][name][:, 2].min()) for f in range(0, frames + 2)]
    if ref_name is not None:
        entry["reference_vertices"] = reference_info[ref_name]["vertices"]
        best = None
        for offset in (-1, 0, 1):
            if not 0 <= 1 + offset <= frames + 1:
                continue
            ref0 = reference[1 + offset][ref_name]
            d = ((first[:, None, :] - ref0[None, :, :]) ** 2).sum(axis=2)
            match = d.argmin(axis=1)
            err = 0.0
            for f in range(1, frames + 1):
                if not 0 <= f + offset <= frames + 1:
                    continue
                a, b = abc[f][name], reference[f + offset][ref_name][match]
                err = max(err, float(np.abs(a - b).max()))
            best = err if best is None else min(best, err)
        entry["worst"] = best
    report["objects"][name] = entry
print(json.dumps(report))
