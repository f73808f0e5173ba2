# SPDX-License-Identifier: GPL-3.0-or-later
"""A small numpy evaluator of MaterialX standard-library value nodes, for the tests.

Written from the MaterialX 1.39 specification (stdlib: add, subtract, multiply, divide, power,
sqrt, modulo, min, max, clamp, absval, floor, sign, sin, cos, acos, atan2, ifgreater,
ifgreatereq, ifequal, mix, extract, combine2, combine3, convert, dotproduct, invert,
roughness_anisotropy; nodes defined by a library node graph through that graph) and evaluated
in float32 like a GPU
shader, independently of hazy_gloss: documents are read with the real ``materialx`` package,
values come out of the nodes' inputs as MaterialX parses them.  ``image`` nodes (and any node
named in ``given``) take their values from the caller: the texels a test feeds.
"""
import sys

import MaterialX as mx
import numpy as np

F32 = np.float32
_WIDTH = {"float": 1, "integer": 1, "vector2": 2, "vector3": 3, "color3": 3, "color4": 4}


def _const(inp, n):
    t = inp.getType()
    v = inp.getValue()
    if t in ("float", "integer"):
        return np.full(n, F32(v), dtype=F32)
    if t in ("string", "filename", "boolean"):
        return v
    arr = np.array(list(v), dtype=F32)
    return np.broadcast_to(arr, (n, arr.size)).copy()


class Evaluator:
    """``Evaluator(graph, n, given={node name: array}, interface={input: array}, library=doc)``;
    ``value(node_name, input_name=None)`` gives a node's output, or the value reaching one of
    its inputs.  ``interface``: the values of a nodedef's implementation graph's interface
    inputs; nodes whose category is not one of the above are evaluated through their nodedef's
    implementation node graph in ``library`` (e.g. open_pbr_anisotropy)."""

    def __init__(self, graph, n, given=None, interface=None, library=None):
        self.g = graph
        self.n = n
        self.given = {k: np.asarray(v, dtype=F32) for k, v in (given or {}).items()}
        self.interface = {k: np.asarray(v, dtype=F32) for k, v in (interface or {}).items()}
        self.library = library
        self.memo = {}

    def input(self, node, name):
        inp = node.getInput(name)
        if inp is None:  # the nodedef default
            nd = node.getNodeDef()
            inp = nd.getActiveInput(name) if nd is not None else None
            if inp is None:
                raise KeyError(f"{node.getName()} has no input {name}")
            if inp.hasDefaultGeomPropString():
                raise NotImplementedError(f"{node.getName()}.{name}: geometric default")
            return _const(inp, self.n)
        up = inp.getConnectedNode()
        if up is not None:
            return self.node(up)
        if inp.hasInterfaceName():
            name = inp.getInterfaceName()
            if name in self.interface:
                v = self.interface[name]
                return np.broadcast_to(v, (self.n,) + v.shape[1:]).astype(F32) if v.ndim else \
                    np.full(self.n, v, dtype=F32)
            raise KeyError(f"no value for the interface input {name}")
        return _const(inp, self.n)

    def value(self, node_name, input_name=None):
        node = self.g.getNode(node_name)
        if node is None:
            raise KeyError(node_name)
        limit = sys.getrecursionlimit()
        sys.setrecursionlimit(max(limit, 40000))  # the layer's node math is thousands deep
        try:
            return self.input(node, input_name) if input_name else self.node(node)
        finally:
            sys.setrecursionlimit(limit)

    def node(self, node):
        key = node.getName()
        if key in self.memo:
            return self.memo[key]
        if key in self.given:
            out = self.given[key]
        else:
            out = self._eval(node)
        self.memo[key] = out
        return out

    def _eval(self, node):
        c = node.getCategory()
        t = node.getType()
        i = lambda name: self.input(node, name)  # noqa: E731
        w = _WIDTH.get(t)

        def bcast(x):  # float operands of vector ops (the FA variants) broadcast
            x = np.asarray(x, dtype=F32)
            if w and w > 1 and x.ndim == 1:
                return x[:, None]
            return x

        with np.errstate(all="ignore"):
            if c == "constant":
                return i("value")
            if c == "modulo":  # mx_mod: x - y floor(x / y)
                a, b = i("in1"), bcast(i("in2"))
                return np.asarray(a - b * np.floor(a / b), dtype=F32)
            if c in ("add", "subtract", "multiply", "divide", "min", "max", "power"):
                a, b = i("in1"), bcast(i("in2"))
                f = {"add": np.add, "subtract": np.subtract, "multiply": np.multiply,
                     "divide": np.divide, "min": np.minimum, "max": np.maximum,
                     "power": np.power}[c]
                return np.asarray(f(a, b), dtype=F32) * np.ones_like(a)
            if c in ("sqrt", "absval", "floor", "sign", "sin", "cos", "acos", "exp"):
                f = {"sqrt": np.sqrt, "absval": np.abs, "floor": np.floor, "sign": np.sign,
                     "sin": np.sin, "cos": np.cos, "acos": np.arccos, "exp": np.exp}[c]
                return np.asarray(f(i("in")), dtype=F32)
            if c == "atan2":
                return np.asarray(np.arctan2(i("iny"), i("inx")), dtype=F32)
            if c == "clamp":
                return np.asarray(np.minimum(np.maximum(i("in"), bcast(i("low"))), bcast(i("high"))), F32)
            if c in ("ifgreater", "ifgreatereq", "ifequal"):
                v1, v2 = i("value1"), i("value2")
                ok = {"ifgreater": v1 > v2, "ifgreatereq": v1 >= v2, "ifequal": v1 == v2}[c]
                a, b = i("in1"), i("in2")
                if np.ndim(a) > 1:
                    ok = ok[:, None]
                return np.where(ok, a, b).astype(F32)
            if c == "mix":
                fg, bg, m = i("fg"), i("bg"), bcast(i("mix"))
                return ((F32(1) - m) * bg + m * fg).astype(F32)
            if c == "extract":
                idx = int(node.getInput("index").getValue()) if node.getInput("index") else 0
                return i("in")[:, idx].astype(F32)
            if c == "combine3":
                return np.stack([i("in1"), i("in2"), i("in3")], axis=-1).astype(F32)
            if c == "combine2":
                return np.stack([i("in1"), i("in2")], axis=-1).astype(F32)
            if c == "invert":  # in: amount - in (amount 1)
                amount = i("amount") if node.getNodeDef().getActiveInput("amount") else F32(1)
                return (amount - i("in")).astype(F32)
            if c == "convert":
                x = i("in")
                if x.ndim == 1:
                    return np.repeat(x[:, None], w, axis=1) if w > 1 else x
                if w == 3 and x.shape[1] >= 3:
                    return x[:, :3].copy()
                raise NotImplementedError(f"convert to {t}")
            if c == "dotproduct":
                return np.sum(i("in1") * i("in2"), axis=-1).astype(F32)
            if c == "roughness_anisotropy":  # mx_roughness_anisotropy.glsl
                r, a = i("roughness"), i("anisotropy")
                r2 = np.clip(r * r, np.finfo(F32).eps, 1.0)
                aspect = np.sqrt(1.0 - np.clip(a, 0.0, 0.98))
                ax = np.where(a > 0, np.minimum(r2 / aspect, 1.0), r2)
                ay = np.where(a > 0, r2 * aspect, r2)
                return np.stack([ax, ay], -1).astype(F32)
            nd = node.getNodeDef()
            impl = nd.getImplementation() if nd is not None else None
            if impl is not None and impl.isA(mx.NodeGraph):  # a node defined by a library graph
                inner = {name: self.input(node, name) for name in (x.getName() for x in nd.getActiveInputs())}
                sub = Evaluator(impl, self.n, interface=inner, library=self.library)
                return sub.node(impl.getOutputs()[0].getConnectedNode())
        raise NotImplementedError(f"{c} ({t}) in {node.getName()}")
