"""Drives the springbake Blender extension the way a user (or a farm script) would, in bpy.

Usage: python blender_extension.py EXTENSION.zip SPRINGBAKE_BINARY WORK_DIR
Run with BLENDER_USER_RESOURCES pointing at an empty folder so the install stays out of the
user's own Blender. Prints one JSON line of measurements; the Rust test checks them.
"""

import json
import os
import sys
import time

import bpy
import numpy as np

from bpy_points import evaluated_world

zip_path, binary, work = sys.argv[1], sys.argv[2], sys.argv[3]
out = {}

bpy.ops.wm.read_factory_settings(use_empty=True)
started = time.monotonic()
bpy.ops.extensions.package_install_files(
    filepath=zip_path, repo="user_default", enable_on_install=True
)
out["installed"] = "bl_ext.user_default.springbake" in bpy.context.preferences.addons.keys()
out["install_seconds"] = time.monotonic() - started


def select_only(objects):
    for o in bpy.context.scene.objects:
        o.select_set(o in objects)
    bpy.context.view_layer.objects.active = objects[0]


def bake_or_error():
    """Runs the operator; the error text when it reported one (bpy raises RuntimeError)."""
    try:
        result = bpy.ops.springbake.bake()
        return None if result == {"FINISHED"} else f"result {result}"
    except RuntimeError as e:
        return str(e)


def new_scene(frames, unit_scale=1.0):
    # read_homefile keeps the preferences (and so the enabled extension); factory settings
    # would disable it.
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    scene.render.fps = 24
    scene.unit_settings.scale_length = unit_scale
    scene.springbake.binary = binary
    scene.springbake.cache_dir = os.path.join(work, f"cache_{len(os.listdir(work))}")
    return scene


# 1. Suzanne above a plane collider (no floor), with a material and a UV layer; 3 s.
scene = new_scene(72)
scene.springbake.use_floor = False
bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0, 0, 0))
plane = bpy.context.object
plane.springbake.collider = True
bpy.ops.mesh.primitive_monkey_add(size=0.6, location=(0, 0, 0.8))
suzanne = bpy.context.object
suzanne.rotation_euler = (0.3, 0.0, 0.5)
material = bpy.data.materials.new("Skin")
material.diffuse_color = (0.8, 0.2, 0.1, 1.0)
suzanne.data.materials.append(material)
bpy.ops.object.modifier_add(type="SUBSURF")
suzanne.springbake.enabled = True
suzanne.springbake.cells = 10
rest = evaluated_world(suzanne)
vertex_count = len(suzanne.data.vertices)
uv_layers = [uv.name for uv in suzanne.data.uv_layers]
select_only([suzanne])
started = time.monotonic()
out["bake_error"] = bake_or_error()
out["bake_seconds"] = time.monotonic() - started
out["modifiers"] = [(m.name, m.type) for m in suzanne.modifiers]
out["vertex_count_kept"] = len(suzanne.data.vertices) == vertex_count
out["material_kept"] = [m.name for m in suzanne.data.materials] == ["Skin"]
out["uv_layers_kept"] = [uv.name for uv in suzanne.data.uv_layers] == uv_layers
out["plane_has_no_modifier"] = len(plane.modifiers) == 0
scene.frame_set(1)
first = evaluated_world(suzanne)
out["frame1_vs_rest_max_m"] = float(np.abs(first - rest).max()) if first.shape == rest.shape else None
lowest = []
for f in range(1, 73):
    scene.frame_set(f)
    lowest.append(float(evaluated_world(suzanne)[:, 2].min()))
out["suzanne_lowest_z"] = lowest
out["plane_z"] = float(evaluated_world(plane)[:, 2].max())
scene.frame_set(48)
rubber_last = evaluated_world(suzanne)

# A second bake after changing the material differs.
suzanne.springbake.material = "jelly"
out["rebake_error"] = bake_or_error()
scene.frame_set(48)
jelly_last = evaluated_world(suzanne)
out["material_change_moves_m"] = float(np.abs(jelly_last - rubber_last).max())

# Free bake restores the rest shape.
out["free"] = list(bpy.ops.springbake.free_bake())
scene.frame_set(30)
freed = evaluated_world(suzanne)
out["after_free_vs_rest_max_m"] = float(np.abs(freed - rest).max())
out["modifiers_after_free"] = [m.type for m in suzanne.modifiers]

# A missing binary: a report, no traceback, the object untouched.
out["rebake_for_missing"] = bake_or_error()
scene.springbake.binary = os.path.join(work, "no-such-springbake")
out["missing_binary_error"] = bake_or_error()
out["modifier_kept_after_failure"] = suzanne.modifiers[0].type == "MESH_CACHE"

# 2. Three bodies and a collider, in centimetre units (1 unit = 1 cm): they fall 50 units
# (0.5 m) and must land in about 0.32 s, not in slow motion.
scene = new_scene(36, unit_scale=0.01)
scene.springbake.use_floor = True
scene.springbake.floor = 0.0
bpy.ops.mesh.primitive_cube_add(size=200.0, location=(0, 0, -100.0))
ground = bpy.context.object
ground.springbake.collider = True
bodies = []
for i, (x, material_name) in enumerate(((-40, "rubber"), (0, "wood"), (40, "soft_rubber"))):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=10.0, location=(x, 0, 60.0))
    obj = bpy.context.object
    obj.name = f"Ball {i}"
    obj.springbake.enabled = True
    obj.springbake.material = material_name
    obj.springbake.cells = 6
    bodies.append(obj)
select_only(bodies)
out["multi_error"] = bake_or_error()
out["multi_modifiers"] = [[m.type for m in b.modifiers] for b in bodies]
fall = {}
for b in bodies:
    lows = []
    for f in range(1, 37):
        scene.frame_set(f)
        lows.append(float(evaluated_world(b)[:, 2].min()))
    fall[b.name] = lows
out["multi_lowest_z"] = fall
out["multi_names"] = [b.name for b in bodies]

# Cancelling a running bake (the runner the modal operator polls): a long bake of the same
# scene stops within seconds of the request.
runner = sys.modules["bl_ext.user_default.springbake.runner"]
pending = os.path.join(scene.springbake.cache_dir, "Scene", "pending")
with open(os.path.join(pending, "scene.toml"), encoding="utf-8") as f:
    long_scene = f.read().replace("frames = 36", "frames = 5000")
long_path = os.path.join(pending, "long.toml")
with open(long_path, "w", encoding="utf-8") as f:
    f.write(long_scene)
job = runner.BakeJob(binary, long_path, os.path.join(pending, "long.json"))
deadline = time.monotonic() + 60
while job.poll() and job.done_frames < 2 and time.monotonic() < deadline:
    time.sleep(0.05)
started = time.monotonic()
job.cancel()
out["cancel"] = {
    "frames_before": job.done_frames,
    "total": job.total_frames,
    "seconds": time.monotonic() - started,
    "returncode": job.returncode,
}

# The panels draw (without a window: a stand-in layout that checks every property and
# operator they name exists).
panels = sys.modules["bl_ext.user_default.springbake.panels"]


class CheckingLayout:
    def __init__(self, seen):
        self.seen = seen
        self.active = True
        self.use_property_split = False
        self.scale_y = 1.0

    def prop(self, data, name, **_):
        assert name in data.bl_rna.properties, f"no property {name} on {data}"
        self.seen.append(name)

    def operator(self, idname, **_):
        group, name = idname.split(".")
        assert hasattr(getattr(bpy.ops, group), name), idname
        self.seen.append(idname)

    def label(self, **_):
        pass

    def row(self, **_):
        return self

    column = box = row


drawn = []
panels.draw_object_settings(CheckingLayout(drawn), bodies[0])
bodies[0].springbake.material = "custom"
panels.draw_object_settings(CheckingLayout(drawn), bodies[0])
panels.draw_scene_settings(CheckingLayout(drawn), bpy.context)
panels.draw_bake_buttons(CheckingLayout(drawn), bpy.context)
out["panel_items"] = sorted(set(drawn))

# 3. An animated object drives the capsule manipulator: it sweeps through a jelly block
# resting on the floor and pushes it along +X.
scene = new_scene(36)
bpy.ops.mesh.primitive_cube_add(size=0.3, location=(0, 0, 0.15))
block = bpy.context.object
block.springbake.material = "jelly"
block.springbake.cells = 6
bpy.ops.object.empty_add(location=(-0.5, 0, 0.1))
pusher = bpy.context.object
pusher.rotation_euler = (0, 0, 1.5708)  # local X along Y: the capsule lies across the path
pusher.keyframe_insert("location", frame=1)
pusher.location = (0.6, 0, 0.1)
pusher.keyframe_insert("location", frame=30)
scene.springbake.manipulator = pusher
scene.springbake.manipulator_radius = 0.04
scene.springbake.manipulator_length = 0.4
select_only([block, pusher])
out["manipulator_error"] = bake_or_error()
out["pusher_modifiers"] = len(pusher.modifiers)
scene.frame_set(1)
x_first = float(evaluated_world(block)[:, 0].mean())
scene.frame_set(36)
x_last = float(evaluated_world(block)[:, 0].mean())
out["block_pushed_m"] = x_last - x_first

print(json.dumps(out))
