# SPDX-License-Identifier: GPL-3.0-or-later
"""The haze layer as it was built until LAYER_VERSION 1 (loose nodes in the artist's tree), kept
to read and take off such layers in files saved then: blender.model.layer upgrades them to the node
group (:func:`remove`, then a new layer with :func:`haze_of`'s values).  Nothing here builds
new layers.

What follows describes that layer.  Haze as a layer on the artist's own BSDF (Make Hazy):
nothing the user built is replaced.

The user's node (Principled, Metallic or Glossy BSDF: the *core*) stays where it is with every
input and link; it renders the narrow lobe of Eq. 1.  The layer adds copies of it that differ
only in what haze changes — the wide lobe's roughness, anisotropy and rotation, and the
Fresnel's F(0) raised from r_c to r (Eq. 3-5) — mixed by β.  The Principled BSDF is linear in
its metallic part (Cycles svm/closure.h: the metal lobe has weight m, the rest 1 - m, under the
same coat and sheen), so a metallic map splits it exactly into a dielectric and a metal part,
each with its own haze mapping (its own r̂_c, so its own β):

  hazy = Mix(m, Mix(β_d, D_n, D_w), Mix(β_m, M_n, M_w))      (the core is D_n, or M_n)

The coat carries its own haze: a Mix by β_c of the above and a copy of it whose coats are the
wide lobe.  At haziness 0 (and coat haziness 0) the layer holds no node at all: the material is
exactly the user's.

The *owned* inputs are those the layer writes on the core: the Principled IOR (F0(η') = gain
F0(η), where gain = r̂ / r̂_c, Eq. 5), its Base Color when it is all metal (F0 = gain base), its
Metallic (0 on the dielectric part when a map splits it), Coat IOR; a Metallic BSDF's η, κ
(Gulbrandsen from (r, g), Physical Conductor) or F82 Base Color; a Glossy BSDF's colour
(k_n = (1-β) r).  Their values as the user set them are kept in the stamp (when linked, the link
stays the source and node math sits in between), so removing the haze restores them.  Every other
input of the copies followed the core.
"""
from __future__ import annotations

import contextlib

import numpy as np

from ... import constants as K
from ...core import gulbrandsen_inverse
from ...core.parameters import HAZE_DEFAULTS
from . import stamp
from ..nodes import ownership
from ..nodes.builder import socket_value

#: Custom property marking the user's core node (it is never one of ours: never removed).
CORE_KEY = "hazy_gloss_core"
LAYER_VERSION = 1

PRINCIPLED = "ShaderNodeBsdfPrincipled"
METALLIC = "ShaderNodeBsdfMetallic"
GLOSSY = ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic")
CORE_TYPES = (PRINCIPLED, METALLIC) + GLOSSY
_NODE_PROPS = {PRINCIPLED: ("distribution", "subsurface_method"),
               METALLIC: ("distribution", "fresnel_type"),
               "ShaderNodeBsdfAnisotropic": ("distribution",), "ShaderNodeBsdfGlossy": ("distribution",)}
_ANISO = {PRINCIPLED: ("Anisotropic", "Anisotropic Rotation"), METALLIC: ("Anisotropy", "Rotation"),
          "ShaderNodeBsdfAnisotropic": ("Anisotropy", "Rotation"),
          "ShaderNodeBsdfGlossy": ("Anisotropy", "Rotation")}
HAZE = HAZE_DEFAULTS


def core_type(node):
    if node.bl_idname == PRINCIPLED:
        return "PRINCIPLED"
    if node.bl_idname == METALLIC:
        return "METALLIC"
    if node.bl_idname in GLOSSY:
        return "GLOSSY"
    return None


class _Links:
    """The links of a tree by (to node, to socket identifier), while a reading runs
    (``socket.links`` walks every link of the tree; an update reads hundreds of sockets).
    Invalidated whenever the layer adds or removes links."""

    tree = None
    into = None

    @classmethod
    def link(cls, sock):
        tree = sock.id_data
        if cls.tree is None or tree.as_pointer() != cls.tree:
            return sock.links[0]
        if cls.into is None:
            cls.into = {(l.to_node.name, l.to_socket.identifier): l for l in tree.links}
        return cls.into.get((sock.node.name, sock.identifier)) or sock.links[0]

    @classmethod
    def changed(cls):
        cls.into = None


@contextlib.contextmanager
def _links_cached(tree):
    """_Links for ``tree`` while the block runs (inside another such block: that one's)."""
    if _Links.tree is not None:
        yield
        return
    _Links.tree, _Links.into = tree.as_pointer(), None
    try:
        yield
    finally:
        _Links.tree = _Links.into = None


def _source(sock):
    if sock is None or not sock.is_linked:
        return None
    link = _Links.link(sock)
    if getattr(link, "is_muted", False) or not getattr(link, "is_valid", True):
        return None
    return link.from_socket


def _new_link(tree, out, sock):
    tree.links.new(out, sock)
    _Links.changed()


def _unlink(tree, sock):
    if sock.is_linked:
        for link in list(sock.links):
            tree.links.remove(link)
        _Links.changed()


def _plain(v):
    if hasattr(v, "__len__") and not isinstance(v, str):
        return tuple(float(x) for x in v)[:3]
    return float(v)


def resolve_link(tree, ref):
    """The output socket a stamped link reference (node name, socket identifier) names, or None."""
    node = tree.nodes.get(ref[0])
    if node is None:
        return None
    return next((s for s in node.outputs if s.identifier == ref[1]), None)


class Input:
    """One input of the core as the mapping reads it: the socket linked into it (or None) and
    its unlinked value.  For an owned input the user's own value and link (kept in the stamp)
    are read, not what the layer wrote."""

    __slots__ = ("value", "link")

    def __init__(self, node, name, base=None):
        sock = node.inputs.get(name)
        self.value = _plain(sock.default_value)
        self.link = _source(sock)
        if base is not None:
            self.link = resolve_link(node.id_data, base["link"]) if "link" in base else None
            if "value" in base:
                self.value = _plain(base["value"])

    @property
    def linked(self):
        return self.link is not None


# --------------------------------------------------------------------------------------------
# Finding, reading and removing a legacy layer
# --------------------------------------------------------------------------------------------

_ROLE = "layer "  # role prefix of the layer's nodes (math nodes: "layer math")


def find_core(tree, name=None):
    """The core node of a layered tree (tagged with CORE_KEY; ``name`` first, so a copy the
    user made with Shift+D, which keeps the tag, is not taken), or None."""
    tagged = [n for n in tree.nodes if n.get(CORE_KEY)]
    if not tagged:
        return None
    core = next((n for n in tagged if n.name == name), tagged[0])
    for n in tagged:
        if n is not core:
            del n[CORE_KEY]
    return core


def _layer_nodes(tree):
    return {r: n for r, n in ownership.ours(tree).items() if r.startswith(_ROLE)}


def _final(tree):
    """The output socket the layer's BSDF leaves through (its last mix), or None."""
    nodes = _layer_nodes(tree)
    for r in ("layer Mix coat", "layer Mix metallic", "layer Mix dielectric", "layer Mix metal",
              "layer Mix physical", "layer Mix glossy"):
        if r in nodes:
            return nodes[r].outputs[0]
    return None


def _destinations(tree, core):
    """Where the material's hazy BSDF goes: the links out of the layer's last mix, or out of
    the core when there is no layer (links into the layer's own nodes excluded)."""
    out = _final(tree) or core.outputs[0]
    return [(l.to_node.name, l.to_socket.identifier) for l in out.links
            if not l.to_node.name.startswith(K.NODE_PREFIX + " " + _ROLE)
            and not (ownership.role(l.to_node) or "").startswith(_ROLE)]


def _connect(tree, out, destinations):
    for name, ident in destinations:
        node = tree.nodes.get(name)
        sock = next((s for s in node.inputs if s.identifier == ident), None) if node else None
        if sock is not None:
            _new_link(tree, out, sock)


def layer_state(mat):
    """The layer's state read from the stamp, sanitised (blender.model.stamp.check_layer: what does
    not read is left out, and listed in ``"problems"``), or None when ``mat`` has no layer.
    Never raises: a stamp that is not a group has no layer."""
    if mat is None:
        return None
    d = stamp.group(mat, K.STAMP)
    if d is not None and "layer" in d:
        raw = d["layer"]
        if isinstance(raw, dict) and raw.get("version", LAYER_VERSION) != LAYER_VERSION:
            return None  # a layer of today's form (blender.model.layer)
        return stamp.check_layer(mat, raw)
    return stamp.lost_layer(mat, d)  # a layer's nodes whose stamp lost "layer", or None


def _restore(core, name, base):
    """Give an input back its user value or link."""
    tree = core.id_data
    sock = core.inputs.get(name)
    if sock is None or base is None:
        return
    if "link" in base:
        src = resolve_link(tree, base["link"])
        if src is not None:
            _new_link(tree, src, sock)
            return
    _unlink(tree, sock)
    if "value" in base:
        sock.default_value = socket_value(sock, base["value"])


def is_baked(mat):
    return "baked" in (layer_state(mat) or {})


def haze_of(mat):
    """The haze parameters stamped on a layered material (HAZE defaults filled in, also for
    values that do not read: layer_state(mat)["problems"] names them)."""
    state = layer_state(mat) or {}
    haze = state.get("haze", {})
    h = dict(HAZE)
    h.update(haze)
    ext = h["haze_extent"]
    h["haze_extent"] = tuple(ext) if isinstance(ext, (tuple, list)) else (float(ext),) * 2
    if "smoothness" not in haze:
        h["smoothness"] = None
    return h


def remove(mat):
    """Take the layer off: the core's owned inputs get the user's values and links back, the
    layer's nodes go, the core's output goes where the layer's went."""
    tree = mat.node_tree
    state = layer_state(mat) or {}
    core = find_core(tree)
    if core is not None:
        destinations = _destinations(tree, core)
        for name, b in state.get("base", {}).items():
            _restore(core, name, b)
    for n in _layer_nodes(tree).values():
        tree.nodes.remove(n)
    if core is not None:
        _connect(tree, core.outputs[0], destinations)
        del core[CORE_KEY]
    if K.STAMP in mat:
        del mat[K.STAMP]


def fingerprint(core):
    """A hash of what the copies must follow: the core's inputs (values and link sources) and
    node settings (the depsgraph handler resyncs when it changes)."""
    with _links_cached(core.id_data):
        return _fingerprint(core)


def _fingerprint(core):
    items = []
    for s in core.inputs:
        src = _source(s)
        if src is not None:
            items.append((s.identifier, "L", src.node.name, src.identifier))
        elif hasattr(s, "default_value"):
            v = s.default_value
            items.append((s.identifier, tuple(v) if hasattr(v, "__len__") else v))
    items += [(p, getattr(core, p)) for p in _NODE_PROPS.get(core.bl_idname, ())] + [core.mute]
    return hash(tuple(items))


def read(mat):
    """The perceptual view of a layered material: the haze parameters, and the core's own
    parameters as it holds them (linked inputs report their unlinked value and are listed in
    ``textured``).  Raises ValueError (one line) when the layer's stamp is damaged."""
    with _links_cached(mat.node_tree):
        return _read(mat)


def _read(mat):
    state = layer_state(mat) or {}
    problem = stamp.layer_problem(mat, state.get("problems", []))
    if problem is not None:
        raise stamp.StampError(problem)
    core = find_core(mat.node_tree, state.get("core"))
    h = haze_of(mat)
    if core is None:
        raise ValueError(f"the core node of {mat.name!r} is gone")
    if core.bl_idname not in CORE_TYPES:
        raise ValueError(f"the haze layer of {mat.name!r} sits on {core.name!r}, a "
                         f"{core.bl_label} node, not a Principled, Metallic or Glossy BSDF: "
                         f"Remove Haze")
    base = state.get("base", {})
    inp = lambda n: Input(core, n, base.get(n))  # noqa: E731
    t = core_type(core)
    a_name, r_name = _ANISO[core.bl_idname]
    p = dict(layered=True, core=core.name, core_type=t, distribution=core.distribution,
             roughness=inp("Roughness").value, anisotropy=inp(a_name).value,
             rotation=inp(r_name).value, edge_tint=(0.0, 0.0, 0.0), base_color=(0.0, 0.0, 0.0),
             transmission=0.0, tangent="UV_MAP", shader_mapping=False, **h)
    textured = sorted(s.name for s in core.inputs if _source(s) is not None
                      and not ownership.is_ours(_source(s).node))
    textured += sorted(n for n, b in base.items() if "link" in b and n not in textured)
    p["textured"] = textured
    if t == "PRINCIPLED":
        m = inp("Metallic")
        p["metallic"] = m.value if not m.linked else None
        p["kind"] = ("DIELECTRIC" if (not m.linked and m.value <= 0.0) else
                     "CONDUCTOR" if (not m.linked and m.value >= 1.0) else "MIXED")
        ior = inp("IOR").value
        f0 = (((ior - 1.0) / (ior + 1.0)) ** 2 if ior != -1.0 else 1.0) * 2.0 * \
            inp("Specular IOR Level").value
        dielectric = tuple(min(max(f0 * c, 0.0), 1.0) for c in inp("Specular Tint").value)
        metal = tuple(min(max(c, 0.0), 1.0) for c in inp("Base Color").value)
        p["core_reflectivity"] = metal if p["kind"] == "CONDUCTOR" else dielectric
        p["dielectric_reflectivity"], p["metal_reflectivity"] = dielectric, metal
        p["base_color"] = inp("Base Color").value
        p["transmission"] = inp("Transmission Weight").value
    elif t == "METALLIC":
        p["kind"] = "CONDUCTOR"
        if core.fresnel_type == "PHYSICAL_CONDUCTOR":
            r, g = gulbrandsen_inverse(np.maximum(np.asarray(inp("IOR").value, float), 0.0),
                                       np.maximum(np.asarray(inp("Extinction").value, float), 0.0))
            p["core_reflectivity"] = tuple(float(x) for x in np.clip(r, 0.0, 1.0))
            p["edge_tint"] = tuple(float(x) for x in np.clip(np.nan_to_num(g), 0.0, 1.0))
        else:
            p["core_reflectivity"] = inp("Base Color").value
            p["edge_tint"] = inp("Edge Tint").value
    else:
        p["kind"] = "LEGACY"
        p["core_reflectivity"] = inp("Color").value
    p["shader_mapping"] = bool(textured)
    return p


