# SPDX-License-Identifier: GPL-3.0-or-later
"""Shader node groups exposing the perceptual parameters (in-shader mapping).

One group per (kind, distribution, anisotropic, smooth): a material only carries the nodes its
configuration needs (no anisotropy nodes when isotropic, no Bézier unless smooth).  Built from
built-in nodes only, so files render the same without the add-on.
"""
import bpy

from ... import constants as K
from ...core import node_math
from ...core.graph import Graph
from ...core.lobes import check_kind
from . import stamp
from ..nodes.builder import TreeBuilder
from ..nodes.emit import emit
from ..nodes.lobes import build_lobes

__all__ = ("GROUP_VERSION", "group_label", "group_name", "group_users", "restore_group_users",
           "rebuild_interface", "build_group", "fits", "ensure_group", "all_configurations")

#: Bumped when what an in-shader group holds changes (5: cheaper node kinds, docs/performance.md
#: "What a node costs"; 6: a cheaper Multiscatter Newton step).
GROUP_VERSION = 6


# Labels from constants' vocabulary (earlier versions named it "Multi GGX": such a group is
# found by its stamp, as a renamed one).
_KIND_LABEL = {t.id: t.label for t in K.KIND_TERMS}
_DIST_LABEL = {t.id: t.label for t in K.DISTRIBUTION_TERMS}


def group_label(distribution="GGX", anisotropic=False, smooth=False):
    """The configuration part of a group's name, e.g. "GGX, Aniso, Smooth" (menu item text)."""
    parts = [_DIST_LABEL[distribution]]
    if anisotropic:
        parts.append("Aniso")
    if smooth:
        parts.append("Smooth")
    return ", ".join(parts)


def group_name(kind, distribution="GGX", anisotropic=False, smooth=False):
    """E.g. "Hazy Gloss Conductor (GGX, Aniso, Smooth)": under Blender 4.5's 63-byte ID limit."""
    return f"Hazy Gloss {_KIND_LABEL[kind]} ({group_label(distribution, anisotropic, smooth)})"


def _socket(iface, name, kind, *, parent=None, default=None, lo=None, hi=None, desc="",
            subtype=None, hide_value=False, in_out="INPUT"):
    s = iface.new_socket(name=name, in_out=in_out, socket_type=kind, parent=parent)
    if subtype is not None and hasattr(s, "subtype"):
        try:
            s.subtype = subtype
        except (TypeError, AttributeError):
            pass
    if default is not None:
        s.default_value = default
    if lo is not None:
        s.min_value = lo
    if hi is not None:
        s.max_value = hi
    s.description = desc
    s.hide_value = hide_value
    return s


def _interface(ng, kind, anisotropic, smooth):
    it = ng.interface
    _socket(it, "BSDF", "NodeSocketShader", in_out="OUTPUT", desc="The composite BRDF of Eq. 1")
    _socket(it, "Beta", "NodeSocketFloat", in_out="OUTPUT", desc="β, mixture ratio of the wide lobe (Eq. 4)")
    _socket(it, "Reflectivity", "NodeSocketColor", in_out="OUTPUT", desc="r, global reflectivity F_r(0) (Eq. 5)")
    _socket(it, "Peak Ratio", "NodeSocketFloat", in_out="OUTPUT", desc="p = f_w(n,n)/f_n(n,n) (Table 2)")
    _socket(it, "Peak Complement", "NodeSocketFloat", in_out="OUTPUT",
            desc="1 - p, computed without cancellation")

    core = it.new_panel("Core")
    _socket(it, "Core Reflectivity", "NodeSocketColor", parent=core, default=(0.5, 0.5, 0.5, 1.0),
            desc="r_c: reflectivity of the sharp core at normal incidence (linear RGB)")
    if kind == "CONDUCTOR":
        _socket(it, "Edge Tint", "NodeSocketColor", parent=core, default=(0.0, 0.0, 0.0, 1.0),
                desc="g: edge tint (Gulbrandsen 2014); black = dielectric-like Fresnel (κ = 0)")
    _socket(it, "Roughness", "NodeSocketFloat", parent=core, default=0.1, lo=0.0, hi=1.0,
            subtype="FACTOR", desc="Core roughness in Blender's convention R = √α_n "
            f"(values below {K.MIN_ROUGHNESS} are raised to it: Cycles' mirror cut-off)")
    if anisotropic:
        _socket(it, "Anisotropy", "NodeSocketFloat", parent=core, default=0.0, lo=0.0, hi=1.0,
                subtype="FACTOR", desc="Core anisotropy (Metallic BSDF convention): "
                "α_n^x = R²/s, α_n^y = R² s, s = √(1-0.9 a)")
        _socket(it, "Rotation", "NodeSocketFloat", parent=core, default=0.0, lo=0.0, hi=1.0,
                subtype="FACTOR", desc="Rotation of the tangent, in turns")
        _socket(it, "Tangent", "NodeSocketVector", parent=core, hide_value=True,
                desc="Tangent (x axis of α^x and λ_h^x); link an explicit tangent")

    haze = it.new_panel("Haze")
    _socket(it, "Haziness", "NodeSocketFloat", parent=haze, default=0.1, lo=0.0, hi=K.MAX_HAZINESS,
            subtype="FACTOR", desc="β_h ∈ [0, 1): proportion of the available haze (Eq. 7). "
            "0-0.1 typical for dielectrics, up to 0.99 for metals")
    if anisotropic:
        _socket(it, "Haze Extent X", "NodeSocketFloat", parent=haze, default=5.0, lo=0.0, hi=1000.0,
                desc="λ_h^x: halo width along the tangent in units of √(α_n^x α_n^y) (Eq. 8)")
        _socket(it, "Haze Extent Y", "NodeSocketFloat", parent=haze, default=5.0, lo=0.0, hi=1000.0,
                desc="λ_h^y: halo width along the bitangent in units of √(α_n^x α_n^y) (Eq. 8)")
    else:
        _socket(it, "Haze Extent", "NodeSocketFloat", parent=haze, default=5.0, lo=0.0, hi=1000.0,
                desc="λ_h: halo width in units of α_n, α_w = α_n (1 + λ_h) (Eq. 8)")
    if smooth:
        _socket(it, "Smoothness", "NodeSocketFloat", parent=haze, default=2.0, lo=K.MIN_SMOOTHNESS, hi=1e6,
                desc="w: weight of the rational Bézier (Eqs. 12-15); large w tends to Eq. 7")

    if kind == "DIELECTRIC":
        base = it.new_panel("Base")
        _socket(it, "Base Color", "NodeSocketColor", parent=base, default=(0.0, 0.0, 0.0, 1.0),
                desc="Diffuse colour under the specular layer (Principled BSDF)")
        _socket(it, "Transmission", "NodeSocketFloat", parent=base, default=0.0, lo=0.0, hi=1.0,
                subtype="FACTOR", desc="Transmission weight; the BTDF shares β, η and α (paper §4.2)")
    _socket(it, "Normal", "NodeSocketVector", hide_value=True, desc="Shading normal (e.g. normal map)")


def _interface_items(iface):
    """What an interface holds, in order: (kind, name, socket type, direction, panel)."""
    out = []
    for item in iface.items_tree:
        parent = getattr(getattr(item, "parent", None), "name", None)
        if item.item_type == "SOCKET":
            out.append(("SOCKET", item.name, item.socket_type, item.in_out, parent))
        else:
            out.append((item.item_type, item.name, parent))
    return out


_SOCKET_ATTRS = ("default_value", "min_value", "max_value", "description", "hide_value")


def group_users(ng):
    """Group nodes using ``ng`` in materials and node groups, with their links and unlinked
    input values by socket name (to restore them after the interface is made anew)."""
    trees = [m.node_tree for m in bpy.data.materials if m.node_tree is not None]
    trees += [t for t in bpy.data.node_groups if t != ng]
    found = []
    for tree in trees:
        for node in tree.nodes:
            if node.bl_idname != "ShaderNodeGroup" or node.node_tree != ng:
                continue
            ins = [(s.name, l.from_socket) for s in node.inputs for l in s.links]
            outs = [(s.name, l.to_socket) for s in node.outputs for l in s.links]
            vals = {s.name: (tuple(s.default_value) if hasattr(s.default_value, "__len__")
                             else s.default_value)
                    for s in node.inputs if not s.is_linked and hasattr(s, "default_value")}
            found.append((tree, node.name, ins, outs, vals))
    return found


def restore_group_users(found):
    for tree, name, ins, outs, vals in found:
        node = tree.nodes.get(name)
        if node is None:
            continue
        for sname, v in vals.items():
            sock = node.inputs.get(sname)
            if sock is not None and hasattr(sock, "default_value") and not sock.is_linked:
                try:
                    sock.default_value = v
                except (TypeError, ValueError):
                    pass
        for sname, src in ins:
            if node.inputs.get(sname) is not None:
                tree.links.new(src, node.inputs[sname])
        for sname, dst in outs:
            if node.outputs.get(sname) is not None:
                tree.links.new(node.outputs[sname], dst)


def rebuild_interface(ng, make_interface, update_sockets=True):
    """Give ``ng`` the interface ``make_interface(tree)`` makes.  A group being rebuilt (an
    outdated version in the user's file) keeps its sockets when they are the same, so every
    link and value its group nodes have stays (``update_sockets``: their defaults, ranges and
    descriptions become the new ones); otherwise the interface is made anew and the group
    nodes' links and values are put back by socket name."""
    if not len(ng.interface.items_tree):
        make_interface(ng)
        return
    tmp = bpy.data.node_groups.new(".Hazy Gloss interface", "ShaderNodeTree")
    try:
        make_interface(tmp)
        if _interface_items(ng.interface) == _interface_items(tmp.interface):
            if update_sockets:
                for have, want in zip(ng.interface.items_tree, tmp.interface.items_tree):
                    for attr in _SOCKET_ATTRS:
                        if hasattr(want, attr) and hasattr(have, attr):
                            setattr(have, attr, getattr(want, attr))
            return
        found = group_users(ng)
        ng.interface.clear()
        make_interface(ng)
        restore_group_users(found)
    finally:
        bpy.data.node_groups.remove(tmp)


def build_group(ng, kind, distribution, anisotropic, smooth):
    ng.nodes.clear()
    rebuild_interface(ng, lambda tree: _interface(tree, kind, anisotropic, smooth))
    gin = ng.nodes.new("NodeGroupInput")
    gin.location = (-300, 0)
    gout = ng.nodes.new("NodeGroupOutput")
    tb = TreeBuilder(ng)
    names = {"core_reflectivity": "Core Reflectivity", "edge_tint": "Edge Tint",
             "roughness": "Roughness", "haziness": "Haziness",
             "haze_extent_x": "Haze Extent X" if anisotropic else "Haze Extent",
             "haze_extent_y": "Haze Extent Y", "anisotropy": "Anisotropy", "rotation": "Rotation",
             "smoothness": "Smoothness"}
    sources = {k: gin.outputs[v] for k, v in names.items() if v in gin.outputs}
    g = Graph()
    src = {k: g.input(k, vector=node_math.INPUTS[k]) for k in sources}
    if not anisotropic:
        src["haze_extent_y"] = src["haze_extent_x"]
    # Multiscatter GGX: β and r solved for Cycles' energy factor (docs/mapping.md §11)
    m = emit(tb, g, node_math.mapping(g, src, kind=kind, anisotropic=anisotropic, smooth=smooth,
                                      distribution=distribution,
                                      multiscatter=distribution == "MULTI_GGX"), sources)
    narrow = dict(roughness=m["roughness"], anisotropy=None, rotation=None)
    wide = dict(roughness=m["roughness_wide"], anisotropy=None, rotation=None)
    if anisotropic:
        a_n = m["anisotropy_narrow"] if kind == "LEGACY" else gin.outputs["Anisotropy"]
        narrow.update(anisotropy=a_n, rotation=gin.outputs["Rotation"])
        wide.update(anisotropy=m["anisotropy_wide"], rotation=m["rotation_wide"])
    if kind == "CONDUCTOR":
        fresnel = dict(ior=m["ior"], extinction=m["extinction"])
    elif kind == "DIELECTRIC":
        fresnel = dict(ior=m["ior"], specular_tint=m["specular_tint"],
                       base_color=gin.outputs["Base Color"], transmission=gin.outputs["Transmission"])
    else:
        fresnel = dict(colour_narrow=m["colour_narrow"], colour_wide=m["colour_wide"])
    shared = dict(normal=gin.outputs["Normal"],
                  tangent=gin.outputs["Tangent"] if anisotropic else None)
    depth = 1 + tb.max_depth
    bsdf = build_lobes(tb, kind, distribution, beta=m["beta"], narrow=narrow, wide=wide,
                       fresnel=fresnel, shared=shared, depth=depth)
    gout.location = (180.0 * (depth + 3), 0)
    for name, key in (("BSDF", None), ("Beta", "beta"), ("Reflectivity", "reflectivity"),
                      ("Peak Ratio", "peak_ratio"), ("Peak Complement", "peak_complement")):
        tb.feed(gout.inputs[name], bsdf if key is None else m[key])
    return m


def fits(ng, kind, distribution="GGX", anisotropic=False, smooth=False):
    """Whether ``ng`` is the add-on's current group for this configuration, by its stamp (so a
    group the user renamed, F2 on a group node, still is)."""
    if ng is None or ng.library is not None:
        return False
    g = stamp.group(ng, K.GROUP_STAMP) or {}
    return (g.get("version") == GROUP_VERSION and g.get("kind") == kind
            and g.get("distribution") == distribution
            and bool(g.get("anisotropic")) == bool(anisotropic)
            and bool(g.get("smooth")) == bool(smooth))


def ensure_group(kind, distribution="GGX", anisotropic=False, smooth=False):
    """The group for this configuration, built on first use and rebuilt when outdated.  Found
    by its name, else by its stamp: a group the user renamed is taken, not copied."""
    check_kind(kind, distribution)
    name = group_name(kind, distribution, anisotropic, smooth)
    ng = bpy.data.node_groups.get(name)
    if ng is not None and not ng.library and \
            (stamp.group(ng, K.GROUP_STAMP) or {}).get("version") == GROUP_VERSION:
        return ng
    if ng is None:
        renamed = next((g for g in bpy.data.node_groups
                        if fits(g, kind, distribution, anisotropic, smooth)), None)
        if renamed is not None:
            return renamed
        ng = bpy.data.node_groups.new(name, "ShaderNodeTree")
    elif ng.library:
        return ng
    build_group(ng, kind, distribution, anisotropic, smooth)
    ng[K.GROUP_STAMP] = {"version": GROUP_VERSION, "kind": kind, "distribution": distribution,
                 "anisotropic": int(anisotropic), "smooth": int(smooth)}
    return ng


def all_configurations():
    for kind, dists in K.NODE_DISTRIBUTIONS.items():
        for dist in dists:
            for aniso in (False, True):
                for smooth in (False, True):
                    yield kind, dist, aniso, smooth
