# SPDX-License-Identifier: GPL-3.0-or-later
"""The surfaces material libraries ship, as Principled BSDF materials (bpy-free).

:func:`principled_of` turns one ``open_pbr_surface`` (1.1, and the 1.2 draft with
``specular_haze``), ``standard_surface``, ``gltf_pbr`` or ``UsdPreviewSurface`` node of a
:class:`~hazy_gloss.interchange.document.Document` into a :class:`SurfaceSpec`: the Principled
BSDF's socket values (or links into a small node network: Image Texture, Math, Vector Math, Mix,
Separate / Combine XYZ, Mapping, UV Map, Normal Map), its distribution, and, for OpenPBR haze,
the keywords of ``api.make_hazy``.  blender/surface_build.py makes the nodes; nothing here
imports bpy.

Each mapping follows the way the format's own tools map it onto a Principled BSDF, corrected
where they are not exact (docs/interchange.md §2 has the tables and the measured differences):

- **OpenPBR**: the inverse of Blender's own MaterialX exporter (base_metalness = Metallic,
  specular_weight = 2 · Specular IOR Level, ...) and of the corrections interchange/layered.py
  writes (OpenPBR's anisotropy keeps α_x, Cycles' the geometric mean; OpenPBR roughens the base
  and sees η/η_c under a coat, Cycles does not — applied here so the Principled renders what
  OpenPBR means); Multiscatter GGX (OpenPBR: "the multiple scattering compensation is assumed to
  apply to both lobes").
- **standard_surface**: MaterialX's translation graph to OpenPBR (specular → specular_weight,
  sheen roughness^0.4 → fuzz roughness) and its own nodegraph (roughness_anisotropy, tangent
  turned by specular_rotation); the Gulbrandsen metal (base colour, edge colour specular_color)
  becomes Principled's F82 metal with the tint that matches its Fresnel at 82°; GGX (the spec's
  BRDFs are single-scattering GGX).
- **gltf_pbr**: Blender's glTF importer (Specular IOR Level = specular / 2, sheen weight 1 with
  sheen_color, anisotropy rotation / 2π), with glTF's anisotropy (α_t = mix(α, 1, s²)) mapped
  exactly; Multiscatter GGX (the glTF spec suggests multiple scattering).
- **UsdPreviewSurface**: Blender's USD importer, with the specular workflow's F(0) =
  specularColor kept (Specular IOR Level and Tint) and the clearcoat's IOR = ior (the spec); GGX.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from .. import constants as K
from ..core.mapping import gulbrandsen_ior
from .brdf import fresnel_conductor_at
from .document import NODEDEFS, OPENPBR_12_INPUTS

__all__ = ("Link", "TexNode", "SurfaceSpec", "SURFACES", "principled_of", "Upstream",
           "openpbr_principled_alpha", "coat_roughened", "coat_relative_ior", "f82_tint_of_conductor")

PRINCIPLED = "ShaderNodeBsdfPrincipled"
#: The shader node categories read as Principled materials, with their distribution.
SURFACES = {"open_pbr_surface": "MULTI_GGX", "standard_surface": "GGX", "gltf_pbr": "MULTI_GGX",
            "UsdPreviewSurface": "GGX"}
#: MaterialX colour spaces -> Blender's (the default OCIO config's names).
COLORSPACES = {"srgb_texture": "sRGB", "lin_rec709": "Linear Rec.709", "raw": "Non-Color",
               "acescg": "ACEScg", "lin_ap1": "ACEScg", "lin_ap0": "ACES2065-1",
               "lin_rec2020": "Linear Rec.2020", "lin_displayp3": "Linear DCI-P3 D65",
               "srgb_displayp3": "Display P3", "g22_rec709": "sRGB", "g18_rec709": "sRGB",
               "none": "Non-Color"}
_ADDRESS = {"periodic": "REPEAT", "clamp": "EXTEND", "constant": "CLIP", "mirror": "MIRROR",
            "black": "CLIP", "repeat": "REPEAT", "useMetadata": "REPEAT"}
_FILTER = {"closest": "Closest", "linear": "Linear", "cubic": "Cubic"}


# --------------------------------------------------------------------------------------------
# What is built
# --------------------------------------------------------------------------------------------


@dataclass(slots=True)
class Link:
    """An output of one node of the spec's network."""

    node: str
    output: str


@dataclass
class TexNode:
    """One Blender node of the network feeding the Principled: ``inputs`` by socket identifier
    (a value, or a Link), ``props`` node properties, ``image`` for an Image Texture (path,
    colorspace, udim)."""

    bl_idname: str
    props: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    image: dict = None
    label: str = ""


@dataclass
class SurfaceSpec:
    """A Principled BSDF material read from a library surface: ``inputs`` socket name -> value
    (float or RGB / XYZ tuple) or Link; ``nodes`` the network; ``haze`` keywords of
    api.make_hazy (None: no haze); ``notes`` what is approximate or not imported."""

    name: str
    source: str
    inputs: dict = field(default_factory=dict)
    props: dict = field(default_factory=dict)
    nodes: dict = field(default_factory=dict)
    haze: dict = None
    haze_target: dict = None  #: the blend the haze reproduces (β, α_n, α_w, F0) and its error
    alpha_clip: float = None  #: alpha threshold of a masked material (glTF MASK, USD threshold)
    bsdf: str = PRINCIPLED
    notes: list = field(default_factory=list)
    lossy: int = 0

    @property
    def exact(self):
        return self.lossy == 0

    def to_dict(self):
        def plain(v):
            return {"link": [v.node, v.output]} if isinstance(v, Link) else v
        return {"bsdf": self.bsdf, "source": self.source, "props": dict(self.props),
                "inputs": {k: plain(v) for k, v in self.inputs.items()},
                "nodes": {k: {"type": n.bl_idname, "props": n.props, "image": n.image,
                              "inputs": {s: plain(v) for s, v in n.inputs.items()}}
                          for k, n in self.nodes.items()},
                "haze": self.haze, "alpha_clip": self.alpha_clip}


class Notes(list):
    """Notes of one material; ``lose`` records one that makes it inexact."""

    lost = 0

    def lose(self, text):
        if text not in self:
            self.append(text)
        self.lost += 1

    def say(self, text):
        if text not in self:
            self.append(text)


# --------------------------------------------------------------------------------------------
# Values: constants folded in float64, links (with an affine map folded in) otherwise
# --------------------------------------------------------------------------------------------


class Val:
    """A scalar (n = 1) or RGB / XYZ (n = 3) value: a constant, or ``link`` · scale + bias (the
    affine part is folded until a node needs it)."""

    __slots__ = ("n", "const", "link", "scale", "bias", "alpha")

    def __init__(self, n, const=None, link=None, scale=None, bias=None, alpha=None):
        self.n = n
        self.const = const
        self.link = link
        self.scale = scale
        self.bias = bias
        self.alpha = alpha  #: a colour image's alpha (Val), when it has one

    @property
    def is_const(self):
        return self.link is None

    def __repr__(self):
        return f"Val({self.const})" if self.is_const else f"Val({self.link}*{self.scale}+{self.bias})"


def _t3(x):
    return x if isinstance(x, tuple) else (x, x, x)


def _map(f, *xs):
    if len(xs) == 2:  # the common case, without the general machinery
        a, b = xs
        ta, tb = type(a) is tuple, type(b) is tuple
        if not (ta or tb):
            return f(a, b)
        a = a if ta else (a, a, a)
        b = b if tb else (b, b, b)
        return (f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]))
    if any(isinstance(x, tuple) for x in xs):
        cols = [_t3(x) for x in xs]
        return tuple(f(*c) for c in zip(*cols))
    return f(*xs)


def _safe_div(a, b):
    return a / b if b != 0.0 else 0.0


def _safe_pow(a, b):
    if a < 0.0 and b != math.floor(b):
        return 0.0
    if a == 0.0 and b < 0.0:
        return 0.0
    try:
        return math.pow(a, b)
    except (OverflowError, ValueError):
        return 0.0


def C(x):
    """A constant Val."""
    if type(x) is float:
        return Val(1, x)
    if isinstance(x, (tuple, list)):
        t = tuple(float(v) for v in x[:3])
        if len(t) == 2:  # a vector2 (uv): z = 0
            t = t + (0.0,)
        return Val(3, t if len(t) == 3 else _t3(t[0] if t else 0.0))
    return Val(1, float(x))


class Builder:
    """The node network of one material: folds constants, keeps affine maps of links, and makes
    Math / Vector Math / Mix / Separate / Combine nodes where a link needs them."""

    def __init__(self):
        self.nodes = {}
        self._count = 0

    def node(self, bl_idname, props=None, inputs=None, label="", image=None):
        self._count += 1
        key = f"{bl_idname.replace('ShaderNode', '')}.{self._count:03d}"
        self.nodes[key] = TexNode(bl_idname, dict(props or {}), dict(inputs or {}), image, label)
        return key

    # -- making links concrete -----------------------------------------------------------------
    def socket(self, v, n=None):
        """What a socket gets: a constant (float / tuple) or a Link (the affine part as a node)."""
        n = v.n if n is None else n
        if v.is_const:
            if n == 3:
                return _t3(v.const)
            return v.const if not isinstance(v.const, tuple) else sum(v.const) / 3.0
        link = v.link
        s, b = v.scale, v.bias
        if s is not None or b is not None:
            s = 1.0 if s is None else s
            b = 0.0 if b is None else b
            if v.n == 1:
                key = self.node("ShaderNodeMath", {"operation": "MULTIPLY_ADD"},
                                {"Value": link, "Value_001": s, "Value_002": b})
                link = Link(key, "Value")
            else:
                key = self.node("ShaderNodeVectorMath", {"operation": "MULTIPLY_ADD"},
                                {"Vector": link, "Vector_001": _t3(s), "Vector_002": _t3(b)})
                link = Link(key, "Vector")
            v.link, v.scale, v.bias = link, None, None  # made once, shared by every use
        if n == 1 and v.n == 3:  # a colour into a float: the average (Vector Math Dot / 3)
            key = self.node("ShaderNodeVectorMath", {"operation": "DOT_PRODUCT"},
                            {"Vector": link, "Vector_001": (1 / 3, 1 / 3, 1 / 3)})
            return Link(key, "Value")
        return link

    # -- arithmetic ----------------------------------------------------------------------------
    def _n(self, *vs):
        return 3 if any(v.n == 3 for v in vs) else 1

    def _node_op(self, op, *vs):
        n = self._n(*vs)
        if n == 1:
            ids = ("Value", "Value_001", "Value_002")
            key = self.node("ShaderNodeMath", {"operation": op},
                            {ids[i]: self.socket(v, 1) for i, v in enumerate(vs)})
            return Val(1, link=Link(key, "Value"))
        ids = ("Vector", "Vector_001", "Vector_002")
        key = self.node("ShaderNodeVectorMath", {"operation": op},
                        {ids[i]: self.socket(v, 3) for i, v in enumerate(vs)})
        return Val(3, link=Link(key, "Vector"))

    def affine(self, v, s, b):
        """v · s + b with constant s, b (floats or tuples)."""
        if v.is_const:
            return Val(max(v.n, 3 if isinstance(s, tuple) or isinstance(b, tuple) else 1),
                       _map(lambda x, y, z: x * y + z, v.const, s, b))
        n = 3 if v.n == 3 or isinstance(s, tuple) or isinstance(b, tuple) else 1
        s0 = 1.0 if v.scale is None else v.scale
        b0 = 0.0 if v.bias is None else v.bias
        scale = _map(lambda x, y: x * y, s0, s)
        bias = _map(lambda x, y, z: x * y + z, b0, s, b)
        if _t3(scale) == (1.0, 1.0, 1.0):
            scale = None
        if _t3(bias) == (0.0, 0.0, 0.0):
            bias = None
        return Val(n, link=v.link, scale=scale, bias=bias, alpha=v.alpha)

    def add(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), _map(lambda x, y: x + y, a.const, b.const))
        if b.is_const:
            return self.affine(a, 1.0, b.const)
        if a.is_const:
            return self.affine(b, 1.0, a.const)
        return self._node_op("ADD", a, b)

    def sub(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), _map(lambda x, y: x - y, a.const, b.const))
        if b.is_const:
            return self.affine(a, 1.0, _map(lambda x: -x, b.const))
        if a.is_const:
            return self.affine(b, -1.0, a.const)
        return self._node_op("SUBTRACT", a, b)

    def mul(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), _map(lambda x, y: x * y, a.const, b.const))
        if b.is_const:
            return self.affine(a, b.const, 0.0)
        if a.is_const:
            return self.affine(b, a.const, 0.0)
        if a.n != b.n:  # colour × float: Vector Math Scale
            vec, sca = (a, b) if a.n == 3 else (b, a)
            key = self.node("ShaderNodeVectorMath", {"operation": "SCALE"},
                            {"Vector": self.socket(vec, 3), "Scale": self.socket(sca, 1)})
            return Val(3, link=Link(key, "Vector"))
        return self._node_op("MULTIPLY", a, b)

    def div(self, a, b):
        """Blender's safe division (x / 0 = 0)."""
        if a.is_const and b.is_const:
            return Val(self._n(a, b), _map(_safe_div, a.const, b.const))
        if b.is_const:
            return self.affine(a, _map(lambda y: _safe_div(1.0, y), b.const), 0.0)
        return self._node_op("DIVIDE", a, b)

    def pow(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), _map(_safe_pow, a.const, b.const))
        if b.is_const and not isinstance(b.const, tuple) and b.const == 1.0:
            return a
        return self._node_op("POWER", a, b)

    def sqrt(self, a):
        if a.is_const:
            return Val(a.n, _map(lambda x: math.sqrt(x) if x > 0 else 0.0, a.const))
        if a.n == 3:
            return self._node_op("POWER", a, C((0.5, 0.5, 0.5)))
        return self._node_op("SQRT", a)

    def minimum(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), _map(min, a.const, b.const))
        return self._node_op("MINIMUM", a, b)

    def maximum(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), _map(max, a.const, b.const))
        return self._node_op("MAXIMUM", a, b)

    def clamp(self, a, lo=0.0, hi=1.0):
        if a.is_const:
            return Val(a.n, _map(lambda x: min(max(x, lo), hi), a.const))
        if a.n == 1:
            key = self.node("ShaderNodeClamp", {"clamp_type": "MINMAX"},
                            {"Value": self.socket(a, 1), "Min": lo, "Max": hi})
            return Val(1, link=Link(key, "Result"))
        return self.minimum(self.maximum(a, C(_t3(lo))), C(_t3(hi)))

    def mix(self, t, a, b):
        """a + t (b - a): a for t = 0, b for t = 1 (exactly, also when a = b)."""
        if t.is_const and a.is_const and b.is_const:
            tc = t.const if not isinstance(t.const, tuple) else t.const[0]
            return Val(self._n(a, b), _map(lambda x, y: x + tc * (y - x) if x != y else x, a.const, b.const))
        if t.is_const:
            tc = t.const if not isinstance(t.const, tuple) else t.const[0]
            if tc == 0.0:
                return a
            if tc == 1.0:
                return b
        if a.is_const and b.is_const and a.const == b.const:
            return a
        n = self._n(a, b)
        if n == 1:
            key = self.node("ShaderNodeMix", {"data_type": "FLOAT", "clamp_factor": False},
                            {"Factor_Float": self.socket(t, 1), "A_Float": self.socket(a, 1),
                             "B_Float": self.socket(b, 1)})
            return Val(1, link=Link(key, "Result_Float"))
        key = self.node("ShaderNodeMix", {"data_type": "VECTOR", "factor_mode": "UNIFORM",
                                          "clamp_factor": False},
                        {"Factor_Float": self.socket(t, 1), "A_Vector": self.socket(a, 3),
                         "B_Vector": self.socket(b, 3)})
        return Val(3, link=Link(key, "Result_Vector"))

    def greater(self, a, b):
        """1 where a > b, else 0 (Math Greater Than)."""
        if a.is_const and b.is_const:
            return C(1.0 if a.const > b.const else 0.0)
        return self._node_op("GREATER_THAN", a, b)

    def channel(self, v, i):
        """Component i (0-2) of a colour / vector; 3: its alpha (1 when it has none)."""
        if i == 3:
            return v.alpha if v.alpha is not None else C(1.0)
        if v.n == 1:
            return v
        if v.is_const:
            return C(_t3(v.const)[i])
        s = None if v.scale is None else _t3(v.scale)[i]
        b = None if v.bias is None else _t3(v.bias)[i]
        key = self.node("ShaderNodeSeparateXYZ", {}, {"Vector": v.link})
        out = Val(1, link=Link(key, "XYZ"[i]))
        if s is None and b is None:
            return out
        return self.affine(out, 1.0 if s is None else s, 0.0 if b is None else b)

    def combine(self, x, y, z):
        if x.is_const and y.is_const and z.is_const:
            return C((x.const, y.const, z.const))
        key = self.node("ShaderNodeCombineXYZ", {}, {"X": self.socket(x, 1), "Y": self.socket(y, 1),
                                                     "Z": self.socket(z, 1)})
        return Val(3, link=Link(key, "Vector"))

    def mean(self, v):
        if v.n == 1:
            return v
        if v.is_const:
            return C(sum(_t3(v.const)) / 3.0)
        return Val(1, link=self.socket(v, 1))

    def as3(self, v):
        return v if v.n == 3 else (C(_t3(v.const)) if v.is_const else self.combine(v, v, v))


# --------------------------------------------------------------------------------------------
# Reading a document: inputs with their nodedef defaults, upstream nodes as Blender nodes
# --------------------------------------------------------------------------------------------

#: (category, output type) -> {input: (type, default)} of every nodedef in the table.
_DEFAULTS = {}
for _nd, (_cat, _typ, _spec) in NODEDEFS.items():
    _DEFAULTS.setdefault((_cat, _typ), _spec)
_BY_CATEGORY = {}
for _nd, (_cat, _typ, _spec) in NODEDEFS.items():
    _BY_CATEGORY.setdefault(_cat, _spec)
_OPENPBR_12 = dict(NODEDEFS["ND_open_pbr_surface_surfaceshader"][2], **OPENPBR_12_INPUTS,
                   emission_weight=("float", 0.0))
_N3 = {"color3": 3, "vector3": 3, "color4": 3, "vector4": 3, "vector2": 3}
_ORDER = {"x": 0, "y": 1, "z": 2, "w": 3, "r": 0, "g": 1, "b": 2, "a": 3}


def surface_defaults(node):
    """The nodedef inputs of a surface node: {input: (type, default)}."""
    cat = node.category
    if cat == "standard_surface" and node.attrs.get("version") == "1.0.0":
        return NODEDEFS["ND_standard_surface_surfaceshader_100"][2]
    if cat == "open_pbr_surface":
        if str(node.attrs.get("version", "")).startswith("1.2"):
            return _OPENPBR_12
        return NODEDEFS["ND_open_pbr_surface_surfaceshader"][2]
    return _BY_CATEGORY.get(cat, {})


def _as_val(dflt):
    if isinstance(dflt, str) or dflt is None:  # a geometric default (Nworld, Tworld, UV0)
        return None
    if isinstance(dflt, bool):
        return C(1.0 if dflt else 0.0)
    return C(dflt)


_DEFAULT_VALS = {}


def _defaults_of(spec):
    """{input: its nodedef default as a constant Val} of a spec (shared: constants are not
    changed)."""
    table = _DEFAULT_VALS.get(id(spec))
    if table is None:
        table = _DEFAULT_VALS[id(spec)] = {k: _as_val(d) for k, (_, d) in spec.items()}
    return table


def _default_val(spec, name):
    """The nodedef default of an input as a constant Val."""
    table = _defaults_of(spec)
    return table[name] if name in table else _as_val(0.0)


class Upstream:
    """Values of a node's inputs: constants (authored, else the nodedef's default), or the
    Blender nodes that compute them from what the document connects (images, math)."""

    def __init__(self, doc, builder, notes, name):
        self.doc = doc
        self.b = builder
        self.notes = notes
        self.name = name
        self.memo = {}
        self.textured = []

    @property
    def directory(self):
        """Where relative texture paths start: the document's folder."""
        doc = self.doc
        return os.path.dirname(os.path.abspath(doc.source)) if doc.source else os.getcwd()

    # -- the surface's inputs ------------------------------------------------------------------
    def input(self, node, graph, name, spec):
        """The Val of input ``name`` of ``node`` (``spec``: {input: (type, default)})."""
        inp = node.inputs.get(name)
        if inp is None:
            return _default_val(spec, name)
        typ, dflt = spec.get(name, ("float", 0.0))
        if inp is not None and inp.problem:
            self.notes.lose(f"{node.name}.{name}: {inp.problem}")
        if inp is not None and inp.type and typ and inp.type != typ and not inp.connected \
                and not (inp.type in _N3 and typ in _N3):
            self.notes.lose(f"{node.name}.{name} is written as {inp.type}, its nodedef says {typ}: "
                            f"ignored (the default is used), as MaterialX's validate() refuses it")
            inp = None
        v = self.resolve(inp, graph, typ, f"{node.name}.{name}")
        if v is None:
            v = self._default(typ, dflt)
        return v

    def _default(self, typ, dflt):
        return _as_val(dflt)

    def resolve(self, inp, graph, typ, where):
        """Val of an input (None: not authored, nor connected to anything that reads)."""
        if inp is None:
            return None
        kind, x, g = self.doc.resolve(inp, graph)
        if kind == "value":
            if x is None:
                if inp.connected:
                    self.notes.lose(f"{where} is connected to nothing that exists: the default is used")
                return None
            if isinstance(x, bool):
                return C(1.0 if x else 0.0)
            if isinstance(x, (int, float)):
                return C(float(x))
            if isinstance(x, tuple):
                return C(x) if len(x) >= 2 else C(x[0])
            return None
        v = self.node_value(x, g, self._output_of(inp, graph), where)
        if v is not None and inp.channels:
            v = self._swizzle(v, inp.channels, where)
        return v

    def _output_of(self, inp, graph):
        """The output name an input reads of its node (through a node graph's output)."""
        out = inp.output
        if inp.nodegraph:
            g = self.doc.graphs.get(inp.nodegraph)
            o = g.outputs.get(inp.output) if g is not None and inp.output else (
                next(iter(g.outputs.values()), None) if g is not None else None)
            out = o.output if o is not None else None
        return out

    def _swizzle(self, v, channels, where):
        idx = [_ORDER.get(c) for c in channels.lower()]
        if any(i is None for i in idx):
            self.notes.lose(f"{where}: channels {channels!r} not understood: read as is")
            return v
        if len(idx) == 1:
            return self.b.channel(v, idx[0])
        if idx[:3] in ([0, 1, 2],):
            return v
        parts = [self.b.channel(v, i) for i in idx[:3]] + [C(0.0)] * (3 - len(idx[:3]))
        return self.b.combine(*parts[:3])

    # -- upstream nodes ------------------------------------------------------------------------
    def node_value(self, n, graph, output, where):
        key = (id(graph), n.name, output)
        if key in self.memo:
            return self.memo[key]
        self.memo[key] = None  # a cycle reads as not connected
        try:
            v = self._node_value(n, graph, output, where)
        except RecursionError:
            v = None
        self.memo[key] = v
        return v

    def _in(self, n, graph, name, typ="float", dflt=0.0):
        inp = n.inputs.get(name)
        if inp is not None and inp.problem:
            self.notes.lose(f"{n.name}.{name}: {inp.problem}")
        v = self.resolve(inp, graph, typ, f"{n.name}.{name}")
        return v if v is not None else (None if dflt is None else C(dflt))

    def _str(self, n, name, dflt=""):
        i = n.inputs.get(name)
        return i.value if i is not None and isinstance(i.value, str) and i.value else dflt

    def _node_value(self, n, g, output, where):
        c = n.category
        b = self.b
        typ = n.type
        n3 = 3 if typ in _N3 else 1
        z = (0.0, 0.0, 0.0) if n3 == 3 else 0.0
        one = (1.0, 1.0, 1.0) if n3 == 3 else 1.0
        if c == "constant":
            return self._in(n, g, "value", typ, z)
        if c in ("image", "tiledimage"):
            return self.image(n, g, c)
        if c in ("gltf_image", "gltf_colorimage", "gltf_normalmap"):
            return self.gltf_image(n, g, output)
        if c in ("UsdUVTexture", "UsdUvTexture"):  # 1.38 files spell it UsdUvTexture
            return self.usd_texture(n, g, output)
        if c in ("texcoord", "UsdPrimvarReader"):
            return self.uv(n, g)
        if c == "UsdTransform2d":
            return self.mapping(self._in(n, g, "in", "vector2", None), self._in(n, g, "scale", "vector2", (1, 1)),
                                self._in(n, g, "rotation", "float", 0.0), self._in(n, g, "translation", "vector2", (0, 0)),
                                f"{n.name}")
        if c == "place2d":
            off = self._in(n, g, "offset", "vector2", (0, 0))
            piv = self._in(n, g, "pivot", "vector2", (0, 0))
            if not (piv.is_const and _t3(piv.const)[:2] == (0.0, 0.0)):
                self.notes.lose(f"{n.name}: place2d pivot is not imported (the Mapping turns about the origin)")
            return self.mapping(self._in(n, g, "texcoord", "vector2", None), self._in(n, g, "scale", "vector2", (1, 1)),
                                self._in(n, g, "rotate", "float", 0.0),
                                b.affine(off, -1.0, 0.0) if off is not None else None, n.name)
        if c in ("add", "subtract", "multiply", "divide", "min", "max", "power", "modulo"):
            a = self._in(n, g, "in1", typ, z)
            d2 = one if c in ("multiply", "divide", "power") else z
            t2 = n.inputs.get("in2").type if n.inputs.get("in2") is not None else typ
            bb = self._in(n, g, "in2", t2 or typ, d2)
            if c == "modulo":
                self.notes.lose(f"{n.name}: modulo is not imported (its first input is used)")
                return a
            return {"add": b.add, "subtract": b.sub, "multiply": b.mul, "divide": b.div,
                    "min": b.minimum, "max": b.maximum, "power": b.pow}[c](a, bb)
        if c == "invert":
            return b.sub(self._in(n, g, "amount", typ, one), self._in(n, g, "in", typ, z))
        if c == "sqrt":
            return b.sqrt(self._in(n, g, "in", typ, z))
        if c == "absval":
            a = self._in(n, g, "in", typ, z)
            return Val(a.n, _map(abs, a.const)) if a.is_const else b._node_op("ABSOLUTE", a)
        if c == "clamp":
            lo = self._in(n, g, "low", "float", 0.0)
            hi = self._in(n, g, "high", "float", 1.0)
            a = self._in(n, g, "in", typ, z)
            if lo.is_const and hi.is_const:
                return b.clamp(a, _t3(lo.const)[0], _t3(hi.const)[0])
            return b.minimum(b.maximum(a, lo), hi)
        if c == "mix":
            return b.mix(self._in(n, g, "mix", "float", 0.0), self._in(n, g, "bg", typ, z),
                         self._in(n, g, "fg", typ, z))
        if c in ("dot", "convert"):
            src = self._in(n, g, "in", typ, None)
            if src is None:
                return C(z)
            return b.as3(src) if n3 == 3 else b.channel(src, 0) if src.n == 3 and c == "convert" else src
        if c == "extract":
            idx = self._in(n, g, "index", "integer", 0)
            v = self._in(n, g, "in", "color4", (0, 0, 0))
            return b.channel(v, int(_t3(idx.const)[0]) if idx.is_const else 0)
        if c in ("separate2", "separate3", "separate4"):
            v = self._in(n, g, "in", "vector3", (0, 0, 0))
            return b.channel(v, _ORDER.get((output or "outx")[-1], 0))
        if c == "swizzle":  # 1.38
            v = self._in(n, g, "in", "vector3", (0, 0, 0))
            ch = self._str(n, "channels", "xyz")
            return self._swizzle(v, ch, n.name)
        if c in ("combine2", "combine3", "combine4"):
            parts = [self._in(n, g, f"in{i}", "float", 0.0) for i in (1, 2, 3)]
            if c == "combine2":
                parts[2] = C(0.0)
            return b.combine(*parts)
        if c == "normalmap":
            return self.normal_map(self._in(n, g, "in", "vector3", (0.5, 0.5, 1.0)),
                                   self._in(n, g, "scale", "float", 1.0), n.name)
        if c in ("normalize",):
            return self._in(n, g, "in", typ, z)
        self.notes.lose(f"{where} is fed by a {c} node, which is not imported: the default is used")
        return None

    # -- textures ------------------------------------------------------------------------------
    def _file(self, n, g):
        f = self._str(n, "file")
        if not f:
            return None
        prefix = n.attrs.get("fileprefix") or (g.attrs.get("fileprefix") if g is not None else None) \
            or self.doc.attrs.get("fileprefix") or ""
        path = prefix + f
        if not os.path.isabs(path):
            path = os.path.join(self.directory, path)
        return os.path.normpath(path)

    def _colorspace(self, n, g, data):
        if data:
            return "Non-Color"
        i = n.inputs.get("file")
        cs = (i.colorspace if i is not None else None) or n.attrs.get("colorspace") or (
            g.attrs.get("colorspace") if g is not None else None) or self.doc.attrs.get("colorspace")
        if not cs:
            return "Linear Rec.709"  # MaterialX: no colour space = the working space, untouched
        got = COLORSPACES.get(cs)
        if got is None:
            self.notes.say(f"{n.name}: colour space {cs!r} has no Blender equivalent here: sRGB")
            return "sRGB"
        return got

    def _tex_node(self, n, g, data, uv, u_mode="periodic", v_mode="periodic", filt="linear"):
        path = self._file(n, g)
        if path is None:
            return None
        if u_mode != v_mode:
            self.notes.say(f"{n.name}: address modes {u_mode}/{v_mode} differ: {u_mode} is used")
        inputs = {}
        if uv is not None:
            inputs["Vector"] = self.b.socket(uv, 3)
        key = self.b.node("ShaderNodeTexImage", {"interpolation": _FILTER.get(filt, "Linear"),
                                                "extension": _ADDRESS.get(u_mode, "REPEAT")},
                          inputs, label=n.name,
                          image={"path": path, "colorspace": self._colorspace(n, g, data),
                                 "udim": "<UDIM>" in path})
        self.textured.append(n.name)
        return key

    def image(self, n, g, cat):
        typ = n.type
        data = typ not in ("color3", "color4")
        uv = self._in(n, g, "texcoord", "vector2", None)
        if cat == "tiledimage":
            tiling = self._in(n, g, "uvtiling", "vector2", (1.0, 1.0))
            off = self._in(n, g, "uvoffset", "vector2", (0.0, 0.0))
            uv = self.mapping(uv, tiling, C(0.0), self.b.affine(off, -1.0, 0.0), n.name)
        key = self._tex_node(n, g, data, uv, self._str(n, "uaddressmode", "periodic"),
                             self._str(n, "vaddressmode", "periodic"), self._str(n, "filtertype", "linear"))
        if key is None:
            d = self._in(n, g, "default", typ, (0, 0, 0) if typ in _N3 else 0.0)
            self.notes.lose(f"{n.name}: an image node without a file: its default is used")
            return d
        col = Val(3, link=Link(key, "Color"), alpha=Val(1, link=Link(key, "Alpha")))
        if typ in _N3:
            return col
        return self.b.channel(col, 0)  # MaterialX reads a float image's first channel

    def gltf_image(self, n, g, output):
        cat = n.category
        uv = self._in(n, g, "texcoord", "vector2", None)
        sc = self._in(n, g, "scale", "vector2", (1.0, 1.0))
        off = self._in(n, g, "offset", "vector2", (0.0, 0.0))
        rot = self._in(n, g, "rotate", "float", 0.0)
        if not (sc.is_const and off.is_const and rot.is_const and _t3(sc.const)[:2] == (1.0, 1.0)
                and _t3(off.const)[:2] == (0.0, 0.0) and rot.const == 0.0):
            self.notes.lose(f"{n.name}: the glTF texture transform is imported as a Mapping of scale "
                            f"and offset about the origin (glTF turns about (0, 1))")
            uv = self.mapping(uv, sc, C(0.0), off, n.name)
        data = cat == "gltf_normalmap" or n.type not in ("color3", "color4")
        key = self._tex_node(n, g, data, uv, self._str(n, "uaddressmode", "periodic"),
                             self._str(n, "vaddressmode", "periodic"), self._str(n, "filtertype", "linear"))
        if key is None:
            return None
        col = Val(3, link=Link(key, "Color"), alpha=Val(1, link=Link(key, "Alpha")))
        if cat == "gltf_normalmap":
            return self.normal_map(col, C(1.0), n.name)
        if cat == "gltf_colorimage":
            fac = self._in(n, g, "color", "color4", (1.0, 1.0, 1.0))
            if output == "outa":
                return self.b.mul(col.alpha, self.b.channel(fac, 3) if fac.n == 3 else fac)
            return self.b.mul(col, fac)
        fac = self._in(n, g, "factor", n.type, (1.0, 1.0, 1.0) if n.type in _N3 else 1.0)
        val = col if n.type in _N3 else self.b.channel(col, 0)
        return self.b.mul(val, fac)

    def usd_texture(self, n, g, output):
        uv = self._in(n, g, "st", "vector2", None)
        wrap = {"black": "constant", "repeat": "periodic"}
        cs = self._str(n, "sourceColorSpace", "auto")
        out = output or "rgb"
        data = cs == "raw" or (cs != "sRGB" and out in ("r", "g", "b", "a"))
        path = self._file(n, g)
        if path is None:
            fb = self._in(n, g, "fallback", "color4", (0.0, 0.0, 0.0))
            return fb if out in ("rgb", "rgba") else self.b.channel(fb, _ORDER.get(out, 0))
        ws = wrap.get(self._str(n, "wrapS", "periodic"), self._str(n, "wrapS", "periodic"))
        wt = wrap.get(self._str(n, "wrapT", "periodic"), self._str(n, "wrapT", "periodic"))
        saved = n.attrs.get("colorspace")
        if cs == "sRGB":
            n.attrs["colorspace"] = "srgb_texture"
        key = self._tex_node(n, g, data, uv, ws, wt)
        if saved is None:
            n.attrs.pop("colorspace", None)
        scale = self._in(n, g, "scale", "color4", (1.0, 1.0, 1.0))
        bias = self._in(n, g, "bias", "color4", (0.0, 0.0, 0.0))
        col = Val(3, link=Link(key, "Color"), alpha=Val(1, link=Link(key, "Alpha")))
        if not (scale.is_const and bias.is_const):
            self.notes.lose(f"{n.name}: a linked scale / bias is not imported")
            scale, bias = C((1.0, 1.0, 1.0)), C((0.0, 0.0, 0.0))
        if out in ("rgb", "rgba"):
            return self.b.affine(col, _t3(scale.const), _t3(bias.const))
        i = _ORDER.get(out, 0)
        ch = self.b.channel(col, i)
        s = _t3(scale.const)[min(i, 2)] if i < 3 else 1.0
        o = _t3(bias.const)[min(i, 2)] if i < 3 else 0.0
        return self.b.affine(ch, s, o)

    def uv(self, n, g):
        idx = self._in(n, g, "index", "integer", 0)
        var = self._str(n, "varname", "")
        if idx.is_const and idx.const not in (0, 0.0):
            self.notes.lose(f"{n.name}: UV set {int(idx.const)} is read as the first UV map")
        key = self.b.node("ShaderNodeUVMap", {"uv_map": var if var not in ("st", "UV0") else ""})
        return Val(3, link=Link(key, "UV"))

    def mapping(self, uv, scale, rotate, location, name):
        """A Mapping (Point) of ``uv`` (None: the first UV map): scale, rotation about Z (degrees,
        counter-clockwise), then location."""
        s = _t3(scale.const) if scale is not None and scale.is_const else (1.0, 1.0, 1.0)
        rot = float(_t3(rotate.const)[0]) if rotate is not None and rotate.is_const else 0.0
        loc = _t3(location.const) if location is not None and location.is_const else (0.0, 0.0, 0.0)
        if any(x is not None and not x.is_const for x in (scale, rotate, location)):
            self.notes.lose(f"{name}: a linked texture transform is not imported")
        if s[:2] == (1.0, 1.0) and rot == 0.0 and loc[:2] == (0.0, 0.0):
            return uv
        if uv is None:
            uv = Val(3, link=Link(self.b.node("ShaderNodeUVMap", {"uv_map": ""}), "UV"))
        key = self.b.node("ShaderNodeMapping", {"vector_type": "POINT"},
                          {"Vector": self.b.socket(uv, 3), "Location": (loc[0], loc[1], 0.0),
                           "Rotation": (0.0, 0.0, math.radians(rot)), "Scale": (s[0], s[1], 1.0)})
        return Val(3, link=Link(key, "Vector"))

    def normal_map(self, v, scale, name):
        """A tangent-space Normal Map of an encoded normal (0-1 per channel, MaterialX's
        normalmap input)."""
        if v.is_const:
            return None  # a constant normal map is the geometric normal when it is (0.5, 0.5, 1)
        st = scale.const if scale.is_const else 1.0
        if not scale.is_const or _t3(st)[0] != 1.0:
            self.notes.lose(f"{name}: normal map scale {st} read as the Normal Map's Strength "
                            f"(MaterialX scales the tangent-space xy, Blender blends the normal)")
        key = self.b.node("ShaderNodeNormalMap", {"space": "TANGENT"},
                          {"Color": self.b.socket(v, 3), "Strength": _t3(st)[0]})
        return Val(3, link=Link(key, "Normal"))

    # -- the tangent ---------------------------------------------------------------------------
    def tangent(self, node, graph, name):
        """(rotation in turns, tangent kind, recognised) of a tangent input: a UV tangent (also
        the default Tworld), a radial one (normalize(transformvector(cross(axis, position)))),
        turned by rotate3d nodes (MaterialX turns clockwise: Cycles' rotation is -amount/360)."""
        return tangent_of(self.doc, node.inputs.get(name), graph)


def tangent_of(doc, inp, graph):
    """(turns, "UV_MAP" | "RADIAL_X/Y/Z", recognised) of a tangent input (docs/interchange.md
    §1: the export's tangent graphs)."""
    kind, n, g = doc.resolve(inp, graph)
    turns = 0.0
    for _ in range(16):
        if kind == "value":
            return turns, "UV_MAP", n is None or n == "Tworld"
        if n.category == "tangent":
            return turns, "UV_MAP", True
        if n.category == "normalize":
            kind, n, g = doc.resolve(n.inputs.get("in"), g)
            continue
        if n.category == "rotate3d":
            k2, amt, _ = doc.resolve(n.inputs.get("amount"), g)
            if k2 != "value":
                return turns, "UV_MAP", False
            turns += -float(amt if amt is not None else 0.0) / 360.0
            kind, n, g = doc.resolve(n.inputs.get("in"), g)
            continue
        if n.category == "transformvector":
            k2, cr, g2 = doc.resolve(n.inputs.get("in"), g)
            if k2 == "node" and cr.category == "crossproduct":
                k3, ax, _ = doc.resolve(cr.inputs.get("in1"), g2)
                for i, a in enumerate("XYZ"):
                    if k3 == "value" and ax is not None and tuple(ax) == tuple(
                            1.0 if j == i else 0.0 for j in range(3)):
                        return turns, f"RADIAL_{a}", True
            return turns, "UV_MAP", False
        return turns, "UV_MAP", False
    return turns, "UV_MAP", False


# --------------------------------------------------------------------------------------------
# Conventions (constants; the node forms use the Builder)
# --------------------------------------------------------------------------------------------


def openpbr_principled_alpha(r, a):
    """(Roughness R, Anisotropic A) of Cycles' Principled that renders OpenPBR's (α_t, α_b) for
    roughness r, anisotropy a: α_t = r² √(2/(1+(1-a)²)), α_b = (1-a) α_t; Cycles α_x = R²/s,
    α_y = R² s, s = √(1-0.9A), so A = a/0.9 and R⁴ = α_t α_b = r⁴ 2(1-a)/(1+(1-a)²).
    Exact for a ≤ 0.9 (Cycles' aspect ≤ 10) and α ≤ 1; returns (R, A, exact)."""
    r = min(max(float(r), 0.0), 1.0)
    a = min(max(float(a), 0.0), 1.0)
    q = 2.0 * (1.0 - a) / (1.0 + (1.0 - a) ** 2)
    rough = r * q ** 0.25 if q > 0 else 0.0
    aniso = a / 0.9
    return min(rough, 1.0), min(aniso, 1.0), aniso <= 1.0 + 1e-12


def coat_roughened(r, coat_r, coat_w):
    """OpenPBR's base roughness under a coat (MaterialX 1.39 open_pbr_surface):
    mix(r, min(1, 2 r_c⁴ + r⁴)^¼, coat_weight)."""
    w = min(max(coat_w, 0.0), 1.0)
    return (1.0 - w) * r + w * min(1.0, 2.0 * coat_r ** 4 + r ** 4) ** 0.25


def coat_relative_ior(eta, eta_c, coat_w):
    """OpenPBR's base IOR under a coat: mix(η, max(η/η_c, η_c/η), coat_weight)."""
    w = min(max(coat_w, 0.0), 1.0)
    if eta <= 0.0 or eta_c <= 0.0:
        return eta
    ratio = eta / eta_c
    return (1.0 - w) * eta + w * (ratio if ratio > 1.0 else 1.0 / ratio)


_ERR_MU = tuple(i / 8.0 for i in range(1, 9))


def f82_tint_of_conductor(f0, edge):
    """Principled's F82 tint (Specular Tint of a metal) for Gulbrandsen's conductor with
    reflectivity ``f0`` and edge colour ``edge`` (standard_surface's metal): the tint that makes
    F82-tint match the conductor's Fresnel at μ̄ = 1/7 (as engines.f82_tint_fit), per channel,
    and the largest |ΔF| over μ (8 samples) between the two models.  Python floats: it runs
    for every metal of a library."""
    tint, err = [], 0.0
    for r, g in zip(f0, edge):
        r = min(max(float(r), 0.0), 0.999)
        eta, kap = (float(x) for x in gulbrandsen_ior(r, min(max(float(g), 0.0), 1.0)))
        schlick = lambda mu: r + (1.0 - r) * (1.0 - mu) ** 5  # noqa: E731
        t = min(max(fresnel_conductor_at(K.F82_MU, eta, kap) / schlick(K.F82_MU), 0.0), 1.0)
        b = schlick(K.F82_MU) * (1.0 - t) / (K.F82_MU * (1.0 - K.F82_MU) ** 6)  # brdf.f82_tint's
        for mu in _ERR_MU:
            err = max(err, abs(fresnel_conductor_at(mu, eta, kap) - (schlick(mu) - b * mu * (1.0 - mu) ** 6)))
        tint.append(t)
    return tuple(tint), err


# --------------------------------------------------------------------------------------------
# The surfaces
# --------------------------------------------------------------------------------------------


_VECTOR_SOCKETS = frozenset(("Base Color", "Specular Tint", "Subsurface Radius", "Sheen Tint",
                             "Coat Tint", "Emission Color", "Color", "Edge Tint", "IOR3"))
#: Inputs of earlier drafts that files still carry (MaterialX's own OpenPBR examples), read as
#: the released names.
ALIASES = {"open_pbr_surface": {"specular_anisotropy": "specular_roughness_anisotropy",
                                "coat_anisotropy": "coat_roughness_anisotropy"}}


class _Surface:
    """One surface node being mapped: its inputs as Vals, the Principled's sockets."""

    __slots__ = ("node", "graph", "notes", "b", "up", "spec_in", "_memo", "out", "_inputs",
                 "_defaults")

    def __init__(self, doc, node, graph, name, notes):
        for old, new in ALIASES.get(node.category, {}).items():
            if old in node.inputs and new not in node.inputs:
                node.inputs[new] = node.inputs.pop(old)
                notes.say(f"{node.name}.{old} (an earlier draft's name) read as {new}")
        self.node = node
        self.graph = graph
        self.notes = notes
        self.b = Builder()
        self.up = Upstream(doc, self.b, notes, name)
        self.spec_in = surface_defaults(node)
        self._memo = {}
        self.out = {}
        self._inputs = node.inputs
        self._defaults = _defaults_of(self.spec_in)
        spec_in = self.spec_in
        for k in node.inputs:
            if k not in spec_in and not (node.category == "open_pbr_surface" and k == "specular_rotation"):
                notes.say(f"{node.name}.{k} is not an input of {node.category}: ignored")

    def v(self, name):
        got = self._memo.get(name)
        if got is None:
            inp = self._inputs.get(name)
            if inp is None:  # the common case: the nodedef's default
                got = self._defaults[name] if name in self._defaults else _default_val(self.spec_in, name)
            elif (inp.value is not None and inp.problem is None and inp.nodename is None
                  and inp.nodegraph is None and inp.interfacename is None and inp.channels is None
                  and inp.type == self.spec_in.get(name, ("",))[0]):  # a plain authored value
                x = inp.value
                got = Val(3, x) if type(x) is tuple and len(x) == 3 else C(x)
            else:
                got = self.up.input(self.node, self.graph, name, self.spec_in)
            self._memo[name] = got
        return got

    def set(self, socket, val, n=None):
        if val is None:
            return
        if val.link is None and (n is None or n == val.n):  # a constant as it is
            c = val.const
            self.out[socket] = c if val.n == 1 or isinstance(c, tuple) else (c, c, c)
            return
        self.out[socket] = self.b.socket(val, n)

    def copy(self, rows):
        """Inputs that are the Principled's sockets as they are: (socket, input) pairs; colour
        and vector sockets take three components."""
        for socket, name in rows:
            self.set(socket, self.v(name), 3 if socket in _VECTOR_SOCKETS else 1)

    def const(self, name):
        """A constant input's value (float or tuple), or None when it is linked."""
        x = self.v(name)
        return None if x is None or not x.is_const else x.const

    def is_default(self, name, dflt=None):
        if name not in self.node.inputs:
            return True
        v = self.v(name)
        if v is None:
            return True
        d = self.spec_in.get(name, ("", dflt))[1] if dflt is None else dflt
        return v.is_const and (_t3(v.const) == _t3(d) if isinstance(d, (tuple, float, int)) else True)

    def unsupported(self, names, what):
        for name in names:
            if name in self.spec_in and not self.is_default(name):
                self.notes.lose(f"{self.node.name}.{name} is not imported ({what})")

    def normals(self, pairs):
        for mx_name, socket in pairs:
            v = self.v(mx_name)
            if v is not None and not v.is_const:
                self.set(socket, v, 3)

    def tangent(self, name, rotation):
        """Tangent and rotation: a turn from rotate3d nodes is added to ``rotation`` (a Val)."""
        turns, kind, ok = self.up.tangent(self.node, self.graph, name)
        if not ok:
            self.notes.lose(f"{self.node.name}.{name}: tangent not recognised: the UV tangent is used")
        if kind.startswith("RADIAL"):
            self.notes.say(f"{self.node.name}.{name}: a radial tangent about {kind[-1]}: Cycles' default "
                           f"radial tangent is about Z through the bounding-box centre")
        key = self.b.node("ShaderNodeTangent", {"direction_type": "UV_MAP" if kind == "UV_MAP" else "RADIAL",
                                                "axis": kind[-1] if kind != "UV_MAP" else "Z"})
        self.out["Tangent"] = Link(key, "Tangent")
        return self.b.add(rotation, C(turns)) if turns else rotation

    def finish(self, source, distribution):
        spec = SurfaceSpec(self.up.name, source, dict(self.out), {"distribution": distribution},
                           self.b.nodes, notes=self.notes)
        return spec


def _opbr_anisotropy_nodes(s, r, a):
    """(R, A) Vals of openpbr_principled_alpha for linked inputs."""
    b = s.b
    ac = b.clamp(a)
    oma = b.sub(C(1.0), ac)
    q = b.div(b.mul(C(2.0), oma), b.add(C(1.0), b.mul(oma, oma)))
    rough = b.mul(r, b.pow(q, C(0.25)))
    return b.clamp(rough), b.clamp(b.mul(ac, C(1.0 / 0.9)))


def _base_colour(s, base, mixes):
    """Principled's Base Color: ``base``, mixed towards each (weight, colour) where the part
    they tint takes over (exact at weights 0 and 1; Blender's own versioning merged
    Subsurface Color the same way)."""
    b = s.b
    out = base
    for wname, cname, what in mixes:
        w, col = s.v(wname), s.v(cname)
        if w.is_const and w.const == 0.0:
            continue
        if not (col.is_const and out.is_const and _t3(col.const) == _t3(out.const)):
            if not (w.is_const and w.const in (1.0,)):
                s.notes.lose(f"{cname} differs from the base colour: the Principled has one colour for "
                             f"its diffuse and its {what} (mixed by {wname}; exact at 0 and 1)")
        out = b.mix(w, out, col)
    return out


def apply_owned(s, owned):
    """The inputs a haze layer owns, as the user set them (layered documents: the record's
    values, or the MaterialX node of the user's link)."""
    for socket, b in (owned or {}).items():
        if "value" in b:
            v = b["value"]
            s.out[socket] = tuple(float(x) for x in v[:3]) if isinstance(v, (list, tuple)) else float(v)
        elif "node" in b:
            scope = s.graph.nodes if s.graph is not None else s.up.doc.nodes
            n = scope.get(b["node"])
            v = s.up.node_value(n, s.graph, b.get("output"), socket) if n is not None else None
            if v is None:
                s.notes.lose(f"the user's link into {socket} is not in the document: the layer's value is kept")
            else:
                s.set(socket, v)


def _set_base(s, weight, subsurface, transmission, metalness, diffuse_roughness):
    """The base layer OpenPBR and standard_surface share, by their input names: Base Color
    (base_color times ``weight``, with the ``subsurface`` and ``transmission`` (weight, colour,
    name) tints), Metallic and Diffuse Roughness.  Returns the base colour and the metalness."""
    base = s.b.mul(s.v("base_color"), s.v(weight))
    s.set("Base Color", _base_colour(s, base, (subsurface, transmission)), 3)
    metal = s.v(metalness)
    s.set("Metallic", metal, 1)
    s.set("Diffuse Roughness", s.v(diffuse_roughness), 1)
    return base, metal


def openpbr(doc, node, graph, name, notes, owned=None):
    """open_pbr_surface (1.1.1; 1.2 draft: specular_haze, emission_weight).  ``owned``: the
    record of a layered document (the user's values of the inputs the layer owns)."""
    s = _Surface(doc, node, graph, name, notes)
    b = s.b
    v = s.v
    version = str(node.attrs.get("version", "1.1"))
    _, metal = _set_base(s, "base_weight", ("subsurface_weight", "subsurface_color", "subsurface"),
                        ("transmission_weight", "transmission_color", "transmission"),
                        "base_metalness", "base_diffuse_roughness")
    spec_w = v("specular_weight")
    s.set("Specular IOR Level", b.mul(spec_w, C(0.5)), 1)
    if not (spec_w.is_const and spec_w.const == 1.0) and not (metal.is_const and metal.const == 0.0):
        notes.lose("specular_weight also scales OpenPBR's metal; Principled's Specular IOR Level does not")
    s.set("Specular Tint", v("specular_color"), 3)
    cw, cr, cior = v("coat_weight"), v("coat_roughness"), v("coat_ior")
    coated = not (cw.is_const and cw.const == 0.0)
    r, a = v("specular_roughness"), v("specular_roughness_anisotropy")
    if coated:  # OpenPBR roughens the base under the coat; Cycles does not: give Cycles that
        if r.is_const and cr.is_const and cw.is_const:
            r = C(coat_roughened(r.const, cr.const, cw.const))
        else:
            c4 = b.mul(C(2.0), b.pow(b.mul(cr, cr), C(2.0)))
            rough4 = b.pow(b.mul(r, r), C(2.0))
            r = b.mix(b.clamp(cw), r, b.pow(b.minimum(b.add(c4, rough4), C(1.0)), C(0.25)))
    if r.is_const and a.is_const:
        rough, aniso, ok = openpbr_principled_alpha(r.const, a.const)
        if not ok:
            notes.lose(f"specular_roughness_anisotropy {a.const:g} is beyond Cycles' aspect 10: "
                       f"Anisotropic 1")
        s.set("Roughness", C(rough))
        s.set("Anisotropic", C(aniso))
    else:
        rough, aniso = _opbr_anisotropy_nodes(s, r, a)
        s.set("Roughness", rough)
        s.set("Anisotropic", aniso)
    eta = v("specular_ior")
    if coated:  # OpenPBR's base sees η/η_c under the coat (Cycles: the Principled IOR)
        if eta.is_const and cior.is_const and cw.is_const:
            eta = C(coat_relative_ior(eta.const, cior.const, cw.const))
            if abs(eta.const - 1.0) < 0.01:
                notes.say(f"under the coat OpenPBR's base has the IOR relative to the coat's: "
                          f"{eta.const:.4g} (the base barely reflects)")
        else:
            eta = b.mix(b.clamp(cw), eta, b.div(eta, cior))
            notes.lose("linked coat or IOR: OpenPBR's coat-relative IOR is taken as η/η_c")
        if not (v("coat_darkening").is_const and v("coat_darkening").const == 0.0):
            notes.lose("coat_darkening: OpenPBR darkens the base under the coat, Cycles does not")
    s.set("IOR", eta, 1)
    s.copy((("Transmission Weight", "transmission_weight"),
            ("Transmission Dispersion Scale", "transmission_dispersion_scale"),
            ("Transmission Dispersion Abbe Number", "transmission_dispersion_abbe_number"),
            ("Subsurface Weight", "subsurface_weight"), ("Subsurface Radius", "subsurface_radius_scale"),
            ("Subsurface Scale", "subsurface_radius"), ("Subsurface Anisotropy", "subsurface_scatter_anisotropy"),
            ("Sheen Weight", "fuzz_weight"), ("Sheen Tint", "fuzz_color"), ("Sheen Roughness", "fuzz_roughness"),
            ("Coat Weight", "coat_weight"), ("Coat Tint", "coat_color"), ("Coat Roughness", "coat_roughness"),
            ("Coat IOR", "coat_ior")))
    s.unsupported(("transmission_depth", "transmission_scatter", "transmission_scatter_anisotropy"),
                  "the Principled BSDF has no interior medium")
    s.unsupported(("coat_roughness_anisotropy",), "the Principled coat is isotropic")
    tfw, tft = v("thin_film_weight"), v("thin_film_thickness")
    thick = b.mul(tft, C(1000.0))  # μm -> nm
    if tfw.is_const:
        if tfw.const == 0.0:
            thick = C(0.0)
        elif tfw.const != 1.0:
            notes.lose(f"thin_film_weight {tfw.const:g}: the film is imported at full weight")
    else:
        notes.lose("a linked thin_film_weight: the film is imported where the weight is above 0")
        thick = b.mul(thick, b.greater(tfw, C(0.0)))
    s.set("Thin Film Thickness", thick, 1)
    s.set("Thin Film IOR", v("thin_film_ior"), 1)
    lum = v("emission_luminance")
    if version.startswith("1.2"):
        lum = b.mul(lum, v("emission_weight"))
    s.set("Emission Color", v("emission_color"), 3)
    s.set("Emission Strength", lum, 1)
    s.set("Alpha", v("geometry_opacity"), 1)
    if not s.is_default("geometry_thin_walled", False):
        s.set("Thin Wall", v("geometry_thin_walled"), 1)
    s.normals((("geometry_normal", "Normal"), ("geometry_coat_normal", "Coat Normal")))
    rot = C(0.0)
    old_rot = node.inputs.get("specular_rotation")  # an earlier draft's: turns, as standard_surface
    if old_rot is not None and isinstance(old_rot.value, float):
        rot = C(-old_rot.value)
        notes.say(f"{node.name}.specular_rotation (an earlier draft's input) read as a turn of the tangent")
    aniso_on = not (a.is_const and a.const == 0.0)
    if aniso_on:
        rot = s.tangent("geometry_tangent", rot)
        s.set("Anisotropic Rotation", b.affine(rot, 1.0, 0.0), 1)
    apply_owned(s, owned)
    spec = s.finish(f"open_pbr_surface {version}", SURFACES["open_pbr_surface"])
    if version.startswith("1.2") or "specular_haze" in node.inputs:
        _openpbr_haze(s, spec, r, a, coated)
    return spec


def _openpbr_haze(s, spec, r_eff, a, coated):
    """specular_haze > 0: the target blend (β, α_n, α_w) for the haze layer (haze_blend)."""
    v = s.v
    haze = v("specular_haze")
    if haze.is_const and haze.const == 0.0:
        return
    spread = v("specular_haze_spread")
    if not (haze.is_const and spread.is_const and r_eff.is_const and a.is_const):
        s.notes.lose("a linked specular_haze / spread or roughness: the haze is not imported")
        return
    r0 = v("specular_roughness").const
    r_haze = r0 + (1.0 - r0) * min(max(spread.const, 0.0), 1.0)  # lerp(r_core, 1, spread)
    if coated:  # 1.2's reference graph roughens the haze under the coat as the core
        cw, cr = v("coat_weight").const, v("coat_roughness").const
        if cw is None or cr is None:
            s.notes.lose("a linked coat: the haze is not imported")
            return
        r_haze = coat_roughened(r_haze, cr, cw)
    rn, an_, _ = openpbr_principled_alpha(r_eff.const, a.const)
    rw, aw_, _ = openpbr_principled_alpha(r_haze, a.const)
    spec.haze_target = dict(beta=min(max(float(haze.const), 0.0), 1.0), roughness=rn, anisotropy=an_,
                            roughness_wide=rw, anisotropy_wide=aw_)


def standard_surface(doc, node, graph, name, notes):
    """standard_surface 1.0.1 (1.0.0 with version="1.0.0")."""
    s = _Surface(doc, node, graph, name, notes)
    b = s.b
    v = s.v
    base, metal = _set_base(s, "base", ("subsurface", "subsurface_color", "subsurface"),
                            ("transmission", "transmission_color", "transmission"),
                            "metalness", "diffuse_roughness")
    s.set("Specular IOR Level", b.mul(v("specular"), C(0.5)), 1)
    spec_c = v("specular_color")
    if metal.is_const and metal.const >= 1.0 and base.is_const and spec_c.is_const:
        tint, err = f82_tint_of_conductor(_t3(base.const), _t3(spec_c.const))
        s.set("Specular Tint", C(tint))
        notes.lose(f"the Gulbrandsen metal (edge colour specular_color) is Principled's F82 metal with "
                   f"Specular Tint {', '.join(f'{t:.3f}' for t in tint)} (max |ΔF| {err:.3f})")
    else:
        s.set("Specular Tint", spec_c, 3)
        if not (metal.is_const and metal.const == 0.0) and not (spec_c.is_const and _t3(spec_c.const) == (1.0, 1.0, 1.0)):
            notes.lose("specular_color is the metal's edge colour in standard_surface and its F82 tint "
                       "in the Principled: read as the tint")
    # roughness: MaterialX's graph, coat_affect_roughness first, then roughness_anisotropy
    r = v("specular_roughness")
    car = b.mul(b.mul(v("coat_affect_roughness"), v("coat")), v("coat_roughness"))
    r = b.mix(car, r, C(1.0))
    a = v("specular_anisotropy")
    if a.is_const:
        if a.const > 0.9:
            notes.lose(f"specular_anisotropy {a.const:g} is beyond Cycles' aspect 10: Anisotropic 1")
        s.set("Anisotropic", C(min(max(a.const, 0.0) / 0.9, 1.0)))
    else:
        s.set("Anisotropic", b.clamp(b.mul(a, C(1.0 / 0.9))))
    s.set("Roughness", r, 1)
    s.copy((("IOR", "specular_IOR"), ("Transmission Weight", "transmission"),
            ("Subsurface Weight", "subsurface"), ("Subsurface Radius", "subsurface_radius"),
            ("Subsurface Scale", "subsurface_scale"), ("Subsurface Anisotropy", "subsurface_anisotropy"),
            ("Sheen Weight", "sheen"), ("Sheen Tint", "sheen_color"), ("Coat Weight", "coat"),
            ("Coat Tint", "coat_color"), ("Coat Roughness", "coat_roughness"), ("Coat IOR", "coat_IOR"),
            ("Thin Film Thickness", "thin_film_thickness"), ("Thin Film IOR", "thin_film_IOR"),
            ("Emission Color", "emission_color"), ("Emission Strength", "emission")))
    s.unsupported(("transmission_depth", "transmission_scatter", "transmission_scatter_anisotropy",
                   "transmission_dispersion", "transmission_extra_roughness"),
                  "the Principled BSDF's transmission has no medium of its own")
    # MaterialX's standard_surface_to_open_pbr: fuzz_roughness = sheen_roughness^0.4 (by eye)
    s.set("Sheen Roughness", b.pow(v("sheen_roughness"), C(0.4)), 1)
    if not s.is_default("sheen"):
        notes.lose("sheen: standard_surface's sheen (Estevez-Kulla) is Cycles' microfiber sheen with "
                   "roughness^0.4 (MaterialX's translation to OpenPBR)")
    s.unsupported(("coat_anisotropy", "coat_rotation", "coat_affect_color"),
                  "the Principled coat is isotropic and does not saturate the base")
    op = v("opacity")
    if op.is_const and len(set(_t3(op.const))) > 1:
        notes.lose("a coloured opacity is imported as its average (Alpha)")
    s.set("Alpha", b.mean(op), 1)
    if not s.is_default("thin_walled", False):
        s.set("Thin Wall", v("thin_walled"), 1)
    s.normals((("normal", "Normal"), ("coat_normal", "Coat Normal")))
    if not (a.is_const and a.const == 0.0):
        rot = s.tangent("tangent", b.affine(v("specular_rotation"), -1.0, 0.0))
        s.set("Anisotropic Rotation", rot, 1)
    return s.finish("standard_surface", SURFACES["standard_surface"])


def gltf_pbr(doc, node, graph, name, notes):
    """gltf_pbr 2.0.1 (MaterialX's glTF PBR: the glTF 2.0 metallic-roughness model and its
    KHR_materials extensions)."""
    s = _Surface(doc, node, graph, name, notes)
    b = s.b
    v = s.v
    s.set("Base Color", v("base_color"), 3)
    metal = v("metallic")
    s.set("Metallic", metal, 1)
    r = v("roughness")
    st = v("anisotropy_strength")
    if st.is_const and st.const == 0.0:
        s.set("Roughness", r, 1)
    elif r.is_const and st.is_const:  # glTF: α_t = mix(α, 1, s²), α_b = α
        alpha = r.const ** 2
        at = alpha + (1.0 - alpha) * min(max(st.const, 0.0), 1.0) ** 2
        ab = alpha
        ratio = ab / at if at > 0 else 1.0
        aniso = (1.0 - ratio) / 0.9
        if aniso > 1.0:
            notes.lose(f"anisotropy_strength {st.const:g}: the aspect {1 / ratio:.3g} is beyond Cycles' 10")
        s.set("Roughness", C(min((at * ab) ** 0.25, 1.0)))
        s.set("Anisotropic", C(min(aniso, 1.0)))
    else:
        s.set("Roughness", r, 1)
        s.set("Anisotropic", st, 1)
        notes.lose("linked glTF anisotropy: strength read as Anisotropic (Blender's glTF importer)")
    if not (st.is_const and st.const == 0.0):
        rot = s.tangent("tangent", b.affine(v("anisotropy_rotation"), 1.0 / (2.0 * math.pi), 0.0))
        s.set("Anisotropic Rotation", rot, 1)
    s.set("IOR", v("ior"), 1)
    spec = v("specular")
    s.set("Specular IOR Level", b.mul(spec, C(0.5)), 1)
    if not (spec.is_const and spec.const == 1.0):
        notes.lose("specular ≠ 1: glTF scales F(90°) too, the Principled only F(0)")
    spec_c = v("specular_color")
    s.set("Specular Tint", spec_c, 3)
    if not (metal.is_const and metal.const == 0.0) and not (spec_c.is_const and _t3(spec_c.const) == (1.0, 1.0, 1.0)):
        notes.lose("specular_color tints glTF's dielectric only; the Principled's Specular Tint also "
                   "tints its metal (F82)")
    s.set("Transmission Weight", v("transmission"), 1)
    mode = s.const("alpha_mode")
    mode = int(mode) if isinstance(mode, (int, float)) else 0
    alpha = v("alpha")
    if mode == 0:
        s.set("Alpha", C(1.0))
    elif mode == 1:
        cut = s.const("alpha_cutoff")
        cut = 0.5 if cut is None else float(cut)
        s.set("Alpha", b.greater(alpha, C(cut - 1e-7)) if not alpha.is_const else
              C(1.0 if alpha.const >= cut else 0.0), 1)
    else:
        s.set("Alpha", alpha, 1)
    s.set("Coat Weight", v("clearcoat"), 1)
    s.set("Coat Roughness", v("clearcoat_roughness"), 1)
    s.set("Coat IOR", C(1.5), 1)  # KHR_materials_clearcoat: a fixed IOR of 1.5
    sheen = v("sheen_color")
    if not (sheen.is_const and _t3(sheen.const) == (0.0, 0.0, 0.0)):
        s.set("Sheen Weight", C(1.0))
        s.set("Sheen Tint", sheen, 3)
        s.set("Sheen Roughness", v("sheen_roughness"), 1)
        notes.lose("sheen: glTF's Charlie sheen is Cycles' microfiber sheen (Blender's glTF importer)")
    s.set("Emission Color", v("emissive"), 3)
    s.set("Emission Strength", v("emissive_strength"), 1)
    irid = v("iridescence")
    if not (irid.is_const and irid.const == 0.0):
        s.set("Thin Film Thickness", b.mul(v("iridescence_thickness"), b.greater(irid, C(0.0))), 1)
        s.set("Thin Film IOR", v("iridescence_ior"), 1)
        if not (irid.is_const and irid.const == 1.0):
            notes.lose("iridescence below 1: the film is imported at full weight")
    s.unsupported(("thickness", "attenuation_color", "dispersion"),
                  "KHR_materials_volume / dispersion: Blender's glTF importer adds a Volume Absorption "
                  "node, not made here")
    occ = v("occlusion")
    if not (occ.is_const and occ.const == 1.0):
        notes.say("occlusion is not imported (path tracers compute it)")
    s.normals((("normal", "Normal"), ("clearcoat_normal", "Coat Normal")))
    spec_out = s.finish("gltf_pbr", SURFACES["gltf_pbr"])
    if mode == 1:
        spec_out.alpha_clip = 0.5 if s.const("alpha_cutoff") is None else float(s.const("alpha_cutoff"))
    return spec_out


def usd_preview_surface(doc, node, graph, name, notes):
    """UsdPreviewSurface 2.6 (metallic and specular workflows)."""
    s = _Surface(doc, node, graph, name, notes)
    b = s.b
    v = s.v
    s.set("Base Color", v("diffuseColor"), 3)
    s.set("Emission Color", v("emissiveColor"), 3)
    s.set("Emission Strength", C(1.0))
    wf = s.const("useSpecularWorkflow")
    ior = v("ior")
    if wf is not None and float(wf) != 0.0:  # specular workflow: F(0) = specularColor, F(90) = 1
        s.set("Metallic", C(0.0))
        sc = v("specularColor")
        if sc.is_const and ior.is_const:
            m = max(_t3(sc.const))
            f0 = ((ior.const - 1.0) / (ior.const + 1.0)) ** 2 if ior.const > 0 else 0.04
            level = m / (2.0 * f0) if f0 > 0 else 0.5
            if level > 1.0:
                notes.lose(f"specularColor {m:.3g} is beyond the Principled's F(0) range at IOR "
                           f"{ior.const:g} (Specular IOR Level at most 1 = 2 F0): capped")
            s.set("Specular IOR Level", C(min(level, 1.0)))
            s.set("Specular Tint", C(tuple(c / m for c in _t3(sc.const)) if m > 0 else (1.0, 1.0, 1.0)))
        else:
            s.set("Specular Tint", sc, 3)
            notes.lose("a linked specularColor is read as the Specular Tint (Blender's USD importer)")
        notes.say("the specular workflow's Schlick Fresnel is the Principled's dielectric Fresnel from "
                  "the same F(0)")
    else:
        s.set("Metallic", v("metallic"), 1)
    s.set("Roughness", v("roughness"), 1)
    s.set("IOR", ior, 1)
    s.set("Coat Weight", v("clearcoat"), 1)
    s.set("Coat Roughness", v("clearcoatRoughness"), 1)
    s.set("Coat IOR", ior, 1)  # the spec: ior applies to the clearcoat
    op = v("opacity")
    thr = s.const("opacityThreshold")
    thr = 0.0 if thr is None else float(thr)
    alpha_clip = None
    if thr > 0.0:
        alpha_clip = thr
        op = b.greater(op, C(thr - 1e-7)) if not op.is_const else C(1.0 if op.const >= thr else 0.0)
    s.set("Alpha", op, 1)
    nrm = v("normal")
    if nrm is not None and not nrm.is_const:  # tangent-space, [-1, 1]: the Normal Map's 0-1 colour
        enc = b.affine(nrm, 0.5, 0.5)
        key = b.node("ShaderNodeNormalMap", {"space": "TANGENT"}, {"Color": b.socket(enc, 3), "Strength": 1.0})
        s.out["Normal"] = Link(key, "Normal")
    disp = v("displacement")
    if not (disp.is_const and disp.const == 0.0):
        notes.lose("displacement is not imported")
    occ = v("occlusion")
    if not (occ.is_const and occ.const == 1.0):
        notes.say("occlusion is not imported (path tracers compute it)")
    out = s.finish("UsdPreviewSurface", SURFACES["UsdPreviewSurface"])
    out.alpha_clip = alpha_clip
    return out


def bsdf_core(doc, node, graph, name, notes, core_type, owned=None):
    """The core of a layered document that is not a Principled: a conductor_bsdf (Metallic,
    Physical Conductor), generalized_schlick_bsdf with color82 = Edge Tint (Metallic F82) or
    with color0 = color90 (Glossy), as interchange/layered.py writes them; roughness is the α
    Cycles renders."""
    s = _Surface(doc, node, graph, name, notes)
    s.spec_in = _DEFAULTS.get((node.category, "BSDF"), {})
    s._defaults = _defaults_of(s.spec_in)
    v = s.v
    alpha = v("roughness")
    ax, ay = (_t3(alpha.const)[:2] if alpha is not None and alpha.is_const else (0.01, 0.01))
    if alpha is not None and not alpha.is_const:
        notes.lose("a linked roughness of the core is imported at its default")
    rough = math.sqrt(math.sqrt(max(ax, 0.0)) * math.sqrt(max(ay, 0.0)))
    s.set("Roughness", C(min(rough, 1.0)))
    glossy = core_type == "GLOSSY"
    if glossy:  # Glossy: a >= 0 makes y the long axis (α_x = R²(1-a), α_y = R²/(1-a))
        ratio = math.sqrt(min(ax, ay) / max(ax, ay)) if max(ax, ay) > 0 else 1.0
        aniso = (1.0 - ratio) if ay >= ax else -(1.0 - ratio)
        s.set("Anisotropy", C(aniso))
        s.set("Color", v("color0"), 3)
        bsdf = "ShaderNodeBsdfGlossy"
    else:
        ratio = min(ax, ay) / max(ax, ay) if max(ax, ay) > 0 else 1.0
        s.set("Anisotropy", C(min((1.0 - ratio) / 0.9, 1.0)))
        bsdf = "ShaderNodeBsdfMetallic"
        if node.category == "conductor_bsdf":
            s.set("IOR", v("ior"), 3)
            s.set("Extinction", v("extinction"), 3)
        else:
            s.set("Base Color", v("color0"), 3)
            s.set("Edge Tint", v("color82"), 3)
    turns, kind, ok = s.up.tangent(node, graph, "tangent")
    rot = turns + (0.25 if not glossy and ay > ax else 0.0)
    if ax != ay:
        s.tangent("tangent", C(0.0))
        s.set("Rotation", C(rot - math.floor(rot)))
    s.normals((("normal", "Normal"),))
    apply_owned(s, owned)
    spec = s.finish(node.category, "GGX")
    spec.bsdf = bsdf
    return spec


_MAPPERS = {"open_pbr_surface": openpbr, "standard_surface": standard_surface, "gltf_pbr": gltf_pbr,
            "UsdPreviewSurface": usd_preview_surface}


def principled_of(doc, node, graph, name, notes=None):
    """SurfaceSpec of one library surface node (``node.category`` in SURFACES)."""
    notes = notes if notes is not None else Notes()
    spec = _MAPPERS[node.category](doc, node, graph, name, notes)
    spec.lossy = notes.lost
    return spec
