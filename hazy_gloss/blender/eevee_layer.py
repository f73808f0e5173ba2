# SPDX-License-Identifier: GPL-3.0-or-later
"""An EEVEE-only simplification of a haze layer (blender.layer): one BSDF whose lobes keep the
layer's peaks, on a second Material Output with target EEVEE.

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

For a haze layer that means (measured in docs/performance.md section 7):

* dielectric, metal, Metallic / Glossy BSDF (2 BSDFs), and a metallic map (4 BSDFs, the two
  narrow lobes share one bin, the two wide ones the other): every bin holds lobes of one
  roughness: no roughness noise (a metallic map's fractional texels get colour noise);
* any Principled core with a coat (Coat Weight > 0 or linked), hazy coat or not: the coat and
  specular closures of every copy alternate, so each bin gets the narrow *and* the wide lobe of
  one layer: noisy until many TAA samples are taken.

What.  :func:`add_eevee_output` builds, next to the layer, ONE copy of the core (per material,
also for a metallic map) whose lobes are the layer's narrow and wide lobes folded into one per
layer, keeping each layer's peak: the β-weighted mean of 1/α²,

    1/α_f² = (1 - β)/α_n² + β/α_w²,   i.e.  R_f = R_n ((1 - β) + β (R_n / R_w)⁴)^(-1/4)

(Blender's roughness R = √α), with the layer's raised F(0) (its IOR, Base Color or coat IOR).
The peak of a GGX lobe is F(0)/(π α²), so the folded lobe has the layer's peak (Eq. 2 of the
paper: the layer's peak is the user's) and its F(0), i.e. about its energy; what it loses is the
two-scale shape: the halo's long tail becomes a slightly wider single lobe.  A metallic map is
folded into the one copy by the map: Metallic = the map, Roughness and Base Color mixed by it
(exact at texels 0 and 1).  The tree then has one coat and one specular closure per pixel (plus
the diffuse): deterministic in EEVEE at any TAA sample count, and one Principled BSDF to shade
instead of 2-8.

The user's Material Output is not touched: Blender renders EEVEE through an output with target
EEVEE when there is one (an exact target is preferred to ALL, whichever is active) and Cycles
through the ALL one (checked in 4.5, 5.2 and 5.3), so removing these nodes, by
:func:`remove_eevee_output`, by the layer rebuilding itself or by Remove Haze (both remove every
node whose role starts with "layer "), gives EEVEE the full layered tree back.  Shader nodes
between the layer and the output (a Mix / Add Shader of the user's) are duplicated for the EEVEE
output; the user's other inputs are linked, not copied.

The copy holds the core's values as they are when it is built: after the core or the haze
changes, call :func:`sync_eevee_output`, which also rebuilds the output after the layer rebuilt
itself (the request is kept in the material's stamp, key "eevee", which the layer keeps and
Remove Haze drops).  Every node made here carries the role ``"layer eevee ..."``
(constants.ROLE).
"""
from __future__ import annotations

from .. import constants as K
from ..core import node_math
from ..core.graph import Graph
from . import layer
from .nodes import ownership
from .nodes.builder import TreeBuilder
from .nodes.emit import emit

ROLE = "layer eevee "
OUTPUT_ROLE = K.EEVEE_OUTPUT_ROLE
assert OUTPUT_ROLE.startswith(ROLE)
BSDF_ROLE = ROLE + "bsdf"
MODE_KEY = "hazy_gloss_eevee_mode"
STAMP_KEY = "eevee"  # in the material's stamp (constants.STAMP): {"mode": ...}
MODES = ("auto", "always")
_PATH_TYPES = ("ShaderNodeMixShader", "ShaderNodeAddShader")


def eevee_nodes(tree):
    """{role: node} of this module's nodes in ``tree``."""
    return {r: n for r, n in ownership.ours(tree).items() if r.startswith(ROLE)}


def has_eevee_output(mat):
    return mat is not None and mat.node_tree is not None and OUTPUT_ROLE in eevee_nodes(mat.node_tree)


def _remove_nodes(mat):
    nodes = eevee_nodes(mat.node_tree)
    for n in nodes.values():
        mat.node_tree.nodes.remove(n)
    return bool(nodes)


def requested_mode(mat):
    """The mode :func:`add_eevee_output` was last asked for on ``mat`` (kept in the material's
    stamp, which the layer keeps when it rebuilds and drops on Remove Haze), or None."""
    d = mat.get(K.STAMP)
    e = d.get(STAMP_KEY) if hasattr(d, "get") else None
    mode = e.get("mode") if hasattr(e, "get") else None
    return mode if mode in MODES else None  # a damaged request is no request


def _set_request(mat, mode):
    d = mat.get(K.STAMP)
    if not hasattr(d, "get"):
        return
    d = d.to_dict() if hasattr(d, "to_dict") else dict(d)
    if mode is None:
        d.pop(STAMP_KEY, None)
    else:
        d[STAMP_KEY] = {"mode": mode}
    mat[K.STAMP] = d


def remove_eevee_output(mat):
    """Remove the EEVEE-only output and everything built for it, and forget the request (so
    :func:`sync_eevee_output` does not bring it back).  Returns whether there was one."""
    had = _remove_nodes(mat)
    _set_request(mat, None)
    _refresh_fallback(mat)
    return had


def _refresh_fallback(mat):
    """An export fallback's EEVEE render output gives way to ours and comes back without it."""
    from . import interchange
    interchange.refresh_stamped_fallback(mat)


def _plan(mat):
    if not layer.is_layered(mat):
        raise ValueError(f"{mat.name!r} has no haze layer (Make Hazy first)")
    state = layer.layer_state(mat) or {}
    core = layer.find_core(mat.node_tree, state.get("core"))
    if core is None:
        raise ValueError(f"the core node of {mat.name!r} is gone: Remove Haze and Make Hazy again")
    return layer.Plan(core, layer.haze_of(mat), dict(state.get("base", {})))


def _has_coat(core):
    sock = core.inputs.get("Coat Weight")
    return sock is not None and (sock.is_linked or sock.default_value > 0.0)


def needs_eevee_output(mat):
    """(whether EEVEE renders the layer with roughness noise, the reason in one sentence)."""
    plan = _plan(mat)
    if not plan.active:
        return False, "the layer holds no node (haziness 0): the material is the user's"
    if plan.type == "PRINCIPLED" and _has_coat(plan.core):
        return True, ("a Principled BSDF with a coat: its layer's coat and specular closures "
                      "alternate between EEVEE's two reflection bins, so each bin holds a narrow "
                      "and a wide lobe and EEVEE picks one at random per pixel")
    return False, ("every EEVEE reflection bin holds lobes of one roughness (narrow lobes in one "
                   "bin, wide lobes in the other): no roughness noise")


# --------------------------------------------------------------------------------------------
# Values: a Python constant or a node output socket
# --------------------------------------------------------------------------------------------


class _Values:
    """The EEVEE copy's inputs as core.graph expressions: what feeds an input becomes a graph
    input (a linked socket) or a constant; ``emit`` builds the nodes the results need."""

    def __init__(self):
        self.g = Graph()
        self.sources = {}
        self._names = {}

    def __call__(self, v, colour=False):
        """An Expr for ``v`` (a socket, a number or a colour) read as a number or, ``colour``,
        as a colour (Blender converts a linked socket of the other kind as its input does)."""
        if _is_socket(v):
            key = (v.node.name, v.identifier, colour)
            if key not in self._names:
                name = f"s{len(self._names)}"
                self._names[key] = name
                self.sources[name] = v
            return self.g.input(self._names[key], vector=colour)
        if colour:
            v = tuple(float(x) for x in v[:3]) if hasattr(v, "__len__") else (float(v),) * 3
            return self.g.const(v)
        return self.g.const(float(v[0]) if hasattr(v, "__len__") else float(v))

    def emit(self, tree, outputs, x, y):
        """``outputs`` (name -> Expr) as sockets or constants; the nodes made are tagged and
        hidden below the core.  Returns (values, number of nodes)."""
        tb = TreeBuilder(tree, x0=x, y0=y)
        out = emit(tb, self.g, outputs, self.sources)
        for i, n in enumerate(tb.created):
            _tag(n, f"{ROLE}math {i}")
            n.hide = True
        return out, len(tb.created)


def _is_socket(v):
    return hasattr(v, "node") and hasattr(v, "is_linked")


def _rgba(v):
    if _is_socket(v):
        return v
    v = tuple(float(x) for x in v)
    return v[:3] + (1.0,) if len(v) >= 3 else (v[0],) * 3 + (1.0,)


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


def _mix_factor(node):
    """β of a layer Mix Shader (its Fac input)."""
    return _read(node.inputs[0])


# --------------------------------------------------------------------------------------------
# Building
# --------------------------------------------------------------------------------------------


def _tag(node, role):
    node[K.ROLE] = role
    node.name = f"{K.NODE_PREFIX} {role}"
    node.label = "Hazy Gloss " + role[len("layer "):]


def _layer_node(tree, role):
    return ownership.ours(tree).get("layer " + role)


def _overrides(mat, plan, val):
    """{input name: Expr} the EEVEE copy of the core gets instead of the core's own (``val``:
    the _Values the expressions belong to)."""
    tree = mat.node_tree
    core = plan.core
    slots = layer._existing(tree, plan)
    first = plan.parts[0] if plan.parts else None
    g = val.g
    out = {}
    rough_name = "Roughness"
    if plan.parts:
        folded = {}
        for part in plan.parts:
            narrow, wide = slots[(part, False, False)], slots[(part, True, False)]
            mix = _layer_node(tree, f"Mix {part.lower()}")
            if part == "GLOSSY":  # an Add Shader of k_n = (1-β) r and k_w = β r
                cn = val(_read(narrow.inputs["Color"]), colour=True)
                cw = val(_read(wide.inputs["Color"]), colour=True)
                sn, sw = g.dot(cn, (1.0, 1.0, 1.0)), g.dot(cw, (1.0, 1.0, 1.0))
                beta = g.div(sw, g.maximum(g.add(sn, sw), 1e-12))
                out["Color"] = g.vmath("ADD", cn, cw)
            else:
                beta = val(_mix_factor(mix))
            folded[part] = node_math.folded_roughness(g, beta, val(_read(narrow.inputs[rough_name])),
                                                      val(_read(wide.inputs[rough_name])))
        if plan.split:  # one copy for both parts: mixed by the user's metallic source
            metal = val(_mix_factor(_layer_node(tree, "Mix metallic")))
            d, k = folded["DIELECTRIC"], folded["METAL"]
            out[rough_name] = g.madd(metal, g.sub(k, d), d)
            out["Metallic"] = metal
            colour = lambda part: val(_read(slots[(part, False, False)].inputs["Base Color"]),  # noqa: E731
                                      colour=True)
            # the Mix Shader's factor is clamped: so is this one
            out["Base Color"] = g.mix(g.clamp(metal, 0.0, 1.0), colour("DIELECTRIC"), colour("METAL"))
        else:
            out[rough_name] = folded[first]
    if plan.coat:
        cw = slots[(first, False, True)]
        out["Coat Roughness"] = node_math.folded_roughness(
            g, val(_mix_factor(_layer_node(tree, "Mix coat"))),
            val(_read(core.inputs["Coat Roughness"])), val(_read(cw.inputs["Coat Roughness"])))
    return out


def _eevee_output_of_user(tree):
    """The output EEVEE renders now (the user's), or a reason why none can be added."""
    outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"
            and not ownership.is_ours(n)]  # an export fallback's outputs are not the user's
    if any(n.target == "EEVEE" for n in outs):
        return None, "the material already has an EEVEE output of its own"
    alls = [n for n in outs if n.target == "ALL"]
    if not alls:
        return None, "the material has no output for all engines"
    return next((n for n in alls if n.is_active_output), alls[0]), None


def add_eevee_output(mat, *, mode="auto"):
    """Give the layered material ``mat`` an EEVEE-only output (:func:`build_eevee_output`) and
    bring an export fallback up to date with it."""
    info = build_eevee_output(mat, mode=mode)
    _refresh_fallback(mat)
    return info


def build_eevee_output(mat, *, mode="auto"):
    """Give the layered material ``mat`` an EEVEE-only output fed by one BSDF with the layer's
    lobes folded (module docstring).  ``mode``: "auto" builds it only where EEVEE would pick
    between lobes of different roughness at random (a Principled core with a coat, see
    :func:`needs_eevee_output`); "always" builds it for any layered material (one BSDF to shade
    in EEVEE instead of 2-8).  Replaces an existing one.

    Returns ``{"added": bool, "reason": str, "nodes": int}``; raises ValueError when ``mat`` has
    no layer.  Touches nothing of the user's or of the layer's own nodes."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    plan = _plan(mat)
    _remove_nodes(mat)
    _set_request(mat, mode)
    needed, why = needs_eevee_output(mat)
    if not plan.active:
        return dict(added=False, reason=why, nodes=0)
    if mode == "auto" and not needed:
        return dict(added=False, reason=why, nodes=0)
    tree = mat.node_tree
    user_out, problem = _eevee_output_of_user(tree)
    final = layer._final(tree)
    if problem is None and final is None:
        problem = "the layer's last mix is gone"
    if problem is None:
        path, problem = _path(user_out, final)
    if problem is not None:
        return dict(added=False, reason=problem + ": EEVEE renders the full layer", nodes=0)

    core = plan.core
    made = []
    val = _Values()
    over, n_math = val.emit(tree, _overrides(mat, plan, val), core.location.x - 1400.0,
                            core.location.y - 700.0)
    bsdf = tree.nodes.new(core.bl_idname)
    for prop in layer._NODE_PROPS.get(core.bl_idname, ()):
        setattr(bsdf, prop, getattr(core, prop))
    _tag(bsdf, BSDF_ROLE)
    bsdf.location = (core.location.x, core.location.y - 600.0)
    bsdf.width = core.width
    bsdf.hide = True
    made.append(bsdf)
    for src, dst in zip(core.inputs, bsdf.inputs):
        if src.identifier != dst.identifier:
            continue
        v = over[src.name] if src.name in over else _read(src)
        if _is_socket(v):
            tree.links.new(v, dst)
        elif v is not None and hasattr(dst, "default_value"):
            dst.default_value = _rgba(v) if dst.type == "RGBA" else (
                tuple(v) if hasattr(v, "__len__") else v)

    # the user's shader nodes between the layer and the output, duplicated
    copies = {}

    def dup(sock):
        node = sock.node
        if sock == final:
            return bsdf.outputs[0]
        if node.name not in path:
            return sock
        if node.name not in copies:
            n = tree.nodes.new(node.bl_idname)
            _tag(n, f"{ROLE}path {len(copies)}")
            n.location = (node.location.x, node.location.y - 600.0)
            n.hide = True
            copies[node.name] = n
            made.append(n)
            for s, d in zip(node.inputs, n.inputs):
                v = _read(s)
                if _is_socket(v):
                    tree.links.new(dup(v), d)
                elif v is not None and hasattr(d, "default_value"):
                    d.default_value = v
        return copies[node.name].outputs[sock.identifier]

    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.target = "EEVEE"
    _tag(out, OUTPUT_ROLE)
    out[MODE_KEY] = mode
    out.location = (user_out.location.x, user_out.location.y - 260.0)
    made.append(out)
    for s, d in zip(user_out.inputs, out.inputs):
        v = _read(s)
        if _is_socket(v):
            tree.links.new(dup(v) if s.name == "Surface" else v, d)
        elif v is not None and hasattr(d, "default_value"):
            d.default_value = v
    user_out.is_active_output = True  # the user's output stays the one the editor shows
    return dict(added=True, reason=why if needed else "requested (mode 'always')",
                nodes=len(made) + n_math)


def _path(user_out, final):
    """Names of the nodes between the layer's last mix (``final``) and ``user_out``'s Surface,
    or a reason why they cannot be duplicated."""
    sock = user_out.inputs["Surface"]
    if not sock.is_linked:
        return None, "nothing is connected to the output's Surface"
    memo = {}

    def reaches(node, depth=0):
        if node.name in memo:
            return memo[node.name]
        memo[node.name] = False
        hit = False
        for s in node.inputs:
            for link in s.links:
                if link.from_socket == final or reaches(link.from_node, depth + 1):
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
    """Bring the EEVEE output of ``mat`` up to date with its layer (after an edit of the core or
    of the haze, also after the layer rebuilt itself and so removed it), in the mode it was
    requested with; nothing when none was requested.  Call it after every layer.apply.
    Returns whether the material has an EEVEE output now."""
    out = eevee_nodes(mat.node_tree).get(OUTPUT_ROLE)
    mode = requested_mode(mat) or (out.get(MODE_KEY) if out is not None else None)
    if mode is None:
        return False
    if not layer.is_layered(mat):
        _remove_nodes(mat)
        return False
    return build_eevee_output(mat, mode=mode)["added"]
