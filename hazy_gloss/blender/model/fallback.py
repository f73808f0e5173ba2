# SPDX-License-Identifier: GPL-3.0-or-later
"""The export fallback that makes Blender's own glTF and USD exporters write the core lobe.

Blender's glTF exporter takes the first Principled BSDF linked to the *active* Material Output
(a Mix of two Metallic BSDFs gives it nothing, a Mix of two Principled its slot 2: the halo);
its USD exporter takes the first Principled / Diffuse BSDF of the tree's node list for the
UsdPreviewSurface and the active "All" output for its MaterialX network.  Cycles and EEVEE,
however, render the output whose target is their own (Cycles / EEVEE) before any "All" output
(ntreeShaderOutputNode).  So the fallback (:func:`add_export_fallback`) adds, with built-in
nodes only:

- "HG Export fallback": a Principled BSDF with the core lobe's look (the material at haziness 0:
  engines.core_surface — metallic, base colour r_c, roughness, anisotropy, IOR, tint);
- "HG Export output": a Material Output (target All), made the active output, fed by it;
- "HG Render output Cycles" / "HG Render output EEVEE": Material Outputs with those targets,
  fed by whatever the renderers used before (the hazy mix) — unless the tree already has a
  dedicated output for that renderer, which keeps winning;
- and, for dielectrics, recreates the add-on's two Principled lobes after the fallback so the
  fallback is the first Principled in the node list (the USD preview's choice).

A haze layer's fallback is the user's own BSDF at haziness 0 (:func:`_layer_fallback`): a copy
of the core with the user's values and links of the inputs the layer owns.

Renders are unchanged (tests/blender/test_interchange.py compares Cycles and EEVEE pixels);
:func:`remove_export_fallback` restores the previous active output.  The nodes carry the add-on's
roles, so a rebuild of the material (blender/material.apply) removes them: call
:func:`add_export_fallback` again after creating or updating a material (it is idempotent and
refreshes the values).
"""
import numpy as np

from ... import constants as K
from ...core import conventions, gulbrandsen_inverse
from ...interchange import engines, materialx, openpbr_corrections
from ...interchange.brdf import fresnel_conductor
from . import layer, layer_group, material, material_read, stamp
from ..nodes.builder import default_value_of, socket_value

__all__ = ("FALLBACK_STAMP", "engine_output", "has_export_fallback", "add_export_fallback",
           "remove_export_fallback", "refresh_export_fallback", "refresh_stamped_fallback")

FALLBACK_STAMP = "hazy_gloss_export_fallback"
_PRINCIPLED = "ShaderNodeBsdfPrincipled"
_OUTPUT = "ShaderNodeOutputMaterial"
_USD_FIRST = (_PRINCIPLED, "ShaderNodeBsdfDiffuse")  # what the USD exporter's preview looks for
_RENDER_TARGETS = ("CYCLES", "EEVEE")


def _outputs(tree):
    return [n for n in tree.nodes if n.bl_idname == _OUTPUT]


def engine_output(outputs, target, active=None):
    """The Material Output a renderer with ``target`` uses (Blender's ntreeShaderOutputNode:
    an exact target beats "All"; among equals the active one, else the first).  ``active``:
    the node to treat as the active output (default: the flagged one)."""
    def is_active(n):
        return n == active if active is not None else n.is_active_output

    best = None
    for n in outputs:
        if n.target == "ALL":
            if best is None or (best.target == "ALL" and is_active(n) and not is_active(best)):
                best = n
        elif n.target == target:
            if best is None or best.target == "ALL" or (is_active(n) and not is_active(best)):
                best = n
    return best


def _role_node(tree, role):
    return material.ours(tree).get(role)


def _new(tree, bl_idname, role, label, location):
    n = tree.nodes.new(bl_idname)
    n.name = f"{K.NODE_PREFIX} {role}"
    n[K.ROLE] = role
    n.label = label
    n.location = location
    return n


def _copy_output_links(tree, src, dst):
    for s in src.inputs:
        d = next((x for x in dst.inputs if x.identifier == s.identifier), None)
        if d is None:
            continue
        if hasattr(s, "default_value") and hasattr(d, "default_value"):
            try:
                d.default_value = s.default_value
            except (TypeError, AttributeError):
                pass
        for link in list(d.links):
            tree.links.remove(link)
        for link in s.links:
            tree.links.new(link.from_socket, d)


def _set(sock, value):
    if sock is None or sock.is_linked or value is None:
        return
    v = value
    if hasattr(sock.default_value, "__len__"):
        v = tuple(value) + (1.0,) * (len(sock.default_value) - len(tuple(value)))
    sock.default_value = v


def _set_fallback_values(node, c, kind):
    ins = node.inputs
    node.distribution = "GGX"
    _set(ins.get("Base Color"), c["base_color"] if kind == "DIELECTRIC" else c["f0"])
    _set(ins.get("Metallic"), c["metallic"])
    _set(ins.get("Roughness"), c["roughness"])
    _set(ins.get("IOR"), c["ior"])
    _set(ins.get("Specular IOR Level"), 0.5)
    _set(ins.get("Specular Tint"), c["specular_tint"])
    _set(ins.get("Transmission Weight"), c["transmission"] if kind == "DIELECTRIC" else 0.0)
    _set(ins.get("Anisotropic"), c["anisotropy"] if c["anisotropy"] is not None else 0.0)
    _set(ins.get("Anisotropic Rotation"), c["rotation"] if c["rotation"] is not None else 0.0)


def _link_like(tree, node, narrow, names):
    """Link ``node``'s inputs from what feeds the same-named inputs of the core lobe."""
    if narrow is None:
        return
    for name in names:
        src = narrow.inputs.get(name)
        dst = node.inputs.get(name)
        if src is None or dst is None:
            continue
        for link in list(dst.links):
            tree.links.remove(link)
        if src.is_linked:
            tree.links.new(src.links[0].from_socket, dst)


def _snapshot(tree, node):
    """Everything needed to recreate one node: settings, socket values, links, custom props."""
    skip = {"name", "label", "location", "width", "height", "parent", "select", "hide", "mute",
            "color", "use_custom_color", "show_options", "show_preview", "show_texture",
            "location_absolute", "warning_propagation", "width_hidden", "is_active_output"}
    props = {}
    for p in node.bl_rna.properties:
        if p.is_readonly or p.identifier in skip or p.identifier.startswith("bl_"):
            continue
        if p.type in ("BOOLEAN", "INT", "FLOAT", "STRING", "ENUM") and getattr(p, "array_length", 0) == 0:
            props[p.identifier] = getattr(node, p.identifier)
    values = []
    for s in node.inputs:
        v = getattr(s, "default_value", None)
        values.append((s.identifier, tuple(v) if hasattr(v, "__len__") else v, s.hide, s.hide_value))
    return dict(
        bl_idname=node.bl_idname, name=node.name, label=node.label, location=tuple(node.location),
        width=node.width, hide=node.hide, mute=node.mute, parent=node.parent,
        use_custom_color=node.use_custom_color, color=tuple(node.color), props=props,
        custom={k: node[k] for k in node.keys()}, values=values,
        links_in=[(l.from_node.name, l.from_socket.identifier, l.to_socket.identifier)
                  for l in tree.links if l.to_node == node],
        links_out=[(l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                   for l in tree.links if l.from_node == node])


def _restore_node(tree, s):
    n = tree.nodes.new(s["bl_idname"])
    n.name = s["name"]
    n.label = s["label"]
    n.location = s["location"]
    n.width = s["width"]
    n.hide = s["hide"]
    n.mute = s["mute"]
    if s["parent"] is not None:
        n.parent = s["parent"]
    n.use_custom_color = s["use_custom_color"]
    n.color = s["color"]
    for k, v in s["props"].items():
        try:
            setattr(n, k, v)
        except (AttributeError, TypeError, ValueError):
            pass
    for k, v in s["custom"].items():
        n[k] = v
    by_id = {x.identifier: x for x in n.inputs}
    for ident, v, hide, hide_value in s["values"]:
        sock = by_id.get(ident)
        if sock is None:
            continue
        if v is not None and hasattr(sock, "default_value"):
            sock.default_value = v
        sock.hide = hide
        sock.hide_value = hide_value
    return n


def _relink(tree, s):
    n = tree.nodes[s["name"]]
    for from_name, from_id, to_id in s["links_in"]:
        src = tree.nodes.get(from_name)
        a = next((x for x in src.outputs if x.identifier == from_id), None) if src else None
        b = next((x for x in n.inputs if x.identifier == to_id), None)
        if a is not None and b is not None:
            tree.links.new(a, b)
    for from_id, to_name, to_id in s["links_out"]:
        dst = tree.nodes.get(to_name)
        a = next((x for x in n.outputs if x.identifier == from_id), None)
        b = next((x for x in dst.inputs if x.identifier == to_id), None) if dst else None
        if a is not None and b is not None:
            tree.links.new(a, b)


def _make_first_bsdf(tree, fallback):
    """Make ``fallback`` the first Principled/Diffuse BSDF of the node list by recreating the
    add-on's BSDF nodes that precede it (remove all, then create the fallback, then them).
    The user's own nodes are never recreated (a script's reference to a removed node points at
    freed memory): when one comes first, a note says so.  Returns (fallback node, notes)."""
    nodes = list(tree.nodes)
    idx = nodes.index(fallback)
    before = [n for n in nodes[:idx] if n.bl_idname in _USD_FIRST]
    if not before:
        return fallback, []
    theirs = [n for n in before if not material.is_ours(n)]
    if theirs:
        return fallback, [f"the tree's own {theirs[0].bl_idname[10:]} “{theirs[0].name}” comes "
                          f"first in the node list: Blender's USD exporter will use it for the "
                          f"preview surface"]
    moved = [n for n in nodes if n.bl_idname in _USD_FIRST and n != fallback and material.is_ours(n)]
    snaps = [_snapshot(tree, n) for n in [fallback] + moved]
    for n in [fallback] + moved:
        tree.nodes.remove(n)
    for s in snaps:
        _restore_node(tree, s)
    for s in snaps:
        _relink(tree, s)
    return tree.nodes[snaps[0]["name"]], []


def has_export_fallback(mat):
    tree = getattr(mat, "node_tree", None)
    return tree is not None and _role_node(tree, K.FALLBACK_ROLE) is not None


def _check_fallback_material(mat):
    if mat is None or getattr(mat, "node_tree", None) is None:
        raise ValueError("no material with a node tree")
    if mat.library is not None:
        raise ValueError(f"material {mat.name!r} is linked from a library and cannot be edited")
    if K.RECOMPOSITE_STAMP in mat:
        raise ValueError(f"{mat.name!r} is in recomposite mode: leave it first")
    p = material_read.read_parameters(mat)
    if p is None:
        if K.MAPS_STAMP in mat:
            raise ValueError(f"{mat.name!r} is driven by converted maps: the export fallback "
                             f"needs a hazy material with constant parameters")
        raise ValueError(f"{mat.name!r} is not a hazy material")
    return p


def _render_outputs(mat, tree):
    """Step 1: the renderers keep what they used (a dedicated output per target).  Returns
    (the reference output, the user's outputs)."""
    mine = material.ours(tree)
    user_outs = [n for n in _outputs(tree) if not material.is_ours(n)]
    if not user_outs:
        raise ValueError(f"{mat.name!r} has no Material Output")
    if mine.get(K.FALLBACK_OUTPUT_ROLE) is None:
        previous = next((n for n in user_outs if n.is_active_output), user_outs[0])
        mat[FALLBACK_STAMP] = {"version": 1, "active": previous.name}
    ref = tree.nodes.get(_fallback_active(mat)) if FALLBACK_STAMP in mat else None
    if ref is None or material.is_ours(ref):
        ref = user_outs[0]
    loc = ref.location
    for i, target in enumerate(_RENDER_TARGETS):
        role = f"{K.RENDER_OUTPUT_ROLE} {target.capitalize()}"
        ours_t = mine.get(role)
        theirs = [n for n in user_outs if n.target == target]
        if target == "EEVEE" and mine.get(K.EEVEE_OUTPUT_ROLE) is not None:
            theirs.append(mine[K.EEVEE_OUTPUT_ROLE])  # the layer's EEVEE-only output
        if theirs:  # the tree has its own output for this renderer: it keeps winning
            if ours_t is not None:
                tree.nodes.remove(ours_t)
            continue
        used = engine_output(user_outs, target, ref)
        if ours_t is None:
            ours_t = _new(tree, _OUTPUT, role, f"Render ({target.capitalize()})",
                          (loc.x, loc.y - 300.0 * (i + 1)))
            ours_t.target = target
        _copy_output_links(tree, used, ours_t)
    return ref, user_outs


def _fallback_node(tree, loc):
    mine = material.ours(tree)
    fb = mine.get(K.FALLBACK_ROLE)
    if fb is None or fb.bl_idname != _PRINCIPLED:
        if fb is not None:
            tree.nodes.remove(fb)
        fb = _new(tree, _PRINCIPLED, K.FALLBACK_ROLE, "Export fallback (core lobe)",
                  (loc.x - 300.0, loc.y - 900.0))
    return fb


def _export_output(tree, fb, ref, user_outs):
    """Step 2: the active "All" output the exporters read, fed by the fallback."""
    loc = ref.location
    x_out = material.ours(tree).get(K.FALLBACK_OUTPUT_ROLE)
    if x_out is None:
        x_out = _new(tree, _OUTPUT, K.FALLBACK_OUTPUT_ROLE, "Export (glTF / USD)",
                     (loc.x, loc.y - 900.0))
    x_out.target = "ALL"
    for link in list(x_out.inputs["Surface"].links):
        tree.links.remove(link)
    tree.links.new(fb.outputs[0], x_out.inputs["Surface"])
    used_all = engine_output(user_outs, "ALL", ref)
    if used_all is not None:  # displacement / volume of the exported surface as before
        for ident in ("Volume", "Displacement"):
            s = used_all.inputs.get(ident)
            d = x_out.inputs.get(ident)
            if s is not None and d is not None:
                for link in list(d.links):
                    tree.links.remove(link)
                if s.is_linked:
                    tree.links.new(s.links[0].from_socket, d)
    x_out.is_active_output = True


def add_export_fallback(mat):
    """Give a hazy material a single-surface fallback that Blender's glTF and USD exporters
    pick up (the core lobe: the material at haziness 0), without changing what Cycles and
    EEVEE render.  Idempotent (a second call refreshes the values); undone by
    :func:`remove_export_fallback`.  Returns a list of notes.  Raises ValueError for a
    material that is not hazy (or is driven by converted maps: not supported yet).

    A material with a haze layer (Make Hazy) gets the user's own BSDF at haziness 0: a
    Principled copy of the core with the user's values and links of the inputs the layer owns
    (:func:`_layer_fallback`)."""
    p = _check_fallback_material(mat)
    if p.get("layered"):
        return _layer_fallback(mat)
    tree = mat.node_tree
    notes = []
    c = engines.core_surface(p, materialx.lobes_of)
    ref, user_outs = _render_outputs(mat, tree)
    loc = ref.location
    fb = _fallback_node(tree, loc)
    _set_fallback_values(fb, c, p["kind"])
    mine = material.ours(tree)
    narrow = mine.get("Narrow lobe")
    _link_like(tree, fb, narrow, ("Normal", "Tangent"))
    tangent = mine.get("Tangent")
    if narrow is None and tangent is not None and c["anisotropy"] is not None:  # in-shader group
        for link in list(fb.inputs["Tangent"].links):
            tree.links.remove(link)
        tree.links.new(tangent.outputs[0], fb.inputs["Tangent"])
    if p["shader_mapping"]:
        textured = material.UserLinks(tree).textured_inputs
        if textured:
            notes.append(f"textures linked into {', '.join(textured)} are not in the fallback "
                         f"(it uses the stamped constants)")
    fb, more = _make_first_bsdf(tree, fb)
    notes += more
    _export_output(tree, fb, ref, user_outs)
    if p["kind"] == "CONDUCTOR":
        notes.append("glTF and USD preview get the core lobe as a metal with F0 = r_c (the "
                     "edge tint survives only as the Principled Specular Tint)")
    return notes


# -- haze layers -----------------------------------------------------------------------------


def _put(tree, sock, value=None, source=None):
    """Set ``sock`` to ``value`` or link it from ``source`` (a socket), dropping other links."""
    if sock is None:
        return
    if source is not None:
        if not (sock.is_linked and sock.links[0].from_socket == source):
            for link in list(sock.links):
                tree.links.remove(link)
            tree.links.new(source, sock)
        return
    for link in list(sock.links):
        tree.links.remove(link)
    if value is not None and hasattr(sock, "default_value"):
        v = socket_value(sock, value)
        cur = sock.default_value
        if (tuple(cur) if hasattr(cur, "__len__") else cur) != v:
            sock.default_value = v


def _user_input(tree, core, name):
    """(value, source socket or None) of the core's input ``name``: the layer node's own
    inputs are the user's values and links."""
    sock = core.inputs.get(name)
    if sock is None:
        return None, None
    src = sock.links[0].from_socket if sock.is_linked else None
    if src is not None and (material.is_ours(src.node) and
                            (material.role(src.node) or "").startswith("layer ")):
        src = None  # a layer node (cannot happen for inputs the layer does not own)
    return default_value_of(sock), src


def _layer_fallback(mat):
    """The export fallback of a layered material: the user's BSDF at haziness 0 (coat
    haziness 0 too).  For a Principled core, a copy of it with every value and link, the
    owned inputs (IOR, Base Color, Metallic, Coat IOR, ...) given the user's own values or
    links back; for a Metallic or Glossy core, a metallic Principled with its colour,
    roughness and anisotropy."""
    tree = mat.node_tree
    state = layer.layer_state(mat) or {}
    node = layer.layer_node(mat)
    core = _CoreProxy(node, state) if node is not None else None
    if core is None:
        raise ValueError(f"the core node of {mat.name!r} is gone: Remove Haze and Make Hazy again")
    notes = []
    ref, user_outs = _render_outputs(mat, tree)
    fb = _fallback_node(tree, ref.location)
    fb.label = "Export fallback (your BSDF at haziness 0)"
    skip = {"Weight"}
    if core.bl_idname == _PRINCIPLED:
        for prop in ("distribution", "subsurface_method"):
            if getattr(fb, prop) != getattr(core, prop):
                setattr(fb, prop, getattr(core, prop))
        for sock in fb.inputs:
            if sock.name in skip or core.inputs.get(sock.name) is None:
                continue
            val, src = _user_input(tree, core, sock.name)
            _put(tree, sock, val, src)
    else:
        _metal_fallback(tree, fb, core, notes)
    first = next((n for n in tree.nodes if n.bl_idname in _USD_FIRST), None)
    if first is not None and first != fb:
        what = ("the layer's core: the narrow lobe, with the inputs the haze raises"
                if first == core else "your BSDF as it was before haze (kept beside the layer node)"
                if first.get(K.ORIGINAL_NODE_KEY) else "not the fallback")
        notes.append(f"Blender's USD exporter takes the first Principled / Diffuse BSDF of the "
                     f"node list for its UsdPreviewSurface: “{first.name}”, {what}. Its MaterialX "
                     f"network (the USD export option) and glTF get the fallback")
    _export_output(tree, fb, ref, user_outs)
    return notes


class _CoreProxy:
    """The layer node seen as the user's BSDF: its inputs, the BSDF's type and settings."""

    def __init__(self, node, state):
        st = stamp.group(node.node_tree, K.GROUP_STAMP) or {}
        self.node = node
        self.name = node.name
        self.inputs = node.inputs
        self.bl_idname = layer_group.BSDF_NODES[st.get("bsdf", "PRINCIPLED")]
        self.settings = dict(st.get("settings") or state.get("settings") or {})

    def __getattr__(self, name):
        if name in ("distribution", "subsurface_method", "fresnel_type"):
            return self.settings.get(name, {"distribution": "GGX", "subsurface_method": "RANDOM_WALK",
                                            "fresnel_type": "F82"}[name])
        raise AttributeError(name)

    def __eq__(self, other):
        return other is self or other == self.node

    __hash__ = object.__hash__


def _metal_fallback(tree, fb, core, notes):
    """A metallic Principled for a Metallic / Glossy core (F82: Base Color and Edge Tint are
    Principled's metal F82 model; Physical Conductor: r and the F82 tint of its Fresnel;
    Glossy: Color as F0, tint 1)."""
    u = lambda name: _user_input(tree, core, name)  # noqa: E731
    dist = core.distribution if core.distribution in ("GGX", "MULTI_GGX") else "GGX"
    if core.distribution != dist:
        notes.append(f"the Principled fallback has no {core.distribution.title()}: GGX")
    fb.distribution = dist
    _put(tree, fb.inputs["Metallic"], 1.0)
    for name in ("Normal", "Tangent"):
        _put(tree, fb.inputs[name], None, u(name)[1])
    _put(tree, fb.inputs["Roughness"], *u("Roughness"))
    glossy = core.bl_idname != "ShaderNodeBsdfMetallic"
    if glossy:
        _put(tree, fb.inputs["Base Color"], *u("Color"))
        _put(tree, fb.inputs["Specular Tint"], (1.0, 1.0, 1.0, 1.0))
        (a, a_src), (rot, rot_src) = u("Anisotropy"), u("Rotation")
        if a_src is not None or rot_src is not None:
            notes.append("the Glossy BSDF's linked anisotropy is not in the fallback")
            a, rot = 0.0, 0.0
        r = float(u("Roughness")[0])
        ax, ay = openpbr_corrections.glossy_alpha(r, a)
        if ax != ay:
            rough, ratio, swap = conventions.lobe_from_alpha(ax, ay)
            a = float(conventions.metallic_anisotropy(ratio))
            rot = float(rot) + (0.25 if swap else 0.0)
        else:
            a = 0.0
        _put(tree, fb.inputs["Anisotropic"], a)
        _put(tree, fb.inputs["Anisotropic Rotation"], rot)
        notes.append("glTF and USD get the Glossy BSDF as a metal with F0 = Color (a Glossy lobe "
                     "has no Fresnel; the metal brightens towards grazing angles)")
        return
    _put(tree, fb.inputs["Anisotropic"], *u("Anisotropy"))
    _put(tree, fb.inputs["Anisotropic Rotation"], *u("Rotation"))
    if core.fresnel_type == "PHYSICAL_CONDUCTOR":
        (eta, e_src), (kap, k_src) = u("IOR"), u("Extinction")
        if e_src is not None or k_src is not None:
            notes.append("the Physical Conductor's linked IOR / Extinction are not in the fallback")
        eta = np.maximum(np.asarray(eta, float)[:3], 0.0)
        kap = np.maximum(np.asarray(kap, float)[:3], 0.0)
        r, _ = gulbrandsen_inverse(eta, kap)
        r = np.clip(np.nan_to_num(r), 0.0, 1.0)
        tint, _ = engines.f82_tint_fit(lambda c: fresnel_conductor(c, eta, kap), r)
        _put(tree, fb.inputs["Base Color"], tuple(r) + (1.0,))
        _put(tree, fb.inputs["Specular Tint"], tuple(tint) + (1.0,))
        notes.append("glTF and USD get the Physical Conductor as Principled's F82 metal (F0 = r, "
                     "the tint matching its Fresnel at 82°)")
    else:
        _put(tree, fb.inputs["Base Color"], *u("Base Color"))
        _put(tree, fb.inputs["Specular Tint"], *u("Edge Tint"))


def remove_export_fallback(mat):
    """Remove what :func:`add_export_fallback` added and make the previous output active
    again.  Returns True when something was removed."""
    tree = getattr(mat, "node_tree", None)
    if tree is None:
        return False
    mine = material.ours(tree)
    roles = [K.FALLBACK_ROLE, K.FALLBACK_OUTPUT_ROLE] + [
        f"{K.RENDER_OUTPUT_ROLE} {t.capitalize()}" for t in _RENDER_TARGETS]
    removed = False
    for r in roles:
        n = mine.get(r)
        if n is not None:
            tree.nodes.remove(n)
            removed = True
    if FALLBACK_STAMP in mat:
        name = _fallback_active(mat)
        del mat[FALLBACK_STAMP]
        prev = tree.nodes.get(name)
        if prev is None:
            prev = next(iter(_outputs(tree)), None)
        if prev is not None:
            prev.is_active_output = True
        removed = True
    return removed


def _fallback_active(mat):
    """The name of the output the fallback replaced ("" when its stamp does not say)."""
    name = (stamp.group(mat, FALLBACK_STAMP) or {}).get("active", "")
    return name if isinstance(name, str) else ""


def refresh_export_fallback(mat):
    """Refresh the fallback's values if the material has one (no-op otherwise)."""
    if has_export_fallback(mat) or FALLBACK_STAMP in mat:
        return add_export_fallback(mat)
    return []


def refresh_stamped_fallback(mat):
    """refresh_export_fallback where the material's stamp says it has one (a key lookup, no
    tree scan: called after every layer or EEVEE-output change).  Raises ValueError as
    add_export_fallback does."""
    if FALLBACK_STAMP in mat:
        refresh_export_fallback(mat)
