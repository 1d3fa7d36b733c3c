"""The extension's settings: per object (`Object.springbake`), per scene (`Scene.springbake`)
and the add-on preferences (where the `springbake` binary is).

Values are in SI units where they are physical (pascals, kg/m³, m/s); lengths the user sees in
the scene (floor height, capsule size) are in Blender units and converted with the scene's unit
scale when the bake is written.
"""

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

# Descriptions from the presets in springbake's core/src/material.rs.
MATERIAL_PRESETS = (
    ("jelly", "Jelly", "E 10 kPa, 1050 kg/m³: barely rebounds, wobbles"),
    ("soft_rubber", "Soft rubber", "E 0.3 MPa, 1100 kg/m³: a 1 m drop rebounds about 0.5 m"),
    ("rubber", "Rubber", "E 1.5 MPa, 1100 kg/m³: a 1 m drop rebounds about 0.45 m"),
    ("foam", "Foam", "E 50 kPa, 60 kg/m³: light and soft"),
    ("wood", "Wood", "E 10 GPa, 600 kg/m³: keeps its shape, bounces a little"),
    ("steel", "Steel", "E 201 GPa, 7850 kg/m³: keeps its shape, bounces"),
    ("custom", "Custom", "Young's modulus, density, Poisson's ratio and damping below"),
)


class SpringbakeObjectSettings(bpy.types.PropertyGroup):
    """What springbake does with one object."""

    enabled: BoolProperty(
        name="springbake body",
        description="Simulate this mesh as a springbake body when baking",
        default=False,
    )
    collider: BoolProperty(
        name="Collider",
        description="A static (passive) surface the bodies collide with",
        default=False,
    )
    material: EnumProperty(
        name="Material",
        description="Material preset, or Custom to give its constants",
        items=MATERIAL_PRESETS,
        default="rubber",
    )
    young: FloatProperty(
        name="Young's modulus",
        description="Stiffness, pascals",
        default=1.5e6,
        min=1.0,
        max=1.0e12,
        soft_min=100.0,
        precision=0,
    )
    density: FloatProperty(
        name="Density", description="kg/m³", default=1100.0, min=0.01, max=1.0e5
    )
    poisson: FloatProperty(
        name="Poisson's ratio",
        description="Lateral contraction under stretch: 0.5 keeps the volume",
        default=0.47,
        min=0.0,
        max=0.499,
    )
    damping: FloatProperty(
        name="Damping",
        description="Damping ratio of the body's wobble (1 = critical)",
        default=0.1,
        min=0.0,
        max=10.0,
    )
    cells: IntProperty(
        name="Cells",
        description="Lattice cells along the object's longest side: more is finer and slower",
        default=10,
        min=1,
        max=128,
    )
    kind: EnumProperty(
        name="Kind",
        items=(
            ("flexible", "Flexible", "Deforms: a soft body"),
            ("rigid", "Rigid", "Keeps its shape exactly, moves and rotates"),
        ),
        default="flexible",
    )
    preserve_volume: BoolProperty(
        name="Preserve volume",
        description="Hold the body's volume while it squashes",
        default=False,
    )
    velocity: FloatVectorProperty(
        name="Initial velocity",
        description="Velocity at the first frame, m/s in world axes",
        subtype="VELOCITY",
        size=3,
        default=(0.0, 0.0, 0.0),
    )


class SpringbakeSceneSettings(bpy.types.PropertyGroup):
    """Scene-wide bake settings; frame range, fps and gravity come from the Blender scene."""

    use_floor: BoolProperty(
        name="Floor", description="An infinite floor the bodies land on", default=True
    )
    floor: FloatProperty(
        name="Floor height",
        description="Height of the floor along Z, in scene units",
        default=0.0,
        subtype="DISTANCE",
    )
    friction: FloatProperty(
        name="Friction",
        description="Coulomb friction on the floor and colliders",
        default=0.4,
        min=0.0,
        max=10.0,
    )
    manipulator: PointerProperty(
        name="Manipulator",
        description="An animated object whose path drives the capsule manipulator",
        type=bpy.types.Object,
    )
    manipulator_radius: FloatProperty(
        name="Radius",
        description="Capsule radius, scene units",
        default=0.05,
        min=0.0001,
        subtype="DISTANCE",
    )
    manipulator_length: FloatProperty(
        name="Length",
        description="Capsule length between the cap centres, scene units (along its local X)",
        default=0.3,
        min=0.0,
        subtype="DISTANCE",
    )
    cache_dir: StringProperty(
        name="Cache folder",
        description="Where bakes are written ('//' is the .blend file's folder; an unsaved file "
        "uses a temporary folder)",
        default="//springbake_cache",
        subtype="DIR_PATH",
    )
    binary: StringProperty(
        name="springbake binary",
        description="Path of the springbake program for this scene; empty: the preferences' "
        "path, else 'springbake' on PATH",
        default="",
        subtype="FILE_PATH",
    )
    # Run state for the panels and the modal operator (set when a bake starts; the operators
    # trust their own running jobs, not these, after a file is reopened).
    is_baking: BoolProperty(default=False)
    progress: FloatProperty(default=0.0, min=0.0, max=1.0, subtype="FACTOR")
    cancel_requested: BoolProperty(default=False)


class SpringbakePreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    binary: StringProperty(
        name="springbake binary",
        description="Path of the springbake program; empty: 'springbake' on PATH",
        default="",
        subtype="FILE_PATH",
    )

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "binary")
        layout.label(text="Build it with `cargo build --release` (target/release/springbake).")


_classes = (SpringbakeObjectSettings, SpringbakeSceneSettings, SpringbakePreferences)


def preferences(context):
    """The add-on preferences, or None when the package is not registered as an add-on."""
    addon = context.preferences.addons.get(__package__)
    return addon.preferences if addon else None


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(_classes)


def register():
    _register_classes()
    bpy.types.Object.springbake = PointerProperty(type=SpringbakeObjectSettings)
    bpy.types.Scene.springbake = PointerProperty(type=SpringbakeSceneSettings)


def unregister():
    del bpy.types.Scene.springbake
    del bpy.types.Object.springbake
    _unregister_classes()
