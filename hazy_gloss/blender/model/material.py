# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy materials in Blender: building and updating their node trees.

A hazy material carries its perceptual parameters as an ID property (constants.STAMP), so a
saved file keeps them and renders identically where the add-on is not installed (only built-in
nodes are used).  The add-on's nodes carry a role (constants.ROLE, a node custom property) and
a name starting with "HG "; everything else in the tree is the user's and is never touched.

- lean (default): the lobes and their mix with physical values from Python
  (core.lobes.describe); one lobe when there is no halo; anisotropy inputs and a Tangent node
  only when anisotropic;
- in-shader: one group node (blender.model.groups) whose perceptual inputs take textures.

A change of parameters sets socket values when the tree already has the right structure, and
rebuilds only when the structure must change (kind, distribution of a group, isotropic <->
anisotropic, halo <-> none, lean <-> in-shader), keeping the user's links into and out of the
hazy nodes, where the user moved them, and their labels.

Reading and checking a hazy material (its stamped parameters, whether it can be edited) is
blender.model.material_read; the user's node-editor edits of the values written here, and
reading them back into the stamp, blender.model.material_edits.
"""
from typing import NamedTuple

import numpy as np

from ... import constants as K
from ...core.lobes import describe
from ...core.parameters import is_anisotropic, normalise
from .. import compat
from . import stamp
from ..nodes.builder import TreeBuilder, set_if_changed
from . import groups
from .groups import ensure_group
from ..nodes.lobes import ANISO_INPUTS, LOBE_NODES, build_lobes, tangent
from ..nodes.ownership import is_ours, output_node, ours, role  # noqa: F401  (re-exported)

GROUP_ROLE = "Hazy Gloss"
GROUP_NODE = f"{K.NODE_PREFIX} {GROUP_ROLE}"  # its default name
STAMP_VERSION = 2


# --------------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------------


def lobes_for(p, **kw):
    """core.lobes.describe for one material's normalised parameters ``p``."""
    return describe(p["kind"], p["distribution"], core_reflectivity=p["core_reflectivity"],
                    edge_tint=p["edge_tint"], roughness=p["roughness"],
                    anisotropy=p["anisotropy"], rotation=p["rotation"], haziness=p["haziness"],
                    haze_extent=p["haze_extent"], smoothness=p["smoothness"],
                    anisotropic=is_anisotropic(p), **kw)


def map_parameters(p):
    """The HazeMapping one material renders with (α <= 1, aspect <= 10, roughness above the
    mirror cut-off).  Raises ValueError on invalid values."""
    return lobes_for(p).mapping


def write_stamp(mat, p):
    """Stamp the normalised parameters ``p`` on ``mat`` (constants.STAMP, with its version)."""
    d = {k: v for k, v in p.items() if k != "smoothness"}
    d["use_smoothness"] = p["smoothness"] is not None
    d["smoothness"] = p["smoothness"] if p["smoothness"] is not None else 2.0
    d["version"] = STAMP_VERSION
    mat[K.STAMP] = d


# --------------------------------------------------------------------------------------------
# The add-on's nodes
# --------------------------------------------------------------------------------------------


def _by_identifier(sockets, identifier):
    for s in sockets:
        if s.identifier == identifier:
            return s
    return None


#: Roles of the node whose output is a hazy material's BSDF, first match wins.
_FINAL_ROLES = ("Lobe mix", "Lobe sum", GROUP_ROLE, "Narrow lobe")


def hazy_output(tree):
    """The output socket of the add-on's BSDF in ``tree`` (the mix, the group, or the core lobe
    alone), or None."""
    mine = ours(tree)
    for r in _FINAL_ROLES:
        if r in mine:
            return mine[r].outputs[0]
    return None


def remove_ours(tree):
    for n in list(ours(tree).values()):
        tree.nodes.remove(n)


#: What the user may set on the add-on's nodes in the node editor that a rebuild keeps (for
#: every role the rebuilt tree still has), besides their location: set in this order (the
#: parent frame before the location, which is relative to it).
_KEPT = ("name", "label", "parent", "width", "hide", "use_custom_color", "color")


class UserLinks:
    """The links between the user's nodes and the hazy nodes, recorded before a rebuild and
    restored after it, with what the user set on our nodes in the node editor: name (F2 on
    older keymaps, the sidebar), label, frame, width, collapse, colour, and where each of them
    is (a single node moved stays where it was put; new nodes follow the moved BSDF).
    ``dropped`` lists group inputs that no longer exist (e.g. Edge Tint of a dielectric)."""

    def __init__(self, tree):
        self.tree = tree
        self.incoming = []  # (from node name, from socket identifier, our role, to input name)
        self.outgoing = []  # (our role, to node name, to socket identifier)
        self.surface_from = None
        self.anchor = None  # (role, location) of the node feeding the surface
        self.labels = {}
        self.dropped = []
        mine = ours(tree)
        by_node = {n.as_pointer(): r for r, n in mine.items()}
        surf = output_node(tree).inputs["Surface"]
        for link in tree.links:
            ra = by_node.get(link.from_node.as_pointer())
            rb = by_node.get(link.to_node.as_pointer())
            if rb is not None and ra is None:
                self.incoming.append((link.from_node.name, link.from_socket.identifier, rb,
                                      link.to_socket.name))
            elif ra is not None and rb is None:
                if link.to_socket == surf:
                    self.anchor = (ra, tuple(link.from_node.location))
                else:
                    self.outgoing.append((ra, link.to_node.name, link.to_socket.identifier))
        if surf.is_linked and by_node.get(surf.links[0].from_node.as_pointer()) is None:
            self.surface_from = (surf.links[0].from_node.name, surf.links[0].from_socket.identifier)
        self.kept = {}  # role -> {property: value}
        for r, n in mine.items():
            if n.label:
                self.labels[r] = n.label
            self.kept[r] = {"name": n.name, "label": n.label,
                            "parent": n.parent.name if n.parent is not None else None,
                            "width": n.width, "hide": n.hide,
                            "use_custom_color": n.use_custom_color, "color": tuple(n.color)}
        self.locations = {r: tuple(n.location) for r, n in mine.items()}

    @property
    def textured_inputs(self):
        return sorted({i[3] for i in self.incoming if i[2] == GROUP_ROLE})

    def restore(self, final):
        """Relink after a rebuild whose BSDF output is ``final``."""
        tree = self.tree
        nodes = tree.nodes
        mine = ours(tree)
        final_role = role(final.node) if final is not None else None
        if self.anchor is not None and final is not None:  # new nodes follow the moved BSDF
            dx = self.anchor[1][0] - final.node.location.x
            dy = self.anchor[1][1] - final.node.location.y
            for n in mine.values():
                n.location = (n.location.x + dx, n.location.y + dy)
        for r, n in mine.items():  # what the user set on a node that is still there
            kept = self.kept.get(r)
            if kept is None:
                continue
            for attr in _KEPT:
                value = kept[attr]
                if attr == "parent":
                    value = nodes.get(value) if value is not None else None
                    if value is not None and value.bl_idname != "NodeFrame":
                        continue
                if attr == "name" and value == n.name:
                    continue
                try:
                    if getattr(n, attr) != value:
                        setattr(n, attr, value)
                except (TypeError, ValueError, AttributeError):
                    pass
            n.location = self.locations[r]
        surf = output_node(tree).inputs["Surface"]
        if self.surface_from is not None:
            src = nodes.get(self.surface_from[0])
            sock = _by_identifier(src.outputs, self.surface_from[1]) if src else None
            if sock is not None:
                tree.links.new(sock, surf)
        for r, to_name, ident in self.outgoing:
            node = nodes.get(to_name)
            sock = _by_identifier(node.inputs, ident) if node else None
            src = final if r == final_role or r not in mine else mine[r].outputs[0]
            if sock is not None and src is not None:
                tree.links.new(src, sock)
        for from_name, ident, r, to_input in self.incoming:
            src = nodes.get(from_name)
            sock = _by_identifier(src.outputs, ident) if src else None
            if sock is None:
                continue
            target = mine[r].inputs.get(to_input) if r in mine else None
            if target is None:
                self.dropped.append(to_input)
                continue
            tree.links.new(sock, target)
        # an add-on tangent replaced by the user's tangent is left dangling: remove it
        t = ours(tree).get("Tangent")
        if t is not None and not any(s.is_linked for s in t.outputs):
            nodes.remove(t)


# --------------------------------------------------------------------------------------------
# Building
# --------------------------------------------------------------------------------------------


def _lobe_values(d, which):
    lobe = d.narrow if which == "narrow" else d.wide
    return dict(roughness=lobe.roughness, anisotropy=lobe.anisotropy, rotation=lobe.rotation)


def _fresnel_values(p, d):
    f = dict(d.fresnel)
    to_tuple = lambda v: tuple(float(x) for x in np.asarray(v).ravel())  # noqa: E731
    for k in ("ior", "extinction", "specular_tint", "colour_narrow", "colour_wide"):
        if k in f:
            f[k] = to_tuple(f[k]) if np.ndim(f[k]) else float(f[k])
    if p["kind"] == "DIELECTRIC":
        f.update(base_color=p["base_color"], transmission=p["transmission"])
    return f


def _build_lean(tb, p, d):
    shared = {"tangent": tangent(tb, p["tangent"], 0) if d.anisotropic else None}
    wide = _lobe_values(d, "wide") if d.wide is not None else None
    return build_lobes(tb, p["kind"], p["distribution"], beta=d.beta,
                       narrow=_lobe_values(d, "narrow"), wide=wide,
                       fresnel=_fresnel_values(p, d), shared=shared, depth=1)


def _group_values(p):
    """{group input name: value} of the perceptual parameters."""
    v = {"Core Reflectivity": p["core_reflectivity"], "Roughness": p["roughness"],
         "Haziness": p["haziness"]}
    if p["kind"] == "CONDUCTOR":
        v["Edge Tint"] = p["edge_tint"]
    if is_anisotropic(p):
        v.update({"Anisotropy": p["anisotropy"], "Rotation": p["rotation"],
                  "Haze Extent X": p["haze_extent"][0], "Haze Extent Y": p["haze_extent"][1]})
    else:
        v["Haze Extent"] = p["haze_extent"][0]
    if p["smoothness"] is not None:
        v["Smoothness"] = p["smoothness"]
    if p["kind"] == "DIELECTRIC":
        v.update({"Base Color": p["base_color"], "Transmission": p["transmission"]})
    return v


def _build_in_shader(tb, p):
    aniso = is_anisotropic(p)
    g = tb.node("ShaderNodeGroup", name=GROUP_ROLE, depth=1)
    g.node_tree = ensure_group(p["kind"], p["distribution"], aniso, p["smoothness"] is not None)
    g.width = 240
    for name, value in _group_values(p).items():
        tb.feed(g.inputs[name], value)
    if aniso:
        tb.link(tangent(tb, p["tangent"], 0), g.inputs["Tangent"])
    return g.outputs["BSDF"]


def _structure(p, d):
    """What decides which nodes a material has (values of the same structure are set in place)."""
    aniso = bool(d.anisotropic)
    if p["shader_mapping"]:
        return ("in-shader", p["kind"], p["distribution"], aniso, p["smoothness"] is not None)
    return ("lean", p["kind"], aniso, d.wide is not None)


def _build(mat, p, d):
    tree = mat.node_tree
    remove_ours(tree)
    tb = TreeBuilder(tree, x0=600.0, roles=True)
    bsdf = _build_in_shader(tb, p) if p["shader_mapping"] else _build_lean(tb, p, d)
    tree.links.new(bsdf, output_node(tree).inputs["Surface"])
    return bsdf


def _set(node, name, value):
    sock = node.inputs.get(name)
    if sock is None or sock.is_linked or value is None:
        return
    set_if_changed(sock, value)


class Write(NamedTuple):
    """One value the add-on writes into its nodes: an input's default value, or a node
    property (``attr``: distribution, a Tangent's direction and axis)."""

    role: str
    name: str
    value: object
    attr: bool = False


def group_fits(ng, p, anisotropic):
    """Whether the node group ``ng`` is the add-on's group for ``p``'s configuration (by its
    stamp, so a group the user renamed still fits)."""
    return groups.fits(ng, p["kind"], p["distribution"], anisotropic, p["smoothness"] is not None)


def writes(mat, p, d):
    """Every value the add-on writes into a tree of ``p``'s structure ([Write]), or None when
    the tree does not have that structure (the caller rebuilds)."""
    mine = ours(mat.node_tree)
    out = []
    if p["shader_mapping"]:
        g = mine.get(GROUP_ROLE)
        if g is None or g.bl_idname != "ShaderNodeGroup" or \
                not group_fits(g.node_tree, p, d.anisotropic):
            return None
        out += [Write(GROUP_ROLE, name, value) for name, value in _group_values(p).items()]
    else:
        node_type = LOBE_NODES[p["kind"]]
        narrow, wide = mine.get("Narrow lobe"), mine.get("Wide lobe")
        if narrow is None or narrow.bl_idname not in node_type or \
                (d.wide is not None) != (wide is not None) or \
                (wide is not None and wide.bl_idname not in node_type):
            return None
        mix_role = "Lobe sum" if p["kind"] == "LEGACY" else "Lobe mix"
        if (d.wide is not None) != (mix_role in mine):
            return None
        f = _fresnel_values(p, d)
        for which, role_, node in (("narrow", "Narrow lobe", narrow), ("wide", "Wide lobe", wide)):
            if node is None:
                continue
            out.append(Write(role_, "distribution", p["distribution"], True))
            lobe = _lobe_values(d, which)
            out.append(Write(role_, "Roughness", lobe["roughness"]))
            if d.anisotropic:
                a_name, r_name = ANISO_INPUTS[p["kind"]]
                out += [Write(role_, a_name, lobe["anisotropy"]),
                        Write(role_, r_name, lobe["rotation"])]
            if p["kind"] == "CONDUCTOR":
                out += [Write(role_, "IOR", f["ior"]), Write(role_, "Extinction", f["extinction"])]
            elif p["kind"] == "DIELECTRIC":
                out += [Write(role_, name, f[key]) for name, key in _DIELECTRIC_INPUTS]
            else:
                out.append(Write(role_, "Color", f["colour_" + which]))
        if mix_role in mine and p["kind"] != "LEGACY":
            out.append(Write(mix_role, "Fac", d.beta))
    t = mine.get("Tangent")
    if d.anisotropic and t is not None and t.bl_idname == "ShaderNodeTangent":
        if p["tangent"] == "UV_MAP":
            out.append(Write("Tangent", "direction_type", "UV_MAP", True))
        else:
            out += [Write("Tangent", "direction_type", "RADIAL", True),
                    Write("Tangent", "axis", p["tangent"][-1], True)]
    return out


_DIELECTRIC_INPUTS = (("IOR", "ior"), ("Specular Tint", "specular_tint"),
                      ("Base Color", "base_color"), ("Transmission Weight", "transmission"))


def _update_values(mat, p, d):
    """Write the values of ``p`` into a tree of the right structure.  Returns False when the
    tree does not have it (the caller rebuilds)."""
    ws = writes(mat, p, d)
    if ws is None:
        return False
    mine = ours(mat.node_tree)
    for w in ws:
        node = mine.get(w.role)
        if node is None:
            continue
        if w.attr:
            if getattr(node, w.name) != w.value:
                setattr(node, w.name, w.value)
        else:
            _set(node, w.name, w.value)
    return True


# --------------------------------------------------------------------------------------------
# What the add-on wrote (blender.model.material_edits compares the nodes with it)
# --------------------------------------------------------------------------------------------

#: The stamp's record of what the add-on last wrote: {role: {input or "@property": value}}.
WRITTEN = "written"


def current_value(node, w):
    """What a Write's target holds now (None for a linked input: the link is the source)."""
    if w.attr:
        return getattr(node, w.name, None)
    sock = node.inputs.get(w.name)
    if sock is None or sock.is_linked or not hasattr(sock, "default_value"):
        return None
    v = sock.default_value
    return tuple(float(x) for x in v) if hasattr(v, "__len__") else float(v)


def record_writes(mat, p, d):
    """Keep in the stamp what the nodes hold now for every value the add-on writes."""
    ws = writes(mat, p, d) or []
    mine = ours(mat.node_tree)
    rec = {}
    for w in ws:
        node = mine.get(w.role)
        now = current_value(node, w) if node is not None else None
        if now is not None:
            rec.setdefault(w.role, {})[("@" if w.attr else "") + w.name] = \
                list(now) if isinstance(now, tuple) else now
    mat[K.STAMP][WRITTEN] = rec


def apply(mat, p, *, force_rebuild=False):
    """Make ``mat``'s hazy nodes render parameters ``p`` (normalised): set values when the tree
    has the right structure, else rebuild it keeping the user's links, locations and labels.
    Returns (HazeMapping, dropped group inputs)."""
    if mat.library is not None:
        raise ValueError(f"material {mat.name!r} is linked from a library and cannot be edited")
    d = lobes_for(p)  # raises before touching the tree
    structure = _structure(p, d)
    if K.RECOMPOSITE_STAMP in mat:  # an edit leaves recomposite mode: rebuild the normal material
        force_rebuild = True
        del mat[K.RECOMPOSITE_STAMP]
    old = stamp.group(mat, K.STAMP)
    same = old is not None and old.get("structure") == repr(structure) and not force_rebuild
    dropped = []
    if not (same and _update_values(mat, p, d)):
        keep = UserLinks(mat.node_tree)
        final = _build(mat, p, d)
        keep.restore(final)
        dropped = keep.dropped
    write_stamp(mat, p)
    mat[K.STAMP]["structure"] = repr(structure)
    record_writes(mat, p, d)
    return d.mapping, dropped


def create_material(name, **params):
    """A new hazy material (see hazy_gloss.api.create_material)."""
    p = normalise(params)
    lobes_for(p)  # validate before creating anything
    mat = compat.new_material(name)
    tree = mat.node_tree
    for n in [n for n in tree.nodes if n.bl_idname != "ShaderNodeOutputMaterial"]:
        tree.nodes.remove(n)
    apply(mat, p)
    return mat


__all__ = ("create_material", "map_parameters", "lobes_for", "apply", "is_ours", "ours", "role",
           "output_node", "GROUP_NODE", "WRITTEN", "current_value", "record_writes", "write_stamp",
           "writes", "GROUP_ROLE")
