"""Open a baked glTF in Blender and report what is in it (the bowling example's check).

Usage: python bowling_blender.py FILE.glb [FROM]

Imports FILE into an empty scene, steps through every animated frame and prints one JSON line
last: {mesh_objects: n, names: [...], frame_start, frame_end (from the imported actions),
objects: {name: {vertices, max_move: largest displacement of a vertex from the first animated
frame, max_distance_change: largest change of a distance between two vertices from the first
frame (0 for a rigid motion), max_distance_change_from: the same over the frames from FROM on
(default: the first)}}}, Blender world units.
"""

import json
import sys

import bpy


def world_vertices(ob):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev = ob.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    pts = [ev.matrix_world @ v.co for v in mesh.vertices]
    ev.to_mesh_clear()
    return pts


def main():
    path = sys.argv[1]
    since = int(sys.argv[2]) if len(sys.argv) > 2 else None
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    scene = bpy.context.scene
    meshes = sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name)
    ranges = [a.frame_range for a in bpy.data.actions]
    if not ranges:
        print(json.dumps({"error": "no animation imported"}))
        return
    start = int(round(min(r[0] for r in ranges)))
    end = int(round(max(r[1] for r in ranges)))
    scene.frame_set(start)
    first = {o.name: world_vertices(o) for o in meshes}
    objects = {
        o.name: {
            "vertices": len(first[o.name]),
            "max_move": 0.0,
            "max_distance_change": 0.0,
            "max_distance_change_from": 0.0,
        }
        for o in meshes
    }
    for frame in range(start, end + 1):
        scene.frame_set(frame)
        for o in meshes:
            a, b = first[o.name], world_vertices(o)
            n = len(a)
            # A rigid motion keeps every distance between vertices; a deformation changes some.
            pairs = [(i, (i + 1) % n) for i in range(n)] + [(i, (i + n // 2) % n) for i in range(n)]
            rec = objects[o.name]
            rec["max_move"] = max(rec["max_move"], max((p - q).length for p, q in zip(a, b)))
            change = max(abs((a[i] - a[j]).length - (b[i] - b[j]).length) for i, j in pairs)
            rec["max_distance_change"] = max(rec["max_distance_change"], change)
            if frame >= (start if since is None else since):
                rec["max_distance_change_from"] = max(rec["max_distance_change_from"], change)
    print(json.dumps({
        "mesh_objects": len(meshes),
        "names": [o.name for o in meshes],
        "frame_start": start,
        "frame_end": end,
        "objects": objects,
    }))


main()
