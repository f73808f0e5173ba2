# SPDX-License-Identifier: GPL-3.0-or-later
"""What an imported surface becomes, bpy-free: :class:`SurfaceSpec` (the Principled BSDF's socket
values or :class:`Link` s into :class:`TexNode` s), the values a mapping computes with
(:class:`Val`: constants folded in float64, or links with an affine map folded in) and the
:class:`Builder` that adds the Math / Vector Math / Mix nodes a linked value needs.
interchange/surfaces.py maps the surfaces onto them; blender/model/surface_build.py makes the nodes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ("PRINCIPLED", "Link", "TexNode", "SurfaceSpec", "Notes", "Val", "triple", "map_values",
           "C", "Builder")


PRINCIPLED = "ShaderNodeBsdfPrincipled"


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


def triple(x):
    return x if isinstance(x, tuple) else (x, x, x)


def map_values(f, *xs):
    if len(xs) == 2:  # the common case, without the general machinery
        a, b = xs
        ta, tb = type(a) is tuple, type(b) is tuple
        if not (ta or tb):
            return f(a, b)
        a = a if ta else (a, a, a)
        b = b if tb else (b, b, b)
        return (f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]))
    if any(isinstance(x, tuple) for x in xs):
        cols = [triple(x) for x in xs]
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
        return Val(3, t if len(t) == 3 else triple(t[0] if t else 0.0))
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
                return triple(v.const)
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
                                {"Vector": link, "Vector_001": triple(s), "Vector_002": triple(b)})
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
                       map_values(lambda x, y, z: x * y + z, v.const, s, b))
        n = 3 if v.n == 3 or isinstance(s, tuple) or isinstance(b, tuple) else 1
        s0 = 1.0 if v.scale is None else v.scale
        b0 = 0.0 if v.bias is None else v.bias
        scale = map_values(lambda x, y: x * y, s0, s)
        bias = map_values(lambda x, y, z: x * y + z, b0, s, b)
        if triple(scale) == (1.0, 1.0, 1.0):
            scale = None
        if triple(bias) == (0.0, 0.0, 0.0):
            bias = None
        return Val(n, link=v.link, scale=scale, bias=bias, alpha=v.alpha)

    def add(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), map_values(lambda x, y: x + y, a.const, b.const))
        if b.is_const:
            return self.affine(a, 1.0, b.const)
        if a.is_const:
            return self.affine(b, 1.0, a.const)
        return self._node_op("ADD", a, b)

    def sub(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), map_values(lambda x, y: x - y, a.const, b.const))
        if b.is_const:
            return self.affine(a, 1.0, map_values(lambda x: -x, b.const))
        if a.is_const:
            return self.affine(b, -1.0, a.const)
        return self._node_op("SUBTRACT", a, b)

    def mul(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), map_values(lambda x, y: x * y, a.const, b.const))
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
            return Val(self._n(a, b), map_values(_safe_div, a.const, b.const))
        if b.is_const:
            return self.affine(a, map_values(lambda y: _safe_div(1.0, y), b.const), 0.0)
        return self._node_op("DIVIDE", a, b)

    def pow(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), map_values(_safe_pow, a.const, b.const))
        if b.is_const and not isinstance(b.const, tuple) and b.const == 1.0:
            return a
        return self._node_op("POWER", a, b)

    def sqrt(self, a):
        if a.is_const:
            return Val(a.n, map_values(lambda x: math.sqrt(x) if x > 0 else 0.0, a.const))
        if a.n == 3:
            return self._node_op("POWER", a, C((0.5, 0.5, 0.5)))
        return self._node_op("SQRT", a)

    def minimum(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), map_values(min, a.const, b.const))
        return self._node_op("MINIMUM", a, b)

    def maximum(self, a, b):
        if a.is_const and b.is_const:
            return Val(self._n(a, b), map_values(max, a.const, b.const))
        return self._node_op("MAXIMUM", a, b)

    def clamp(self, a, lo=0.0, hi=1.0):
        if a.is_const:
            return Val(a.n, map_values(lambda x: min(max(x, lo), hi), a.const))
        if a.n == 1:
            key = self.node("ShaderNodeClamp", {"clamp_type": "MINMAX"},
                            {"Value": self.socket(a, 1), "Min": lo, "Max": hi})
            return Val(1, link=Link(key, "Result"))
        return self.minimum(self.maximum(a, C(triple(lo))), C(triple(hi)))

    def mix(self, t, a, b):
        """a + t (b - a): a for t = 0, b for t = 1 (exactly, also when a = b)."""
        if t.is_const and a.is_const and b.is_const:
            tc = t.const if not isinstance(t.const, tuple) else t.const[0]
            return Val(self._n(a, b), map_values(lambda x, y: x + tc * (y - x) if x != y else x, a.const, b.const))
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
            return C(triple(v.const)[i])
        s = None if v.scale is None else triple(v.scale)[i]
        b = None if v.bias is None else triple(v.bias)[i]
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
            return C(sum(triple(v.const)) / 3.0)
        return Val(1, link=self.socket(v, 1))

    def as3(self, v):
        return v if v.n == 3 else (C(triple(v.const)) if v.is_const else self.combine(v, v, v))
