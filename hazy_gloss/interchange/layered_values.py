# SPDX-License-Identifier: GPL-3.0-or-later
"""The value side of a layered export: typed MaterialX values (:class:`V`, a constant or a node
output) and :class:`ValueWriter`, which writes a Blender tree's value nodes (Math, Vector Math,
Mix, Color Ramp, Image Texture, Normal Map, ...) as standard-library nodes with Cycles'
semantics, folding constants in float64.  interchange/layered.py's Writer adds the shaders.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from .. import constants as K
from ..core.graph import ramp_table
from .builder import Builder
from .document import NODEDEFS, Node, valid_name
from .layered_tree import ADDRESS, FILTER, MX_TYPE, COLORSPACES, LUMA

__all__ = ("V", "mx_constant", "ValueWriter", "tangent_kind", "format_value")


# --------------------------------------------------------------------------------------------
# Typed values: a constant or a node output
# --------------------------------------------------------------------------------------------


@dataclass(slots=True, eq=False)  # eq=False: compared and hashed by identity, as before
class V:
    """A MaterialX value: ``const`` (a float or a tuple) or ``node`` (a Node, with ``output``
    for multi-output nodes), of MaterialX ``type``."""

    type: str
    const: object = None
    node: Node = None
    output: str = None

    @property
    def is_const(self):
        return self.node is None

    def array(self):
        return np.asarray(self.const, dtype=np.float64)

    def __repr__(self):
        return f"V({self.type}, {self.const if self.node is None else self.node.name})"


_WIDTH = {"float": 1, "vector2": 2, "vector3": 3, "color3": 3, "color4": 4}


def mx_constant(type_, value):
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    n = _WIDTH[type_]
    if arr.size == 1 and n > 1:
        arr = np.repeat(arr, n)
    if n == 1:
        return V(type_, float(arr[0]))
    return V(type_, tuple(float(x) for x in arr[:n]))


# --------------------------------------------------------------------------------------------
# The writer's values
# --------------------------------------------------------------------------------------------


class ValueWriter:
    """The value half of :class:`layered.Writer`: names, nodes, arithmetic on :class:`V`, and the
    Blender tree's value nodes.  ``notes``: a list the writer appends to (what is approximate or
    not exported, in plain words, each once)."""

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
            return mx_constant(t, fold(self.convert(a, t).array(), self.convert(b, t).array()))
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
                    return mx_constant(t, a.array() / bv)
                return V(t, node=self.node(self._nd("divide", t), base, in1=self.convert(a, t),
                                           in2=mx_constant(t, bv)))
            if a.is_const:
                with np.errstate(divide="ignore", invalid="ignore"):
                    return mx_constant(t, np.where(bv != 0, a.array() / np.where(bv != 0, bv, 1.0), 0.0))
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
        bounds = [b if isinstance(b, V) else mx_constant("float", float(b)) for b in (lo, hi)]
        if a.is_const and all(b.is_const for b in bounds):
            return mx_constant(a.type, np.clip(a.array(), float(bounds[0].const), float(bounds[1].const)))
        t = a.type if a.type in ("float", "vector3") else "vector3"
        a2 = self.convert(a, t)
        low, high = (mx_constant(t, float(b.const)) if b.is_const else self.convert(b, t) for b in bounds)
        out = V(t, node=self.node(f"ND_clamp_{t}", base, **{"in": a2}, low=low, high=high))
        return self.convert(out, a.type)

    def unary(self, cat, a, base, fold):
        if a.is_const:
            return mx_constant(a.type, fold(a.array()))
        t = a.type if a.type in ("float", "vector3") else "vector3"
        return self.convert(V(t, node=self.node(f"ND_{cat}_{t}", base, **{"in": self.convert(a, t)})),
                            a.type)

    def sqrt(self, a, base="sqrt"):
        return self.unary("sqrt", self.maximum(a, mx_constant(a.type, 0.0), base + "_nonneg"), base, np.sqrt)

    def power(self, a, b, base="power"):
        """Cycles' safe_powf: 0 for a negative base with a non-integer exponent."""
        t = a.type if a.type != "float" else b.type
        a = self.convert(a, t)
        if a.is_const and b.is_const:
            av, bv = a.array(), np.broadcast_to(self.convert(b, t).array(), a.array().shape)
            with np.errstate(all="ignore"):
                bad = (av < 0) & (bv != np.trunc(bv))
                return mx_constant(t, np.where(bad, 0.0, np.power(np.where(bad, 1.0, av), bv)))
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
                                        in2=mx_constant(t, e)))
                if int(e) % 2:
                    if t != "float":
                        lanes = [self.power(self.lane(a, i), b, f"{base}_{'xyz'[i]}") for i in range(3)]
                        return self.combine(lanes, base)
                    neg = self.mul(p, mx_constant("float", -1.0), base + "_neg")
                    p = self.select("ifgreatereq", a, mx_constant("float", 0.0), p, neg, base + "_signed")
                return p
            if e > 0:  # a negative base gives 0: power(max(a, 0), e)
                return V(t, node=self.node(f"ND_power_{t}", base, in1=self.maximum(a, mx_constant(t, 0.0), base + "_nonneg"),
                                           in2=mx_constant(t, e)))
        if t != "float":
            lanes = [self.power(self.lane(a, i), self.lane(b, i), f"{base}_{'xyz'[i]}") for i in range(3)]
            return self.combine(lanes, base)
        # a linked exponent: a ≥ 0: a^b; a < 0: |a|^b (-1)^b for an integer b, else 0
        p = V("float", node=self.node("ND_power_float", base, in1=self.unary("absval", a, base + "_abs", np.abs),
                                      in2=b))
        odd = self.node("ND_modulo_float", base + "_odd", in1=self.unary("absval", b, base + "_babs", np.abs),
                        in2=2.0)
        sign = self.sub(mx_constant("float", 1.0), self.mul(V("float", node=odd), mx_constant("float", 2.0), base + "_2odd"),
                        base + "_parity")
        neg = self.select("ifequal", self.unary("floor", b, base + "_floor", np.floor), b,
                          self.mul(p, sign, base + "_negbase"), mx_constant("float", 0.0), base + "_int")
        return self.select("ifgreatereq", a, mx_constant("float", 0.0), p, neg, base + "_safe")

    def select(self, cat, v1, v2, a, b, base):
        """ifgreater / ifgreatereq / ifequal(value1, value2): a when true, else b."""
        t = a.type if a.type != "float" else b.type
        if a.is_const and b.is_const and np.array_equal(a.array(), b.array()):
            return self.convert(a, t)  # (either way the same: no node)
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
        if a.is_const and b.is_const and np.array_equal(self.convert(a, typ).array(),
                                                        self.convert(b, typ).array()):
            return self.convert(a, typ)  # (a select between one value: a film of 0 either way)
        if t.is_const and t.type == "float":
            tv = float(t.const)
            if tv == 0.0:
                return self.convert(a, typ)
            if tv == 1.0:
                return self.convert(b, typ)
            if a.is_const and b.is_const:
                return mx_constant(typ, (1.0 - tv) * self.convert(a, typ).array() + tv * self.convert(b, typ).array())
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
                return mx_constant(to, arr[0])
            out = list(arr[:3]) + ([1.0] if to == "color4" else [])
            return mx_constant(to, out[:_WIDTH[to]])
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
            t = MX_TYPE.get(sock.type, "float")
            return self.convert(mx_constant(t, v), to)
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
                          f"written at the socket's own value {format_value(v)}")
                got = mx_constant(MX_TYPE.get(sock.type, "float"), v)
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
            return mx_constant("float", node.outputs[0].value if node.outputs and node.outputs[0].value is not None
                      else node.props.get("value", 0.0))
        if t == "ShaderNodeRGB":
            return mx_constant("color3", node.outputs[0].value if node.outputs[0].value is not None else (0, 0, 0))
        if t == "ShaderNodeTexImage":
            return self.image(node, oid)
        if t == "ShaderNodeTexEnvironment":
            return self.environment(node, oid)
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
            return V("vector3", node=self.tangent_node(tangent_kind(node)))
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
        a = self.value(ins[0]) if ins else mx_constant("float", 0.0)
        b = self.value(ins[1]) if len(ins) > 1 else mx_constant("float", 0.0)
        c = self.value(ins[2]) if len(ins) > 2 else mx_constant("float", 0.0)
        n = node.name
        one, zero = mx_constant("float", 1.0), mx_constant("float", 0.0)
        r = {"ADD": lambda: self.add(a, b, n), "SUBTRACT": lambda: self.sub(a, b, n),
             "MULTIPLY": lambda: self.mul(a, b, n), "DIVIDE": lambda: self.div(a, b, n),
             "MULTIPLY_ADD": lambda: self.add(self.mul(a, b, n + "_mul"), c, n),
             "POWER": lambda: self.power(a, b, n), "SQRT": lambda: self.sqrt(a, n),
             "MINIMUM": lambda: self.minimum(a, b, n), "MAXIMUM": lambda: self.maximum(a, b, n),
             "LESS_THAN": lambda: self.select("ifgreater", b, a, one, zero, n),
             "GREATER_THAN": lambda: self.select("ifgreater", a, b, one, zero, n),
             "COMPARE": lambda: self.select("ifgreatereq",
                                            self.maximum(c, mx_constant("float", float(np.finfo(np.float32).eps)), n + "_eps"),
                                            self.unary("absval", self.sub(a, b, n + "_diff"), n + "_abs", np.abs),
                                            one, zero, n),
             "ABSOLUTE": lambda: self.unary("absval", a, n, np.abs),
             "FLOOR": lambda: self.unary("floor", a, n, np.floor),
             "COSINE": lambda: self.unary("cos", a, n, np.cos),
             "SINE": lambda: self.unary("sin", a, n, np.sin),
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
        a = self.value(vec[0], "vector3") if vec else mx_constant("vector3", 0.0)
        b = self.value(vec[1], "vector3") if len(vec) > 1 else mx_constant("vector3", 0.0)
        c = self.value(vec[2], "vector3") if len(vec) > 2 else mx_constant("vector3", 0.0)
        n = node.name
        if op == "SCALE":
            s = next((x for x in ins if x.type == "VALUE"), None)
            return self.mul(a, self.value(s) if s is not None else mx_constant("float", 1.0), n)
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
            return mx_constant("color3", (1.0 - t) * table[i] + t * table[j])
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
                return mx_constant("vector3", y0)
            # anchored at x0 as a float32 (what MaterialX reads): a steep segment (slope up to
            # 255 per unit step) would move by s · (x0 - fl(x0)) otherwise
            x0 = float(np.float32(knots[k]))
            y0 = y0 + s * (x0 - knots[k])
            d = self.sub(x, mx_constant("float", x0), f"{node.name}_from{k}")
            return self.add(mx_constant("vector3", y0), self.mul(mx_constant("vector3", s), d, f"{node.name}_slope{k}"),
                            f"{node.name}_line{k}")
        v = line(len(keep) - 1)
        for k in range(len(keep) - 2, -1, -1):
            v = self.select("ifgreater", mx_constant("float", knots[k + 1]), x, line(k), v, f"{node.name}_seg{k}")
        return self.convert(v, "color3")  # (a colour: into a float socket by luma, not the mean)

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
            c = self.power(c, mx_constant("float", 2.0 * b if b < 0.5 else 0.5 / (1.0 - b)), node.name + "_blend")
        return self.sub(mx_constant("float", 1.0), c, node.name)

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

    def environment(self, node, oid):
        """An Environment Texture read in a computed direction (the layer's lookup tables): the
        image at the direction's equirectangular coordinates, as Cycles maps them
        (direction_to_equirectangular: u = (atan2(y, x) - π) / -2π, v = (acos(z / |d|) - π) / -π)."""
        if node.props.get("projection", "EQUIRECTANGULAR") != "EQUIRECTANGULAR":
            self.note(f"Environment Texture “{node.name}”: {node.props['projection']} projection "
                      f"is not exported")
            return None
        vec = node.input("Vector")
        src, _ = self._follow(vec)
        d = self.value(vec, "vector3") if src is not None else None
        if d is None:
            self.note(f"Environment Texture “{node.name}” reads no computed direction: not exported")
            return None
        n = node.name
        x, y, z = (self.lane(d, i) for i in range(3))
        length = self.sqrt(self.dot(d, d, n + "_dd"), n + "_len")
        if all(c.is_const for c in (x, y, z)):
            yx = mx_constant("float", float(np.arctan2(y.const, x.const)))
        else:
            yx = V("float", node=self.node("ND_atan2_float", n + "_atan2", iny=y, inx=x))
        c = self.div(z, length, n + "_cos")
        ac = self.unary("acos", c, n + "_acos", np.arccos)
        u = self.div(self.sub(yx, mx_constant("float", math.pi), n + "_u0"), mx_constant("float", -2.0 * math.pi), n + "_u")
        v = self.div(self.sub(ac, mx_constant("float", math.pi), n + "_v0"), mx_constant("float", -math.pi), n + "_v")
        return self.image(node, oid, self.convert(self.combine((u, v, mx_constant("float", 0.0)), n + "_uv"),
                                                  "vector2"))

    def image(self, node, oid, texcoord=None):
        img = node.image
        if not img or not img.get("path"):
            what = f"“{img['name']}”" if img else "no image"
            kind = "Environment Texture" if node.type == "ShaderNodeTexEnvironment" else "Image Texture"
            self.note(f"{kind} “{node.name}” has {what} without a file on disk (packed or "
                      f"generated): written at the socket's value")
            return None
        if texcoord is None and node.props.get("projection", "FLAT") != "FLAT":
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
            n.set("filtertype", "string", FILTER.get(node.props.get("interpolation", "Linear"), "linear"))
            mode = ADDRESS.get(node.props.get("extension", "REPEAT"), "periodic")
            if mode != "periodic":
                n.set("uaddressmode", "string", mode)
                n.set("vaddressmode", "string", mode)
            uv = texcoord if texcoord is not None else self.texcoord(node)
            if uv is not None:
                self.put(n, "texcoord", uv, "vector2")
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
        """The coordinates an Image Texture reads: None for the first UV set (MaterialX's
        default), a vector2 V where node math computes them (the layer's lookup tables)."""
        vec = node.input("Vector")
        src, out = self._follow(vec)
        if src is None:
            return None  # MaterialX's default: the first UV set (Blender: the active render UV map)
        if src.type in _COMPUTED_UV:
            v = self.value(vec, "vector3")
            if v is not None:
                return self.convert(v, "vector2")
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


#: Nodes whose output an Image Texture's coordinates are written from (exported as math).
_COMPUTED_UV = {"ShaderNodeVectorMath", "ShaderNodeCombineXYZ", "ShaderNodeMath", "ShaderNodeMix"}


def tangent_kind(node):
    """The tangent a Tangent node gives, in builder.Builder.tangent's terms."""
    if node is None or node.props.get("direction_type", "RADIAL") == "UV_MAP":
        return "UV_MAP"
    return f"RADIAL_{node.props.get('axis', 'Z')}"


def format_value(v):
    arr = np.atleast_1d(np.asarray(v, dtype=np.float64))
    return ", ".join(f"{x:.4g}" for x in arr) if arr.size > 1 else f"{arr[0]:.4g}"
