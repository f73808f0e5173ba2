# SPDX-License-Identifier: GPL-3.0-or-later
"""Haze layers (Make Hazy, blender/layer.py) as MaterialX 1.39 networks, bpy-free.

A layered material is the artist's own shading network with a haze layer in it: the user's
BSDF (the core) renders the narrow lobe, hidden copies of it the wide one, Mix Shaders mix
them by β (and by the metallic map, and the coat's β).  It is written as what the Blender
tree holds, node by node, from the Material Output the renderers use (:class:`Writer`):

- **Principled BSDF** -> ``open_pbr_surface`` (OpenPBR 1.1.1, the version MaterialX 1.39
  ships), the mapping Blender's own MaterialX exporter uses (base_metalness = Metallic,
  specular_weight = 2 · Specular IOR Level, specular_color = Specular Tint, fuzz = sheen, ...)
  with three corrections where OpenPBR's model differs from Cycles' Principled (measured in
  docs/interchange.md §5): α_x, α_y kept exactly (OpenPBR's anisotropy keeps α_x, Cycles
  the geometric mean; Blender's exporter scales the anisotropy by 0.7), and under a coat the
  roughening and the coat-relative IOR OpenPBR applies to the base specular undone
  (coat_darkening 0: Cycles does not darken the base beyond the coat's albedo);
- **Metallic BSDF** -> ``conductor_bsdf`` (Physical Conductor) or ``generalized_schlick_bsdf``
  (F82, color82 = Edge Tint, Cycles' F82-tint), **Glossy BSDF** -> ``generalized_schlick_bsdf``
  with F ≡ Color; roughness as the α Cycles renders; wrapped in ``surface``;
- **Mix Shader** -> ``mix`` (fg = the second shader, bg = the first, mix = the clamped factor:
  the layer's β, metallic map, coat β), of BSDFs when both sides are BSDFs, else of
  surfaceshaders; **Add Shader** -> ``add`` of BSDFs (the layer's Glossy lobes);
- values: the socket's value when unlinked; **Image Texture** -> ``image`` (file, colour space
  from the image's, filter, address mode; the layer's baked maps are image textures too);
  **Math / Vector Math / Mix / Separate / Combine XYZ / Color Ramp / Value / RGB / Layer Weight
  / Normal Map / Tangent** -> standard-library nodes with Cycles' semantics (safe division,
  safe power and square root, the Color Ramp as the piecewise-linear 256-entry table Cycles
  looks up, exact) — the layer's live node math is exported per pixel.  Anything else is
  exported at the socket's own value, with a note.

The module only reads a snapshot (:class:`Tree`), made from bpy by blender/interchange.py.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from .. import constants as K
from ..core import gulbrandsen_inverse
from ..core.graph import ramp_table
from .builder import Builder
from .document import NODEDEFS, Input, Node, NodeGraph, valid_name

__all__ = ("Socket", "BNode", "Tree", "Writer", "graph_of", "openpbr_alpha", "openpbr_inverse",
           "coat_roughness_inverse", "coat_ior_inverse", "LUMA")

#: Blender's colour -> float conversion (Cycles linear_rgb_to_gray with the default OCIO
#: config's Rec.709 luma coefficients).
LUMA = (0.2126, 0.7152, 0.0722)
#: Blender image colour spaces -> MaterialX colour spaces.
COLORSPACES = {"sRGB": K.MATERIALX_SRGB_COLORSPACE, "Non-Color": K.MATERIALX_DATA_COLORSPACE,
               "Raw": K.MATERIALX_DATA_COLORSPACE, "Linear Rec.709": "lin_rec709",
               "Linear": "lin_rec709", "Linear CIE-XYZ E": None, "ACEScg": "acescg",
               "ACES2065-1": "lin_ap0", "Linear Rec.2020": "lin_rec2020",
               "Rec.2020": "lin_rec2020", "Linear DCI-P3 D65": "lin_displayp3",
               "Display P3": "srgb_displayp3", "Linear FilmLight E-Gamut": None}
_ADDRESS = {"REPEAT": "periodic", "EXTEND": "clamp", "CLIP": "constant", "MIRROR": "mirror"}
_FILTER = {"Linear": "linear", "Closest": "closest", "Cubic": "cubic", "Smart": "cubic"}
_MX_TYPE = {"VALUE": "float", "RGBA": "color3", "VECTOR": "vector3", "INT": "float",
            "BOOLEAN": "float"}
_PRINCIPLED = "ShaderNodeBsdfPrincipled"
_METALLIC = "ShaderNodeBsdfMetallic"
_GLOSSY = ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic")


# --------------------------------------------------------------------------------------------
# The snapshot of a Blender tree (made by blender/interchange.py)
# --------------------------------------------------------------------------------------------


@dataclass
class Socket:
    identifier: str
    name: str
    type: str  #: Blender's socket type: VALUE, RGBA, VECTOR, SHADER, INT, ...
    value: object = None  #: the unlinked value (float or tuple), None when it has none
    link: tuple = None  #: (from node name, from socket identifier) of a valid, unmuted link
    enabled: bool = True
    linked: bool = False  #: an output with links
    node: str = ""  #: the node it belongs to (for the notes)


@dataclass
class BNode:
    name: str
    type: str  #: bl_idname
    inputs: list = field(default_factory=list)
    outputs: list = field(default_factory=list)
    props: dict = field(default_factory=dict)  #: operation, data_type, distribution, ...
    label: str = ""
    role: str = None  #: the add-on's role (hazy_gloss_role), None for the user's nodes
    core: bool = False  #: the layer's core (the user's BSDF)
    mute: bool = False
    image: dict = None  #: Image Texture: name, path (absolute), colorspace, source, packed
    ramp: dict = None  #: Color Ramp: color_mode, interpolation, elements [(pos, rgba)]
    base: dict = None  #: the core: the user's own value / link of each owned input

    def input(self, key):
        """The enabled input with this identifier, else the first enabled one with this name."""
        for s in self.inputs:
            if s.identifier == key and s.enabled:
                return s
        return next((s for s in self.inputs if s.name == key and s.enabled),
                    next((s for s in self.inputs if s.name == key or s.identifier == key), None))

    def output(self, identifier):
        return next((s for s in self.outputs if s.identifier == identifier), None)


@dataclass
class Tree:
    """A material's node tree: nodes by name, the Material Output the renderers use, and the
    haze layer's state (``layer``: haze, core, core_type, parts, coat, baked, maps)."""

    name: str
    nodes: dict = field(default_factory=dict)
    output: str = None
    layer: dict = field(default_factory=dict)

    def core(self):
        return next((n for n in self.nodes.values() if n.core), None)


# --------------------------------------------------------------------------------------------
# OpenPBR against Cycles' Principled: the corrections (constants; node forms in the Writer)
# --------------------------------------------------------------------------------------------


def principled_alpha(roughness, anisotropy):
    """(α_x, α_y) Cycles renders for a Principled / Metallic lobe (R, A saturated, s = √(1-0.9a),
    α_x = R²/s, α_y = R² s, each clamped to 1)."""
    r = min(max(float(roughness), 0.0), 1.0)
    a = min(max(float(anisotropy), 0.0), 1.0)
    s = math.sqrt(1.0 - 0.9 * a)
    return min(r * r / s, K.ALPHA_MAX), min(r * r * s, K.ALPHA_MAX)


def glossy_alpha(roughness, anisotropy):
    """(α_x, α_y) of a Glossy BSDF (a = clamp(A, ±0.99); a ≥ 0: α_x = R²(1-a), α_y = R²/(1-a))."""
    r = min(max(float(roughness), 0.0), 1.0) ** 2
    a = min(max(float(anisotropy), -0.99), 0.99)
    if abs(a) <= 1e-4:
        return min(r, 1.0), min(r, 1.0)
    if a < 0:
        return min(r / (1.0 + a), 1.0), min(r * (1.0 + a), 1.0)
    return min(r * (1.0 - a), 1.0), min(r / (1.0 - a), 1.0)


def openpbr_alpha(roughness, anisotropy):
    """MaterialX 1.39's open_pbr_anisotropy: α_x = r² √(2/(1+(1-a)²)), α_y = (1-a) α_x."""
    r, a = float(roughness), float(anisotropy)
    ax = r * r * math.sqrt(2.0 / (1.0 + (1.0 - a) ** 2))
    return ax, (1.0 - a) * ax


def openpbr_inverse(alpha_x, alpha_y):
    """(specular_roughness, specular_roughness_anisotropy) whose open_pbr_anisotropy is
    (α_x, α_y), α_x ≥ α_y (before any coat roughening)."""
    ax, ay = float(alpha_x), float(alpha_y)
    if ax <= 0.0:
        return 0.0, 0.0
    a = min(max(1.0 - ay / ax, 0.0), 1.0)
    return math.sqrt(ax / math.sqrt(2.0 / (1.0 + (1.0 - a) ** 2))), a


def coat_roughening(roughness, coat_roughness, coat_weight):
    """OpenPBR's base roughness under a coat (MaterialX 1.39 open_pbr_surface):
    mix(r, min(1, 2 r_c⁴ + r⁴)^¼, coat_weight)."""
    r, c, w = float(roughness), float(coat_roughness), float(coat_weight)
    return (1.0 - w) * r + w * min(1.0, 2.0 * c ** 4 + r ** 4) ** 0.25


def coat_roughness_inverse(target, coat_roughness, coat_weight):
    """(r, residual): the specular_roughness OpenPBR roughens into ``target`` under the coat
    (bisection: coat_roughening is increasing in r); residual ≠ 0 when even r = 0 is rougher."""
    w = min(max(float(coat_weight), 0.0), 1.0)
    t = float(target)
    if w == 0.0:
        return t, 0.0
    lo, hi = 0.0, max(t, 0.0)
    if coat_roughening(0.0, coat_roughness, w) >= t:
        return 0.0, coat_roughening(0.0, coat_roughness, w) - t
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if coat_roughening(mid, coat_roughness, w) < t:
            lo = mid
        else:
            hi = mid
    r = 0.5 * (lo + hi)
    return r, coat_roughening(r, coat_roughness, w) - t


def coat_eta(ior, coat_ior, coat_weight):
    """OpenPBR's base IOR under a coat: mix(η, max(η/η_c, η_c/η), coat_weight)."""
    e, c, w = float(ior), float(coat_ior), float(coat_weight)
    ratio = e / c
    return (1.0 - w) * e + w * (ratio if ratio > 1.0 else 1.0 / ratio)


def coat_ior_inverse(ior, coat_ior, coat_weight):
    """(specular_ior, residual) whose coat-relative IOR (coat_eta) is Cycles' ``ior`` (Cycles
    uses the Principled IOR for the base specular whatever the coat)."""
    e, c = float(ior), max(float(coat_ior), 1.0)
    w = min(max(float(coat_weight), 0.0), 1.0)
    if w == 0.0 or e <= 0.0:
        return e, 0.0
    x = e / ((1.0 - w) + w / c)  # the branch η_o ≥ η_c: linear
    if x >= c:
        return x, coat_eta(x, c, w) - e
    if w == 1.0:
        x = c / e
    else:  # η_o < η_c: (1-w) x² - e x + w c = 0; below its minimum 2√((1-w) w c): the minimum
        disc = e * e - 4.0 * (1.0 - w) * w * c
        x = ((e - math.sqrt(disc)) / (2.0 * (1.0 - w)) if disc >= 0.0
             else math.sqrt(w * c / (1.0 - w)))
    x = min(max(x, 1e-6), c)
    return x, coat_eta(x, c, w) - e


# --------------------------------------------------------------------------------------------
# Typed values: a constant or a node output
# --------------------------------------------------------------------------------------------


class V:
    """A MaterialX value: ``const`` (a float or a tuple) or ``node`` (a Node, with ``output``
    for multi-output nodes), of MaterialX ``type``."""

    __slots__ = ("type", "const", "node", "output")

    def __init__(self, type_, const=None, node=None, output=None):
        self.type = type_
        self.const = const
        self.node = node
        self.output = output

    @property
    def is_const(self):
        return self.node is None

    def array(self):
        return np.asarray(self.const, dtype=np.float64)

    def __repr__(self):
        return f"V({self.type}, {self.const if self.node is None else self.node.name})"


_WIDTH = {"float": 1, "vector2": 2, "vector3": 3, "color3": 3, "color4": 4}


def _c(type_, value):
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    n = _WIDTH[type_]
    if arr.size == 1 and n > 1:
        arr = np.repeat(arr, n)
    if n == 1:
        return V(type_, float(arr[0]))
    return V(type_, tuple(float(x) for x in arr[:n]))


# --------------------------------------------------------------------------------------------
# The writer
# --------------------------------------------------------------------------------------------


class Writer:
    """Writes one Blender tree into a NodeGraph.  ``notes``: a list the writer appends to (what
    is approximate or not exported, in plain words, each once)."""

    def __init__(self, tree, graph, notes, *, directory=None):
        self.tree = tree
        self.g = graph
        self.notes = notes
        self.directory = directory
        self.taken = set(graph.nodes)
        self._values = {}
        self._shaders = {}
        self._black = None
        self.images = []  #: (Blender image name, file written) of every image node
        self.surfaces = {}  #: Blender BSDF node name -> the MaterialX node written for it
        self.mixes = {}  #: Blender Mix / Add Shader name -> the MaterialX node
        self.stack = []

    # -- notes, names, nodes -------------------------------------------------------------------
    def note(self, text):
        if text not in self.notes:
            self.notes.append(text)

    def inverse_of_constants(self, inverse, values, note):
        """``inverse`` (a value and its residual) of constant ``values`` as a float constant,
        with the note ``note(residual)`` when it is not exact; None when a value is not a
        constant (the caller builds nodes)."""
        if not all(v.is_const for v in values):
            return None
        value, residual = inverse(*(v.const for v in values))
        if abs(residual) > 1e-6:
            self.note(note(residual))
        return _c("float", value)

    def name(self, base):
        return valid_name(base, self.taken)

    def node(self, nodedef, base, **inputs):
        cat, typ, spec = NODEDEFS[nodedef]
        n = Node(self.name(base), cat, typ, nodedef=nodedef)
        for k, v in inputs.items():
            self.put(n, k, v, spec[k][0])
        return self.g.add(n)

    def put(self, n, key, v, type_=None):
        """Set input ``key`` of ``n`` from a V (converted to the input's type), a Node or a
        constant."""
        if type_ is None:
            type_ = NODEDEFS[n.nodedef][2][key][0]
        if isinstance(v, Node):
            n.set(key, type_, node=v)
            return
        if isinstance(v, V):
            v = self.convert(v, type_) if type_ in _WIDTH else v
            if v.is_const:
                n.set(key, type_, v.const)
            else:
                n.set(key, type_, node=v.node, output=v.output)
            return
        n.set(key, type_, v)

    # -- arithmetic on V (constants folded in float64) -----------------------------------------
    def _nd(self, cat, a_type, b_type=None):
        name = f"ND_{cat}_{a_type}" + ("FA" if b_type == "float" and a_type != "float" else "")
        if name not in NODEDEFS:
            raise KeyError(f"no nodedef {name} in the table")
        return name

    def _bin(self, cat, a, b, base, fold):
        t = a.type if a.type != "float" else b.type
        if a.is_const and b.is_const:
            return _c(t, fold(self.convert(a, t).array(), self.convert(b, t).array()))
        calc = t if t == "float" or f"ND_{cat}_{t}" in NODEDEFS else "vector3"
        a2, b2 = self.convert(a, calc), b
        if not (b.type == "float" and calc != "float" and f"ND_{cat}_{calc}FA" in NODEDEFS):
            b2 = self.convert(b, calc)
        out = V(calc, node=self.node(self._nd(cat, calc, b2.type), base, in1=a2, in2=b2))
        return self.convert(out, t)

    def add(self, a, b, base="add"):
        if b.is_const and not np.any(b.array()):
            return self.convert(a, a.type if a.type != "float" else b.type)
        return self._bin("add", a, b, base, np.add)

    def sub(self, a, b, base="subtract"):
        if b.is_const and not np.any(b.array()) and a.type == b.type:
            return a
        return self._bin("subtract", a, b, base, np.subtract)

    def mul(self, a, b, base="multiply"):
        for x, y in ((a, b), (b, a)):
            if x.is_const and np.all(x.array() == 1.0) and x.type in ("float", y.type):
                return y
        return self._bin("multiply", a, b, base, np.multiply)

    def div(self, a, b, base="divide"):
        """Blender's safe division: x / 0 = 0."""
        t = a.type if a.type != "float" else b.type
        if b.is_const:
            bv = np.broadcast_to(b.array(), (_WIDTH[t],) if t != "float" else ())
            if np.all(bv != 0):
                if a.is_const:
                    return _c(t, a.array() / bv)
                return V(t, node=self.node(self._nd("divide", t), base, in1=self.convert(a, t),
                                           in2=_c(t, bv)))
            if a.is_const:
                with np.errstate(divide="ignore", invalid="ignore"):
                    return _c(t, np.where(bv != 0, a.array() / np.where(bv != 0, bv, 1.0), 0.0))
        if t == "float":
            q = self.node("ND_divide_float", base, in1=a, in2=b)
            return V("float", node=self.node("ND_ifequal_float", base + "_safe", value1=b,
                                             value2=0.0, in1=0.0, in2=V("float", node=q)))
        lanes = [self.div(self.lane(a, i), self.lane(b, i), f"{base}_{'xyz'[i]}") for i in range(3)]
        return self.combine(lanes, base)

    def minimum(self, a, b, base="min"):
        return self._bin("min", a, b, base, np.fmin)

    def maximum(self, a, b, base="max"):
        return self._bin("max", a, b, base, np.fmax)

    def clamp(self, a, lo=0.0, hi=1.0, base="clamp"):
        """Numbers or (Clamp node with linked bounds) float Vs for ``lo``, ``hi``."""
        bounds = [b if isinstance(b, V) else _c("float", float(b)) for b in (lo, hi)]
        if a.is_const and all(b.is_const for b in bounds):
            return _c(a.type, np.clip(a.array(), float(bounds[0].const), float(bounds[1].const)))
        t = a.type if a.type in ("float", "vector3") else "vector3"
        a2 = self.convert(a, t)
        low, high = (_c(t, float(b.const)) if b.is_const else self.convert(b, t) for b in bounds)
        out = V(t, node=self.node(f"ND_clamp_{t}", base, **{"in": a2}, low=low, high=high))
        return self.convert(out, a.type)

    def unary(self, cat, a, base, fold):
        if a.is_const:
            return _c(a.type, fold(a.array()))
        t = a.type if a.type in ("float", "vector3") else "vector3"
        return self.convert(V(t, node=self.node(f"ND_{cat}_{t}", base, **{"in": self.convert(a, t)})),
                            a.type)

    def sqrt(self, a, base="sqrt"):
        return self.unary("sqrt", self.maximum(a, _c(a.type, 0.0), base + "_nonneg"), base, np.sqrt)

    def power(self, a, b, base="power"):
        """Cycles' safe_powf: 0 for a negative base with a non-integer exponent."""
        t = a.type if a.type != "float" else b.type
        a = self.convert(a, t)
        if a.is_const and b.is_const:
            av, bv = a.array(), np.broadcast_to(self.convert(b, t).array(), a.array().shape)
            with np.errstate(all="ignore"):
                bad = (av < 0) & (bv != np.trunc(bv))
                return _c(t, np.where(bad, 0.0, np.power(np.where(bad, 1.0, av), bv)))
        if b.is_const and np.all(b.array() == np.ravel(b.array())[0]):
            e = float(np.ravel(b.array())[0])
            if e == 1.0:
                return a
            if e == 2.0:
                return self.mul(a, a, base)
            if e == 0.5:
                return self.sqrt(a, base)
            if e == int(e):  # an integer power of any base: |a|^e, negated for odd e and a < 0
                p = V(t, node=self.node(f"ND_power_{t}", base, in1=self.unary("absval", a, base + "_abs", np.abs),
                                        in2=_c(t, e)))
                if int(e) % 2:
                    if t != "float":
                        lanes = [self.power(self.lane(a, i), b, f"{base}_{'xyz'[i]}") for i in range(3)]
                        return self.combine(lanes, base)
                    neg = self.mul(p, _c("float", -1.0), base + "_neg")
                    p = self.select("ifgreatereq", a, _c("float", 0.0), p, neg, base + "_signed")
                return p
            if e > 0:  # a negative base gives 0: power(max(a, 0), e)
                return V(t, node=self.node(f"ND_power_{t}", base, in1=self.maximum(a, _c(t, 0.0), base + "_nonneg"),
                                           in2=_c(t, e)))
        if t != "float":
            lanes = [self.power(self.lane(a, i), self.lane(b, i), f"{base}_{'xyz'[i]}") for i in range(3)]
            return self.combine(lanes, base)
        # a linked exponent: a ≥ 0: a^b; a < 0: |a|^b (-1)^b for an integer b, else 0
        p = V("float", node=self.node("ND_power_float", base, in1=self.unary("absval", a, base + "_abs", np.abs),
                                      in2=b))
        odd = self.node("ND_modulo_float", base + "_odd", in1=self.unary("absval", b, base + "_babs", np.abs),
                        in2=2.0)
        sign = self.sub(_c("float", 1.0), self.mul(V("float", node=odd), _c("float", 2.0), base + "_2odd"),
                        base + "_parity")
        neg = self.select("ifequal", self.unary("floor", b, base + "_floor", np.floor), b,
                          self.mul(p, sign, base + "_negbase"), _c("float", 0.0), base + "_int")
        return self.select("ifgreatereq", a, _c("float", 0.0), p, neg, base + "_safe")

    def select(self, cat, v1, v2, a, b, base):
        """ifgreater / ifgreatereq / ifequal(value1, value2): a when true, else b."""
        t = a.type if a.type != "float" else b.type
        if v1.is_const and v2.is_const:
            x, y = float(v1.const), float(v2.const)
            ok = {"ifgreater": x > y, "ifgreatereq": x >= y, "ifequal": x == y}[cat]
            return self.convert(a if ok else b, t)
        nd = f"ND_{cat}_{t if t in ('float', 'vector3') else 'vector3'}"
        t2 = NODEDEFS[nd][1]
        return self.convert(V(t2, node=self.node(nd, base, value1=v1, value2=v2,
                                                 in1=self.convert(a, t2), in2=self.convert(b, t2))), t)

    def mix(self, t, a, b, base="mix"):
        """(1-t) a + t b."""
        typ = a.type if a.type != "float" else b.type
        if t.is_const and t.type == "float":
            tv = float(t.const)
            if tv == 0.0:
                return self.convert(a, typ)
            if tv == 1.0:
                return self.convert(b, typ)
            if a.is_const and b.is_const:
                return _c(typ, (1.0 - tv) * self.convert(a, typ).array() + tv * self.convert(b, typ).array())
        nt = typ if typ in ("float", "vector3", "color3") else "vector3"
        nd = f"ND_mix_{nt}" if t.type == "float" else "ND_mix_vector3_vector3"  # (per lane)
        if t.type != "float":
            nt = "vector3"
        return self.convert(V(nt, node=self.node(nd, base, fg=self.convert(b, nt),
                                                 bg=self.convert(a, nt), mix=t)), typ)

    def lane(self, v, i):
        if v.type == "float":
            return v
        if v.is_const:
            return V("float", float(v.const[i]))
        t = v.type if v.type in ("vector3", "color4") else "vector3"
        src = self.convert(v, t)
        return V("float", node=self.node(f"ND_extract_{t}", f"{src.node.name}_{'xyzw'[i]}",
                                         **{"in": src}, index=i))

    def combine(self, lanes, base="combine"):
        if all(x.is_const for x in lanes):
            return V("vector3", tuple(float(x.const) for x in lanes))
        return V("vector3", node=self.node("ND_combine3_vector3", base, in1=lanes[0], in2=lanes[1],
                                           in3=lanes[2]))

    def dot(self, a, b, base="dot"):
        a, b = self.convert(a, "vector3"), self.convert(b, "vector3")
        if a.is_const and b.is_const:
            return V("float", float(np.dot(a.array(), b.array())))
        return V("float", node=self.node("ND_dotproduct_vector3", base, in1=a, in2=b))

    def convert(self, v, to):
        """Blender's implicit socket conversions: float -> (f, f, f), colour -> float by luma,
        vector -> float by the average, colour <-> vector component-wise."""
        if v.type == to or to not in _WIDTH:
            return v
        if v.is_const:
            arr = v.array().reshape(-1)
            if to == "float":
                if v.type in ("color3", "color4"):
                    return V("float", float(np.dot(arr[:3], LUMA)))
                return V("float", float(np.mean(arr[:3])))
            if arr.size == 1:
                return _c(to, arr[0])
            out = list(arr[:3]) + ([1.0] if to == "color4" else [])
            return _c(to, out[:_WIDTH[to]])
        if to == "float":
            weights = LUMA if v.type in ("color3", "color4") else (1 / 3, 1 / 3, 1 / 3)
            return self.dot(v, V("vector3", weights), f"{v.node.name}_to_float")
        if v.type == "float":
            return V(to, node=self.node(f"ND_convert_float_{to}", f"{v.node.name}_to_{to}", **{"in": v}))
        if v.type == "color4":
            v = V("color3", node=self.node("ND_convert_color4_color3", f"{v.node.name}_rgb", **{"in": v}))
            if to == "color3":
                return v
        key = (id(v.node), v.output, to)
        hit = self._values.get(key)
        if hit is None:
            hit = V(to, node=self.node(f"ND_convert_{v.type}_{to}", f"{v.node.name}_to_{to}", **{"in": v}))
            self._values[key] = hit
        return hit

    # -- the Blender tree ----------------------------------------------------------------------
    def _follow(self, sock):
        """(node, output socket) feeding ``sock`` through reroutes, or (None, None)."""
        link = sock.link if sock is not None else None
        for _ in range(64):
            if link is None:
                return None, None
            node = self.tree.nodes.get(link[0])
            if node is None:
                return None, None
            if node.type != "NodeReroute":
                return node, node.output(link[1])
            link = node.inputs[0].link if node.inputs else None
        return None, None

    def value(self, sock, to="float"):
        """The MaterialX value of a Blender input socket, as ``to``."""
        if sock is None:
            return None
        node, out = self._follow(sock)
        if node is None:
            v = sock.value
            if v is None:
                v = 0.0
            t = _MX_TYPE.get(sock.type, "float")
            return self.convert(_c(t, v), to)
        key = (node.name, out.identifier if out is not None else "", to)
        if key not in self._values:
            self.stack.append(node.name)
            if len(self.stack) > 200:
                raise ValueError("node cycle or a network too deep to export")
            try:
                got = self._node_value(node, out)
            finally:
                self.stack.pop()
            if got is None:
                v = sock.value if sock.value is not None else 0.0
                owner = f"“{sock.node}”" if sock.node else "a node"
                self.note(f"“{sock.name}” of {owner} is linked from “{node.name}” "
                          f"({node.type.replace('ShaderNode', '')}), which is not exported: "
                          f"written at the socket's own value {_fmt(v)}")
                got = _c(_MX_TYPE.get(sock.type, "float"), v)
            self._values[key] = self.convert(got, to)
        return self._values[key]

    def _in(self, node, key, to="float"):
        return self.value(node.input(key), to)

    def _node_value(self, node, out):
        t = node.type
        oid = out.identifier if out is not None else ""
        if node.mute:
            self.note(f"muted node “{node.name}”: exported at the linked socket's value")
            return None
        if t == "ShaderNodeValue":
            return _c("float", node.outputs[0].value if node.outputs and node.outputs[0].value is not None
                      else node.props.get("value", 0.0))
        if t == "ShaderNodeRGB":
            return _c("color3", node.outputs[0].value if node.outputs[0].value is not None else (0, 0, 0))
        if t == "ShaderNodeTexImage":
            return self.image(node, oid)
        if t == "ShaderNodeMath":
            return self.math(node)
        if t == "ShaderNodeVectorMath":
            return self.vector_math(node, oid)
        if t == "ShaderNodeMix":
            return self.mix_node(node, oid)
        if t in ("ShaderNodeSeparateXYZ", "ShaderNodeSeparateRGB", "ShaderNodeSeparateColor"):
            if t == "ShaderNodeSeparateColor" and node.props.get("mode", "RGB") != "RGB":
                return None
            src = node.inputs[0]
            v = self.value(src, "vector3")
            idx = {"X": 0, "Y": 1, "Z": 2, "R": 0, "G": 1, "B": 2, "Red": 0, "Green": 1, "Blue": 2}.get(
                out.name if out is not None else "X", 0)
            return self.lane(v, idx)
        if t in ("ShaderNodeCombineXYZ", "ShaderNodeCombineRGB", "ShaderNodeCombineColor"):
            if t == "ShaderNodeCombineColor" and node.props.get("mode", "RGB") != "RGB":
                return None
            lanes = [self.value(s, "float") for s in node.inputs[:3]]
            v = self.combine(lanes, node.name)
            return v if t == "ShaderNodeCombineXYZ" else self.convert(v, "color3")
        if t == "ShaderNodeValToRGB":
            if oid != "Color":
                return None
            return self.ramp(node)
        if t == "ShaderNodeLayerWeight":
            return self.layer_weight(node, oid)
        if t == "ShaderNodeNormalMap":
            return self.normal_map(node)
        if t == "ShaderNodeTangent":
            return V("vector3", node=self.tangent_node(_tangent_kind(node)))
        if t == "ShaderNodeClamp":
            lo, hi = self._in(node, "Min"), self._in(node, "Max")
            if node.props.get("clamp_type", "MINMAX") != "MINMAX":
                return None
            if lo.is_const and hi.is_const:
                return self.clamp(self._in(node, "Value"), float(lo.const), float(hi.const), node.name)
            return self.clamp(self._in(node, "Value"), lo, hi, node.name)
        return None

    # -- value nodes ---------------------------------------------------------------------------
    def math(self, node):
        op = node.props.get("operation", "ADD")
        ins = [s for s in node.inputs if s.enabled]
        a = self.value(ins[0]) if ins else _c("float", 0.0)
        b = self.value(ins[1]) if len(ins) > 1 else _c("float", 0.0)
        c = self.value(ins[2]) if len(ins) > 2 else _c("float", 0.0)
        n = node.name
        one, zero = _c("float", 1.0), _c("float", 0.0)
        r = {"ADD": lambda: self.add(a, b, n), "SUBTRACT": lambda: self.sub(a, b, n),
             "MULTIPLY": lambda: self.mul(a, b, n), "DIVIDE": lambda: self.div(a, b, n),
             "MULTIPLY_ADD": lambda: self.add(self.mul(a, b, n + "_mul"), c, n),
             "POWER": lambda: self.power(a, b, n), "SQRT": lambda: self.sqrt(a, n),
             "MINIMUM": lambda: self.minimum(a, b, n), "MAXIMUM": lambda: self.maximum(a, b, n),
             "LESS_THAN": lambda: self.select("ifgreater", b, a, one, zero, n),
             "GREATER_THAN": lambda: self.select("ifgreater", a, b, one, zero, n),
             "COMPARE": lambda: self.select("ifgreatereq",
                                            self.maximum(c, _c("float", float(np.finfo(np.float32).eps)), n + "_eps"),
                                            self.unary("absval", self.sub(a, b, n + "_diff"), n + "_abs", np.abs),
                                            one, zero, n),
             "ABSOLUTE": lambda: self.unary("absval", a, n, np.abs),
             "FLOOR": lambda: self.unary("floor", a, n, np.floor),
             "COSINE": lambda: self.unary("cos", a, n, np.cos),
             "EXPONENT": lambda: self.unary("exp", a, n, np.exp),
             "SIGN": lambda: self.unary("sign", a, n, np.sign)}.get(op)
        if r is None:
            self.note(f"Math {op.title()} (“{n}”) is not exported")
            return None
        v = r()
        return self.clamp(v, base=n + "_clamp") if node.props.get("use_clamp") else v

    def vector_math(self, node, oid):
        op = node.props.get("operation", "ADD")
        ins = [s for s in node.inputs if s.enabled]
        vec = [s for s in ins if s.type == "VECTOR"]
        a = self.value(vec[0], "vector3") if vec else _c("vector3", 0.0)
        b = self.value(vec[1], "vector3") if len(vec) > 1 else _c("vector3", 0.0)
        c = self.value(vec[2], "vector3") if len(vec) > 2 else _c("vector3", 0.0)
        n = node.name
        if op == "SCALE":
            s = next((x for x in ins if x.type == "VALUE"), None)
            return self.mul(a, self.value(s) if s is not None else _c("float", 1.0), n)
        if op == "DOT_PRODUCT":
            return self.dot(a, b, n)
        if op == "LENGTH":
            return self.sqrt(self.dot(a, a, n + "_sq"), n)
        r = {"ADD": lambda: self.add(a, b, n), "SUBTRACT": lambda: self.sub(a, b, n),
             "MULTIPLY": lambda: self.mul(a, b, n), "DIVIDE": lambda: self.div(a, b, n),
             "MULTIPLY_ADD": lambda: self.add(self.mul(a, b, n + "_mul"), c, n),
             "POWER": lambda: self.power(a, b, n),
             "MINIMUM": lambda: self.minimum(a, b, n), "MAXIMUM": lambda: self.maximum(a, b, n),
             "ABSOLUTE": lambda: self.unary("absval", a, n, np.abs),
             "FLOOR": lambda: self.unary("floor", a, n, np.floor)}.get(op)
        if r is None:
            self.note(f"Vector Math {op.title()} (“{n}”) is not exported")
            return None
        return r()

    def mix_node(self, node, oid):
        dt = node.props.get("data_type", "FLOAT")
        if dt == "RGBA" and node.props.get("blend_type", "MIX") != "MIX":
            self.note(f"Mix “{node.name}” blends with {node.props.get('blend_type')}: not exported")
            return None
        if dt == "VECTOR" and node.props.get("factor_mode", "UNIFORM") != "UNIFORM":
            t = self.value(node.input("Factor_Vector"), "vector3")
            if node.props.get("clamp_factor", True):
                t = self.clamp(t, base=node.name + "_factor")
            return self.mix(t, self.value(node.input("A_Vector"), "vector3"),
                            self.value(node.input("B_Vector"), "vector3"), node.name)
        suffix = {"FLOAT": "_Float", "VECTOR": "_Vector", "RGBA": "_Color"}.get(dt)
        if suffix is None:
            return None
        to = {"FLOAT": "float", "VECTOR": "vector3", "RGBA": "color3"}[dt]
        t = self.value(node.input("Factor_Float"), "float")
        if node.props.get("clamp_factor", True):
            t = self.clamp(t, base=node.name + "_factor")
        v = self.mix(t, self.value(node.input("A" + suffix), to), self.value(node.input("B" + suffix), to),
                     node.name)
        if dt == "RGBA" and node.props.get("clamp_result"):
            v = self.clamp(v, base=node.name + "_clamp")
        return v

    def ramp(self, node):
        r = node.ramp or {}
        els = r.get("elements") or [(0.0, (0.0, 0.0, 0.0, 1.0)), (1.0, (1.0, 1.0, 1.0, 1.0))]
        if r.get("color_mode", "RGB") != "RGB" or r.get("interpolation", "LINEAR") != "LINEAR":
            self.note(f"Color Ramp “{node.name}” is not linear RGB: exported as linear RGB")
        stops = tuple((float(p), tuple(float(x) for x in col[:3])) for p, col in els)
        table = ramp_table(stops).astype(np.float64)
        x = self.clamp(self._in(node, "Fac"), base=node.name + "_fac")
        if x.is_const:  # Cycles: f·255, linear between table entries
            f = float(x.const) * (len(table) - 1)
            i = min(int(f), len(table) - 1)
            t = f - i
            j = min(i + 1, len(table) - 1)
            return _c("vector3", (1.0 - t) * table[i] + t * table[j])
        # the table's linear interpolant as a sum of clamped ramps over its kinks
        xs = np.arange(len(table)) / (len(table) - 1.0)
        slopes = np.diff(table, axis=0) / np.diff(xs)[:, None]
        keep = [0]
        for i in range(1, len(slopes)):
            if np.any(np.abs(slopes[i] - slopes[keep[-1]]) > 1e-9 * (1.0 + np.abs(slopes[i]))):
                keep.append(i)
        knots = [xs[i] for i in keep] + [1.0]
        # the segment holding x, selected from the top: f = t_k + s_k (x - x_k) with
        # ifgreater(x_k+1, x) — one segment's line per pixel, so float32 rounds as Cycles'
        # lookup does (a sum of clamped segments accumulates rounding over all of them)
        def line(k):
            s = slopes[keep[k]]
            y0 = table[keep[k]]
            if not np.any(s):
                return _c("vector3", y0)
            # anchored at x0 as a float32 (what MaterialX reads): a steep segment (slope up to
            # 255 per unit step) would move by s · (x0 - fl(x0)) otherwise
            x0 = float(np.float32(knots[k]))
            y0 = y0 + s * (x0 - knots[k])
            d = self.sub(x, _c("float", x0), f"{node.name}_from{k}")
            return self.add(_c("vector3", y0), self.mul(_c("vector3", s), d, f"{node.name}_slope{k}"),
                            f"{node.name}_line{k}")
        v = line(len(keep) - 1)
        for k in range(len(keep) - 2, -1, -1):
            v = self.select("ifgreater", _c("float", knots[k + 1]), x, line(k), v, f"{node.name}_seg{k}")
        return v

    def layer_weight(self, node, oid):
        """Facing = 1 - |N·I| at Blend 0.5 (Cycles svm_node_layer_weight); Fresnel not exported."""
        if oid != "Facing":
            return None
        blend = self._in(node, "Blend")
        nrm = self._in(node, "Normal", "vector3") if node.input("Normal").link else \
            V("vector3", node=self.world("normal", "ND_normal_vector3"))
        view = V("vector3", node=self.world("viewdirection", "ND_viewdirection_vector3"))
        c = self.unary("absval", self.dot(nrm, view, node.name + "_cos"), node.name + "_abs", np.abs)
        if not blend.is_const:
            return None
        b = float(blend.const)
        if b != 0.5:
            b = min(max(b, 0.0), 1.0 - 1e-5)
            c = self.power(c, _c("float", 2.0 * b if b < 0.5 else 0.5 / (1.0 - b)), node.name + "_blend")
        return self.sub(_c("float", 1.0), c, node.name)

    def world(self, what, nodedef):
        name = f"{what}_world"
        n = self.g.nodes.get(name)
        if n is None:
            n = self.g.add(Node(name, NODEDEFS[nodedef][0], "vector3", nodedef=nodedef))
            self.taken.add(name)
            n.set("space", "string", "world")
        return n

    def normal_map(self, node):
        if node.props.get("space", "TANGENT") != "TANGENT":
            self.note(f"Normal Map “{node.name}” is not in tangent space: not exported")
            return None
        col = self._in(node, "Color", "vector3")
        strength = self._in(node, "Strength")
        if not strength.is_const or float(strength.const) != 1.0:
            self.note(f"Normal Map “{node.name}”: Strength is MaterialX's scale of the tangent-space "
                      f"xy (Cycles blends the normals)")
        return V("vector3", node=self.node("ND_normalmap_float", node.name, **{"in": col}, scale=strength))

    def tangent_node(self, kind, rotation=0.0, suffix=""):
        t = Builder(self.g).tangent(kind, rotation, suffix)
        self.taken |= set(self.g.nodes)
        return t

    def image(self, node, oid):
        img = node.image
        if not img or not img.get("path"):
            what = f"“{img['name']}”" if img else "no image"
            self.note(f"Image Texture “{node.name}” has {what} without a file on disk (packed or "
                      f"generated): written at the socket's value")
            return None
        if node.props.get("projection", "FLAT") != "FLAT":
            self.note(f"Image Texture “{node.name}”: {node.props['projection']} projection written "
                      f"as a flat UV lookup")
        key = ("image", node.name)
        img_node = self._values.get(key)
        if img_node is None:
            path = img["path"]
            file = path
            if self.directory:
                try:
                    file = os.path.relpath(path, self.directory)
                except ValueError:
                    file = path
            file = file.replace(os.sep, "/")
            want4 = any(o.identifier == "Alpha" and o.linked for o in node.outputs)
            nd = "ND_image_color4" if want4 else "ND_image_color3"
            n = self.node(nd, node.name)
            n.set("file", "filename", file,
                  colorspace=self.colorspace(img, node))
            n.set("filtertype", "string", _FILTER.get(node.props.get("interpolation", "Linear"), "linear"))
            mode = _ADDRESS.get(node.props.get("extension", "REPEAT"), "periodic")
            if mode != "periodic":
                n.set("uaddressmode", "string", mode)
                n.set("vaddressmode", "string", mode)
            self.texcoord(node)
            self.images.append((img.get("name", ""), file))
            img_node = self._values[key] = V(NODEDEFS[nd][1], node=n)
        if oid == "Alpha":
            if img_node.type != "color4":
                return None
            return self.lane(img_node, 3)
        return img_node if img_node.type == "color3" else self.convert(img_node, "color3")

    def colorspace(self, img, node):
        cs = img.get("colorspace", "sRGB")
        if img.get("is_data"):
            return K.MATERIALX_DATA_COLORSPACE
        mx_cs = COLORSPACES.get(cs)
        if mx_cs is None:
            self.note(f"image “{img.get('name')}” is in colour space {cs!r}, which MaterialX does "
                      f"not name: read as {K.MATERIALX_COLORSPACE}")
            return K.MATERIALX_COLORSPACE
        return mx_cs

    def texcoord(self, node):
        vec = node.input("Vector")
        src, out = self._follow(vec)
        if src is None:
            return None  # MaterialX's default: the first UV set (Blender: the active render UV map)
        if src.type == "ShaderNodeTexCoord" and out is not None and out.identifier == "UV":
            return None
        if src.type == "ShaderNodeUVMap":
            if src.props.get("uv_map"):
                self.note(f"Image Texture “{node.name}” reads UV map {src.props['uv_map']!r}: "
                          f"written as the first UV set")
            return None
        self.note(f"Image Texture “{node.name}” reads its coordinates from “{src.name}” "
                  f"({src.type.replace('ShaderNode', '')}): written with the first UV set")
        return None

    # -- shaders -------------------------------------------------------------------------------
    def shader(self, sock):
        """("bsdf" | "edf" | "surface", Node) of a shader socket, or None (no closure)."""
        node, out = self._follow(sock)
        if node is None:
            return None
        if node.name in self._shaders:
            return self._shaders[node.name]
        self.stack.append(node.name)
        if len(self.stack) > 200:
            raise ValueError("node cycle or a network too deep to export")
        try:
            got = self._shader(node)
        finally:
            self.stack.pop()
        self._shaders[node.name] = got
        return got

    def shader_of_node(self, node):
        """:meth:`shader` of a node no socket leads to (the user's BSDF a layer node holds)."""
        if node.name not in self._shaders:
            self._shaders[node.name] = self._shader(node)
        return self._shaders[node.name]

    def _shader(self, node):
        t = node.type
        if node.mute:
            self.note(f"muted shader “{node.name}”: not exported")
            return None
        if t == _PRINCIPLED:
            n = self.principled(node)
            self.surfaces[node.name] = n
            return ("surface", n)
        if t == _METALLIC:
            n = self.metallic(node)
            self.surfaces[node.name] = n
            return ("bsdf", n)
        if t in _GLOSSY:
            n = self.glossy(node)
            self.surfaces[node.name] = n
            return ("bsdf", n)
        if t == "ShaderNodeBsdfDiffuse":
            rough = self._in(node, "Roughness")
            if not rough.is_const or float(rough.const) != 0.0:
                self.note(f"Diffuse BSDF “{node.name}”: MaterialX's Oren-Nayar for Cycles' roughness")
            return ("bsdf", self.node("ND_oren_nayar_diffuse_bsdf", node.name, weight=1.0,
                                      color=self._in(node, "Color", "color3"), roughness=rough,
                                      **self.normal_kw(node, "Normal")))
        if t == "ShaderNodeEmission":
            col = self.mul(self._in(node, "Color", "color3"), self._in(node, "Strength"), node.name + "_color")
            return ("edf", self.node("ND_uniform_edf", node.name, color=col))
        if t == "ShaderNodeMixShader":
            return self.mix_shader(node)
        if t == "ShaderNodeAddShader":
            return self.add_shader(node)
        self.note(f"shader “{node.name}” ({t.replace('ShaderNode', '')}) is not exported: black")
        return None

    def normal_kw(self, node, key, name="normal"):
        s = node.input(key)
        if s is None or s.link is None:
            return {}
        v = self.value(s, "vector3")
        return {} if v.is_const else {name: v}

    def lift(self, sh, base):
        """A surfaceshader of a shader result."""
        if sh is None:
            if self._black is None:
                self._black = self.node("ND_surface", "black")
                self._black.set("opacity", "float", 1.0)
            return self._black
        kind, n = sh
        if kind == "surface":
            return n
        key = ("surface", n.name)
        if key not in self._values:
            s = self.node("ND_surface", base + "_surface")
            s.set("bsdf" if kind == "bsdf" else "edf", "BSDF" if kind == "bsdf" else "EDF", node=n)
            s.set("opacity", "float", 1.0)
            self._values[key] = s
        return self._values[key]

    def mix_shader(self, node):
        a = self.shader(node.inputs[1])
        b = self.shader(node.inputs[2])
        fac = self.clamp(self.value(node.inputs[0]), base=node.name + "_factor")
        if a is None and b is None:
            return None
        if fac.is_const and float(fac.const) in (0.0, 1.0):
            pass  # still written: the tree's structure (a mix by 0 or 1)
        if a is not None and b is not None and a[0] == b[0] and a[0] in ("bsdf", "edf"):
            kind = a[0]
            port = "BSDF" if kind == "bsdf" else "EDF"
            n = self.node("ND_mix_bsdf" if kind == "bsdf" else "ND_mix_edf", node.name, mix=fac)
            n.set("fg", port, node=b[1])
            n.set("bg", port, node=a[1])
            self.mixes[node.name] = n
            return (kind, n)
        n = self.node("ND_mix_surfaceshader", node.name, mix=fac)
        n.set("fg", "surfaceshader", node=self.lift(b, node.name + "_b"))
        n.set("bg", "surfaceshader", node=self.lift(a, node.name + "_a"))
        self.mixes[node.name] = n
        return ("surface", n)

    def add_shader(self, node):
        a = self.shader(node.inputs[0])
        b = self.shader(node.inputs[1])
        if a is None or b is None:
            return a or b
        if a[0] == b[0] and a[0] in ("bsdf", "edf"):
            nd = "ND_add_bsdf" if a[0] == "bsdf" else "ND_add_edf"
            n = self.node(nd, node.name)
            t = "BSDF" if a[0] == "bsdf" else "EDF"
            n.set("in1", t, node=a[1])
            n.set("in2", t, node=b[1])
            self.mixes[node.name] = n
            return (a[0], n)
        if {a[0], b[0]} == {"bsdf", "edf"}:
            bsdf, edf = (a, b) if a[0] == "bsdf" else (b, a)
            s = self.node("ND_surface", node.name)
            s.set("bsdf", "BSDF", node=bsdf[1])
            s.set("edf", "EDF", node=edf[1])
            s.set("opacity", "float", 1.0)
            self.mixes[node.name] = s
            return ("surface", s)
        self.note(f"Add Shader “{node.name}” adds an OpenPBR surface, which MaterialX 1.39 cannot "
                  f"add: its first shader is exported")
        return a

    # -- BSDFs ---------------------------------------------------------------------------------
    def _alpha(self, node, fn, r_name, a_name):
        """(α as a vector2 V, anisotropic?) with Cycles' convention ``fn`` (constants), or the
        node form of the Metallic/Principled convention."""
        r, a = self._in(node, r_name), self._in(node, a_name)
        if r.is_const and a.is_const:
            ax, ay = fn(r.const, a.const)
            return V("vector2", (ax, ay)), ax != ay
        if fn is glossy_alpha:
            self.note(f"Glossy BSDF “{node.name}”: textured roughness / anisotropy written with the "
                      f"Metallic convention α = roughness_anisotropy(R, 0.9 a)")
        r = self.clamp(r, base=node.name + "_rough")
        a = self.mul(self.clamp(a, base=node.name + "_aniso"), _c("float", 0.9), node.name + "_aniso09")
        return V("vector2", node=self.node("ND_roughness_anisotropy", node.name + "_alpha",
                                           roughness=r, anisotropy=a)), True

    def _dist(self, node):
        d = node.props.get("distribution", "GGX")
        if d in ("BECKMANN", "ASHIKHMIN_SHIRLEY"):
            self.note(f"“{node.name}” uses {d.replace('_', '-').title()}: written as ggx (MaterialX "
                      f"1.39 has no other distribution)")
        return "ggx"

    def _tangent(self, node, rot_name, aniso):
        if not aniso:
            return None
        src, _ = self._follow(node.input("Tangent"))
        kind = _tangent_kind(src) if src is not None and src.type == "ShaderNodeTangent" else "RADIAL_Z"
        if src is not None and src.type != "ShaderNodeTangent":
            self.note(f"the Tangent of “{node.name}” comes from “{src.name}”: written as a UV tangent")
            kind = "UV_MAP"
        rot = self._in(node, rot_name)
        return self.tangent_node(kind, float(rot.const) if rot.is_const else rot.node,
                                 "_" + valid_name(node.name))

    def metallic(self, node):
        alpha, aniso = self._alpha(node, principled_alpha, "Roughness", "Anisotropy")
        tangent = self._tangent(node, "Rotation", aniso)
        kw = dict(weight=1.0, roughness=alpha, distribution=self._dist(node), **self.normal_kw(node, "Normal"))
        if tangent is not None:
            kw["tangent"] = tangent
        if node.props.get("fresnel_type", "F82") == "PHYSICAL_CONDUCTOR":
            return self.node("ND_conductor_bsdf", node.name, ior=self._in(node, "IOR", "color3"),
                             extinction=self._in(node, "Extinction", "color3"), **kw)
        base = self.clamp(self._in(node, "Base Color", "color3"), base=node.name + "_f0")
        tint = self.clamp(self._in(node, "Edge Tint", "color3"), base=node.name + "_f82")
        return self.node("ND_generalized_schlick_bsdf", node.name, color0=base, color82=tint,
                         color90=(1.0, 1.0, 1.0), exponent=5.0, scatter_mode="R", **kw)

    def glossy(self, node):
        alpha, aniso = self._alpha(node, glossy_alpha, "Roughness", "Anisotropy")
        tangent = self._tangent(node, "Rotation", aniso)
        col = self.maximum(self._in(node, "Color", "color3"), _c("color3", 0.0), node.name + "_colour")
        kw = dict(weight=1.0, roughness=alpha, distribution=self._dist(node), **self.normal_kw(node, "Normal"))
        if tangent is not None:
            kw["tangent"] = tangent
        return self.node("ND_generalized_schlick_bsdf", node.name, color0=col, color82=(1.0, 1.0, 1.0),
                         color90=col, exponent=5.0, scatter_mode="R", **kw)

    def principled(self, node):
        """open_pbr_surface with the Principled BSDF's values (module docstring)."""
        n = node.name
        val = lambda key, to="float": self._in(node, key, to)  # noqa: E731
        sat = lambda v, nm: self.clamp(v, base=f"{n}_{nm}")  # noqa: E731
        metallic = sat(val("Metallic"), "metallic")
        rough, aniso = sat(val("Roughness"), "rough"), sat(val("Anisotropic"), "aniso")
        coat_w = self.maximum(val("Coat Weight"), _c("float", 0.0), n + "_coat_w")
        coat_r = sat(val("Coat Roughness"), "coat_rough")
        coat_ior = self.maximum(val("Coat IOR"), _c("float", 1.0), n + "_coat_ior")
        ior = self.maximum(val("IOR"), _c("float", 1e-5), n + "_ior")
        level = self.maximum(val("Specular IOR Level"), _c("float", 0.0), n + "_level")
        coated = not (coat_w.is_const and float(coat_w.const) == 0.0)
        # α: OpenPBR keeps α_x = r² √(2/(1+(1-a)²)), α_y = (1-a) α_x; Cycles α_x = R²/s, α_y = R² s
        if rough.is_const and aniso.is_const:
            ax, ay = principled_alpha(rough.const, aniso.const)
            r_e, a_o = openpbr_inverse(ax, ay)
            r_e, a_o = _c("float", r_e), _c("float", a_o)
        elif aniso.is_const and float(aniso.const) == 0.0:
            r_e, a_o = rough, _c("float", 0.0)
        else:
            r_e, a_o = self._openpbr_inverse_nodes(rough, aniso, n)
        # under a coat: undo OpenPBR's roughening and its coat-relative base IOR
        if coated:
            r_e = self.inverse_of_constants(
                coat_roughness_inverse, (r_e, coat_r, coat_w),
                lambda res: f"“{n}”: the coat roughens OpenPBR's base beyond its roughness "
                            f"{_fmt(r_e.const)} (coat roughness {_fmt(coat_r.const)}): written at 0") \
                or self._uncoated_roughness_nodes(r_e, coat_r, coat_w, n)
            ior = self.inverse_of_constants(
                coat_ior_inverse, (ior, coat_ior, coat_w),
                lambda res: f"“{n}”: no specular_ior gives OpenPBR's coat-relative IOR "
                            f"{_fmt(ior.const)}: off by {res:.3g}") \
                or self._uncoated_ior_nodes(ior, coat_ior, coat_w, n)
        # specular_weight: Principled's Specular IOR Level acts on the dielectric only
        if metallic.is_const and float(metallic.const) >= 1.0:
            spec_w = _c("float", 1.0)
        else:
            spec_w = self.mul(level, _c("float", 2.0), n + "_spec_w")
            if not metallic.is_const or float(metallic.const) > 0.0:
                if not (level.is_const and float(level.const) == 0.5):
                    self.note(f"“{n}”: OpenPBR's specular_weight (2 × Specular IOR Level) also scales "
                              f"the metallic part; Principled's level does not")
        tint = val("Specular Tint", "color3")
        if metallic.is_const and float(metallic.const) >= 1.0:
            tint = self.clamp(tint, base=n + "_tint")  # Cycles' F82 tint is min(tint, 1)
        s = self.node("ND_open_pbr_surface_surfaceshader", n)
        put = lambda k, v: self.put(s, k, v)  # noqa: E731
        put("base_weight", _c("float", 1.0))
        put("base_color", val("Base Color", "color3"))
        if node.input("Diffuse Roughness") is not None:
            put("base_diffuse_roughness", sat(val("Diffuse Roughness"), "diffuse_rough"))
        put("base_metalness", metallic)
        put("specular_weight", spec_w)
        put("specular_color", tint)
        put("specular_roughness", r_e)
        put("specular_ior", ior)
        put("specular_roughness_anisotropy", a_o)
        trans = sat(val("Transmission Weight"), "transmission")
        if not (trans.is_const and float(trans.const) == 0.0):
            self.note(f"“{n}”: transmission is approximate in MaterialX: OpenPBR tints the refracted "
                      f"light once by transmission_color (the Base Color), Cycles by √Base Color at "
                      f"each interface, and its dielectric Fresnel is the exact one where Cycles' "
                      f"Principled keeps F0 (docs/interchange.md §5)")
        put("transmission_weight", trans)
        put("transmission_color", val("Base Color", "color3"))
        put("subsurface_weight", sat(val("Subsurface Weight"), "subsurface"))
        put("subsurface_color", val("Base Color", "color3"))
        put("subsurface_radius", val("Subsurface Scale"))
        put("subsurface_radius_scale", val("Subsurface Radius", "color3"))
        if node.input("Subsurface Anisotropy") is not None:
            put("subsurface_scatter_anisotropy", val("Subsurface Anisotropy"))
        put("fuzz_weight", self.maximum(val("Sheen Weight"), _c("float", 0.0), n + "_sheen"))
        put("fuzz_color", val("Sheen Tint", "color3"))
        put("fuzz_roughness", sat(val("Sheen Roughness"), "sheen_rough"))
        put("coat_weight", coat_w)
        put("coat_color", val("Coat Tint", "color3"))
        put("coat_roughness", coat_r)
        put("coat_ior", coat_ior)
        put("coat_darkening", _c("float", 0.0))
        put("emission_luminance", val("Emission Strength"))
        put("emission_color", val("Emission Color", "color3"))
        if node.input("Thin Film Thickness") is not None:
            thick = val("Thin Film Thickness")
            if not (thick.is_const and float(thick.const) <= 0.1):
                self.note(f"“{n}”: the thin film is OpenPBR's model in MaterialX (its film on the "
                          f"specular_ior the layer raised); Cycles' film reflectance differs "
                          f"(docs/thin-film.md)")
            if thick.is_const:
                put("thin_film_weight", _c("float", 1.0 if float(thick.const) > 0.1 else 0.0))
            else:
                put("thin_film_weight", self.select("ifgreater", thick, _c("float", 0.1), _c("float", 1.0),
                                                    _c("float", 0.0), n + "_film_on"))
            put("thin_film_thickness", self.mul(thick, _c("float", 0.001), n + "_film_um"))
            put("thin_film_ior", val("Thin Film IOR"))
        put("geometry_opacity", sat(val("Alpha"), "alpha"))
        for key, inp in (("Normal", "geometry_normal"), ("Coat Normal", "geometry_coat_normal")):
            kw = self.normal_kw(node, key, inp)
            if kw:
                put(inp, kw[inp])
        aniso_on = not (a_o.is_const and float(a_o.const) == 0.0)
        tangent = self._tangent(node, "Anisotropic Rotation", aniso_on)
        if tangent is not None:
            s.set("geometry_tangent", "vector3", node=tangent)
        if coated:
            tint_c = val("Coat Tint", "color3")
            if not (tint_c.is_const and np.all(tint_c.array() == 1.0)):
                self.note(f"“{n}”: OpenPBR's coat_color tints by a constant factor, Cycles' Coat Tint "
                          f"by tint^(1/cos θ_t) (the same at normal incidence)")
        return s

    def _uncoated_roughness_nodes(self, r_e, coat_r, coat_w, n):
        """OpenPBR's coat roughening undone in nodes, exact at coat weight 0 and 1:
        mix(r, (max(r⁴ - 2 c⁴, 0))^¼, w)."""
        r4 = self.mul(self.mul(r_e, r_e, n + "_r2"), self.mul(r_e, r_e, n + "_r2b"), n + "_r4")
        c2 = self.mul(coat_r, coat_r, n + "_c2")
        c4 = self.mul(self.mul(c2, c2, n + "_c4"), _c("float", 2.0), n + "_2c4")
        inner = self.maximum(self.sub(r4, c4, n + "_r4c4"), _c("float", 0.0), n + "_pos")
        un = self.sqrt(self.sqrt(inner, n + "_q2"), n + "_q4")
        if not coat_w.is_const:
            self.note(f"“{n}”: textured Coat Weight: OpenPBR's coat roughening and base IOR "
                      f"are undone exactly at weights 0 and 1 only")
        return self.mix(self.clamp(coat_w, base=n + "_coat_w01"), r_e, un, n + "_uncoated")

    def _uncoated_ior_nodes(self, ior, coat_ior, coat_w, n):
        """OpenPBR's coat-relative base IOR undone in nodes, the branch η_o ≥ η_c:
        η / ((1-w) + w/η_c)."""
        w = self.clamp(coat_w, base=n + "_coat_wi")
        den = self.add(self.sub(_c("float", 1.0), w, n + "_1mw"), self.div(w, coat_ior, n + "_w_c"),
                       n + "_den")
        return self.div(ior, den, n + "_ior_coated")

    def _openpbr_inverse_nodes(self, rough, aniso, n):
        """Node form of openpbr_inverse(principled_alpha(R, A)) (α clamps at 1 not modelled)."""
        s2 = self.sub(_c("float", 1.0), self.mul(aniso, _c("float", 0.9), n + "_a09"), n + "_s2")
        a_o = self.sub(_c("float", 1.0), s2, n + "_aniso_o")
        # r_e = R ((1 + s⁴) / (2 s²))^¼
        s4 = self.mul(s2, s2, n + "_s4")
        q = self.div(self.add(s4, _c("float", 1.0), n + "_1ps4"), self.mul(s2, _c("float", 2.0), n + "_2s2"),
                     n + "_q")
        r_e = self.mul(rough, self.sqrt(self.sqrt(q, n + "_q2"), n + "_q4"), n + "_rough_o")
        return r_e, a_o


def _tangent_kind(node):
    """The tangent a Tangent node gives, in builder.Builder.tangent's terms."""
    if node is None or node.props.get("direction_type", "RADIAL") == "UV_MAP":
        return "UV_MAP"
    return f"RADIAL_{node.props.get('axis', 'Z')}"


def _fmt(v):
    arr = np.atleast_1d(np.asarray(v, dtype=np.float64))
    return ", ".join(f"{x:.4g}" for x in arr) if arr.size > 1 else f"{arr[0]:.4g}"


# --------------------------------------------------------------------------------------------
# One material
# --------------------------------------------------------------------------------------------


def graph_of(tree, name, notes, *, directory=None):
    """(NodeGraph NG_<name> with a surfaceshader output "out", Writer) for a layered tree."""
    g = NodeGraph(f"NG_{name}")
    w = Writer(tree, g, notes, directory=directory)
    out = tree.nodes.get(tree.output) if tree.output else None
    if out is None:
        raise ValueError(f"{tree.name}: no Material Output the renderers use")
    surf = out.input("Surface")
    sh = w.shader(surf)
    top = w.lift(sh, "surface")
    for key in ("Volume", "Displacement"):
        s = out.input(key)
        if s is not None and s.link is not None:
            w.note(f"the Material Output's {key} is not exported")
    g.outputs["out"] = Input("out", "surfaceshader", nodename=top.name)
    lay = tree.layer or {}
    g.attrs[f"{K.MATERIALX_ATTR}_kind"] = "LAYER"
    g.attrs[f"{K.MATERIALX_ATTR}_model"] = (
        "haze layer on the user's BSDF: the core (narrow lobe, F(0) raised to r) and its wide "
        "copies as open_pbr_surface / pbr BSDFs, mixed by beta as the Blender tree mixes them")
    if lay.get("live_math"):
        w.note("the layer's node math (textured inputs) is exported per pixel as standard-library "
               "math with Cycles' semantics")
    return g, w


#: Version of the hazygloss_layer record: 2 adds what the importer needs to rebuild the layer
#: (the core's node, its settings and the user's own values of the inputs the layer owns).
LAYER_RECORD_VERSION = 2


def layer_record(tree, writer=None):
    """The layer's state as JSON for the document (hazygloss_layer): the haze parameters, the
    core (its Blender name, type and settings, the MaterialX node written for it) and, per
    input the layer owns, the user's own value or the MaterialX node of the user's link — what
    materialx_import needs to rebuild the same layer (the core's other inputs are in its
    node)."""
    lay = dict(tree.layer or {})
    lay["record"] = LAYER_RECORD_VERSION
    core = tree.core()
    if core is not None:
        lay["core_props"] = {k: core.props[k] for k in ("distribution", "fresnel_type",
                                                        "subsurface_method") if k in core.props}
        if writer is not None and core.name not in writer.surfaces and not core.mute:
            writer.shader_of_node(core)  # a layer node's core renders inside it: its own surface
        if writer is not None and core.name in writer.surfaces:
            lay["core_node"] = writer.surfaces[core.name].name
        base = {}
        for name, b in (core.base or {}).items():
            if "value" in b:
                c = np.asarray(b["value"], float).reshape(-1)
                base[name] = {"value": float(c[0]) if c.size == 1 else [float(x) for x in c[:3]]}
            elif "link" in b and writer is not None:
                sock = core.input(name)
                probe = Socket(sock.identifier if sock else name, name, sock.type if sock else "VALUE",
                               None, tuple(b["link"]), True, False, core.name)
                v = writer.value(probe, _MX_TYPE.get(probe.type, "float"))
                if v is not None and not v.is_const:
                    base[name] = {"node": v.node.name, "output": v.output}
                elif v is not None:
                    c = np.asarray(v.const, float).reshape(-1)
                    base[name] = {"value": float(c[0]) if c.size == 1 else [float(x) for x in c[:3]]}
        lay["base"] = base
    return json.dumps(lay, sort_keys=True, default=lambda o: list(o) if isinstance(o, tuple) else str(o))


# --------------------------------------------------------------------------------------------
# The user's BSDF at haziness 0 (USD preview, export fallback)
# --------------------------------------------------------------------------------------------


def user_value(core, name):
    """The core's input ``name`` as the user set it: the stamped user value of an owned input
    (the layer wrote another), else the socket's own value (also when it is linked)."""
    b = (core.base or {}).get(name)
    if b is not None and "value" in b:
        return b["value"]
    s = core.input(name)
    return s.value if s is not None else None


def preview_values(tree):
    """UsdPreviewSurface inputs of the user's BSDF at haziness 0 (constants: a linked input
    gives its socket's value), or None without a core."""
    core = tree.core()
    if core is None:
        return None
    u = lambda name, d=0.0: user_value(core, name) if core.input(name) is not None else d  # noqa: E731
    rgb = lambda v: tuple(float(x) for x in np.broadcast_to(np.asarray(v, float).reshape(-1)[:3], 3))  # noqa: E731
    out = dict(metallic=1.0, roughness=float(u("Roughness")), ior=1.5, clearcoat=0.0,
               clearcoatRoughness=0.01, opacity=1.0, emissiveColor=(0.0, 0.0, 0.0))
    if core.type == _PRINCIPLED:
        out.update(metallic=min(max(float(u("Metallic")), 0.0), 1.0), diffuseColor=rgb(u("Base Color")),
                   ior=float(u("IOR", 1.5)), clearcoat=min(max(float(u("Coat Weight")), 0.0), 1.0),
                   clearcoatRoughness=float(u("Coat Roughness", 0.03)),
                   opacity=min(max(float(u("Alpha", 1.0)), 0.0), 1.0),
                   emissiveColor=tuple(c * float(u("Emission Strength")) for c in rgb(u("Emission Color", (1, 1, 1)))))
    elif core.type == _METALLIC:
        if core.props.get("fresnel_type") == "PHYSICAL_CONDUCTOR":
            r, _ = gulbrandsen_inverse(np.maximum(np.asarray(rgb(u("IOR")), float), 0.0),
                                       np.maximum(np.asarray(rgb(u("Extinction")), float), 0.0))
            out["diffuseColor"] = rgb(np.clip(np.nan_to_num(r), 0.0, 1.0))
        else:
            out["diffuseColor"] = rgb(u("Base Color"))
    else:
        out["diffuseColor"] = rgb(u("Color"))
    return out
