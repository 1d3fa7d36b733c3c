"""Blender soft-body reference for the standard benchmark scene (docs/benchmarks.md).

A 1 m cube as a 16x16x16 vertex grid (15 cells per side) whose springs are the same ones
springbake's lattice uses (cell edges plus one diagonal per square face), bottom at 1 m above a
collision plane at z = 0, 24 fps, 100 frames baked through Blender's soft body (edge springs,
no goal). Prints one JSON line last: wall time of the bake, vertex/edge counts, the lowest
vertex reached and where the cube ended.

Usage: .venv/bin/python tests/clients/bench_blender_softbody.py [--frames N] [--n 16]
       [--stiff1000 990]  (pull/push stiffness x 1000)
"""

import json
import sys
import time

import bpy


def arg(name, default):
    if name in sys.argv:
        return int(sys.argv[sys.argv.index(name) + 1])
    return default


def grid_mesh(n, size, bottom):
    """Vertices of an n^3 grid spanning `size` metres, bottom at `bottom` (Z up), and the
    lattice springs: axis edges and one diagonal per square face of every cell."""
    h = size / (n - 1)
    idx = lambda i, j, k: i + n * (j + n * k)
    verts = [(i * h, j * h, bottom + k * h) for k in range(n) for j in range(n) for i in range(n)]
    edges = set()
    for k in range(n):
        for j in range(n):
            for i in range(n):
                a = idx(i, j, k)
                if i + 1 < n:
                    edges.add((a, idx(i + 1, j, k)))
                if j + 1 < n:
                    edges.add((a, idx(i, j + 1, k)))
                if k + 1 < n:
                    edges.add((a, idx(i, j, k + 1)))
                # One diagonal per square face (the face's low corner to its high corner).
                if i + 1 < n and j + 1 < n:
                    edges.add((a, idx(i + 1, j + 1, k)))
                if j + 1 < n and k + 1 < n:
                    edges.add((a, idx(i, j + 1, k + 1)))
                if i + 1 < n and k + 1 < n:
                    edges.add((a, idx(i + 1, j, k + 1)))
    return verts, sorted(edges)


def main():
    frames = arg("--frames", 100)
    n = arg("--n", 16)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = 24
    scene.frame_start = 1
    scene.frame_end = frames

    verts, edges = grid_mesh(n, 1.0, 1.0)
    mesh = bpy.data.meshes.new("cube_grid")
    mesh.from_pydata(verts, edges, [])
    mesh.update()
    cube = bpy.data.objects.new("cube", mesh)
    scene.collection.objects.link(cube)

    # Free body (no goal) on edge springs. Blender's spring model is not in SI units. Its
    # defaults (pull/push 0.5) let the cube sag to a third of its height, so pull/push 0.99
    # (mass 1 per vertex, damping 0.5, default adaptive step: error limit 0.1, 10..300 steps
    # per frame) stands in for rubber: the cube keeps its shape through the landing. Setting
    # the mass to 1100 kg over the vertices with stiff springs diverges within a few frames.
    sb_mod = cube.modifiers.new("Softbody", type="SOFT_BODY")
    sb = cube.soft_body
    sb.use_goal = False
    sb.use_edges = True
    sb.use_stiff_quads = False
    sb.use_self_collision = False
    sb.friction = 0.4
    sb.pull = float(arg("--stiff1000", 990)) / 1000.0
    sb.push = sb.pull
    pc = sb_mod.point_cache
    pc.frame_start = 1
    pc.frame_end = frames

    plane_mesh = bpy.data.meshes.new("floor")
    s = 10.0
    plane_mesh.from_pydata([(-s, -s, 0.0), (s, -s, 0.0), (s, s, 0.0), (-s, s, 0.0)], [], [(0, 1, 2, 3)])
    plane_mesh.update()
    floor = bpy.data.objects.new("floor", plane_mesh)
    scene.collection.objects.link(floor)
    floor.modifiers.new("Collision", type="COLLISION")

    depsgraph = bpy.context.evaluated_depsgraph_get()
    scene.frame_set(1)
    t0 = time.perf_counter()
    for f in range(1, frames + 1):
        scene.frame_set(f)
    wall = time.perf_counter() - t0

    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev = cube.evaluated_get(depsgraph)
    zs = [v.co.z for v in ev.data.vertices]
    print(
        json.dumps(
            {
                "client": "blender_softbody",
                "blender": bpy.app.version_string,
                "frames": frames,
                "vertices": len(verts),
                "springs": len(edges),
                "wall_s": round(wall, 4),
                "lowest_z_end": min(zs),
                "highest_z_end": max(zs),
                "height_end": max(zs) - min(zs),
                "pull": sb.pull,
                "step_min": sb.step_min,
                "step_max": sb.step_max,
            }
        )
    )


main()
