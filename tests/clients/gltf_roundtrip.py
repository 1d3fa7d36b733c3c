"""Blender round trip of springbake's glTF caches (morph targets and lattice skin).

Usage: python gltf_roundtrip.py SPEC.json

SPEC is a list of {file, fps, frames, objects: [{name, vertex_count, frames: [[ [x,y,z] per
vertex ] per listed frame], uvs, materials}]}, positions in glTF world coordinates (Y-up).
For each file: import it into an empty scene, and for Blender frame = baked frame + offset
(offset 0 and 1 are both measured) evaluate every visible mesh object and compare its world
vertices with the expected ones (nearest-vertex distance both ways, so Blender's vertex order
does not matter). Blender's importer maps glTF (x, y, z) to (x, -z, y); we map back.
Prints one JSON line last: {files: [{frame_offset, visible_mesh_objects, objects: [...]}]}.
"""

import json
import sys

import bpy
from mathutils import Vector
from mathutils.kdtree import KDTree


def kdtree(points):
    tree = KDTree(len(points))
    for i, p in enumerate(points):
        tree.insert(p, i)
    tree.balance()
    return tree


def evaluated_world(ob):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev = ob.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    mw = ev.matrix_world
    pts = []
    for v in mesh.vertices:
        w = mw @ v.co
        pts.append(Vector((w.x, w.z, -w.y)))  # Blender Z-up back to glTF Y-up
    ev.to_mesh_clear()
    return pts


def two_way_error(got, expected):
    tg = kdtree(got)
    te = kdtree(expected)
    worst = 0.0
    for p in expected:
        worst = max(worst, tg.find(p)[2])
    for p in got:
        worst = max(worst, te.find(p)[2])
    return worst


def find(by_name, exp):
    """The visible mesh object of a glTF node: by node name, else by mesh name (Blender names
    a skinned mesh that has child nodes after its mesh and keeps the node as an empty)."""
    return by_name.get(exp["name"]) or by_name.get(exp.get("mesh_name"))


def check_file(spec):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=spec["file"])
    scene = bpy.context.scene
    visible = [o for o in scene.objects if o.type == "MESH" and o.visible_get()]
    by_name = {o.name: o for o in visible}
    expected = {o["name"]: o for o in spec["objects"]}
    errors = {}
    for offset in (0, 1):
        worst = {}
        for k, f in enumerate(spec["frames"]):
            scene.frame_set(f + offset)
            for name, exp in expected.items():
                ob = find(by_name, exp)
                if ob is None:
                    worst[name] = 1e30
                    continue
                pts = [Vector(p) for p in exp["frames"][k]]
                err = two_way_error(evaluated_world(ob), pts)
                worst[name] = max(worst.get(name, 0.0), err)
        errors[offset] = worst
    offset = min(errors, key=lambda o: max(errors[o].values()))
    objects = []
    for name, exp in expected.items():
        ob = find(by_name, exp)
        entry = {
            "blender_object": ob.name if ob else None,
            "name": name,
            "max_error": errors[offset][name],
            "max_error_other_offset": errors[1 - offset][name],
            "expected_vertex_count": exp["vertex_count"],
        }
        if ob is not None:
            mesh = ob.data
            entry["vertex_count"] = len(mesh.vertices)
            uv_missing = 0
            if exp["uvs"]:
                tree = kdtree([Vector((u, 1.0 - v, 0.0)) for u, v in exp["uvs"]])
                layer = mesh.uv_layers[0] if mesh.uv_layers else None
                if layer is None:
                    uv_missing = len(mesh.loops)
                else:
                    for d in layer.data:
                        if tree.find(Vector((d.uv.x, d.uv.y, 0.0)))[2] > 1e-5:
                            uv_missing += 1
            entry["uv_missing"] = uv_missing
            slots = [s.material.name for s in ob.material_slots if s.material]
            entry["materials"] = slots
            entry["materials_ok"] = all(m in slots for m in exp["materials"])
        objects.append(entry)
    return {
        "file": spec["file"],
        "frame_offset": offset,
        "visible_mesh_objects": len(visible),
        "visible_names": sorted(by_name),
        "armatures": [(o.name, o.parent.name if o.parent else None) for o in scene.objects if o.type == "ARMATURE"],
        "hidden_objects": [o.name for o in scene.objects if not o.visible_get()],
        "objects": objects,
    }


def main():
    with open(sys.argv[1]) as f:
        specs = json.load(f)
    print(json.dumps({"files": [check_file(s) for s in specs]}))


if __name__ == "__main__":
    main()
