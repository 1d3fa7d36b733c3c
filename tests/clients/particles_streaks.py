"""Reads an emitter's streaks back with usd-core: at time code FRAME, the number of curve
segments of `<emitter>_streaks` and of points of `<emitter>`, and over the particles alive at
FRAME - 1 too (matched by id) the mean cosine between each streak (tail to head) and the
particle's travel since FRAME - 1, and the mean of the streak's length over that travel.

Usage: python particles_streaks.py STAGE.usda POINTS_PRIM FRAME
Prints one JSON line: {"segments", "points", "cosine", "length_ratio", "streak_prims"}.
"""

import json
import sys

from pxr import Usd, UsdGeom

path, prim_path, frame = sys.argv[1], sys.argv[2], int(sys.argv[3])
stage = Usd.Stage.Open(path)
points = UsdGeom.Points(stage.GetPrimAtPath(prim_path))
curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(prim_path + "_streaks"))
now, before = Usd.TimeCode(frame), Usd.TimeCode(frame - 1)
previous = dict(zip(points.GetIdsAttr().Get(before), points.GetPointsAttr().Get(before)))
ids = points.GetIdsAttr().Get(now)
ends = curves.GetPointsAttr().Get(now)
cosines, ratios = [], []
for i, pid in enumerate(ids):
    if pid not in previous:
        continue
    tail, head = ends[2 * i], ends[2 * i + 1]
    travel = head - previous[pid]
    streak = head - tail
    if travel.GetLength() > 1e-6:
        cosines.append(streak.GetDot(travel) / (streak.GetLength() * travel.GetLength()))
        ratios.append(streak.GetLength() / travel.GetLength())
streak_prims = sorted(
    str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves)
)
print(json.dumps({
    "segments": len(curves.GetCurveVertexCountsAttr().Get(now) or []),
    "points": len(ids),
    "cosine": sum(cosines) / len(cosines) if cosines else None,
    "length_ratio": sum(ratios) / len(ratios) if ratios else None,
    "streak_prims": streak_prims,
}))
