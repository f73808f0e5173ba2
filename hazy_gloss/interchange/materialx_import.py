# SPDX-License-Identifier: GPL-3.0-or-later
"""MaterialX (and USD, through interchange/usd.py) documents into materials: what
``api.import_materialx``, File > Import and ``import-materialx`` read (bpy-free).

For every ``surfacematerial`` (1.38 / 1.39; 1.37 ``material`` + ``shaderref`` are read as 1.38
has them) :func:`recognise` gives an :class:`ImportedMaterial`:

- the surfaces material libraries ship — ``open_pbr_surface`` 1.1 and the 1.2 draft,
  ``standard_surface``, ``gltf_pbr``, ``UsdPreviewSurface`` — become Principled BSDF materials
  (:mod:`.surfaces`: ``ImportedMaterial.surface``), their textures and simple math as nodes, and
  OpenPBR 1.2's ``specular_haze`` a haze layer (:mod:`.haze_blend`: the keywords of
  api.make_hazy whose layer renders the same blend);
- a haze layer exported by the add-on (``hazygloss_flavour`` "layer", interchange/layered.py)
  comes back as the user's BSDF with its layer (the record's haze parameters and the user's own
  values of the inputs the layer owns);
- an Eq. 1 graph (a BSDF ``mix`` of two conductor / dielectric / generalized_schlick lobes that
  differ in roughness, ours or a foreign writer's) becomes a hazy material of the add-on's own
  (``parameters``: core.inverse_haze_mapping, or the stored perceptual parameters of our files).

A damaged input is reported and read the way MaterialX 1.39.5 reads it (document.read_value:
a float written as a list is its first number, a value MaterialX refuses is skipped and the
nodedef's default used); a material that still cannot be read is reported and the rest of the
file is read.  No parameter returned is ever non-finite.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from .. import constants as K
from ..core.lobes import describe
from ..core.mapping import gulbrandsen_ior, inverse_haze_mapping
from ..core.parameters import HAZE_DEFAULTS, is_anisotropic, normalise
from . import engines, haze_blend, surfaces
from .document import (NODEDEFS, OPENPBR_12_INPUTS, OPENPBR_INPUTS, OPENPBR_UNSUPPORTED,
                       read_xml, valid_name)
from .surface_inputs import tangent_of
from .surface_nodes import Notes as _Notes

__all__ = ("ImportedMaterial", "lobes_of", "recognise", "read", "resolve_haze", "LOBES", "as_float",
           "as_tuple")

_ATTR = K.MATERIALX_ATTR
#: MaterialX BSDF node categories of Eq. 1's lobes, with the kind of hazy material they make.
LOBES = {"conductor_bsdf": "CONDUCTOR", "dielectric_bsdf": "DIELECTRIC",
         "generalized_schlick_bsdf": "LEGACY"}
_LOBES = LOBES
_DEFAULTS = {}
for _nd, (_cat, _typ, _spec) in NODEDEFS.items():
    _DEFAULTS.setdefault((_cat, _typ), _spec)


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


def as_float(x):
    return float(np.asarray(x))


def as_tuple(x):
    return tuple(float(v) for v in np.asarray(x, dtype=np.float64).reshape(-1))


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
    source: str = ""  #: "hazy_gloss", "two-lobe mix", "single lobe", "hazy_gloss layer", a surface
    notes: list = field(default_factory=list)
    physical: dict = field(default_factory=dict)
    deviation: float = 0.0  #: max relative difference of the re-mapped physical values
    maps: dict = None  #: {map name: absolute path} of a map-driven material (hazy_gloss only)
    map_info: dict = None
    material: object = None  #: the Blender material made from it (set by the importer in Blender)
    #: a library surface (or a layered document's core) as a Principled / Metallic / Glossy
    #: material: surfaces.SurfaceSpec, with ``haze`` for api.make_hazy
    surface: object = None

    @property
    def ok(self):
        return self.parameters is not None or self.maps is not None or self.surface is not None


class _Eval:
    """Reads constant values out of a document (following connections through a few pure
    nodes); inputs fed by images or anything else are flagged as textured."""

    def __init__(self, doc):
        self.doc = doc

    def default(self, node, name):
        spec = _DEFAULTS.get((node.category, node.type))
        if spec is not None and name in spec:
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
        if inp is not None and inp.problem:
            textured.append(f"{node.name}.{name}: {inp.problem}")
        kind, v, g = self.doc.resolve(inp, graph)
        if kind == "value":
            return self.default(node, name) if v is None else v
        if v.category == "artistic_ior":  # Gulbrandsen (r, g) -> (η, κ), as MaterialX has it
            r = np.clip(np.asarray(self.value(v, g, "reflectivity", textured), float), 0.0, 0.99)
            e = np.asarray(self.value(v, g, "edge_color", textured), float)
            eta, kap = gulbrandsen_ior(r, e)
            return as_tuple(kap if inp.output == "extinction" else eta)
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
        return tangent_of(self.doc, node.inputs.get(name), graph)


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
    out = dict(beta=as_float(d.beta), alpha=tuple(as_float(a) for a in m.alpha),
               alpha_wide=tuple(as_float(a) for a in m.alpha_wide))
    if d.kind == "CONDUCTOR":
        out.update(ior=as_tuple(m.ior), extinction=as_tuple(m.extinction))
    elif d.kind == "DIELECTRIC":
        out.update(ior=as_float(m.dielectric_ior), tint=as_tuple(d.fresnel["specular_tint"]))
    else:
        out.update(colour=as_tuple(m.reflectivity))
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
    rc = as_tuple(np.clip(inv.core_reflectivity, 0.0, 1.0))
    g = as_tuple(np.clip(inv.edge_tint, 0.0, 1.0))
    lam = tuple(as_float(v) for v in inv.haze_extent)
    rough, aniso, rot, lam = _alpha_to_roughness(ax, ay, rotation, lam, notes)
    p = dict(kind=kind, distribution=dist, core_reflectivity=rc,
             edge_tint=g if kind == "CONDUCTOR" else (0.0, 0.0, 0.0), roughness=min(rough, 1.0),
             anisotropy=aniso, rotation=rot, haziness=min(as_float(inv.haziness), K.MAX_HAZINESS),
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


def _openpbr_values(ev, shader, graph):
    """The OpenPBR inputs engines.openpbr_12 sets, as read from the document."""
    out = {}
    for k in ("specular_haze", "specular_haze_spread", "specular_roughness",
              "specular_roughness_anisotropy", "base_metalness", "specular_color", "base_color",
              "specular_ior"):
        out[k] = ev.value(shader, graph, k, [])
    return out


def _openpbr_stored(ev, mat, label, shader, graph):
    """Our own OpenPBR-flavour export: the stored parameters, if the surface is what they
    write (else None: the surface is read as any OpenPBR surface)."""
    stored = _stored(mat)
    if stored is None:
        return None
    q = engines.openpbr_12(lobes_of(stored)).parameters
    doc_q = _openpbr_values(ev, shader, graph)
    same = all(_close(doc_q[k], q[k]) for k in doc_q if k in q and k != "base_color") and (
        stored["kind"] == "DIELECTRIC" or _close(doc_q["base_color"], q["base_color"]))
    if not same:
        return None
    return ImportedMaterial(label, stored, True, "hazy_gloss (OpenPBR flavour)", [
        "written by hazy_gloss: the stored parameters restore the original material "
        "(the OpenPBR surface is its approximation)"])


# --------------------------------------------------------------------------------------------
# Library surfaces: Principled BSDF materials
# --------------------------------------------------------------------------------------------


#: The IOR input of each library surface (for the notes), and the largest IOR Blender's
#: Principled BSDF takes.
_IOR_INPUT = {"open_pbr_surface": "specular_ior", "standard_surface": "specular_IOR",
              "gltf_pbr": "ior", "UsdPreviewSurface": "ior"}
_IOR_MAX = 1000.0


def _valid_ior(spec, category):
    """An IOR below 1 (0 made the Principled's IOR 0.0) is outside the Principled's range: the
    IOR ≥ 1 with the same F(0) = ((η-1)/(η+1))² instead, capped at Blender's largest, and a
    note — as the other inputs beyond what Cycles takes are capped with one."""
    eta = spec.inputs.get("IOR")
    if not isinstance(eta, (int, float)) or isinstance(eta, bool) or not math.isfinite(eta) \
            or eta >= 1.0:
        return
    new = min(1.0 / eta, _IOR_MAX) if eta > 0.0 else _IOR_MAX
    spec.inputs["IOR"] = new
    spec.notes.append(f"{_IOR_INPUT.get(category, 'IOR')} {eta:g} is below 1, outside the "
                      f"Principled's IOR range: imported as IOR {new:.4g}, the one with the same "
                      f"F(0) (refraction differs)")
    spec.lossy += 1


def _surface(doc, mat, label, shader, graph):
    notes = _Notes()
    spec = surfaces.principled_of(doc, shader, graph, label, notes)
    _valid_ior(spec, shader.category)
    if spec.haze_target is not None:
        spec.notes.append("specular_haze: a haze layer (api.make_hazy) reproduces OpenPBR 1.2's "
                          "blend of the core and haze lobes (docs/interchange.md §2)")
    for other in ("backsurfaceshader", "displacementshader"):
        if mat.inputs.get(other) is not None and mat.inputs[other].connected:
            notes.lose(f"the material's {other} is not imported")
    return ImportedMaterial(label, None, spec.exact, spec.source, spec.notes, surface=spec)


def resolve_haze(spec):
    """``spec.haze`` (the keywords of api.make_hazy) from ``spec.haze_target`` (OpenPBR 1.2's
    blend, set by surfaces.openpbr): the user's F(0) that the haze layer raises back to the
    document's is written into ``spec.inputs`` (IOR of a dielectric, Base Color of a metal).
    Returns spec.haze (None without haze).  Costs ~0.1 s per material under Multiscatter GGX
    (haze_blend.solve runs the layer's forward mapping ~10 times), so it is done when the
    material is made, not when the file is read."""
    t = spec.haze_target
    if t is None or spec.haze is not None:
        return spec.haze
    ins = spec.inputs
    const = all(not isinstance(ins.get(k), surfaces.Link) for k in (
        "Metallic", "IOR", "Specular Tint", "Specular IOR Level", "Base Color", "Roughness",
        "Anisotropic", "Thin Film Thickness"))
    if not const:
        spec.notes.append("specular_haze with linked inputs: not imported (haziness 0)")
        spec.lossy += 1
        return None
    metal = float(ins.get("Metallic", 0.0))
    if 0.0 < metal < 1.0:
        spec.notes.append(f"specular_haze on a partly metallic surface ({metal:g}): the haze layer "
                          f"gives each part its own β; mapped for the "
                          f"{'metal' if metal >= 0.5 else 'dielectric'}")
        spec.lossy += 1
    if float(ins.get("Thin Film Thickness", 0.0)) > 0.1:
        spec.notes.append("specular_haze over a thin film: mapped without the film")
        spec.lossy += 1
    dist = spec.props.get("distribution", "MULTI_GGX")
    rot = ins.get("Anisotropic Rotation", 0.0)
    rot = float(rot) if not isinstance(rot, surfaces.Link) else 0.0
    tint = np.asarray(ins.get("Specular Tint", (1.0, 1.0, 1.0)), float)
    if metal >= 0.5:
        part, f0 = "METAL", np.clip(np.asarray(ins.get("Base Color", (0.8,) * 3), float), 0.0, 1.0)
    else:
        part = "DIELECTRIC"
        eta = float(ins.get("IOR", 1.5))
        level = float(ins.get("Specular IOR Level", 0.5))
        f0 = ((eta - 1.0) / (eta + 1.0)) ** 2 * 2.0 * level * np.clip(tint, 0.0, None)
    sol = haze_blend.solve(part, dist, f0, t["beta"], t["roughness"], t["anisotropy"],
                           t["roughness_wide"], rot=rot, tint=tuple(np.clip(tint, 0.0, 1.0)))
    if sol.haziness <= 0.0:
        spec.notes.append("specular_haze with no room for a halo (no spread or no reflection): "
                          "haziness 0")
        return None
    if part == "METAL":
        ins["Base Color"] = tuple(sol.core_reflectivity)
    else:
        m = max(float(np.max(tint)) * 2.0 * level, 1e-30)
        f = min(max(sol.core_reflectivity) / m, K.ONE_MINUS_ULP32)
        ins["IOR"] = float((1.0 + math.sqrt(f)) / (1.0 - math.sqrt(f)))
    lx, ly = sol.haze_extent
    spec.haze = dict(haziness=sol.haziness, haze_extent=lx if lx == ly else (lx, ly))
    t["error"] = sol.error
    if sol.error > 1e-6:
        spec.notes.append(f"specular_haze {t['beta']:g} needs a haziness at the mapping's bound (Eq. 6; "
                          f"haziness is kept below 1): β off by {sol.beta_error:.3g}, F(0) by "
                          f"{sol.reflectivity_error:.3g} (relative)")
        spec.lossy += 1
    return spec.haze


# --------------------------------------------------------------------------------------------
# Haze layers exported by the add-on
# --------------------------------------------------------------------------------------------


def _recognise_layer(doc, mat, label):
    """A layered material of ours: the core BSDF rebuilt from its node in the network (its own
    values; the layer-owned inputs from the record) and the record's haze parameters."""
    notes = _Notes()
    try:
        rec = json.loads(mat.attrs.get(f"{_ATTR}_layer") or "{}")
    except ValueError:
        rec = {}
    if not isinstance(rec, dict):
        rec = {}
    k, top, graph = doc.resolve(mat.inputs.get("surfaceshader"))
    if k != "node":
        return ImportedMaterial(label, None, False, "hazy_gloss layer", ["no layer network"])
    # a .mtlx keeps the network in a node graph; USD (interchange/usd.py) flattens it into
    # shaders named by their prim paths <material>/NG/<node>
    scope = graph.nodes if graph is not None else doc.nodes
    prefix = "" if graph is not None else (top.name.rsplit("/", 1)[0] + "/" if "/" in top.name else "")
    core_name = rec.get("core_node") or (valid_name(rec["core"]) if isinstance(rec.get("core"), str) else None)
    core = scope.get(prefix + core_name) if core_name else None
    ctype = rec.get("core_type")
    if core is None or ctype not in ("PRINCIPLED", "METALLIC", "GLOSSY"):
        return ImportedMaterial(label, None, False, "hazy_gloss layer", [
            "a haze layer whose record does not name its core (a document of an older version): "
            "not imported"])
    if rec.get("record", 1) < 2:
        notes.lose("an older layer record without the user's own values of the inputs the layer "
                   "owns: the layer's raised values are taken")
    owned = {name: (dict(b, node=prefix + b["node"]) if isinstance(b.get("node"), str) else b)
             for name, b in (rec.get("base") or {}).items() if isinstance(b, dict)}
    if ctype == "PRINCIPLED":
        spec = surfaces.openpbr(doc, core, graph, label, notes, owned=owned)
    else:
        spec = surfaces.bsdf_core(doc, core, graph, label, notes, ctype, owned=owned)
    props = rec.get("core_props") or {}
    for key in ("distribution", "fresnel_type", "subsurface_method"):
        if isinstance(props.get(key), str):
            spec.props[key] = props[key]
    haze = rec.get("haze") or {}
    kw = {}
    for key in HAZE_DEFAULTS:
        if key not in haze:
            continue
        val = haze[key]
        if val == "texture":
            notes.lose(f"the layer's {key} comes from a map: not imported (its default is used)")
            continue
        kw[key] = tuple(val) if isinstance(val, list) else val
    if rec.get("baked"):
        notes.lose("a baked layer (texture conversion): rebuilt as a live layer of its constant "
                   "haze parameters")
    others = [n.name[len(prefix):] for n in scope.values() if n.name.startswith(prefix) and (
        n.category in surfaces.SURFACES or n.category in LOBES or n.category in (
            "oren_nayar_diffuse_bsdf", "uniform_edf"))]
    mine = {core.name[len(prefix):]} | {valid_name(r) for r in rec.get("nodes", []) if isinstance(r, str)}
    extra = [n for n in others if n not in mine and not n.startswith(valid_name(f"{K.NODE_PREFIX} "))]
    if extra:
        notes.lose(f"the network around the core ({', '.join(extra[:4])}) is not rebuilt: the core "
                   f"and its layer are")
    spec.haze = kw
    spec.source = "hazy_gloss layer"
    spec.lossy = notes.lost
    spec.notes = notes
    return ImportedMaterial(label, None, notes.lost == 0, "hazy_gloss layer", notes, surface=spec)


# --------------------------------------------------------------------------------------------
# Documents
# --------------------------------------------------------------------------------------------


def recognise(doc, *, use_stored=True, progress=None):
    """ImportedMaterial for every surfacematerial of a Document.  ``use_stored=False`` ignores
    the perceptual parameters hazy_gloss stores with its materials (recovers everything from
    the graph, as for a foreign document).  ``progress``: callable(fraction, message)."""
    ev = _Eval(doc)
    out = []
    mats = doc.materials()
    includes = [n.attrs.get("href") or "?" for n in doc.nodes.values()
                if n.category == "xi:include"]
    step = max(1, len(mats) // 100)
    for i, mat in enumerate(mats):
        label = mat.attrs.get(f"{_ATTR}_name") or mat.name
        try:
            out.append(_checked(_recognise_one(ev, doc, mat, label, use_stored)))
        except (ValueError, TypeError, IndexError, KeyError, AttributeError, ZeroDivisionError,
                OverflowError, RecursionError) as exc:  # a damaged material: said, the rest read
            what = str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__
            out.append(ImportedMaterial(label, None, False, "", [f"damaged, not imported: {what}"]))
        if includes:
            _blame_includes(out[-1], includes)
        if progress is not None and (i % step == 0 or i == len(mats) - 1):
            progress((i + 1) / len(mats), "recognising materials")
    return out


_DANGLING = " is connected to nothing that exists"


def _blame_includes(im, includes):
    """In a document with xi:include, what points at nothing most likely is in the included
    file (the reader does not follow includes): one note saying so instead of one per input."""
    missing = [n for n in im.notes if _DANGLING in n or n == "no surface shader"]
    if not missing:
        return
    where = [n.split(_DANGLING)[0] for n in missing if _DANGLING in n]
    takes = "takes its default" if len(where) == 1 else "take their defaults"
    what = f"{', '.join(where)} {takes}" if where else "its surface shader is not in this file"
    im.notes[:] = [n for n in im.notes if n not in missing] + [
        f"includes are not followed (xi:include of {', '.join(includes)}): {what}"]


def _finite(v):
    """A value Blender's float32 sockets hold (finite, within float32's range)."""
    if isinstance(v, float):
        return -K.FLOAT32_MAX <= v <= K.FLOAT32_MAX
    if isinstance(v, tuple):
        return all(isinstance(x, (int, float)) and -K.FLOAT32_MAX <= x <= K.FLOAT32_MAX for x in v)
    return True


def _checked(im):
    """Parameters with a non-finite number are no parameters (a damaged document)."""
    if im.surface is not None:
        sp = im.surface
        bad = [k for k, v in sp.inputs.items() if not _finite(v)] + [
            f"{k}.{s}" for k, n in sp.nodes.items() for s, v in n.inputs.items() if not _finite(v)]
        if bad:
            return ImportedMaterial(im.name, None, False, im.source,
                                    im.notes + [f"damaged, not imported: {bad[0]} is not finite"])
        return im
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
        return _recognise_layer(doc, mat, label)
    k, shader, g = doc.resolve(mat.inputs.get("surfaceshader"))
    if k != "node":
        return ImportedMaterial(label, None, False, "", ["no surface shader"])
    if shader.category == "surface":
        return _recognise_eq1(ev, mat, label, shader, g, use_stored)
    if shader.category == "open_pbr_surface" and use_stored:
        ours = _openpbr_stored(ev, mat, label, shader, g)
        if ours is not None:
            return ours
    if shader.category in surfaces.SURFACES:
        return _surface(doc, mat, label, shader, g)
    return ImportedMaterial(label, None, False, "", [
        f"{shader.category} is not a surface this importer reads (open_pbr_surface, "
        f"standard_surface, gltf_pbr, UsdPreviewSurface, or a surface with a two-lobe mix)"])


def read(path, *, use_stored=True, progress=None):
    """ImportedMaterial for every material of the MaterialX file at ``path``.  ``progress``:
    callable(fraction, message), fraction non-decreasing from 0 to 1 (reading the file is the
    first half, recognising the materials the second)."""
    def half(lo):
        return None if progress is None else (lambda f, msg: progress(lo + 0.5 * f, msg))
    doc = read_xml(os.fspath(path), progress=half(0.0))
    return recognise(doc, use_stored=use_stored, progress=half(0.5))
