# SPDX-License-Identifier: GPL-3.0-or-later
"""The texture batch-conversion operator (the conversion itself is blender/actions/convert.py and
the convert_inputs, convert_outputs and convert_wiring modules it uses)."""
import os
import re
import tempfile
import time

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from ... import constants as K
from ...conversion import convert as conversion
from ...conversion.convert import ConversionError
from .. import compat
from ..actions.convert import convert_maps_steps
from ..actions.convert_pbr import convert_library_steps, convert_set_steps
from ..model.convert_wiring import wire_material
from .properties import operator_property

__all__ = ("ConversionJob", "HAZY_GLOSS_OT_convert_maps", "HAZY_GLOSS_OT_convert_pbr_set",
           "register", "unregister", "classes")

# --------------------------------------------------------------------------------------------
# Operator
# --------------------------------------------------------------------------------------------

#: (property stem, label, role) of the maps the operator offers.
_MAPS = (
    ("core_reflectivity", "Core Reflectivity", "colour"),
    ("edge_tint", "Edge Tint", "colour"),
    ("roughness", "Roughness", "data"),
    ("anisotropy", "Anisotropy", "data"),
    ("rotation", "Rotation", "data"),
    ("haziness", "Haziness", "data"),
    ("haze_extent", "Haze Extent", "data"),
    ("haze_extent_y", "Haze Extent Y", "data"),
)

#: What each kind's conversion writes (the labels are constants' vocabulary).
_KIND_MAPS = {"CONDUCTOR": "Metallic BSDF lobes, η and κ maps",
              "DIELECTRIC": "Principled BSDF lobes, η and specular tint maps",
              "LEGACY": "Glossy BSDF lobes (no Fresnel), weight maps"}
_KIND_ITEMS = [(t.id, t.label, _KIND_MAPS[t.id]) for t in K.KIND_TERMS]
_DIST_ITEMS = [(t.id, t.label, "") for t in K.DISTRIBUTION_TERMS]


def _fallback_dir(mat_name):
    """<temp>/hazy_gloss_maps/<material name as one safe folder name> (never '.', '..' or a
    hidden name: leading dots are dropped)."""
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", mat_name or "").lstrip(".") or "maps"
    base = os.path.join(tempfile.gettempdir(), "hazy_gloss_maps")
    return os.path.join(base, safe)


class ConversionJob:
    """A conversion generator run a slice at a time (the modal operator's timer events), with
    its conversion.Progress.  :meth:`cancel` is what Esc does: the conversion stops at its next strip
    and undoes itself (the output folder as it was)."""

    def __init__(self, steps, progress):
        self.steps, self.progress = steps, progress
        self.result = self.error = None
        self.finished = False

    def step(self, seconds=0.1):
        """Run for about ``seconds``; True once the conversion has ended (``result`` or
        ``error`` set)."""
        end = time.monotonic() + seconds
        try:
            while not self.finished:
                next(self.steps)
                if time.monotonic() >= end:
                    break
        except StopIteration as stop:
            self.result, self.finished = stop.value, True
        except Exception as exc:  # ConversionError and ConversionCancelled included
            self.error, self.finished = exc, True
        return self.finished

    def cancel(self):
        self.progress.cancel()

    def run(self):
        """To the end, blocking (background mode: no events)."""
        while not self.step(3600.0):
            pass
        return self


class _ModalConversion:
    """Asks for its options in a dialog, then runs a ConversionJob modally: Blender's progress
    bar, a status line (step or map, UDIM tile, set, percent, time left), Esc cancels (undone,
    nothing written).  In background mode (no window, no events) the job runs to its end at
    once."""

    _job = None
    _timer = None

    def invoke(self, context, event):
        """The options dialog first (OK runs execute)."""
        return context.window_manager.invoke_props_dialog(self, width=420)

    def start(self, context, job, finish):
        self._finish = finish
        self._job = job
        window = getattr(context, "window", None)
        if bpy.app.background or window is None:
            return self._end(context, job.run())
        wm = context.window_manager
        wm.progress_begin(0, 1000)
        self._timer = wm.event_timer_add(0.05, window=window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC" and event.value == "PRESS":
            job.cancel()
        elif event.type != "TIMER":
            return {"PASS_THROUGH"}
        job.step(0.15)
        context.window_manager.progress_update(int(1000 * job.progress.fraction))
        _status(context, job.progress.status())
        if not job.finished:
            return {"RUNNING_MODAL"}
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        _status(context, None)
        return self._end(context, job)

    def done(self, warnings, info):
        """The end of a conversion that went through: its warnings, then the result line."""
        for w in warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, info)
        return {"FINISHED"}

    def _end(self, context, job):
        if isinstance(job.error, conversion.ConversionCancelled):
            self.report({"WARNING"}, f"Hazy maps: {job.error}")
            return {"CANCELLED"}
        if job.error is not None:
            if not isinstance(job.error, ConversionError):
                raise job.error
            self.report({"ERROR"}, str(job.error))
            return {"CANCELLED"}
        try:
            return self._finish(context, job.result)
        except ConversionError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}


def _status(context, text):
    workspace = getattr(context, "workspace", None)
    if workspace is not None:
        try:
            workspace.status_text_set(text)
        except (AttributeError, RuntimeError, TypeError):
            pass


class HAZY_GLOSS_OT_convert_maps(_ModalConversion, bpy.types.Operator):
    """Convert perceptual hazy-gloss maps (haziness, haze extent, core reflectivity...) into
    physical maps and wire them into the active material's lean node tree"""

    bl_idname = "hazy_gloss.convert_maps"
    bl_label = "Convert Hazy Gloss Maps"
    bl_options = {"REGISTER", "UNDO"}

    kind: EnumProperty(name="Kind", items=_KIND_ITEMS, default="CONDUCTOR")
    distribution: EnumProperty(name="Distribution", items=_DIST_ITEMS, default="GGX")

    core_reflectivity_image: StringProperty(name="Core Reflectivity Map",
                                            description="Image datablock (colour, decoded to linear)")
    core_reflectivity_path: StringProperty(name="Core Reflectivity File", subtype="FILE_PATH")
    core_reflectivity: operator_property("core_reflectivity", (0.5, 0.5, 0.5))
    edge_tint_image: StringProperty(name="Edge Tint Map")
    edge_tint_path: StringProperty(name="Edge Tint File", subtype="FILE_PATH")
    edge_tint: operator_property("edge_tint", (0.0, 0.0, 0.0))
    roughness_image: StringProperty(name="Roughness Map", description="Non-Color map of R = √α")
    roughness_path: StringProperty(name="Roughness File", subtype="FILE_PATH")
    roughness: operator_property("roughness", 0.1)
    anisotropy_image: StringProperty(name="Anisotropy Map")
    anisotropy_path: StringProperty(name="Anisotropy File", subtype="FILE_PATH")
    anisotropy: operator_property("anisotropy", 0.0)
    rotation_image: StringProperty(name="Rotation Map")
    rotation_path: StringProperty(name="Rotation File", subtype="FILE_PATH")
    rotation: operator_property("rotation", 0.0)
    haziness_image: StringProperty(name="Haziness Map")
    haziness_path: StringProperty(name="Haziness File", subtype="FILE_PATH")
    haziness: operator_property("haziness", 0.5)
    haze_extent_image: StringProperty(name="Haze Extent Map", description="Both axes, or X")
    haze_extent_path: StringProperty(name="Haze Extent File", subtype="FILE_PATH")
    haze_extent: operator_property("haze_extent_x", 5.0)
    anisotropic_extent: BoolProperty(name="Separate Y Extent", default=False,
                                     description="Give the haze extent along Y separately")
    haze_extent_y_image: StringProperty(name="Haze Extent Y Map")
    haze_extent_y_path: StringProperty(name="Haze Extent Y File", subtype="FILE_PATH")
    haze_extent_y: operator_property("haze_extent_y", 5.0)
    use_smoothness: BoolProperty(name="Smooth Variation", default=False,
                                 description="Use the rational Bézier (Eqs. 12-15) instead of Eq. 7")
    smoothness: operator_property("smoothness", 2.0)
    base_color: operator_property("base_color", (0.0, 0.0, 0.0))
    transmission: operator_property("transmission", 0.0)

    directory: StringProperty(name="Output Folder", subtype="DIR_PATH", default="//hazy_maps/",
                              description="Where the physical maps are written ('//' = next to "
                                          "the .blend; an unsaved file uses a temp folder)")
    prefix: StringProperty(name="File Prefix", default="")
    file_format: EnumProperty(name="Format", default="OPEN_EXR", items=[
        ("OPEN_EXR", "OpenEXR (float)", "32-bit float, lossless ZIP"),
        ("PNG", "PNG 16-bit", "Unbounded maps stored with documented encodings")])
    resample: BoolProperty(name="Resample", default=False,
                           description="Resample maps of other sizes to the largest (bilinear)")
    wire: BoolProperty(name="Wire Into Active Material", default=True)
    interpolation: EnumProperty(name="Interpolation", default="Linear", items=[
        ("Linear", "Linear", ""), ("Closest", "Closest", ""), ("Cubic", "Cubic", "")])

    def _source(self, stem):
        name = getattr(self, stem + "_image")
        if name:
            img = bpy.data.images.get(name)
            if img is None:
                raise ConversionError(f"{stem}: no image datablock named {name!r}")
            return img
        path = getattr(self, stem + "_path")
        if path:
            return path
        return None

    def _inputs(self):
        inputs = {}
        for stem in ("core_reflectivity", "edge_tint", "roughness", "anisotropy", "rotation",
                     "haziness"):
            if stem == "edge_tint" and self.kind != "CONDUCTOR":
                continue
            src = self._source(stem)
            if src is None:
                value = getattr(self, stem)
                src = tuple(value) if stem in ("core_reflectivity", "edge_tint") else value
            inputs[stem] = src
        x = self._source("haze_extent")
        x = x if x is not None else self.haze_extent
        if self.anisotropic_extent:
            y = self._source("haze_extent_y")
            inputs["haze_extent_x"] = x
            inputs["haze_extent_y"] = y if y is not None else self.haze_extent_y
        else:
            inputs["haze_extent"] = x
        return inputs

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "kind")
        layout.prop(self, "distribution")
        for stem, label, _role in _MAPS:
            if stem == "edge_tint" and self.kind != "CONDUCTOR":
                continue
            if stem == "haze_extent_y":
                layout.prop(self, "anisotropic_extent")
                if not self.anisotropic_extent:
                    continue
            box = layout.box()
            box.label(text=label)
            box.prop_search(self, stem + "_image", bpy.data, "images", text="Image")
            box.prop(self, stem + "_path", text="File")
            if not getattr(self, stem + "_image") and not getattr(self, stem + "_path"):
                box.prop(self, stem, text="Constant")
        layout.prop(self, "use_smoothness")
        if self.use_smoothness:
            layout.prop(self, "smoothness")
        if self.kind == "DIELECTRIC":
            layout.prop(self, "base_color")
            layout.prop(self, "transmission")
        layout.separator()
        layout.prop(self, "directory")
        layout.prop(self, "prefix")
        layout.prop(self, "file_format")
        layout.prop(self, "resample")
        layout.prop(self, "wire")
        if self.wire:
            layout.prop(self, "interpolation")

    def execute(self, context):
        obj = getattr(context, "object", None)
        mat = obj.active_material if obj is not None else None
        if self.wire and mat is None:
            if obj is not None and hasattr(obj.data, "materials"):
                mat = compat.new_material("Hazy Maps")
                if obj.material_slots:
                    obj.active_material = mat
                else:
                    obj.data.materials.append(mat)
                self.report({"INFO"}, f"created material {mat.name!r} on {obj.name!r}")
            else:
                self.report({"WARNING"}, "no active object with materials: maps are written "
                                         "but not wired")
        directory = self.directory or "//hazy_maps/"
        if directory.startswith("//") and not bpy.data.filepath:
            directory = _fallback_dir(mat.name if mat else "maps")
            self.report({"WARNING"}, f"the .blend is not saved: maps go to {directory} "
                                     "(save the file or choose an output folder to keep them "
                                     "next to it)")
        try:
            inputs = self._inputs()
            prog = conversion.Progress()
            steps = convert_maps_steps(
                inputs, directory, kind=self.kind, distribution=self.distribution,
                smoothness=self.smoothness if self.use_smoothness else None,
                file_format=self.file_format, resample=self.resample, prefix=self.prefix,
                progress=prog)
        except ConversionError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        wire = self.wire and mat is not None
        settings = dict(interpolation=self.interpolation, base_color=tuple(self.base_color),
                        transmission=self.transmission)

        def finish(context, result):
            if wire:
                wire_material(mat, result, **settings)
            return self.done(result.report.warnings,
                             f"Hazy maps: {result.report.summary(len(result))} -> "
                             f"{os.path.dirname(next(iter(result.values())))}")

        return self.start(context, ConversionJob(steps, prog), finish)




# --------------------------------------------------------------------------------------------
# PBR texture sets
# --------------------------------------------------------------------------------------------

#: (map, label) of the PBR set operator's file inputs.
_PBR_FILES = (("base_color", "Base Color"), ("metallic", "Metallic"), ("roughness", "Roughness"),
              ("normal", "Normal (OpenGL)"), ("coat", "Coat"), ("alpha", "Opacity"),
              ("haziness", "Haziness"))


class HAZY_GLOSS_OT_convert_pbr_set(_ModalConversion, bpy.types.Operator):
    """Turn a PBR texture set (base colour, metallic, roughness, normal, ... as texture
    libraries ship them) into a Principled material with a haze layer baked into maps; with
    Batch, every subfolder of the folder is a set and becomes a material"""

    bl_idname = "hazy_gloss.convert_pbr_set"
    bl_label = "Convert PBR Texture Set"
    bl_options = {"REGISTER", "UNDO"}

    folder: StringProperty(name="Set Folder", subtype="DIR_PATH",
                           description="The folder of the set: its maps are found by their names "
                                       "(BaseColor / Albedo / diff, Metallic, Roughness, NormalGL...)")
    batch: BoolProperty(name="Batch: One Set per Subfolder", default=False)
    base_color_path: StringProperty(name="Base Color", subtype="FILE_PATH")
    metallic_path: StringProperty(name="Metallic", subtype="FILE_PATH")
    roughness_path: StringProperty(name="Roughness", subtype="FILE_PATH")
    normal_path: StringProperty(name="Normal", subtype="FILE_PATH")
    coat_path: StringProperty(name="Coat", subtype="FILE_PATH")
    alpha_path: StringProperty(name="Opacity", subtype="FILE_PATH")
    haziness_path: StringProperty(name="Haziness Map", subtype="FILE_PATH")
    haziness: operator_property("haziness", 0.1)
    haze_extent: operator_property("haze_extent_x", 5.0)
    coat_haziness: operator_property("coat_haziness", 0.0)
    coat_haze_extent: operator_property("coat_haze_extent", 5.0)
    into_active: BoolProperty(name="Into the Active Material", default=False,
                              description="Put the set into the active material's Principled BSDF "
                                          "(its empty inputs) instead of a new material")
    directory: StringProperty(name="Output Folder", subtype="DIR_PATH", default="//hazy_maps/")
    interpolation: EnumProperty(name="Interpolation", default="Linear", items=[
        ("Linear", "Linear", ""), ("Closest", "Closest", ""), ("Cubic", "Cubic", "")])

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "folder")
        layout.prop(self, "batch")
        if not self.batch:
            box = layout.box()
            box.label(text="Maps (override what the folder gives)")
            for stem, label in _PBR_FILES:
                box.prop(self, stem + "_path", text=label)
            layout.prop(self, "into_active")
        layout.prop(self, "haziness")
        layout.prop(self, "haze_extent")
        layout.prop(self, "coat_haziness")
        layout.prop(self, "coat_haze_extent")
        layout.prop(self, "directory")
        layout.prop(self, "interpolation")

    def _haze(self):
        return dict(haziness=self.haziness, haze_extent=self.haze_extent,
                    coat_haziness=self.coat_haziness, coat_haze_extent=self.coat_haze_extent)

    def execute(self, context):
        folder = bpy.path.abspath(self.folder) if self.folder else ""
        directory = self.directory or "//hazy_maps/"
        if directory.startswith("//") and not bpy.data.filepath:
            directory = _fallback_dir(os.path.basename(os.path.normpath(folder)) or "pbr")
            self.report({"WARNING"}, f"the .blend is not saved: maps go to {directory}")
        out_dir = bpy.path.abspath(directory)
        obj = getattr(context, "object", None)
        prog = conversion.Progress()
        if self.batch:
            if not folder or not os.path.isdir(folder):
                self.report({"ERROR"}, "Batch needs a folder whose subfolders are the sets")
                return {"CANCELLED"}
            steps = convert_library_steps(folder, out_dir, haze=self._haze(),
                                          interpolation=self.interpolation, progress=prog)

            def finish_batch(context, report):
                for name, why in report.failed:
                    self.report({"WARNING"}, f"{name}: {why}")
                level = {"INFO"} if report.done else {"ERROR"}  # no set converted: it failed
                self.report(level, f"Hazy maps: {report.summary()}"
                            + (f": {', '.join(r.material.name for _, r in report.done)}"
                               if report.done else ""))
                return {"FINISHED"} if report.done else {"CANCELLED"}

            return self.start(context, ConversionJob(steps, prog), finish_batch)
        overrides = {stem: bpy.path.abspath(getattr(self, stem + "_path"))
                     for stem, _ in _PBR_FILES if getattr(self, stem + "_path")}
        target = obj.active_material if (self.into_active and obj is not None) else None
        if self.into_active and target is None:
            self.report({"ERROR"}, "Into the Active Material: the active object has no material")
            return {"CANCELLED"}
        if not folder and not overrides:
            self.report({"ERROR"}, "give the set's folder or its maps")
            return {"CANCELLED"}
        steps = convert_set_steps(folder, out_dir, haze=self._haze(), material=target,
                                  name=os.path.basename(os.path.normpath(folder)) or None,
                                  overrides=overrides, interpolation=self.interpolation,
                                  progress=prog)

        def finish(context, res):
            mat = res.material
            if target is None and obj is not None and hasattr(obj.data, "materials") \
                    and obj.library is None:
                if obj.material_slots:
                    obj.active_material = mat
                else:
                    obj.data.materials.append(mat)
            return self.done(res.report.warnings, f"“{mat.name}”: a Principled BSDF with the set "
                                                  f"and a baked haze layer ({len(res)} maps in "
                                                  f"{out_dir})")

        return self.start(context, ConversionJob(steps, prog), finish)


classes = (HAZY_GLOSS_OT_convert_maps, HAZY_GLOSS_OT_convert_pbr_set)

register, unregister = bpy.utils.register_classes_factory(classes)
