# SPDX-License-Identifier: GPL-3.0-or-later
"""Every difference between Blender 4.5 LTS and 5.0 that the add-on meets, in one place."""
import bpy

VERSION = bpy.app.version


def eevee_engine_id():
    """5.0 accepts only BLENDER_EEVEE; 4.2-4.5 call the new EEVEE BLENDER_EEVEE_NEXT."""
    items = bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items.keys()
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in items else "BLENDER_EEVEE"


def new_material(name):
    """A material with a node tree (use_nodes is deprecated in 5.0, required in 4.x)."""
    mat = bpy.data.materials.new(name)
    if VERSION < (5, 0, 0):
        mat.use_nodes = True
    return mat


def exact_conductor_fresnel():
    """Metallic BSDF PHYSICAL_CONDUCTOR is the exact conductor Fresnel from 5.0 on; 4.5 uses an
    approximation exact only at normal incidence (BLENDER-FACTS.md)."""
    return VERSION >= (5, 0, 0)


def shader_add_menu():
    """The menu whose contents the Shader Editor's Add menu (Shift+A) draws.

    4.5 and 5.0 both define ``NODE_MT_shader_node_add_all`` (``NODE_MT_add`` draws it with
    ``menu_contents`` when the edited tree is a shader tree; 5.0 generates it from a base class).
    Older or future versions without it fall back to ``NODE_MT_add``, which is shared by all node
    editors: draw functions appended to it must check ``space_data.tree_type`` themselves."""
    menu = getattr(bpy.types, "NODE_MT_shader_node_add_all", None)
    return menu if menu is not None else bpy.types.NODE_MT_add
