# SPDX-License-Identifier: GPL-3.0-or-later
"""A small helper to write shader node graphs as expressions.

Every operand is either a node socket (linked) or a Python constant (typed into the unlinked
input), so the same lobe code builds a lean tree (constants) and an in-shader tree (sockets).
Nodes are laid out in columns by depth so generated trees stay readable.
"""
import bpy

NodeSocket = bpy.types.NodeSocket


class TreeBuilder:
    #: the scalar Math node type (the compositor's builder swaps in its own)
    MATH_NODE = "ShaderNodeMath"

    def __init__(self, tree, *, x0=0.0, y0=0.0, prefix="HG"):
        self.tree = tree
        self.nodes = tree.nodes
        self.links = tree.links
        self.prefix = prefix
        self._depth = {}
        self._rows = {}
        self.x0 = x0
        self.y0 = y0
        self.created = []

    # -- node creation ----------------------------------------------------------------------
    def node(self, bl_idname, *, label=None, name=None, depth=None, **props):
        n = self.nodes.new(bl_idname)
        for k, val in props.items():
            setattr(n, k, val)
        if label:
            n.label = label
        if name:
            n.name = f"{self.prefix} {name}"
        self.created.append(n)
        if depth is not None:
            self.place(n, depth)
        return n

    def place(self, node, depth):
        row = self._rows.get(depth, 0)
        self._rows[depth] = row + 1
        node.location = (self.x0 + 180.0 * depth, self.y0 - 160.0 * row)
        self._depth[node.name] = depth

    def depth_of(self, value):
        if isinstance(value, NodeSocket):
            return self._depth.get(value.node.name, 0)
        return 0

    def feed(self, socket, value):
        """Link a socket or type a constant into ``socket``."""
        if isinstance(value, NodeSocket):
            self.links.new(value, socket)
        elif value is not None:
            if socket.type in ("RGBA",) and not hasattr(value, "__len__"):
                value = (value, value, value, 1.0)
            elif socket.type == "RGBA" and len(value) == 3:
                value = (*value, 1.0)
            elif socket.type == "VECTOR" and not hasattr(value, "__len__"):
                value = (value, value, value)
            socket.default_value = value

    # -- scalar math --------------------------------------------------------------------------
    def math(self, op, a, b=None, c=None, *, label=None, clamp=False):
        d = 1 + max(self.depth_of(a), self.depth_of(b), self.depth_of(c))
        n = self.node(self.MATH_NODE, operation=op, use_clamp=clamp, label=label)
        self.place(n, d)
        self.feed(n.inputs[0], a)
        if b is not None:
            self.feed(n.inputs[1], b)
        if c is not None:
            self.feed(n.inputs[2], c)
        return n.outputs[0]

    def add(self, a, b, **kw):
        return self.math("ADD", a, b, **kw)

    def sub(self, a, b, **kw):
        return self.math("SUBTRACT", a, b, **kw)

    def mul(self, a, b, **kw):
        return self.math("MULTIPLY", a, b, **kw)

    def div(self, a, b, **kw):  # Blender's Math divide is safe: x / 0 = 0
        return self.math("DIVIDE", a, b, **kw)

    def madd(self, a, b, c, **kw):  # a * b + c
        return self.math("MULTIPLY_ADD", a, b, c, **kw)

    def sqrt(self, a, **kw):
        return self.math("SQRT", a, **kw)

    def minimum(self, a, b, **kw):
        return self.math("MINIMUM", a, b, **kw)

    def maximum(self, a, b, **kw):
        return self.math("MAXIMUM", a, b, **kw)

    def less(self, a, b, **kw):  # 1.0 if a < b else 0.0
        return self.math("LESS_THAN", a, b, **kw)

    def clamp(self, a, lo, hi, **kw):
        return self.minimum(self.maximum(a, lo), hi, **kw)

    def select(self, cond, if_true, if_false, **kw):
        """cond ∈ {0, 1}: exact selection (no blend arithmetic on the chosen value)."""
        t = self.mul(cond, if_true)
        return self.madd(self.sub(1.0, cond), if_false, t, **kw)

    # -- vector (per-channel) math ----------------------------------------------------------
    def vmath(self, op, a, b=None, c=None, *, label=None):
        d = 1 + max(self.depth_of(a), self.depth_of(b), self.depth_of(c))
        n = self.node("ShaderNodeVectorMath", operation=op, label=label)
        self.place(n, d)
        self.feed(n.inputs[0], a)
        if b is not None:
            self.feed(n.inputs[1], b)
        if c is not None:
            if op == "SCALE":
                self.feed(n.inputs["Scale"], c)
            else:
                self.feed(n.inputs[2], c)
        out = n.outputs["Vector"]
        return out

    def vscale(self, v, s, **kw):
        n_out = self.vmath("SCALE", v, None, s, **kw)
        return n_out

    def separate(self, colour):
        n = self.node("ShaderNodeSeparateColor", depth=1 + self.depth_of(colour))
        self.feed(n.inputs[0], colour)
        return n.outputs[0], n.outputs[1], n.outputs[2]

    def channel_max(self, colour):
        r, g, b = self.separate(colour)
        return self.maximum(self.maximum(r, g), b)

    def link(self, out_socket, in_socket):
        self.links.new(out_socket, in_socket)
