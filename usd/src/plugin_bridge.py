"""springbake's host for Python plug-ins (docs/plugins.md). Rust calls load_plugin(path) once
per discovered file, then call_import / call_export; bulk data crosses as flat little-endian
byte arrays. Any exception a plug-in raises becomes a BridgeError naming the plug-in's file
and line."""

import os
import traceback

import numpy as np


class BridgeError(Exception):
    def __init__(self, message, location=None):
        super().__init__(message)
        self.message = message
        self.location = location


KINDS = ("importer", "exporter", "force_field", "procedure")


def _where(error, path):
    """`line N` of the deepest frame of the traceback inside the plug-in's file."""
    line = None
    for frame in traceback.extract_tb(error.__traceback__):
        if os.path.abspath(frame.filename) == os.path.abspath(path):
            line = frame.lineno
    if line is None and isinstance(error, SyntaxError):
        line = error.lineno
    return "line %s" % (line if line is not None else "?")


def _raised(error, path, doing):
    return BridgeError(
        "the plug-in raised %s while %s: %s" % (type(error).__name__, doing, error),
        _where(error, path),
    )


def load_plugin(path):
    """Runs the file as a module; returns (namespace, kind, name, extensions)."""
    with open(path, "r", encoding="utf-8") as f:
        source = f.read()
    namespace = {"__file__": path, "__name__": "springbake_plugin_" + os.path.basename(path)[:-3]}
    try:
        exec(compile(source, path, "exec"), namespace)
    except BaseException as e:  # a plug-in must never take the host down
        raise _raised(e, path, "loading")
    return (namespace,) + _manifest(namespace)


def entry_points(folders):
    """The `springbake.plugins` entry points of the installed packages, as sorted
    (name, value) pairs (importlib.metadata reads every *.dist-info on sys.path, to which
    the host's package `folders` are added: the venv's, $PYTHONPATH's)."""
    import sys
    from importlib.metadata import entry_points as installed

    for folder in folders:
        if folder not in sys.path:
            sys.path.append(folder)
    return sorted((ep.name, ep.value) for ep in installed(group="springbake.plugins"))


def load_entry_point(name, value):
    """Imports an entry point's module (`package.module`); returns (namespace, kind, name,
    extensions, file) like load_plugin, the module's own dict as the namespace."""
    import importlib

    module_name = value.split(":")[0].strip()
    try:
        module = importlib.import_module(module_name)
    except BaseException as e:
        where = None
        for frame in traceback.extract_tb(e.__traceback__):
            where = "%s, line %s" % (frame.filename, frame.lineno)
        raise BridgeError(
            "the module raised %s while importing: %s" % (type(e).__name__, e),
            where,
        )
    namespace = vars(module)
    path = getattr(module, "__file__", None) or module_name
    return (namespace,) + _manifest(namespace) + (path,)


def _manifest(namespace):
    """(kind, name, extensions) of a plug-in's SPRINGBAKE_PLUGIN dict, checked."""
    info = namespace.get("SPRINGBAKE_PLUGIN")
    if not isinstance(info, dict):
        raise BridgeError("defines no SPRINGBAKE_PLUGIN dict (kind, name, extensions)")
    kind, name, extensions = info.get("kind"), info.get("name"), info.get("extensions")
    if kind not in KINDS:
        raise BridgeError("SPRINGBAKE_PLUGIN['kind'] must be one of %s, got %r" % (KINDS, kind))
    if not isinstance(name, str) or not name:
        raise BridgeError("SPRINGBAKE_PLUGIN['name'] must be a non-empty string")
    if kind in ("force_field", "procedure"):
        extensions = []
    elif not isinstance(extensions, (list, tuple)) or not extensions or not all(
        isinstance(e, str) and e and "." not in e for e in extensions
    ):
        raise BridgeError("SPRINGBAKE_PLUGIN['extensions'] must be a list like ['ply']")
    entry = {"importer": "import_file", "exporter": "export", "force_field": "force",
             "procedure": "run"}[kind]
    if not callable(namespace.get(entry)):
        raise BridgeError("a %s plug-in must define %s()" % (kind, entry))
    return kind, name, [e.lower() for e in extensions]


def _array(value, what, width, dtype, location):
    try:
        a = np.asarray(value, dtype=dtype)
    except Exception as e:
        raise BridgeError("%s is not numeric (%s)" % (what, e), location)
    if a.ndim != 2 or a.shape[1] != width:
        raise BridgeError("%s must have shape (n, %d), got %s" % (what, width, a.shape), location)
    if dtype == np.float64 and not np.isfinite(a).all():
        raise BridgeError("%s has non-finite values" % what, location)
    return np.ascontiguousarray(a.astype("<f8" if dtype == np.float64 else "<i4"))


def call_import(namespace, plugin_path, path):
    """The plug-in's meshes as dicts of byte arrays (positions f64×3, faces i32×3, optional
    uvs f64×2, normals f64×3, matrix f64×16 row-major)."""
    try:
        meshes = namespace["import_file"](path)
    except BaseException as e:
        raise _raised(e, plugin_path, "importing " + path)
    if not isinstance(meshes, (list, tuple)) or not meshes:
        raise BridgeError("import_file() must return a non-empty list of meshes")
    out = []
    for k, m in enumerate(meshes):
        where = "import_file()[%d]" % k
        if not isinstance(m, dict):
            raise BridgeError("each mesh must be a dict, got %s" % type(m).__name__, where)
        positions = _array(m.get("positions"), "positions", 3, np.float64, where)
        faces = _array(m.get("faces"), "faces", 3, np.int32, where)
        if faces.size and (faces.min() < 0 or faces.max() >= len(positions)):
            raise BridgeError("faces index outside positions (%d points)" % len(positions), where)
        item = {
            "name": str(m.get("name") or "mesh_%d" % k),
            "positions": positions.tobytes(),
            "faces": faces.tobytes(),
        }
        for key, width in (("uvs", 2), ("normals", 3)):
            if m.get(key) is not None:
                a = _array(m[key], key, width, np.float64, where)
                if len(a) != len(positions):
                    raise BridgeError("%s must have one row per position" % key, where)
                item[key] = a.tobytes()
        if m.get("matrix") is not None:
            mat = np.asarray(m["matrix"], dtype="<f8")
            if mat.shape != (4, 4):
                raise BridgeError("matrix must be 4×4, got %s" % (mat.shape,), where)
            item["matrix"] = np.ascontiguousarray(mat).tobytes()
        out.append(item)
    return out


def call_export(namespace, plugin_path, spec, out_path):
    """Gives the plug-in the bake (numpy arrays) and the path to write."""
    meshes = []
    for m in spec["meshes"]:
        frames = np.frombuffer(m["frames"], dtype="<f4").reshape(spec["frame_count"], -1, 3)
        meshes.append({
            "name": m["name"],
            "frames": frames,
            "triangles": np.frombuffer(m["triangles"], dtype="<i4").reshape(-1, 3),
            "matrix": np.frombuffer(m["matrix"], dtype="<f8").reshape(4, 4),
        })
    baked = {"fps": spec["fps"], "frame_count": spec["frame_count"], "meshes": meshes,
             "up_axis": spec["up_axis"], "meters_per_unit": spec["meters_per_unit"]}
    try:
        namespace["export"](baked, out_path)
    except BaseException as e:
        raise _raised(e, plugin_path, "exporting")
    if not os.path.isfile(out_path):
        raise BridgeError("export() wrote nothing to the path it was given")


def _wants_masses(function):
    import inspect

    try:
        return len(inspect.signature(function).parameters) >= 4
    except (TypeError, ValueError):
        return False


def call_force(namespace, plugin_path, positions, velocities, masses, time):
    """The field's forces (n×3 f64 bytes) on nodes given as flat f64 bytes."""
    x = np.frombuffer(positions, dtype="<f8").reshape(-1, 3)
    v = np.frombuffer(velocities, dtype="<f8").reshape(-1, 3)
    m = np.frombuffer(masses, dtype="<f8")
    function = namespace["force"]
    try:
        if _wants_masses(function):
            f = function(x, v, float(time), m)
        else:
            f = function(x, v, float(time))
    except BaseException as e:
        raise _raised(e, plugin_path, "computing forces")
    return _array(f, "force()", 3, np.float64, "force()").tobytes()


def call_check(namespace, plugin_path, args_json):
    """The procedure's own check of its scene arguments (an optional `check(args)` that
    raises on bad ones)."""
    import json

    check = namespace.get("check")
    if callable(check):
        try:
            check(json.loads(args_json))
        except BaseException as e:
            raise _raised(e, plugin_path, "checking its arguments")


def call_procedure(namespace, plugin_path, positions, velocities, masses, time, args_json):
    """Runs the procedure on one body; returns (its new node velocities as n×3 f64 bytes or
    None to leave them, the built-in procedures to apply next as JSON): run() returns None
    or a dict with any of "velocities" (n×3), "impulse" ([x, y, z] N·s on the whole body),
    "material" (a preset or scene material name), "pin" (True: hold the body where it is,
    False: release it) and "procedures" (a list of built-in procedures as scene files write
    them, e.g. {"set_velocity": [0, 2, 0]} or "settle"), applied in that order."""
    import json

    body = {
        "positions": np.frombuffer(positions, dtype="<f8").reshape(-1, 3).copy(),
        "velocities": np.frombuffer(velocities, dtype="<f8").reshape(-1, 3).copy(),
        "masses": np.frombuffer(masses, dtype="<f8").copy(),
        "time": float(time),
    }
    try:
        out = namespace["run"](body, json.loads(args_json))
    except BaseException as e:
        raise _raised(e, plugin_path, "running")
    if out is None:
        return None, "[]"
    if not isinstance(out, dict):
        out = {"velocities": out}
    known = ("velocities", "impulse", "material", "pin", "procedures")
    unknown = [k for k in out if k not in known]
    if unknown:
        raise BridgeError("run() returned unknown keys %s (known: %s)" % (unknown, ", ".join(known)), "run()")
    v = out.get("velocities")
    if v is not None:
        v = _array(v, "run()['velocities']", 3, np.float64, "run()")
        if len(v) != len(body["masses"]):
            raise BridgeError("run() returned %d velocities for %d nodes" % (len(v), len(body["masses"])), "run()")
        v = v.tobytes()
    then = []
    if out.get("impulse") is not None:
        j = _array(np.asarray(out["impulse"], dtype=float).reshape(1, -1), "run()['impulse']", 3, np.float64, "run()")
        then.append({"apply_impulse": [float(x) for x in j[0]]})
    if out.get("material") is not None:
        if not isinstance(out["material"], str):
            raise BridgeError("run()['material'] must be a material name, got %r" % (out["material"],), "run()")
        then.append({"change_material": out["material"]})
    if out.get("pin") is not None:
        then.append("pin" if out["pin"] else "unpin")
    extra = out.get("procedures") or []
    if not isinstance(extra, (list, tuple)):
        raise BridgeError("run()['procedures'] must be a list", "run()")
    then.extend(extra)
    try:
        text = json.dumps(then)
    except (TypeError, ValueError) as e:
        raise BridgeError("run()['procedures'] is not plain data: %s" % e, "run()")
    return v, text
