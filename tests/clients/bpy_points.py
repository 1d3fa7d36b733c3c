"""What the Blender test clients measure on an object, shared by them."""

import bpy
import numpy as np


def evaluated_world(obj):
    """World positions (n×3, numpy) of `obj`'s evaluated mesh: modifiers (a Mesh Cache, shape
    keys) applied at the current frame, then its world matrix."""
    ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = ev.to_mesh()
    co = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    ev.to_mesh_clear()
    m = np.array(obj.matrix_world)
    return co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
