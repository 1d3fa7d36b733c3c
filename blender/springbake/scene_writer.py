"""Turns the Blender scene into a springbake scene folder the CLI can bake.

The folder holds `scene.toml`, one OBJ per body (`bodies/`) and per collider (`colliders/`).
Coordinates are written the way Blender's own OBJ exporter writes them, Y-up and in metres:
Blender's world `(x, y, z)` in scene units becomes `(x, z, -y) × unit scale`. Each body's OBJ
lists the object's vertices in Blender's own order (no splitting at UV or normal seams), taken
after its modifiers at the scene's first frame when they keep the vertex count (shape keys,
armatures, deform modifiers), else from the base mesh, so the point cache the CLI writes has
one point per vertex of the original object.
"""

import json
import math
import os
import re
from dataclasses import dataclass, field

import bpy
import numpy as np

from . import cache

SCENE_FILE = "scene.toml"
CACHE_NAME = "bake.pc2"


class SceneError(Exception):
    """A setting or object that cannot be baked; the message names it."""


@dataclass
class Body:
    """One object simulated as a body: where its OBJ goes and where its cache will be."""

    obj: bpy.types.Object
    mesh_name: str  # the OBJ object name, which names the CLI's per-body cache file
    obj_path: str  # relative to the scene folder
    rest_matrix: list  # matrix_world at the first frame (4×4 rows), to map caches back
    vertex_count: int
    notes: list = field(default_factory=list)


@dataclass
class BakePlan:
    """Everything written for one bake, and what is needed to read its results back."""

    folder: str
    bodies: list
    unit_scale: float
    frame_start: int
    frames: int
    notes: list = field(default_factory=list)

    def cache_file_of(self, body):
        """The PC2 the CLI writes for `body` (one body: `bake.pc2`, several: per mesh name)."""
        if len(self.bodies) == 1:
            return os.path.join(self.folder, CACHE_NAME)
        stem, ext = os.path.splitext(CACHE_NAME)
        return os.path.join(self.folder, f"{stem}_{body.mesh_name}{ext}")


def to_metres_y_up(points_bu, unit_scale):
    """Blender world points (n×3, scene units, Z-up) as springbake's Y-up metres."""
    p = np.asarray(points_bu, dtype=np.float64)
    return np.stack((p[:, 0], p[:, 2], -p[:, 1]), axis=1) * unit_scale


def from_metres_y_up(points_m, unit_scale):
    """Inverse of `to_metres_y_up` (n×3 or frames×n×3)."""
    p = np.asarray(points_m, dtype=np.float64)
    return np.stack((p[..., 0], -p[..., 2], p[..., 1]), axis=-1) / unit_scale


def toml_string(text):
    """A TOML basic string (JSON's escapes are valid TOML when non-ASCII is kept as is)."""
    return json.dumps(text, ensure_ascii=False)


def num(x):
    """A setting for TOML: 7 significant digits (Blender stores settings as 32-bit floats, so
    9.81 stays 9.81, not 9.81000042), and no negative zero."""
    return f"{float(x) + 0.0:.7g}"


def toml_vector(v, digits=9):
    """A vector for TOML; positions keep 9 digits (a float32 read back exactly)."""
    return "[" + ", ".join(f"{float(c) + 0.0:.{digits}g}" for c in v) + "]"


def file_stem(name, index):
    """A file name made from an object name: `[A-Za-z0-9_-]` only, unique by its index."""
    clean = re.sub(r"[^A-Za-z0-9_-]", "_", name)[:48] or "object"
    return f"{index:03d}_{clean}"


def _mesh_arrays(obj, depsgraph, ignore_modifier):
    """World positions (n×3, scene units) and polygons of `obj`, in its own vertex order.

    Uses the evaluated mesh (modifiers applied) when it keeps the base mesh's vertex count,
    else the base mesh; `ignore_modifier` (a previous bake's Mesh Cache) is switched off
    while evaluating so a new bake starts from the rest shape. Returns (positions, loops,
    loop_starts, loop_totals, note).
    """
    note = None
    cached = obj.modifiers.get(ignore_modifier) if ignore_modifier else None
    was_shown = cached.show_viewport if cached else None
    if cached:
        cached.show_viewport = False
        depsgraph.update()
    try:
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        base = obj.data
        if len(mesh.vertices) != len(base.vertices):
            note = (
                f"'{obj.name}': its modifiers change the vertex count "
                f"({len(base.vertices)} → {len(mesh.vertices)}); baked the base mesh, the "
                "modifiers apply after the cache"
            )
            source = base
        else:
            source = mesh
        n = len(source.vertices)
        co = np.empty(n * 3, dtype=np.float64)
        source.vertices.foreach_get("co", co)
        co = co.reshape(n, 3)
        loops = np.empty(len(source.loops), dtype=np.int64)
        source.loops.foreach_get("vertex_index", loops)
        starts = np.empty(len(source.polygons), dtype=np.int64)
        totals = np.empty(len(source.polygons), dtype=np.int64)
        source.polygons.foreach_get("loop_start", starts)
        source.polygons.foreach_get("loop_total", totals)
        evaluated.to_mesh_clear()
    finally:
        if cached:
            cached.show_viewport = was_shown
    matrix = np.array(obj.matrix_world, dtype=np.float64)
    world = co @ matrix[:3, :3].T + matrix[:3, 3]
    return world, loops, starts, totals, note


def write_obj(path, name, points_m, loops, starts, totals):
    """An OBJ with one object: every vertex (in order), the polygons, and loose vertices as
    one-point `l` elements so the importer keeps every vertex in the cache."""
    used = np.zeros(len(points_m), dtype=bool)
    used[loops] = True
    lines = [f"# written by the springbake Blender extension\no {name}\n"]
    lines.extend(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in points_m)
    one_based = loops + 1
    for start, total in zip(starts.tolist(), totals.tolist()):
        corners = " ".join(map(str, one_based[start : start + total].tolist()))
        lines.append(f"f {corners}\n")
    lines.extend(f"l {i + 1} {i + 1}\n" for i in np.flatnonzero(~used).tolist())
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.writelines(lines)


def _material_toml(settings):
    if settings.material != "custom":
        return toml_string(settings.material)
    return (
        f"{{ young = {num(settings.young)}, density = {num(settings.density)}, "
        f"poisson = {num(settings.poisson)}, damping = {num(settings.damping)} }}"
    )


def _manipulator_toml(scene, settings, unit_scale, fps):
    """The `[[manipulator]]` table: the object's world position and yaw at every frame."""
    obj = settings.manipulator
    keys = []
    current = scene.frame_current
    try:
        for frame in range(scene.frame_start, scene.frame_end + 1):
            scene.frame_set(frame)
            m = obj.matrix_world
            centre = to_metres_y_up([m.translation], unit_scale)[0]
            x_axis = m.col[0]
            yaw = math.degrees(math.atan2(x_axis[1], x_axis[0]))
            t = (frame - scene.frame_start) / fps
            keys.append(
                f"  {{ t = {t:.9g}, position = {toml_vector(centre)}, yaw = {num(yaw)} }},"
            )
    finally:
        scene.frame_set(current)
    return (
        "\n[[manipulator]]\n"
        f"# the capsule follows {toml_string(obj.name)}, one key per frame\n"
        f"radius = {num(settings.manipulator_radius * unit_scale)}\n"
        f"length = {num(settings.manipulator_length * unit_scale)}\n"
        f"friction = {num(settings.friction)}\n"
        "keys = [\n" + "\n".join(keys) + "\n]\n"
    )


def plan_bake(context, objects, folder):
    """Writes the scene folder for baking `objects` (mesh objects) and returns the plan.

    Raises SceneError naming the object or setting at fault.
    """
    scene = context.scene
    settings = scene.springbake
    unit_scale = scene.unit_settings.scale_length or 1.0
    fps = scene.render.fps / (scene.render.fps_base or 1.0)
    frames = scene.frame_end - scene.frame_start + 1
    if frames < 2:
        raise SceneError(
            f"the scene's frame range {scene.frame_start}–{scene.frame_end} has fewer than "
            "two frames"
        )
    bodies_objects = [
        o
        for o in objects
        if o.type == "MESH" and not o.springbake.collider and o != settings.manipulator
    ]
    if not bodies_objects:
        raise SceneError("select the mesh objects to bake")
    for obj in bodies_objects:
        if len(obj.data.polygons) == 0:
            raise SceneError(f"'{obj.name}' has no faces; a body needs a surface")
    colliders = [
        o
        for o in scene.objects
        if o.type == "MESH" and o.springbake.collider and o not in bodies_objects
    ]
    os.makedirs(os.path.join(folder, "bodies"), exist_ok=True)
    os.makedirs(os.path.join(folder, "colliders"), exist_ok=True)

    current = scene.frame_current
    scene.frame_set(scene.frame_start)
    depsgraph = context.evaluated_depsgraph_get()
    bodies = []
    notes = []
    body_tables = []
    collider_tables = []
    try:
        for index, obj in enumerate(bodies_objects):
            world, loops, starts, totals, note = _mesh_arrays(obj, depsgraph, cache.MODIFIER_NAME)
            if note:
                notes.append(note)
            mesh_name = f"b{index}"
            rel = f"bodies/{file_stem(obj.name, index)}.obj"
            write_obj(
                os.path.join(folder, rel),
                mesh_name,
                to_metres_y_up(world, unit_scale),
                loops,
                starts,
                totals,
            )
            s = obj.springbake
            velocity = to_metres_y_up([s.velocity], 1.0)[0]
            body_tables.append(
                "\n[[body]]\n"
                f"name = {toml_string(obj.name)}\n"
                f"source = {toml_string(rel)}\n"
                f"cells = {s.cells}\n"
                f"material = {_material_toml(s)}\n"
                f"kind = {toml_string(s.kind)}\n"
                f"preserve_volume = {'true' if s.preserve_volume else 'false'}\n"
                f"velocity = {toml_vector(velocity, 7)}\n"
            )
            bodies.append(
                Body(
                    obj=obj,
                    mesh_name=mesh_name,
                    obj_path=rel,
                    rest_matrix=[list(row) for row in obj.matrix_world],
                    vertex_count=len(world),
                )
            )
        for index, obj in enumerate(colliders):
            world, loops, starts, totals, _ = _mesh_arrays(obj, depsgraph, None)
            rel = f"colliders/{file_stem(obj.name, index)}.obj"
            write_obj(
                os.path.join(folder, rel),
                f"c{index}",
                to_metres_y_up(world, unit_scale),
                loops,
                starts,
                totals,
            )
            collider_tables.append(
                "\n[[collider]]\n"
                f"name = {toml_string(obj.name)}\n"
                f"source = {toml_string(rel)}\n"
                f"friction = {num(settings.friction)}\n"
            )
    finally:
        scene.frame_set(current)

    gravity = -scene.gravity[2] if scene.use_gravity else 0.0
    if scene.use_gravity and (abs(scene.gravity[0]) > 1e-9 or abs(scene.gravity[1]) > 1e-9):
        notes.append("the scene's gravity has a horizontal part; springbake uses its Z part")
    text = [
        "# Written by the springbake Blender extension: Y-up metres "
        "(Blender's (x, y, z) × unit scale → (x, z, -y)).\n",
        f"# Blender file: {toml_string(bpy.data.filepath or 'unsaved')}, scene "
        f"{toml_string(scene.name)}\n",
        "\n[output]\n",
        f"path = {toml_string(CACHE_NAME)}\n",
        f"fps = {num(fps)}\n",
        f"frames = {frames}\n",
        "\n[world]\n",
        'up = "y"\n',
        f"gravity = {num(max(gravity, 0.0))}\n",
        f"friction = {num(settings.friction)}\n",
    ]
    if gravity < 0.0:
        notes.append("the scene's gravity points up; springbake baked without gravity")
    if settings.use_floor:
        text.append(f"floor = {num(settings.floor * unit_scale)}\n")
    text.extend(body_tables)
    text.extend(collider_tables)
    if settings.manipulator is not None:
        text.append(_manipulator_toml(scene, settings, unit_scale, fps))
    with open(os.path.join(folder, SCENE_FILE), "w", encoding="utf-8", newline="\n") as f:
        f.writelines(text)
    return BakePlan(
        folder=folder,
        bodies=bodies,
        unit_scale=unit_scale,
        frame_start=scene.frame_start,
        frames=frames,
        notes=notes,
    )
