"""Checks USD files springbake wrote, as `usdchecker` would and for what DCC importers rely
on (issue 23 item 4). usd-core's wheel has no usdchecker script; its checks live in the
UsdValidation framework, which this runs in full (every registered validator).

Usage: python usd_check.py FILE.usda [FILE.usdc ...]
Prints one JSON line: {file: [problems]} (an empty list is a pass). Beyond the validators:
upAxis, metersPerUnit, timeCodesPerSecond, framesPerSecond, startTimeCode and endTimeCode
authored; one flat layer (no sublayers, references or payloads); every mesh with time-sampled
points has `subdivisionScheme = "none"` authored, an `extent` sample at each points sample
that is the points' bounds there (renderers cull by it), and normals either left out or sampled at the same times.
"""

import json
import sys

from pxr import Usd, UsdGeom, UsdValidation

validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()


def check(path):
    problems = []
    stage = Usd.Stage.Open(path)
    for error in UsdValidation.ValidationContext(validators).Validate(stage):
        problems.append("%s: %s" % (error.GetName(), error.GetMessage()))
    for key in ("upAxis", "metersPerUnit", "timeCodesPerSecond", "framesPerSecond",
                "startTimeCode", "endTimeCode"):
        if not stage.HasAuthoredMetadata(key):
            problems.append("stage metadata %s is not authored" % key)
    root = stage.GetRootLayer()
    if root.subLayerPaths:
        problems.append("sublayers: %s" % list(root.subLayerPaths))
    for prim in stage.Traverse():
        if prim.HasAuthoredReferences() or prim.HasAuthoredPayloads():
            problems.append("%s has a composition arc" % prim.GetPath())
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        times = mesh.GetPointsAttr().GetTimeSamples()
        if not times:
            continue
        where = str(prim.GetPath())
        scheme = mesh.GetSubdivisionSchemeAttr()
        if not scheme.HasAuthoredValue() or scheme.Get() != UsdGeom.Tokens.none:
            problems.append("%s: subdivisionScheme is not 'none'" % where)
        if mesh.GetExtentAttr().GetTimeSamples() != times:
            problems.append("%s: extent is not sampled with the points" % where)
        for t in times:
            want = UsdGeom.PointBased.ComputeExtent(mesh.GetPointsAttr().Get(t))
            got = mesh.GetExtentAttr().Get(t)
            if got is None or any(abs(g[k] - w[k]) > 1e-5 * (1 + abs(w[k]))
                                  for g, w in zip(got, want) for k in range(3)):
                problems.append("%s: extent at %g is %s, not the points' bounds %s"
                                % (where, t, got, want))
                break
        normals = mesh.GetNormalsAttr()
        if normals.HasAuthoredValue() and normals.GetTimeSamples() != times:
            problems.append("%s: normals are authored but not animated with the points" % where)
        if prim.HasAttribute("primvars:normals"):
            problems.append("%s: primvars:normals cannot follow the points" % where)
    return problems


print(json.dumps({path: check(path) for path in sys.argv[1:]}))
