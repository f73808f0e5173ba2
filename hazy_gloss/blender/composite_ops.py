# SPDX-License-Identifier: GPL-3.0-or-later
"""Operators for editing haziness after the render (hazy_gloss/composite.py, paper §4.3)."""
import bpy
from bpy.props import BoolProperty, FloatProperty, StringProperty

from .. import composite


def _cycles(context):
    return context.scene is not None and context.scene.render.engine == "CYCLES"


class HAZY_GLOSS_OT_setup_recomposite(bpy.types.Operator):
    """Render the four radiance buffers and the β, r, p, mask AOVs of every hazy material, so
    haziness and core reflectivity can be edited in the compositor after the render"""

    bl_idname = "hazy_gloss.setup_recomposite"
    bl_label = "Set Up Haze Recomposite"
    bl_options = {"REGISTER", "UNDO"}

    holdout: BoolProperty(
        name="Hold Out Non-Hazy Objects", default=True,
        description="Hold out non-hazy objects in the four recomposite layers (camera rays only), "
        "so they are path traced once, in the original layer")
    compositor: BoolProperty(
        name="Add Compositor Nodes", default=True,
        description="Feed the 'Hazy Gloss Recomposite' group from Render Layers nodes")

    @classmethod
    def poll(cls, context):
        if not _cycles(context):
            cls.poll_message_set("The recomposite passes need Cycles")
            return False
        return True

    def execute(self, context):
        scene = context.scene
        template = context.view_layer if context.view_layer.name not in composite.LAYERS else None
        try:
            report = composite.setup_recomposite(scene, template=template,
                                                 holdout=self.holdout,
                                                 compositor=self.compositor)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for name, reason in report["skipped"].items():
            self.report({"WARNING"}, f"{name}: {reason}; rendered unchanged")
        for name, notes in report["notes"].items():
            for note in notes:
                self.report({"INFO"}, f"{name}: {note}")
        if not report["converted"]:
            self.report({"WARNING"}, "No hazy material in the scene")
        else:
            self.report({"INFO"}, f"{len(report['converted'])} hazy material(s) in recomposite mode; "
                        "render to a multilayer EXR")
        return {"FINISHED"}


class HAZY_GLOSS_OT_clear_recomposite(bpy.types.Operator):
    """Remove the recomposite view layers, material switches and compositor nodes"""

    bl_idname = "hazy_gloss.clear_recomposite"
    bl_label = "Clear Haze Recomposite"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        composite.clear_recomposite(context.scene)
        return {"FINISHED"}


class HAZY_GLOSS_OT_load_recomposite(bpy.types.Operator):
    """Recomposite a saved multilayer EXR: the compositor reads it through Image nodes (no
    rendering needed)"""

    bl_idname = "hazy_gloss.load_recomposite"
    bl_label = "Recomposite EXR"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH")
    filter_glob: StringProperty(default="*.exr", options={"HIDDEN"})
    haziness: FloatProperty(name="Haziness", default=0.5, min=0.0, max=0.9999, subtype="FACTOR")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        try:
            composite.passes_from_exr(bpy.path.abspath(self.filepath))  # validates the file
        except (OSError, KeyError, ValueError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        composite.build_compositor(context.scene, source=self.filepath, haziness=self.haziness)
        return {"FINISHED"}


def draw_operators(layout):
    col = layout.column(align=True)
    col.operator(HAZY_GLOSS_OT_setup_recomposite.bl_idname, icon="RENDERLAYERS")
    col.operator(HAZY_GLOSS_OT_load_recomposite.bl_idname, icon="NODE_COMPOSITING")
    col.operator(HAZY_GLOSS_OT_clear_recomposite.bl_idname, icon="X")


class HAZY_GLOSS_PT_recomposite(bpy.types.Panel):
    """Properties > View Layer: edit haziness after the render (paper §4.3)."""
    bl_idname = "HAZY_GLOSS_PT_recomposite"
    bl_label = "Hazy Gloss Recomposite"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "view_layer"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.render.engine == "CYCLES"

    def draw(self, context):
        draw_operators(self.layout)


class HAZY_GLOSS_MT_recomposite(bpy.types.Menu):
    """Render > Hazy Gloss Recomposite (also what F3 search finds)."""
    bl_idname = "HAZY_GLOSS_MT_recomposite"
    bl_label = "Hazy Gloss Recomposite"

    def draw(self, context):
        draw_operators(self.layout)


def draw_render_menu(self, context):
    self.layout.separator()
    self.layout.menu(HAZY_GLOSS_MT_recomposite.bl_idname)


classes = (HAZY_GLOSS_OT_setup_recomposite, HAZY_GLOSS_OT_clear_recomposite,
           HAZY_GLOSS_OT_load_recomposite, HAZY_GLOSS_PT_recomposite, HAZY_GLOSS_MT_recomposite)

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    _register_classes()
    bpy.types.TOPBAR_MT_render.append(draw_render_menu)


def unregister():
    bpy.types.TOPBAR_MT_render.remove(draw_render_menu)
    _unregister_classes()
