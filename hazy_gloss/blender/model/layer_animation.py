# SPDX-License-Identifier: GPL-3.0-or-later
"""Keyframes and drivers of a layer's BSDF inputs follow the sockets when Make Hazy or Remove
Haze moves them between the artist's node and the layer node; never another ID's."""
import re

import bpy

from .. import compat

__all__ = ("own_animation", "move_animation", "input_curves", "follow_names", "unshift_inputs")


_INPUT_PATH = re.compile(r'^nodes\["((?:[^"\\]|\\.)*)"\]\.inputs\[(\d+)\](.*)$')


def _fcurves(idblock):
    anim = getattr(idblock, "animation_data", None)
    if anim is None:
        return []
    curves = list(anim.drivers) + compat.slot_fcurves(anim.action, anim)
    for track in anim.nla_tracks:
        for strip in track.strips:
            curves += compat.slot_fcurves(strip.action, strip)
    return curves


def own_animation(tree, node_names):
    """Before the layer renames or re-points the curves of ``node_names``' inputs: an action
    ``tree`` shares with another ID (``mat.copy()`` shares it) is replaced by a copy of its own,
    as Blender's Make Single User does, so the other material keeps its animation.  Returns the
    names of the copies."""
    anim = getattr(tree, "animation_data", None)
    if anim is None:
        return []
    owners = [anim] + [strip for track in anim.nla_tracks for strip in track.strips]
    refs = {}
    for owner in owners:
        if owner.action is not None:
            refs[owner.action] = refs.get(owner.action, 0) + 1
    prefixes = tuple(f'nodes["{bpy.utils.escape_identifier(n)}"].' for n in node_names)
    copies = {}
    for owner in owners:
        action = owner.action
        if action is None or action.users - int(action.use_fake_user) <= refs[action]:
            continue  # (only this tree uses it)
        if not any(fc.data_path.startswith(prefixes)
                   for fc in compat.slot_fcurves(action, owner)):
            continue
        slot = getattr(owner, "action_slot", None)
        ident = slot.identifier if slot is not None else None
        if action not in copies:
            copies[action] = action.copy()
        owner.action = copies[action]
        if ident is not None and getattr(owner, "action_slot", None) is None:
            owner.action_slot = copies[action].slots.get(ident)
    return [c.name for c in copies.values()]


def _by_position(tree, node):
    """(curve, input position, rest of the path) of the keyframes and drivers of ``tree`` on
    ``node``'s inputs keyed by position (``nodes["<node>"].inputs[<i>]...``)."""
    for fc in _fcurves(tree):
        m = _INPUT_PATH.match(fc.data_path)
        if m is not None and m.group(1).replace('\\"', '"') == node.name:
            yield fc, int(m.group(2)), m.group(3)


def move_animation(tree, src, dst):
    """Keyframes and drivers on ``src``'s inputs drive ``dst``'s inputs of the same name."""
    index = {s.name: i for i, s in enumerate(dst.inputs)}
    for fc, i, rest in list(_by_position(tree, src)):
        if i < len(src.inputs) and src.inputs[i].name in index:
            fc.data_path = dst.inputs[index[src.inputs[i].name]].path_from_id() + rest


def input_curves(tree, node):
    """[(curve, input name, rest of the path)] of the keyframes and drivers on ``node``'s inputs,
    taken before its sockets change (another group): Blender moves such paths itself when
    ``node_tree`` is set, by socket identifier, which differ in meaning between groups."""
    return [(fc, node.inputs[i].name, rest) for fc, i, rest in _by_position(tree, node)
            if i < len(node.inputs)]


def follow_names(node, curves):
    """After ``node``'s sockets changed: the ``curves`` (input_curves, taken before) drive the
    input of the same name; one whose input is gone keys it by name, so nothing drives the
    wrong input."""
    index = {s.name: i for i, s in enumerate(node.inputs)}
    head = f'nodes["{bpy.utils.escape_identifier(node.name)}"].inputs'
    for fc, name, rest in curves:
        fc.data_path = (f"{head}[{index[name]}]" if name in index else
                        f'{head}["{bpy.utils.escape_identifier(name)}"]') + rest


def unshift_inputs(tree, node, orig, offset, total, frame):
    """Undo Blender's versioning shift of ``node``'s input curves (it moved positions
    orig..total-1 to orig+offset..total-1+offset, as for the BSDF that gained an input, though
    ``node`` is a group).  A curve at a position both a moved and an unmoved curve can hold
    (total..total-1+offset) is told by its value at ``frame`` (the socket holds the value the
    right curve gave when the file was saved).  Returns the names of the inputs whose curve
    could not be told apart (left where it is)."""
    head = f'nodes["{bpy.utils.escape_identifier(node.name)}"].inputs'
    found = {}
    for fc, i, rest in _by_position(tree, node):
        found.setdefault(i, []).append((fc, rest))
    unsure = []
    for i, curves in sorted(found.items()):
        if not orig + offset <= i < total + offset:
            continue
        for fc, rest in curves:
            moved = True if i < total else _moved(fc, node, i - offset, i, frame)
            if moved is None:
                unsure.append(node.inputs[i].name if i < len(node.inputs) else f"input {i}")
            elif moved:
                fc.data_path = f"{head}[{i - offset}]{rest}"
    return unsure


def _moved(fc, node, old, now, frame):
    """Whether the curve ``fc`` belongs to input ``old`` (it gives that input's value at
    ``frame``, not input ``now``'s), to ``now`` (the other way round), or None: cannot tell
    (the same value, neither, or a driver's curve)."""
    if getattr(fc, "driver", None) is not None:
        return None
    value = fc.evaluate(frame)

    def holds(k):
        if k >= len(node.inputs) or not hasattr(node.inputs[k], "default_value"):
            return False
        v = node.inputs[k].default_value
        v = v[fc.array_index] if hasattr(v, "__len__") else v
        return abs(float(v) - value) <= 1e-6 * max(1.0, abs(value))
    at_old, at_now = holds(old), holds(now)
    return None if at_old == at_now else at_old
