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

Import (:func:`read`, :func:`recognise`) is interchange/materialx_import.py (re-exported here):
Eq. 1 graphs back into hazy materials, library surfaces (OpenPBR, standard_surface, gltf_pbr,
UsdPreviewSurface) into Principled materials, haze layers into the same layer.
"""
from __future__ import annotations

import json
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

from .. import constants as K
from ..conversion.convert import output_specs
from ..core.parameters import PARAMETERS, normalise
from . import engines, layered
from .builder import Builder
from .document import (NODEDEFS, OPENPBR_12_INPUTS, OPENPBR_INPUTS, Document, Input, Node,
                       NodeGraph, format_value, valid_name, write_xml)
# the reading side (re-exported: materialx.read is the reader's entry point)
from .materialx_import import LOBES as _LOBES, ImportedMaterial, as_float, as_tuple, lobes_of, read, recognise

__all__ = ("FLAVOURS", "Source", "ImportedMaterial", "ExportReport", "lobes_of", "build_document",
           "write", "read", "recognise", "validate", "materialx_available", "output_problem",
           "file_identity", "USD_EXTENSIONS")

FLAVOURS = ("eq1", "openpbr_1.2")
_ATTR = K.MATERIALX_ATTR
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
    tables: list = field(default_factory=list)  #: lookup tables written beside the document
    validated: object = None  #: True / False, or None when the materialx package is missing
    validation: str = ""

    @property
    def notes(self):
        return [f"{n}: {note}" for n, _, notes in self.materials for note in notes]


def _record(p):
    """The perceptual parameters as a JSON-able dict (what the stamp holds)."""
    out = {}
    for k in PARAMETERS:
        v = p.get(k)
        out[k] = list(v) if isinstance(v, tuple) else v
    return out


# --------------------------------------------------------------------------------------------
# Graph building helpers (the node builder: interchange/builder.py)
# --------------------------------------------------------------------------------------------


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
    b = Builder(g)
    if p["distribution"] in _DIST_NOTE:
        notes.append(_DIST_NOTE[p["distribution"]])
    dist = _DIST[p["distribution"]]
    tangent = b.tangent(p["tangent"], p["rotation"]) if d.anisotropic else None
    ax, ay = (as_float(a) for a in m.alpha)
    wx, wy = (as_float(a) for a in m.alpha_wide)
    if d.kind == "CONDUCTOR":
        fres = dict(ior=as_tuple(m.ior), extinction=as_tuple(m.extinction))
    elif d.kind == "DIELECTRIC":
        fres = dict(ior=as_float(m.dielectric_ior), tint=as_tuple(d.fresnel["specular_tint"]))
    else:
        fres = dict(colour=as_tuple(m.reflectivity))
    narrow = _lobe(b, d.kind, "lobe_narrow", (ax, ay), fres, dist, tangent)
    wide = _lobe(b, d.kind, "lobe_wide", (wx, wy), fres, dist, tangent)
    lobe_args = {"narrow": ((ax, ay), fres, dist, tangent), "wide": ((wx, wy), fres, dist, tangent)}
    top = _finish_specular(b, d.kind, narrow, wide, as_float(d.beta), p["base_color"],
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
    b = Builder(g)
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
             f"{_ATTR}_flavour": "layer", f"{_ATTR}_layer": layered.layer_record(src.layer, w)}
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
    inputs = {k: OPENPBR_INPUTS[k] for k in _OPENPBR_12_WRITTEN}
    inputs.update(OPENPBR_12_INPUTS)
    nd = ET.Element("nodedef", name=K.OPENPBR_12_NODEDEF, node="open_pbr_surface",
                    version=K.OPENPBR_12_VERSION, nodegroup="pbr",
                    doc="OpenPBR Surface 1.2 (dev_1.2, unreleased): the subset of inputs "
                        "hazy_gloss writes, with specular_haze and specular_haze_spread. "
                        "Embedded so that the document validates with MaterialX 1.39.")
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
        t = Builder(g).tangent(p["tangent"], rot)
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


#: The USD layers the exporter writes (usd-core cannot create a .usdz package: one is zipped
#: from layers, e.g. with usdzip).
USD_EXTENSIONS = (".usd", ".usda", ".usdc")
_SNIFF = 1 << 16  # bytes read to tell what an existing file is


def _is_document(path, kind):
    """Whether the existing file ``path`` is a ``kind`` document ("mtlx" / "usd"), or empty."""
    with open(path, "rb") as f:
        head = f.read(_SNIFF)
    if not head:
        return True  # (nothing to lose)
    if kind == "usd":
        return head.startswith((b"#usda", b"PXR-USDC", b"PK\x03\x04"))
    text = head.decode("utf-8", "replace").lstrip("\ufeff \t\r\n")
    return text.startswith("<") and re.search(r"<materialx[\s>/]", text) is not None


def output_problem(path, kind="mtlx"):
    """Why ``path`` must not be written as a ``kind`` document ("mtlx" or "usd"), in one line
    naming it, or None.  Refused: a folder, a USD extension usd-core cannot write, a folder
    that cannot hold it, and an existing file that is not a document of that kind (a .blend,
    an image: it would be lost).  Writing over an earlier export is allowed."""
    path = os.path.abspath(os.fspath(path))
    if os.path.isdir(path):
        return f"{path} is a folder: give the name of the file to write"
    ext = os.path.splitext(path)[1].lower()
    if kind == "usd" and ext not in USD_EXTENSIONS:
        why = "usd-core cannot create a .usdz package" if ext == ".usdz" else \
            f"not {ext or 'a name without an extension'}"
        return f"{path}: USD export writes {', '.join(USD_EXTENSIONS)} files ({why})"
    if os.path.lexists(path):
        what = "a USD layer" if kind == "usd" else "a MaterialX document"
        try:
            ok = os.path.isfile(path) and _is_document(path, kind)
        except OSError as exc:
            return f"{path} cannot be read ({exc.strerror or exc}): not overwritten"
        if not ok:
            return f"{path} exists and is not {what}: not overwritten (give another file name)"
    folder = os.path.dirname(path)
    while not os.path.lexists(folder):  # (missing folders are created: the nearest that exists)
        folder = os.path.dirname(folder)
    if not os.path.isdir(folder):
        return f"{path}: {folder} is a file, not a folder"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"{path}: the folder {folder} is not writable"
    return None


def file_identity(path):
    """What tells whether ``path`` was replaced (None: there is no such file)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


def write(sources, path, flavour="eq1", *, validate_with_package=True, **options):
    """Write ``sources`` to one MaterialX document at ``path``; returns an ExportReport.
    ValueError (one line) when ``path`` must not be written (:func:`output_problem`)."""
    path = os.path.abspath(os.fspath(path))
    problem = output_problem(path)
    if problem is not None:
        raise ValueError(problem)
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    doc, done = build_document(sources, flavour, directory=os.path.dirname(path), **options)
    write_xml(doc, path)
    rep = ExportReport(path, flavour, done)
    if validate_with_package:
        rep.validated, rep.validation = validate(path)
    return rep
