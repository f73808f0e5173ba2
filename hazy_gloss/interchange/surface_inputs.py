# SPDX-License-Identifier: GPL-3.0-or-later
"""Reading a MaterialX document for interchange/surfaces.py: a surface node's inputs with their
nodedef defaults, and the nodes upstream of an input (images, math, mix, normal maps,
tangents, ...) as the Blender nodes of a :class:`~.surface_nodes.SurfaceSpec` (:class:`Upstream`).
"""
from __future__ import annotations

import math
import os

from .document import NODEDEFS, OPENPBR_12_INPUTS
from .layered_tree import LUMA
from .surface_nodes import C, map_values, triple, Link, Val

__all__ = ("COLORSPACES", "DEFAULTS", "surface_defaults", "defaults_of", "default_val", "Upstream",
           "tangent_of")

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
# Reading a document: inputs with their nodedef defaults, upstream nodes as Blender nodes
# --------------------------------------------------------------------------------------------

#: (category, output type) -> {input: (type, default)} of every nodedef in the table.
DEFAULTS = {}
for _nd, (_cat, _typ, _spec) in NODEDEFS.items():
    DEFAULTS.setdefault((_cat, _typ), _spec)
_BY_CATEGORY = {}
for _nd, (_cat, _typ, _spec) in NODEDEFS.items():
    _BY_CATEGORY.setdefault(_cat, _spec)
_OPENPBR_12 = dict(NODEDEFS["ND_open_pbr_surface_surfaceshader"][2], **OPENPBR_12_INPUTS,
                   emission_weight=("float", 0.0))
_N3 = {"color3": 3, "vector3": 3, "color4": 3, "vector4": 3, "vector2": 3}
_ORDER = {"x": 0, "y": 1, "z": 2, "w": 3, "r": 0, "g": 1, "b": 2, "a": 3}
#: MaterialX unary nodes the export writes for Math nodes -> (Blender operation, its fold);
#: Vector Math has no Exponent, so exp is read for floats only.
_UNARY = {"floor": ("FLOOR", lambda x: float(math.floor(x))), "sin": ("SINE", math.sin),
          "cos": ("COSINE", math.cos), "sign": ("SIGN", lambda x: float((x > 0) - (x < 0))),
          "exp": ("EXPONENT", lambda x: math.exp(x) if x < 709.0 else math.inf)}


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


def defaults_of(spec):
    """{input: its nodedef default as a constant Val} of a spec (shared: constants are not
    changed)."""
    table = _DEFAULT_VALS.get(id(spec))
    if table is None:
        table = _DEFAULT_VALS[id(spec)] = {k: _as_val(d) for k, (_, d) in spec.items()}
    return table


def default_val(spec, name):
    """The nodedef default of an input as a constant Val."""
    table = defaults_of(spec)
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
            return default_val(spec, name)
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
            if not (piv.is_const and triple(piv.const)[:2] == (0.0, 0.0)):
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
            return Val(a.n, map_values(abs, a.const)) if a.is_const else b._node_op("ABSOLUTE", a)
        if c == "clamp":
            lo = self._in(n, g, "low", "float", 0.0)
            hi = self._in(n, g, "high", "float", 1.0)
            a = self._in(n, g, "in", typ, z)
            if lo.is_const and hi.is_const:
                return b.clamp(a, triple(lo.const)[0], triple(hi.const)[0])
            return b.minimum(b.maximum(a, lo), hi)
        if c == "mix":
            return b.mix(self._in(n, g, "mix", "float", 0.0), self._in(n, g, "bg", typ, z),
                         self._in(n, g, "fg", typ, z))
        if c == "dotproduct":  # the export's colour / vector -> float (luma or mean weights)
            return self.dot(self._in(n, g, "in1", "vector3", (0, 0, 0)),
                            self._in(n, g, "in2", "vector3", (0, 0, 0)))
        if c in ("ifgreater", "ifgreatereq"):  # the export's Math comparisons and Ramp segments
            v1 = self._in(n, g, "value1", "float", 1.0)
            v2 = self._in(n, g, "value2", "float", 0.0)
            t = b.greater(v1, v2) if c == "ifgreater" else b.sub(C(1.0), b.greater(v2, v1))
            return b.mix(t, self._in(n, g, "in2", typ, z), self._in(n, g, "in1", typ, z))
        if c in _UNARY and (n3 == 1 or c != "exp"):
            a = self._in(n, g, "in", typ, z)
            op, f = _UNARY[c]
            return Val(a.n, map_values(f, a.const)) if a.is_const else b._node_op(op, a)
        if c in ("dot", "convert"):
            src = self._in(n, g, "in", typ, None)
            if src is None:
                return C(z)
            return b.as3(src) if n3 == 3 else b.channel(src, 0) if src.n == 3 and c == "convert" else src
        if c == "extract":
            idx = self._in(n, g, "index", "integer", 0)
            v = self._in(n, g, "in", "color4", (0, 0, 0))
            return b.channel(v, int(triple(idx.const)[0]) if idx.is_const else 0)
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

    def dot(self, a, w):
        """a · w (MaterialX dotproduct): a Vector Math Dot Product, or one scaled channel when w
        is a constant axis (the export's colour -> float is a dot with constant weights)."""
        b = self.b
        if a.is_const and w.is_const:
            return C(sum(x * y for x, y in zip(triple(a.const), triple(w.const))))
        if a.is_const:
            a, w = w, a
        if w.is_const:
            wt = triple(w.const)
            used = [i for i, x in enumerate(wt) if x != 0.0]
            if not used:
                return C(0.0)
            if a.n == 1:  # a float reads as (f, f, f)
                return b.affine(a, sum(wt), 0.0)
            if len(used) == 1:
                return b.affine(b.channel(a, used[0]), wt[used[0]], 0.0)
            if all(abs(x - y) <= 1e-7 for x, y in zip(wt, LUMA)):
                # the export's colour -> float: back to Blender's own conversion (its luma
                # coefficients, which round LUMA differently), so a round trip is exact
                key = b.node("ShaderNodeRGBToBW", {}, {"Color": b.socket(a, 3)})
                return Val(1, link=Link(key, "Val"))
        key = b.node("ShaderNodeVectorMath", {"operation": "DOT_PRODUCT"},
                     {"Vector": b.socket(a, 3), "Vector_001": b.socket(w, 3)})
        return Val(1, link=Link(key, "Value"))

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
        if not (sc.is_const and off.is_const and rot.is_const and triple(sc.const)[:2] == (1.0, 1.0)
                and triple(off.const)[:2] == (0.0, 0.0) and rot.const == 0.0):
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
            return self.b.affine(col, triple(scale.const), triple(bias.const))
        i = _ORDER.get(out, 0)
        ch = self.b.channel(col, i)
        s = triple(scale.const)[min(i, 2)] if i < 3 else 1.0
        o = triple(bias.const)[min(i, 2)] if i < 3 else 0.0
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
        s = triple(scale.const) if scale is not None and scale.is_const else (1.0, 1.0, 1.0)
        rot = float(triple(rotate.const)[0]) if rotate is not None and rotate.is_const else 0.0
        loc = triple(location.const) if location is not None and location.is_const else (0.0, 0.0, 0.0)
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
        if not scale.is_const or triple(st)[0] != 1.0:
            self.notes.lose(f"{name}: normal map scale {st} read as the Normal Map's Strength "
                            f"(MaterialX scales the tangent-space xy, Blender blends the normal)")
        key = self.b.node("ShaderNodeNormalMap", {"space": "TANGENT"},
                          {"Color": self.b.socket(v, 3), "Strength": triple(st)[0]})
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
