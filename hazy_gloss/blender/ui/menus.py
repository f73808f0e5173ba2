# SPDX-License-Identifier: GPL-3.0-or-later
"""Shader Editor > Add > Hazy Gloss, the ``hazy_gloss.add_node`` operator, and the bundled
asset library of node groups.

- The Add menu entry is appended in one place (``compat.shader_add_menu()``) and removed in
  ``unregister``.  Its submenus list every node-group configuration (kind x distribution x
  anisotropic x smooth); each item runs ``hazy_gloss.add_node``, which builds the group with
  ``ensure_group`` (so it is the same group the scripting API uses) and adds a group node.
- ``scripts/build.py`` writes ``assets/hazy_gloss_nodes.blend`` (every group marked as an asset,
  with a description and a catalog under "Hazy Gloss") and ``assets/blender_assets.cats.txt``
  into the built extension.  ``register`` adds that folder to Preferences > File Paths > Asset
  Libraries (only read there, never written) and ``unregister`` removes it again.  Running from
  a source checkout there is no ``assets/`` folder and no library is registered.
"""
import os
import uuid

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from ... import constants as K
from ...core.lobes import check_kind
from ...utils import looks, presets
from .. import compat
from . import interchange_ops, properties
from .context import PRESET_SUBDIR, foreign_tree, no_material
from ..model.groups import all_configurations, ensure_group, group_label

__all__ = ("KINDS", "ASSET_LIBRARY_NAME", "ASSET_DIRNAME", "ASSET_BLEND", "CATALOG_FILE",
           "CATALOG_ROOT", "KIND_LABELS", "describe", "item_label", "catalog_path", "catalog_id",
           "catalog_definitions", "package_dir", "asset_directory", "register_asset_library",
           "unregister_asset_library", "HAZY_GLOSS_OT_add_node", "configurations", "KIND_MENUS",
           "HAZY_GLOSS_MT_add", "draw_add_menu", "HAZY_GLOSS_MT_presets", "HAZY_GLOSS_MT_material",
           "draw_menu_entry", "draw_convert_entry", "draw_recomposite_operators",
           "HAZY_GLOSS_MT_recomposite", "draw_render_menu", "ENTRIES", "add_entries",
           "remove_entries", "register", "unregister", "classes")

KINDS = K.KINDS

# --------------------------------------------------------------------------------------------
# Descriptions and catalogs (also used by scripts/build.py to write the asset library)
# --------------------------------------------------------------------------------------------

ASSET_LIBRARY_NAME = "Hazy Gloss"
ASSET_DIRNAME = "assets"
ASSET_BLEND = "hazy_gloss_nodes.blend"
CATALOG_FILE = "blender_assets.cats.txt"
CATALOG_ROOT = "Hazy Gloss"

KIND_LABELS = {t.id: t.label for t in K.KIND_TERMS}
_KIND_TEXT = {
    "CONDUCTOR": "Metal: two Metallic BSDFs with physical-conductor Fresnel from Core "
                 "Reflectivity and Edge Tint",
    "DIELECTRIC": "Dielectric: two Principled BSDF specular layers sharing one IOR, over Base "
                  "Color, with optional Transmission",
    "LEGACY": "Legacy: two Glossy BSDFs without Fresnel, coloured so the mix keeps the "
              "reflectivity",
}
_DISTRIBUTIONS = K.DISTRIBUTIONS
_DIST_LABELS = {t.id: t.label for t in K.DISTRIBUTION_TERMS}

# Fixed namespace, so catalog UUIDs are the same in every build (files keep their catalogs).
_CATALOG_NAMESPACE = uuid.UUID("5c1e3f0e-4a8b-4f6e-9d2a-6f3b1c0d9e71")


def describe(kind, distribution="GGX", anisotropic=False, smooth=False):
    """One-paragraph description of a node-group configuration (tooltip and asset text)."""
    shape = ("anisotropic: Anisotropy, Rotation, Haze Extent X/Y and a Tangent input (link one)"
             if anisotropic else "isotropic")
    mapping = ("smooth haze mapping (rational Bézier, Smoothness input)" if smooth
               else "haze mapping of Eq. 7")
    return (f"Hazy gloss (Barla, Pacanowski & Vangorp 2018): a sharp core plus a wide halo whose "
            f"Haziness and Haze Extent leave the core's peak unchanged. {_KIND_TEXT[kind]}; "
            f"{_DIST_LABELS[distribution]} microfacets; {shape}; {mapping}. Built-in nodes "
            f"only: files render the same without the add-on")


def item_label(kind, distribution="GGX", anisotropic=False, smooth=False):
    """Menu text of a configuration: the group name without "Hazy Gloss <Kind> · "."""
    return group_label(distribution, anisotropic, smooth)


def catalog_path(kind):
    return f"{CATALOG_ROOT}/{KIND_LABELS[kind]}"


def catalog_id(path):
    return str(uuid.uuid5(_CATALOG_NAMESPACE, path))


def catalog_definitions():
    """Text of ``blender_assets.cats.txt``: "Hazy Gloss" and one child catalog per kind."""
    lines = [
        "# This is an Asset Catalog Definition file for Blender.",
        "#",
        "# Empty lines and lines starting with `#` will be ignored.",
        "# The first non-ignored line should be the version indicator.",
        '# Other lines are of the format "UUID:catalog/path/for/assets:simple catalog name"',
        "",
        "VERSION 1",
        "",
    ]
    paths = [CATALOG_ROOT] + [catalog_path(k) for k in KINDS]
    lines += [f"{catalog_id(p)}:{p}:{p.replace('/', '-')}" for p in paths]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# Asset library registration
# --------------------------------------------------------------------------------------------


def package_dir():
    return compat.PACKAGE_DIR


def asset_directory():
    """The folder holding the bundled asset .blend (exists only in a built extension)."""
    return os.path.join(package_dir(), ASSET_DIRNAME)


def _same_path(a, b):
    def norm(p):
        return os.path.normcase(os.path.realpath(bpy.path.abspath(p)))
    return bool(a) and bool(b) and norm(a) == norm(b)


_registered = {"path": None}


def register_asset_library(directory=None):
    """Add ``directory`` (default: the bundled ``assets/``) as an asset library.  Returns the
    UserAssetLibrary, or None when the folder holds no asset file (source checkout).  An entry
    with the same path (e.g. saved in the preferences by an earlier session) is reused."""
    directory = directory or asset_directory()
    if not os.path.isfile(os.path.join(directory, ASSET_BLEND)):
        return None
    libraries = bpy.context.preferences.filepaths.asset_libraries
    lib = next((lib for lib in libraries if _same_path(lib.path, directory)), None)
    if lib is None:
        # import_method keeps Blender's default: APPEND_REUSE in 4.5, PACK (linked and packed
        # into the file) in 5.0, where APPEND_REUSE cannot be set on a user library.
        lib = libraries.new(name=ASSET_LIBRARY_NAME, directory=directory)
    _registered["path"] = directory
    return lib


def unregister_asset_library():
    directory = _registered["path"]
    _registered["path"] = None
    if directory is None:
        return
    libraries = bpy.context.preferences.filepaths.asset_libraries
    for lib in [lib for lib in libraries if _same_path(lib.path, directory)]:
        libraries.remove(lib)


# --------------------------------------------------------------------------------------------
# Operator
# --------------------------------------------------------------------------------------------


def _material_tree(mat):
    if mat is None:
        return None
    return getattr(mat, "node_tree", None)


def _target_tree(context, material_name=""):
    """The shader tree to add to: the named material's, else the Shader Editor's edited tree,
    else the active object's active material's."""
    if material_name:
        return _material_tree(bpy.data.materials.get(material_name))
    space = getattr(context, "space_data", None)
    if space is not None and space.type == "NODE_EDITOR":
        if space.tree_type == "ShaderNodeTree" and space.edit_tree is not None:
            return space.edit_tree
        return None
    obj = getattr(context, "object", None)
    return _material_tree(getattr(obj, "active_material", None))


def _editable(tree):
    """A material's embedded tree reports its owner's library; linked data is read-only."""
    if tree is None:
        return False
    if getattr(tree, "library", None) is not None:
        return False
    return getattr(tree, "is_editable", True)


class HAZY_GLOSS_OT_add_node(bpy.types.Operator):
    """Add a Hazy Gloss node group to the shader tree"""

    bl_idname = "hazy_gloss.add_node"
    bl_label = "Add Hazy Gloss Node"
    bl_options = {"REGISTER", "UNDO"}

    kind: EnumProperty(
        name="Kind",
        items=[(k, KIND_LABELS[k], _KIND_TEXT[k]) for k in KINDS],
        default="CONDUCTOR",
    )
    distribution: EnumProperty(
        name="Distribution",
        items=[(d, _DIST_LABELS[d], "") for d in _DISTRIBUTIONS],
        default="GGX",
    )
    anisotropic: BoolProperty(name="Anisotropic", default=False)
    smooth: BoolProperty(name="Smooth", description="Smooth haze mapping (Bézier)", default=False)
    material: StringProperty(
        name="Material",
        description="Add to this material's tree (scripts); default: the edited shader tree, "
                    "else the active object's active material",
        default="",
        options={"HIDDEN", "SKIP_SAVE"},
    )
    use_transform: BoolProperty(
        name="Use Transform",
        description="Start moving the node after adding it",
        default=False,
        options={"HIDDEN", "SKIP_SAVE"},
    )

    @classmethod
    def poll(cls, context):
        # In a node editor it needs an editable shader tree; elsewhere (scripts, F3 search)
        # execute() resolves the target (``material``, else the active object's material).
        space = getattr(context, "space_data", None)
        if space is not None and space.type == "NODE_EDITOR":
            if space.tree_type != "ShaderNodeTree" or space.edit_tree is None:
                cls.poll_message_set("Needs a shader node tree")
                return False
            problem = foreign_tree(context)  # a World's or a Light's tree: no BSDF goes there
            if problem is not None:
                cls.poll_message_set(problem)
                return False
        return True

    @classmethod
    def description(cls, context, properties):
        try:
            return describe(properties.kind, properties.distribution, properties.anisotropic,
                            properties.smooth)
        except KeyError:
            return cls.__doc__

    def execute(self, context):
        try:
            check_kind(self.kind, self.distribution)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        if self.material and bpy.data.materials.get(self.material) is None:
            problem = no_material(context, self.material)
        else:
            problem = None if self.material else foreign_tree(context)
        if problem is not None:
            self.report({"ERROR"}, problem)
            return {"CANCELLED"}
        tree = _target_tree(context, self.material)
        if tree is None:
            self.report({"ERROR"}, f"“{self.material}” has no shader nodes to add to"
                        if self.material else "No shader tree to add to")
            return {"CANCELLED"}
        if not _editable(tree):
            self.report({"ERROR"}, "The material is linked from a library and is read-only "
                        "(make it local first)")
            return {"CANCELLED"}
        group = ensure_group(self.kind, self.distribution, self.anisotropic, self.smooth)
        if tree == group:
            self.report({"ERROR"}, "A node group cannot contain itself")
            return {"CANCELLED"}

        for n in tree.nodes:
            n.select = False
        node = tree.nodes.new("ShaderNodeGroup")
        node.node_tree = group
        node.width = 240
        node.select = True
        tree.nodes.active = node
        space = getattr(context, "space_data", None)
        if not self.material and space is not None and space.type == "NODE_EDITOR":
            node.location = space.cursor_location
        else:
            out = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"), None)
            if out is not None:
                node.location = (out.location.x - 320.0, out.location.y)
        return {"FINISHED"}

    def invoke(self, context, event):
        space = context.space_data
        in_editor = not self.material and space is not None and space.type == "NODE_EDITOR"
        if in_editor:  # place the node under the mouse, as Blender's own Add menu does
            if context.region is not None and context.region.type == "WINDOW":
                space.cursor_location_from_region(event.mouse_region_x, event.mouse_region_y)
            elif space.edit_tree is not None:
                space.cursor_location = space.edit_tree.view_center
        result = self.execute(context)
        if in_editor and self.use_transform and "FINISHED" in result:
            bpy.ops.node.translate_attach_remove_on_cancel("INVOKE_DEFAULT")
        return result


# --------------------------------------------------------------------------------------------
# Menus
# --------------------------------------------------------------------------------------------


def configurations(kind):
    return [c for c in all_configurations() if c[0] == kind]


def _draw_kind(self, context):
    layout = self.layout
    layout.operator_context = "INVOKE_REGION_WIN"
    previous = None
    for kind, dist, aniso, smooth in configurations(self.hazy_kind):
        if previous is not None and dist != previous:
            layout.separator()
        previous = dist
        props = layout.operator(HAZY_GLOSS_OT_add_node.bl_idname,
                                text=item_label(kind, dist, aniso, smooth))
        props.kind = kind
        props.distribution = dist
        props.anisotropic = aniso
        props.smooth = smooth
        props.use_transform = True


def _kind_menu(kind):
    return type(f"HAZY_GLOSS_MT_add_{kind.lower()}", (bpy.types.Menu,), {
        "bl_idname": f"HAZY_GLOSS_MT_add_{kind.lower()}",
        "bl_label": KIND_LABELS[kind],
        "bl_description": _KIND_TEXT[kind],
        "hazy_kind": kind,
        "draw": _draw_kind,
    })


KIND_MENUS = tuple(_kind_menu(k) for k in KINDS)


class HAZY_GLOSS_MT_add(bpy.types.Menu):
    """Hazy Gloss node groups"""

    bl_idname = "HAZY_GLOSS_MT_add"
    bl_label = "Hazy Gloss"

    def draw(self, context):
        layout = self.layout
        for menu in KIND_MENUS:
            layout.menu(menu.bl_idname)


def draw_add_menu(self, context):
    """Appended to the Shader Editor's Add menu (compat.shader_add_menu())."""
    space = getattr(context, "space_data", None)
    if space is not None and getattr(space, "tree_type", "ShaderNodeTree") != "ShaderNodeTree":
        return
    if foreign_tree(context) is not None:  # the groups are BSDFs: materials only
        return
    layout = self.layout
    layout.separator()
    layout.menu(HAZY_GLOSS_MT_add.bl_idname, icon="NODE_MATERIAL")


class HAZY_GLOSS_MT_presets(bpy.types.Menu):
    bl_label = "Hazy Gloss Presets"
    bl_idname = "HAZY_GLOSS_MT_presets"
    preset_subdir = PRESET_SUBDIR
    preset_operator = "script.execute_preset"

    def draw(self, context):
        layout = self.layout
        layout.label(text="Looks (their haze)")
        for pid, name, _desc in looks.enum_items():
            layout.operator("hazy_gloss.apply_preset", text=name).preset = pid
        layout.separator()
        layout.label(text="From the paper")
        for pid, name, _desc in presets.enum_items():
            layout.operator("hazy_gloss.apply_preset", text=name).preset = pid
        layout.separator()
        layout.label(text="Your presets")
        bpy.types.Menu.draw_preset(self, context)


def _preset_begins(_context, _filepath):
    properties.begin_preset()


def _preset_ends(_context, filepath):
    properties.end_preset(bpy.path.display_name(os.path.basename(filepath), title_case=False))


# script.execute_preset calls these around a user preset: a haze layer takes only its haze from
# a whole material's preset (and the reverse), saying once what it left out
HAZY_GLOSS_MT_presets.reset_cb = staticmethod(_preset_begins)
HAZY_GLOSS_MT_presets.post_cb = staticmethod(_preset_ends)


class HAZY_GLOSS_MT_material(bpy.types.Menu):
    """Shader Editor > Node > Hazy Gloss and the material specials menu: the material operators
    live in menus so F3 menu search finds them."""
    bl_idname = "HAZY_GLOSS_MT_material"
    bl_label = "Hazy Gloss"

    def draw(self, context):
        layout = self.layout
        layout.operator("hazy_gloss.make_hazy")
        layout.operator("hazy_gloss.remove_haze")
        layout.operator("hazy_gloss.new_material")
        layout.operator("hazy_gloss.import_two_lobe_mix")
        layout.operator("hazy_gloss.convert_pbr_set", icon="TEXTURE")
        layout.menu("HAZY_GLOSS_MT_presets", text="Apply Hazy Preset")


def draw_menu_entry(self, context):
    self.layout.menu(HAZY_GLOSS_MT_material.bl_idname)


def draw_convert_entry(self, context):
    self.layout.operator("hazy_gloss.convert_maps", icon="IMAGE_DATA")
    self.layout.operator("hazy_gloss.convert_pbr_set", icon="TEXTURE")


def draw_recomposite_operators(layout):
    """The recomposite operators (this menu and the View Layer panel)."""
    col = layout.column(align=True)
    col.operator("hazy_gloss.setup_recomposite", icon="RENDERLAYERS")
    col.operator("hazy_gloss.load_recomposite", icon="NODE_COMPOSITING")
    col.operator("hazy_gloss.clear_recomposite", icon="X")


class HAZY_GLOSS_MT_recomposite(bpy.types.Menu):
    """Render > Hazy Gloss Recomposite (also what F3 search finds)."""
    bl_idname = "HAZY_GLOSS_MT_recomposite"
    bl_label = "Hazy Gloss Recomposite"

    def draw(self, context):
        draw_recomposite_operators(self.layout)


def draw_render_menu(self, context):
    self.layout.separator()
    self.layout.menu(HAZY_GLOSS_MT_recomposite.bl_idname)


#: (Blender menu, draw function) entries appended by add_entries (each menu exists in 4.5-5.3);
#: the Shader Editor's Add menu comes from compat.shader_add_menu().
ENTRIES = (("NODE_MT_node", draw_menu_entry), ("MATERIAL_MT_context_menu", draw_menu_entry),
           ("NODE_MT_node", draw_convert_entry), ("TOPBAR_MT_render", draw_render_menu),
           ("TOPBAR_MT_file_export", interchange_ops.draw_export_menu),
           ("TOPBAR_MT_file_import", interchange_ops.draw_import_menu),
           ("MATERIAL_MT_context_menu", interchange_ops.draw_material_menu))


classes = (HAZY_GLOSS_OT_add_node, *KIND_MENUS, HAZY_GLOSS_MT_add, HAZY_GLOSS_MT_presets,
           HAZY_GLOSS_MT_material, HAZY_GLOSS_MT_recomposite)

_appended = []


def add_entries():
    """Append the add-on's entries to Blender's menus (removed again by remove_entries)."""
    for menu_name, draw in ENTRIES:
        menu = getattr(bpy.types, menu_name, None)
        if menu is not None:
            menu.append(draw)
            _appended.append((menu, draw))
    menu = compat.shader_add_menu()
    menu.append(draw_add_menu)
    _appended.append((menu, draw_add_menu))


def remove_entries():
    while _appended:
        menu, draw = _appended.pop()
        try:
            menu.remove(draw)
        except (ValueError, RuntimeError):
            pass


register, unregister = bpy.utils.register_classes_factory(classes)
