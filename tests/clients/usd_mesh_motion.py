"""Per mesh of a baked USD stage (instance proxies included): its points' time samples and
its lowest world z at the first and last sample. Prints one JSON line.

Usage: usd_mesh_motion.py STAGE
"""
import json
import sys

from pxr import Usd, UsdGeom

stage = Usd.Stage.Open(sys.argv[1])
meshes = {}
for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
    if not prim.IsA(UsdGeom.Mesh):
        continue
    mesh = UsdGeom.Mesh(prim)
    samples = mesh.GetPointsAttr().GetTimeSamples()
    row = {"samples": len(samples), "instance_proxy": prim.IsInstanceProxy()}
    if samples:
        world = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(samples[0])
        for key, t in (("lowest_first", samples[0]), ("lowest_last", samples[-1])):
            row[key] = min(world.Transform(p)[2] for p in mesh.GetPointsAttr().Get(t))
    meshes[str(prim.GetPath())] = row
print(json.dumps({"meshes": meshes}))
