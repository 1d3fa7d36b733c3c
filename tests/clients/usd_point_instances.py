"""Where a source stage's PointInstancer draws its prototype's points (usd-core's own
instance transforms, mask applied) against the realised copies in a baked stage at its first
time sample: per instance, the largest distance between the two point sets. Prints one JSON
line: {"instancer_visible": bool, "copies": {path: {"exists", "error" (m), "centre",
"visible", "samples"}}, "masked_copies": [paths of copies of a masked instance]}.

Usage: usd_point_instances.py SOURCE INSTANCER PROTOTYPE_MESH BAKED
"""
import json
import sys

from pxr import Usd, UsdGeom

source_path, instancer_path, mesh_path, baked_path = sys.argv[1:5]
source = Usd.Stage.Open(source_path)
instancer = UsdGeom.PointInstancer(source.GetPrimAtPath(instancer_path))
mesh = source.GetPrimAtPath(mesh_path)
t = Usd.TimeCode.Default()
root = mesh  # the test's prototype root is the mesh itself
inside = UsdGeom.Xformable(mesh).ComputeLocalToWorldTransform(t) * UsdGeom.Xformable(
    root
).ComputeLocalToWorldTransform(t).GetInverse()
xforms = instancer.ComputeInstanceTransformsAtTime(t, t)
mask = instancer.ComputeMaskAtTime(t) or [True] * len(xforms)
world = UsdGeom.Xformable(instancer.GetPrim()).ComputeLocalToWorldTransform(t)
points = UsdGeom.Mesh(mesh).GetPointsAttr().Get(t)

baked = Usd.Stage.Open(baked_path)
group = instancer.GetPrim().GetParent().GetPath().AppendChild(instancer.GetPrim().GetName() + "_instances")
copies = {}
for i, m in enumerate(mask):
    if not m:
        continue
    expected = [(inside * xforms[i] * world).Transform(p) for p in points]
    prim = baked.GetPrimAtPath(group.AppendChild("%s_%d" % (mesh.GetName(), i)))
    row = {"exists": bool(prim)}
    if prim:
        copy = UsdGeom.Mesh(prim)
        first = copy.GetPointsAttr().GetTimeSamples()[0]
        to_world = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(first)
        got = [to_world.Transform(p) for p in copy.GetPointsAttr().Get(first)]
        row["error"] = max((a - b).GetLength() for a, b in zip(expected, got))
        row["centre"] = [sum(p[k] for p in got) / len(got) for k in range(3)]
        row["visible"] = UsdGeom.Imageable(prim).ComputeVisibility(t) != UsdGeom.Tokens.invisible
        row["samples"] = len(copy.GetPointsAttr().GetTimeSamples())
    copies[str(prim.GetPath()) if prim else str(i)] = row
masked = [str(p.GetPath()) for p in baked.Traverse() if p.GetName().endswith("_3")]
visible = UsdGeom.Imageable(baked.GetPrimAtPath(instancer_path)).ComputeVisibility(t)
print(json.dumps({
    "instancer_visible": visible != UsdGeom.Tokens.invisible,
    "copies": copies,
    "masked_copies": masked,
}))
