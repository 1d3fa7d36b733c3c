"""Play springbake's PC2/MDD caches on Blender's own OBJ import and compare vertex positions.

Usage: python pointcache_blender.py SPEC.json

SPEC: {"fps": 24, "samples": N, "cases": [{"obj": path, "format": "PC2"|"MDD",
        "frame_start": S, "frames": [...], "files": {object name: cache path}}]}

For every case: factory settings, `bpy.ops.wm.obj_import`, a Mesh Cache modifier with default
axes on each imported object, then at each scene frame f the evaluated mesh (object-local
coordinates, which Blender's OBJ importer keeps in the file's Y-up values and rotates with the
object matrix) is compared with the expected position: the vertex's rest position in Blender's
own vertex order plus displacement(sample, rest) with sample = clamp(f - S, 0, N - 1).
Prints one JSON line last.
"""

import json
import math
import sys

import bpy


def displacement(k, p):
    """Must match `displacement` in exporters/tests/pointcache_blender.rs."""
    x, y, z = p
    return (
        0.01 * k * math.sin(3.0 * x + 2.0 * y),
        0.02 * k * math.cos(2.0 * z - x),
        0.005 * k * (x * z + 1.0),
    )


def main():
    spec = json.load(open(sys.argv[1]))
    samples = spec["samples"]
    results = []
    for case in spec["cases"]:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        scene.render.fps = int(round(spec["fps"]))
        bpy.ops.wm.obj_import(filepath=case["obj"])
        rest = {}
        for ob in bpy.data.objects:
            if ob.type != "MESH":
                continue
            rest[ob.name] = [tuple(v.co) for v in ob.data.vertices]
            md = ob.modifiers.new("cache", "MESH_CACHE")
            md.cache_format = case["format"]
            md.filepath = case["files"][ob.name]
            md.frame_start = case["frame_start"]
            defaults = (md.time_mode, md.forward_axis, md.up_axis, md.frame_scale, md.play_mode)
        out_objects = []
        for name, rest_co in rest.items():
            out_objects.append(
                {
                    "name": name,
                    "verts": len(rest_co),
                    "max_err": 0.0,
                    "max_disp": 0.0,
                    "frames": [],
                }
            )
        for f in case["frames"]:
            scene.frame_set(f)
            depsgraph = bpy.context.evaluated_depsgraph_get()
            sample = min(max(f - case["frame_start"], 0), samples - 1)
            for entry in out_objects:
                ob = bpy.data.objects[entry["name"]]
                ob_eval = ob.evaluated_get(depsgraph)
                mesh = ob_eval.to_mesh()
                got = [tuple(v.co) for v in mesh.vertices]
                ob_eval.to_mesh_clear()
                rest_co = rest[entry["name"]]
                err = 0.0
                disp = 0.0
                for g, r in zip(got, rest_co):
                    d = displacement(sample, r)
                    want = (r[0] + d[0], r[1] + d[1], r[2] + d[2])
                    err = max(err, max(abs(g[i] - want[i]) for i in range(3)))
                    disp = max(disp, max(abs(g[i] - r[i]) for i in range(3)))
                if len(got) != len(rest_co):
                    err = 1e30
                entry["max_err"] = max(entry["max_err"], err)
                entry["max_disp"] = max(entry["max_disp"], disp)
                entry["frames"].append({"frame": f, "sample": sample, "err": err})
        results.append(
            {
                "obj": case["obj"],
                "format": case["format"],
                "frame_start": case["frame_start"],
                "modifier_defaults": list(map(str, defaults)),
                "objects": out_objects,
            }
        )
    print(json.dumps({"cases": results}))


main()
