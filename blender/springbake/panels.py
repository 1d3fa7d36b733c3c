"""The panels: Properties → Physics (the active object's settings and the scene's) and the
3D view's sidebar (tab "springbake"), both drawing the same layout."""

import bpy

from . import operators


def draw_object_settings(layout, obj):
    s = obj.springbake
    layout.prop(s, "enabled")
    layout.prop(s, "collider")
    if s.collider:
        layout.label(text="Static surface: bodies collide with it", icon="MOD_PHYSICS")
        return
    col = layout.column()
    col.active = s.enabled
    col.prop(s, "material")
    if s.material == "custom":
        sub = col.column(align=True)
        sub.prop(s, "young")
        sub.prop(s, "density")
        sub.prop(s, "poisson")
        sub.prop(s, "damping")
    col.prop(s, "kind")
    col.prop(s, "cells")
    col.prop(s, "preserve_volume")
    col.prop(s, "velocity")


def draw_scene_settings(layout, context):
    scene = context.scene
    s = scene.springbake
    col = layout.column()
    col.label(
        text=f"Frames {scene.frame_start}–{scene.frame_end} at "
        f"{scene.render.fps / scene.render.fps_base:g} fps, gravity from the scene"
    )
    row = col.row(align=True)
    row.prop(s, "use_floor")
    sub = row.row()
    sub.active = s.use_floor
    sub.prop(s, "floor", text="Height")
    col.prop(s, "friction")
    col.prop(s, "manipulator")
    if s.manipulator is not None:
        sub = col.column(align=True)
        sub.prop(s, "manipulator_radius")
        sub.prop(s, "manipulator_length")
    col.prop(s, "cache_dir")
    col.prop(s, "binary")


def draw_bake_buttons(layout, context):
    s = context.scene.springbake
    if s.is_baking and operators.is_running():
        layout.prop(s, "progress", text="Baking", slider=True)
        layout.operator("springbake.cancel_bake", icon="CANCEL")
        return
    row = layout.row(align=True)
    row.scale_y = 1.4
    row.operator("springbake.bake", icon="PHYSICS")
    row.operator("springbake.free_bake", icon="TRASH")


class SPRINGBAKE_PT_physics(bpy.types.Panel):
    bl_label = "springbake"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "physics"

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == "MESH"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        draw_object_settings(layout, context.object)
        draw_bake_buttons(layout, context)


class SPRINGBAKE_PT_physics_scene(bpy.types.Panel):
    bl_label = "Scene"
    bl_parent_id = "SPRINGBAKE_PT_physics"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "physics"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        self.layout.use_property_split = True
        draw_scene_settings(self.layout, context)


class SPRINGBAKE_PT_sidebar(bpy.types.Panel):
    bl_label = "springbake"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "springbake"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        obj = context.object
        if obj is not None and obj.type == "MESH":
            draw_object_settings(layout, obj)
        else:
            layout.label(text="Select a mesh object")
        draw_bake_buttons(layout, context)
        box = layout.box()
        box.label(text="Scene")
        draw_scene_settings(box, context)


_classes = (SPRINGBAKE_PT_physics, SPRINGBAKE_PT_physics_scene, SPRINGBAKE_PT_sidebar)


register, unregister = bpy.utils.register_classes_factory(_classes)
