"""springbake's Python package as a user's script uses it (issue 22 item 5).

Usage: python_package.py FOLDER
FOLDER holds scene.toml (its output: cli.glb, already baked by the CLI) and icosphere.glb.
Bakes the scene file and the same scene as a dict, with a progress callback; stops a bake
from the callback; provokes a BakeError; inspects the mesh; bakes FOLDER/field/scene.toml
(a plug-in's force field, called every substep) to python.glb. Prints one JSON line.
"""
import faulthandler
import json
import os
import sys

# A bake that hangs (it once did, with a plug-in's force field) fails instead of waiting for
# ever: the watchdog is a C thread, so it fires even while a call holds the interpreter.
faulthandler.dump_traceback_later(300, exit=True)

import numpy
import springbake

folder = sys.argv[1]
os.chdir(folder)
report = {"module": springbake.__file__, "version": springbake.__version__}

seen = []
result = springbake.bake("scene.toml", output="from_file.glb", progress=lambda d, t: seen.append((d, t)))
mesh = result["meshes"][0]
positions = mesh["positions"]
report["file"] = {
    "outputs": [os.path.basename(p) for p in result["outputs"]],
    "fps": result["fps"],
    "frame_count": result["frame_count"],
    "name": mesh["name"],
    "shape": list(positions.shape),
    "dtype": str(positions.dtype),
    "progress_calls": len(seen),
    "last_progress": list(seen[-1]) if seen else None,
    "report_frames": len(result["report"]["frames"]),
}
# The scene as a dict in the scene-file schema, relative paths from base_dir.
with open("scene.toml", "rb") as f:
    import tomllib

    scene = tomllib.load(f)
scene["output"]["path"] = "from_dict.glb"
os.chdir("/")
from_dict = springbake.bake(scene, base_dir=folder)
os.chdir(folder)
report["dict_outputs"] = [os.path.basename(p) for p in from_dict["outputs"]]
report["dict_positions_equal"] = bool(
    numpy.array_equal(from_dict["meshes"][0]["positions"], positions)
)
# Lowest point of the first frame and of all frames in the scene (metres, Y-up).
m = mesh["world_from_local"]
world = positions @ m[:3, :3].T + m[:3, 3]
report["lowest_first"] = float(world[0, :, 1].min() * result["meters_per_unit"])
report["lowest_ever"] = float(world[:, :, 1].min() * result["meters_per_unit"])


def stop_at_three(done, total):
    if done == 3:
        raise KeyError("stop at three")


try:
    springbake.bake("scene.toml", output="stopped.glb", progress=stop_at_three)
    report["stopped"] = "not raised"
except KeyError as e:
    report["stopped"] = str(e)
report["stopped_written"] = os.path.exists("stopped.glb")

try:
    springbake.bake({"output": {"pth": "x.glb"}}, base_dir=folder)
    report["bake_error"] = "not raised"
except springbake.BakeError as e:
    report["bake_error"] = str(e)

os.chdir(os.path.join(folder, "field"))
field = springbake.bake("scene.toml", output="python.glb")
report["field_frames"] = field["frame_count"]
os.chdir(folder)

info = springbake.inspect("icosphere.glb", cells=8)
report["inspect"] = {"format": info["format"], "vertices": info["meshes"][0]["vertices"],
                     "lattice_nodes": info["meshes"][0]["lattice"]["nodes"]}
faulthandler.cancel_dump_traceback_later()
print(json.dumps(report))
