# SPDX-License-Identifier: GPL-3.0-or-later
"""Which material the UI acts on (shared by operators, panels and properties, so none of them
imports another); why a material cannot be edited is material_read.edit_problem."""
import bpy

__all__ = ("PRESET_SUBDIR", "foreign_tree", "target_material", "no_material")


#: Where user presets live (AddPresetBase and the presets menu).
PRESET_SUBDIR = "hazy_gloss/material"


def _shader_editor_owner(context):
    """The data-block whose shader tree the context's Shader Editor shows, else None."""
    space = getattr(context, "space_data", None)
    if space is not None and getattr(space, "type", "") == "NODE_EDITOR" \
            and getattr(space, "tree_type", "") == "ShaderNodeTree":
        return getattr(space, "id", None)
    return None


def foreign_tree(context):
    """One line when the Shader Editor shows a World's or a Light's nodes (the add-on's
    operators are for materials), else None."""
    owner = _shader_editor_owner(context)
    if owner is None or isinstance(owner, bpy.types.Material):
        return None
    what = "World" if isinstance(owner, bpy.types.World) else \
        "Light" if isinstance(owner, bpy.types.Light) else "Line Style"
    return (f"The Shader Editor shows the {what} “{owner.name}”: Hazy Gloss works on materials "
            f"(show a material's nodes)")


def target_material(context, name=""):
    """The named material, else the Properties editor's / Shader Editor's material, else the
    active object's active material; None when the Shader Editor shows a World's or a Light's
    nodes (acting on another material than the one in view would surprise)."""
    if name:
        return bpy.data.materials.get(name)
    mat = getattr(context, "material", None)
    if mat is not None:
        return mat
    owner = _shader_editor_owner(context)
    if isinstance(owner, bpy.types.Material):
        return owner
    if owner is not None:
        return None
    obj = getattr(context, "object", None) or getattr(context, "active_object", None)
    return getattr(obj, "active_material", None) if obj is not None else None


def no_material(context, name=""):
    """Why :func:`target_material` found nothing, in one line (the same words everywhere)."""
    if name:
        return f"No material named “{name}”"
    return foreign_tree(context) or "No active material"
