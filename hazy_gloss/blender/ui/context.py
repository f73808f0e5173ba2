# SPDX-License-Identifier: GPL-3.0-or-later
"""Which material the UI acts on (shared by operators, panels and properties, so none of them
imports another); why a material cannot be edited is material_read.edit_problem."""
import bpy


#: Where user presets live (AddPresetBase and the presets menu).
PRESET_SUBDIR = "hazy_gloss/material"


def target_material(context, name=""):
    """The named material, else the Properties editor's / Shader Editor's material, else the
    active object's active material."""
    if name:
        return bpy.data.materials.get(name)
    mat = getattr(context, "material", None)
    if mat is not None:
        return mat
    space = getattr(context, "space_data", None)
    if space is not None and getattr(space, "type", "") == "NODE_EDITOR" \
            and getattr(space, "tree_type", "") == "ShaderNodeTree":
        owner = getattr(space, "id", None)
        if isinstance(owner, bpy.types.Material):
            return owner
    obj = getattr(context, "object", None) or getattr(context, "active_object", None)
    return getattr(obj, "active_material", None) if obj is not None else None
