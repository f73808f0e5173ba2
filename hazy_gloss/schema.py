# SPDX-License-Identifier: GPL-3.0-or-later
"""The one schema of the perceptual parameters (bpy-free and numpy-free: the command line reads
it under a bare Python).

:data:`SCHEMA` holds one :class:`Parameter` per parameter: its API keyword, UI label, paper
symbol (Barla, Pacanowski & Vangorp 2018), type, defaults, ranges, tooltip, where it applies
(a hazy material, a haze layer, both) and to which kinds.  Everything else is derived from it:
the names, defaults and ranges below (core.parameters validates with them), the panel's
and the operators' properties (blender/ui/properties.py), the haze layer's sockets
(:data:`HAZE_SOCKETS`), the haze maps of texture conversion and the command line
(:data:`HAZE_MAP_INPUTS`), and the tables of docs/parameters.md (scripts/parameter_table.py).  The words of kinds, distributions and
tangents are constants.KIND_TERMS, DISTRIBUTION_TERMS, TANGENT_TERMS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from . import constants as K

__all__ = ("Parameter", "SCHEMA", "SCHEMA_BY_NAME", "PARAMETERS", "DEFAULTS", "HAZE_PARAMETERS",
           "HAZE_DEFAULTS", "RANGES", "HAZE_SOCKETS", "HAZE_MAP_INPUTS", "LAYER_MAP_INPUTS",
           "map_inputs", "property_names", "preset_properties", "property_specs",
           "operator_property", "socket_keys", "layer_sockets", "LAYER", "MATERIAL")

MATERIAL, LAYER, BOTH = "material", "layer", "both"
_SAME = object()  # Parameter.layer_default: as ``default``


@dataclass(frozen=True)
class Parameter:
    """One perceptual parameter.

    type: "colour" (linear RGB), "float", "extent" (a number or an (x, y) pair), "bool", "enum"
    (one of ``terms``, a constants.*_TERMS).  ``default`` on a hazy material, ``layer_default``
    on a haze layer.  ``range``: the valid (lo, hi), hi None = unbounded (colours per channel);
    ``ui``: (min, max) of the panel property and the layer socket when not ``range``; ``soft``:
    the slider's (soft_min, soft_max), None for Blender's.  A default of None makes it optional
    (a "use_" toggle in the panel; ``placeholder`` is the value shown and socketed while off).
    ``more``: the panel's other properties of it, (property, label, tooltip).  ``sockets``: the
    haze layer's inputs, (socket name, tooltip) (an extent: X then Y), on the layers of the
    ``bsdfs`` (blender/model/layer_group.BSDF_NODES; () all) — an optional one on smooth
    layers only.  ``maps``: a map (or a
    constant) in texture conversion and on the command line.  ``configures``: picks the node
    configuration (a preset sets it first).  ``doc``, ``doc_layer``, ``range_note``: the
    columns of docs/parameters.md."""
    name: str
    label: str
    symbol: str
    type: str
    default: object
    where: str = MATERIAL
    layer_default: object = _SAME
    range: tuple = None
    ui: tuple = None
    soft: tuple = None
    factor: bool = False
    precision: int = None
    description: str = ""
    kinds: tuple = K.KINDS
    terms: tuple = ()
    more: tuple = ()
    placeholder: float = None
    panel: bool = True
    sockets: tuple = ()
    bsdfs: tuple = ()
    maps: bool = False
    configures: bool = False
    why: str = ""
    doc: str = ""
    doc_layer: str = ""
    range_note: str = ""

    @property
    def on_material(self):
        return self.where in (MATERIAL, BOTH)

    @property
    def on_layer(self):
        return self.where in (LAYER, BOTH)

    @property
    def haze_default(self):
        return self.default if self.layer_default is _SAME else self.layer_default

    @property
    def limits(self):
        """(min, max) of the panel property and the layer socket."""
        return self.ui if self.ui is not None else self.range


#: Every parameter, in the order of PARAMETERS then the layer's own (HAZE_PARAMETERS' order).
SCHEMA = (
    Parameter(
        "kind", "Kind", "—", "enum", "CONDUCTOR", terms=K.KIND_TERMS, configures=True,
        doc="conductor Fresnel (η, κ) shared by both lobes / Principled IOR from r̂ / no Fresnel, "
            "weights k_n = (1-β) r, k_w = β r"),
    Parameter(
        "distribution", "Distribution", "—", "enum", "GGX", terms=K.DISTRIBUTION_TERMS,
        configures=True, description="Microfacet distribution of both lobes",
        doc="lobe shape; p follows (Table 2)"),
    Parameter(
        "core_reflectivity", "Core Reflectivity", "r_c", "colour", (0.5, 0.5, 0.5),
        range=(0.0, 1.0), soft=(0.0, 1.0),
        description="r_c: reflectivity of the sharp core at normal incidence (linear RGB). "
                    "Haze never changes the brightness of the highlight's peak",
        doc="reflectivity of the sharp core at normal incidence; the halo takes its chroma (§2.4)"),
    Parameter(
        "edge_tint", "Edge Tint", "g", "colour", (0.0, 0.0, 0.0), range=(0.0, 1.0),
        soft=(0.0, 1.0), kinds=("CONDUCTOR",),
        description="g: colour towards grazing angles (Gulbrandsen 2014); black = "
                    "dielectric-like Fresnel",
        doc="colour towards grazing angles (Gulbrandsen 2014); 0 gives κ = 0, a dielectric Fresnel"),
    Parameter(
        "roughness", "Roughness", "α_n = R²", "float", 0.1, range=(0.0, 1.0), factor=True,
        precision=3,
        description="Core roughness, Blender's convention R = √α (the paper's α_n is R²)",
        range_note=f"lobes use R ≥ {K.MIN_ROUGHNESS:g}",
        doc="width of the core; Blender's convention R = √α"),
    Parameter(
        "anisotropy", "Anisotropy", "a: α_n^x = R²/s, α_n^y = R² s", "float", 0.0,
        range=(0.0, 1.0), factor=True,
        description="Stretch of the core along the tangent (Metallic BSDF convention, "
                    "at most 10:1)",
        doc="s = √(1 - 0.9a) (Metallic convention): the core's aspect, at most 10:1"),
    Parameter(
        "rotation", "Rotation", "—", "float", 0.0, range=(-math.inf, math.inf), ui=(0.0, 1.0),
        factor=True, description="Rotation of the tangent, in turns", range_note="turns",
        doc="rotation of the tangent of anisotropic lobes"),
    Parameter(
        "haziness", "Haziness", "β_h", "float", 0.5, where=BOTH, layer_default=0.0,
        range=(0.0, K.MAX_HAZINESS), soft=(0.0, 0.99), factor=True, precision=3, maps=True,
        description="β_h: proportion of the halo the energy and positivity bounds allow. "
                    "About 0-0.1 for dielectrics, up to 0.99 for metals",
        sockets=(("Haziness", "β_h: how much of the halo energy conservation allows (Eq. 7); "
                  "the peak stays"),),
        why=" (1 would break energy conservation)",
        range_note="the paper's [0, 1)",
        doc="share of the haze the energy and positivity bounds allow (Eq. 7); 0-0.1 is typical "
            "for dielectrics",
        doc_layer="the base's halo; each part (dielectric, metal) mapped on its own Fresnel"),
    Parameter(
        "haze_extent", "Haze Extent", "λ_h, (λ_h^x, λ_h^y)", "extent", (5.0, 5.0), where=BOTH,
        range=(0.0, None), ui=(0.0, 1000.0), soft=(None, 20.0), maps=True,
        description="λ_h: width of the halo in units of the core's roughness "
                    "(α_w = α_n + λ_h √(α_n^x α_n^y)); along the tangent when unlinked",
        more=(("haze_extent_y", "Haze Extent Y", "λ_h^y: width of the halo across the tangent"),
              ("haze_extent_linked", "Link Haze Extents",
               "One haze extent for both directions (isotropic halo)")),
        sockets=(("Haze Extent X", "λ_h^x: halo width along the tangent, in units of the core's "
                                   "roughness (Eq. 8)"),
                 ("Haze Extent Y", "λ_h^y: halo width along the bitangent, in units of the "
                                   "core's roughness (Eq. 8)")),
        why=" (units of the core's roughness)",
        doc="halo width in units of the core's: α_w = α_n + λ_h √(α_n^x α_n^y) (Eq. 8)",
        doc_layer="the base halo's width"),
    Parameter(
        "smoothness", "Smoothness", "w", "float", None, where=BOTH,
        range=(K.MIN_SMOOTHNESS, math.inf), ui=(K.MIN_SMOOTHNESS, 1e6), soft=(0.5, 16.0),
        placeholder=2.0,
        description="w: weight of the Bézier; larger is closer to Eq. 7, smaller is smoother "
                    "but reaches less haze",
        more=(("use_smoothness", "Smooth Haze",
               "Use the rational Bézier mapping (Eqs. 12-15) instead of the piecewise "
               "linear Eq. 7: no kink where r_c = p (useful with textured reflectivity)"),),
        sockets=(("Smoothness", "w: weight of the smooth haze curve (rational Bézier, "
                                "Eqs. 12-15)"),),
        why=" (the Bézier weight w; None selects Eq. 7)",
        doc="None: Eq. 7 (a kink at r_c = p); w: the rational Bézier of Eqs. 12-15 (smooth in "
            "r_c; large w → Eq. 7)",
        doc_layer="Eq. 7 or the Bézier"),
    Parameter(
        "shader_mapping", "In-Shader Mapping", "—", "bool", False, configures=True,
        description="Compute the mapping in the shader (a node group whose inputs take "
                    "textures) instead of constants computed here (leaner, faster to render)",
        doc="the mapping as nodes (for textures) instead of constants from Python"),
    Parameter(
        "base_color", "Base Color", "—", "colour", (0.0, 0.0, 0.0), range=(0.0, 1.0),
        soft=(0.0, 1.0), kinds=("DIELECTRIC",),
        description="Diffuse colour under a dielectric's specular layer",
        doc="diffuse under the specular layer"),
    Parameter(
        "transmission", "Transmission", "—", "float", 0.0, range=(0.0, 1.0), factor=True,
        kinds=("DIELECTRIC",),
        description="Transmission weight of a dielectric (the BTDF shares β, η and α)",
        doc="BTDF with the same β, η, α (§4.2)"),
    Parameter(
        "tangent", "Tangent", "—", "enum", "UV_MAP", terms=K.TANGENT_TERMS,
        description="Tangent used by anisotropic lobes",
        doc="the tangent of anisotropic lobes (a UV map's, or radial about an axis)"),
    # the haze layer's own (Make Hazy on the artist's BSDF; r_c and α_n are the BSDF's)
    Parameter(
        "reflectivity_cap", "Reflectivity Cap", "a bound on r_c", "float", 1.0, where=LAYER,
        range=(0.0, 1.0), factor=True, panel=False,
        sockets=(("Reflectivity Cap", "r_c at most this where haze is on (1: off): room for a "
                  "halo on a colour at or near 1, which otherwise has none, at the cost of that "
                  "much peak"),),
        why=" (1: no cap)", range_note="1 = off",
        doc="the layer maps min(r_c, cap): room for a halo on a colour at or near 1 (none "
            "otherwise), the peak then the cap's (mapping.md §13); the panel proposes 0.98 "
            "where haze cannot show"),
    Parameter(
        "coat_haziness", "Coat Haziness", "β_h of the coat", "float", 0.0, where=LAYER,
        range=(0.0, K.MAX_HAZINESS), soft=(None, 0.99), factor=True, precision=3, maps=True,
        range_note="the paper's [0, 1)",
        description="β_h of the coat: a halo around the clear coat's reflection (lacquer, "
                    "varnish, car paint), mapped on the coat's own Fresnel (Coat IOR); the "
                    "coat's peak stays",
        bsdfs=("PRINCIPLED",),
        sockets=(("Coat Haziness", "β_h of the clear coat: a halo of its own, on the Coat "
                                   "IOR's Fresnel"),),
        doc="a halo around the coat's reflection, on r_c = F0(Coat IOR)"),
    Parameter(
        "coat_haze_extent", "Coat Haze Extent", "λ_h of the coat", "float", 5.0, where=LAYER,
        range=(0.0, None), ui=(0.0, 1000.0), soft=(None, 20.0), maps=True,
        description="λ_h of the coat: width of the coat's halo in units of the coat roughness",
        bsdfs=("PRINCIPLED",),
        sockets=(("Coat Haze Extent", "λ_h of the coat, in units of the Coat Roughness"),),
        doc="the coat halo's width (isotropic: Cycles' coat is)"),
    Parameter(
        "keep_body_colour", "Keep Body Colour", "—", "bool", False, where=LAYER,
        description="Brighten the base colour under a hazy dielectric so that the diffuse "
                    "colour stays what it was (haze raises the reflectivity, which lets less "
                    "light reach the base); where a colour cannot get brighter, the rest is "
                    "reported",
        doc="Base Color × c(view) so the diffuse under a hazy dielectric stays (mapping.md §12)"),
)
SCHEMA_BY_NAME = {p.name: p for p in SCHEMA}

#: Every perceptual parameter of a hazy material (the stamp's keys).
PARAMETERS = tuple(p.name for p in SCHEMA if p.on_material)
DEFAULTS = {p.name: p.default for p in SCHEMA if p.on_material}

#: The parameters of a haze layer on a user's BSDF (Make Hazy); the core's own parameters stay
#: on its node.
HAZE_PARAMETERS = tuple(p.name for p in SCHEMA if p.on_layer)
HAZE_DEFAULTS = {p.name: p.haze_default for p in SCHEMA if p.on_layer}

#: (lo, hi) of the numeric parameters, hi None = unbounded; colours per channel.
RANGES = {p.name: p.range for p in SCHEMA if p.range is not None}


def _sockets():
    out = {}
    for p in SCHEMA:
        lo, hi = p.limits if p.sockets else (None, None)
        default = p.placeholder if p.haze_default is None else p.haze_default
        if p.type == "extent":
            for (name, desc), axis in zip(p.sockets, "xy"):
                out[f"{p.name}_{axis}"] = (name, default["xy".index(axis)], lo, hi, desc)
        elif p.sockets:
            (name, desc), = p.sockets
            out[p.name] = (name, default, lo, hi, desc)
    return out


#: The haze layer's own inputs (the group node's Haze panel): socket key -> (socket name,
#: default, min, max, paper symbol and meaning); an extent has an _x and a _y socket.
HAZE_SOCKETS = _sockets()


def socket_keys(p):
    """The HAZE_SOCKETS keys of parameter ``p``."""
    if not p.sockets:
        return ()
    return (f"{p.name}_x", f"{p.name}_y") if p.type == "extent" else (p.name,)


def layer_sockets(bsdf, smooth):
    """The HAZE_SOCKETS keys a layer group on a ``bsdf`` (PRINCIPLED, METALLIC, GLOSSY) has,
    in panel order; an optional parameter's only when ``smooth`` (its value selects the curve)."""
    return [k for p in SCHEMA if (not p.bsdfs or bsdf in p.bsdfs)
            and (p.haze_default is not None or smooth) for k in socket_keys(p)]

def map_inputs(p):
    """The map inputs of parameter ``p`` in texture conversion and on the command line (an
    extent: also one per axis), () when it takes no map."""
    if not p.maps:
        return ()
    return (p.name, f"{p.name}_x", f"{p.name}_y") if p.type == "extent" else (p.name,)


#: The haze parameters that take a map (or a constant) in texture conversion and on the command
#: line.
HAZE_MAP_INPUTS = tuple(n for p in SCHEMA if p.on_layer for n in map_inputs(p))
#: Those of them only a haze layer has (they make a conversion a PBR set's).
LAYER_MAP_INPUTS = tuple(n for p in SCHEMA if p.on_layer and not p.on_material
                         for n in map_inputs(p))


def property_names(p):
    """The panel properties of parameter ``p``, in the order a preset sets them."""
    if not p.panel:
        return ()
    more = [m[0] for m in p.more]
    if p.type == "extent":  # the link first: it decides what setting X does
        return (more[1], f"{p.name}_x", more[0])
    return tuple(more) + (p.name,)


def preset_properties(where):
    """The properties a preset sets on a hazy material (``where`` MATERIAL) or a haze layer
    (LAYER): the ones that pick the node configuration first."""
    params = [p for p in SCHEMA if (p.on_material if where == MATERIAL else p.on_layer)]
    ordered = [p for p in params if p.configures] + [p for p in params if not p.configures]
    return tuple(n for p in ordered for n in property_names(p))


def property_specs():
    """The panel's properties of the parameters (bpy-free): (property name, bpy.props
    constructor name, its keywords without get, set and options), in the PropertyGroup's order;
    blender/ui/properties.py adds the accessors.  An optional parameter also stores the value
    it remembers while off (``<name>_memory``, last)."""
    out, memories = [], []
    for p in SCHEMA:
        if not (p.panel and (p.on_material or p.on_layer)):
            continue
        info = {"name": p.label}
        if p.type == "enum":
            out.append((p.name, "EnumProperty", dict(info, items=K.enum_items(p.terms),
                                                     **_desc(p.description))))
            continue
        if p.type == "bool":
            out.append((p.name, "BoolProperty", dict(info, description=p.description)))
            continue
        if p.type == "colour":
            out.append((p.name, "FloatVectorProperty",
                        dict(info, subtype="COLOR", size=3, soft_min=p.soft[0],
                             soft_max=p.soft[1], description=p.description)))
            continue
        num = dict(min=p.limits[0], max=p.limits[1])
        if p.soft is not None:
            num.update({k: v for k, v in zip(("soft_min", "soft_max"), p.soft) if v is not None})
        if p.factor:
            num["subtype"] = "FACTOR"
        if p.precision is not None:
            num["precision"] = p.precision
        if p.type == "extent":
            (y, y_label, y_desc), (linked, l_label, l_desc) = p.more
            out += [(f"{p.name}_x", "FloatProperty", dict(info, **num, description=p.description)),
                    (y, "FloatProperty", dict(name=y_label, **num, description=y_desc)),
                    (linked, "BoolProperty", dict(name=l_label, description=l_desc))]
            continue
        if p.default is None:  # optional: a toggle, and the value it remembers while off
            (use, u_label, u_desc), = p.more
            out.append((use, "BoolProperty", dict(name=u_label, description=u_desc)))
            memories.append((f"{p.name}_memory", "FloatProperty",
                             dict(default=p.placeholder, min=p.limits[0])))
        out.append((p.name, "FloatProperty", dict(info, **num, description=p.description)))
    return out + memories


def operator_property(prop, default):
    """(bpy.props constructor name, keywords) of the panel property ``prop`` (a name of
    :func:`property_specs`; an extent's axes are ``<name>_x`` and ``<name>_y``) for an operator
    of its own: the panel's label, range, slider and tooltip with the operator's ``default``."""
    for name, ctor, keywords in property_specs():
        if name == prop:
            kw = dict(keywords, default=default)
            # the range as the slider's only: a script's value out of it is refused with the
            # API's message (a hard limit would clamp it, saying nothing)
            for hard in ("min", "max"):
                if hard in kw:
                    kw.setdefault(f"soft_{hard}", kw.pop(hard))
            return ctor, kw
    raise KeyError(f"no panel property {prop!r} in the schema")


def _desc(text):
    return {"description": text} if text else {}
