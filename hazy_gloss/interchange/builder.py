# SPDX-License-Identifier: GPL-3.0-or-later
"""Adding MaterialX nodes to a node graph by nodedef name, and the tangent a lobe follows:
what the Eq. 1 and OpenPBR exports (interchange/materialx.py) and the haze layer's network
(interchange/layered.py) build with.
"""
from __future__ import annotations

from .document import NODEDEFS, Node

__all__ = ("Builder",)


class Builder:
    """Nodes of one graph: :meth:`node` adds a node of a nodedef with its inputs (values or
    nodes), :meth:`tangent` the tangent a lobe's α_x follows."""

    def __init__(self, graph):
        self.g = graph

    def node(self, nodedef, name, **inputs):
        cat, typ, spec = NODEDEFS[nodedef]
        n = Node(name, cat, typ)
        for k, v in inputs.items():
            t = spec[k][0]
            if isinstance(v, Node):
                n.set(k, t, node=v)
            else:
                n.set(k, t, v)
        return self.g.add(n)

    # -- tangents ------------------------------------------------------------------------------
    def tangent(self, kind, rotation, suffix=""):
        """The tangent a lobe's α_x follows: the UV tangent (index 0) or a radial one around an
        object axis (cross(axis, P_object) in world space: Blender's radial tangent is taken
        around the bounding-box centre, this one around the object origin), turned by
        ``rotation`` turns about the normal (a number, or a node giving turns)."""
        if kind == "UV_MAP":
            t = self.g.nodes.get("tangent_uv") or self.node("ND_tangent_vector3", "tangent_uv",
                                                            space="world", index=0)
        else:
            axis = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}[kind[-1]]
            t = self.g.nodes.get("tangent_radial")
            if t is None:
                pos = self.node("ND_position_vector3", "position_object", space="object")
                cr = self.node("ND_crossproduct_vector3", "radial_cross", in1=axis, in2=pos)
                tw = self.node("ND_transformvector_vector3", "radial_world", fromspace="object",
                               tospace="world")
                tw.set("in", "vector3", node=cr)
                t = self.node("ND_normalize_vector3", "tangent_radial")
                t.set("in", "vector3", node=tw)
        if isinstance(rotation, (int, float)) and rotation == 0:
            return t
        normal = self.g.nodes.get("normal_world") or self.node("ND_normal_vector3", "normal_world",
                                                                space="world")
        rot = self.node("ND_rotate3d_vector3", f"tangent_rotated{suffix}", axis=normal)
        rot.set("in", "vector3", node=t)
        if isinstance(rotation, Node):  # turns from a map: amount = -360 * rotation
            amount = self.node("ND_multiply_float", f"rotation_degrees{suffix}", in1=rotation,
                               in2=-360.0)
            rot.set("amount", "float", node=amount)
        else:
            rot.set("amount", "float", -360.0 * float(rotation))
        return rot
