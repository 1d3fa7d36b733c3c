"""Open USD files with Blender (bpy, `bpy.ops.wm.usd_import`) and print, as one JSON line, the
world-space vertex positions (metres, Blender's Z-up) of every visible mesh object at the
requested frames, evaluated through the depsgraph.

usage: python usd_blender_frames.py SPEC.json
SPEC: {"files": [{"path": "...", "frames": [0, 2, 4]}, ...]}
Output: {"files": [{"path": ..., "frame_start": ..., "frame_end": ..., "fps": ...,
                    "objects": {name: {"frames": {"0": [[x, y, z], ...], ...}}}}]}
"""
import json
import sys

import bpy


def main():
    spec = json.load(open(sys.argv[1]))
    results = []
    for item in spec["files"]:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.wm.usd_import(filepath=item["path"])
        scene = bpy.context.scene
        objects = {}
        for f in item["frames"]:
            scene.frame_set(f)
            depsgraph = bpy.context.evaluated_depsgraph_get()
            for ob in scene.objects:
                if ob.type != "MESH" or not ob.visible_get():
                    continue
                ev = ob.evaluated_get(depsgraph)
                mesh = ev.to_mesh()
                mw = ev.matrix_world
                pts = [list(mw @ v.co) for v in mesh.vertices]
                ev.to_mesh_clear()
                objects.setdefault(ob.name, {"frames": {}})["frames"][str(f)] = pts
        results.append({
            "path": item["path"],
            "frame_start": scene.frame_start,
            "frame_end": scene.frame_end,
            "fps": scene.render.fps / scene.render.fps_base,
            "objects": objects,
        })
    print(json.dumps({"files": results}))


main()
