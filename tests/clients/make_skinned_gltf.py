"""Writes a skinned, animated glTF the way an artist's Blender file exports it (issue 19 item 4).

Usage: make_skinned_gltf.py OUT.glb
A cylinder (r 0.15 m, 1 m tall, bottom 0.5 m above the origin) bound to a two-bone armature by
automatic-free vertex groups (the lower half to "Lower", the upper half to "Upper", blended at
the middle); the upper bone bends 60 degrees at frame 1 and straightens by frame 24; a shape
key "Bulge" at 0.4. The glTF's bind pose is the straight cylinder; what renders at frame 1 is
bent and bulged.
"""
import math
import sys

import bpy

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.frame_start, scene.frame_end = 1, 24

bpy.ops.mesh.primitive_cylinder_add(radius=0.15, depth=1.0, vertices=16, location=(0, 0, 1.0))
body = bpy.context.active_object
body.name = "Tube"
bpy.ops.object.mode_set(mode="EDIT")
bpy.ops.mesh.subdivide(number_cuts=6)
bpy.ops.object.mode_set(mode="OBJECT")

bpy.ops.object.armature_add(location=(0, 0, 0.5))
rig = bpy.context.active_object
rig.name = "Rig"
bpy.ops.object.mode_set(mode="EDIT")
lower = rig.data.edit_bones[0]
lower.name = "Lower"
lower.head, lower.tail = (0, 0, 0), (0, 0, 0.5)
upper = rig.data.edit_bones.new("Upper")
upper.head, upper.tail = (0, 0, 0.5), (0, 0, 1.0)
upper.parent = lower
bpy.ops.object.mode_set(mode="OBJECT")

groups = {name: body.vertex_groups.new(name=name) for name in ("Lower", "Upper")}
for v in body.data.vertices:
    z = v.co.z  # local: -0.5 .. 0.5
    w_up = min(max((z + 0.1) / 0.2, 0.0), 1.0)
    groups["Upper"].add([v.index], w_up, "REPLACE")
    groups["Lower"].add([v.index], 1.0 - w_up, "REPLACE")
body.parent = rig
body.matrix_parent_inverse = rig.matrix_world.inverted()
mod = body.modifiers.new("Armature", "ARMATURE")
mod.object = rig

body.shape_key_add(name="Basis")
bulge = body.shape_key_add(name="Bulge")
for v, k in zip(body.data.vertices, bulge.data):
    k.co = v.co * 1.0
    k.co.x *= 1.5
    k.co.y *= 1.5
bulge.value = 0.4

pose = rig.pose.bones["Upper"]
pose.rotation_mode = "XYZ"
pose.rotation_euler = (math.radians(60), 0, 0)
pose.keyframe_insert("rotation_euler", frame=1)
pose.rotation_euler = (0, 0, 0)
pose.keyframe_insert("rotation_euler", frame=24)
scene.frame_set(1)

bpy.ops.export_scene.gltf(filepath=out, export_format="GLB", export_skins=True,
                          export_morph=True, export_animations=True)
print("wrote", out)
