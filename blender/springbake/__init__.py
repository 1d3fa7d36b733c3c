"""springbake for Blender: bake the selected objects as soft bodies and play the result on them.

The extension is a thin host around the `springbake` command-line tool:

- `properties` owns the settings (`Object.springbake`, `Scene.springbake`, the preferences);
- `scene_writer` turns the Blender scene into a springbake scene folder (one OBJ per body in
  Blender's own vertex order, colliders, the manipulator's keys, `scene.toml`);
- `runner` runs the CLI as a background process with progress and cancellation;
- `cache` reads the PC2 files it writes, maps them into each object's local space and attaches
  them as a Mesh Cache modifier first in the stack (and removes it again);
- `operators` and `panels` are the user interface (`bpy.ops.springbake.bake()`,
  `bpy.ops.springbake.free_bake()`, Properties → Physics and the 3D view's sidebar).
"""

from . import operators, panels, properties

_modules = (properties, operators, panels)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
    operators.cancel_running_bakes()
