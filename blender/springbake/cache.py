"""Point caches on the original objects: reads the PC2 the CLI wrote (Y-up metres, world),
maps it into the object's local space in scene units, writes it atomically beside the .blend
and attaches it as a Mesh Cache modifier first in the modifier stack, so the object's
materials, UVs, vertex groups and later modifiers stay. `free` removes it again.
"""

import os
import struct
import tempfile

import bpy
import numpy as np

MODIFIER_NAME = "springbake"
PC2_MAGIC = b"POINTCACHE2\0"
_HEADER = struct.Struct("<12siiffi")


class CacheError(Exception):
    """A cache file that cannot be read or does not fit its object."""


def read_pc2(path):
    """(frames × points × 3 float32 array, start frame, sample rate) of a PC2 file."""
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < _HEADER.size:
        raise CacheError(f"{path}: shorter than a PC2 header")
    magic, version, points, start, rate, samples = _HEADER.unpack_from(data)
    if magic != PC2_MAGIC or version != 1 or points < 0 or samples < 0:
        raise CacheError(f"{path}: not a PC2 version 1 file")
    expected = _HEADER.size + points * samples * 12
    if len(data) != expected:
        raise CacheError(f"{path}: {len(data)} bytes, the header says {expected}")
    frames = np.frombuffer(data, dtype="<f4", offset=_HEADER.size).reshape(samples, points, 3)
    return frames, start, rate


def write_pc2_atomically(path, frames, start=0.0, rate=1.0):
    """Writes `frames` (frames × points × 3) as PC2 through a temporary file and a rename,
    so a reader never sees half a file and a failure keeps the old one."""
    frames = np.ascontiguousarray(frames, dtype="<f4")
    samples, points, _ = frames.shape
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".springbake-", suffix=".pc2", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(_HEADER.pack(PC2_MAGIC, 1, points, start, rate, samples))
            f.write(frames.tobytes())
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def to_local(frames_world_bu, rest_matrix):
    """World points (frames × n × 3, scene units) in the object's local space at rest."""
    m = np.array(rest_matrix, dtype=np.float64)
    inverse = np.linalg.inv(m)
    return frames_world_bu @ inverse[:3, :3].T + inverse[:3, 3]


def attach(obj, path, frame_start):
    """Puts (or updates) the Mesh Cache modifier playing `path` first in `obj`'s stack."""
    mod = obj.modifiers.get(MODIFIER_NAME)
    if mod is None or mod.type != "MESH_CACHE":
        if mod is not None:
            obj.modifiers.remove(mod)
        mod = obj.modifiers.new(MODIFIER_NAME, "MESH_CACHE")
    mod.cache_format = "PC2"
    mod.filepath = bpy.path.relpath(path) if bpy.data.filepath else path
    mod.frame_start = frame_start
    mod.time_mode = "FRAME"
    mod.play_mode = "SCENE"
    mod.deform_mode = "OVERWRITE"
    mod.interpolation = "LINEAR"
    mod.forward_axis = "POS_Y"
    mod.up_axis = "POS_Z"
    index = list(obj.modifiers).index(mod)
    if index != 0:
        obj.modifiers.move(index, 0)
    obj.update_tag()
    return mod


def free(obj, delete_file=True):
    """Removes the bake from `obj` (its modifier, and its cache file). True if there was one."""
    mod = obj.modifiers.get(MODIFIER_NAME)
    if mod is None:
        return False
    path = bpy.path.abspath(mod.filepath) if mod.type == "MESH_CACHE" else None
    obj.modifiers.remove(mod)
    obj.update_tag()
    if delete_file and path and os.path.isfile(path):
        os.unlink(path)
    return True
