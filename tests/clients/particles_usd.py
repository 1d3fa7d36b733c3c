"""Reads springbake's particle effects back with usd-core: per Points prim, at each given time
code, the point count, the mean width and the mean displayOpacity.

Usage: python particles_usd.py STAGE.usda FRAME...
Prints one JSON line: {prim path: [[count, mean width, mean opacity] at each FRAME]}.
"""

import json
import sys

from pxr import Usd, UsdGeom

path, frames = sys.argv[1], [int(f) for f in sys.argv[2:]]
stage = Usd.Stage.Open(path)
out = {}
for prim in stage.Traverse():
    if not prim.IsA(UsdGeom.Points):
        continue
    points = UsdGeom.Points(prim)
    opacity = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayOpacity")
    rows = []
    for f in frames:
        t = Usd.TimeCode(f)
        pts = points.GetPointsAttr().Get(t) or []
        widths = points.GetWidthsAttr().Get(t) or []
        alphas = opacity.Get(t) or []
        n = len(pts)
        rows.append([
            n,
            sum(widths) / n if n else 0.0,
            sum(alphas) / n if n else 0.0,
            len(points.GetIdsAttr().Get(t) or []),
        ])
    out[str(prim.GetPath())] = rows
print(json.dumps(out))
