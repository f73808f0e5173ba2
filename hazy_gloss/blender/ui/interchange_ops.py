# SPDX-License-Identifier: GPL-3.0-or-later
"""The MaterialX / USD operators: File > Import and Export, the material context menu's export
fallback, and the USDHook that carries haze layers through Blender's own USD export and import
(thin: blender/actions/interchange.py, usd_hook.py and blender/model/fallback.py hold the
work)."""
import os

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ... import constants as K
from ...interchange import usd
from ..model import fallback, material_read
from ..actions import interchange, make_hazy, usd_hook
from .context import no_material, target_material
from ..actions.messages import plain_message
from .reports import report

__all__ = ("HAZY_GLOSS_OT_import_materialx", "HAZY_GLOSS_OT_export_materialx",
           "HAZY_GLOSS_OT_export_usd", "HAZY_GLOSS_OT_add_export_fallback",
           "HAZY_GLOSS_OT_remove_export_fallback", "HAZY_GLOSS_usd_hook", "draw_export_menu",
           "draw_import_menu", "draw_material_menu", "register", "unregister", "classes")


class HAZY_GLOSS_OT_import_materialx(bpy.types.Operator, ImportHelper):
    """Read materials from MaterialX (.mtlx) or USD: OpenPBR, Standard Surface, glTF PBR and
    UsdPreviewSurface surfaces become Principled BSDF materials (OpenPBR 1.2's haze a haze
    layer), two-lobe mixes hazy materials, with a report of what is not exact"""

    bl_idname = "hazy_gloss.import_materialx"
    bl_label = "Import Hazy Gloss MaterialX"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default="*.mtlx;*.usd;*.usda;*.usdc", options={"HIDDEN"})

    def execute(self, context):
        if os.path.splitext(self.filepath)[1].lower() in (".usd", ".usda", ".usdc") and not usd.available():
            report(self, "ERROR", usd.USD_MISSING)
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            res = interchange.import_materialx(
                self.filepath, progress=lambda f, msg: wm.progress_update(int(100 * f)),
                apply_haze=make_hazy.apply_imported_haze)
        except (ValueError, OSError, RuntimeError) as exc:
            report(self, "ERROR", plain_message(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        exact = sum(1 for im in res.report if im.material is not None and im.exact)
        report(self, "INFO", f"Imported {len(res)} material{'s' if len(res) != 1 else ''} "
               f"({exact} exact) of {len(res.report)} found")
        said = 0
        for im in res.report:
            if (im.notes or im.material is None) and said < 20:
                report(self, "WARNING", f"{im.name}: " + ("; ".join(im.notes) or "not imported"))
                said += 1
        if said < sum(1 for im in res.report if im.notes or im.material is None):
            report(self, "WARNING", "more notes in each material's hazy_gloss_import property")
        return {"FINISHED"} if res else {"CANCELLED"}


_SELECTION = [("ALL", "All Hazy Materials", "Every hazy material in the file"),
              ("SELECTED", "Selected Objects", "Hazy materials of the selected objects"),
              ("ACTIVE", "Active Material", "The active object's active material")]
_FLAVOURS = [("eq1", "Eq. 1 (MaterialX 1.39 pbr)", "Exact: a mix of two lobes with one Fresnel, "
              "standard library nodes only"),
             ("openpbr_1.2", "OpenPBR 1.2 (unreleased)", "open_pbr_surface 1.2 with specular_haze: "
              "approximate (its error is reported); the 1.2 nodedef is embedded")]


def _selected_materials(context, selection):
    if selection == "ALL":
        return None
    if selection == "ACTIVE":
        m = target_material(context)
        return [m] if m is not None else []
    mats = []
    for obj in getattr(context, "selected_objects", []) or []:
        for slot in getattr(obj, "material_slots", []):
            if slot.material is not None and slot.material not in mats:
                mats.append(slot.material)
    return mats


class _MaterialsExport(ExportHelper):
    """An export of the chosen hazy materials (``selection``): ``write(mats)`` writes them and
    returns how many it wrote, the file's path and the (level, message) pairs to report after
    the count."""
    bl_options = {"REGISTER"}
    write_errors = (ValueError, OSError)

    def unavailable(self):
        """Why the export cannot run here (None: it can)."""
        return None

    def execute(self, context):
        why = self.unavailable()
        if why:
            report(self, "ERROR", why)
            return {"CANCELLED"}
        mats = _selected_materials(context, self.selection)
        try:
            count, path, reports = self.write(mats)
        except self.write_errors as exc:
            report(self, "ERROR", plain_message(exc))
            return {"CANCELLED"}
        report(self, "INFO", f"Wrote {count} hazy material{'s' if count != 1 else ''} "
               f"to {bpy.path.basename(path)}")
        for level, text in reports:
            report(self, level, text)
        return {"FINISHED"}


def _notes_report(notes):
    """The report of what was not exact or skipped: the first six notes, on one line."""
    return [("WARNING", "; ".join(notes[:6]))] if notes else []


class HAZY_GLOSS_OT_export_materialx(_MaterialsExport, bpy.types.Operator):
    """Write hazy materials to a MaterialX document: each one an exact Eq. 1 graph (a mix of two
    microfacet lobes sharing one Fresnel) from the standard library"""

    bl_idname = "hazy_gloss.export_materialx"
    bl_label = "Export Hazy Gloss MaterialX"

    filename_ext = ".mtlx"
    filter_glob: StringProperty(default="*.mtlx", options={"HIDDEN"})
    selection: EnumProperty(name="Materials", items=_SELECTION, default="ALL")
    flavour: EnumProperty(name="Flavour", items=_FLAVOURS, default="eq1")
    validate: BoolProperty(name="Validate", default=True,
                           description="Validate with the materialx package when it is installed")

    def write(self, mats):
        rep = interchange.export_materialx(mats, self.filepath, self.flavour, validate=self.validate)
        reports = []
        if rep.validated is None and self.validate:
            reports.append(("WARNING", "Not validated: the materialx package is not installed "
                            "(pip install materialx); the file itself does not need it"))
        elif rep.validated is False:
            reports.append(("ERROR", f"MaterialX validation failed: {rep.validation}"))
        return (len(rep.materials), rep.path,
                reports + _notes_report(rep.notes + list(getattr(rep, "skipped", []))))


class HAZY_GLOSS_OT_export_usd(_MaterialsExport, bpy.types.Operator):
    """Write hazy materials to USD as MaterialX networks (UsdShade), with a UsdPreviewSurface of
    the core lobe (needs the pxr module: pip install usd-core)"""

    bl_idname = "hazy_gloss.export_usd"
    bl_label = "Export Hazy Gloss USD"
    write_errors = (ValueError, OSError, RuntimeError)

    filename_ext = ".usda"
    filter_glob: StringProperty(default="*.usd;*.usda;*.usdc", options={"HIDDEN"})
    selection: EnumProperty(name="Materials", items=_SELECTION, default="ALL")
    preview: BoolProperty(name="Preview Surface", default=True,
                          description="Add a UsdPreviewSurface of the core lobe")

    def unavailable(self):
        return None if usd.available() else usd.USD_MISSING

    def write(self, mats):
        path, done, skipped = interchange.export_usd(mats, self.filepath, preview=self.preview)
        return len(done), path, _notes_report(skipped)


class HAZY_GLOSS_OT_add_export_fallback(bpy.types.Operator):
    """Make Blender's glTF and USD exporters write the core lobe of this hazy material (its look
    at haziness 0) instead of nothing or the halo; renders are unchanged"""

    bl_idname = "hazy_gloss.add_export_fallback"
    bl_label = "Add Export Fallback (glTF / USD)"
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(name="Material", default="", options={"HIDDEN", "SKIP_SAVE"})
    all_materials: BoolProperty(name="All Hazy Materials", default=False, options={"SKIP_SAVE"},
                                description="Every hazy material of the file, not only this one")

    def execute(self, context):
        if self.all_materials:
            mats = [m for m in bpy.data.materials if material_read.is_hazy(m) and m.library is None
                    and K.RECOMPOSITE_STAMP not in m]
        else:
            mats = [target_material(context, self.material)]
            if mats[0] is None:
                report(self, "ERROR", no_material(context, self.material))
                return {"CANCELLED"}
        done, notes = [], []
        for mat in mats:
            try:
                notes += fallback.add_export_fallback(mat)
            except ValueError as exc:
                if not self.all_materials:
                    report(self, "ERROR", plain_message(exc))
                    return {"CANCELLED"}
                notes.append(plain_message(exc))
                continue
            done.append(mat.name)
        if not done:
            report(self, "ERROR", "No hazy material to give an export fallback")
            return {"CANCELLED"}
        report(self, "INFO", (f"“{done[0]}”" if len(done) == 1 else f"{len(done)} materials")
               + ": glTF and USD export now get the core lobe")
        if notes:
            report(self, "WARNING", "; ".join(sorted(set(notes))))
        return {"FINISHED"}


class HAZY_GLOSS_OT_remove_export_fallback(bpy.types.Operator):
    """Remove the export fallback nodes and make the previous output active again"""

    bl_idname = "hazy_gloss.remove_export_fallback"
    bl_label = "Remove Export Fallback"
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(name="Material", default="", options={"HIDDEN", "SKIP_SAVE"})

    def execute(self, context):
        mat = target_material(context, self.material)
        if mat is None or not fallback.remove_export_fallback(mat):
            report(self, "ERROR", "No export fallback to remove")
            return {"CANCELLED"}
        report(self, "INFO", f"“{mat.name}”: export fallback removed")
        return {"FINISHED"}


class HAZY_GLOSS_usd_hook(bpy.types.USDHook):
    """Haze layers through File > Export / Import > Universal Scene Description: each hazy
    material's exact network and haze values on the exported Material, and a hazy material
    back on import.  A failure leaves Blender's own result and says so in one line (an
    exception here would make Blender's export report an error)."""

    bl_idname = "hazy_gloss"
    bl_label = "Hazy Gloss"
    bl_description = "Carry haze layers through USD export and import"

    @staticmethod
    def on_material_export(export_context, bl_material, usd_material):
        try:
            notes = usd_hook.export_material(export_context.get_stage(), bl_material,
                                             usd_material, export_context.export_texture)
        except Exception as exc:  # noqa: BLE001 (see the class docstring)
            print(f"Hazy Gloss: “{bl_material.name}” is in the USD file without its haze: "
                  f"{plain_message(exc)}")
            return False
        if notes:
            print(f"Hazy Gloss: “{bl_material.name}” in USD: {'; '.join(notes)}")
        return notes is not None

    @staticmethod
    def material_import_poll(import_context, usd_material):
        try:
            return usd_hook.wants(usd_material)
        except Exception:  # noqa: BLE001 (Blender's importer reads it then)
            return False

    @staticmethod
    def on_material_import(import_context, bl_material, usd_material):
        try:
            notes = usd_hook.import_material(import_context.get_stage(), bl_material, usd_material)
        except Exception as exc:  # noqa: BLE001 (Blender then reads its preview surface)
            print(f"Hazy Gloss: {usd_material.GetPath()} is read without its haze layer (as "
                  f"Blender reads its preview surface): {plain_message(exc)}")
            return False
        if notes:
            print(f"Hazy Gloss: “{bl_material.name}” from USD: {'; '.join(notes)}")
        return True


# --------------------------------------------------------------------------------------------
# Menu entries (appended by menus.add_entries through menus.ENTRIES)
# --------------------------------------------------------------------------------------------


def draw_export_menu(self, context):
    self.layout.operator("hazy_gloss.export_materialx", text="Hazy Gloss MaterialX (.mtlx)")
    self.layout.operator("hazy_gloss.export_usd", text="Hazy Gloss USD (.usda)")


def draw_import_menu(self, context):
    self.layout.operator("hazy_gloss.import_materialx", text="Hazy Gloss MaterialX (.mtlx, .usd)")


def draw_material_menu(self, context):
    layout = self.layout
    layout.separator()
    layout.operator("hazy_gloss.add_export_fallback")
    layout.operator("hazy_gloss.add_export_fallback",
                    text="Add Export Fallback to All Hazy Materials").all_materials = True
    layout.operator("hazy_gloss.remove_export_fallback")
    op = layout.operator("hazy_gloss.export_materialx", text="Export Hazy Material (MaterialX)")
    op.selection = "ACTIVE"


classes = (HAZY_GLOSS_OT_export_materialx, HAZY_GLOSS_OT_export_usd,
           HAZY_GLOSS_OT_add_export_fallback, HAZY_GLOSS_OT_remove_export_fallback,
           HAZY_GLOSS_OT_import_materialx, HAZY_GLOSS_usd_hook)

register, unregister = bpy.utils.register_classes_factory(classes)
