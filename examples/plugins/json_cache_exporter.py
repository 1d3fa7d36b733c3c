"""A springbake exporter plug-in: the bake as a JSON point cache (`.pointcache.json`), one
array of [x, y, z] per vertex per frame in each mesh's local frame, with the frame rate and
the mesh's placement — a format small tools and web pages read without a glTF loader.
See docs/plugins.md."""

import json

SPRINGBAKE_PLUGIN = {"kind": "exporter", "name": "jsoncache", "extensions": ["json"]}


def export(baked, path):
    meshes = []
    for m in baked["meshes"]:
        meshes.append({
            "name": m["name"],
            "matrix": m["matrix"].tolist(),
            "triangles": m["triangles"].tolist(),
            "frames": [[[round(float(c), 6) for c in p] for p in frame] for frame in m["frames"]],
        })
    document = {
        "fps": baked["fps"],
        "frame_count": baked["frame_count"],
        "up_axis": baked["up_axis"],
        "meters_per_unit": baked["meters_per_unit"],
        "meshes": meshes,
    }
    with open(path, "w", encoding="utf-8") as f:
        json.dump(document, f)
