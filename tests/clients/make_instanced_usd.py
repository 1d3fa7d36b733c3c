"""Writes a USD stage with native instances, a point instancer and an invisible mesh, as
usd-core (any DCC's USD export) authors them (issue 19 item 3).

Usage: make_instanced_usd.py OUT.usda
/World/Crate0 and /World/Crate1: instanceable internal references to the class /Proto (a
0.4 m box), at z = 1 and 1.5 (Z-up metres); /World/Scatter (moved 0.5 m along x): a
PointInstancer whose prototype /World/Scatter/Prototypes/Pebble (its root moved 0.1 m up) is
drawn only at its four points, the second turned 90° about z and scaled 0.5, the fourth
masked (invisibleIds); /World/Ghost: an invisible box at z = 2.
"""
import sys

from pxr import Gf, Usd, UsdGeom

out = sys.argv[1]
stage = Usd.Stage.CreateNew(out)
UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
UsdGeom.SetStageMetersPerUnit(stage, 1.0)
world = UsdGeom.Xform.Define(stage, "/World")
stage.SetDefaultPrim(world.GetPrim())
s = 0.2
POINTS = [(-s, -s, -s), (s, -s, -s), (s, s, -s), (-s, s, -s), (-s, -s, s), (s, -s, s), (s, s, s), (-s, s, s)]
FACES = [0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6, 3, 0, 4, 7]


def box(path):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(POINTS)
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr(FACES)
    mesh.CreateSubdivisionSchemeAttr("none")
    return mesh


stage.CreateClassPrim("/Proto")
box("/Proto/Box")
for i in range(2):
    crate = UsdGeom.Xform.Define(stage, "/World/Crate%d" % i)
    crate.AddTranslateOp().Set(Gf.Vec3d(-1.0 + 2.0 * i, 0, 1.0 + 0.5 * i))
    crate.GetPrim().GetReferences().AddInternalReference("/Proto")
    crate.GetPrim().SetInstanceable(True)
scatter = UsdGeom.PointInstancer.Define(stage, "/World/Scatter")
scatter.AddTranslateOp().Set(Gf.Vec3d(0.5, 0, 0))
pebble = box("/World/Scatter/Prototypes/Pebble")
pebble.AddTranslateOp().Set(Gf.Vec3d(0, 0, 0.1))
scatter.CreatePrototypesRel().SetTargets([pebble.GetPath()])
scatter.CreateProtoIndicesAttr([0, 0, 0, 0])
scatter.CreatePositionsAttr([(0, 3, 1), (0, 4, 1), (0, 5, 1), (0, 6, 1)])
turn = Gf.Rotation(Gf.Vec3d(0, 0, 1), 90).GetQuat()
scatter.CreateOrientationsAttr([Gf.Quath(1, 0, 0, 0), Gf.Quath(turn), Gf.Quath(1, 0, 0, 0), Gf.Quath(1, 0, 0, 0)])
scatter.CreateScalesAttr([(1, 1, 1), (0.5, 0.5, 0.5), (1, 1, 1), (1, 1, 1)])
scatter.CreateInvisibleIdsAttr([3])
ghost = UsdGeom.Xform.Define(stage, "/World/GhostXf")
ghost.AddTranslateOp().Set(Gf.Vec3d(0, -3, 2))
box("/World/GhostXf/Ghost")
UsdGeom.Imageable(ghost.GetPrim()).MakeInvisible()
stage.GetRootLayer().Save()
print("wrote", out)
