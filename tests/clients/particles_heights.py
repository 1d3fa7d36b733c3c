"""The lowest particle over a square of the ground plan, per frame (issue 20: particles
bounce off colliders). Y-up stages.

Usage: python particles_heights.py STAGE.usda HALF_WIDTH FRAMES
Prints one JSON line: {prim path: [lowest y among the points with |x|, |z| < HALF_WIDTH, or
null, at each time code 0 .. FRAMES-1]}.
"""

import json
import sys

from pxr import Usd, UsdGeom

path, half, frames = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
stage = Usd.Stage.Open(path)
out = {}
for prim in stage.Traverse():
    if not prim.IsA(UsdGeom.Points):
        continue
    attr = UsdGeom.Points(prim).GetPointsAttr()
    rows = []
    for f in range(frames):
        inside = [p[1] for p in (attr.Get(f) or []) if abs(p[0]) < half and abs(p[2]) < half]
        rows.append(min(inside) if inside else None)
    out[str(prim.GetPath())] = rows
print(json.dumps(out))
