# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy Gloss panels: Shader Editor sidebar (tab "Hazy Gloss") and Material Properties.

Both draw the same thing for the active material (:func:`draw_material`): the perceptual
sliders, kind / distribution / in-shader vs constant mapping, presets, the mapped physical
values read-only (β, r, η, κ, α_n, α_w, p, k̂_h from ``api.map_parameters``), warnings in plain
words, and two plots.

Plots: drawn with numpy (``utils.plots``) into previews of a ``bpy.utils.previews`` collection
and shown with ``layout.template_icon``.  Measured in 4.5 and 5.0 (background mode): a
collection preview takes exact pixels through ``image_pixels_float`` (stored 8-bit), also from
``draw()`` since it is not ID data; an image data-block's ``preview`` is generated
asynchronously by the UI from the image (size 0 in background mode, not settable) and writing
an image in ``draw()`` is forbidden, so it is not used for the panel.  ``hazy_gloss.plot_to_image``
writes full-resolution float copies into hidden image data-blocks (zero users: not saved).
Plots are recomputed only when the parameters or the plot settings change.
"""

import bpy
import numpy as np

from ... import constants as K
from ...core.parameters import is_anisotropic
from ...schema import HAZE_SOCKETS, SCHEMA_BY_NAME
from ..actions import eevee_output, messages
from ..model import layer, material, material_edits, material_read, stamp
from . import plots, preferences, properties
from .context import target_material
from ..model.material_read import edit_problem, maps_problem
from ..model.layer_group import haze_params
from ..actions.messages import plain_message
from .menus import draw_recomposite_operators

__all__ = ("warnings_for", "node_edit_notes", "mapped_values", "draw_presets_row", "draw_haze",
           "draw_warnings", "draw_physical_values", "draw_material", "layer_rows", "layer_warnings",
           "draw_layer", "layer_group_params", "draw_eevee", "HAZY_GLOSS_PT_material",
           "HAZY_GLOSS_PT_shader_editor", "HAZY_GLOSS_PT_recomposite", "register", "unregister",
           "classes")

# --------------------------------------------------------------------------------------------
# Warnings and mapped values
# --------------------------------------------------------------------------------------------

_CLAMP_TEXT = {
    "alpha_wide >": "The halo is wider than Blender allows (roughness 1), so it was narrowed: "
                    "lower Haze Extent or Roughness",
    "alpha_wide aspect": "The halo is more than 10 times longer one way than the other, which "
                         "Blender's anisotropy cannot do; it was shortened",
    "reflectivity at 1": "Reflectivity reached 1: there is no room left for haze",
}


def warnings_for(mat, p, m, context=None, prefs=None):
    """Plain-language warnings for a hazy material (list of strings)."""
    prefs = prefs or preferences.get(context)
    out = []
    for reason in m.clamped:
        for key, text in _CLAMP_TEXT.items():
            if reason.startswith(key):
                out.append(text)
                break
        else:
            out.append(reason)
    r_max = float(np.asarray(m.reflectivity_max))
    rc_max = float(np.max(p["core_reflectivity"]))
    if p["kind"] == "DIELECTRIC" and r_max > prefs.dielectric_warning:
        out.append(f"Reflectivity r = {r_max:.3f} (IOR {float(np.asarray(m.dielectric_ior)):.2f}) "
                   f"is more than any common dielectric reflects: it will look like a metal. "
                   f"Lower Haziness or Haze Extent")
    elif p["kind"] == "DIELECTRIC" and p["haziness"] > 0.1:
        out.append(f"Haziness {p['haziness']:.2f} is above the usual 0-0.1 for dielectrics: "
                   f"haze raises the reflectivity (r = {r_max:.3f})")
    if p["kind"] != "DIELECTRIC" and p["haziness"] > 0 and rc_max > 0.9:
        room = (1.0 - rc_max) / max(float(np.asarray(m.peak_complement)), 1e-9)
        out.append(f"A very bright core ({rc_max:.2f}) leaves little room for haze (energy "
                   f"conservation): at most {min(room, 1.0):.2f} of halo intensity")
    if p["roughness"] < K.min_roughness(p["distribution"]):
        out.append(f"Roughness below {K.min_roughness(p['distribution'])} is raised to it: a "
                   f"perfect mirror cannot carry a halo")
    if p["kind"] == "LEGACY":
        out.append("Legacy lobes have no Fresnel: reflections do not brighten at grazing angles")
    if is_anisotropic(p):
        obj = getattr(context, "object", None) if context is not None else None
        data = getattr(obj, "data", None)
        if p["tangent"] == "UV_MAP" and data is not None and hasattr(data, "uv_layers") \
                and len(data.uv_layers) == 0:
            out.append("Anisotropy follows the UV map's tangent, but the object has no UV map")
        scene = getattr(context, "scene", None) if context is not None else None
        if scene is not None and "EEVEE" in scene.render.engine:
            out.append("EEVEE ignores anisotropy: render with Cycles to see it")
    return out


def _names(edits, most=3):
    names = [str(e) for e in edits]
    return ", ".join(names[:most]) + (f" and {len(names) - most} more" if len(names) > most else "")


#: (material, parameters, edits) -> the edits adopt_edits replaces: the panel draws many times
#: a second, the inverse mapping runs once per edit that does not read.
_REPLACED = {}


def node_edit_notes(mat, p):
    """[(text, icon)] about the user's node-editor edits of the add-on's nodes that are not in
    the parameters yet (the depsgraph handler reads them back right after the edit; a material
    no object uses is read back on its next change): kept, or replaced by the next change."""
    try:
        edits = material_edits.node_edits(mat, p)
        if not edits:
            return []
        key = (mat.session_uid, repr(p), repr(edits))
        replaced = _REPLACED.get(key)
        if replaced is None:
            replaced = _REPLACED[key] = material_edits.adopt_edits(mat, p, edits)[1]
            if len(_REPLACED) > 64:
                _REPLACED.pop(next(iter(_REPLACED)))
    except (ValueError, TypeError):
        return []
    out = []
    kept = [e for e in edits if e not in replaced]
    if kept:
        out.append((f"Node-editor edits ({_names(kept)}) are read back into these parameters "
                    f"on the next change", "INFO"))
    if replaced:
        out.append((f"Node-editor edits these parameters cannot represent ({_names(replaced)}) "
                    f"are replaced by the next change here", "ERROR"))
    return out


def _fmt(v, digits=3):
    arr = np.asarray(v, dtype=np.float64).ravel()
    if arr.size == 1 or np.all(arr == arr[0]):
        return f"{arr[0]:.{digits}g}"
    return "(" + ", ".join(f"{x:.{digits}g}" for x in arr) + ")"


def mapped_values(p, m):
    """[(label, value text)] of the physical parameters the material renders with."""
    rows = [("β (wide lobe)", _fmt(m.beta)), ("r = F_r(0)", _fmt(m.reflectivity))]
    if p["kind"] == "CONDUCTOR":
        rows += [("η", _fmt(m.ior)), ("κ", _fmt(m.extinction))]
    elif p["kind"] == "DIELECTRIC":
        rows += [("η", _fmt(m.dielectric_ior, 4))]
    else:
        rows += [("k_n, k_w", f"{_fmt(m.weight_narrow)}, {_fmt(m.weight_wide)}")]
    ax, ay = (float(np.asarray(a)) for a in m.alpha)
    wx, wy = (float(np.asarray(a)) for a in m.alpha_wide)
    rows += [("α_n", _fmt((ax, ay) if ax != ay else ax, 4)),
             ("α_w", _fmt((wx, wy) if wx != wy else wx, 4)),
             ("p (peak ratio)", _fmt(m.peak_ratio)),
             ("k̂_h (halo)", _fmt(m.halo_intensity))]
    return rows


# --------------------------------------------------------------------------------------------
# Drawing
# --------------------------------------------------------------------------------------------


def draw_presets_row(layout):
    """The presets menu with add / remove, as Blender's preset panels have it."""
    row = layout.row(align=True)
    row.menu("HAZY_GLOSS_MT_presets", text="Presets", icon="PRESET")
    row.operator("hazy_gloss.preset_add", text="", icon="ADD")
    row.operator("hazy_gloss.preset_add", text="", icon="REMOVE").remove_active = True


def draw_haze(layout, hg):
    """The haze controls (β_h, λ_h with its x / y link, the smooth variant's w): the same for a
    whole hazy material and for a haze layer."""
    haze = layout.box().column()
    haze.use_property_split = True
    haze.use_property_decorate = False
    haze.label(text="Haze", icon="LIGHT_SUN")
    haze.prop(hg, "haziness", slider=True)
    row = haze.row(align=True)
    row.prop(hg, "haze_extent_x", text="Extent" if hg.haze_extent_linked else "Extent X")
    row.prop(hg, "haze_extent_linked", text="", icon="LINKED" if hg.haze_extent_linked else "UNLINKED")
    if not hg.haze_extent_linked:
        haze.prop(hg, "haze_extent_y", text="Extent Y")
    row = haze.row(align=True)
    row.prop(hg, "use_smoothness", text="Smooth")
    sub = row.row(align=True)
    sub.active = hg.use_smoothness
    sub.prop(hg, "smoothness", text="w")


def draw_warnings(layout, warns):
    """A box of the plain-language warnings (nothing when there are none)."""
    if warns:
        box = layout.box()
        for text in warns:
            box.label(text=text, icon="ERROR")


def draw_physical_values(layout, idname, rows):
    """The closed-by-default "Physical Values" subpanel: a two-column grid of (label, value)
    rows. Returns the subpanel's body (None while it is closed) for notes below the grid."""
    header, panel = layout.panel(f"{idname}_physical", default_closed=True)
    header.label(text="Physical Values")
    if panel is not None:
        grid = panel.grid_flow(row_major=True, columns=2, even_columns=True, align=True)
        for label, value in rows:
            grid.label(text=label)
            grid.label(text=value)
    return panel


def draw_material(layout, context, mat, idname):
    """The body of both panels; ``idname`` keeps their collapsible sections apart."""
    prefs = preferences.get(context)
    if mat is None:
        layout.label(text="No active material", icon="INFO")
        layout.operator("hazy_gloss.new_material", icon="ADD")
        return
    problem = edit_problem(mat)
    if not material_read.is_hazy(mat):
        col = layout.column()
        if mat.library is not None:
            col.label(text="Linked from a library: read-only", icon="LIBRARY_DATA_DIRECT")
            return
        if maps_problem(mat):
            col.label(text=maps_problem(mat), icon="TEXTURE")
            col.operator("hazy_gloss.convert_maps", icon="IMAGE_DATA")
            return
        col.label(text=f"“{mat.name}” is not hazy", icon="INFO")
        row = col.row(align=True)
        row.operator("hazy_gloss.make_hazy", icon="SHADING_RENDERED")
        row.operator("hazy_gloss.import_two_lobe_mix", text="Import Two-Lobe Mix")
        col.operator("hazy_gloss.new_material", icon="ADD")
        return
    hg = properties.settings(mat)
    if layer.is_layered(mat):
        draw_layer(layout, context, mat, idname, hg, problem)
        return
    p, damaged = material_read.read_parameters_lenient(mat)

    col = layout.column()
    if problem is not None:
        box = col.box()
        box.alert = True
        box.label(text=problem, icon="LIBRARY_DATA_DIRECT")
    if damaged is not None:  # the sliders show the defaults where the stamp does not read
        box = col.box()
        box.alert = True
        box.label(text=damaged, icon="ERROR")
        box.label(text="Apply a preset (Presets below) to reset the parameters", icon="PRESET")
    err = messages.error_for(mat)
    if err and problem is None and err != damaged:
        box = col.box()
        box.alert = True
        box.label(text=err, icon="ERROR")
    if K.RECOMPOSITE_STAMP in mat:
        col.label(text="In recomposite mode: a change here rebuilds the normal material",
                  icon="NODE_COMPOSITING")
    if damaged is None and problem is None:
        for text, icon in node_edit_notes(mat, p):
            box = col.box()
            box.alert = icon == "ERROR"
            box.label(text=text, icon=icon)
    body = col.column()
    body.enabled = problem is None

    draw_presets_row(body)

    body.prop(hg, "kind", expand=True)
    split = body.column()
    split.use_property_split = True
    split.use_property_decorate = False
    split.prop(hg, "distribution")
    split.prop(hg, "shader_mapping", text="In-Shader Mapping")

    core = body.box().column()
    core.use_property_split = True
    core.use_property_decorate = False
    core.label(text="Core", icon="SHADING_SOLID")
    core.prop(hg, "core_reflectivity")
    if p["kind"] == "CONDUCTOR":
        core.prop(hg, "edge_tint")
    core.prop(hg, "roughness", slider=True)
    core.prop(hg, "anisotropy", slider=True)
    if is_anisotropic(p):
        core.prop(hg, "rotation", slider=True)
        core.prop(hg, "tangent")

    draw_haze(body, hg)

    if p["kind"] == "DIELECTRIC":
        base = body.box().column()
        base.use_property_split = True
        base.use_property_decorate = False
        base.label(text="Base", icon="MATERIAL")
        base.prop(hg, "base_color")
        base.prop(hg, "transmission", slider=True)

    try:
        m = material.map_parameters(p)
    except ValueError as exc:
        box = col.box()
        box.alert = True
        box.label(text=plain_message(exc), icon="ERROR")
        return

    draw_warnings(col, warnings_for(mat, p, m, context, prefs))

    panel = draw_physical_values(col, idname, mapped_values(p, m))
    if panel is not None:
        if p["shader_mapping"] and properties.has_hazy_nodes(mat):
            group = material.ours(mat.node_tree).get(material.GROUP_ROLE)
            if group is not None and any(s.is_linked for s in group.inputs
                                         if s.name not in ("Normal", "Tangent")):
                panel.label(text="Textured inputs vary these per pixel", icon="TEXTURE")

    if prefs.show_plots:
        header, panel = col.panel(f"{idname}_plots", default_closed=False)
        header.label(text="Plots")
        if panel is not None:
            row = panel.row()
            c1 = row.column(align=True)
            c1.template_icon(icon_value=plots.plot_icon(mat, "haze", prefs), scale=7.0)
            c1.label(text="Halo k_h vs core r_c")
            c2 = row.column(align=True)
            c2.template_icon(icon_value=plots.plot_icon(mat, "brdf", prefs), scale=7.0)
            c2.label(text="BRDF: core, halo, total")
            panel.label(text="Red: bounds P, E / total · magenta: core · cyan: halo")
            panel.operator("hazy_gloss.plot_to_image", icon="IMAGE_DATA")


_SHOWN = (("beta dielectric", "Dielectric: β"), ("IOR dielectric", "Dielectric: IOR"),
          ("reflectivity dielectric", "Dielectric: r = F(0)"), ("beta metal", "Metal: β"),
          ("reflectivity metal", "Metal: r = F(0)"), ("beta", "β"), ("reflectivity", "r = F(0)"),
          ("ior", "η"), ("extinction", "κ"), ("roughness wide", "Wide roughness R_w"),
          ("beta coat", "Coat: β"), ("coat IOR", "Coat: IOR"),
          ("coat roughness wide", "Coat: wide roughness"))


_DIELECTRIC_KEYS = ("beta dielectric", "IOR dielectric", "reflectivity dielectric")
_METAL_KEYS = ("beta metal", "reflectivity metal")


def _parts(node):
    """(dielectric, metal): which parts of a Principled BSDF render, by the layer node's
    Metallic (linked or between 0 and 1: both; a BSDF without Metallic: both keys absent)."""
    sock = node.inputs.get("Metallic") if node is not None else None
    if sock is None or sock.is_linked:
        return True, True
    metallic = float(sock.default_value)
    return metallic < 1.0, metallic > 0.0


def layer_rows(info):
    """[(label, value text)] of what the layer's group computes for the layer node's values
    (a part the BSDF's Metallic leaves out is not shown)."""
    vals = info["values"]
    dielectric, metal = _parts(info.get("node"))
    hidden = (() if dielectric else _DIELECTRIC_KEYS) + (() if metal else _METAL_KEYS)
    return [(label, _fmt(vals[key], 4)) for key, label in _SHOWN
            if key in vals and key not in hidden]


def layer_warnings(info, context=None, prefs=None):
    """Plain-language warnings for a haze layer (list of strings)."""
    prefs = prefs or preferences.get(context)
    out = list(info["notes"])
    vals = info["values"]
    r = vals.get("reflectivity dielectric") if _parts(info.get("node"))[0] else None
    if r is not None and max(np.atleast_1d(r)) > prefs.dielectric_warning and \
            vals.get("beta dielectric", 0.0) > 0.0:
        out.append(f"The dielectric reflects r = {max(np.atleast_1d(r)):.3f}: it will look like "
                   f"a metal. Lower Haziness or Haze Extent")
    node = info["node"]
    tf = node.inputs.get("Thin Film Thickness")
    if tf is not None and (tf.is_linked or tf.default_value > 0.1):
        out.append("Thin film: the layer raises the BSDF's F(0) as without a film, so the peak "
                   "follows the film only approximately")
    return out


def draw_layer(layout, context, mat, idname, hg, problem):
    """A haze layer: the layer node's Haze sockets (drawn from the node, so they can be
    keyframed and driven here too), its settings, what it computes; the BSDF's own inputs are
    on the node."""
    col = layout.column()
    try:
        layer.read(mat)  # a damaged record or a missing layer node raises, in one line
        info = layer.summary(mat)
    except ValueError as exc:  # say so, offer the way out
        box = col.box()
        box.alert = True
        box.label(text=plain_message(exc), icon="ERROR")
        if stamp.own_way_out((layer.layer_state(mat) or {}).get("problems") or []) is None:
            col.operator("hazy_gloss.remove_haze", icon="X")  # (else it refuses)
        return
    node = info["node"]
    if problem is not None:
        box = col.box()
        box.alert = True
        box.label(text=problem, icon="LIBRARY_DATA_DIRECT")
    err = messages.error_for(mat)
    if err and problem is None:
        box = col.box()
        box.alert = True
        box.label(text=err, icon="ERROR")
    if layer.outdated_group(mat) and problem is None:
        col.operator("hazy_gloss.upgrade_layers", icon="FILE_REFRESH").material = mat.name
    head = col.box().column(align=True)
    head.label(text=f"Haze layer node “{node.name}” ({node.node_tree.name})", icon="NODE_MATERIAL")
    head.label(text="Its own inputs are the BSDF's: edit them on the node as usual")
    body = col.column()
    body.enabled = problem is None
    draw_presets_row(body)

    haze = body.box().column()
    haze.use_property_split = True
    haze.label(text="Haze", icon="LIGHT_SUN")
    for param in layer_group_params(node):
        sock = node.inputs.get(HAZE_SOCKETS[param][0])
        if sock is None:
            continue
        row = haze.row()
        if sock.is_linked:
            row.label(text=f"{sock.name}: from “{sock.links[0].from_node.name}”", icon="TEXTURE")
        else:
            row.prop(sock, "default_value", text=sock.name,
                     slider=_slider(param))
    row = haze.row(align=True)
    row.prop(hg, "use_smoothness", text="Smooth Haze Curve")
    if "Coat Weight" in node.inputs:
        coat = node.inputs["Coat Weight"]
        if not (coat.is_linked or coat.default_value > 0.0):
            haze.label(text="Coat Haziness needs a coat (Coat Weight > 0)", icon="INFO")
        body.prop(hg, "keep_body_colour")
    body.operator("hazy_gloss.add_haziness_map", icon="BRUSH_DATA")
    draw_eevee(body, mat, hg)

    draw_warnings(col, layer_warnings(info, context))
    panel = draw_physical_values(col, idname, layer_rows(info))
    if panel is not None:
        if info["textured"]:
            panel.label(text="For the unlinked values; linked inputs vary them per pixel",
                        icon="TEXTURE")
    col.operator("hazy_gloss.remove_haze", icon="X")


def _slider(key):
    """A haze socket drawn as a slider: a factor with a slider range (haziness, not the cap)."""
    p = SCHEMA_BY_NAME.get(key)
    return p is not None and p.factor and p.soft is not None


def layer_group_params(node):
    """The haze parameters the layer node's group has, in panel order."""
    st = stamp.group(node.node_tree, K.GROUP_STAMP) or {}
    return haze_params(st.get("bsdf", "PRINCIPLED"), bool(st.get("smooth")))


def draw_eevee(layout, mat, hg):
    """The EEVEE-only simplification (blender/actions/eevee_output.py): the choice, and whether it is
    in effect here and why."""
    box = layout.box().column()
    box.use_property_split = True
    box.use_property_decorate = False
    box.prop(hg, "eevee_output")
    try:
        noisy, why = eevee_output.needs_eevee_output(mat)
    except ValueError:
        return
    built = eevee_output.has_eevee_output(mat)
    if built:
        box.label(text="EEVEE renders one folded BSDF (same peak, a single lobe's halo)",
                  icon="CHECKMARK")
    elif noisy:
        box.label(text="EEVEE picks between narrow and wide lobes at random here (coat): "
                  "noisy at few TAA samples", icon="INFO")


def _context_material(context):
    return target_material(context)


def _in_material_properties(context):
    return getattr(context, "material", None) is not None or \
        getattr(context, "object", None) is not None


def _in_object_shader_editor(context):
    space = getattr(context, "space_data", None)
    if space is None or getattr(space, "tree_type", "") != "ShaderNodeTree":
        return False
    if getattr(space, "shader_type", "OBJECT") != "OBJECT":
        return False
    return _context_material(context) is not None or getattr(context, "object", None) is not None


def _material_panel(idname, subpanel_prefix, shown, **placement):
    """The Hazy Gloss material panel class ``idname``: placed by ``placement`` (bl_space_type,
    bl_region_type...), polled by ``shown(context)``, its subpanels named by the prefix."""
    def draw(self, context):
        draw_material(self.layout, context, _context_material(context), subpanel_prefix)

    return type(idname, (bpy.types.Panel,), dict(
        bl_label="Hazy Gloss", bl_idname=idname, **placement,
        poll=classmethod(lambda cls, context: shown(context)), draw=draw))


HAZY_GLOSS_PT_material = _material_panel(
    "HAZY_GLOSS_PT_material", "hazy_gloss_material", _in_material_properties,
    bl_space_type="PROPERTIES", bl_region_type="WINDOW", bl_context="material")
HAZY_GLOSS_PT_shader_editor = _material_panel(
    "HAZY_GLOSS_PT_shader_editor", "hazy_gloss_node", _in_object_shader_editor,
    bl_space_type="NODE_EDITOR", bl_region_type="UI", bl_category="Hazy Gloss")


class HAZY_GLOSS_PT_recomposite(bpy.types.Panel):
    """Properties > View Layer: edit haziness after the render (paper §4.3)."""
    bl_idname = "HAZY_GLOSS_PT_recomposite"
    bl_label = "Hazy Gloss Recomposite"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "view_layer"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.render.engine == "CYCLES"

    def draw(self, context):
        draw_recomposite_operators(self.layout)


classes = (HAZY_GLOSS_PT_material, HAZY_GLOSS_PT_shader_editor, HAZY_GLOSS_PT_recomposite)

register, unregister = bpy.utils.register_classes_factory(classes)
