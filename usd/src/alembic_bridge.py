"""springbake's Alembic bridge: writes baked frames as an Ogawa archive through alembic3d
(PyAlembic). Rust calls write_archive(out_path, spec) with flat little-endian byte arrays;
everything else about the layout (names, axes, winding) is decided on the Rust side
(usd/src/alembic.rs)."""

import imath
from alembic3d.Abc import OArchive
from alembic3d.AbcCoreAbstract import TimeSampling
from alembic3d.AbcGeom import (
    GeometryScope,
    ON3fGeomParamSample,
    OPolyMesh,
    OPolyMeshSchemaSample,
    OV2fGeomParamSample,
    OXform,
    XformSample,
)


class BridgeError(Exception):
    def __init__(self, message, location=None):
        super().__init__(message)
        self.message = message
        self.location = location


def _v3f(data, count):
    return imath.V3fArrayFromBuffer(memoryview(data).cast("B").cast("f", shape=[count, 3]))


def _v2f(data, count):
    return imath.V2fArrayFromBuffer(memoryview(data).cast("B").cast("f", shape=[count, 2]))


def _ints(data):
    return imath.IntArrayFromBuffer(memoryview(data).cast("B").cast("i"))


def _matrix(data):
    import array

    values = array.array("d")
    values.frombytes(data)
    return imath.M44d(*values)


def write_archive(out_path, spec):
    """One Xform (the mesh's placement, constant) with one PolyMesh child per mesh; the
    PolyMesh's first sample has the topology, UVs and normals, every later sample new
    positions (and normals)."""
    fps = float(spec["fps"])
    frame_count = int(spec["frame_count"])
    try:
        # Not CreateArchiveWithInfo: it stamps the wall-clock date into the archive, and the
        # same bake must give the same bytes.
        archive = OArchive(out_path, True)
    except Exception as e:
        raise BridgeError("alembic3d cannot create the archive: %s" % e)
    sampling = archive.addTimeSampling(TimeSampling(1.0 / fps, 0.0))
    top = archive.getTop()
    for item in spec["meshes"]:
        name = item["name"]
        n = int(item["point_count"])
        corners = int(item["corner_count"])
        stride = n * 12
        nstride = corners * 12
        points = item["points"]
        if len(points) != stride * frame_count:
            raise BridgeError("points data has the wrong size", "/" + name)
        xform = OXform(top, name, sampling)
        placement = XformSample()
        placement.setMatrix(_matrix(item["world"]))
        xform.getSchema().set(placement)
        mesh = OPolyMesh(xform, name + "Shape", sampling)
        schema = mesh.getSchema()
        indices = _ints(item["indices"])
        counts = _ints(item["counts"])
        normals = item.get("normals")
        for f in range(frame_count):
            p = _v3f(points[f * stride:(f + 1) * stride], n)
            if f == 0:
                uvs = None
                if item.get("uvs") is not None:
                    uvs = OV2fGeomParamSample(
                        _v2f(item["uvs"], corners), GeometryScope.kFacevaryingScope
                    )
                if normals is not None:
                    ns = ON3fGeomParamSample(
                        _v3f(normals[:nstride], corners), GeometryScope.kFacevaryingScope
                    )
                    sample = OPolyMeshSchemaSample(
                        p, indices, counts, uvs or OV2fGeomParamSample(), ns
                    )
                elif uvs is not None:
                    sample = OPolyMeshSchemaSample(p, indices, counts, uvs)
                else:
                    sample = OPolyMeshSchemaSample(p, indices, counts)
            else:
                sample = OPolyMeshSchemaSample(p)
                if normals is not None:
                    sample.setNormals(
                        ON3fGeomParamSample(
                            _v3f(normals[f * nstride:(f + 1) * nstride], corners),
                            GeometryScope.kFacevaryingScope,
                        )
                    )
            schema.set(sample)
    # The archive is finished when the function returns and its objects are released.
