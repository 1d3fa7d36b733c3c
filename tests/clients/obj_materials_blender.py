"""OBJ materials through a bake, seen by Blender.

Usage:
  python obj_materials_blender.py make FOLDER   writes FOLDER/props.obj (+ .mtl + texture) with
                                                Blender's OBJ exporter, and props.glb with its
                                                glTF exporter: a textured "Brick" cube and a
                                                plain "Blue" sphere
  python obj_materials_blender.py look FILE     imports FILE (.obj, .glb, .usda or .usdz) and prints what
                                                Blender sees: visible mesh objects, each
                                                material's base colour (when not textured) and
                                                whether it is textured, UV layers per object
Prints one JSON line last.
"""

import json
import os
import sys

import bpy


def make(folder):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    image = bpy.data.images.new("bricks", 16, 16)
    image.pixels = [v for i in range(256) for v in ((0.9, 0.3, 0.2, 1.0) if (i // 4) % 2 else (0.5, 0.1, 0.05, 1.0))]
    image.filepath_raw = os.path.join(folder, "bricks.png")
    image.file_format = "PNG"
    image.save()
    bpy.ops.mesh.primitive_cube_add(size=0.4, location=(0, 0, 1.0))
    cube = bpy.context.object
    cube.name = "Crate"
    brick = bpy.data.materials.new("Brick")
    brick.use_nodes = True
    nodes = brick.node_tree.nodes
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    brick.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    cube.data.materials.append(brick)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.2, location=(1.0, 0, 1.0))
    ball = bpy.context.object
    ball.name = "Ball"
    blue = bpy.data.materials.new("Blue")
    blue.use_nodes = True
    bsdf = next(n for n in blue.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (0.1, 0.3, 0.9, 1.0)
    ball.data.materials.append(blue)
    bpy.ops.wm.obj_export(
        filepath=os.path.join(folder, "props.obj"),
        export_materials=True,
        path_mode="RELATIVE",
    )
    bpy.ops.export_scene.gltf(filepath=os.path.join(folder, "props.glb"))
    return {"made": sorted(os.listdir(folder))}


def look(path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if path.endswith(".obj"):
        bpy.ops.wm.obj_import(filepath=path)
    elif path.endswith((".usda", ".usdc", ".usd", ".usdz")):
        bpy.ops.wm.usd_import(filepath=path)
    else:
        bpy.ops.import_scene.gltf(filepath=path)
    visible = [o for o in bpy.context.scene.objects if o.type == "MESH" and o.visible_get()]
    materials = {}
    for o in visible:
        for slot in o.material_slots:
            m = slot.material
            if m is None or not m.use_nodes:
                continue
            bsdf = next((n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
            # Textured: an image node whose file loaded (a missing file has no pixels).
            textured = any(
                n.type == "TEX_IMAGE" and n.image and n.image.size[0] > 0
                for n in m.node_tree.nodes
            )
            base = bsdf.inputs["Base Color"] if bsdf else None
            colour = list(base.default_value) if base is not None and not base.is_linked else None
            materials[m.name] = {"colour": colour, "textured": textured}
    return {
        "objects": len(visible),
        "materials": materials,
        "uv_layers": sorted(len(o.data.uv_layers) for o in visible),
    }


if __name__ == "__main__":
    mode, target = sys.argv[1], sys.argv[2]
    print(json.dumps(make(target) if mode == "make" else look(target)))
