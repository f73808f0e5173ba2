# SPDX-License-Identifier: GPL-3.0-or-later
"""Which parts a haze layer's group holds (core.layer_graph.PARTS): those the node's inputs can
reach.  An input reaches a part when it is linked, keyframed, driven, or holds a value that
needs it (Metallic above 0 needs the metal part, a Coat Weight and Coat Haziness above 0 the
coat, ...).  The group follows: Make Hazy picks it, an edit that needs another part moves the
layer node to the group that has it (actions.sync), and a saved file's group covers every
frame of its animation (keyed inputs count whatever their value)."""
from __future__ import annotations

from ... import constants as K
from ...core import layer_graph
from ...schema import HAZE_SOCKETS
from .. import compat
from . import layer_group, stamp

__all__ = ("needed", "missing")

#: Cycles builds no closure below this weight (kernel/svm/types.h CLOSURE_WEIGHT_CUTOFF) and
#: no film thinner than this (THINFILM_THICKNESS_CUTOFF, nm).
WEIGHT_CUTOFF = 1e-5
FILM_CUTOFF = 0.1


class _Reader:
    """The node's inputs: which vary (linked, keyframed, driven) and their values; haze values
    from ``haze`` (Make Hazy's, by parameter) where given, else from the node's haze sockets."""

    def __init__(self, node, haze):
        self.inputs = {s.name: s for s in node.inputs if s.name}
        paths = compat.animated_paths(node.id_data)
        self.live = {s.name for s in self.inputs.values()
                     if s.is_linked or s.path_from_id() + ".default_value" in paths}
        self.haze = haze or {}

    def varies(self, name):
        return name in self.live

    def value(self, name, default=0.0):
        s = self.inputs.get(name)
        v = getattr(s, "default_value", default) if s is not None else default
        if hasattr(v, "__len__"):
            return max(float(x) for x in tuple(v)[:3])
        return float(v)

    def above(self, name, cutoff):
        return name in self.inputs and (self.varies(name) or self.value(name) > cutoff)

    def haze_value(self, param):
        """(varies, value) of a haze parameter."""
        if param in self.haze and self.haze[param] is not None:
            v = self.haze[param]
            if isinstance(v, str):  # a texture's marker: it varies
                return True, 0.0
            if hasattr(v, "__len__"):
                return False, [float(x) for x in v]
            return False, float(v)
        name = HAZE_SOCKETS[param][0]
        if name not in self.inputs:
            return False, 0.0
        return self.varies(name), self.value(name)


def _extents_differ(r):
    """The halo may be anisotropic: either extent varies, or they differ."""
    given = r.haze.get("haze_extent")
    if given is not None and not isinstance(given, str):
        xy = list(given) if hasattr(given, "__len__") else [given, given]
        return float(xy[0]) != float(xy[-1])
    vx, x = r.haze_value("haze_extent_x")
    vy, y = r.haze_value("haze_extent_y")
    return vx or vy or x != y


def needed(kind, node, haze=None):
    """The parts (sorted names) a group of BSDF ``kind`` needs for ``node`` (the artist's BSDF
    at Make Hazy, or a layer node) and ``haze`` (haze values by parameter; None: the node's)."""
    r = _Reader(node, haze)
    parts = set()
    if kind == "PRINCIPLED":
        if r.varies("Metallic"):
            parts |= {"dielectric", "metal"}
        else:
            m = r.value("Metallic")
            if m < 1.0:
                parts.add("dielectric")
            if m > 0.0:
                parts.add("metal")
        coat_varies, coat = r.haze_value("coat_haziness")
        if r.above("Coat Weight", WEIGHT_CUTOFF) and (coat_varies or coat > 0.0):
            parts.add("coat")
        if "dielectric" in parts:
            if r.above("Thin Film Thickness", FILM_CUTOFF):
                parts.add("film")
            if r.above("Transmission Weight", WEIGHT_CUTOFF):
                parts.add("transmission")
                if r.above("Thin Wall", 0.5):
                    parts.add("thin_wall")
        if r.above("Anisotropic", 0.0) or _extents_differ(r):
            parts.add("aniso")
    else:  # Metallic (saturated anisotropy) and Glossy (either sign)
        aniso = r.varies("Anisotropy") or (r.value("Anisotropy") > 0.0 if kind == "METALLIC"
                                           else r.value("Anisotropy") != 0.0)
        if aniso or _extents_differ(r):
            parts.add("aniso")
    return tuple(sorted(parts & set(layer_graph.PARTS[kind])))


#: A part's name in the notes.
_PART_WORDS = {"dielectric": "dielectric", "metal": "metal", "coat": "coat haze",
               "film": "thin film", "transmission": "transmission", "thin_wall": "thin wall",
               "aniso": "anisotropy"}


def missing(node):
    """The parts (in words) the layer node's inputs reach that its group does not hold."""
    cfg = stamp.group(node.node_tree, K.GROUP_STAMP) or {} if node.node_tree is not None else {}
    if cfg.get("kind") != "layer" or cfg.get("baked"):
        return []
    held = set(layer_group.parts_of(node.node_tree))
    return [_PART_WORDS[p] for p in needed(cfg.get("bsdf", "PRINCIPLED"), node) if p not in held]
