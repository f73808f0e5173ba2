# SPDX-License-Identifier: GPL-3.0-or-later
"""Operators for editing haziness after the render (model/recomposite.py, paper §4.3)."""
import bpy
from bpy.props import BoolProperty, StringProperty

from ...core.parameters import check_value
from ...recomposite import LAYERS, passes_from_exr
from ..model import recomposite
from .properties import operator_property

__all__ = ("HAZY_GLOSS_OT_setup_recomposite", "HAZY_GLOSS_OT_clear_recomposite",
           "HAZY_GLOSS_OT_load_recomposite", "register", "unregister", "classes")


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
        template = context.view_layer if context.view_layer.name not in LAYERS else None
        try:
            report = recomposite.setup_recomposite(scene, template=template,
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
        recomposite.clear_recomposite(context.scene)
        return {"FINISHED"}


class HAZY_GLOSS_OT_load_recomposite(bpy.types.Operator):
    """Recomposite a saved multilayer EXR: the compositor reads it through Image nodes (no
    rendering needed)"""

    bl_idname = "hazy_gloss.load_recomposite"
    bl_label = "Recomposite EXR"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH")
    filter_glob: StringProperty(default="*.exr", options={"HIDDEN"})
    haziness: operator_property("haziness", 0.5)

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        try:
            check_value("haziness", self.haziness)  # (the slider's range only: a script's value)
            passes_from_exr(bpy.path.abspath(self.filepath))  # validates the file
        except (OSError, KeyError, ValueError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        recomposite.build_compositor(context.scene, source=self.filepath, haziness=self.haziness)
        return {"FINISHED"}


classes = (HAZY_GLOSS_OT_setup_recomposite, HAZY_GLOSS_OT_clear_recomposite,
           HAZY_GLOSS_OT_load_recomposite)

register, unregister = bpy.utils.register_classes_factory(classes)
