"""A springbake importer plug-in for PLY meshes (ASCII and binary), e.g. Blender's
File > Export > Stanford PLY. Positions, normals (nx ny nz) and UVs (s t or u v) per vertex;
faces of any size, fanned into triangles. Blender writes Z-up, so the stage is Z-up metres.

Copy it into `plugins/` beside a scene (or a folder of $SPRINGBAKE_PLUGIN_PATH); then
`springbake bake mesh.ply` and `[[body]] source = "mesh.ply"` work. See docs/plugins.md."""

import os

import numpy as np

SPRINGBAKE_PLUGIN = {"kind": "importer", "name": "ply", "extensions": ["ply"], "up_axis": "Z"}

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def _header(f):
    if f.readline().strip() != b"ply":
        raise ValueError("not a PLY file (no 'ply' magic)")
    fmt, elements = None, []
    while True:
        line = f.readline()
        if not line:
            raise ValueError("the header has no end_header")
        words = line.decode("ascii", "replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property":
            if words[1] == "list":
                elements[-1][2].append((words[4], ("list", _TYPES[words[2]], _TYPES[words[3]])))
            else:
                elements[-1][2].append((words[2], _TYPES[words[1]]))
        elif words[0] == "end_header":
            return fmt, elements


def _read_binary(f, fmt, elements):
    order = "<" if fmt == "binary_little_endian" else ">"
    data = {}
    for name, count, props in elements:
        if all(not isinstance(t, tuple) for _, t in props):
            dtype = np.dtype([(p, order + t) for p, t in props])
            data[name] = np.frombuffer(f.read(dtype.itemsize * count), dtype=dtype, count=count)
            continue
        rows = []
        for _ in range(count):
            row = {}
            for p, t in props:
                if isinstance(t, tuple):
                    n_t, item_t = np.dtype(order + t[1]), np.dtype(order + t[2])
                    n = int(np.frombuffer(f.read(n_t.itemsize), dtype=n_t)[0])
                    row[p] = np.frombuffer(f.read(item_t.itemsize * n), dtype=item_t)
                else:
                    dt = np.dtype(order + t)
                    row[p] = np.frombuffer(f.read(dt.itemsize), dtype=dt)[0]
            rows.append(row)
        data[name] = rows
    return data


def _read_ascii(f, elements):
    tokens = f.read().split()
    at = 0
    data = {}
    for name, count, props in elements:
        rows = []
        for _ in range(count):
            row = {}
            for p, t in props:
                if isinstance(t, tuple):
                    n = int(tokens[at])
                    row[p] = np.array([float(x) for x in tokens[at + 1:at + 1 + n]])
                    at += 1 + n
                else:
                    row[p] = float(tokens[at])
                    at += 1
            rows.append(row)
        data[name] = rows
    return data


def _column(vertices, names):
    if isinstance(vertices, np.ndarray):
        if all(n in vertices.dtype.names for n in names):
            return np.stack([vertices[n].astype(float) for n in names], axis=1)
        return None
    if vertices and all(n in vertices[0] for n in names):
        return np.array([[v[n] for n in names] for v in vertices], dtype=float)
    return None


def import_file(path):
    with open(path, "rb") as f:
        fmt, elements = _header(f)
        data = _read_ascii(f, elements) if fmt == "ascii" else _read_binary(f, fmt, elements)
    vertices = data.get("vertex")
    if vertices is None or len(vertices) == 0:
        raise ValueError("no vertex element")
    positions = _column(vertices, ("x", "y", "z"))
    triangles = []
    for face in data.get("face", []):
        ring = [int(i) for i in (face.get("vertex_indices") if "vertex_indices" in face else face.get("vertex_index"))]
        triangles.extend([ring[0], ring[k], ring[k + 1]] for k in range(1, len(ring) - 1))
    uvs = _column(vertices, ("s", "t"))
    if uvs is None:
        uvs = _column(vertices, ("u", "v"))
    return [{
        "name": os.path.splitext(os.path.basename(path))[0],
        "positions": positions,
        "faces": np.array(triangles, dtype=np.int32).reshape(-1, 3),
        "normals": _column(vertices, ("nx", "ny", "nz")),
        "uvs": uvs,
    }]
