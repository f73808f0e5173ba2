# SPDX-License-Identifier: GPL-3.0-or-later
"""Every difference between Blender 4.5 LTS, 5.2 LTS and 5.3 that the add-on meets, in one place.

Features are detected from RNA where Blender offers that (no property is read just to see
whether it exists: reading a deprecated property warns), versions where behaviour changed
without an API change.  docs/blender-versions.md lists what changed and when.
"""
import os
import sys

import bpy

__all__ = ("VERSION", "ADDON_PACKAGE", "PACKAGE_DIR", "new_material", "shader_add_menu",
           "COMPOSITOR_EFFECT", "compositor_uses_groups", "compositor_math_node", "compositor_tree",
           "compositor_output", "animated_paths", "slot_fcurves", "use_blenders_pxr")

VERSION = bpy.app.version

#: The add-on's package (``bl_ext.<repo>.hazy_gloss`` as an extension; preferences are stored
#: under it) and its folder, from this module's place: hazy_gloss/blender/compat.py.
ADDON_PACKAGE = __package__.rpartition(".")[0]
PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

_SCENE_PROPS = bpy.types.Scene.bl_rna.properties


def new_material(name):
    """A material with a node tree (use_nodes is deprecated in 5.0, required in 4.x)."""
    mat = bpy.data.materials.new(name)
    if VERSION < (5, 0, 0):
        mat.use_nodes = True
    return mat


def shader_add_menu():
    """The menu whose contents the Shader Editor's Add menu (Shift+A) draws.

    4.5 and 5.x define ``NODE_MT_shader_node_add_all`` (``NODE_MT_add`` draws it with
    ``menu_contents`` when the edited tree is a shader tree).  Versions without it fall back to
    ``NODE_MT_add``, which is shared by all node editors: draw functions appended to it must
    check ``space_data.tree_type`` themselves."""
    menu = getattr(bpy.types, "NODE_MT_shader_node_add_all", None)
    return menu if menu is not None else bpy.types.NODE_MT_add


# --------------------------------------------------------------------------------------------
# Compositor
#   4.5:      the scene owns ``scene.node_tree`` (``scene.use_nodes``); output = Composite node;
#             math = CompositorNodeMath.
#   5.0-5.2:  a CompositorNodeTree group in ``scene.compositing_node_group``; output = its Group
#             Output; math = ShaderNodeMath (CompositorNodeMath and Composite are gone).
#   5.3:      ``scene.compositing_node_group`` is deprecated (removal in 6.0); the scene holds a
#             stack ``scene.compositor_effects`` whose effects each have a ``node_group``.
# --------------------------------------------------------------------------------------------

COMPOSITOR_EFFECT = "Hazy Gloss"


def compositor_uses_groups():
    """5.0+: compositor trees are node groups with a Group Output."""
    return "compositor_effects" in _SCENE_PROPS or "compositing_node_group" in _SCENE_PROPS


def compositor_math_node():
    return "ShaderNodeMath" if compositor_uses_groups() else "CompositorNodeMath"


def _effect(scene, create):
    effects = scene.compositor_effects
    eff = effects.active
    if eff is None:
        eff = next(iter(effects), None)
    if eff is None and create:
        eff = effects.new(name=COMPOSITOR_EFFECT)
    return eff


def compositor_tree(scene, create=True):
    """The scene's compositor tree (created and enabled when ``create``), or None."""
    if "compositor_effects" in _SCENE_PROPS:
        eff = _effect(scene, create)
        if eff is None:
            return None
        if eff.node_group is None and create:
            eff.node_group = _new_compositor_group(scene)
        return eff.node_group
    if "compositing_node_group" in _SCENE_PROPS:
        tree = scene.compositing_node_group
        if tree is None and create:
            tree = _new_compositor_group(scene)
            scene.compositing_node_group = tree
        return tree
    if create:
        scene.use_nodes = True
    return scene.node_tree


def _new_compositor_group(scene):
    tree = bpy.data.node_groups.new(f"{scene.name} Compositing", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    return tree


def compositor_output(tree, name, location=(900, 0)):
    """The input socket that is the compositor's result (created, named ``name``, if missing)."""
    if compositor_uses_groups():
        if not any(i.in_out == "OUTPUT" for i in tree.interface.items_tree
                   if getattr(i, "item_type", "SOCKET") == "SOCKET"):
            tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        out = next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"), None)
        if out is None:
            out = tree.nodes.new("NodeGroupOutput")
            out.name = name
            out.location = location
        return out.inputs[0]
    out = next((n for n in tree.nodes if n.bl_idname == "CompositorNodeComposite"), None)
    if out is None:
        out = tree.nodes.new("CompositorNodeComposite")
        out.name = name
        out.location = location
    return out.inputs["Image"]


def animated_paths(idblock):
    """The data paths of ``idblock`` driven by drivers or keyframes."""
    anim = getattr(idblock, "animation_data", None)
    if anim is None:
        return set()
    paths = {fc.data_path for fc in anim.drivers}
    return paths | {fc.data_path for fc in slot_fcurves(anim.action, anim)}


def slot_fcurves(action, owner):
    """The F-curves of ``action`` that animate ``owner`` (an AnimData or an NLA strip): in the
    slotted actions of 4.4+ (where ``Action.fcurves`` is gone or only the first slot's) the
    channelbag of ``owner.action_slot`` alone; an action can hold other IDs' slots."""
    if action is None:
        return []
    layers = getattr(action, "layers", None)
    if layers is None:  # (before 4.4: one ID per action)
        return list(action.fcurves)
    slot = getattr(owner, "action_slot", None)
    if slot is None:
        return []
    return [fc for layer in layers for strip in layer.strips
            for bag in [strip.channelbag(slot)] if bag is not None for fc in bag.fcurves]


def use_blenders_pxr():
    """Make Blender's own ``pxr`` (USD) the one Python imports: its USD export and import hand
    the USDHook their stage in it.  Only the bpy module needs this (a pip usd-core on the path
    comes first there; the application has its own first).  Only pxr: Blender's bundled
    MaterialX lacks the shader generators a pip MaterialX has.  Returns None, or one line
    saying why the hook cannot work in this Python (another pxr was imported first)."""
    if not bpy.app.module:
        return None
    if "pxr" in sys.modules:
        own = os.path.realpath(bpy.utils.system_resource("PYTHON"))
        if not os.path.realpath(sys.modules["pxr"].__file__).startswith(own):
            return ("another pxr (usd-core) was imported before Blender's: Blender's USD export "
                    "and import cannot carry haze layers in this Python")
        return None
    before = list(sys.path)
    bpy.utils.expose_bundled_modules()
    try:
        import pxr.Usd  # noqa: F401
    except ImportError:
        pass
    finally:
        sys.path[:] = before
    return None
