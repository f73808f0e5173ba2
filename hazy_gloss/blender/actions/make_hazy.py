# SPDX-License-Identifier: GPL-3.0-or-later
"""Make Hazy and Import Two-Lobe Mix as plain functions (the operators only call these).

- :func:`make_hazy`: a haze layer on the material's own Principled / Metallic / Glossy BSDF
  (blender.model.layer): the node and everything else in the tree stay as they are.
- :func:`import_two_lobe_mix`: a Mix Shader of two Glossy or two Metallic lobes -> perceptual
  parameters (core.inverse_haze_mapping), with a report of what is not exactly representable.

Both return (status, message, notes): status "FINISHED", "NOOP" or "ERROR".
"""
import math

import bpy
import numpy as np

from ... import constants as K
from ...core import inverse_haze_mapping
from ...core.conventions import lobe_alphas, metallic_anisotropy
from ...core.parameters import normalise, normalise_haze
from ...schema import HAZE_SOCKETS
from ..model import fallback, layer, layer_group, material, material_read, stamp
from . import messages, sync
from ..model.material_read import baked_problem, edit_problem, maps_problem, shown
from ..nodes import ownership
from .messages import plain_message

__all__ = ("GLOSSY", "CORE_NODES", "surface_bsdfs", "find_core_bsdf", "replace_with_hazy",
           "tree_problem", "make_hazy", "apply_imported_haze", "remove_haze", "find_two_lobe_mix",
           "import_two_lobe_mix", "materials_or_all", "upgrade_layers", "add_haziness_map")


def _is_live(mat):
    return material_read.is_hazy(mat) and bool(material.ours(mat.node_tree))


# --------------------------------------------------------------------------------------------
# Reading existing BSDF nodes
# --------------------------------------------------------------------------------------------

# The Glossy BSDF node is created as "ShaderNodeBsdfGlossy" but reports bl_idname
# "ShaderNodeBsdfAnisotropic" (Glossy and Anisotropic were merged in 4.0): accept both.
GLOSSY = ("ShaderNodeBsdfAnisotropic", "ShaderNodeBsdfGlossy")
CORE_NODES = ("ShaderNodeBsdfPrincipled", "ShaderNodeBsdfMetallic") + GLOSSY
_SHADER_PASS = ("ShaderNodeMixShader", "ShaderNodeAddShader")


def _source(sock):
    """The output socket linked into ``sock`` (ignoring muted links), or None."""
    if sock is None or not sock.is_linked:
        return None
    link = sock.links[0]
    if getattr(link, "is_muted", False) or not getattr(link, "is_valid", True):
        return None
    return link.from_socket


def _value(node, name, default=None):
    sock = node.inputs.get(name)
    if sock is None or not hasattr(sock, "default_value"):
        return default
    v = sock.default_value
    if hasattr(v, "__len__"):
        return tuple(float(x) for x in v)
    return float(v)


def _rgb(v):
    return tuple(float(np.clip(x, 0.0, 1.0)) for x in tuple(v)[:3])


def surface_bsdfs(tree):
    """(BSDFs, groups): the Principled / Metallic / Glossy BSDFs feeding the Surface of the
    output Cycles renders (finals), then of the one EEVEE renders, directly or through Mix / Add
    Shader nodes, reroutes and the shader inputs of node groups, closest to the output first;
    and the node groups met on the way that hold such a BSDF (their insides are not searched:
    other materials may share them)."""
    outs = [ownership.engine_output(tree, e) for e in ("CYCLES", "EEVEE")]
    seen, found, groups = set(), [], []
    for out in dict.fromkeys(o for o in outs if o is not None):
        queue = [_source(out.inputs["Surface"])]
        while queue:
            sock = queue.pop(0)
            if sock is None or sock.node.name in seen:
                continue
            node = sock.node
            seen.add(node.name)
            if node.bl_idname in CORE_NODES and not node.mute and not material.is_ours(node):
                found.append(node)
            elif node.bl_idname == "ShaderNodeGroup":
                if _holds_bsdf(node.node_tree, set()):
                    groups.append(node)
                # (a group that mixes the shaders it is given: those are the material's)
                queue.extend(_source(s) for s in node.inputs if s.type == "SHADER")
            elif node.bl_idname in _SHADER_PASS or node.bl_idname == "NodeReroute":
                queue.extend(_source(s) for s in node.inputs if s.type == "SHADER" or
                             node.bl_idname == "NodeReroute")
    return found, groups


def _holds_bsdf(ng, seen):
    """Whether the node group ``ng`` (or one nested in it) has a Principled, Metallic or Glossy
    BSDF."""
    if ng is None or ng.name in seen:
        return False
    seen.add(ng.name)
    return any(n.bl_idname in CORE_NODES or (n.bl_idname == "ShaderNodeGroup"
                                              and _holds_bsdf(n.node_tree, seen)) for n in ng.nodes)


def find_core_bsdf(tree):
    """The BSDF Make Hazy puts its layer on: the one closest to the Material Output."""
    found, _ = surface_bsdfs(tree)
    return found[0] if found else None


# --------------------------------------------------------------------------------------------
# Replacing nodes by the hazy nodes, in place
# --------------------------------------------------------------------------------------------


def _socket_ref(sock):
    return (sock.node.name, sock.identifier, sock.is_output)


def _resolve(tree, ref):
    node = tree.nodes.get(ref[0])
    if node is None:
        return None
    for s in (node.outputs if ref[2] else node.inputs):
        if s.identifier == ref[1]:
            return s
    return None


def replace_with_hazy(mat, replaced, p, links):
    """Remove the nodes ``replaced`` (the first one's output is what the hazy BSDF replaces),
    build the hazy nodes for ``p`` and wire them where that output went.  ``links`` maps group
    input names to the output sockets to connect (textures, normal map).  Returns
    (HazeMapping, names of inputs that could not be linked)."""
    tree = mat.node_tree
    head = replaced[0]
    out = ownership.output_node(tree, create=False)
    if out is None:
        out = tree.nodes.new("ShaderNodeOutputMaterial")
        out.location = (head.location.x + 300, head.location.y)
    surf = out.inputs["Surface"]
    src = _source(surf)
    surf_src = _socket_ref(src) if src is not None and src.node.name != head.name else None
    targets = [_socket_ref(l.to_socket) for l in head.outputs[0].links if l.to_socket != surf]
    link_refs = {name: _socket_ref(s) for name, s in links.items()}
    location = tuple(head.location)
    material.map_parameters(p)  # raises before anything is touched
    for node in replaced:
        tree.nodes.remove(node)
    m, _ = material.apply(mat, p, force_rebuild=True)
    ours = material.hazy_output(tree)
    if surf_src is not None:
        s = _resolve(tree, surf_src)
        if s is not None:
            tree.links.new(s, surf)
    for ref in targets:
        s = _resolve(tree, ref)
        if s is not None:
            tree.links.new(ours, s)
    dropped = []
    group = material.ours(tree).get(material.GROUP_ROLE)
    for name, ref in link_refs.items():
        s = _resolve(tree, ref)
        target = group.inputs.get(name) if group is not None else None
        if s is None or target is None:
            dropped.append(name)
            continue
        tree.links.new(s, target)
    if "Tangent" in link_refs and group is not None:  # the api's own tangent node is unused now
        for n in [n for n in tree.nodes if material.is_ours(n) and n.bl_idname == "ShaderNodeTangent"]:
            if not any(o.is_linked for o in n.outputs):
                tree.nodes.remove(n)
    dx, dy = location[0] - ours.node.location.x, location[1] - ours.node.location.y
    for n in tree.nodes:
        if material.is_ours(n):
            n.location = (n.location.x + dx, n.location.y + dy)
    return m, dropped


def tree_problem(mat):
    """Why ``mat``'s nodes are not what renders it (one line), or None."""
    if getattr(mat, "node_tree", None) is None:
        return f"“{mat.name}” has no node tree (turn Use Nodes on in its Surface panel)"
    if bpy.app.version < (5, 0, 0) and not mat.use_nodes:  # (5.x always renders the nodes)
        return (f"“{mat.name}” does not use its nodes (Use Nodes is off in its Surface panel): "
                f"turn Use Nodes on first")
    return None


def make_hazy(mat, *, haziness=None, haze_extent=None, node=None, **haze):
    """Put a haze layer on ``mat``'s own BSDF (blender.model.layer): ``node`` (a node or its name),
    else the Principled, Metallic or Glossy BSDF closest to the Material Output (also inside
    Mix / Add Shader trees) becomes the layer node, with every input, link and keyframe; at
    haziness 0 the material renders as before.  On a material that has a layer already, the
    haze values given are set on it, the others kept (a new layer: HAZE_DEFAULTS for those not
    given).  Returns (status, message, notes): status "FINISHED" (made hazy or updated) or
    "ERROR"."""
    problem = edit_problem(mat)
    if problem is not None and (mat is None or mat.library is not None
                                or getattr(mat, "override_library", None) is not None):
        return "ERROR", problem, []
    if maps_problem(mat):
        return "ERROR", maps_problem(mat), []
    if tree_problem(mat):
        return "ERROR", tree_problem(mat), []
    if node is not None and not isinstance(node, (str, bpy.types.Node)):
        return "ERROR", f"node must be a node or its name, got {node!r:.40}", []
    given = dict(haze)
    given.update({k: v for k, v in (("haziness", haziness), ("haze_extent", haze_extent))
                  if v is not None})
    if layer.is_layered(mat):
        return _update_layer(mat, given, node)
    if material_read.is_hazy(mat):
        return ("ERROR", f"“{mat.name}” is a hazy material of its own (New Hazy Material): "
                f"change it with its panel or api.update_material", [])
    found, groups = surface_bsdfs(mat.node_tree)
    if node is not None:
        name = node if isinstance(node, str) else node.name
        node = mat.node_tree.nodes.get(name)
        if node is None or node.bl_idname not in CORE_NODES or material.is_ours(node):
            return ("ERROR", f"“{mat.name}” has no Principled, Metallic or Glossy BSDF named "
                    f"“{name}”", [])
    elif found:
        node = found[0]
    elif groups:
        return ("ERROR", f"The BSDF of “{mat.name}” is inside the node group “{groups[0].name}” "
                f"(“{groups[0].node_tree.name if groups[0].node_tree else '?'}”), which other "
                f"materials may share: ungroup it (Ctrl+Alt+G) to add haze to this material", [])
    else:
        return ("ERROR", f"“{mat.name}” has no Principled, Metallic or Glossy BSDF connected to its "
                "Material Output: nothing to make hazy (use New Hazy Material instead)", [])
    try:
        h = normalise_haze(given)
        layer.apply(mat, h, core=node)
    except ValueError as exc:
        return "ERROR", plain_message(exc), []
    notes = []
    others = [n.name for n in found if n != node]
    if others:
        notes.append(f"also found {', '.join('“' + n + '”' for n in others)}, not hazed (one "
                     f"layer per material: pick the BSDF with the operator's Node option)")
    lnode = layer.layer_node(mat)
    notes += layer.notes(mat)
    msg = (f"Made “{mat.name}” hazy: its {node.bl_label} is now the haze layer node “{lnode.name}” "
           f"(every input, link and keyframe kept; haziness {shown(h['haziness'])})")
    return "FINISHED", msg, notes


def apply_imported_haze(mat, node, haze):
    """The haze layer of an imported material (interchange.import_materialx's ``apply_haze``):
    Make Hazy on its BSDF ``node``; ValueError (one line) when it cannot."""
    status, msg, _ = make_hazy(mat, node=node, **haze)
    if status == "ERROR":
        raise ValueError(msg)


def _update_layer(mat, given, node):
    """make_hazy on a material that has a layer: its haze values set (the BSDF stays)."""
    if node is not None:
        name = node if isinstance(node, str) else node.name
        have = layer.layer_node(mat)
        other = mat.node_tree.nodes.get(name)
        if have is not None and name != have.name and (
                other is None or other.bl_idname not in CORE_NODES or material.is_ours(other)):
            return ("ERROR", f"“{mat.name}” has no Principled, Metallic or Glossy BSDF named "
                    f"“{name}” (its haze layer is on “{have.name}”)", [])
        if have is not None and name != have.name:
            return ("ERROR", f"“{mat.name}” has a haze layer on “{have.name}” already (one layer per "
                    f"material): Remove Haze first to put it on “{name}”", [])
    if layer.is_baked(mat):  # (its group has no haze inputs: nothing would change)
        return ("ERROR", baked_problem(mat), []) if given else \
            ("NOOP", f"“{mat.name}” is hazy already: its haze was converted into its maps", [])
    try:
        h = normalise_haze(given, layer.haze_of(mat))
        layer.apply(mat, h)
    except ValueError as exc:
        return "ERROR", plain_message(exc), []
    sync.refresh_derived(mat)  # the EEVEE-only output and the export fallback follow
    return ("FINISHED", f"Updated the haze layer of “{mat.name}” (haziness "
                        f"{shown(h['haziness'])})",
            layer.held_haze(mat, given) + layer.notes(mat))


def remove_haze(mat):
    """Take a haze layer off: the user's BSDF gets its own values and links back and the
    layer's nodes go.  Returns (status, message, notes)."""
    if not layer.is_layered(mat):
        return "NOOP", f"“{mat.name}” has no haze layer: nothing to remove", []
    problem = edit_problem(mat)
    if problem is not None:
        return "ERROR", problem, []
    state = layer.layer_state(mat) or {}
    kept, lnode = layer.original_node(mat), layer.layer_node(mat)
    where = stamp.own_way_out(state.get("problems", []))  # (a grouped or ungrouped layer node)
    if where is not None:  # (it still renders: removing the record would hide it)
        return "ERROR", f"Cannot remove the haze of “{mat.name}”: {where}", []
    if kept is not None and lnode is not None and (
            not kept.mute or kept.outputs[0].is_linked):
        # (Remove Haze gives that node the layer node's values and links: the artist's edits)
        return "ERROR", (f"“{kept.name}” in “{mat.name}” is in use again (un-muted or "
                         f"connected): Remove Haze would overwrite it with the layer node's "
                         f"values; mute and disconnect it, or delete it, then Remove Haze"), []
    notes = []
    if any(keys is None and (".base" in why or why.startswith("layer is"))
           for why, keys in state.get("problems", [])):
        notes.append("the layer's record of the BSDF's own values was damaged: the inputs it "
                     "could not restore keep the values the layer gave them")
    if layer.original_node(mat) is None:
        notes.append("the BSDF kept beside the layer node was deleted: a new one with the "
                     "layer node's values and links takes its place")
    elif layer.layer_node(mat) is None:
        swapped = layer.tagged_layer_node(mat)
        notes.append(f"the layer node “{swapped.name}” uses another group now: it stays, as "
                     f"yours; the BSDF is back beside it, unconnected" if swapped is not None
                     else "the layer node was deleted, and its links with it: the BSDF is "
                          "back, unconnected")
    copies = layer.layer_copies(mat)
    if copies:
        notes.append(f"{', '.join(f'“{n.name}”' for n in copies)}, a copy of the layer node, "
                     f"stay{'s' if len(copies) == 1 else ''} (yours) and still render"
                     f"{'s' if len(copies) == 1 else ''} haze")
    also = ""
    if fallback.remove_export_fallback(mat):  # the user's output active again, as before
        also = ", and its export fallback"
    core = (layer.find_core(mat.node_tree, state.get("core")) if state.get("legacy")
            else layer.original_node(mat))
    label = core.bl_label if core is not None else ""
    lnode = None if state.get("legacy") else layer.layer_node(mat)
    maps = [f"“{l.from_node.image.name}”" for s in (lnode.inputs if lnode else ()) for l in s.links
            if K.PAINTED_MAP in (getattr(l.from_node, "image", None) or {})]
    if maps:
        many = len(maps) > 1
        notes.append(f"the haziness map{'s' if many else ''} {', '.join(maps)} "
                     f"stay{'' if many else 's'} in the tree, unlinked (your paint): delete when "
                     f"no longer needed")
    edited = layer_group.edited_parts(lnode.node_tree) if lnode is not None else []
    if edited:  # (with no user it would be lost on save: the artist's work)
        lnode.node_tree.use_fake_user = True
        notes.append(f"the layer group “{lnode.node_tree.name}”, edited by hand, stays in the "
                     f"file (fake user): delete it when no longer needed")
    layer.remove(mat)
    where = f" from its {label} “{core.name}”" if core is not None else ""
    return "FINISHED", f"Removed the haze layer of “{mat.name}”{where}{also}", notes


# --------------------------------------------------------------------------------------------
# Two-lobe mix -> perceptual parameters
# --------------------------------------------------------------------------------------------

_LOBE_NODES = GLOSSY + ("ShaderNodeBsdfMetallic",)


def find_two_lobe_mix(tree):
    """(mix node, lobe A, lobe B) for a Mix / Add Shader of two Glossy or two Metallic BSDFs
    that feeds the active output's Surface (directly or through other Mix / Add Shaders)."""
    out = ownership.output_node(tree, create=False)
    if out is None:
        return None
    queue = [_source(out.inputs["Surface"])]
    while queue:
        sock = queue.pop(0)
        if sock is None:
            continue
        node = sock.node
        if node.bl_idname in _SHADER_PASS:
            shaders = [s for s in node.inputs if s.type == "SHADER"]
            srcs = [_source(s) for s in shaders]
            nodes = [s.node if s is not None else None for s in srcs]
            if len(nodes) == 2 and all(n is not None and n.bl_idname in _LOBE_NODES and not n.mute
                                       and not material.is_ours(n) for n in nodes) and nodes[0].bl_idname == nodes[1].bl_idname \
                    and nodes[0] != nodes[1]:
                return node, nodes[0], nodes[1]
            queue.extend(srcs)
    return None


def _lobe_alpha(node):
    """(α_x, α_y, rotation in turns) of a Glossy / Metallic lobe in its node's convention,
    rotated so that α_x >= α_y."""
    return lobe_alphas(_value(node, "Roughness", 0.5), float(_value(node, "Anisotropy", 0.0)),
                       float(_value(node, "Rotation", 0.0)), glossy=node.bl_idname in GLOSSY)


def _rot_diff(a, b):
    """Difference of two lobe orientations in turns, modulo a half turn, in [0, 0.25]."""
    d = (a - b) % 0.5
    return min(d, 0.5 - d)


def import_two_lobe_mix(mat):
    """Convert a two-lobe mix to a hazy material in place.  Returns (status, message, notes)."""
    problem = edit_problem(mat)
    if mat is None or mat.library is not None or getattr(mat, "override_library", None) is not None:
        return "ERROR", problem, []
    if _is_live(mat):
        return "NOOP", f"“{mat.name}” is already hazy: nothing to do", []
    if maps_problem(mat):
        return "ERROR", maps_problem(mat), []
    if tree_problem(mat):
        return "ERROR", tree_problem(mat), []
    found = find_two_lobe_mix(mat.node_tree)
    if found is None:
        return ("ERROR", f"“{mat.name}” has no Mix Shader of two Glossy or two Metallic BSDFs "
                "connected to its Material Output", [])
    mix, a, b = found
    notes = []
    if mix.bl_idname == "ShaderNodeMixShader":
        if _source(mix.inputs[0]) is not None:
            notes.append("the mix factor is textured: its value at conversion was used")
        fac = float(np.clip(mix.inputs[0].default_value, 0.0, 1.0))
        w_a, w_b = 1.0 - fac, fac
    else:
        w_a = w_b = 1.0
    la, lb = _lobe_alpha(a), _lobe_alpha(b)
    if la[0] * la[1] <= lb[0] * lb[1]:
        (n_node, n_w, (nx, ny, n_rot)), (w_node, w_w, (wx, wy, w_rot)) = (a, w_a, la), (b, w_b, lb)
    else:
        (n_node, n_w, (nx, ny, n_rot)), (w_node, w_w, (wx, wy, w_rot)) = (b, w_b, lb), (a, w_a, la)
    if n_node.distribution != w_node.distribution:
        notes.append(f"the lobes use {n_node.distribution} and {w_node.distribution}: "
                     f"{n_node.distribution} used for both")
    dist = n_node.distribution
    # express the wide lobe in the narrow lobe's frame (x along its long axis)
    n_iso = abs(nx - ny) <= 1e-9 * nx
    w_iso = abs(wx - wy) <= 1e-9 * wx
    if n_iso and not w_iso:
        n_rot = w_rot
    elif not w_iso:
        d = _rot_diff(w_rot, n_rot)
        if abs(d - 0.25) < 1e-4:
            wx, wy = wy, wx
        elif d > 1e-4:
            notes.append("the lobes are rotated against each other: the halo's orientation "
                         "follows the core's")
    kind = "LEGACY" if n_node.bl_idname in GLOSSY else "CONDUCTOR"
    total_w = n_w + w_w if kind == "CONDUCTOR" else None
    edge_tint = None
    if kind == "CONDUCTOR":
        if mix.bl_idname == "ShaderNodeAddShader":
            notes.append("two added metallic lobes reflect more than 1: scaled to a mix")
        beta = w_w / total_w if total_w > 0 else 0.0
        fresnel = []
        for node in (n_node, w_node):
            if node.fresnel_type == "PHYSICAL_CONDUCTOR":
                fresnel.append(("P", np.asarray(_value(node, "IOR")[:3]),
                                np.asarray(_value(node, "Extinction")[:3])))
            else:
                fresnel.append(("F", np.asarray(_value(node, "Base Color")[:3]),
                                np.asarray(_value(node, "Edge Tint")[:3])))
        (ft, x0, y0), (ft1, x1, y1) = fresnel
        if ft != ft1 or not (np.allclose(x0, x1, rtol=1e-5, atol=1e-7)
                             and np.allclose(y0, y1, rtol=1e-5, atol=1e-7)):
            notes.append("the two lobes have different Fresnel settings: the core lobe's are used "
                         "(Eq. 1 shares one Fresnel term)")
        if ft == "P":
            kw = dict(ior=np.maximum(x0, 0.0), extinction=np.maximum(y0, 0.0))
        else:
            kw = dict(reflectivity=np.clip(x0, 0.0, 1.0))
            edge_tint = _rgb(y0)
            notes.append("F82 lobes became Gulbrandsen's conductor Fresnel (identical at normal "
                         "incidence)")
    else:
        c_n = n_w * np.asarray(_value(n_node, "Color")[:3])
        c_w = w_w * np.asarray(_value(w_node, "Color")[:3])
        refl = c_n + c_w
        ch = int(np.argmax(refl))
        beta = float(c_w[ch] / refl[ch]) if refl[ch] > 0 else 0.0
        if not np.allclose(c_w, beta * refl, rtol=1e-4, atol=1e-6):
            notes.append("the two lobes have different colours: Eq. 1 needs one colour (the "
                         "brightest channel's ratio is used)")
        kw = dict(reflectivity=np.clip(refl, 0.0, 1.0))
        if np.any(refl > 1.0):
            notes.append("the lobes reflect more than 1 in total: clamped")
    inv = inverse_haze_mapping(beta, (nx, ny), (wx, wy), distribution=dist, alpha_max=1.0, **kw)
    notes.extend(inv.warnings)
    rough = math.sqrt(math.sqrt(nx * ny))
    ratio = ny / nx if nx > 0 else 1.0
    aniso = float(metallic_anisotropy(ratio))
    if ratio < 0.1 - 1e-9:
        notes.append("core anisotropy beyond 10:1 limited")
    params = dict(kind=kind, distribution=dist if dist in K.NODE_DISTRIBUTIONS[kind] else "GGX",
                  core_reflectivity=tuple(float(x) for x in inv.core_reflectivity),
                  edge_tint=edge_tint if edge_tint is not None else
                  tuple(float(x) for x in inv.edge_tint),
                  roughness=rough, anisotropy=aniso, rotation=n_rot,
                  haziness=float(inv.haziness),
                  haze_extent=(float(inv.haze_extent[0]), float(inv.haze_extent[1])),
                  shader_mapping=False)
    links = {}
    normals = {_socket_ref(s) if s is not None else None
               for s in (_source(n_node.inputs.get("Normal")), _source(w_node.inputs.get("Normal")))}
    if len(normals) == 1 and None not in normals:
        links["Normal"] = _source(n_node.inputs["Normal"])
    elif len(normals) > 1:
        notes.append("the lobes use different normals: the core lobe's is used")
        if _source(n_node.inputs.get("Normal")) is not None:
            links["Normal"] = _source(n_node.inputs["Normal"])
    if aniso > 0 or not w_iso:
        t = _source(n_node.inputs.get("Tangent"))
        if t is not None:
            links["Tangent"] = t
        else:
            params["tangent"] = "RADIAL_Z"
    for node in (n_node, w_node):
        for name in ("Roughness", "Color", "Base Color", "Edge Tint", "IOR", "Extinction",
                     "Anisotropy", "Rotation"):
            if _source(node.inputs.get(name)) is not None:
                notes.append(f"the texture on {node.name}'s {name} was not carried over")
    if links:
        params["shader_mapping"] = True
    lobe_label = n_node.bl_label  # the nodes are removed below
    try:
        p = normalise(params)
        m = material.map_parameters(p)
        m, dropped = replace_with_hazy(mat, [mix, n_node, w_node], p, links)
    except ValueError as exc:
        return "ERROR", plain_message(exc), notes
    # how close is the result to the original two lobes?
    dev = abs(float(m.beta) - beta)
    for got, want in zip((float(v) for v in m.alpha_wide), (wx, wy)):
        dev = max(dev, abs(got - want) / max(want, 1e-12))
    if not bool(np.all(inv.exact)) or dev > 1e-3:
        notes.append(f"not exactly representable (largest relative difference {dev:.2g})")
    msg = (f"Imported the two {lobe_label} lobes of “{mat.name}”: haziness "
           f"{params['haziness']:.3g}, haze extent {params['haze_extent'][0]:.3g}"
           + (f" x {params['haze_extent'][1]:.3g}" if params['haze_extent'][0] != params['haze_extent'][1] else ""))
    return "FINISHED", msg, notes


# --------------------------------------------------------------------------------------------
# Haze layers: upgrade, paintable haziness
# --------------------------------------------------------------------------------------------


def materials_or_all(materials):
    """``materials`` as a list, or every material of the file when it is None; TypeError (one
    line) for what is not a collection of them (one material is put in a list)."""
    if materials is None:
        return list(bpy.data.materials)
    if isinstance(materials, bpy.types.Material):
        return [materials]
    if isinstance(materials, (str, bytes)) or not hasattr(materials, "__iter__"):
        raise TypeError(f"upgrade_layers expects a list of materials, or None for all of the "
                        f"file's; got {type(materials).__name__} {materials!r:.40}")
    return list(materials)


def upgrade_layers(materials, every=False):
    """Move the layer nodes among ``materials`` on another Blender's or add-on's group to this
    one's; ``every`` (the file's materials, none named) passes over linked ones with a note.
    Returns (status, message, notes)."""
    done, notes, linked = [], [], []
    for mat in materials:
        if layer.outdated_group(mat) is None:
            continue
        if every and mat.library is not None:
            linked.append(mat)
            continue
        problem = edit_problem(mat)
        if problem is not None:
            notes.append(problem)
            continue
        try:
            layer.refresh_group(mat)
        except ValueError as exc:
            notes.append(f"“{mat.name}”: {plain_message(exc)}")
            continue
        messages.clear_error(mat)
        sync.refresh_derived(mat)  # a requested EEVEE-only output is rebuilt on the layer node
        error = messages.error_for(mat)
        if error:
            notes.append(f"“{mat.name}”: upgraded, but {error[:1].lower()}{error[1:]}")
        done.append(mat.name)
    failed = bool(notes)
    if linked:
        libs = sorted({bpy.path.basename(m.library.filepath) for m in linked})
        notes.append(f"{len(linked)} linked material{'s' if len(linked) != 1 else ''} with an "
                     f"earlier layer left as they are (read-only here): upgrade "
                     f"{'them' if len(linked) != 1 else 'it'} in {', '.join(libs)}")
    if not done and not failed:
        return "NOOP", "No haze layer of an earlier Hazy Gloss or another Blender to upgrade", notes
    msg = (f"Upgraded {len(done)} haze layer{'s' if len(done) != 1 else ''} to this Blender's "
           f"layer node"
           + (f": {', '.join('“' + n + '”' for n in done)}" if done else ""))
    return ("FINISHED" if done else "ERROR"), msg, notes


def add_haziness_map(mat, *, size=1024, param="haziness"):
    """A paintable image linked to the layer node's haziness (or ``param``: coat_haziness):
    an Image Texture with a new float, Non-Color image filled with the current value, made the
    active paint slot.  The image is packed into the file (farm-safe), and packed again on
    every save once painted.  Returns (status, message, notes)."""
    problem = edit_problem(mat)
    if problem is not None:
        return "ERROR", problem, []
    node = layer.layer_node(mat)
    if node is None:
        problems = (layer.layer_state(mat) or {}).get("problems")
        return "ERROR", (stamp.layer_problem(mat, problems) if problems else
                         f"“{mat.name}” has no haze layer node: Make Hazy first"), []
    if param not in ("haziness", "coat_haziness"):
        return "ERROR", f"param must be haziness or coat_haziness, got {param!r}", []
    sock = node.inputs.get(HAZE_SOCKETS[param][0])
    if sock is None:
        return "ERROR", f"the layer of “{mat.name}” has no {HAZE_SOCKETS[param][0]} input", []
    if sock.is_linked:
        return ("ERROR", f"{sock.name} of “{node.name}” is linked to “{sock.links[0].from_node.name}” "
                f"already: disconnect it first to paint a map instead", [])
    if isinstance(size, bool) or not isinstance(size, (int, float, np.integer)) or \
            not (math.isfinite(size) and size == int(size) and 16 <= size <= 16384):
        return "ERROR", f"size must be a whole number of pixels, 16 to 16384, got {size!r}", []
    size = int(size)
    tree = mat.node_tree
    kept = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeTexImage" and n.image is not None
                 and n.image.get(K.PAINTED_MAP) == param and not n.outputs["Color"].is_linked), None)
    if kept is not None:  # (the map painted before a Remove Haze: this layer takes it back)
        tree.links.new(kept.outputs["Color"], sock)
        tree.nodes.active = kept
        return ("FINISHED", f"Linked the map “{kept.image.name}” painted before to {sock.name} of "
                f"“{node.name}” (Texture Paint: it is the active paint slot)",
                _map_notes(mat, node, sock))
    value = float(sock.default_value)
    img = bpy.data.images.new(f"{mat.name} {sock.name}", size, size, alpha=False,
                              float_buffer=True, is_data=True)
    px = np.full(size * size * 4, value, np.float32)
    px[3::4] = 1.0
    img.pixels.foreach_set(px)
    img.pack()  # (a generated image is packed only once it has pixels: as OpenEXR)
    img[K.PAINTED_MAP] = param  # (packed again on save once painted: sync.repack_painted_maps)
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.label = f"{sock.name} Map"
    tex.location = (node.location.x - 320.0, node.location.y - 120.0)
    tex.parent = node.parent
    tree.links.new(tex.outputs["Color"], sock)
    tree.nodes.active = tex
    return ("FINISHED", f"Linked a paintable {size}x{size} map “{img.name}” to {sock.name} "
            f"of “{node.name}” (Texture Paint: it is the active paint slot)",
            _map_notes(mat, node, sock, filled=value))


def _map_notes(mat, node, sock, filled=None):
    """What to know about a map just linked into ``sock`` (``filled``: the value a new map
    holds): keys it overrides, no UV map to paint with."""
    notes = []
    if sock.name in layer.animated_inputs(node):  # (linked, the input no longer reads them)
        held = f" (filled with this frame's value, {filled:.4g})" if filled is not None else ""
        notes.append(f"{sock.name} was animated: the map{held} decides it now, and its keys or "
                     f"driver do nothing while the map is linked")
    objs = [o for o in bpy.data.objects if o.type == "MESH" and
            any(s.material == mat for s in o.material_slots)]
    if objs and not any(o.data.uv_layers for o in objs):
        notes.append("the objects using it have no UV map: add one to paint the map")
    return notes
