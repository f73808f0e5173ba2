# SPDX-License-Identifier: GPL-3.0-or-later
"""An EEVEE-only simplification of a haze layer (blender.model.layer): the layer node's "EEVEE" output
(each layer's lobes folded into one BSDF that keeps its peaks) on a second Material Output with
target EEVEE.

Why.  EEVEE (4.2-5.3) stores at most three closures per pixel (G-buffer bins): diffuse,
subsurface, refraction and translucency share bin 0, reflections get bin 1 or bins 1 and 2.  A
material with more than one reflection closure (two Glossy / Principled BSDFs, or one Principled
with a coat) is flagged "clear coat" and its reflection closures alternate between the two
reflection bins in the order the shader evaluates them; a Principled BSDF evaluates its coat,
then its (metal + dielectric) specular, then its diffuse.  When two or more closures land in the
same bin, EEVEE keeps one per pixel and sample, picked at random in proportion to its weight and
scaled by total / chosen weight (reservoir sampling: eevee_nodetree_closures_lib; the random
number changes with every TAA sample).  Nothing is dropped and the mean is right, but lobes of
different roughness that share a bin turn into noise that only TAA samples average out.

For a haze layer that means (measured in docs/performance.md section 7): a layer on a
Principled BSDF with a coat (Coat Weight > 0 or linked), hazy coat or not, puts the narrow and
the wide lobe of one layer in each bin: noisy until many TAA samples are taken; the other
layers keep one roughness per bin.

What.  The layer's group computes, beside the full layer, one copy of the core whose lobes are
each layer's narrow and wide lobes folded into one (core.layer_graph, mapping.md §12):

    1/α_f² = (1 - β)/α_n² + β/α_w²,   i.e.  R_f = R_n ((1 - β) + β (R_n / R_w)⁴)^(-1/4)

with the layer's raised F(0): the same peak and about the same energy, a single lobe's halo
instead of the two-scale one.  A metallic map folds into the one copy by the map (Metallic =
the map, Roughness and Base Color mixed by it: exact at texels 0 and 1).  :func:`add_eevee_output`
puts that output on a Material Output with target EEVEE; Blender renders EEVEE through it and
Cycles through the ALL one (checked in 4.5, 5.2 and 5.3).  The user's shader nodes between the
layer node and the output (a Mix / Add Shader) are duplicated for it (their other inputs are
linked, not copied).  Since the group computes the folded lobe from the layer node's inputs,
the output follows every change of them by itself; only a change of the path to the output
needs :func:`sync_eevee_output` (the request is kept in the material's stamp, key "eevee").
Every node made here carries the role ``"layer eevee ..."`` (constants.ROLE).
"""
from __future__ import annotations

from ... import constants as K
from ..model import fallback, layer
from ..model.material_read import edit_problem
from ..nodes import ownership

__all__ = ("ROLE", "OUTPUT_ROLE", "MODE_KEY", "STAMP_KEY", "MODES", "eevee_nodes",
           "has_eevee_output", "remove_nodes", "requested_mode", "follows_the_user",
           "remove_eevee_output", "needs_eevee_output", "add_eevee_output", "build_eevee_output",
           "sync_eevee_output")

ROLE = K.EEVEE_ROLE
OUTPUT_ROLE = K.EEVEE_OUTPUT_ROLE
MODE_KEY = "hazy_gloss_eevee_mode"
STAMP_KEY = "eevee"  # in the material's stamp (constants.STAMP): {"mode": ...}
MODES = ("auto", "always")
_PATH_TYPES = ("ShaderNodeMixShader", "ShaderNodeAddShader", "NodeReroute")


def eevee_nodes(tree):
    """{role: node} of this module's nodes in ``tree``."""
    return {r: n for r, n in ownership.ours(tree).items() if r.startswith(ROLE)}


def has_eevee_output(mat):
    return mat is not None and mat.node_tree is not None and OUTPUT_ROLE in eevee_nodes(mat.node_tree)


def remove_nodes(mat):
    """Remove every node built here (the request stays); returns whether there were any."""
    return ownership.remove_roles(mat.node_tree, ROLE)


def requested_mode(mat):
    """The mode :func:`add_eevee_output` was last asked for on ``mat`` (kept in the material's
    stamp), or None."""
    mode = _request(mat).get("mode")
    return mode if mode in MODES else None  # a damaged request is no request


def _request(mat):
    """The request kept in the material's stamp ({"mode", "follows"}), {} when none reads."""
    d = mat.get(K.STAMP)
    e = d.get(STAMP_KEY) if hasattr(d, "get") else None
    return e if hasattr(e, "get") else {}


def _set_request(mat, mode, follows=""):
    d = mat.get(K.STAMP)
    if not hasattr(d, "get"):
        return
    d = d.to_dict() if hasattr(d, "to_dict") else dict(d)
    if mode is None:
        d.pop(STAMP_KEY, None)
    else:
        d[STAMP_KEY] = {"mode": mode, "follows": follows}
    mat[K.STAMP] = d


def follows_the_user(mat):
    """Whether the EEVEE output was built from the output the artist has now (the active one
    of theirs for all engines): after they switch to another, it is rebuilt from that one
    (sync.sync), else EEVEE would keep rendering the layer through it."""
    was = _request(mat).get("follows", "")
    user_out, _ = _eevee_output_of_user(mat.node_tree)
    return was == (user_out.name if user_out is not None else "")


def remove_eevee_output(mat):
    """Remove the EEVEE-only output and forget the request.  Returns whether there was one."""
    _refuse_linked(mat)
    had = remove_nodes(mat)
    _set_request(mat, None)
    _refresh_fallback(mat)
    return had


def _refuse_linked(mat):
    """Linked and overridden materials are read-only here, as for every other entry point."""
    if mat is not None and (mat.library is not None or
                            getattr(mat, "override_library", None) is not None):
        raise ValueError(edit_problem(mat))


def _refresh_fallback(mat):
    """An export fallback's EEVEE render output gives way to ours and comes back without it."""
    fallback.refresh_stamped_fallback(mat)


def _layer_node(mat):
    node = layer.layer_node(mat)
    if node is None:
        raise ValueError(f"{mat.name!r} has no haze layer (Make Hazy first)")
    return node


def needs_eevee_output(mat):
    """(whether EEVEE renders the layer with roughness noise, the reason in one sentence)."""
    node = layer.layer_node(mat)
    coat = node.inputs.get("Coat Weight") if node is not None else None
    if coat is not None and (coat.is_linked or coat.default_value > 0.0):
        return True, ("a Principled BSDF with a coat: its layer's coat and specular closures "
                      "alternate between EEVEE's two reflection bins, so each bin holds a narrow "
                      "and a wide lobe and EEVEE picks one at random per pixel")
    return False, ("every EEVEE reflection bin holds lobes of one roughness (narrow lobes in one "
                   "bin, wide lobes in the other): no roughness noise")


def _tag(node, role):
    node[K.ROLE] = role
    node.name = f"{K.NODE_PREFIX} {role}"
    node.label = "Hazy Gloss " + role[len("layer "):]


def _read(sock):
    """What feeds an input: the output socket linked into it, else its value."""
    if sock.is_linked:
        link = sock.links[0]
        if not getattr(link, "is_muted", False) and getattr(link, "is_valid", True):
            return link.from_socket
    if not hasattr(sock, "default_value"):
        return None
    v = sock.default_value
    return tuple(v) if hasattr(v, "__len__") else v


def _eevee_output_of_user(tree):
    """The output EEVEE renders now (the user's), or a reason why none can be added."""
    outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"
            and not ownership.is_ours(n)]  # an export fallback's outputs are not the user's
    if any(n.target == "EEVEE" for n in outs):
        return None, ("the material already has an EEVEE output of its own: EEVEE renders what "
                      "that output is given")
    alls = [n for n in outs if n.target == "ALL"]
    if not alls:
        return None, "the material has no output for all engines: EEVEE renders the full layer"
    return next((n for n in alls if n.is_active_output), alls[0]), None


def add_eevee_output(mat, *, mode="auto"):
    """Give the layered material ``mat`` an EEVEE-only output (:func:`build_eevee_output`) and
    bring an export fallback up to date with it."""
    _refuse_linked(mat)
    info = build_eevee_output(mat, mode=mode)
    _refresh_fallback(mat)
    return info


def build_eevee_output(mat, *, mode="auto"):
    """Give the layered material ``mat`` an EEVEE-only output fed by the layer node's EEVEE
    socket (module docstring).  ``mode``: "auto" builds it only where EEVEE would pick between
    lobes of different roughness at random (a Principled core with a coat, see
    :func:`needs_eevee_output`); "always" for any layer.  Replaces an existing one.

    Returns ``{"added": bool, "reason": str, "nodes": int}``; raises ValueError when ``mat`` has
    no layer.  Touches nothing of the user's nodes nor the layer node."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    node = _layer_node(mat)
    remove_nodes(mat)
    tree = mat.node_tree
    user_out, problem = _eevee_output_of_user(tree)
    _set_request(mat, mode, user_out.name if user_out is not None else "")
    needed, why = needs_eevee_output(mat)
    if mode == "auto" and not needed:
        return dict(added=False, reason=why, nodes=0)
    final = node.outputs["BSDF"]
    if problem is None:
        path, problem = _path(user_out, final)
        if problem is not None:
            problem += ": EEVEE renders the full layer"
    if problem is not None:
        return dict(added=False, reason=problem, nodes=0)
    made = []
    copies = {}

    def dup(sock):
        src = sock.node
        if sock == final:
            return node.outputs["EEVEE"]
        if src.name not in path:
            return sock
        if src.name not in copies:
            n = tree.nodes.new(src.bl_idname)
            _tag(n, f"{ROLE}path {len(copies)}")
            n.location = (src.location.x, src.location.y - 260.0)
            n.hide = True
            copies[src.name] = n
            made.append(n)
            for s, d in zip(src.inputs, n.inputs):
                v = _read(s)
                if hasattr(v, "node"):
                    tree.links.new(dup(v), d)
                elif v is not None and hasattr(d, "default_value"):
                    d.default_value = v
        return copies[src.name].outputs[sock.identifier]

    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.target = "EEVEE"
    _tag(out, OUTPUT_ROLE)
    out[MODE_KEY] = mode
    out.location = (user_out.location.x, user_out.location.y - 260.0)
    made.append(out)
    for s, d in zip(user_out.inputs, out.inputs):
        v = _read(s)
        if hasattr(v, "node"):
            tree.links.new(dup(v) if s.name == "Surface" else v, d)
        elif v is not None and hasattr(d, "default_value"):
            d.default_value = v
    user_out.is_active_output = True  # the user's output stays the one the editor shows
    return dict(added=True, reason=why if needed else "requested (mode 'always')",
                nodes=len(made))


def _path(user_out, final):
    """Names of the nodes between the layer node's output (``final``) and ``user_out``'s
    Surface, or a reason why they cannot be duplicated."""
    sock = user_out.inputs["Surface"]
    if not sock.is_linked:
        return None, "nothing is connected to the output's Surface"
    memo = {}

    def reaches(node):
        if node.name in memo:
            return memo[node.name]
        memo[node.name] = False
        hit = False
        for s in node.inputs:
            for link in s.links:
                if link.from_socket == final or reaches(link.from_node):
                    hit = True
        memo[node.name] = hit
        return hit

    src = sock.links[0].from_socket
    if src == final:
        return set(), None
    if not reaches(src.node):
        return None, "the layer does not reach the output's Surface"
    path = {name for name, hit in memo.items() if hit}
    bad = [name for name in path if user_out.id_data.nodes[name].bl_idname not in _PATH_TYPES]
    if bad:
        n = user_out.id_data.nodes[bad[0]]
        return None, f"the layer reaches the output through “{n.name}” ({n.bl_idname})"
    return path, None


def sync_eevee_output(mat):
    """Rebuild the EEVEE output of ``mat`` in the mode it was requested with (after the path
    between the layer node and the output changed); nothing when none was requested.  Returns
    whether the material has an EEVEE output now."""
    out = eevee_nodes(mat.node_tree).get(OUTPUT_ROLE)
    mode = requested_mode(mat) or (out.get(MODE_KEY) if out is not None else None)
    if mode is None:
        return False
    if not layer.is_layered(mat):
        remove_nodes(mat)
        return False
    return build_eevee_output(mat, mode=mode)["added"]
