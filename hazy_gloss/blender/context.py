# SPDX-License-Identifier: GPL-3.0-or-later
"""Which material the UI acts on, and why it cannot be edited (shared by operators, panels and
properties, so none of them imports another)."""
import bpy

from .. import constants as K
from . import material

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


def edit_problem(mat):
    """Why ``mat`` cannot be edited, in plain words, or None."""
    if mat is None:
        return "No material"
    lib = mat.library
    if lib is not None:
        return (f"“{mat.name}” is linked from the library file “{bpy.path.basename(lib.filepath)}” "
                f"and is read-only here. Edit it in that file, or make it local "
                f"(Object > Relations > Make Local) to change it in this one")
    if getattr(mat, "override_library", None) is not None:
        return (f"“{mat.name}” is a library override; its node tree cannot be rebuilt. "
                f"Make it local to edit it")
    if not material.is_hazy(mat):
        return f"“{mat.name}” is not a hazy material: use Make Hazy first"
    return None


def maps_problem(mat):
    """Why a material driven by converted maps cannot be edited from the panel, or None."""
    if mat is not None and K.MAPS_STAMP in mat:
        return (f"“{mat.name}” is driven by converted texture maps: convert the maps again "
                f"(Convert Maps) to change it")
    return None

