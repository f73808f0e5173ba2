# SPDX-License-Identifier: GPL-3.0-or-later
"""File > Import > Hazy Gloss MaterialX: a thin operator over api.import_materialx (the API
makes the haze layers of imported materials; blender/interchange.py holds the work)."""
import os

import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ImportHelper

from .. import api
from ..interchange import usd
from .messages import plain_message
from .reports import report


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
            res = api.import_materialx(self.filepath, progress=lambda f, msg: wm.progress_update(int(100 * f)))
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


classes = (HAZY_GLOSS_OT_import_materialx,)

register, unregister = bpy.utils.register_classes_factory(classes)
