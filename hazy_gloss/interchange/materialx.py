# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy materials as MaterialX 1.39 documents, and back (bpy-free; the ``materialx`` package is
only used, when installed, to validate).

Export (:func:`build_document`, :func:`write`) — one document, one node graph per material,
every node from the released standard libraries (docs/interchange.md has the node-by-node
table):

    surfacematerial  <-  surface (bsdf)  <-  nodegraph NG_<name>.out
    CONDUCTOR   mix(fg = conductor_bsdf(α_w), bg = conductor_bsdf(α_n), mix = β)
                both lobes: ior = η, extinction = κ (RGB, Gulbrandsen), the same tangent
    DIELECTRIC  layer(top = mix(fg = dielectric_bsdf(α_w), bg = dielectric_bsdf(α_n), β),
                      base = oren_nayar_diffuse_bsdf(base colour, roughness 0))
                both lobes: ior = η (from r̂), tint = chroma of r_c, scatter_mode R;
                with transmission: mix(fg = layer(wide, base_w), bg = layer(narrow, base_n), β),
                base_x = mix(fg = dielectric_bsdf(α_x, scatter_mode T), bg = diffuse, t)
    LEGACY      mix(fg = generalized_schlick_bsdf(α_w), bg = ...(α_n), β) with
                color0 = color90 = r and color82 = 1: F ≡ r, no Fresnel (docs/interchange.md)

``roughness`` is α (MaterialX applies no remapping), a vector2 along the lobe's tangent; the
``mix`` node is mix(bg, fg, mix), so fg is the wide lobe and mix = β (Eq. 1).  Anisotropic
materials get one tangent (UV tangent, or a radial one) turned by rotate3d(amount =
-360 · rotation): MaterialX's rotate3d turns clockwise about the axis, Cycles' rotation
counter-clockwise.  The material's perceptual parameters go with it as a JSON attribute
(``hazygloss_parameters``), so the add-on reads its own files back exactly.

Materials driven by converted physical maps (``mat["hazy_gloss_maps"]``, docs/textures.md) are
written with one ``image`` node per map (colorspace "raw": data, no transform), the PNG
encodings decoded with math nodes, roughness and anisotropy turned into α with
``roughness_anisotropy`` (Blender's α_x = R²/s, α_y = R² s, s = √(1-0.9a) is exactly
roughness_anisotropy(R, 0.9 a)).

The OpenPBR flavour (``flavour="openpbr_1.2"``) writes one ``open_pbr_surface`` of version 1.2
per material with specular_haze and specular_haze_spread (engines.openpbr_12 gives the values
and measures their error).  1.2 is not in the released libraries: the document embeds a nodedef
for the subset of 1.2 inputs it uses, implemented as the mix of two released 1.1.1 surfaces
(core and haze roughness) — which is 1.2's haze when coat and fuzz are off — so it validates and
generates shaders with MaterialX 1.39 (drop ``embed_openpbr_12`` once 1.2 ships).

Import (:func:`read`, :func:`recognise`) finds, for every surfacematerial, a BSDF mix of two
conductor_bsdf / dielectric_bsdf / generalized_schlick_bsdf lobes that differ only in roughness
(through layer / nodegraph outputs / interface inputs), or an open_pbr_surface with
specular_haze, and turns the physical parameters into perceptual ones with
:func:`hazy_gloss.core.inverse_haze_mapping`, reporting every step that is not exact.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from .. import constants as K
from ..convert import output_specs
from ..core.lobes import describe
from ..core.mapping import gulbrandsen_ior, inverse_haze_mapping
from ..core.parameters import PARAMETERS, is_anisotropic, normalise
from . import engines
from .brdf import f82_tint, fresnel_conductor
from .document import (NODEDEFS, OPENPBR_12_INPUTS, OPENPBR_INPUTS, OPENPBR_UNSUPPORTED,
                       Document, Input, Node, NodeGraph, read_xml, valid_name, write_xml)

__all__ = ("FLAVOURS", "Source", "ImportedMaterial", "ExportReport", "lobes_of", "build_document",
           "write", "read", "recognise", "validate", "materialx_available")

FLAVOURS = ("eq1", "openpbr_1.2")
_ATTR = K.MATERIALX_ATTR
_LOBES = {"conductor_bsdf": "CONDUCTOR", "dielectric_bsdf": "DIELECTRIC",
          "generalized_schlick_bsdf": "LEGACY"}
_CATEGORY = {v: k for k, v in _LOBES.items()}
#: MaterialX 1.39's microfacet nodes offer one distribution (enum="ggx").
_DIST = {"GGX": "ggx", "MULTI_GGX": "ggx", "BECKMANN": "ggx", "ASHIKHMIN_SHIRLEY": "ggx"}
_DIST_NOTE = {
    "MULTI_GGX": "Multiscatter GGX written as ggx with the single-scatter haze mapping "
                 "(Cycles' energy factor is Cycles' own; MaterialX renderers compensate GGX "
                 "their own way)",
    "BECKMANN": "Beckmann lobes written as ggx: MaterialX 1.39 has no other distribution (the "
                "peak, set by α, is the same; the tails differ)",
    "ASHIKHMIN_SHIRLEY": "Ashikhmin-Shirley lobes written as ggx: MaterialX 1.39 has no other "
                         "distribution",
}


# --------------------------------------------------------------------------------------------
# What is exported
# --------------------------------------------------------------------------------------------


@dataclass
class Source:
    """One material to export: ``parameters`` (perceptual, as stamped on a hazy material), or
    ``maps`` ({map name: path} of a material wired to converted maps, with ``kind``,
    ``distribution``, ``anisotropic``; ``base_color``/``transmission``/``tangent`` are then read
    from its nodes)."""

    name: str
    parameters: dict = None
    maps: dict = None
    kind: str = None
    distribution: str = "GGX"
    anisotropic: bool = False
    base_color: tuple = (0.0, 0.0, 0.0)
    transmission: float = 0.0
    tangent: str = "UV_MAP"
    filtertype: str = "linear"
    notes: list = field(default_factory=list)
    #: a material with a haze layer (Make Hazy): its node tree, interchange.layered.Tree
    layer: object = None


@dataclass
class ExportReport:
    path: str
    flavour: str
    materials: list = field(default_factory=list)  #: (name, MaterialX name, [notes])
    validated: object = None  #: True / False, or None when the materialx package is missing
    validation: str = ""

    @property
    def notes(self):
        return [f"{n}: {note}" for n, _, notes in self.materials for note in notes]


def lobes_of(p):
    """core.lobes.describe for one material's normalised perceptual parameters, as MaterialX's
    single-scatter ggx lobes draw them (Multiscatter GGX: the paper's mapping, without the
    correction for Cycles' energy factor)."""
    dist = "GGX" if p["distribution"] == "MULTI_GGX" else p["distribution"]
    return describe(p["kind"], dist, core_reflectivity=p["core_reflectivity"],
                    edge_tint=p["edge_tint"], roughness=p["roughness"],
                    anisotropy=p["anisotropy"], rotation=p["rotation"], haziness=p["haziness"],
                    haze_extent=p["haze_extent"], smoothness=p["smoothness"],
                    anisotropic=is_anisotropic(p))


def _f(x):
    return float(np.asarray(x))


def _t(x):
    return tuple(float(v) for v in np.asarray(x, dtype=np.float64).reshape(-1))


def _record(p):
    """The perceptual parameters as a JSON-able dict (what the stamp holds)."""
    out = {}
    for k in PARAMETERS:
        v = p.get(k)
        out[k] = list(v) if isinstance(v, tuple) else v
    return out


# --------------------------------------------------------------------------------------------
# Graph building helpers
# --------------------------------------------------------------------------------------------


class _Builder:
    def __init__(self, graph):
        self.g = graph

    def node(self, nodedef, name, **inputs):
        cat, typ, spec = NODEDEFS[nodedef]
        n = Node(name, cat, typ)
        for k, v in inputs.items():
            t = spec[k][0]
            if isinstance(v, Node):
                n.set(k, t, node=v)
            else:
                n.set(k, t, v)
        return self.g.add(n)

    # -- tangents ------------------------------------------------------------------------------
    def tangent(self, kind, rotation, suffix=""):
        """The tangent a lobe's α_x follows: the UV tangent (index 0) or a radial one around an
        object axis (cross(axis, P_object) in world space: Blender's radial tangent is taken
        around the bounding-box centre, this one around the object origin), turned by
        ``rotation`` turns about the normal (a number, or a node giving turns)."""
        if kind == "UV_MAP":
            t = self.g.nodes.get("tangent_uv") or self.node("ND_tangent_vector3", "tangent_uv",
                                                            space="world", index=0)
        else:
            axis = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}[kind[-1]]
            t = self.g.nodes.get("tangent_radial")
            if t is None:
                pos = self.node("ND_position_vector3", "position_object", space="object")
                cr = self.node("ND_crossproduct_vector3", "radial_cross", in1=axis, in2=pos)
                tw = self.node("ND_transformvector_vector3", "radial_world", fromspace="object",
                               tospace="world")
                tw.set("in", "vector3", node=cr)
                t = self.node("ND_normalize_vector3", "tangent_radial")
                t.set("in", "vector3", node=tw)
        if isinstance(rotation, (int, float)) and rotation == 0:
            return t
        normal = self.g.nodes.get("normal_world") or self.node("ND_normal_vector3", "normal_world",
                                                                space="world")
        rot = self.node("ND_rotate3d_vector3", f"tangent_rotated{suffix}", axis=normal)
        rot.set("in", "vector3", node=t)
        if isinstance(rotation, Node):  # turns from a map: amount = -360 * rotation
            amount = self.node("ND_multiply_float", f"rotation_degrees{suffix}", in1=rotation,
                               in2=-360.0)
            rot.set("amount", "float", node=amount)
        else:
            rot.set("amount", "float", -360.0 * float(rotation))
        return rot


def _lobe(b, kind, name, alpha, fresnel, distribution, tangent, scatter_mode="R"):
    """One lobe node.  ``alpha``: (α_x, α_y) or a vector2 node; ``fresnel``: dict of values or
    nodes (ior/extinction, ior/tint, colour)."""
    nd = "ND_" + _CATEGORY[kind]
    n = b.node(nd, name, weight=1.0)
    spec = NODEDEFS[nd][2]

    def put(key, v):
        if isinstance(v, Node):
            n.set(key, spec[key][0], node=v)
        else:
            n.set(key, spec[key][0], v)

    if kind == "CONDUCTOR":
        put("ior", fresnel["ior"])
        put("extinction", fresnel["extinction"])
    elif kind == "DIELECTRIC":
        put("tint", fresnel["tint"])
        put("ior", fresnel["ior"])
    else:
        put("color0", fresnel["colour"])
        put("color82", (1.0, 1.0, 1.0))
        put("color90", fresnel["colour"])
        put("exponent", 5.0)
    put("roughness", alpha)
    if tangent is not None:
        put("tangent", tangent)
    put("distribution", distribution)
    if kind != "CONDUCTOR":
        put("scatter_mode", scatter_mode)
    return n


def _mix(b, name, fg, bg, beta):
    n = b.node("ND_mix_bsdf", name)
    n.set("fg", "BSDF", node=fg)
    n.set("bg", "BSDF", node=bg)
    if isinstance(beta, Node):
        n.set("mix", "float", node=beta)
    else:
        n.set("mix", "float", float(beta))
    return n


def _dielectric_base(b, base_color, transmission, lobes):
    """The dielectric's base: the diffuse, or (transmission) one base per lobe."""
    diffuse = b.node("ND_oren_nayar_diffuse_bsdf", "base_diffuse", weight=1.0,
                     color=tuple(base_color), roughness=0.0)
    if transmission <= 0:
        return diffuse, None
    bases = {}
    for which, (alpha, fresnel, dist, tangent) in lobes.items():
        t = _lobe(b, "DIELECTRIC", f"transmission_{which}", alpha,
                  dict(ior=fresnel["ior"], tint=tuple(base_color)), dist, tangent,
                  scatter_mode="T")
        bases[which] = _mix(b, f"base_{which}", t, diffuse, float(transmission))
    return diffuse, bases


def _finish_specular(b, kind, narrow, wide, beta, base_color=None, transmission=0.0, lobe_args=None):
    if kind != "DIELECTRIC":
        return _mix(b, "haze_mix", wide, narrow, beta)
    diffuse, bases = _dielectric_base(b, base_color, transmission, lobe_args)
    if bases is None:
        mix = _mix(b, "haze_mix", wide, narrow, beta)
        layer = b.node("ND_layer_bsdf", "specular_over_base")
        layer.set("top", "BSDF", node=mix)
        layer.set("base", "BSDF", node=diffuse)
        return layer
    layers = {}
    for which, lobe in (("narrow", narrow), ("wide", wide)):
        layer = b.node("ND_layer_bsdf", f"layer_{which}")
        layer.set("top", "BSDF", node=lobe)
        layer.set("base", "BSDF", node=bases[which])
        layers[which] = layer
    return _mix(b, "haze_mix", layers["wide"], layers["narrow"], beta)


# --------------------------------------------------------------------------------------------
# Eq. 1 graphs
# --------------------------------------------------------------------------------------------


def _graph_constant(name, p, notes):
    d = lobes_of(p)
    m = d.mapping
    g = NodeGraph(f"NG_{name}")
    b = _Builder(g)
    if p["distribution"] in _DIST_NOTE:
        notes.append(_DIST_NOTE[p["distribution"]])
    dist = _DIST[p["distribution"]]
    tangent = b.tangent(p["tangent"], p["rotation"]) if d.anisotropic else None
    ax, ay = (_f(a) for a in m.alpha)
    wx, wy = (_f(a) for a in m.alpha_wide)
    if d.kind == "CONDUCTOR":
        fres = dict(ior=_t(m.ior), extinction=_t(m.extinction))
    elif d.kind == "DIELECTRIC":
        fres = dict(ior=_f(m.dielectric_ior), tint=_t(d.fresnel["specular_tint"]))
    else:
        fres = dict(colour=_t(m.reflectivity))
    narrow = _lobe(b, d.kind, "lobe_narrow", (ax, ay), fres, dist, tangent)
    wide = _lobe(b, d.kind, "lobe_wide", (wx, wy), fres, dist, tangent)
    lobe_args = {"narrow": ((ax, ay), fres, dist, tangent), "wide": ((wx, wy), fres, dist, tangent)}
    top = _finish_specular(b, d.kind, narrow, wide, _f(d.beta), p["base_color"],
                           p["transmission"], lobe_args)
    g.outputs["out"] = Input("out", "BSDF", nodename=top.name)
    for reason, n in m.clamped.items():
        notes.append(f"clamped as Cycles renders it: {reason}")
    return g


def _decode(b, name, img, spec):
    if spec.png == "ratio":  # x / (1 - x)
        typ = "color3" if spec.channels == 3 else "float"
        one = (1.0, 1.0, 1.0) if typ == "color3" else 1.0
        den = b.node(f"ND_subtract_{typ}", f"{name}_one_minus", in1=one, in2=img)
        return b.node(f"ND_divide_{typ}", f"{name}_decoded", in1=img, in2=den)
    if spec.png == "negate":
        return b.node("ND_multiply_float", f"{name}_decoded", in1=img, in2=-1.0)
    return img


def _graph_maps(name, src, directory, notes):
    kind = str(src.kind).upper()
    specs = {s.name: s for s in output_specs(kind, src.anisotropic)}
    missing = sorted(set(specs) - set(src.maps))
    if missing:
        raise ValueError(f"{src.name}: the converted maps lack {', '.join(missing)}")
    g = NodeGraph(f"NG_{name}")
    b = _Builder(g)
    nodes = {}
    for mname, spec in specs.items():
        path = os.fspath(src.maps[mname])
        file = path
        if directory:
            try:
                file = os.path.relpath(path, directory)
            except ValueError:  # another drive
                file = path
        file = file.replace(os.sep, "/")
        typ = "color3" if spec.channels == 3 else "float"
        img = b.node(f"ND_image_{typ}", f"map_{mname}", filtertype=src.filtertype)
        img.set("file", "filename", file, colorspace=K.MATERIALX_DATA_COLORSPACE)
        nodes[mname] = _decode(b, f"map_{mname}", img, spec) if path.lower().endswith(".png") else img
    dist = _DIST[str(src.distribution).upper()]
    if str(src.distribution).upper() in _DIST_NOTE:
        notes.append(_DIST_NOTE[str(src.distribution).upper()])

    def alpha(which):
        suffix = "" if which == "narrow" else "_wide"
        rough = nodes["roughness" + suffix]
        if not src.anisotropic:
            a = 0.0
        elif kind == "LEGACY":  # Glossy a <= 0: α_x = R²/(1-|a|), α_y = R²(1-|a|) -> a' = 1-(1+a)²
            one_plus = b.node("ND_add_float", f"aniso{suffix}_1pa", in1=nodes["anisotropy" + suffix], in2=1.0)
            sq = b.node("ND_multiply_float", f"aniso{suffix}_sq", in1=one_plus, in2=one_plus)
            a = b.node("ND_subtract_float", f"aniso{suffix}_mx", in1=1.0, in2=sq)
        else:  # Metallic/Principled s = √(1 - 0.9 a): roughness_anisotropy with 0.9 a
            a = b.node("ND_multiply_float", f"aniso{suffix}_mx", in1=nodes["anisotropy" + suffix], in2=0.9)
        return b.node("ND_roughness_anisotropy", f"alpha_{which}", roughness=rough, anisotropy=a)

    tangents = {"narrow": None, "wide": None}
    if src.anisotropic:
        tangents = {"narrow": b.tangent(src.tangent, nodes["rotation"], "_narrow"),
                    "wide": b.tangent(src.tangent, nodes["rotation_wide"], "_wide")}
    if kind == "CONDUCTOR":
        fres = dict(ior=nodes["ior"], extinction=nodes["extinction"])
    elif kind == "DIELECTRIC":
        fres = dict(ior=nodes["ior"], tint=nodes["specular_tint"])
    else:  # r = k_n + k_w, mixed by β below (F ≡ r)
        fres = dict(colour=b.node("ND_add_color3", "reflectivity", in1=nodes["weight_narrow"],
                                  in2=nodes["weight_wide"]))
    lobe_args = {}
    lobes = {}
    for which in ("narrow", "wide"):
        a = alpha(which)
        lobes[which] = _lobe(b, kind, f"lobe_{which}", a, fres, dist, tangents[which])
        lobe_args[which] = (a, fres, dist, tangents[which])
    top = _finish_specular(b, kind, lobes["narrow"], lobes["wide"], nodes["beta"], src.base_color,
                           src.transmission, lobe_args)
    g.outputs["out"] = Input("out", "BSDF", nodename=top.name)
    notes.append("driven by converted maps: " + ", ".join(sorted(specs)))
    return g


def _add_material(doc, name, label, shader, attrs):
    doc.nodes[shader.name] = shader
    mat = Node(name, "surfacematerial", "material", attrs=attrs)
    mat.set("surfaceshader", "surfaceshader", node=shader)
    doc.nodes[name] = mat
    return mat


def _layered(doc, src, taken, directory, flavour):
    """A haze layer: the Blender tree as OpenPBR surfaces / pbr BSDFs and mixes (layered.py)."""
    from . import layered
    notes = list(src.notes)
    if flavour != "eq1":
        notes.append("a haze layer is written as its own network (OpenPBR 1.1.1 surfaces mixed by "
                     "β) whatever the flavour")
    name = valid_name(src.name, taken)
    try:
        g, w = layered.graph_of(src.layer, name, notes, directory=directory)
    except (KeyError, NotImplementedError, RecursionError, TypeError) as exc:
        raise ValueError(f"{src.name}: its haze layer's network could not be written "
                         f"({type(exc).__name__}: {exc})") from exc
    doc.graphs[g.name] = g
    taken.add(g.name)
    attrs = {f"{_ATTR}_name": src.name, f"{_ATTR}_version": K.INTERCHANGE_VERSION,
             f"{_ATTR}_flavour": "layer", f"{_ATTR}_layer": layered.layer_record(src.layer)}
    mat = Node(name, "surfacematerial", "material", attrs=attrs)
    mat.set("surfaceshader", "surfaceshader", nodegraph=g.name, output="out")
    doc.nodes[name] = mat
    return name, notes


def _eq1(doc, src, taken, directory):
    notes = list(src.notes)
    name = valid_name(src.name, taken)
    attrs = {f"{_ATTR}_name": src.name, f"{_ATTR}_version": K.INTERCHANGE_VERSION,
             f"{_ATTR}_flavour": "eq1"}
    if src.maps:
        g = _graph_maps(name, src, directory, notes)
        attrs[f"{_ATTR}_maps"] = json.dumps(dict(
            kind=str(src.kind).upper(), distribution=str(src.distribution).upper(),
            anisotropic=bool(src.anisotropic), base_color=list(src.base_color),
            transmission=float(src.transmission), tangent=src.tangent))
        kind = str(src.kind).upper()
    else:
        p = normalise(dict(src.parameters), explicit=())
        if p["shader_mapping"]:
            notes.append("in-shader mapping: written with its constant parameters (textures "
                         "linked into the group are not exported)")
        g = _graph_constant(name, p, notes)
        attrs[f"{_ATTR}_parameters"] = json.dumps(_record(p))
        kind = p["kind"]
    g.attrs[f"{_ATTR}_kind"] = kind
    g.attrs[f"{_ATTR}_model"] = ("Barla 2018 Eq. 1: ((1-beta) f_narrow + beta f_wide) F, "
                                 "mix(fg=wide, bg=narrow, mix=beta)")
    doc.graphs[g.name] = g
    taken.add(g.name)
    surf = Node(valid_name(f"SR_{name}", taken), "surface", "surfaceshader")
    surf.set("bsdf", "BSDF", nodegraph=g.name, output="out")
    surf.set("opacity", "float", 1.0)
    _add_material(doc, name, src.name, surf, attrs)
    return name, notes


# --------------------------------------------------------------------------------------------
# OpenPBR 1.2 flavour
# --------------------------------------------------------------------------------------------

_OPENPBR_12_WRITTEN = ("base_weight", "base_color", "base_metalness", "specular_weight",
                       "specular_color", "specular_roughness", "specular_ior",
                       "specular_roughness_anisotropy", "transmission_weight",
                       "geometry_normal", "geometry_tangent")


def _openpbr_12_definition():
    """The embedded nodedef (OpenPBR 1.2 subset) and its implementation from released nodes."""
    import xml.etree.ElementTree as ET
    inputs = {k: OPENPBR_INPUTS[k] for k in _OPENPBR_12_WRITTEN}
    inputs.update(OPENPBR_12_INPUTS)
    nd = ET.Element("nodedef", name=K.OPENPBR_12_NODEDEF, node="open_pbr_surface",
                    version=K.OPENPBR_12_VERSION, nodegroup="pbr",
                    doc="OpenPBR Surface 1.2 (dev_1.2, unreleased): the subset of inputs "
                        "hazy_gloss writes, with specular_haze and specular_haze_spread. "
                        "Embedded so that the document validates with MaterialX 1.39.")
    from .document import format_value
    for k, (t, v) in inputs.items():
        e = ET.SubElement(nd, "input", name=k, type=t)
        if isinstance(v, str) and t.startswith("vector"):
            e.set("defaultgeomprop", v)
        else:
            e.set("value", format_value(v, t))
    ET.SubElement(nd, "output", name="out", type="surfaceshader")
    ng = ET.Element("nodegraph", name="NG_open_pbr_surface_v1_2_hazygloss",
                    nodedef=K.OPENPBR_12_NODEDEF)
    hr = ET.SubElement(ng, "mix", name="haze_roughness", type="float")
    ET.SubElement(hr, "input", name="fg", type="float", value="1")
    ET.SubElement(hr, "input", name="bg", type="float", interfacename="specular_roughness")
    ET.SubElement(hr, "input", name="mix", type="float", interfacename="specular_haze_spread")
    for which in ("core", "haze"):
        s = ET.SubElement(ng, "open_pbr_surface", name=f"surface_{which}", type="surfaceshader",
                          version=K.OPENPBR_RELEASED_VERSION)
        for k in _OPENPBR_12_WRITTEN:
            t = OPENPBR_INPUTS[k][0]
            if which == "haze" and k == "specular_roughness":
                ET.SubElement(s, "input", name=k, type=t, nodename="haze_roughness")
            else:
                ET.SubElement(s, "input", name=k, type=t, interfacename=k)
    mx = ET.SubElement(ng, "mix", name="haze_mix", type="surfaceshader")
    ET.SubElement(mx, "input", name="fg", type="surfaceshader", nodename="surface_haze")
    ET.SubElement(mx, "input", name="bg", type="surfaceshader", nodename="surface_core")
    ET.SubElement(mx, "input", name="mix", type="float", interfacename="specular_haze")
    ET.SubElement(ng, "output", name="out", type="surfaceshader", nodename="haze_mix")
    return [nd, ng]


def _openpbr(doc, src, taken, measure):
    notes = list(src.notes)
    if src.maps:
        raise ValueError(f"{src.name}: the OpenPBR 1.2 flavour writes constant materials only "
                         f"(this one is driven by converted maps: use flavour 'eq1')")
    p = normalise(dict(src.parameters), explicit=())
    d = lobes_of(p)
    fit = engines.engine_parameters(d, ("openpbr_1_2",), measure=measure)["openpbr_1_2"]
    notes += fit.notes
    if measure:
        e = fit.error
        notes.append(f"BRDF error against Eq. 1: max {e['max']:.3g}, mean {e['mean']:.3g}")
    name = valid_name(src.name, taken)
    q = fit.parameters
    s = Node(valid_name(f"SR_{name}", taken), "open_pbr_surface", "surfaceshader",
             attrs={"version": K.OPENPBR_12_VERSION})
    for k in ("base_weight", "base_metalness", "specular_weight", "specular_roughness",
              "specular_roughness_anisotropy", "specular_haze", "specular_haze_spread"):
        t = OPENPBR_INPUTS.get(k, OPENPBR_12_INPUTS.get(k))[0]
        s.set(k, t, float(q[k]))
    s.set("specular_color", "color3", tuple(q["specular_color"]))
    if p["kind"] == "DIELECTRIC":
        s.set("base_color", "color3", tuple(p["base_color"]))
        s.set("specular_ior", "float", float(q["specular_ior"]))
        if p["transmission"] > 0:
            s.set("transmission_weight", "float", float(p["transmission"]))
    else:
        s.set("base_color", "color3", tuple(q["base_color"]))
    rot = p["rotation"] + q["geometry_tangent_rotation"]
    if d.anisotropic:
        g = NodeGraph(f"NG_{name}_tangent")
        t = _Builder(g).tangent(p["tangent"], rot)
        g.outputs["out"] = Input("out", "vector3", nodename=t.name)
        doc.graphs[g.name] = g
        taken.add(g.name)
        s.set("geometry_tangent", "vector3", nodegraph=g.name, output="out")
    attrs = {f"{_ATTR}_name": src.name, f"{_ATTR}_version": K.INTERCHANGE_VERSION,
             f"{_ATTR}_flavour": "openpbr_1.2", f"{_ATTR}_parameters": json.dumps(_record(p))}
    if measure:
        attrs[f"{_ATTR}_openpbr_error"] = json.dumps(fit.error)
    _add_material(doc, name, src.name, s, attrs)
    return name, notes


# --------------------------------------------------------------------------------------------
# Documents
# --------------------------------------------------------------------------------------------


def build_document(sources, flavour="eq1", *, directory=None, embed_openpbr_12=True, measure=True):
    """(Document, [(name, MaterialX name, notes)]) for ``sources`` (Source objects).
    ``directory``: where the file goes (texture paths are written relative to it)."""
    if flavour not in FLAVOURS:
        raise ValueError(f"flavour must be one of {', '.join(FLAVOURS)}, got {flavour!r}")
    doc = Document(attrs={"colorspace": K.MATERIALX_COLORSPACE})
    doc.comments.append(
        "Written by hazy_gloss (Barla, Pacanowski & Vangorp 2018, A Composite BRDF Model for "
        "Hazy Gloss). " + ("Eq. 1 from the MaterialX 1.39 pbr library." if flavour == "eq1" else
                           "Targets OpenPBR 1.2 (dev_1.2, unreleased): open_pbr_surface "
                           "version 1.2 with specular_haze / specular_haze_spread; the nodedef "
                           "is embedded (a subset, implemented with OpenPBR 1.1.1)."))
    if any(getattr(src, "layer", None) is not None for src in sources):
        doc.comments.append(
            "Materials with a haze layer (hazygloss_flavour layer) are the artist's own network: "
            "each BSDF of the layer an open_pbr_surface (OpenPBR 1.1.1) or a pbr BSDF, mixed by "
            "beta as the Blender tree mixes them (docs/interchange.md section 5).")
    if flavour == "openpbr_1.2":
        doc.attrs[f"{_ATTR}_flavour"] = "openpbr_1.2"
        if embed_openpbr_12:
            doc.extra.extend(_openpbr_12_definition())
    taken = set()
    done = []
    for src in sources:
        if src.layer is not None:
            name, notes = _layered(doc, src, taken, directory, flavour)
        elif flavour == "eq1":
            name, notes = _eq1(doc, src, taken, directory)
        else:
            name, notes = _openpbr(doc, src, taken, measure)
        done.append((src.name, name, notes))
    return doc, done


def materialx_available():
    try:
        import MaterialX  # noqa: F401
    except ImportError:
        return False
    return True


def validate(path):
    """(ok, message) from the materialx package's Document.validate() with the standard
    libraries loaded, or (None, reason) when the package is not installed."""
    try:
        import MaterialX as mx
    except ImportError:
        return None, ("the materialx package is not installed (pip install materialx): the "
                      "document was written but not validated")
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    doc.importLibrary(lib)
    ok, msg = doc.validate()
    return bool(ok), msg


def write(sources, path, flavour="eq1", *, validate_with_package=True, **options):
    """Write ``sources`` to one MaterialX document at ``path``; returns an ExportReport."""
    path = os.path.abspath(os.fspath(path))
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    doc, done = build_document(sources, flavour, directory=os.path.dirname(path), **options)
    write_xml(doc, path)
    rep = ExportReport(path, flavour, done)
    if validate_with_package:
        rep.validated, rep.validation = validate(path)
    return rep


# --------------------------------------------------------------------------------------------
# Import
# --------------------------------------------------------------------------------------------


@dataclass
class ImportedMaterial:
    """One material recognised in a document.  ``parameters``: keyword arguments for
    api.create_material (perceptual); ``exact``: the parameters reproduce the document's
    BRDF (its physical values within 1e-6 relative, no textured input); ``notes``: every
    approximation, and what the inverse mapping could not recover uniquely (e.g. the haze
    extent beyond α_w = 1, which renders the same)."""

    name: str
    parameters: dict = None
    exact: bool = False
    source: str = ""  #: "hazy_gloss", "two-lobe mix", "single lobe", "OpenPBR 1.2"
    notes: list = field(default_factory=list)
    physical: dict = field(default_factory=dict)
    deviation: float = 0.0  #: max relative difference of the re-mapped physical values
    maps: dict = None  #: {map name: absolute path} of a map-driven material (hazy_gloss only)
    map_info: dict = None
    material: object = None  #: the Blender material made from it (set by the importer in Blender)

    @property
    def ok(self):
        return self.parameters is not None or self.maps is not None


class _Notes(list):
    """Notes of one import; ``lose`` records one that makes the import inexact."""

    lost = 0

    def lose(self, text):
        self.append(text)
        self.lost += 1


class _Eval:
    """Reads constant values out of a document (following connections through a few pure
    nodes); inputs fed by images or anything else are flagged as textured."""

    def __init__(self, doc):
        self.doc = doc

    def default(self, node, name):
        for nd, (cat, typ, spec) in NODEDEFS.items():
            if cat == node.category and typ == node.type and name in spec:
                return spec[name][1]
        if node.category == "open_pbr_surface":
            spec = dict(OPENPBR_INPUTS)
            spec.update(OPENPBR_12_INPUTS)
            if name in spec:
                return spec[name][1]
            return OPENPBR_UNSUPPORTED.get(name)
        return None

    def value(self, node, graph, name, textured):
        inp = node.inputs.get(name)
        kind, v, g = self.doc.resolve(inp, graph)
        if kind == "value":
            return self.default(node, name) if v is None else v
        if v.category == "artistic_ior":  # Gulbrandsen (r, g) -> (η, κ), as MaterialX has it
            r = np.clip(np.asarray(self.value(v, g, "reflectivity", textured), float), 0.0, 0.99)
            e = np.asarray(self.value(v, g, "edge_color", textured), float)
            eta, kap = gulbrandsen_ior(r, e)
            return _t(kap if inp.output == "extinction" else eta)
        return self.node_value(v, g, textured, f"{node.name}.{name}")

    def node_value(self, n, g, textured, where):
        c = n.category
        if c == "constant":
            return self.value(n, g, "value", textured)
        if c == "image":
            textured.append(where)
            d = self.value(n, g, "default", textured)
            return d
        if c == "roughness_anisotropy":
            r = float(self.value(n, g, "roughness", textured))
            a = float(self.value(n, g, "anisotropy", textured))
            alpha = min(max(r * r, 1.1920929e-07), 1.0)
            if a > 0:
                s = math.sqrt(1.0 - min(max(a, 0.0), 0.98))
                return (min(alpha / s, 1.0), alpha * s)
            return (alpha, alpha)
        if c == "roughness_dual":  # (r_x², r_y²); r_y < 0 means r_y = r_x
            r = tuple(float(x) for x in self.value(n, g, "roughness", textured) or (0.0, -1.0))
            rx, ry = r[0], (r[1] if r[1] >= 0 else r[0])
            return (min(max(rx * rx, 1.1920929e-07), 1.0), min(max(ry * ry, 1.1920929e-07), 1.0))
        if c in ("add", "subtract", "multiply", "divide") and n.type in ("float", "color3", "vector2", "vector3"):
            a = np.asarray(self.value(n, g, "in1", textured), dtype=np.float64)
            b = np.asarray(self.value(n, g, "in2", textured), dtype=np.float64)
            with np.errstate(divide="ignore", invalid="ignore"):
                out = {"add": a + b, "subtract": a - b, "multiply": a * b, "divide": a / b}[c]
            return float(out) if out.ndim == 0 else tuple(float(x) for x in out)
        if c == "mix" and n.type in ("float", "color3", "vector2", "vector3"):
            fg = np.asarray(self.value(n, g, "fg", textured), dtype=np.float64)
            bg = np.asarray(self.value(n, g, "bg", textured), dtype=np.float64)
            m = float(self.value(n, g, "mix", textured))
            out = bg + (fg - bg) * m
            return float(out) if out.ndim == 0 else tuple(float(x) for x in out)
        if c == "convert":
            return self.value(n, g, "in", textured)
        textured.append(f"{where} <- {c}")
        return self.default(n, "value")

    def tangent(self, node, graph, name):
        """(rotation in turns, tangent kind, recognised) of a lobe's tangent input."""
        inp = node.inputs.get(name)
        kind, n, g = self.doc.resolve(inp, graph)
        turns = 0.0
        for _ in range(16):
            if kind == "value":
                return turns, "UV_MAP", n is None or n == "Tworld"
            if n.category == "tangent":
                return turns, "UV_MAP", True
            if n.category == "normalize":
                kind, n, g = self.doc.resolve(n.inputs.get("in"), g)
                continue
            if n.category == "rotate3d":
                tex = []
                turns += -float(self.value(n, g, "amount", tex)) / 360.0
                if tex:
                    return turns, "UV_MAP", False
                kind, n, g = self.doc.resolve(n.inputs.get("in"), g)
                continue
            if n.category == "transformvector":
                k2, cr, g2 = self.doc.resolve(n.inputs.get("in"), g)
                if k2 == "node" and cr.category == "crossproduct":
                    ax = self.value(cr, g2, "in1", [])
                    for i, a in enumerate("XYZ"):
                        if tuple(ax) == tuple(1.0 if j == i else 0.0 for j in range(3)):
                            return turns, f"RADIAL_{a}", True
                return turns, "UV_MAP", False
            return turns, "UV_MAP", False
        return turns, "UV_MAP", False


_FRESNEL_INPUTS = {"CONDUCTOR": ("ior", "extinction"), "DIELECTRIC": ("ior", "tint"),
                   "LEGACY": ("color0", "color82", "color90", "exponent")}


def _lobe_values(ev, node, graph, kind):
    tex = []
    v = {k: ev.value(node, graph, k, tex) for k in _FRESNEL_INPUTS[kind] + ("weight", "roughness", "distribution")}
    if kind != "CONDUCTOR":
        v["scatter_mode"] = ev.value(node, graph, "scatter_mode", tex)
    v["rotation"], v["tangent"], v["tangent_ok"] = ev.tangent(node, graph, "tangent")
    v["textured"] = tex
    return v


def _close(a, b, rtol=K.INTERCHANGE_RTOL):
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):  # a damaged file's inf / NaN: not close
        return bool(np.all(np.abs(a - b) <= rtol * np.maximum(np.abs(a), np.abs(b)) + 1e-12))


def _rel(a, b):
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        return float(np.max(np.abs(a - b) / np.maximum(np.maximum(np.abs(a), np.abs(b)), 1e-300)))


def _bsdf_structure(ev, node, graph, notes):
    """Walk the BSDF: (kind, narrow, wide, beta, base) with lobes as (Node, graph)."""
    doc = ev.doc
    base = dict(base_color=(0.0, 0.0, 0.0), transmission=0.0, textured=[])

    def res(n, g, name):
        k, x, gg = doc.resolve(n.inputs.get(name), g)
        return (x, gg) if k == "node" else (None, None)

    def read_base(n, g):
        if n is None:
            return
        if n.category in ("oren_nayar_diffuse_bsdf", "burley_diffuse_bsdf"):
            tex = []
            base["base_color"] = tuple(ev.value(n, g, "color", tex))
            w = float(ev.value(n, g, "weight", tex))
            if w != 1.0:
                base["base_color"] = tuple(w * c for c in base["base_color"])
            if tex:
                base["textured"] += tex
                notes.lose("the base colour is textured: imported at the image's default")
        elif n.category == "mix" and n.type == "BSDF":
            fg, gf = res(n, g, "fg")
            bg, gb = res(n, g, "bg")
            tex = []
            t = float(ev.value(n, g, "mix", tex))
            if fg is not None and fg.category == "dielectric_bsdf":
                base["transmission"] = t
                read_base(bg, gb)
            elif bg is not None and bg.category == "dielectric_bsdf":
                base["transmission"] = 1.0 - t
                read_base(fg, gf)
            else:
                notes.lose(f"base {n.name!r} not recognised: base colour black")
        else:
            notes.lose(f"base {n.category!r} not recognised: base colour black")

    n, g = node, graph
    if n.category == "layer":
        read_base(*res(n, g, "base"))
        n, g = res(n, g, "top")
        if n is None:
            return None
    if n.category in _LOBES:
        return (_LOBES[n.category], (n, g), (n, g), 0.0, base, "single lobe")
    if n.category == "mix" and n.type == "BSDF":
        fg, gf = res(n, g, "fg")
        bg, gb = res(n, g, "bg")
        tex = []
        m = float(ev.value(n, g, "mix", tex))
        if tex:
            base["textured"] += tex
            notes.lose("the mix weight β is textured: imported at the image's default value")
        if fg is None or bg is None:
            return None
        if fg.category == "layer" and bg.category == "layer":  # per-lobe layers (transmission)
            read_base(*res(bg, gb, "base"))
            fg, gf = res(fg, gf, "top")
            bg, gb = res(bg, gb, "top")
            if fg is None or bg is None:
                return None
        if fg.category in _LOBES and fg.category == bg.category:
            return (_LOBES[fg.category], (bg, gb), (fg, gf), m, base, "two-lobe mix")
        notes.append(f"mix of {fg.category} and {bg.category}: not a two-lobe hazy mix")
        return None
    if n.category == "add" and n.type == "BSDF":
        a, ga = res(n, g, "in1")
        b, gb = res(n, g, "in2")
        if a is not None and b is not None and a.category == b.category == "generalized_schlick_bsdf":
            return ("LEGACY", (a, ga), (b, gb), None, base, "two-lobe sum")
        return None
    return None


def _alpha_to_roughness(ax, ay, rotation, extent, notes):
    """(R, anisotropy, rotation, (λx, λy)) in Blender's Metallic convention from α."""
    lx, ly = extent
    if ay > ax:
        ax, ay, lx, ly = ay, ax, ly, lx
        rotation += 0.25
    rough = math.sqrt(math.sqrt(ax) * math.sqrt(ay))
    ratio = ay / ax if ax > 0 else 1.0
    aniso = (1.0 - ratio) / 0.9
    if aniso > 1.0:
        notes.lose(f"core aspect {1 / ratio:.3g} is beyond Blender's 10: anisotropy 1")
        aniso = 1.0
    rotation = rotation - math.floor(rotation) if rotation else 0.0
    return rough, aniso, rotation, (lx, ly)


def _physical(d):
    m = d.mapping
    out = dict(beta=_f(d.beta), alpha=tuple(_f(a) for a in m.alpha),
               alpha_wide=tuple(_f(a) for a in m.alpha_wide))
    if d.kind == "CONDUCTOR":
        out.update(ior=_t(m.ior), extinction=_t(m.extinction))
    elif d.kind == "DIELECTRIC":
        out.update(ior=_f(m.dielectric_ior), tint=_t(d.fresnel["specular_tint"]))
    else:
        out.update(colour=_t(m.reflectivity))
    return out


def _deviation(phys, d):
    """Max relative difference between the document's physical values and those of ``d``."""
    ref = _physical(d)
    worst = 0.0
    for k, v in phys.items():
        if k in ref:
            a, b = np.asarray(v, float), np.asarray(ref[k], float)
            if k == "beta":
                worst = max(worst, abs(float(a) - float(b)))  # absolute: β may be 0
            else:
                worst = max(worst, _rel(a, b))
    return worst


def _from_physical(kind, dist, phys, rotation, tangent, base, smoothness, notes):
    """inverse_haze_mapping of one material's physical values -> (parameters, exact)."""
    ax, ay = phys["alpha"]
    wx, wy = phys["alpha_wide"]
    beta = phys["beta"]
    if kind == "CONDUCTOR":
        inv = inverse_haze_mapping(beta, (ax, ay), (wx, wy), ior=phys["ior"],
                                   extinction=phys["extinction"], distribution=dist,
                                   smoothness=smoothness, alpha_max=K.ALPHA_MAX)
    else:
        if kind == "DIELECTRIC":
            eta = float(phys["ior"])
            rmax = ((eta - 1.0) / (eta + 1.0)) ** 2
            tint = np.asarray(phys["tint"], dtype=np.float64)
            if not math.isclose(float(np.max(tint)), 1.0, rel_tol=1e-9):
                notes.lose("dielectric tint with max channel ≠ 1: reflectivity = F0(η) · tint")
            r = rmax * tint
        else:
            r = np.asarray(phys["colour"], dtype=np.float64)
        inv = inverse_haze_mapping(beta, (ax, ay), (wx, wy), reflectivity=r, distribution=dist,
                                   smoothness=smoothness, alpha_max=K.ALPHA_MAX)
    notes.extend(inv.warnings)
    rc = _t(np.clip(inv.core_reflectivity, 0.0, 1.0))
    g = _t(np.clip(inv.edge_tint, 0.0, 1.0))
    lam = tuple(_f(v) for v in inv.haze_extent)
    rough, aniso, rot, lam = _alpha_to_roughness(ax, ay, rotation, lam, notes)
    p = dict(kind=kind, distribution=dist, core_reflectivity=rc,
             edge_tint=g if kind == "CONDUCTOR" else (0.0, 0.0, 0.0), roughness=min(rough, 1.0),
             anisotropy=aniso, rotation=rot, haziness=min(_f(inv.haziness), K.MAX_HAZINESS),
             haze_extent=lam, smoothness=smoothness, tangent=tangent)
    if kind == "DIELECTRIC":
        p["base_color"] = tuple(float(np.clip(c, 0, 1)) for c in base["base_color"])
        p["transmission"] = float(np.clip(base["transmission"], 0, 1))
    return p, bool(np.all(inv.exact))


def _check(name, p, phys, notes, source):
    """Normalise ``p``, map it forward and compare with the document: an ImportedMaterial."""
    try:
        p = normalise(p)
        d = lobes_of(p)
    except ValueError as exc:
        notes.append(f"not representable: {exc}")
        return ImportedMaterial(name, None, False, source, notes, phys)
    dev = _deviation(phys, d)
    exact = dev <= 1e-6 and not getattr(notes, "lost", 0)
    if dev > 1e-6:
        notes.append(f"the imported material differs from the document by up to {dev:.3g} "
                     f"(relative, physical parameters)")
    return ImportedMaterial(name, p, exact, source, notes, phys, dev)


def _stored(mat):
    raw = mat.attrs.get(f"{_ATTR}_parameters")
    if not raw:
        return None
    try:
        p = json.loads(raw)
        for k, v in list(p.items()):
            if isinstance(v, list):
                p[k] = tuple(v)
        return normalise(p, explicit=())
    except (ValueError, TypeError):
        return None


def _recognise_eq1(ev, mat, label, shader, graph, use_stored=True):
    notes = _Notes()
    kind_of = ev.doc.resolve(shader.inputs.get("bsdf"), graph)
    if kind_of[0] != "node":
        return ImportedMaterial(label, None, False, "", ["the surface has no BSDF"])
    found = _bsdf_structure(ev, kind_of[1], kind_of[2], notes)
    if found is None:
        return ImportedMaterial(label, None, False, "", notes + ["no two-lobe hazy BSDF found"])
    kind, (nn, gn), (wn, gw), beta, base, source = found
    vn = _lobe_values(ev, nn, gn, kind)
    vw = _lobe_values(ev, wn, gw, kind)
    for v in (vn, vw):
        if v["textured"]:
            notes.lose("textured inputs imported at their image's default value: "
                         + ", ".join(v["textured"]))
    an = tuple(float(x) for x in vn["roughness"])
    aw = tuple(float(x) for x in vw["roughness"])
    if source == "two-lobe sum":  # legacy add: weights in the colours
        cn = np.asarray(vn["color0"], float)
        cw = np.asarray(vw["color0"], float)
        if an[0] * an[1] > aw[0] * aw[1]:
            an, aw, cn, cw, vn, vw = aw, an, cw, cn, vw, vn
        tot = cn + cw
        beta = float(np.max(cw) / np.max(tot)) if np.max(tot) > 0 else 0.0
        vn = dict(vn, color0=tuple(tot), color90=tuple(tot))
        vw = dict(vw, color0=tuple(tot), color90=tuple(tot))
    elif an[0] * an[1] > aw[0] * aw[1]:  # the narrow lobe is the one with the smaller α_x α_y
        an, aw, vn, vw = aw, an, vw, vn
        beta = 1.0 - beta
    # one shared Fresnel
    for k in _FRESNEL_INPUTS[kind] + ("distribution",):
        if k in ("color0", "color90") and source == "two-lobe sum":
            continue
        if vn[k] != vw[k] and not (isinstance(vn[k], (tuple, float)) and _close(vn[k], vw[k])):
            notes.lose(f"the lobes do not share {k} ({vn[k]} vs {vw[k]}): the narrow lobe's is used")
    for v in (vn, vw):
        if not math.isclose(float(v["weight"]), 1.0, rel_tol=1e-12):
            notes.lose(f"lobe weight {v['weight']:g} ≠ 1 ignored")
    if not vn["tangent_ok"]:
        notes.lose("tangent not recognised: the UV tangent is used")
    if not _close(vn["rotation"], vw["rotation"]):
        d_rot = (vw["rotation"] - vn["rotation"]) % 0.5
        if math.isclose(d_rot, 0.25, abs_tol=1e-9):
            aw = (aw[1], aw[0])
        else:
            notes.lose("the lobes' tangents differ: the halo is taken along the core's tangent")
    dist_name = str(vn["distribution"]).lower()
    dist = {"ggx": "GGX", "beckmann": "BECKMANN"}.get(dist_name)
    if dist is None:
        notes.lose(f"distribution {dist_name!r} read as GGX")
        dist = "GGX"
    if kind == "DIELECTRIC" and dist == "BECKMANN":
        notes.lose("Beckmann dielectric lobes read as GGX (the Principled BSDF has no Beckmann)")
        dist = "GGX"
    if kind == "LEGACY":
        c0, c90 = vn["color0"], vn["color90"]
        if not _close(c0, c90):
            notes.lose("generalized_schlick with color90 ≠ color0 read as a constant F = color0 "
                         "(legacy lobes have no Fresnel)")
        if not _close(vn["color82"], (1.0, 1.0, 1.0)):
            notes.lose("color82 ≠ 1 ignored")
    if kind != "CONDUCTOR" and str(vn.get("scatter_mode", "R")) != "R":
        notes.lose(f"scatter_mode {vn['scatter_mode']} of the lobes read as R")
    phys = dict(beta=float(beta), alpha=an, alpha_wide=aw)
    if kind == "CONDUCTOR":
        phys.update(ior=tuple(vn["ior"]), extinction=tuple(vn["extinction"]))
    elif kind == "DIELECTRIC":
        phys.update(ior=float(vn["ior"]), tint=tuple(vn["tint"]))
    else:
        phys.update(colour=tuple(vn["color0"]))
    maps_raw = mat.attrs.get(f"{_ATTR}_maps")
    if maps_raw:  # our own map-driven material: hand back its maps
        return _recognise_maps(ev, label, maps_raw, nn, gn, notes)
    stored = _stored(mat) if use_stored else None
    if stored is not None and stored["kind"] == kind:
        d = lobes_of(stored)
        dev = _deviation(phys, d)
        if dev <= K.INTERCHANGE_RTOL:
            return ImportedMaterial(label, stored, not notes.lost, "hazy_gloss", notes, phys, dev)
        notes.append(f"the graph was edited after export (differs by {dev:.3g}): the stored "
                     f"parameters are ignored")
    smooth = stored["smoothness"] if stored is not None else None
    p, _ = _from_physical(kind, dist, phys, vn["rotation"], vn["tangent"], base, smooth, notes)
    out = _check(label, p, phys, notes, source)
    out.exact = out.exact and not (vn["textured"] or vw["textured"] or base["textured"])
    return out


def _recognise_maps(ev, label, raw, narrow, graph, notes):
    info = json.loads(raw)
    g = graph
    maps = {}
    base = os.path.dirname(os.path.abspath(ev.doc.source)) if ev.doc.source else os.getcwd()
    for n in (g.nodes.values() if g is not None else ev.doc.nodes.values()):
        if n.category == "image" and n.name.startswith("map_"):
            f = n.value("file", "")
            maps[n.name[4:]] = os.path.normpath(os.path.join(base, f)) if not os.path.isabs(f) else f
    notes.append("a map-driven material: its converted maps are imported as image textures")
    return ImportedMaterial(label, None, True, "hazy_gloss", notes, maps=maps, map_info=info)


def _gulbrandsen_fit(f0, tint):
    """Edge tint g (per channel) whose Gulbrandsen conductor Fresnel is closest (L2 over μ) to
    OpenPBR's F82-tint Fresnel with F0 and tint; returns (η, κ, g, max |ΔF|)."""
    f0 = np.clip(np.asarray(f0, dtype=np.float64), 1e-6, 1.0 - 1e-9)
    mu = np.linspace(0.0, 1.0, 129)
    target = np.clip(f82_tint(mu, f0, tint), 0.0, 1.0)
    gs = np.linspace(0.0, 1.0, 401)
    best = np.zeros(3)
    for ch in range(3):
        r = np.full_like(gs, f0[ch])
        eta, kap = gulbrandsen_ior(r, gs)
        err = [np.sum((fresnel_conductor(mu, e, k) - target[:, ch]) ** 2) for e, k in zip(eta, kap)]
        i = int(np.argmin(err))
        lo, hi = gs[max(i - 1, 0)], gs[min(i + 1, len(gs) - 1)]
        for _ in range(40):  # golden-section refinement
            a = hi - (hi - lo) * 0.618
            b = lo + (hi - lo) * 0.618
            ea = np.sum((fresnel_conductor(mu, *gulbrandsen_ior(f0[ch], a)) - target[:, ch]) ** 2)
            eb = np.sum((fresnel_conductor(mu, *gulbrandsen_ior(f0[ch], b)) - target[:, ch]) ** 2)
            lo, hi = (lo, b) if ea < eb else (a, hi)
        best[ch] = 0.5 * (lo + hi)
    eta, kap = gulbrandsen_ior(f0, best)
    fit = np.array([fresnel_conductor(mu, eta[c], kap[c]) for c in range(3)]).T
    return eta, kap, best, float(np.max(np.abs(fit - target)))


def _openpbr_values(ev, shader, graph):
    """The OpenPBR inputs engines.openpbr_12 sets, as read from the document."""
    out = {}
    for k in ("specular_haze", "specular_haze_spread", "specular_roughness",
              "specular_roughness_anisotropy", "base_metalness", "specular_color", "base_color",
              "specular_ior"):
        out[k] = ev.value(shader, graph, k, [])
    return out


def _recognise_openpbr(ev, mat, label, shader, graph, use_stored=True):
    notes = _Notes()
    tex = []

    def val(k):
        return ev.value(shader, graph, k, tex)

    haze = float(val("specular_haze"))
    spread = float(val("specular_haze_spread"))
    if "specular_haze" not in shader.inputs:
        notes.append("no specular_haze: imported with haziness 0 (an OpenPBR 1.1 surface)")
    for k, dflt in OPENPBR_UNSUPPORTED.items():
        if k in shader.inputs and float(np.max(np.asarray(val(k), float))) != dflt:
            notes.lose(f"{k} is not part of a hazy material: ignored")
    metal = float(val("base_metalness"))
    kind = "CONDUCTOR" if metal >= 0.5 else "DIELECTRIC"
    if 0.0 < metal < 1.0:
        notes.lose(f"base_metalness {metal:g} is neither 0 nor 1: read as "
                     f"{'a metal' if kind == 'CONDUCTOR' else 'a dielectric'}")
    r_core = float(val("specular_roughness"))
    aniso = float(val("specular_roughness_anisotropy"))
    at, ab = engines.openpbr_anisotropy(r_core, aniso)
    r_haze = r_core + (1.0 - r_core) * spread
    ht, hb = engines.openpbr_anisotropy(r_haze, aniso)
    rot, tangent, ok = ev.tangent(shader, graph, "geometry_tangent")
    if not ok:
        notes.lose("geometry_tangent not recognised: the UV tangent is used")
    phys = dict(beta=haze, alpha=(at, ab), alpha_wide=(ht, hb))
    base = dict(base_color=(0.0, 0.0, 0.0), transmission=0.0)
    sw = float(val("specular_weight"))
    if not math.isclose(sw, 1.0):
        notes.lose(f"specular_weight {sw:g} ≠ 1 ignored")
    if kind == "CONDUCTOR":
        f0 = np.asarray(val("base_color"), float) * float(val("base_weight"))
        tint = np.asarray(val("specular_color"), float)
        eta, kap, g, err = _gulbrandsen_fit(f0, tint)
        notes.lose(f"F82-tint metal Fresnel fitted with Gulbrandsen's edge tint "
                     f"(max |ΔF| = {err:.3g})")
        phys.update(ior=_t(eta), extinction=_t(kap))
    else:
        eta = float(val("specular_ior"))
        tint = np.asarray(val("specular_color"), float)
        m = float(np.max(tint))
        if m > 0 and not np.allclose(tint, tint[0]):
            notes.lose("specular_color tints OpenPBR's whole dielectric Fresnel; Blender's "
                         "Specular Tint leaves the grazing edge white")
        phys.update(ior=eta, tint=_t(tint / m if m > 0 else np.ones(3)))
        if m > 0 and not math.isclose(m, 1.0):
            r_hat = ((eta - 1) / (eta + 1)) ** 2 * m
            phys["ior"] = float((1 + math.sqrt(r_hat)) / (1 - math.sqrt(r_hat)))
            notes.append("specular_color's brightness folded into the index of refraction")
        base["base_color"] = tuple(np.asarray(val("base_color"), float) * float(val("base_weight")))
        base["transmission"] = float(val("transmission_weight"))
    if tex:
        notes.lose("textured inputs imported at their image's default value: " + ", ".join(tex))
    stored = _stored(mat) if use_stored else None
    if stored is not None:  # ours: the original material, if the surface was not edited since
        q = engines.openpbr_12(lobes_of(stored)).parameters
        doc_q = _openpbr_values(ev, shader, graph)
        same = all(_close(doc_q[k], q[k]) for k in doc_q if k in q and k != "base_color") and (
            stored["kind"] == "DIELECTRIC" or _close(doc_q["base_color"], q["base_color"]))
        if same:
            return ImportedMaterial(label, stored, True, "hazy_gloss (OpenPBR flavour)", [
                "written by hazy_gloss: the stored parameters restore the original material "
                "(the OpenPBR surface is its approximation)"], phys)
        notes.append("the OpenPBR surface was edited after export: the stored parameters are ignored")
    p, _ = _from_physical(kind, "GGX", phys, rot, tangent, base, None, notes)
    out = _check(label, p, phys, notes, "OpenPBR 1.2")
    out.exact = out.exact and not tex
    return out


def recognise(doc, *, use_stored=True):
    """ImportedMaterial for every surfacematerial of a Document.  ``use_stored=False`` ignores
    the perceptual parameters hazy_gloss stores with its materials (recovers everything from
    the graph, as for a foreign document)."""
    ev = _Eval(doc)
    out = []
    for mat in doc.materials():
        label = mat.attrs.get(f"{_ATTR}_name") or mat.name
        try:
            out.append(_checked(_recognise_one(ev, doc, mat, label, use_stored)))
        except (ValueError, TypeError, IndexError, KeyError, AttributeError, ZeroDivisionError,
                OverflowError, RecursionError) as exc:  # a damaged material: said, the rest read
            what = str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__
            out.append(ImportedMaterial(label, None, False, "", [f"damaged, not imported: {what}"]))
    return out


def _checked(im):
    """Parameters with a non-finite number are no parameters (a damaged document)."""
    if im.parameters is None:
        return im
    for key, v in im.parameters.items():
        nums = v if isinstance(v, (tuple, list)) else (v,)
        if any(isinstance(x, (int, float)) and not isinstance(x, bool) and not math.isfinite(x)
               for x in nums):
            return ImportedMaterial(im.name, None, False, im.source,
                                    im.notes + [f"damaged, not imported: {key} is not finite"])
    return im


def _recognise_one(ev, doc, mat, label, use_stored):
    """ImportedMaterial of one surfacematerial."""
    if mat.attrs.get(f"{_ATTR}_flavour") == "layer":
        return ImportedMaterial(label, None, False, "hazy_gloss layer", [
            "a haze layer on the artist's own BSDF (OpenPBR surfaces mixed by β): importing "
            "it back as a layered material is not supported yet"])
    k, shader, g = doc.resolve(mat.inputs.get("surfaceshader"))
    if k != "node":
        return ImportedMaterial(label, None, False, "", ["no surface shader"])
    if shader.category == "surface":
        return _recognise_eq1(ev, mat, label, shader, g, use_stored)
    if shader.category == "open_pbr_surface":
        return _recognise_openpbr(ev, mat, label, shader, g, use_stored)
    return ImportedMaterial(label, None, False, "", [
        f"{shader.category} is not a hazy surface (expected surface with a two-lobe "
        f"mix, or open_pbr_surface with specular_haze)"])


def read(path, *, use_stored=True):
    """ImportedMaterial for every material of the MaterialX file at ``path``."""
    return recognise(read_xml(os.fspath(path)), use_stored=use_stored)
