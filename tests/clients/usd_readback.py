"""Read a USD file with usd-core's own API and print what springbake's USD tests check, as one
JSON line: stage metadata, and per mesh prim its world matrix (column-vector convention,
row-major), topology sizes, the points time samples (times and values) and normals samples.

usage: usd_readback.py FILE
"""
import json
import sys

from pxr import Usd, UsdGeom


def main():
    path = sys.argv[1]
    stage = Usd.Stage.Open(path)
    out = {
        "up_axis": str(UsdGeom.GetStageUpAxis(stage)),
        "meters_per_unit": UsdGeom.GetStageMetersPerUnit(stage),
        "time_codes_per_second": stage.GetTimeCodesPerSecond(),
        "frames_per_second": stage.GetFramesPerSecond(),
        "start": stage.GetStartTimeCode(),
        "end": stage.GetEndTimeCode(),
        "meshes": {},
    }
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        points = mesh.GetPointsAttr()
        times = points.GetTimeSamples()
        normals = mesh.GetNormalsAttr()
        gf = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
        st = UsdGeom.PrimvarsAPI(prim).GetPrimvar("st")
        out["meshes"][str(prim.GetPath())] = {
            # transpose Gf's row-vector matrix into the column-vector convention
            "world": [gf[j][i] for i in range(4) for j in range(4)],
            "face_vertex_counts": list(mesh.GetFaceVertexCountsAttr().Get()),
            "face_vertex_index_count": len(mesh.GetFaceVertexIndicesAttr().Get()),
            "rest_points": [list(p) for p in points.Get(Usd.TimeCode.Default()) or []],
            "times": list(times),
            "points": [[list(p) for p in points.Get(t)] for t in times],
            "normal_times": list(normals.GetTimeSamples()),
            "normals_interpolation": str(mesh.GetNormalsInterpolation()),
            "normal_counts": [len(normals.Get(t)) for t in normals.GetTimeSamples()],
            "first_normals": [list(n) for n in (normals.Get(times[0]) if times and normals.GetTimeSamples() else [])],
            "has_primvar_normals": bool(UsdGeom.PrimvarsAPI(prim).GetPrimvar("normals")),
            "extent_times": list(mesh.GetExtentAttr().GetTimeSamples()),
            "st_count": len(st.Get()) if st and st.HasAuthoredValue() else 0,
            "st_interpolation": str(st.GetInterpolation()) if st else None,
        }
    print(json.dumps(out))


main()
