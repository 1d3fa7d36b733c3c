"""The texture maps of each UsdPreviewSurface material of a stage: for every input of the
surface shader fed by a UsdUVTexture, the texture's file, whether it resolves, its colour
space, scale and bias. Prints one JSON line.

Usage: usd_material_maps.py STAGE
"""
import json
import sys

from pxr import Usd, UsdShade

stage = Usd.Stage.Open(sys.argv[1])
out = {}
for prim in stage.Traverse():
    if not prim.IsA(UsdShade.Material):
        continue
    surface = UsdShade.Material(prim).ComputeSurfaceSource()[0]
    maps = {}
    for shader_input in surface.GetInputs():
        source = shader_input.GetConnectedSource()
        if not source:
            continue
        texture = UsdShade.Shader(source[0].GetPrim())
        if texture.GetIdAttr().Get() != "UsdUVTexture":
            continue
        asset = texture.GetInput("file").Get()
        value = lambda name: texture.GetInput(name).Get() if texture.GetInput(name) else None
        maps[shader_input.GetBaseName()] = {
            "file": asset.path,
            "resolves": bool(asset.resolvedPath),
            "output": str(source[1]),
            "colour_space": value("sourceColorSpace"),
            "scale": list(value("scale")) if value("scale") is not None else None,
            "bias": list(value("bias")) if value("bias") is not None else None,
        }
    out[prim.GetName()] = maps
print(json.dumps(out))
