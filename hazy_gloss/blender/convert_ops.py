# SPDX-License-Identifier: GPL-3.0-or-later
"""The texture batch-conversion operator (the conversion itself is blender/convert.py)."""
import os
import re
import tempfile

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       StringProperty)

from .. import constants as K
from ..convert import ConversionError
from . import compat
from .convert import convert_maps, wire_material

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

_KIND_ITEMS = [("CONDUCTOR", "Conductor", "Metallic BSDF lobes, η and κ maps"),
               ("DIELECTRIC", "Dielectric", "Principled BSDF lobes, η and specular tint maps"),
               ("LEGACY", "Legacy", "Glossy BSDF lobes (no Fresnel), weight maps")]
_DIST_ITEMS = [("GGX", "GGX", ""), ("BECKMANN", "Beckmann", ""),
               ("MULTI_GGX", "Multiscatter GGX", ""), ("ASHIKHMIN_SHIRLEY", "Ashikhmin-Shirley", "")]


def _fallback_dir(mat_name):
    """<temp>/hazy_gloss_maps/<material name as one safe folder name> (never '.', '..' or a
    hidden name: leading dots are dropped)."""
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", mat_name or "").lstrip(".") or "maps"
    base = os.path.join(tempfile.gettempdir(), "hazy_gloss_maps")
    return os.path.join(base, safe)


class HAZY_GLOSS_OT_convert_maps(bpy.types.Operator):
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
    core_reflectivity: FloatVectorProperty(name="Core Reflectivity", subtype="COLOR", size=3,
                                           min=0.0, max=1.0, default=(0.5, 0.5, 0.5))
    edge_tint_image: StringProperty(name="Edge Tint Map")
    edge_tint_path: StringProperty(name="Edge Tint File", subtype="FILE_PATH")
    edge_tint: FloatVectorProperty(name="Edge Tint", subtype="COLOR", size=3, min=0.0, max=1.0,
                                   default=(0.0, 0.0, 0.0))
    roughness_image: StringProperty(name="Roughness Map", description="Non-Color map of R = √α")
    roughness_path: StringProperty(name="Roughness File", subtype="FILE_PATH")
    roughness: FloatProperty(name="Roughness", min=0.0, max=1.0, default=0.1, subtype="FACTOR")
    anisotropy_image: StringProperty(name="Anisotropy Map")
    anisotropy_path: StringProperty(name="Anisotropy File", subtype="FILE_PATH")
    anisotropy: FloatProperty(name="Anisotropy", min=0.0, max=1.0, default=0.0, subtype="FACTOR")
    rotation_image: StringProperty(name="Rotation Map")
    rotation_path: StringProperty(name="Rotation File", subtype="FILE_PATH")
    rotation: FloatProperty(name="Rotation", default=0.0)
    haziness_image: StringProperty(name="Haziness Map")
    haziness_path: StringProperty(name="Haziness File", subtype="FILE_PATH")
    haziness: FloatProperty(name="Haziness", min=0.0, max=K.MAX_HAZINESS, default=0.5, subtype="FACTOR")
    haze_extent_image: StringProperty(name="Haze Extent Map", description="Both axes, or X")
    haze_extent_path: StringProperty(name="Haze Extent File", subtype="FILE_PATH")
    haze_extent: FloatProperty(name="Haze Extent", min=0.0, default=5.0)
    anisotropic_extent: BoolProperty(name="Separate Y Extent", default=False,
                                     description="Give the haze extent along Y separately")
    haze_extent_y_image: StringProperty(name="Haze Extent Y Map")
    haze_extent_y_path: StringProperty(name="Haze Extent Y File", subtype="FILE_PATH")
    haze_extent_y: FloatProperty(name="Haze Extent Y", min=0.0, default=5.0)
    use_smoothness: BoolProperty(name="Smooth Variation", default=False,
                                 description="Use the rational Bézier (Eqs. 12-15) instead of Eq. 7")
    smoothness: FloatProperty(name="Smoothness", min=K.MIN_SMOOTHNESS, default=2.0)
    base_color: FloatVectorProperty(name="Base Color", subtype="COLOR", size=3, min=0.0, max=1.0,
                                    default=(0.0, 0.0, 0.0))
    transmission: FloatProperty(name="Transmission", min=0.0, max=1.0, default=0.0)

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

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=420)

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
        wm = context.window_manager
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
        begun = False
        try:
            wm.progress_begin(0, 100)
            begun = True
        except (RuntimeError, AttributeError):
            pass

        def progress(done, total, _message):
            if begun:
                wm.progress_update(int(100 * done / max(total, 1)))

        try:
            inputs = self._inputs()
            result = convert_maps(
                inputs, directory, kind=self.kind, distribution=self.distribution,
                smoothness=self.smoothness if self.use_smoothness else None,
                file_format=self.file_format, resample=self.resample, prefix=self.prefix,
                progress=progress)
            if self.wire and mat is not None:
                wire_material(mat, result, interpolation=self.interpolation,
                              base_color=tuple(self.base_color), transmission=self.transmission)
        except ConversionError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            if begun:
                wm.progress_end()
        for w in result.report.warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"Hazy maps: {result.report.summary(len(result))} -> "
                              f"{os.path.dirname(next(iter(result.values())))}")
        return {"FINISHED"}


classes = (HAZY_GLOSS_OT_convert_maps,)

register, unregister = bpy.utils.register_classes_factory(classes)
