"""Print, as one JSON line, every mesh prim's points in world space computed by usd-core
(`ComputeLocalToWorldTransform` applied with Gf's own row-vector convention), plus the stage's
up axis and metersPerUnit. springbake's importer must agree.

usage: usd_world_points.py FILE
"""
import json
import sys

from pxr import Usd, UsdGeom


def main():
    stage = Usd.Stage.Open(sys.argv[1])
    meshes = {}
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        m = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
        pts = UsdGeom.Mesh(prim).GetPointsAttr().Get()
        meshes[str(prim.GetPath())] = [list(m.Transform(p)) for p in pts]
    print(json.dumps({
        "up_axis": str(UsdGeom.GetStageUpAxis(stage)),
        "meters_per_unit": UsdGeom.GetStageMetersPerUnit(stage),
        "meshes": meshes,
    }))


main()
