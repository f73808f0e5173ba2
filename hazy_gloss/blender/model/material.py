# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy materials in Blender: building, updating and reading their node trees.

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
"""
from typing import NamedTuple

import bpy
import numpy as np

from ... import constants as K
from ...core import inverse_haze_mapping
from ...core.conventions import lobe_alphas, metallic_anisotropy
from ...core.lobes import describe
from ...core.parameters import DEFAULTS, is_anisotropic, normalise
from .. import compat
from . import layer, stamp
from ..nodes.builder import TreeBuilder, set_if_changed, socket_value
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


def _stamp(mat, p):
    d = {k: v for k, v in p.items() if k != "smoothness"}
    d["use_smoothness"] = p["smoothness"] is not None
    d["smoothness"] = p["smoothness"] if p["smoothness"] is not None else 2.0
    d["version"] = STAMP_VERSION
    mat[K.STAMP] = d


def check_material(mat, caller):
    """TypeError (one line) unless ``mat`` is a bpy.types.Material."""
    if isinstance(mat, bpy.types.Material):
        return
    hint = ""
    if isinstance(mat, str):
        hint = f" (look it up first: {caller}(bpy.data.materials[{mat!r}], ...))"
    elif isinstance(mat, bpy.types.Object):
        hint = " (an object: pass obj.active_material)"
    raise TypeError(f"{caller} expects a bpy.types.Material, got {type(mat).__name__}{hint}")


def read_parameters(mat):
    """The perceptual parameters stamped on a hazy material, or None.  Raises ValueError (one
    line naming the material, the parameter and what is valid; blender.model.stamp.StampError) when
    the stored values do not read.  A layered material (Make Hazy on the user's BSDF) gives its
    haze parameters and the core's own (blender.model.layer.read), with ``layered`` True."""
    check_material(mat, "read_parameters")
    if K.STAMP not in mat:
        return None
    if layer.is_layered(mat):
        return layer.read(mat)
    values, problems = stamp.read_material(mat)
    if problems:
        raise stamp.StampError(stamp.material_problem(mat, problems))
    return normalise(values, explicit=())


def read_parameters_lenient(mat):
    """(parameters, problem): what the panel shows — the stamped parameters, the defaults for
    whatever does not read — and the one-line reason why not, or None.  Never raises."""
    try:
        return read_parameters(mat), None
    except (ValueError, TypeError) as exc:
        problem = str(exc)
    p = tree_defaults(mat)
    try:
        if layer.is_layered(mat):
            p.update(layer.haze_of(mat))
        else:
            values, _ = stamp.read_material(mat)
            p.update(values or {})
        return normalise(p, explicit=()), problem
    except (ValueError, TypeError):
        return normalise({}), problem


def tree_defaults(mat):
    """DEFAULTS, with what the tree tells for values a damaged stamp lost: in-shader mapping
    when the add-on's group node is there."""
    d = dict(DEFAULTS)
    tree = getattr(mat, "node_tree", None)
    if tree is not None:
        d["shader_mapping"] = GROUP_ROLE in ours(tree)
    return d


def is_hazy(mat):
    return mat is not None and K.STAMP in mat


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
# Node-editor edits: what the user changed in the add-on's nodes since the add-on wrote them
# --------------------------------------------------------------------------------------------

#: The stamp's record of what the add-on last wrote: {role: {input or "@property": value}}.
WRITTEN = "written"


def _current(node, w):
    """What a Write's target holds now (None for a linked input: the link is the source)."""
    if w.attr:
        return getattr(node, w.name, None)
    sock = node.inputs.get(w.name)
    if sock is None or sock.is_linked or not hasattr(sock, "default_value"):
        return None
    v = sock.default_value
    return tuple(float(x) for x in v) if hasattr(v, "__len__") else float(v)


def _record(mat, p, d):
    """Keep in the stamp what the nodes hold now for every value the add-on writes."""
    ws = writes(mat, p, d) or []
    mine = ours(mat.node_tree)
    rec = {}
    for w in ws:
        node = mine.get(w.role)
        now = _current(node, w) if node is not None else None
        if now is not None:
            rec.setdefault(w.role, {})[("@" if w.attr else "") + w.name] = \
                list(now) if isinstance(now, tuple) else now
    mat[K.STAMP][WRITTEN] = rec


def _differs(now, was):
    if isinstance(now, str) or isinstance(was, str):
        return now != was
    a = np.atleast_1d(np.asarray(now, dtype=np.float64))
    b = np.atleast_1d(np.asarray(was, dtype=np.float64))
    if a.shape != b.shape:
        n = min(a.size, b.size)  # an RGBA socket against an RGB value: alpha is not ours
        a, b = a[:n], b[:n]
    return bool(np.any(np.abs(a - b) > 1e-6 + 1e-5 * np.abs(b)))


def _readable(was, attr):
    """Whether a value of the stamp's record reads as what the add-on wrote: a setting's name,
    or a number or list of numbers (anyone can edit the stamp: the rest is not compared)."""
    if attr:
        return isinstance(was, str)
    number = lambda x: isinstance(x, (int, float)) and not isinstance(x, bool)  # noqa: E731
    return number(was) or (isinstance(was, list) and 0 < len(was) <= 4 and all(map(number, was)))


class Edit(NamedTuple):
    """A value the user changed in the node editor: the add-on wrote ``was``, the node holds
    ``now``."""

    role: str
    node: str  # the node's name now
    name: str
    now: object
    was: object
    attr: bool

    def __str__(self):
        return f"{self.node}: {self.name}"


def node_edits(mat, p=None):
    """[Edit] of the add-on's values the user changed in the node editor (socket values and
    node settings of a lean or in-shader tree of the stamped structure).  Compared with what
    the add-on last wrote (the stamp's record); for a material stamped before the record
    existed, with what the stamped parameters map to now."""
    if not is_hazy(mat) or mat.node_tree is None or layer.is_layered(mat):
        return []
    try:
        p = p or read_parameters(mat)
        d = lobes_for(p)
    except (ValueError, TypeError):
        return []
    ws = writes(mat, p, d)
    if ws is None:  # not the stamped structure: the next change rebuilds
        return []
    rec = (stamp.group(mat, K.STAMP) or {}).get(WRITTEN)
    mine = ours(mat.node_tree)
    out = []
    for w in ws:
        node = mine.get(w.role)
        if node is None:
            continue
        now = _current(node, w)
        if now is None:
            continue
        key = ("@" if w.attr else "") + w.name
        if isinstance(rec, dict):
            entry = rec.get(w.role)
            was = entry.get(key) if isinstance(entry, dict) else None
            if not _readable(was, w.attr):
                continue  # not recorded (or a damaged record): nothing to compare with
        else:
            was = w.value if w.attr else socket_value(node.inputs[w.name], w.value)
        if _differs(now, was):
            out.append(Edit(w.role, node.name, w.name, now, was, w.attr))
    return out


#: Group inputs -> the perceptual parameter they are (in-shader mapping).
_GROUP_KEYS = {"Core Reflectivity": "core_reflectivity", "Edge Tint": "edge_tint",
               "Roughness": "roughness", "Anisotropy": "anisotropy", "Rotation": "rotation",
               "Haziness": "haziness", "Smoothness": "smoothness", "Base Color": "base_color",
               "Transmission": "transmission"}


def _adopt_group(p, edits):
    """p with the group inputs the user edited (they are the perceptual parameters)."""
    q = dict(p)
    ex, ey = q["haze_extent"]
    for e in edits:
        v = e.now
        if e.role == "Tangent":
            continue
        if e.name == "Haze Extent":
            ex = ey = v
        elif e.name == "Haze Extent X":
            ex = v
        elif e.name == "Haze Extent Y":
            ey = v
        elif e.name in _GROUP_KEYS:
            q[_GROUP_KEYS[e.name]] = tuple(v[:3]) if isinstance(v, tuple) else v
    q["haze_extent"] = (ex, ey)
    return q


def _tangent_of(mat, p):
    t = ours(mat.node_tree).get("Tangent")
    if t is None or t.bl_idname != "ShaderNodeTangent":
        return p["tangent"]
    return "UV_MAP" if t.direction_type == "UV_MAP" else f"RADIAL_{t.axis}"


def _lobe_alpha(value, lobe, kind, anisotropic, rotation):
    """(α_x, α_y, rotation) of one lean lobe in its node's convention, long axis along x
    (``value(role, input)`` reads the lobe's inputs; an isotropic one keeps ``rotation``)."""
    if not anisotropic:
        a = float(np.clip(value(lobe, "Roughness"), 0.0, 1.0)) ** 2
        return a, a, rotation
    a_name, r_name = ANISO_INPUTS[kind]
    return lobe_alphas(value(lobe, "Roughness"), float(value(lobe, a_name)),
                       float(value(lobe, r_name)), glossy=kind == "LEGACY")


def _other_lobe(lobe):
    return "Wide lobe" if lobe == "Narrow lobe" else "Narrow lobe"


def _adopt_lean(mat, p, d, edits, pending=()):
    """p with a lean tree's values read back through the inverse haze mapping
    (core.inverse_haze_mapping), or None when they are not a hazy material's (the lobes no
    longer share one Fresnel term, a Glossy colour pair has no single β, ...).  A value shared
    by both lobes (the Fresnel inputs, a dielectric's base, the distribution) that the user
    changed on one lobe is taken as the new shared value.  ``pending``: edits not tried here,
    read as the add-on wrote them."""
    kind = p["kind"]
    mine = ours(mat.node_tree)
    narrow, wide = mine["Narrow lobe"], mine.get("Wide lobe")
    edited = {(e.role, e.name): e.now for e in edits}
    held = {(e.role, e.name): e.was for e in pending}

    def value(node_role, name):
        if (node_role, name) in edited:
            return edited[(node_role, name)]
        if name in _SHARED[kind] and (_other_lobe(node_role), name) in edited:
            return edited[(_other_lobe(node_role), name)]
        if (node_role, name) in held:
            v = held[(node_role, name)]
            return tuple(float(x) for x in v)[:3] if isinstance(v, (list, tuple)) else float(v)
        v = mine[node_role].inputs[name].default_value
        return tuple(float(x) for x in v)[:3] if hasattr(v, "__len__") else float(v)

    dist = edited.get(("Narrow lobe", "distribution")) or \
        edited.get(("Wide lobe", "distribution")) or p["distribution"]
    if dist not in K.NODE_DISTRIBUTIONS[kind] or dist == "MULTI_GGX":
        return None  # Multiscatter GGX: Cycles' energy factor is not inverted here
    aniso = bool(d.anisotropic)
    ax, ay, rot = _lobe_alpha(value, "Narrow lobe", kind, aniso, p["rotation"])
    rough = (ax * ay) ** 0.25
    anisotropy = float(metallic_anisotropy(ay / ax)) if aniso and ax > 0 else 0.0
    if wide is not None:
        wx, wy, wrot = _lobe_alpha(value, "Wide lobe", kind, aniso, p["rotation"])
        turn = (wrot - rot) % 0.5
        if aniso and abs(turn - 0.25) < 1e-4:
            wx, wy = wy, wx
        elif aniso and min(turn, 0.5 - turn) > 1e-4:
            return None  # the halo is rotated against the core
    else:
        wx, wy = (float(a) for a in d.mapping.alpha_wide)
    kw = {}
    if kind == "CONDUCTOR":
        if narrow.fresnel_type != "PHYSICAL_CONDUCTOR":
            return None
        kw = dict(ior=value("Narrow lobe", "IOR"), extinction=value("Narrow lobe", "Extinction"))
        beta = float(value("Lobe mix", "Fac")) if wide is not None else 0.0
    elif kind == "DIELECTRIC":
        ior = float(value("Narrow lobe", "IOR"))
        f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 if ior != -1.0 else 1.0
        tint = np.asarray(value("Narrow lobe", "Specular Tint"), float)[:3]
        kw = dict(reflectivity=np.clip(f0 * tint, 0.0, 1.0))
        beta = float(value("Lobe mix", "Fac")) if wide is not None else 0.0
    else:
        k_n = np.asarray(value("Narrow lobe", "Color"), float)[:3]
        k_w = np.asarray(value("Wide lobe", "Color"), float)[:3] if wide is not None else 0 * k_n
        r = k_n + k_w
        ch = int(np.argmax(r))
        beta = float(k_w[ch] / r[ch]) if r[ch] > 0 else 0.0
        kw = dict(reflectivity=np.clip(r, 0.0, 1.0))
    try:
        inv = inverse_haze_mapping(beta, (ax, ay), (max(wx, ax), max(wy, ay)), distribution=dist,
                                   smoothness=p["smoothness"], alpha_max=K.ALPHA_MAX, **kw)
    except ValueError:
        return None
    q = dict(p, distribution=dist, roughness=rough, anisotropy=anisotropy, rotation=rot % 1.0,
             core_reflectivity=tuple(float(x) for x in np.clip(inv.core_reflectivity, 0, 1)),
             haziness=float(np.clip(inv.haziness, 0.0, K.MAX_HAZINESS)),
             haze_extent=tuple(float(x) for x in inv.haze_extent))
    if not aniso:
        q["rotation"] = p["rotation"]
    if kind == "CONDUCTOR":
        q["edge_tint"] = tuple(float(x) for x in np.clip(inv.edge_tint, 0, 1))
    if kind == "DIELECTRIC":
        q["base_color"] = tuple(value("Narrow lobe", "Base Color"))[:3]
        q["transmission"] = float(value("Narrow lobe", "Transmission Weight"))
    if wide is None:  # no halo: the haze values stay (they do not show)
        q["haziness"], q["haze_extent"] = p["haziness"], p["haze_extent"]
    return q


#: Inputs both lean lobes share (Eq. 1 has one Fresnel term).
_SHARED = {"CONDUCTOR": ("IOR", "Extinction"),
           "DIELECTRIC": ("IOR", "Specular Tint", "Base Color", "Transmission Weight"),
           "LEGACY": ()}


def _matches(mat, q, edits, pending=()):
    """``q`` normalised when it writes back what the nodes hold (the edited values where the
    user set them, shared values following the lobe the user edited; the ``pending`` edits,
    not tried here, are not compared), else None."""
    try:
        q = normalise(q, explicit=())
        dq = lobes_for(q)
    except (ValueError, TypeError):
        return None
    ws = writes(mat, q, dq)
    if ws is None:
        return None
    mine = ours(mat.node_tree)
    edited = {(e.role, e.name): e.now for e in edits}
    skipped = {(e.role, e.name) for e in pending}
    lean = not q["shader_mapping"]
    for w in ws:
        if (w.role, w.name) in skipped:
            continue
        node = mine.get(w.role)
        now = _current(node, w) if node is not None else None
        if (w.role, w.name) in edited:
            now = edited[(w.role, w.name)]
        elif lean and (w.name in _SHARED.get(q["kind"], ()) or (w.attr and w.name == "distribution")):
            now = edited.get((_other_lobe(w.role), w.name), now)
        if now is None:
            continue
        want = w.value if w.attr else socket_value(node.inputs[w.name], w.value)
        if _differs(now, want):
            return None
    return q


def adopt_edits(mat, p=None, edits=None):
    """(parameters, replaced): the stamped parameters with the user's node-editor edits read
    back (in-shader: the group inputs are the perceptual parameters; lean: the inverse haze
    mapping), each kept only when the result writes back what the nodes hold, and the edits
    that could not be read back (they are replaced by the next change), as [Edit].  When not
    all of them read together, one at a time: an edit that does not read does not take the
    others with it."""
    p = p or read_parameters(mat)
    edits = node_edits(mat, p) if edits is None else edits
    if not edits:
        return p, []
    d = lobes_for(p)
    base = dict(p, tangent=_tangent_of(mat, p))  # a Tangent node's settings are the tangent

    def read(trial, pending):
        if p["shader_mapping"]:
            q = _adopt_group(base, trial)
        else:
            q = _adopt_lean(mat, base, d, trial, pending)
        return _matches(mat, q, trial, pending) if q is not None else None

    q = read(edits, [])
    if q is not None:
        return q, []
    kept = []
    for e in edits:
        if read(kept + [e], [x for x in edits if x not in kept and x is not e]) is not None:
            kept.append(e)
    replaced = [e for e in edits if e not in kept]
    q = read(kept, replaced) if kept else None
    return (q, replaced) if q is not None else (p, edits)


def adopt_node_edits(mat):
    """Read the user's node-editor edits of a lean / in-shader material into its stamp (the
    nodes are not touched: they already hold the values).  Returns (adopted, replaced) lists
    of Edit; called by the depsgraph handler (blender.actions.sync) after the user edits a node."""
    if mat is None or mat.library is not None or not is_hazy(mat) or layer.is_layered(mat):
        return [], []
    try:
        p = read_parameters(mat)
        edits = node_edits(mat, p)
        if not edits:
            return [], []
        q, replaced = adopt_edits(mat, p, edits)
    except (ValueError, TypeError):
        return [], []
    adopted = [e for e in edits if e not in replaced]
    if adopted:
        if q != p:
            old = stamp.group(mat, K.STAMP) or {}
            _stamp(mat, q)
            if isinstance(old.get("structure"), str):
                mat[K.STAMP]["structure"] = old["structure"]
        _record(mat, q, lobes_for(q))
        if replaced:  # keep the record of what could not be read back: still an edit
            rec = mat[K.STAMP][WRITTEN]
            for e in replaced:
                key = ("@" if e.attr else "") + e.name
                if e.role in rec:
                    rec[e.role][key] = list(e.was) if isinstance(e.was, tuple) else e.was
    return adopted, replaced


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
    _stamp(mat, p)
    mat[K.STAMP]["structure"] = repr(structure)
    _record(mat, p, d)
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


__all__ = ("create_material", "read_parameters", "read_parameters_lenient",
           "check_material", "node_edits", "adopt_edits", "adopt_node_edits", "is_hazy",
           "map_parameters",
           "lobes_for", "apply", "is_ours", "ours", "role", "output_node", "GROUP_NODE",
           "DEFAULTS", "edit_problem", "maps_problem")


def edit_problem(mat):
    """Why ``mat`` cannot be edited, in plain words, or None."""
    if mat is None:
        return "No material"
    lib = mat.library
    if lib is not None:
        return (f"“{mat.name}” is linked from the library file “{bpy.path.basename(lib.filepath)}” "
                f"and is read-only here. Edit it in that file, or make it local "
                f"(Object > Relations > Make Local) to change it in this one")
    if getattr(mat, "override_library", None) is not None:
        return (f"“{mat.name}” is a library override; its node tree cannot be rebuilt. "
                f"Make it local to edit it")
    if not is_hazy(mat):
        return f"“{mat.name}” is not a hazy material: use Make Hazy first"
    return None


def maps_problem(mat):
    """Why a material driven by converted maps cannot be edited from the panel, or None."""
    if mat is not None and K.MAPS_STAMP in mat:
        return (f"“{mat.name}” is driven by converted texture maps: convert the maps again "
                f"(Convert Maps) to change it")
    return None

