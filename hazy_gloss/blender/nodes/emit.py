# SPDX-License-Identifier: GPL-3.0-or-later
"""Emit a :class:`hazy_gloss.core.graph.Graph` as nodes: shader trees (Math, Vector Math,
Clamp, Mix, Separate/Combine Color, Color Ramp) or compositor trees (scalar Math only: vectors
become three lanes, selects become arithmetic, colours are split with the compositor's Separate
Color)."""
import numpy as np

from ... import constants as K
from ...core.graph import Expr
from .. import compat

_MIX_IDS = {False: ("Factor_Float", "A_Float", "B_Float", "Result_Float"),
            True: ("Factor_Float", "A_Vector", "B_Vector", "Result_Vector")}


def _by_id(sockets, identifier):
    for s in sockets:
        if s.identifier == identifier:
            return s
    raise KeyError(identifier)


def emit(tb, graph, outputs, sources, *, backend="SHADER", reuse=None, nodes_by_expr=None,
         known=None, route=None):
    """Build the nodes ``outputs`` (an Expr or a dict/list of them) need with TreeBuilder ``tb``.

    ``sources``: input name -> socket or constant.  Returns ``outputs`` with every Expr replaced
    by a socket or a Python constant (the shader backend), or, for the compositor, vectors by a
    tuple of three lanes.  ``reuse``: the nodes an earlier emit of a graph with the same
    signature created (``tb.created`` order): they are updated in place instead of new ones
    (constants and links set again), so a change of values rebuilds nothing.
    ``nodes_by_expr``: a dict filled with {expression index: the node made for it} (shader
    backend; lanes of one vector share their Separate node).  ``known``: {expression index:
    socket} of expressions made elsewhere (a node group's inputs): used, not built.
    ``route(expr)`` (shader backend): {input name: socket} for the node of ``expr``, where its
    graph inputs come from (a layer group's frames each have a Group Input); else
    ``sources``."""
    emitter = (_ShaderEmitter(tb, sources, graph.tables) if backend == "SHADER"
               else _CompositorEmitter(tb, sources))
    emitter.route = route
    if reuse is not None:
        tb.reuse = list(reuse)
    known = known or {}
    try:
        for e in graph.used(outputs, stop=known):
            if e.index in known:
                emitter.sockets[e.index] = known[e.index]
                continue
            emitter.visit(e)
            if nodes_by_expr is not None and e.op != "input":
                nodes_by_expr[e.index] = emitter.sockets[e.index].node
    finally:
        tb.reuse = None
    return _replace(outputs, emitter.value)


def _replace(o, value):
    if isinstance(o, dict):
        return {k: _replace(v, value) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return type(o)(_replace(v, value) for v in o)
    return value(o) if isinstance(o, Expr) else o


def _const(e):
    v = e.value
    return tuple(float(x) for x in v) if e.vector else float(v)


class _ShaderEmitter:
    MATH = "ShaderNodeMath"

    def __init__(self, tb, sources, tables=None):
        self.tb = tb
        self.sources = sources
        self.tables = tables or {}
        self.sockets = {}
        self.depth = {}
        self.separated = {}
        self.route = None
        self._inputs = None  # {input name: socket} of the node being made (route)

    def value(self, e):
        if e.is_const:
            return _const(e)
        if e.op == "input" and self._inputs is not None:
            return self._inputs[e.name]
        return self.sockets[e.index]

    def _depth(self, e):
        return 0 if e.is_const else self.depth.get(e.index, 0)

    def _node(self, bl_idname, e, **props):
        d = 1 + max((self._depth(a) for a in e.args), default=0)
        n = self.tb.node(bl_idname, label=e.label, **props)
        self.tb.place(n, d)
        self.depth[e.index] = d
        return n

    def visit(self, e):
        if e.op == "input":
            self.sockets[e.index] = self.sources.get(e.name)
            return
        self._inputs = self.route(e) if self.route is not None else None
        try:
            self._visit(e)
        finally:
            self._inputs = None

    def _visit(self, e):
        tb = self.tb
        if e.op == "SEPARATE":  # one Separate Color node per vector, shared by its lanes (one
            src = e.args[0]        # SVM node where Separate XYZ compiles to one per lane)
            if src.index not in self.separated:
                node = self._node("ShaderNodeSeparateColor", e, mode="RGB")
                tb.feed(node.inputs[0], self.value(src))
                self.separated[src.index] = (node, self.depth[e.index])
            node, d = self.separated[src.index]
            self.depth[e.index] = d
            self.sockets[e.index] = node.outputs[e.lane]
            return
        if e.op == "COMBINE":
            n = self._node("ShaderNodeCombineColor", e, mode="RGB")  # (likewise)
            for sock, a in zip(n.inputs, e.args):
                tb.feed(sock, self.value(a))
            self.sockets[e.index] = n.outputs[0]
            return
        if e.op == "MIX":
            n = self._node("ShaderNodeMix", e, data_type="VECTOR" if e.vector else "FLOAT",
                           clamp_factor=False)
            fac, a, b, res = _MIX_IDS[e.vector]
            tb.feed(_by_id(n.inputs, fac), self.value(e.args[0]))
            tb.feed(_by_id(n.inputs, a), self.value(e.args[1]))
            tb.feed(_by_id(n.inputs, b), self.value(e.args[2]))
            self.sockets[e.index] = _by_id(n.outputs, res)
            return
        if e.op == "VMIX":  # vector Mix (a vector factor: Non-Uniform)
            uniform = not e.args[0].vector
            n = self._node("ShaderNodeMix", e, data_type="VECTOR", clamp_factor=False,
                           factor_mode="UNIFORM" if uniform else "NON_UNIFORM")
            fac = "Factor_Float" if uniform else "Factor_Vector"
            for ident, a in zip((fac, "A_Vector", "B_Vector"), e.args):
                tb.feed(_by_id(n.inputs, ident), self.value(a))
            self.sockets[e.index] = _by_id(n.outputs, "Result_Vector")
            return
        if e.op == "SATURATE":  # colour Mix with Clamp Result: v in [0, 1] per lane
            # v enters as B at factor 1 over A = 0: kept as is, ±inf included, in every version
            # (as A at factor 0, 4.5 and 5.2 turn inf into NaN: docs/blender-versions.md)
            n = self._node("ShaderNodeMix", e, data_type="RGBA", blend_type="MIX",
                           clamp_factor=False, clamp_result=True)
            tb.feed(_by_id(n.inputs, "Factor_Float"), 1.0)
            tb.feed(_by_id(n.inputs, "A_Color"), (0.0, 0.0, 0.0, 1.0))
            tb.feed(_by_id(n.inputs, "B_Color"), self.value(e.args[0]))
            self.sockets[e.index] = _by_id(n.outputs, "Result_Color")
            return
        if e.op == "CLAMP":
            n = self._node("ShaderNodeClamp", e, clamp_type="MINMAX")
            for sock, a in zip(n.inputs, e.args):
                tb.feed(sock, self.value(a))
            self.sockets[e.index] = n.outputs[0]
            return
        if e.op == "RAMP":  # linear RGB Color Ramp with the graph's stops (set on reuse too)
            n = self._node("ShaderNodeValToRGB", e)
            ramp = n.color_ramp
            if not _ramp_is(ramp, e.value):  # (a reused ramp usually already is: a slider
                ramp.color_mode = "RGB"     # change must not rewrite 64 stops)
                ramp.interpolation = "LINEAR"
                elements = ramp.elements
                while len(elements) > 1:
                    elements.remove(elements[-1])
                elements[0].position = e.value[0][0]
                for pos, _ in e.value[1:]:  # increasing: each new element is the last
                    elements.new(pos)
                for el, (pos, col) in zip(elements, e.value):
                    el.color = (*col, 1.0)
            tb.feed(n.inputs["Fac"], self.value(e.args[0]))
            self.sockets[e.index] = n.outputs["Color"]
            return
        if e.op == "TABLE":  # an Environment Texture of the table's float image (core.graph)
            n = self._node("ShaderNodeTexEnvironment", e, interpolation="Linear",
                           projection="EQUIRECTANGULAR")
            n.image = table_image(e.value, self.tables[e.value])
            tb.feed(n.inputs["Vector"], self.value(e.args[0]))
            self.sockets[e.index] = n.outputs["Color"]
            return
        if e.op.startswith("V"):
            op = e.op[1:]
            n = self._node("ShaderNodeVectorMath", e, operation=op)
            if op == "SCALE":
                tb.feed(n.inputs[0], self.value(e.args[0]))
                tb.feed(n.inputs["Scale"], self.value(e.args[1]))
            else:
                for sock, a in zip(n.inputs, e.args):
                    tb.feed(sock, self.value(a))
            self.sockets[e.index] = n.outputs["Value" if not e.vector else "Vector"]
            return
        n = self._node(self.MATH, e, operation=e.op, use_clamp=e.clamp)
        for sock, a in zip(n.inputs, e.args):
            tb.feed(sock, self.value(a))
        self.sockets[e.index] = n.outputs[0]


def table_image(name, data):
    """The packed float image (Non-Color, full float) that holds a graph table, made once per
    file and checked by its values' hash (an image of that name holding other values is
    replaced under a new name, never overwritten: another group may read it)."""
    import hashlib

    import bpy
    digest = hashlib.sha1(np.ascontiguousarray(data, np.float32).tobytes()).hexdigest()[:12]
    # (4.5 cuts ID names at 63 bytes: the hash must survive, so the name gives way)
    room = 63 - len(K.TABLE_IMAGE_PREFIX) - len(digest) - 1
    full = f"{K.TABLE_IMAGE_PREFIX}{name[:room]} {digest}"
    img = bpy.data.images.get((full, None))  # (a local one: never a linked image)
    if img is not None and img.get("hazy_gloss_table") == digest:
        return img
    h, w = data.shape[:2]
    img = bpy.data.images.new(full, w, h, alpha=False, float_buffer=True, is_data=True)
    px = np.ones((h, w, 4), np.float32)
    data = np.asarray(data, np.float32)
    px[..., :3] = data if data.ndim == 3 else data[..., None]
    img.pixels.foreach_set(px.ravel())
    if hasattr(img, "use_half_precision"):
        img.use_half_precision = False
    img.pack()
    img["hazy_gloss_table"] = digest
    return img


def _ramp_is(ramp, stops):
    """Whether a Color Ramp already holds ``stops`` ((position, rgb), ...), linear RGB."""
    if ramp.color_mode != "RGB" or ramp.interpolation != "LINEAR" or \
            len(ramp.elements) != len(stops):
        return False
    f32 = np.float32
    for el, (pos, col) in zip(ramp.elements, stops):
        if f32(el.position) != f32(pos) or any(f32(a) != f32(b) for a, b in zip(el.color, col)):
            return False
    return True


class _CompositorEmitter:
    """Scalar Math nodes only (4.5's compositor has no vector math or float mix)."""

    def __init__(self, tb, sources):
        self.tb = tb
        self.sources = sources
        self.math_id = compat.compositor_math_node()
        self.vals = {}  # index -> socket/float, or a tuple of three lanes for vectors

    def value(self, e):
        if e.is_const:
            c = _const(e)
            return c if not e.vector else tuple(c)
        return self.vals[e.index]

    def _lanes(self, e):
        v = self.value(e)
        if e.vector:
            return v
        return (v, v, v)

    def _math(self, op, *args, clamp=False, label=None):
        tb = self.tb
        d = 1 + max((tb.depth_of(a) for a in args), default=0)
        n = tb.node(self.math_id, operation=op, use_clamp=clamp, label=label)
        tb.place(n, d)
        for sock, a in zip(n.inputs, args):
            tb.feed(sock, a)
        return n.outputs[0]

    def visit(self, e):
        tb = self.tb
        if e.op == "input":
            src = self.sources[e.name]
            if e.vector and not isinstance(src, tuple) and hasattr(src, "node"):
                n = tb.node("CompositorNodeSeparateColor", depth=1 + tb.depth_of(src))
                tb.link(src, n.inputs[0])
                src = tuple(n.outputs[:3])
            self.vals[e.index] = src
            return
        if e.op == "SEPARATE":
            self.vals[e.index] = self._lanes(e.args[0])[e.lane]
            return
        if e.op == "COMBINE":
            self.vals[e.index] = tuple(self.value(a) for a in e.args)
            return
        if e.op == "VMIX":  # (1 - t) a + t b per lane
            t, a, b = (self._lanes(x) for x in e.args)
            self.vals[e.index] = tuple(
                self._math("MULTIPLY_ADD", t[i], b[i],
                           self._math("MULTIPLY", self._math("SUBTRACT", 1.0, t[i]), a[i]),
                           label=e.label) for i in range(3))
            return
        if e.op == "MIX":  # (1 - t) a + t b
            t = self.value(e.args[0])
            lanes = list(zip(self._lanes(e.args[1]), self._lanes(e.args[2]))) if e.vector \
                else [(self.value(e.args[1]), self.value(e.args[2]))]
            omt = self._math("SUBTRACT", 1.0, t)
            out = tuple(self._math("MULTIPLY_ADD", t, b, self._math("MULTIPLY", omt, a),
                                   label=e.label) for a, b in lanes)
            self.vals[e.index] = out if e.vector else out[0]
            return
        if e.op == "RAMP":
            raise NotImplementedError("the compositor backend has no Color Ramp of the graph's form")
        if e.op == "SATURATE":
            self.vals[e.index] = tuple(self._math("MINIMUM", self._math("MAXIMUM", x, 0.0), 1.0,
                                                  label=e.label) for x in self._lanes(e.args[0]))
            return
        if e.op == "CLAMP":  # Maximum then Minimum (the same for bounds that are not NaN)
            x, lo, hi = (self.value(a) for a in e.args)
            if isinstance(lo, float) and lo >= 0.0 and hi == 1.0:
                self.vals[e.index] = self._math("MAXIMUM", x, lo, clamp=True, label=e.label)
            else:
                self.vals[e.index] = self._math("MINIMUM", self._math("MAXIMUM", x, lo), hi,
                                                label=e.label)
            return
        if e.op == "VDOT_PRODUCT":
            a, b = self._lanes(e.args[0]), self._lanes(e.args[1])
            acc = self._math("MULTIPLY", a[0], b[0])
            for i in (1, 2):
                acc = self._math("MULTIPLY_ADD", a[i], b[i], acc, label=e.label if i == 2 else None)
            self.vals[e.index] = acc
            return
        if e.op.startswith("V"):
            op = e.op[1:]
            if op == "SCALE":
                s = self.value(e.args[1])
                out = tuple(self._math("MULTIPLY", x, s, label=e.label) for x in self._lanes(e.args[0]))
            else:
                lanes = [self._lanes(a) for a in e.args]
                out = tuple(self._math(op, *(la[i] for la in lanes), label=e.label) for i in range(3))
            self.vals[e.index] = out
            return
        self.vals[e.index] = self._math(e.op, *(self.value(a) for a in e.args), clamp=e.clamp,
                                        label=e.label)


def combine_compositor(tb, lanes, alpha=1.0):
    """Three lanes (+ alpha) as one compositor colour socket."""
    d = 1 + max(tb.depth_of(x) for x in (*lanes, alpha))
    n = tb.node("CompositorNodeCombineColor", depth=d)
    for sock, x in zip(n.inputs[:4], (*lanes, alpha)):
        tb.feed(sock, x)
    return n.outputs[0]


__all__ = ("emit", "combine_compositor")
