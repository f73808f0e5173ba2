# SPDX-License-Identifier: GPL-3.0-or-later
"""Creating, laying out and feeding nodes (every tree the add-on builds goes through here).

Operands are node sockets (linked) or Python constants (typed into the unlinked input), so
the same lobe code builds a lean tree (constants) and a texture-driven one (sockets).  Nodes
are placed in columns by depth so generated trees stay readable.
"""
import bpy

from ... import constants as K

__all__ = ("NodeSocket", "TreeBuilder", "set_if_changed", "socket_value", "default_value_of")

NodeSocket = bpy.types.NodeSocket


class TreeBuilder:
    def __init__(self, tree, *, x0=0.0, y0=0.0, prefix=K.NODE_PREFIX, roles=False):
        self.tree = tree
        self.nodes = tree.nodes
        self.links = tree.links
        self.prefix = prefix
        self.roles = roles  # tag named nodes with constants.ROLE (material trees)
        self._depth = {}
        self._rows = {}
        self.x0 = x0
        self.y0 = y0
        self.created = []
        self.reuse = None  # nodes to take instead of creating new ones (nodes.emit)
        self._placed = set()  # names of reused nodes
        #: node name -> (depth, row) of place(); with ``set_locations`` False place() only
        #: records it, for a caller that lays the nodes out itself (each location set updates
        #: the whole tree: one per node is what a large group can afford)
        self.grid = {}
        self.set_locations = True

    def node(self, bl_idname, *, label=None, name=None, depth=None, **props):
        """A new node; ``name`` becomes "<prefix> <name>" and, in a material tree, its role.
        With ``reuse`` set, the next node of that list (of the same type) is taken instead."""
        if self.reuse:
            n = self.reuse.pop(0)
            if n.bl_idname != bl_idname:
                raise ValueError(f"cannot reuse {n.bl_idname} as {bl_idname}")
            for k, val in props.items():
                if getattr(n, k) != val:
                    setattr(n, k, val)
            self.created.append(n)
            self._placed.add(n.name)
            if depth is not None:
                self._depth[n.name] = depth
            return n
        n = self.nodes.new(bl_idname)
        for k, val in props.items():
            setattr(n, k, val)
        if label:
            n.label = label
        if name:
            n.name = f"{self.prefix} {name}"
            if self.roles:
                n[K.ROLE] = name
        elif self.prefix and self.roles:
            n.name = f"{self.prefix} {n.name}"
        self.created.append(n)
        if depth is not None:
            self.place(n, depth)
        return n

    def place(self, node, depth):
        if node.name in self._placed:  # a reused node keeps where it is (the user may move it)
            self._depth[node.name] = depth
            return
        row = self._rows.get(depth, 0)
        self._rows[depth] = row + 1
        self.grid[node.name] = (depth, row)
        if self.set_locations:
            node.location = (self.x0 + 180.0 * depth, self.y0 - 160.0 * row)
        self._depth[node.name] = depth

    def depth_of(self, value):
        if isinstance(value, NodeSocket):
            return self._depth.get(value.node.name, 0)
        return 0

    @property
    def max_depth(self):
        return max(self._depth.values(), default=0)

    def feed(self, socket, value):
        """Link a socket or type a constant into ``socket``.  Into a reused node (an update of
        a tree of the same structure and sources, nodes.emit) links are already there and only
        changed constants are written."""
        if isinstance(value, NodeSocket):
            if not (self._placed and socket.is_linked and socket.node.name in self._placed):
                self.links.new(value, socket)
        elif value is not None:
            v = socket_value(socket, value)
            if socket.node.name in self._placed:
                cur = socket.default_value
                if (tuple(cur) if hasattr(cur, "__len__") else cur) == v:
                    return
            socket.default_value = v

    def link(self, out_socket, in_socket):
        self.links.new(out_socket, in_socket)


def set_if_changed(socket, value):
    """Give ``socket`` the ``value`` (in its form: :func:`socket_value`) unless it has it
    already (each set updates the whole tree)."""
    value = socket_value(socket, value)
    current = socket.default_value
    if (tuple(current) if hasattr(current, "__len__") else current) != value:
        socket.default_value = value


def socket_value(socket, value):
    """``value`` in the form ``socket.default_value`` takes (RGBA colours, 3-vectors)."""
    if socket.type == "RGBA":
        if not hasattr(value, "__len__"):
            return (float(value),) * 3 + (1.0,)
        value = tuple(float(v) for v in value)
        return value + (1.0,) if len(value) == 3 else value
    if socket.type == "VECTOR":
        if not hasattr(value, "__len__"):
            return (float(value),) * 3
        return tuple(float(v) for v in value)
    if socket.type == "BOOLEAN":
        return bool(value)
    if socket.type == "INT":
        return int(value)
    return float(value)


def default_value_of(sock):
    """An input's own value as floats (a tuple for a vector or colour); None for a socket
    without a number (a shader, a string)."""
    v = getattr(sock, "default_value", None)
    if v is None or isinstance(v, str):
        return None
    if hasattr(v, "__len__"):
        return tuple(float(x) for x in v)
    try:
        return float(v)
    except (TypeError, ValueError):
        return None
