# SPDX-License-Identifier: GPL-3.0-or-later
"""The haze layer as it was built until LAYER_VERSION 1 (loose nodes in the artist's tree), kept
to read and take off such layers in files saved then: blender.layer upgrades them to the node
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
input of the copies follows the core (:func:`sync`).
"""
from __future__ import annotations

import contextlib

import numpy as np

from .. import constants as K
from . import compat
from ..core import gulbrandsen_inverse
from ..core import body_colour, node_math, thin_film
from ..core.graph import Graph
from ..core.lobes import describe
from ..core.parameters import HAZE_DEFAULTS
from .nodes import ownership
from .nodes.builder import TreeBuilder, socket_value
from .nodes.emit import emit

#: Custom property marking the user's core node (it is never one of ours: never removed).
CORE_KEY = "hazy_gloss_core"
LAYER_VERSION = 1
STAMP_VERSION = 2  # blender.material.STAMP_VERSION (the stamp's format)

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
#: A haze value given per texel (a map baked by texture conversion): the haze dict holds this
#: string instead of a number, and the graph reads the input "haze:<name>".
TEXTURE = "texture"
#: Haze values that can be maps, with their graph input names.
HAZE_MAPS = ("haziness", "haze_extent_x", "haze_extent_y", "coat_haziness", "coat_haze_extent")
#: material session_uid -> fingerprint of its core when the layer last wrote it (blender.sync).
FINGERPRINTS = {}


def core_type(node):
    if node.bl_idname == PRINCIPLED:
        return "PRINCIPLED"
    if node.bl_idname == METALLIC:
        return "METALLIC"
    if node.bl_idname in GLOSSY:
        return "GLOSSY"
    return None


class _Links:
    """The links of a tree by (to node, to socket identifier), while :func:`apply` runs
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


def _linked_from(sock, out):
    """Whether ``out`` is what feeds ``sock``."""
    return sock.is_linked and _Links.link(sock).from_socket == out


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


def _socket_ref(sock):
    return [sock.node.name, sock.identifier]


def _resolve(tree, ref):
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
            self.link = _resolve(node.id_data, base["link"]) if "link" in base else None
            if "value" in base:
                self.value = _plain(base["value"])

    @property
    def linked(self):
        return self.link is not None


# --------------------------------------------------------------------------------------------
# The plan: parts, copies, owned inputs
# --------------------------------------------------------------------------------------------


class Plan:
    """What the layer needs for a core node and its haze parameters."""

    def __init__(self, core, haze, base):
        self.core = core
        self.type = core_type(core)
        self.haze = haze
        self.base = base  # owned input -> {"value": ...} / {"link": [node, socket]}
        self.inp = lambda name: Input(core, name, base.get(name))  # noqa: E731
        on = _positive(haze["haziness"])
        coat = False
        if self.type == "PRINCIPLED":
            m = self.inp("Metallic")
            parts = (("DIELECTRIC", "METAL") if m.linked or 0.0 < m.value < 1.0 else
                     ("METAL",) if m.value >= 1.0 else ("DIELECTRIC",))
            cw = self.inp("Coat Weight")
            coat = _positive(haze["coat_haziness"]) and (cw.linked or cw.value > 0.0)
        elif self.type == "METALLIC":
            parts = ("PHYSICAL",) if core.fresnel_type == "PHYSICAL_CONDUCTOR" else ("METAL",)
        else:
            parts = ("GLOSSY",)
        self.parts = parts if on else ()
        self.split = len(self.parts) == 2
        self.coat = coat
        a_name = _ANISO[core.bl_idname][0]
        a = self.inp(a_name)
        lx, ly = haze["haze_extent"]
        self.anisotropic = on and (a.linked or a.value != 0.0 or lx != ly)
        self.maps = tuple(n for n in HAZE_MAPS if _haze_value(haze, n) == TEXTURE)
        self.film = _film(self) if self.parts and (self.type == "PRINCIPLED" or (
            self.type == "METALLIC" and self.parts == ("METAL",))) else None
        self.notes = []  # what values() could not make exact, in plain words
        self.body = bool(haze.get("keep_body_colour")) and "DIELECTRIC" in self.parts and \
            self.film is None and not self.maps and not any(
                self.inp(n).linked for n in ("Roughness", "IOR", "Specular Tint",
                                             "Specular IOR Level", "Anisotropic"))
        self.facing = None  # the Layer Weight Facing socket body colour reads (set by apply)
        if haze.get("keep_body_colour") and "DIELECTRIC" in self.parts and not self.body:
            self.notes.append("Keep Body Colour needs constant Roughness, IOR, Specular Tint, "
                              "Specular IOR Level and Anisotropic, no thin film and no haze "
                              "maps: not applied")

    @property
    def active(self):
        return bool(self.parts) or self.coat

    def slots(self):
        """(part, wide, coat_wide) of every BSDF the layer needs; the first is the core."""
        base = [(p, w) for p in self.parts for w in (False, True)] or [(None, False)]
        return [(p, w, cw) for cw in ((False, True) if self.coat else (False,)) for p, w in base]

    def owned(self):
        """The core's inputs the layer writes."""
        names = []
        if self.parts:
            first = self.parts[0]
            names += {"DIELECTRIC": ["IOR"], "METAL": ["Base Color"], "PHYSICAL": ["IOR", "Extinction"],
                      "GLOSSY": ["Color"]}[first]
            if self.film is not None and "DIELECTRIC" in self.parts:
                names.append("Specular Tint")  # a film's peak needs the tint too
            if self.body and "Base Color" not in names:
                names.append("Base Color")  # keep body colour: base c(μ) under the haze
            if self.split:
                names.append("Metallic")
        if self.coat:
            names.append("Coat IOR")
        return names

    def key(self):
        """The structure (which nodes exist and which inputs are linked); values of the same
        structure are set in place."""
        linked = tuple(sorted(s.name for s in self.core.inputs if _source(s) is not None
                              and not ownership.is_ours(_source(s).node)))
        return repr((self.type, self.parts, self.coat, self.anisotropic,
                     self.haze["smoothness"] is not None, linked, self.maps, self.body,
                     tuple(sorted(k for k, v in self.base.items() if "link" in v))))


def _film(plan):
    """(thickness, film IOR) of an active constant thin film whose part inputs are constants
    (the peak then follows the film exactly, core.thin_film), else None."""
    if plan.core.inputs.get("Thin Film Thickness") is None:  # a Metallic BSDF before 5.0
        return None
    t, n = plan.inp("Thin Film Thickness"), plan.inp("Thin Film IOR")
    if t.linked or n.linked or not thin_film.film_active(t.value):
        return None
    names = (["Base Color", "Specular Tint", "IOR", "Specular IOR Level", "Roughness"]
             if plan.type == "PRINCIPLED" else ["Base Color", "Edge Tint", "Roughness"])
    if any(plan.inp(nm).linked for nm in names):
        return None
    return float(t.value), float(n.value)


def _positive(v):
    return v == TEXTURE or float(v) > 0.0


def _haze_value(haze, name):
    if name.startswith("haze_extent_"):
        return haze["haze_extent"]["xy".index(name[-1])]
    return haze[name]


def _slot_role(part, wide, coat_wide):
    name = {"DIELECTRIC": "dielectric", "METAL": "metal", "PHYSICAL": "metal", "GLOSSY": "glossy",
            None: "core"}[part]
    return f"{name} {'wide' if wide else 'narrow'}{' coat wide' if coat_wide else ''}"


# --------------------------------------------------------------------------------------------
# Values
# --------------------------------------------------------------------------------------------


def _f0(g, ior):
    return g.math("POWER", g.div(g.sub(ior, 1.0), g.add(ior, 1.0)), 2.0)


def _ior_from_f0(g, f0):
    """(1+√f)/(1-√f), with 1 - √f = (1 - f)/(1 + √f)."""
    f0 = g.minimum(f0, K.ONE_MINUS_ULP32)
    sq = g.add(g.sqrt(f0), 1.0)
    return g.div(g.mul(sq, sq), g.maximum(g.sub(1.0, f0), 1e-12))


def _mapping(plan, g, x, kind, rc, edge_tint, rough, aniso, rot, haziness, extent, smooth, dist,
             anisotropic, lobe=None, tint=None):
    """The haze mapping of one part: core.lobes.describe (float64) when every input is a
    constant, else core.node_math on the graph.  ``lobe``, ``tint``: the Multiscatter GGX lobe
    type when the part's node is not the kind's own (core.multiscatter.correct_mapping).
    Returns Exprs."""
    consts = [e for e in (rc, edge_tint, rough, aniso, rot, tint, haziness) + tuple(extent)
              if hasattr(e, "is_const")]
    dist = dist if dist in K.NODE_DISTRIBUTIONS[kind] else "GGX"
    if all(e.is_const for e in consts):
        val = lambda e: np.asarray(e.value, np.float64) if hasattr(e, "value") else e  # noqa: E731
        ms = None
        if lobe is not None:
            ms = dict(lobe=lobe)
            if tint is not None:
                ms["tint"] = np.broadcast_to(val(tint), (3,))
        d = describe(kind, dist, core_reflectivity=tuple(np.broadcast_to(val(rc), (3,))),
                     edge_tint=tuple(np.broadcast_to(val(edge_tint), (3,))),
                     roughness=float(val(rough)), anisotropy=float(val(aniso)),
                     rotation=float(val(rot)), haziness=haziness, haze_extent=extent,
                     smoothness=smooth, anisotropic=anisotropic, strict=False, multiscatter=ms)
        m = d.mapping
        wide = d.wide if d.wide is not None else d.narrow
        out = dict(beta=float(d.beta), reflectivity_max=float(m.reflectivity_max),
                   core_max=float(np.max(m.core_reflectivity)),
                   reflectivity=tuple(float(c) for c in m.reflectivity),
                   roughness_wide=float(wide.roughness))
        if anisotropic:
            out.update(anisotropy_wide=float(wide.anisotropy), rotation_wide=float(wide.rotation))
        if kind == "CONDUCTOR":
            out.update(ior=tuple(map(float, m.ior)), extinction=tuple(map(float, m.extinction)))
        if kind == "LEGACY":
            out.update(colour_narrow=tuple(map(float, d.fresnel.get("colour_narrow", m.reflectivity))),
                       colour_wide=tuple(map(float, d.fresnel.get("colour_wide", (0.0, 0.0, 0.0)))))
        return {k: g.const(v) for k, v in out.items()}, m
    src = dict(core_reflectivity=rc, edge_tint=edge_tint, roughness=rough, anisotropy=aniso,
               rotation=rot, haziness=haziness, haze_extent_x=extent[0], haze_extent_y=extent[1],
               smoothness=smooth)
    ms = None
    if dist == "MULTI_GGX":  # Cycles' energy factor in node math too (core.node_multiscatter)
        ms = lobe or {"CONDUCTOR": "CONDUCTOR", "DIELECTRIC": "DIELECTRIC", "LEGACY": "LEGACY"}[kind]
    return node_math.mapping(g, src, kind=kind, anisotropic=anisotropic, smooth=smooth is not None,
                             distribution=dist, multiscatter=ms, tint=tint), None


def values(plan):
    """(graph, {(slot, input name): Expr}, {mix role: Expr}, sources, mappings) of a plan."""
    core, haze, t = plan.core, plan.haze, plan.type
    g = Graph()
    sources = {}

    def x(name, vector=False):
        i = plan.inp(name)
        if i.linked:
            key = f"in:{name}"
            sources[key] = i.link
            return g.input(key, vector=vector)
        return g.const(i.value)

    def hz(name):  # a haze value: a number, or the graph input of its map
        v = _haze_value(haze, name)
        return g.input(f"haze:{name}") if v == TEXTURE else v

    writes, mixes, maps = {}, {}, {}
    a_name, r_name = _ANISO[core.bl_idname]
    rough, aniso, rot = x("Roughness"), x(a_name), x(r_name)
    if t == "GLOSSY":  # Glossy's anisotropy convention read into the Metallic one
        aniso, rot = node_math.glossy_to_metallic(g, aniso, rot)
    dist = core.distribution if core.distribution in K.DISTRIBUTIONS else "GGX"
    for part in plan.parts:
        edge = g.const(0.0)
        if part == "DIELECTRIC":
            f0_user = _f0(g, x("IOR"))
            level = g.mul(g.maximum(x("Specular IOR Level"), 0.0), 2.0)
            rc, kind = g.vmath("SCALE", x("Specular Tint", True), g.mul(f0_user, level)), "DIELECTRIC"
        elif part == "PHYSICAL":
            rc, edge = node_math.gulbrandsen_inverse(g, x("IOR", True), x("Extinction", True))
            kind = "CONDUCTOR"
        elif part == "METAL":
            rc, kind = x("Base Color", True), "DIELECTRIC"
        else:
            rc, kind = x("Color", True), "LEGACY"
        tint_name = "Specular Tint" if t == "PRINCIPLED" else "Edge Tint"
        lobe = dict(lobe="F82_TINT", tint=x(tint_name, True)) if part == "METAL" else {}
        film = plan.film if part in ("DIELECTRIC", "METAL") else None
        if film is not None:  # the film's interference sets the peak: map from it (thin_film)
            base = np.asarray(plan.inp("Base Color").value, float)
            tint = np.asarray(plan.inp(tint_name).value, float)
            if part == "DIELECTRIC":
                ior, lvl = float(plan.inp("IOR").value), float(plan.inp("Specular IOR Level").value)
            if part == "METAL":
                rc = g.const(tuple(thin_film.metal_reflectance(base, tint, *film)))
            else:
                rc = g.const(tuple(thin_film.dielectric_reflectance(ior, lvl, tint, *film)))
        m, mp = _mapping(plan, g, x, kind, rc, edge, rough, aniso, rot, hz("haziness"),
                         (hz("haze_extent_x"), hz("haze_extent_y")), haze["smoothness"], dist,
                         plan.anisotropic, **lobe)
        if mp is not None:
            maps[part] = mp
        own = {}
        if film is not None:  # the IOR / Base Color whose film gives r in every channel
            r = np.asarray(m["reflectivity"].value, float)
            if part == "METAL":
                b2, ok = thin_film.metal_base_for_reflectance(r, tint, *film, near=base)
                own["Base Color"] = g.const(tuple(b2))
                got = thin_film.metal_reflectance(b2, tint, *film)
            else:
                best = None  # one IOR meets one weighted sum; the tint fixes the channels
                for wts in ((1.0, 1.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
                    i2, _ = thin_film.dielectric_ior_for_reflectance(r, lvl, tint, *film, weights=wts)
                    i2 = float(np.asarray(i2))
                    t2, ok_ = thin_film.dielectric_tint_for_reflectance(r, i2, lvl, *film)
                    got_ = thin_film.dielectric_reflectance(i2, lvl, t2, *film)
                    err = float(np.max(np.abs(np.asarray(got_) / np.maximum(r, 1e-12) - 1.0)))
                    if best is None or err < best[0] - 1e-12:
                        best = (err, i2, t2, ok_, got_)
                    if np.all(ok_):
                        break
                _, ior2, t2, ok, got = best
                own["IOR"], own["Specular Tint"] = g.const(ior2), g.const(tuple(t2))
            if not np.all(ok):
                off = float(np.max(np.abs(np.asarray(got) / np.maximum(r, 1e-12) - 1.0)))
                plan.notes.append(f"the thin film cannot reflect as much as this haze needs: "
                                  f"the peak moves by {off:.1%} (lower Haziness)")
        elif part == "DIELECTRIC":
            gain = g.div(m["reflectivity_max"], g.maximum(m["core_max"], 1e-30))
            own["IOR"] = _ior_from_f0(g, g.mul(f0_user, gain))
        elif part == "PHYSICAL":
            own["IOR"], own["Extinction"] = m["ior"], m["extinction"]
        elif part == "METAL":
            own["Base Color"] = m["reflectivity"]
        if plan.body and part == "DIELECTRIC" and mp is not None:
            own["Base Color"] = _body_colour(plan, g, x, mp, own["IOR"], dist)
        if plan.split:
            own["Metallic"] = g.const(1.0 if part == "METAL" else 0.0)
        for wide in (False, True):
            w = dict(own)
            if part == "GLOSSY":
                w["Color"] = m["colour_wide" if wide else "colour_narrow"]
            if wide:
                w["Roughness"] = m["roughness_wide"]
                if plan.anisotropic:  # kind LEGACY gives Glossy's convention, the others the Metallic one
                    w[a_name], w[r_name] = m["anisotropy_wide"], m["rotation_wide"]
            for name, e in w.items():
                writes[((part, wide), name)] = e
        mixes[f"Mix {part.lower()}"] = m["beta"]
    if "facing" in g.inputs:
        sources["facing"] = plan.facing
    if plan.split:
        mixes["Mix metallic"] = x("Metallic")
    if plan.coat:
        f0c = _f0(g, g.maximum(x("Coat IOR"), 1.0))
        # the coat is always energy-compensated GGX (bsdf_coat_setup): its own correction
        mc, mp = _mapping(plan, g, x, "DIELECTRIC", f0c, g.const(0.0), x("Coat Roughness"),
                          g.const(0.0), g.const(0.0), hz("coat_haziness"),
                          (hz("coat_haze_extent"),) * 2, None, "MULTI_GGX", False, lobe="COAT")
        if mp is not None:
            maps["COAT"] = mp
        gain = g.div(mc["reflectivity_max"], g.maximum(mc["core_max"], 1e-30))
        writes[("coat", "Coat IOR")] = _ior_from_f0(g, g.mul(f0c, gain))
        writes[("coat wide", "Coat Roughness")] = mc["roughness_wide"]
        mixes["Mix coat"] = mc["beta"]
    return g, writes, mixes, sources, maps


def _body_colour(plan, g, x, m, ior_hazy, dist):
    """Base Color = min(base c(f), 1), c fitted in the Layer Weight Facing f (core.body_colour):
    the diffuse under the hazy dielectric as it was under the user's (Cycles attenuates it by
    the specular layer's albedo, which haze raises)."""
    base = x("Base Color", True)
    bright = plan.inp("Base Color").value if not base.is_const else base.value
    tint = plan.inp("Specular Tint").value
    bc = body_colour.compensation(
        m.alpha, float(plan.inp("IOR").value), float(ior_hazy.value), float(m.beta), m.alpha_wide,
        base_color=np.asarray(bright, float)[:3] if base.is_const else (1.0, 1.0, 1.0),
        tint=np.asarray(tint, float)[:3], level=float(plan.inp("Specular IOR Level").value),
        distribution=dist)
    note = bc.warning()
    if note:
        plan.notes.append(note)
    a = np.asarray(bc.coefficients, np.float64)
    f = g.input("facing")
    if bc.grey:  # Horner: p <- p f + a[k]
        p = g.const(float(a[-1, 0]))
        for k in range(a.shape[0] - 2, -1, -1):
            p = g.math("MULTIPLY_ADD", p, f, float(a[k, 0]))
        c = g.vmath("SCALE", base, p)
    else:
        fv = g.combine(f, f, f)
        p = g.const(tuple(a[-1]))
        for k in range(a.shape[0] - 2, -1, -1):
            p = g.vmath("MULTIPLY_ADD", p, fv, tuple(a[k]))
        c = g.vmath("MULTIPLY", base, p)
    return g.vmath("MINIMUM", c, (1.0, 1.0, 1.0))


def slot_writes(plan, writes, slot):
    """{input name: value} one BSDF of the layer gets."""
    part, wide, cw = slot
    out = {}
    for (key, name), e in writes.items():
        if key == "coat" or (key == "coat wide" and cw) or key == (part, wide):
            out[name] = e
    return out


# --------------------------------------------------------------------------------------------
# Building and updating
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


def _write(tree, node, name, value):
    sock = node.inputs.get(name)
    if sock is None:
        return
    if hasattr(value, "node"):
        if not _linked_from(sock, value):
            _new_link(tree, value, sock)
        return
    _unlink(tree, sock)
    v = socket_value(sock, value)
    cur = sock.default_value
    if (tuple(cur) if hasattr(cur, "__len__") else cur) != v:
        sock.default_value = v


def sync_node(core, copy, skip=()):
    """``copy``'s inputs and node settings made the core's (values and links), except ``skip``."""
    tree = core.id_data
    for src, dst in zip(core.inputs, copy.inputs):
        if src.identifier != dst.identifier or src.name in skip:
            continue
        link = _source(src)
        if link is not None:
            if not _linked_from(dst, link):
                _new_link(tree, link, dst)
            continue
        _unlink(tree, dst)
        if hasattr(src, "default_value"):
            val = src.default_value
            val = tuple(val) if hasattr(val, "__len__") else val
            cur = dst.default_value
            if (tuple(cur) if hasattr(cur, "__len__") else cur) != val:
                dst.default_value = val
    for prop in _NODE_PROPS.get(core.bl_idname, ()):
        if getattr(copy, prop) != getattr(core, prop):
            setattr(copy, prop, getattr(core, prop))


def _current(sock):
    """What an input holds now: {"link": ref} or {"value": v}."""
    src = _source(sock)
    if src is not None:
        return {"link": _socket_ref(src)}
    return {"value": _plain(sock.default_value)}


def _stamp(mat):
    d = mat.get(K.STAMP)
    return (d.to_dict() if hasattr(d, "to_dict") else dict(d)) if d is not None else None


def layer_state(mat):
    """The layer's state read from the stamp, sanitised (blender.stamp.check_layer: what does
    not read is left out, and listed in ``"problems"``), or None when ``mat`` has no layer.
    Never raises: a stamp that is not a group has no layer."""
    from . import stamp as _stamp_module
    if mat is None:
        return None
    d = _stamp_module.group(mat, K.STAMP)
    if d is not None and "layer" in d:
        raw = d["layer"]
        if isinstance(raw, dict) and raw.get("version", LAYER_VERSION) != LAYER_VERSION:
            return None  # a layer of today's form (blender.layer)
        return _stamp_module.check_layer(mat, raw)
    return _stamp_module.lost_layer(mat, d)  # a layer's nodes whose stamp lost "layer", or None


def is_layered(mat):
    return mat is not None and layer_state(mat) is not None


def _adopt(core, state):
    """Owned inputs the user changed since the layer wrote them become their new user values
    (a node-editor edit of the core's IOR, say, is adopted, not overwritten)."""
    base, written = dict(state.get("base", {})), state.get("written", {})
    for name, w in written.items():
        sock = core.inputs.get(name)
        if sock is None:
            continue
        now = _current(sock)
        if "link" in now:
            node = core.id_data.nodes.get(now["link"][0])
            if node is not None and not ownership.is_ours(node):
                base[name] = now  # the user linked something new
        elif "value" in w and not _same(now["value"], w["value"]):
            base[name] = now
    return base


def _same(a, b):
    a, b = np.atleast_1d(np.asarray(a, float)), np.atleast_1d(np.asarray(b, float))
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= 1e-6 * np.maximum(1.0, np.abs(b))))


def _restore(core, name, base):
    """Give an input back its user value or link."""
    tree = core.id_data
    sock = core.inputs.get(name)
    if sock is None or base is None:
        return
    if "link" in base:
        src = _resolve(tree, base["link"])
        if src is not None:
            _new_link(tree, src, sock)
            return
    _unlink(tree, sock)
    if "value" in base:
        sock.default_value = socket_value(sock, base["value"])


def apply(mat, haze, *, core=None, baked=None):
    """Make ``mat``'s layer render ``haze`` (a dict like HAZE) on its core node: values set in
    place when the structure is unchanged, else the layer's nodes rebuilt.  ``baked``: outputs
    read from maps instead of node math (texture conversion): {"maps": {output key: Image},
    "vector": the coordinates socket or None, "interpolation": ...}; kept in the stamp, so
    later updates keep them.  Returns the constant parts' HazeMappings by part."""
    with _links_cached(mat.node_tree):
        return _apply(mat, haze, core, baked)


def output_keys(plan):
    """The layer's outputs for ``plan``: {key: Expr} with keys ("w", (part, wide) | "coat" |
    "coat wide", input name) for values written on BSDFs and ("m", mix role) for mix factors,
    and the graph, its sources and the constant parts' mappings."""
    g, writes, mixes, sources, maps = values(plan)
    flat = {("w",) + k: e for k, e in writes.items()}
    flat.update({("m", r): e for r, e in mixes.items()})
    return flat, g, sources, maps


def is_baked(mat):
    return "baked" in (layer_state(mat) or {})


def _baked_from_state(tree, state):
    import ast

    import bpy
    b = state.get("baked")
    if not b:
        return None
    maps = {}
    for k, name in b.get("maps", {}).items():
        img = bpy.data.images.get(name)
        if img is not None:
            maps[ast.literal_eval(k)] = img
    vec = _resolve(tree, b["vector"]) if b.get("vector") else None
    return dict(maps=maps, vector=vec, interpolation=b.get("interpolation", "Linear"))  # (no
    #   "sources": apply compares the stamp's with what the layer reads now)


def _apply(mat, haze, core, baked):
    tree = mat.node_tree
    state = layer_state(mat) or {}
    core = core or find_core(tree, state.get("core"))
    if core is None:
        raise ValueError(f"the core node of {mat.name!r} is gone, so its Hazy Gloss layer cannot "
                         f"be updated: Remove Haze and Make Hazy again")
    # the core as the layer left it: its copies need no sync (a haze-only update)
    followed = FINGERPRINTS.get(mat.session_uid) == fingerprint(core)
    base = _adopt(core, state)
    plan = Plan(core, haze, base)
    animated = compat.animated_paths(tree)
    for name in plan.owned():  # inputs owned for the first time: keep what the user has there
        if name not in base:
            path = core.inputs[name].path_from_id() + ".default_value"
            if path in animated:
                raise ValueError(f"the {name} of “{core.name}” is animated (keyframes or a "
                                 f"driver), and haze has to set it: connect the animated value "
                                 f"through a Value node instead, then add haze")
            base[name] = _current(core.inputs[name])
    plan = Plan(core, haze, base)
    returned = [n for n in base if n not in plan.owned()]  # no longer owned (given back below)
    flat, g, sources, maps = output_keys(plan)  # (reads the user's values from base)
    if baked is None:
        baked = _baked_from_state(tree, state)
    baked_maps = dict(baked["maps"]) if baked else {}
    live = {k: e for k, e in flat.items() if k not in baked_maps}
    unfed = sorted({e.name for e in g.used(live) if e.op == "input" and e.name != "facing"
                    and sources.get(e.name) is None})
    read = sorted(k for k in sources if k.startswith("in:"))
    if baked_maps and "sources" in (state.get("baked") or {}) and baked is not None and \
            baked.get("sources") is None and read != sorted(state["baked"]["sources"]):
        unfed = unfed or [n for n in read if n not in state["baked"]["sources"]] or read
    if unfed:  # (a baked layer whose material changed so that new values depend on the maps)
        what = ", ".join(n.split(":", 1)[-1] for n in unfed)
        raise ValueError(f"the layer of {mat.name!r} needs {what} per pixel, which only its "
                         f"converted maps held: convert the maps again (or Remove Haze)")
    # nothing above changed the tree; from here on it is updated
    for name in returned:
        _restore(core, name, base.pop(name))
    key = plan.key()
    if plan.body:  # the view cosine body colour reads: a Layer Weight on the core's normal
        plan.facing = sources["facing"] = _facing(tree, core)
    signature = str((g.signature(live), sorted((k, _socket_ref(v)) for k, v in sources.items()
                                               if not k.startswith("haze:")),
                     sorted(repr(k) for k in baked_maps)))
    layer_nodes = _layer_nodes(tree)
    old_math = [tree.nodes.get(n) for n in state.get("math", [])]
    same = (plan.active and state.get("structure") == key and bool(layer_nodes)
            and all(_ROLE + _slot_role(*s) in layer_nodes for s in plan.slots()[1:]))
    reuse = old_math if same and state.get("signature") == signature and not baked_maps and \
        all(n is not None for n in old_math) else None
    destinations = _destinations(tree, core)
    keep = plan.facing.node if plan.facing is not None else None
    if not same:
        for n in layer_nodes.values():
            if n != keep:
                tree.nodes.remove(n)
    elif reuse is None:
        for n in old_math:
            if n is not None:
                tree.nodes.remove(n)
    _Links.changed()
    tb = TreeBuilder(tree, x0=core.location.x - 180.0 * 10, y0=core.location.y - 480.0, roles=True)
    out = emit(tb, g, live, sources, reuse=reuse)
    texs = {}  # one Image Texture per map (the lobes share the IOR map)
    for k, img in sorted(baked_maps.items(), key=lambda kv: repr(kv[0])):
        tex = texs.get(img.name)
        if tex is None:
            tex = texs[img.name] = tb.node("ShaderNodeTexImage", label=f"Hazy Gloss map {img.name}")
            tex.image, tex.interpolation = img, baked.get("interpolation", "Linear")
            tex.location = (core.location.x - 520.0, core.location.y - 300.0 - 60.0 * len(texs))
            tex.hide = True
            if baked.get("vector") is not None:
                tb.link(baked["vector"], tex.inputs["Vector"])
        out[k] = tex.outputs["Color"]
    math_nodes = list(tb.created)
    for i, n in enumerate(math_nodes):
        n[K.ROLE] = f"{_ROLE}math {i}"
    nodes = _existing(tree, plan) if same else _build(mat, plan, tb)
    _Links.changed()
    written = {}
    w_all = {k[1:]: v for k, v in out.items() if k[0] == "w"}
    for slot, node in nodes.items():
        w = slot_writes(plan, w_all, slot)
        for name, val in w.items():
            _write(tree, node, name, val)
        if node is core:
            written = {name: _current(core.inputs[name]) for name in w}
        elif not (same and followed):
            sync_node(core, node, skip=set(w))
    current = _layer_nodes(tree)
    for k, val in out.items():
        if k[0] != "m":
            continue
        role = k[1]
        for suffix in ("", " coat wide"):
            mix = current.get(_ROLE + role + suffix)
            if mix is not None and mix.bl_idname == "ShaderNodeMixShader":
                if hasattr(val, "node"):
                    if not _linked_from(mix.inputs[0], val):
                        _new_link(tree, val, mix.inputs[0])
                else:
                    _write(tree, mix, mix.inputs[0].name, val)
    if not same:
        _connect(tree, _final(tree) or core.outputs[0], destinations)
    core[CORE_KEY] = True
    d = _stamp(mat) or {}
    d["layer"] = {"version": LAYER_VERSION, "core": core.name, "structure": key,
                  "signature": signature, "math": [n.name for n in math_nodes], "base": base,
                  "written": written,
                  "haze": {k: (list(v) if isinstance(v, tuple) else v) for k, v in haze.items()
                           if v is not None}}
    if baked_maps:  # (ID properties hold no None)
        b = {"maps": {repr(k): img.name for k, img in baked_maps.items()},
             "interpolation": baked.get("interpolation", "Linear"),
             "sources": baked.get("sources") or read}  # what the maps were computed from
        if baked.get("vector") is not None:
            b["vector"] = _socket_ref(baked["vector"])
        d["layer"]["baked"] = b
    d["version"] = STAMP_VERSION
    mat[K.STAMP] = d
    FINGERPRINTS[mat.session_uid] = fingerprint(core)
    return maps


def _facing(tree, core):
    node = _layer_nodes(tree).get(_ROLE + "facing")
    if node is None:
        node = tree.nodes.new("ShaderNodeLayerWeight")
        node.name = f"{K.NODE_PREFIX} {_ROLE}facing"
        node[K.ROLE] = _ROLE + "facing"
        node.label = "Hazy Gloss view cosine"
        node.hide = True
        node.location = (core.location.x - 520.0, core.location.y + 80.0)
    node.inputs["Blend"].default_value = 0.5
    normal = _source(core.inputs["Normal"])
    if normal is not None:
        if not _linked_from(node.inputs["Normal"], normal):
            _new_link(tree, normal, node.inputs["Normal"])
    elif node.inputs["Normal"].is_linked:
        _unlink(tree, node.inputs["Normal"])
    return node.outputs["Facing"]


def _existing(tree, plan):
    core = find_core(tree)
    nodes = _layer_nodes(tree)
    return {slot: (core if i == 0 else nodes[_ROLE + _slot_role(*slot)])
            for i, slot in enumerate(plan.slots())}


def _build(mat, plan, tb):
    """The copies and mixes of ``plan`` (the core is the first slot)."""
    core = plan.core
    nodes = {}
    for i, slot in enumerate(plan.slots()):
        if i == 0:
            nodes[slot] = core
            continue
        role = _slot_role(*slot)
        n = tb.node(core.bl_idname, name=_ROLE + role, label=f"Hazy Gloss {role}")
        for prop in _NODE_PROPS.get(core.bl_idname, ()):
            setattr(n, prop, getattr(core, prop))
        n.location = (core.location.x, core.location.y - 200.0 - 40.0 * i)
        n.width = core.width
        n.hide = True  # the copies follow the core: the user edits the core
        nodes[slot] = n
    x0 = core.location.x + core.width + 80.0
    count = [0]

    def mix(role, a, b, column, add=False):
        m = tb.node("ShaderNodeAddShader" if add else "ShaderNodeMixShader", name=_ROLE + role,
                    label=f"Hazy Gloss {role}")
        m.location = (x0 + 200.0 * column, core.location.y - 140.0 * count[0])
        count[0] += 1
        first = 0 if add else 1
        tb.link(a, m.inputs[first])
        tb.link(b, m.inputs[first + 1])
        return m.outputs[0]

    results = {}
    for cw in ((False, True) if plan.coat else (False,)):
        sfx = " coat wide" if cw else ""
        parts = {}
        for part in plan.parts:
            parts[part] = mix(f"Mix {part.lower()}{sfx}", nodes[(part, False, cw)].outputs[0],
                              nodes[(part, True, cw)].outputs[0], 0, add=(part == "GLOSSY"))
        if plan.split:
            results[cw] = mix(f"Mix metallic{sfx}", parts["DIELECTRIC"], parts["METAL"], 1)
        elif parts:
            results[cw] = next(iter(parts.values()))
        else:
            results[cw] = nodes[(None, False, cw)].outputs[0]
    if plan.coat:
        mix("Mix coat", results[False], results[True], 2)
    return nodes


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
    FINGERPRINTS.pop(mat.session_uid, None)


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
    from . import stamp as _stamp_module
    state = layer_state(mat) or {}
    problem = _stamp_module.layer_problem(mat, state.get("problems", []))
    if problem is not None:
        raise _stamp_module.StampError(problem)
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


_SUMMARIES = {}


def summary(mat):
    """What the panel shows of a layered material: the core, the plan, the constant parts'
    HazeMappings by part ("COAT" for the coat), whether node math varies them per pixel, and the
    number of BSDF nodes the layer renders.  Cached until the stamp or the core changes (the
    panel draws it many times a second).  Raises ValueError (one line) when the layer's stamp
    is damaged or its core is gone."""
    from . import stamp as _stamp_module
    state = layer_state(mat) or {}
    problem = _stamp_module.layer_problem(mat, state.get("problems", []))
    if problem is not None:
        raise _stamp_module.StampError(problem)
    core = find_core(mat.node_tree, state.get("core"))
    key = (repr(state), fingerprint(core) if core is not None else None)
    hit = _SUMMARIES.get(mat.session_uid)
    if hit is not None and hit[0] == key:  # fresh node references (undo replaces them)
        hit[1]["core"] = hit[1]["plan"].core = core
        return hit[1]
    out = _summary(mat, state)
    _SUMMARIES[mat.session_uid] = (key, out)
    if len(_SUMMARIES) > 64:
        _SUMMARIES.pop(next(iter(_SUMMARIES)))
    return out


def _summary(mat, state):
    core = find_core(mat.node_tree, state.get("core"))
    if core is None:
        raise ValueError(f"the core node of {mat.name!r} is gone: Remove Haze and Make Hazy again")
    if core.bl_idname not in CORE_TYPES:
        raise ValueError(f"the haze layer of {mat.name!r} sits on {core.name!r}, a "
                         f"{core.bl_label} node, not a Principled, Metallic or Glossy BSDF: "
                         f"Remove Haze")
    plan = Plan(core, haze_of(mat), dict(state.get("base", {})))
    _, _, _, sources, maps = values(plan)
    return dict(core=core, plan=plan, maps=maps,
                textured=sorted(k[3:] for k in sources if k.startswith("in:")),
                bsdfs=len(plan.slots()) if plan.active else 1)
