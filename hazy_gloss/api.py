# SPDX-License-Identifier: GPL-3.0-or-later
"""Scripting API: create and update hazy materials (used by operators, tests and pipelines).

    import hazy_gloss; hazy_gloss.register()
    from hazy_gloss import api
    mat = api.create_material("Brushed", kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3),
                              edge_tint=(1, 0.8, 0.5), roughness=0.1, haziness=0.8, haze_extent=5)

Roughness is Blender's R = √α (α = R²).  Perceptual parameters are stamped on the material as
an ID property (``mat["hazy_gloss"]``), so a file saved with hazy materials keeps them and renders
identically where the add-on is not installed (only built-in nodes are used).
"""
import numpy as np

from .blender import compat
from .core import haze_mapping
from .node_groups.builder import TreeBuilder
from .node_groups.groups import ensure_group, min_roughness
from .node_groups.lobes import KINDS, build_lobes, check_distribution
from .utils.conventions import (ALPHA_MAX, MAX_ASPECT, alpha_from_roughness, glossy_anisotropy,
                                metallic_anisotropy, metallic_to_glossy_anisotropy, lobe_from_alpha)

STAMP = "hazy_gloss"
NODE_PREFIX = "HG"
PARAMETERS = ("kind", "distribution", "core_reflectivity", "edge_tint", "roughness", "anisotropy",
              "rotation", "haziness", "haze_extent", "smoothness", "shader_mapping", "base_color",
              "transmission", "tangent")

DEFAULTS = dict(kind="CONDUCTOR", distribution="GGX", core_reflectivity=(0.5, 0.5, 0.5),
                edge_tint=(0.0, 0.0, 0.0), roughness=0.1, anisotropy=0.0, rotation=0.0,
                haziness=0.5, haze_extent=(5.0, 5.0), smoothness=None, shader_mapping=False,
                base_color=(0.0, 0.0, 0.0), transmission=0.0, tangent="UV_MAP")


def _rgb(value, name):
    arr = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)) if np.ndim(value) == 0 \
        else np.asarray(value, dtype=np.float64)[:3]
    if arr.shape != (3,):
        raise ValueError(f"{name} must be a number or an RGB triple")
    return tuple(float(x) for x in arr)


def _pair(value):
    if isinstance(value, (tuple, list)):
        return float(value[0]), float(value[1])
    return float(value), float(value)


def normalise_parameters(params):
    """Fill defaults, check types and ranges; raise ValueError with a clear message."""
    unknown = set(params) - set(PARAMETERS)
    if unknown:
        raise ValueError(f"unknown hazy parameters: {', '.join(sorted(unknown))}")
    p = dict(DEFAULTS)
    p.update({k: v for k, v in params.items()})
    p["kind"] = str(p["kind"]).upper()
    p["distribution"] = str(p["distribution"]).upper()
    check_distribution(p["kind"], p["distribution"])
    p["core_reflectivity"] = _rgb(p["core_reflectivity"], "core_reflectivity")
    p["edge_tint"] = _rgb(p["edge_tint"], "edge_tint") if p["kind"] == "CONDUCTOR" else (0.0, 0.0, 0.0)
    p["base_color"] = _rgb(p["base_color"], "base_color")
    p["haze_extent"] = _pair(p["haze_extent"])
    for key in ("roughness", "anisotropy", "rotation", "haziness", "transmission"):
        p[key] = float(p[key])
    for key in ("roughness", "anisotropy", "transmission"):
        if not 0.0 <= p[key] <= 1.0:
            raise ValueError(f"{key} must be in [0, 1], got {p[key]}")
    if p["smoothness"] is not None:
        p["smoothness"] = float(p["smoothness"])
    p["shader_mapping"] = bool(p["shader_mapping"])
    if p["tangent"] not in ("UV_MAP", "RADIAL_X", "RADIAL_Y", "RADIAL_Z"):
        raise ValueError("tangent must be UV_MAP or RADIAL_X/Y/Z")
    return p


def is_anisotropic(p):
    return p["anisotropy"] > 0.0 or p["haze_extent"][0] != p["haze_extent"][1]


def map_parameters(p):
    """Run the haze mapping for one material as Cycles will render it (α <= 1, aspect <= 10,
    roughness above the mirror cut-off).  Raises ValueError on invalid values."""
    rough = max(p["roughness"], min_roughness(p["distribution"]))
    ax, ay = alpha_from_roughness(rough, p["anisotropy"])
    return haze_mapping(p["core_reflectivity"], p["edge_tint"], (float(ax), float(ay)),
                        p["haziness"], p["haze_extent"], distribution=p["distribution"],
                        smoothness=p["smoothness"], alpha_max=ALPHA_MAX, max_aspect=MAX_ASPECT,
                        strict=True)


# --------------------------------------------------------------------------------------------
# Material trees
# --------------------------------------------------------------------------------------------


def _output_node(tree):
    outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    for n in outs:
        if n.is_active_output:
            return n
    if outs:
        return outs[0]
    n = tree.nodes.new("ShaderNodeOutputMaterial")
    n.location = (1400, 0)
    return n


GROUP_NODE = NODE_PREFIX + " Hazy Gloss"


def is_ours(node):
    """A node the add-on built (and rebuilds); everything else in the tree is the user's."""
    return node.name.startswith(NODE_PREFIX + " ")



def _surface_socket(tree):
    out = _output_node(tree)
    return out.inputs["Surface"]


class _UserLinks:
    """Record the links between the user's nodes and the hazy nodes, restore them after a
    rebuild.  ``dropped`` lists inputs that no longer exist (e.g. Edge Tint of a dielectric)."""

    def __init__(self, mat):
        self.tree = mat.node_tree
        self.incoming = []  # (from_node, from_socket identifier, to input name)
        self.outgoing = []  # (to_node, to_socket identifier)
        self.surface_from = None
        self.location = None
        self.dropped = []
        tree = self.tree
        surf = _surface_socket(tree)
        for link in tree.links:
            a, b = link.from_node, link.to_node
            if is_ours(b) and not is_ours(a) and b.name == GROUP_NODE:
                self.incoming.append((a.name, link.from_socket.identifier, link.to_socket.name))
            elif is_ours(a) and not is_ours(b):
                self.location = tuple(a.location)  # the hazy BSDF's output node
                if link.to_socket != surf:
                    self.outgoing.append((b.name, link.to_socket.identifier))
        if surf.is_linked:
            src = surf.links[0].from_node
            if not is_ours(src):
                self.surface_from = (src.name, surf.links[0].from_socket.identifier)

    @property
    def has_textures(self):
        return bool(self.incoming)

    def restore(self):
        tree = self.tree
        nodes = tree.nodes
        surf = _surface_socket(tree)
        ours = surf.links[0].from_socket if surf.is_linked else None
        final = ours.node if ours is not None else None
        if final is not None and self.location is not None:  # keep where the user put our nodes
            dx = self.location[0] - final.location.x
            dy = self.location[1] - final.location.y
            if dx or dy:
                for n in nodes:
                    if is_ours(n):
                        n.location = (n.location.x + dx, n.location.y + dy)
        if self.surface_from is not None:
            src = nodes.get(self.surface_from[0])
            sock = _by_identifier(src.outputs, self.surface_from[1]) if src else None
            if sock is not None:
                tree.links.new(sock, surf)
        if ours is not None:
            for to_name, ident in self.outgoing:
                node = nodes.get(to_name)
                sock = _by_identifier(node.inputs, ident) if node else None
                if sock is not None:
                    tree.links.new(ours, sock)
        group = nodes.get(GROUP_NODE)
        for from_name, ident, to_input in self.incoming:
            src = nodes.get(from_name)
            sock = _by_identifier(src.outputs, ident) if src else None
            if sock is None:
                continue
            target = group.inputs.get(to_input) if group is not None else None
            if target is None:
                self.dropped.append(to_input)
                continue
            tree.links.new(sock, target)
        # an api-made tangent node replaced by the user's tangent is left dangling: remove it
        for n in [n for n in nodes if is_ours(n) and n.bl_idname == "ShaderNodeTangent"]:
            if not any(s.is_linked for s in n.outputs):
                nodes.remove(n)


def _by_identifier(sockets, identifier):
    for s in sockets:
        if s.identifier == identifier:
            return s
    return None


def _remove_ours(tree):
    for n in [n for n in tree.nodes if is_ours(n)]:
        tree.nodes.remove(n)


def _tangent(tb, p, depth):
    t = tb.node("ShaderNodeTangent", name="Tangent", depth=depth)
    if p["tangent"] == "UV_MAP":
        t.direction_type = "UV_MAP"
    else:
        t.direction_type = "RADIAL"
        t.axis = p["tangent"][-1]
    return t.outputs[0]


def _f(x):
    return float(np.asarray(x))


def _build_lean(tree, p, m):
    """Only what this material needs: two lobes and the mix with physical values from Python;
    one lobe when there is no halo; anisotropy inputs and a tangent only when anisotropic."""
    tb = TreeBuilder(tree, prefix=NODE_PREFIX, x0=600.0)
    kind, dist = p["kind"], p["distribution"]
    aniso = is_anisotropic(p)
    shared = {"tangent": _tangent(tb, p, 0) if aniso else None}
    rough = max(p["roughness"], min_roughness(dist))
    narrow = dict(roughness=rough, anisotropy=None, rotation=None)
    wx, wy = (_f(a) for a in m.alpha_wide)
    nx, ny = (_f(a) for a in alpha_from_roughness(rough, p["anisotropy"]))
    r_w, ratio, swap = lobe_from_alpha(wx, wy)
    wide = dict(roughness=_f(r_w), anisotropy=None, rotation=None)
    if aniso:
        a_n = p["anisotropy"] if kind != "LEGACY" else _f(metallic_to_glossy_anisotropy(p["anisotropy"]))
        narrow.update(anisotropy=a_n, rotation=p["rotation"])
        a_w = metallic_anisotropy(ratio) if kind != "LEGACY" else glossy_anisotropy(ratio)
        wide.update(anisotropy=_f(a_w), rotation=p["rotation"] + 0.25 * bool(swap))
    beta = _f(m.beta)
    if beta <= 0.0 or (wx == nx and wy == ny):
        wide = None  # no halo: the core lobe alone is Eq. 1 exactly
    r = tuple(float(x) for x in m.reflectivity)
    if kind == "CONDUCTOR":
        fresnel = dict(ior=tuple(float(x) for x in m.ior),
                       extinction=tuple(float(x) for x in m.extinction))
    elif kind == "DIELECTRIC":
        rc = np.asarray(p["core_reflectivity"])
        tint = tuple(float(x) for x in (rc / rc.max() if rc.max() > 0 else np.ones(3)))
        fresnel = dict(ior=_f(m.dielectric_ior), specular_tint=tint, base_color=p["base_color"],
                       transmission=p["transmission"])
    else:
        if wide is None:
            fresnel = dict(colour_narrow=r)
        else:
            fresnel = dict(colour_narrow=tuple(float(x) for x in m.weight_narrow),
                           colour_wide=tuple(float(x) for x in m.weight_wide))
    return build_lobes(tb, kind, dist, beta=beta, narrow=narrow, wide=wide, fresnel=fresnel,
                       shared=shared, depth=1)


def _build_in_shader(tree, p):
    tb = TreeBuilder(tree, prefix=NODE_PREFIX, x0=600.0)
    aniso = is_anisotropic(p)
    ng = ensure_group(p["kind"], p["distribution"], aniso, p["smoothness"] is not None)
    g = tb.node("ShaderNodeGroup", name="Hazy Gloss", depth=1)
    g.node_tree = ng
    g.width = 240
    ins = g.inputs
    tb.feed(ins["Core Reflectivity"], p["core_reflectivity"])
    if p["kind"] == "CONDUCTOR":
        tb.feed(ins["Edge Tint"], p["edge_tint"])
    tb.feed(ins["Roughness"], p["roughness"])
    tb.feed(ins["Haziness"], p["haziness"])
    if aniso:
        tb.feed(ins["Anisotropy"], p["anisotropy"])
        tb.feed(ins["Rotation"], p["rotation"])
        tb.feed(ins["Haze Extent X"], p["haze_extent"][0])
        tb.feed(ins["Haze Extent Y"], p["haze_extent"][1])
        tb.link(_tangent(tb, p, 0), ins["Tangent"])
    else:
        tb.feed(ins["Haze Extent"], p["haze_extent"][0])
    if p["smoothness"] is not None:
        tb.feed(ins["Smoothness"], p["smoothness"])
    if p["kind"] == "DIELECTRIC":
        tb.feed(ins["Base Color"], p["base_color"])
        tb.feed(ins["Transmission"], p["transmission"])
    return g.outputs["BSDF"]


def _stamp(mat, p):
    d = {k: v for k, v in p.items() if k != "smoothness"}
    d["use_smoothness"] = p["smoothness"] is not None
    d["smoothness"] = p["smoothness"] if p["smoothness"] is not None else 2.0
    d["version"] = 1
    mat[STAMP] = d


def read_parameters(mat):
    """The perceptual parameters stamped on a hazy material, or None."""
    d = mat.get(STAMP)
    if d is None:
        return None
    d = d.to_dict() if hasattr(d, "to_dict") else dict(d)
    p = {k: d[k] for k in PARAMETERS if k in d and k != "smoothness"}
    p["smoothness"] = float(d["smoothness"]) if d.get("use_smoothness") else None
    for k in ("core_reflectivity", "edge_tint", "base_color", "haze_extent"):
        if k in p:
            p[k] = tuple(float(x) for x in p[k])
    return normalise_parameters(p)


def is_hazy(mat):
    return mat is not None and STAMP in mat


def apply(mat, p):
    """(Re)build the hazy part of ``mat``'s node tree for parameters ``p`` (normalised)."""
    if mat.library is not None:
        raise ValueError(f"material {mat.name!r} is linked from a library and cannot be edited")
    m = map_parameters(p)  # raises before touching the tree
    tree = mat.node_tree
    _remove_ours(tree)
    bsdf = _build_in_shader(tree, p) if p["shader_mapping"] else _build_lean(tree, p, m)
    out = _output_node(tree)
    tree.links.new(bsdf, out.inputs["Surface"])
    _stamp(mat, p)
    return m


def create_material(name, *, kind="CONDUCTOR", core_reflectivity=(0.5, 0.5, 0.5), edge_tint=0.0,
                    roughness=0.1, anisotropy=0.0, haziness=0.5, haze_extent=5.0, smoothness=None,
                    distribution="GGX", shader_mapping=False, **extra):
    """Create a hazy material.  ``roughness`` is Blender's R = √α_n; ``haze_extent`` a number or
    an (x, y) pair; ``smoothness`` None (Eq. 7) or the Bézier weight w.  Extra keywords:
    rotation, base_color, transmission (dielectric), tangent ("UV_MAP" or "RADIAL_X/Y/Z")."""
    p = normalise_parameters(dict(kind=kind, core_reflectivity=core_reflectivity, edge_tint=edge_tint,
                                  roughness=roughness, anisotropy=anisotropy, haziness=haziness,
                                  haze_extent=haze_extent, smoothness=smoothness,
                                  distribution=distribution, shader_mapping=shader_mapping, **extra))
    map_parameters(p)  # validate before creating anything
    mat = compat.new_material(name)
    tree = mat.node_tree
    for n in [n for n in tree.nodes if n.bl_idname != "ShaderNodeOutputMaterial"]:
        tree.nodes.remove(n)
    apply(mat, p)
    return mat


def update_material(mat, **changes):
    """Change some perceptual parameters of a hazy material and rebuild its hazy nodes, keeping
    the user's links into the group (textures) and out of the BSDF (e.g. into a Mix Shader).
    Returns the HazeMapping of the new parameters."""
    return update_material_links(mat, **changes)[0]


def update_material_links(mat, **changes):
    """:func:`update_material`, also returning the group inputs whose links had to be dropped
    because the new configuration has no such input (e.g. Edge Tint of a dielectric)."""
    p = read_parameters(mat)
    if p is None:
        raise ValueError(f"material {mat.name!r} is not a hazy material")
    p.update(changes)
    p = normalise_parameters(p)
    keep = _UserLinks(mat)
    if keep.has_textures and not p["shader_mapping"]:
        names = ", ".join(sorted({i[2] for i in keep.incoming}))
        raise ValueError(f"Textures are connected to {names}: constant mapping cannot use "
                         f"them. Keep in-shader mapping, or disconnect them first")
    m = apply(mat, p)
    keep.restore()
    return m, keep.dropped


__all__ = ("create_material", "update_material", "read_parameters", "is_hazy", "map_parameters",
           "KINDS")


def convert_maps(inputs, out_dir, *, kind="CONDUCTOR", smoothness=None, distribution="GGX",
                 file_format="OPEN_EXR", **options):
    """Batch-convert perceptual maps into physical maps (paper §2.4); docs/textures.md.

    ``inputs`` maps parameter names (core_reflectivity, edge_tint, roughness or alpha, anisotropy,
    rotation, haziness, haze_extent or haze_extent_x + haze_extent_y) to an image path (``<UDIM>``
    token for tile sets), a ``bpy.types.Image``, or a constant; missing ones take the defaults of
    create_material.  Writes float OpenEXR (or 16-bit PNG) physical maps into ``out_dir``
    atomically and returns ``{map name: path}`` with ``.report`` (texels, clamped texels per
    reason and parameter, seconds, warnings).  Options: resample=False, prefix="",
    exr_codec="ZIP", material=None (wire the maps into that material's lean tree),
    interpolation="Linear", progress=None (callable(done, total, message)).
    Bad input raises hazy_gloss.convert.ConversionError (a ValueError) with a one-line message."""
    from .blender import convert as _convert
    return _convert.convert_maps(inputs, out_dir, kind=kind, smoothness=smoothness,
                                 distribution=distribution, file_format=file_format, **options)
