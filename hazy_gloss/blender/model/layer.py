# SPDX-License-Identifier: GPL-3.0-or-later
"""Haze as one node on the artist's own BSDF (Make Hazy): the *layer node*.

Make Hazy puts a group node (blender.model.layer_group: one group per configuration, shared) where
the artist's Principled, Metallic or Glossy BSDF (the *core*) was: it takes the core's name,
label, place, frame and colour, every input value and link, every keyframe and driver of the
inputs, and the links out of it.  Its inputs are the core's own, in the core's panels, and a
Haze panel; the group computes everything haze needs from them (core.layer_graph), so the
render depends on nothing Python writes after Make Hazy: keyframes, drivers and textures on any
input, a haze input included, render right, with or without the add-on.

The core itself is kept, untouched but for its name (" (before haze)") and its links, which
the layer node now has: collapsed and muted, next to the layer node.  Remove Haze gives its
name, place, links and animation back, with the layer node's current values (what the artist
set since), and removes the layer node: the tree is the artist's again.

The material's stamp (``mat["hazy_gloss"]["layer"]``) records only what the tree cannot tell:
which nodes are the layer and the core, where the core was, and the layer's settings (the
smooth haze curve, Keep Body Colour, the EEVEE-only output).  Values live in the sockets.

Reading a layer back (:func:`read`, :func:`notes`, :func:`summary`) is here; what the layer node's
group computes for its values is blender.model.layer_values, what the layer cannot do for them
blender.model.layer_notes.
"""
from __future__ import annotations

import numpy as np

from ... import constants as K
from ...core import gulbrandsen_inverse
from ...core.conventions import metallic_anisotropy
from ...core.parameters import HAZE_DEFAULTS
from ...schema import HAZE_SOCKETS, SCHEMA
from .. import compat
from . import (layer_animation, layer_group, layer_notes, layer_parts, layer_values, layer_wiring,
               stamp)
from ..nodes import ownership
from ..nodes.builder import set_if_changed, socket_value

__all__ = ("LAYER_VERSION", "STAMP_VERSION", "PRINCIPLED", "HAZE", "TEXTURE", "PARKED_SUFFIX",
           "LAYER_ROLE", "core_type", "layer_state", "is_layered", "is_baked", "layer_node",
           "tagged_layer_node", "layer_copies", "original_node", "connection_problems", "wrap",
           "animated_inputs", "remove", "set_haze", "held_haze", "haze_of", "apply", "wanted_group",
           "outdated_group", "refresh_group", "swap_group", "read", "record_baked_sources", "notes",
           "summary")

LAYER_VERSION = 2
STAMP_VERSION = 3  # 3: the layer as one node
PRINCIPLED = "ShaderNodeBsdfPrincipled"
HAZE = HAZE_DEFAULTS
#: A haze value fed by a link (a map, a procedural mask): its value is per shading point.
TEXTURE = K.TEXTURED
PARKED_SUFFIX = " (before haze)"
#: constants.ROLE of the layer node (the add-on's node: it builds and removes it).
LAYER_ROLE = "Haze layer"
_PARKED_LABEL = " — before haze (Remove Haze restores it)"


def core_type(node):
    return layer_group.kind_of(node)


# --------------------------------------------------------------------------------------------
# Finding the layer
# --------------------------------------------------------------------------------------------


def _raw_state(mat):
    """The layer's record from the stamp, sanitised (blender.model.stamp.check_layer_node: entries that
    do not read are left out), or None."""
    try:
        d = stamp.group(mat, K.STAMP) if mat is not None else None
    except (TypeError, ValueError):
        return None
    raw = d.get("layer") if d is not None else None
    if isinstance(raw, dict) and raw.get("version") == LAYER_VERSION:
        return stamp.check_layer_node(raw)
    return None


def _tagged(tree, key):
    return next((n for n in tree.nodes if n.get(key)), None) if tree is not None else None


def layer_state(mat):
    """The layer's record (a dict with "node", "original", "restore", "problems"), or None.  A
    tree that holds a layer node whose stamp lost its record is a damaged layer ("lost": True)."""
    if mat is None:
        return None
    raw = _raw_state(mat)
    if raw is not None:
        state = dict(raw)
        state["problems"] = _problems(mat, raw)
        return state
    tree = getattr(mat, "node_tree", None)
    node = _tagged(tree, K.LAYER_NODE_KEY)
    if node is not None and node.bl_idname == "ShaderNodeGroup" and \
            layer_group.is_layer_group(node.node_tree):
        what = stamp.describe(mat)
        return {"version": LAYER_VERSION, "lost": True, "problems": [
            (f"the stamp is {what}, but the tree holds the haze layer node “{node.name}”", None)]}
    return None


def is_layered(mat):
    """Whether ``mat`` has a haze layer (damaged or not).  Cheap for the common case (a stamp without a "layer" entry and no tagged node), which
    every slider change of a hazy material asks."""
    if mat is None:
        return False
    try:
        d = mat.get(K.STAMP)
        has_entry = d is not None and hasattr(d, "keys") and "layer" in d
    except (TypeError, AttributeError):
        has_entry = False
    if not has_entry:
        tree = getattr(mat, "node_tree", None)
        if tree is None or not any(n.get(K.LAYER_NODE_KEY) for n in tree.nodes):
            return False
    return layer_state(mat) is not None


def is_baked(mat):
    """A layer whose haze comes from converted maps (texture conversion)."""
    node = layer_node(mat)
    return node is not None and bool(layer_values.group_config(node).get("baked"))


def _kept_node(mat, state_key, tag, accept=lambda node: True):
    """The node the layer's record names under ``state_key``, else the first node carrying the
    ``tag`` key (either only when ``accept``-ed), or None."""
    tree = getattr(mat, "node_tree", None)
    if tree is None:
        return None
    name = (_raw_state(mat) or {}).get(state_key)
    node = tree.nodes.get(name) if name else None
    if node is not None and node.get(tag) and accept(node):
        return node
    return next((n for n in tree.nodes if n.get(tag) and accept(n)), None)


def layer_node(mat):
    """The layer's group node (by the stamp's name, else by its tag), or None."""
    return _kept_node(mat, "node", K.LAYER_NODE_KEY,
                      lambda n: n.bl_idname == "ShaderNodeGroup" and layer_group.is_layer_group(n.node_tree))


def tagged_layer_node(mat):
    """The node the layer's record names (or tags) as the layer node, whatever group it has
    now (the artist may have given it another), or None."""
    node = _kept_node(mat, "node", K.LAYER_NODE_KEY)
    return node if node is not None and node.bl_idname == "ShaderNodeGroup" else None


def layer_copies(mat):
    """Copies of the layer node the artist made (Shift+D), which Remove Haze leaves."""
    node = layer_node(mat)
    return layer_wiring.copies_of(mat.node_tree, node) if node is not None else []


def original_node(mat):
    """The artist's BSDF kept beside the layer node (by the stamp's name, else its tag), or None."""
    return _kept_node(mat, "original", K.ORIGINAL_NODE_KEY)


def _problems(mat, raw):
    """[(one line, haze parameters that fix it or None)] of a layer whose tree no longer fits
    its record."""
    if layer_node(mat) is not None:
        return []
    node = tagged_layer_node(mat)
    if node is None:
        where = layer_wiring.misplaced_layer(mat.node_tree)
        return [(where, stamp.OWN_WAY_OUT) if where else ("its layer node is gone (deleted)", None)]
    other = f"“{node.node_tree.name}”" if node.node_tree is not None else "no group"
    return [(f"its layer node “{node.name}” uses {other}, not a Hazy Gloss layer group", None)]


def connection_problems(mat):
    """[one line] on why the layer node does not render as the panel shows it (muted, bypassed,
    disconnected, a copy rendering: blender.model.layer_wiring)."""
    node = layer_node(mat)
    return [] if node is None else layer_wiring.wiring_problems(mat, node, original_node(mat))


# --------------------------------------------------------------------------------------------
# Making and removing
# --------------------------------------------------------------------------------------------


def _stamp(mat):
    d = mat.get(K.STAMP)
    return (d.to_dict() if hasattr(d, "to_dict") else dict(d)) if d is not None else {}


def _write_state(mat, state):
    d = _stamp(mat)
    d["layer"] = state
    d["version"] = STAMP_VERSION
    mat[K.STAMP] = d


def _unique_name(tree, base):
    name, i = base, 1
    while tree.nodes.get(name) is not None:
        i += 1
        name = f"{base} {i}"
    return name


def wrap(mat, core, haze, *, smooth=None, keep_body_colour=False, baked=False):
    """Put the layer node in ``core``'s place (see the module docstring).  ``haze``: haze
    values (HAZE keys) for the Haze panel; ``baked``: the group that reads the haze mapping's
    values from converted maps (texture conversion links them).  Returns the layer node."""
    tree = mat.node_tree
    kind = core_type(core)
    if kind is None:
        raise ValueError(f"“{core.name}” is a {core.bl_label} node: a haze layer wraps a "
                         f"Principled, Metallic or Glossy BSDF")
    settings = layer_group.settings_of(core)
    use_smooth = haze.get("smoothness") is not None if smooth is None else smooth
    ng = layer_group.ensure_group(kind, settings, use_smooth, baked,
                                  bool(keep_body_colour) and kind == "PRINCIPLED" and not baked,
                                  None if baked else layer_parts.needed(kind, core, haze))
    restore = {"name": core.name, "label": core.label, "location": list(core.location),
               "width": float(core.width), "hide": bool(core.hide), "mute": bool(core.mute),
               "parent": core.parent.name if core.parent is not None else "",
               "use_custom_color": bool(core.use_custom_color), "color": list(core.color)}
    name = core.name
    layer_animation.own_animation(tree, [name])  # (before the rename: it renames curves)
    parked = _unique_name(tree, name + PARKED_SUFFIX)
    core.name = parked  # (Blender moves the animation of its inputs with the new name)
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = ng
    node.name = name
    node[K.LAYER_NODE_KEY] = True
    node[K.ROLE] = LAYER_ROLE
    node.label = core.label
    node.parent = core.parent
    node.location = core.location
    node.width = max(core.width, 240.0)
    node.use_custom_color, node.color = core.use_custom_color, core.color
    _take_inputs(tree, core, node)
    for dest in [link.to_socket for link in core.outputs[0].links]:
        tree.links.new(node.outputs["BSDF"], dest)  # (replaces the link from the core)
    layer_animation.move_animation(tree, core, node)
    set_haze(node, haze)
    # the artist's node, kept as it was: collapsed and muted beside the layer node
    core[K.ORIGINAL_NODE_KEY] = True
    core.hide, core.mute = True, True
    core.label = (core.label or name) + _PARKED_LABEL
    core.location = (core.location.x, core.location.y + 60.0)
    _write_state(mat, {"version": LAYER_VERSION, "node": node.name, "original": core.name,
                       "restore": restore})
    return node


def _take_inputs(tree, src, dst):
    """``dst``'s inputs get ``src``'s values and links (by name); ``src`` keeps both (muted and
    off the output it renders nothing; its links show what the layer started from, and
    leaving them halves the link edits, each of which updates the whole tree)."""
    into = _links_into(tree, src)
    for sock in layer_group.bsdf_inputs(src):
        target = dst.inputs.get(sock.name)
        if target is None:
            continue
        if hasattr(sock, "default_value") and hasattr(target, "default_value"):
            set_if_changed(target, layer_values.plain(sock.default_value))
        for link in into.get(sock.identifier, ()):
            # a new group node's input has no link to replace: no limit to verify
            new = tree.links.new(link.from_socket, target, verify_limits=False)
            if link.is_muted:
                new.is_muted = True  # (a muted link renders nothing: so on the layer too)


def _links_into(tree, node):
    """{input identifier: [links]} of ``node`` (one pass over the tree's links: a socket's
    ``links`` scans them all)."""
    out = {}
    for link in tree.links:
        if link.to_node == node:
            out.setdefault(link.to_socket.identifier, []).append(link)
    return out


def _give_back(tree, src, dst):
    """The core ``dst`` gets the layer node ``src``'s current values and links, by name (a
    link the core kept from before the haze goes where the layer node's input is unlinked)."""
    into_src, into_dst = _links_into(tree, src), _links_into(tree, dst)
    for sock in layer_group.bsdf_inputs(dst):
        have = src.inputs.get(sock.name)
        if have is None:
            continue
        if hasattr(sock, "default_value") and hasattr(have, "default_value"):
            sock.default_value = socket_value(sock, layer_values.plain(have.default_value))
        now = into_src.get(have.identifier, [])
        kept = into_dst.get(sock.identifier, [])
        if [l.from_socket for l in now] == [l.from_socket for l in kept]:
            continue
        for link in kept:
            tree.links.remove(link)
        for link in now:
            tree.links.new(link.from_socket, sock)


def animated_inputs(node):
    """Names of ``node``'s inputs driven by keyframes or drivers."""
    tree = node.id_data
    paths = compat.animated_paths(tree)
    return [s.name for s in node.inputs if s.path_from_id() + ".default_value" in paths]


def remove(mat):
    """Take the layer off: the artist's BSDF is where it was with the layer node's values, links
    and animation; the layer node and what was built for it go."""
    tree = mat.node_tree
    raw = _raw_state(mat) or {}
    node, core = layer_node(mat), original_node(mat)
    _remove_eevee_nodes(mat)
    layer_animation.own_animation(tree, [n.name for n in (node, core) if n is not None])
    converted = layer_values.converted_map_nodes(node)
    if core is None and node is not None:  # the artist deleted the kept BSDF: a new one
        core = _new_core(tree, node)
    if core is not None:
        if node is not None:
            _give_back(tree, node, core)
            for dest in [link.to_socket for link in node.outputs["BSDF"].links]:
                tree.links.new(core.outputs[0], dest)
            layer_animation.move_animation(tree, node, core)
        restore = _followed(raw.get("restore", {}), node)
        if K.ORIGINAL_NODE_KEY in core:
            del core[K.ORIGINAL_NODE_KEY]
        if node is not None:
            tree.nodes.remove(node)
            node = None
        _restore_node(tree, core, restore)
    elif node is not None:  # the artist's node is gone: keep the layer node as it is
        del node[K.LAYER_NODE_KEY]
    for tex in converted:  # (their files stay; only the layer node read them)
        tree.nodes.remove(tex)
    swapped = tagged_layer_node(mat)  # (on another group: the artist's now)
    if swapped is not None and K.LAYER_NODE_KEY in swapped:
        del swapped[K.LAYER_NODE_KEY]
    if K.STAMP in mat:
        del mat[K.STAMP]


def _followed(restore, node):
    """The record of how the BSDF was, with what the artist changed on the layer node since
    (Make Hazy gave it the BSDF's name, label, frame, place and colour): renamed, relabelled,
    moved or re-framed, the BSDF comes back so."""
    if node is None:
        return restore
    now = {"name": node.name, "label": node.label, "location": list(node.location),
           "parent": node.parent.name if node.parent is not None else "",
           "use_custom_color": bool(node.use_custom_color), "color": list(node.color)}
    out = dict(restore)
    for key, value in now.items():
        was = restore.get(key)
        if was is None:
            continue
        same = (np.allclose(value, was, atol=1e-3) if isinstance(value, list) else value == was)
        if not same:
            out[key] = value
    if out.get("parent") != restore.get("parent"):
        out["location"] = now["location"]  # (relative to the new frame)
    return out


def _new_core(tree, node):
    """A BSDF of the layer group's type and settings in the layer node's place (Remove Haze
    gives it the node's values and links), or None for a node without a layer group."""
    cfg = layer_values.group_config(node)
    idname = layer_group.BSDF_NODES.get(cfg.get("bsdf"))
    if idname is None:
        return None
    core = tree.nodes.new(idname)
    for key, value in cfg.get("settings", {}).items():
        try:
            setattr(core, key, value)
        except (TypeError, AttributeError):  # (a setting this Blender does not have)
            pass
    core.parent, core.location = node.parent, node.location
    return core


def _remove_eevee_nodes(mat):
    """The EEVEE-only output (blender/actions/eevee_output.py) goes with the layer."""
    ownership.remove_roles(mat.node_tree, K.EEVEE_ROLE)


def _restore_node(tree, core, restore):
    name = restore.get("name")
    if not name and core.name.endswith(PARKED_SUFFIX):  # (a damaged record: the name it had)
        name = core.name[:-len(PARKED_SUFFIX)]
    if isinstance(name, str) and name and (tree.nodes.get(name) is None or tree.nodes.get(name) == core):
        core.name = name
    if "label" not in restore and core.label.endswith(_PARKED_LABEL):
        core.label = core.label[:-len(_PARKED_LABEL)]
        if core.label == (name or core.name):
            core.label = ""
    if "mute" not in restore:
        core.mute = False
    if "hide" not in restore:
        core.hide = False
    for key in ("label", "hide", "mute", "use_custom_color"):
        if key in restore:
            try:
                setattr(core, key, restore[key])
            except (TypeError, ValueError):
                pass
    for key in ("width", "color"):
        if key in restore:
            try:
                setattr(core, key, restore[key])
            except (TypeError, ValueError):
                pass
    parent = tree.nodes.get(restore.get("parent", "")) if restore.get("parent") else None
    core.parent = parent
    if "location" in restore:
        try:
            core.location = restore["location"]
        except (TypeError, ValueError):
            pass


# --------------------------------------------------------------------------------------------
# Haze values (the Haze panel's sockets)
# --------------------------------------------------------------------------------------------


def _haze_socket(node, param):
    return node.inputs.get(HAZE_SOCKETS[param][0])


def set_haze(node, haze):
    """Write haze values (HAZE keys; haze_extent a pair) into the layer node's sockets: a link
    into one of them stays (the map feeds it), its value is set beneath."""
    values = {}
    for key, v in haze.items():
        if key == "haze_extent" and v is not None:
            ext = tuple(v) if isinstance(v, (tuple, list)) else (v, v)
            values["haze_extent_x"], values["haze_extent_y"] = ext
        elif key in HAZE_SOCKETS and v is not None and v != TEXTURE:
            values[key] = v
    for key, v in values.items():
        sock = _haze_socket(node, key)
        if sock is not None and v != TEXTURE:
            set_if_changed(sock, v)


def held_haze(mat, keys):
    """One note per haze value of ``keys`` (HAZE keys) that something else decides on the
    layer node: a link into its socket, or keyframes / a driver on it."""
    node = layer_node(mat)
    if node is None:
        return []
    paths = compat.animated_paths(node.id_data)
    notes = []
    for key in keys:
        for k in (("haze_extent_x", "haze_extent_y") if key == "haze_extent" else (key,)):
            sock = _haze_socket(node, k) if k in HAZE_SOCKETS else None
            if sock is None:
                continue
            if sock.is_linked:
                notes.append(f"{sock.name} is linked (a map or mask feeds it): the link decides "
                             f"what renders; the value set waits beneath it")
            elif sock.path_from_id() + ".default_value" in paths:
                notes.append(f"{sock.name} is animated (keyframes or a driver): they set it again "
                             f"on the next frame; change the keys instead")
    return notes


def haze_of(mat):
    """The haze parameters a layer renders with (HAZE keys; a linked socket gives TEXTURE)."""
    node = layer_node(mat)
    h = dict(HAZE)
    h["smoothness"] = None
    if node is None:
        return h
    cfg = layer_values.group_config(node)
    h["keep_body_colour"] = bool(cfg.get("body", False))
    if cfg.get("baked"):  # (no haze inputs: the haze its maps were converted with)
        baked = (_raw_state(mat) or {}).get("baked_haze", {})
        h.update({k: tuple(v) if isinstance(v, list) else v for k, v in baked.items()})
        return h
    vals = {}
    for param in HAZE_SOCKETS:
        sock = _haze_socket(node, param)
        if sock is not None:
            vals[param] = TEXTURE if sock.is_linked else float(sock.default_value)
    for p in SCHEMA:
        if not p.sockets:
            continue
        if p.type == "extent":
            h[p.name] = tuple(vals.get(f"{p.name}_{a}", d) for a, d in zip("xy", HAZE[p.name]))
        elif p.name in vals and (p.haze_default is not None or cfg.get("smooth")):
            h[p.name] = vals[p.name]  # an optional one (smoothness) only where it acts
    return h


# --------------------------------------------------------------------------------------------
# apply: make, update
# --------------------------------------------------------------------------------------------


def apply(mat, haze, *, core=None):
    """Make ``mat``'s layer render ``haze``: a new layer on ``core``, else the layer node's haze
    sockets set — and its group swapped when the haze curve changes (smooth or Eq. 7), Keep
    Body Colour is switched or the parts it needs change.  Returns {}."""
    node = layer_node(mat)
    if node is None:
        if core is None:
            raise ValueError(stamp.layer_problem(mat, (layer_state(mat) or {}).get("problems") or
                                                 [("its layer node is gone", None)]))
        wrap(mat, core, haze, keep_body_colour=bool(haze.get("keep_body_colour")))
        return {}
    want = wanted_group(node, haze)
    if want is not None and not layer_group.fits(node.node_tree, *want):  # (also: another
        swap_group(node, layer_group.ensure_group(*want))  # Blender's or add-on's group)
    set_haze(node, haze)
    return {}


def wanted_group(node, haze=None):
    """The configuration (ensure_group's arguments) of the group this Blender and add-on build
    for the layer node: its group's, with the haze curve (smooth or Eq. 7) and Keep Body Colour
    of ``haze`` when given, and the parts its inputs reach now (layer_parts).  None when the
    node has no layer group."""
    cfg = layer_values.group_config(node)
    if cfg.get("kind") != "layer":
        return None
    kind, baked = cfg.get("bsdf", "PRINCIPLED"), bool(cfg.get("baked"))
    smooth, body = bool(cfg.get("smooth")), bool(cfg.get("body"))
    if haze is not None and not baked:
        smooth = haze.get("smoothness") is not None
        body = bool(haze.get("keep_body_colour", body)) and kind == "PRINCIPLED"
    parts = layer_group.all_parts(kind) if baked else layer_parts.needed(kind, node, haze)
    return kind, dict(cfg.get("settings", {})), smooth, baked, body, parts


def outdated_group(mat):
    """The Blender version (e.g. "5.2") or "an earlier Hazy Gloss" whose group the layer node
    uses when that is not the group this Blender and add-on build; else None."""
    node = layer_node(mat)
    want = wanted_group(node) if node is not None else None
    # a group linked from a library is up to date when its stamp is this one's (whatever its
    # parts: layer_parts.missing says which are missing)
    if want is None or layer_group.fits(node.node_tree, *want[:5], linked_ok=True,
                                        parts=layer_group.parts_of(node.node_tree)):
        return None
    made = layer_values.group_config(node).get("blender")
    return f"Blender {made}" if made != layer_group.version_tag() else "an earlier Hazy Gloss"


def refresh_group(mat):
    """Move the layer node to the group this Blender and add-on build for it (its values, links
    and haze stay).  Returns whether it moved."""
    if outdated_group(mat) is None:
        return False
    node = layer_node(mat)
    swap_group(node, layer_group.ensure_group(*wanted_group(node)))
    return True


def swap_group(node, ng):
    """Give the layer node the group ``ng``, keeping every value, link (muted or not) and
    keyframe or driver by socket name (Blender keeps them by socket identifier and position,
    which differ between groups)."""
    tree = node.id_data
    layer_animation.own_animation(tree, [node.name])  # (a shared action stays the other's)
    curves = layer_animation.input_curves(tree, node)
    vals = {s.name: layer_values.plain(s.default_value) for s in node.inputs
            if hasattr(s, "default_value")}
    ins = [(s.name, l.from_socket, l.is_muted) for s in node.inputs for l in s.links]
    outs = [(s.name, l.to_socket, l.is_muted) for s in node.outputs for l in s.links]
    for link in [l for s in list(node.inputs) + list(node.outputs) for l in s.links]:
        tree.links.remove(link)
    node.node_tree = ng
    for link in [l for s in list(node.inputs) + list(node.outputs) for l in s.links]:
        tree.links.remove(link)
    for name, v in vals.items():
        s = node.inputs.get(name)
        if s is not None and hasattr(s, "default_value"):
            s.default_value = socket_value(s, v)
    for name, src, muted in ins:
        s = node.inputs.get(name)
        if s is not None and not s.is_linked:
            tree.links.new(src, s).is_muted = muted
    for name, dst, muted in outs:
        s = node.outputs.get(name)
        if s is not None:
            tree.links.new(s, dst).is_muted = muted
    layer_animation.follow_names(node, curves)


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------


def read(mat):
    """The perceptual view of a layered material: the haze parameters and the core's own, as
    the layer node holds them (linked inputs report their unlinked value and are listed in
    ``textured``).  Raises ValueError (one line) when the layer is damaged."""
    state = layer_state(mat) or {}
    if state.get("problems"):
        raise stamp.StampError(stamp.layer_problem(mat, state["problems"]))
    node = layer_node(mat)
    kind = (stamp.group(node.node_tree, K.GROUP_STAMP) or {}).get("bsdf", "PRINCIPLED")
    h = haze_of(mat)
    inp = {s.name: s for s in node.inputs}

    def val(name, default=0.0):
        s = inp.get(name)
        if s is None or not hasattr(s, "default_value"):
            return default
        v = s.default_value
        return tuple(float(x) for x in v)[:3] if hasattr(v, "__len__") else float(v)

    settings = layer_values.group_config(node).get("settings", {})
    aniso, rot = ("Anisotropic", "Anisotropic Rotation") if kind == "PRINCIPLED" else ("Anisotropy", "Rotation")
    p = dict(layered=True, core=node.name, core_type=kind,
             distribution=settings.get("distribution", "GGX"), roughness=val("Roughness"),
             anisotropy=val(aniso), rotation=val(rot), edge_tint=(0.0, 0.0, 0.0),
             base_color=(0.0, 0.0, 0.0), transmission=0.0, tangent="UV_MAP",
             shader_mapping=False, **h)
    _, linked = layer_values.inputs_of(node)
    p["textured"] = sorted(n for n in linked if n not in {v[0] for v in HAZE_SOCKETS.values()})
    p["animated"] = animated_inputs(node)
    if kind == "PRINCIPLED":
        m = inp["Metallic"]
        p["metallic"] = None if m.is_linked else float(m.default_value)
        mv = float(m.default_value)
        p["kind"] = ("DIELECTRIC" if not m.is_linked and mv <= 0.0 else
                     "CONDUCTOR" if not m.is_linked and mv >= 1.0 else "MIXED")
        ior = val("IOR", 1.5)
        f0 = (((ior - 1.0) / (ior + 1.0)) ** 2 if ior != -1.0 else 1.0) * 2.0 * val("Specular IOR Level", 0.5)
        dielectric = tuple(min(max(f0 * c, 0.0), 1.0) for c in val("Specular Tint", (1.0,) * 3))
        metal = tuple(min(max(c, 0.0), 1.0) for c in val("Base Color", (0.8,) * 3))
        p["core_reflectivity"] = metal if p["kind"] == "CONDUCTOR" else dielectric
        p["dielectric_reflectivity"], p["metal_reflectivity"] = dielectric, metal
        p["base_color"] = val("Base Color", (0.8,) * 3)
        p["transmission"] = val("Transmission Weight")
    elif kind == "METALLIC":
        p["kind"] = "CONDUCTOR"
        if settings.get("fresnel_type") == "PHYSICAL_CONDUCTOR":
            r, g = gulbrandsen_inverse(np.maximum(np.asarray(val("IOR", (1.0,) * 3), float), 0.0),
                                       np.maximum(np.asarray(val("Extinction", (0.0,) * 3), float), 0.0))
            p["core_reflectivity"] = tuple(float(x) for x in np.clip(r, 0.0, 1.0))
            p["edge_tint"] = tuple(float(x) for x in np.clip(np.nan_to_num(g), 0.0, 1.0))
        else:
            p["core_reflectivity"] = val("Base Color", (0.8,) * 3)
            p["edge_tint"] = val("Edge Tint", (1.0,) * 3)
    else:
        p["kind"] = "LEGACY"
        p["core_reflectivity"] = val("Color", (0.8,) * 3)
        glossy = p["anisotropy"]
        if glossy:  # the Glossy node's convention (docs/blender-versions.md), read as the
            # perceptual one: the same axis ratio (1 - |A|)², the long axis along x
            k = 1.0 - min(abs(glossy), 0.99)
            p["anisotropy"] = float(metallic_anisotropy(k * k))
            p["rotation"] += 0.25 if glossy > 0 else 0.0
    p["shader_mapping"] = bool(p["textured"])
    p["notes"] = notes(mat, quick=False)  # (a bypassed layer node, haze that cannot show, ...)
    return p


def record_baked_sources(mat, record, haze=None):
    """Record what a baked layer's maps were computed from: the BSDF inputs (``record``:
    layer_values.input_record) and the haze (HAZE keys; TEXTURE where a map gave it)."""
    raw = dict(_raw_state(mat) or {})
    raw["baked_from"] = record
    if haze:
        raw["baked_haze"] = {k: list(v) if isinstance(v, tuple) else v
                             for k, v in haze.items() if k in HAZE}
    _write_state(mat, raw)


def notes(mat, quick=True):
    """What the panel, the operators and the API say about a layer, in plain words: a muted,
    bypassed or disconnected layer node; an edited layer group (``quick``: as last found, see
    layer_group.edited_parts; read_parameters looks afresh); haze that cannot show (no room
    above the core's reflectivity); what the layer only approximates for these values."""
    out = connection_problems(mat)
    node = layer_node(mat)
    if node is None:
        return out
    out += layer_notes.out_of_range_notes(node, animated_inputs(node))
    out += layer_notes.mirror_core_notes(node)
    closures = layer_wiring.closure_count(mat.node_tree, fold=False)  # (folding costs ~6 ms)
    if closures > layer_wiring.MAX_CLOSURES:
        closures = layer_wiring.closure_count(mat.node_tree)
    if closures > layer_wiring.MAX_CLOSURES:
        out.append(f"Cycles counts up to {closures} closures in this material, over its "
                   f"{layer_wiring.MAX_CLOSURES}: where more than that have weight at one point "
                   f"it drops the rest (5.x logs “Maximum number of closures exceeded”); the "
                   f"layer's BSDF copies count 12 each as Principled: mix fewer BSDFs beside it")
    edited = layer_group.edited_parts(node.node_tree, cached=quick)
    if edited:
        out.append(f"its layer group was edited by hand ({', '.join(f'“{n}”' for n in edited)}): "
                   f"what renders is not what the panel and these notes show")
    missing = layer_parts.missing(node)
    if missing:
        out.append(f"its layer group has no {' or '.join(missing)} part, which its inputs now "
                   f"need (they were changed where Hazy Gloss did not run): those points render "
                   f"without haze until it moves the layer to its group (any edit here, or "
                   f"Upgrade Haze Layers)")
    made = outdated_group(mat)
    if made:
        out.append(f"its layer group was made by {made}: Upgrade Haze Layers (or any haze "
                   f"edit) moves it to this one's (each Blender's Multiscatter GGX needs its own "
                   f"correction)")
    if is_baked(mat):
        was = (_raw_state(mat) or {}).get("baked_from") or {}
        changed = layer_values.baked_changes(was, node)
        if changed:
            out.append(f"its haze comes from converted maps made for other {', '.join(changed)}: "
                       f"convert the maps again (or Remove Haze, then Make Hazy for a live layer)")
        return out
    h = haze_of(mat)
    if h.get("haziness") in (0.0, TEXTURE) and h.get("coat_haziness") in (0.0, TEXTURE, None):
        return out  # no haze set here: nothing it could not do
    try:
        vals = layer_values.LazyValues(node, layer_notes.outputs_for_notes(node))
    except (ValueError, TypeError, KeyError):  # (a damaged group: no value notes)
        return out
    linked, more = vals.linked, []
    try:  # (the group's values are evaluated by the first note that reads one)
        if h.get("haziness") not in (0.0, TEXTURE) and "Haziness" not in linked:
            more += layer_notes.room_notes(node, vals, linked, h)
        if layer_values.group_config(node).get("body") and vals.get("beta dielectric", 0.0) > 0.0:
            more.append(layer_notes.body_note(node, vals, linked))
        more.append(layer_notes.coat_note(node, vals, linked))
        film = layer_notes.film_peak_change(node, vals, linked)
    except layer_values.LazyValues.Failed:
        return out
    if film is not None and abs(film) > 1e-5:
        more.append(f"thin film: the layer raises F(0) as without a film, so the peak moves by "
                    f"{100 * film:+.2f}% here (lower Haziness, or thin the film)")
    return out + [n for n in more if n]


def summary(mat):
    """What the panel shows of a layer: its node, the values its group computes for the
    node's unlinked inputs, which inputs are linked or animated, the notes."""
    node = layer_node(mat)
    if node is None:
        state = layer_state(mat) or {}
        raise ValueError(f"The haze layer of “{mat.name}” is damaged: "
                         f"{(state.get('problems') or [('its layer node is gone', None)])[0][0]}")
    vals, linked = layer_values.values(node)
    return dict(node=node, values=vals, textured=linked, animated=animated_inputs(node),
                notes=notes(mat), group=node.node_tree.name)
