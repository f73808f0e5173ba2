# SPDX-License-Identifier: GPL-3.0-or-later
"""What a haze layer node's group computes (blender.model.layer: the layer node): what the group
is built for (its stamp), its graph (core.layer_graph, cached per configuration), and that graph
evaluated in numpy with Blender's node semantics for the node's unlinked input values: the
panel's Physical Values, the numbers the notes (blender.model.layer_notes) judge.  Linked inputs
are named, not followed: their values vary per shading point."""
from __future__ import annotations

import numpy as np

from ... import constants as K
from ...core import layer_graph
from ...core.graph import evaluate as evaluate_graph
from ...schema import HAZE_SOCKETS
from . import layer_group, stamp
from ..nodes import ownership

__all__ = ("group_config", "inputs_of", "graph_input_name", "graph_of", "evaluate", "LazyValues",
           "cycles_closures", "varying_math", "values", "input_fingerprint", "plain", "input_record",
           "baked_changes", "converted_map_nodes")


def group_config(node):
    """What the layer node's group is built for (its stamp): bsdf, settings, smooth, baked."""
    return stamp.group(node.node_tree, K.GROUP_STAMP) or {} if node.node_tree is not None else {}


def inputs_of(node):
    """{graph input name: value} of the layer node's unlinked inputs and the names linked."""
    vals, linked = {}, []
    for s in node.inputs:
        if not s.name or not hasattr(s, "default_value"):
            continue
        if s.is_linked:
            linked.append(s.name)
        v = s.default_value
        v = tuple(float(x) for x in v)[:3] if hasattr(v, "__len__") else float(v)
        vals[graph_input_name(s.name)] = v
    return vals, linked


def graph_input_name(socket_name):
    """The core.layer_graph input a layer node's input (by socket name) feeds."""
    for param, (name, *_rest) in HAZE_SOCKETS.items():
        if name == socket_name:
            return layer_graph.haze_name(param)
    for key, (name, _) in layer_graph.BAKED.items():
        if name == socket_name:
            return layer_graph.baked_name(key)
    return layer_graph.input_name(socket_name)


_LAYERS = {}


def graph_of(node):
    """The core.layer_graph.Layer of a layer node's group (cached per configuration)."""
    st = stamp.group(node.node_tree, K.GROUP_STAMP) or {}
    cfg = layer_group.config_for(st.get("bsdf", "PRINCIPLED"), st.get("settings", {}),
                                 smooth=bool(st.get("smooth")), baked=bool(st.get("baked")),
                                 body=bool(st.get("body")), parts=st.get("parts"))
    lay = _LAYERS.get(cfg.key())
    if lay is None:
        lay = _LAYERS[cfg.key()] = layer_graph.build(cfg)
    return lay


_NEEDED = {}


def evaluate(node, outputs, lazy=False, overrides=None):
    """({name: value} of the graph ``outputs`` of the layer node's group for the node's
    unlinked input values, the names of its linked inputs); ``overrides``: {graph input name:
    value} in place of the node's (what another setting would give)."""
    lay = graph_of(node)
    vals, linked = inputs_of(node)
    vals.update(overrides or {})
    key = (id(lay),) + tuple((k, id(v)) for k, v in outputs.items())
    needed = _NEEDED.get(key)
    if needed is None:
        needed = _NEEDED[key] = {e.name for e in lay.graph.used(outputs) if e.op == "input"}
    inputs = {}
    for name in needed:
        v = vals.get(name, 0.0)  # (Keep Body Colour's view cosine: face-on, Facing 0)
        vector = lay.graph.inputs[name].vector
        inputs[name] = np.broadcast_to(np.asarray(v, np.float32), (3,)) if vector else np.float32(v)
    out = evaluate_graph(outputs, inputs, lay.graph.tables, lazy=lazy)
    return {k: (tuple(float(x) for x in np.ravel(v)) if np.size(v) > 1 else float(v))
            for k, v in out.items()}, linked


class LazyValues:
    """:func:`evaluate` of ``outputs`` for the layer node, done on the first value read (the
    notes of a material whose judged inputs are linked read none); ``linked``: the names of
    its linked inputs."""

    def __init__(self, node, outputs):
        self._node, self._outputs, self._values = node, outputs, None
        self.linked = inputs_of(node)[1]

    class Failed(Exception):
        """The group's values did not evaluate (a damaged group)."""

    def _all(self):
        if self._values is None:
            try:
                self._values = evaluate(self._node, self._outputs, lazy=True)[0]
            except (ValueError, TypeError, KeyError) as exc:
                raise self.Failed(str(exc)) from exc
        return self._values

    def __contains__(self, key):  # (evaluate gives every output asked for)
        return key in self._outputs

    def __getitem__(self, key):
        return self._all()[key]

    def get(self, key, default=None):
        return self._all().get(key, default) if key in self._outputs else default


def cycles_closures(node, per_slot):
    """How many closures Cycles counts for the layer node's Cycles output (``per_slot``: a BSDF
    copy's count): a Mix Shader of the group whose factor Cycles folds to a constant <= 0 or
    >= 1 keeps one branch (MixClosureNode::constant_fold), the others keep both."""
    lay = graph_of(node)
    vals, linked = inputs_of(node)
    key = (id(lay), per_slot, tuple(sorted(linked)), tuple(sorted(vals.items())))
    if key in _CLOSURES:  # (the panel's notes ask on every redraw: 6 ms to work out)
        return _CLOSURES[key]
    if len(_CLOSURES) > 256:
        _CLOSURES.clear()
    known = set(vals) - {graph_input_name(name) for name in linked}
    mixes = [t for t in layer_graph.walk(lay.cycles) if isinstance(t, layer_graph.Mix) and not t.add]
    value = _cycles_constants(lay.graph, [t.factor for t in mixes], vals, known)

    def count(t):
        if isinstance(t, layer_graph.Slot):
            return per_slot
        f = None if t.add else value(t.factor)
        if f is not None and float(np.max(f)) <= 0.0:
            return count(t.a)
        if f is not None and float(np.min(f)) >= 1.0:
            return count(t.b)
        return count(t.a) + count(t.b)
    _CLOSURES[key] = count(lay.cycles)
    return _CLOSURES[key]


_CLOSURES = {}


def varying_math(node):
    """How many of the group's math nodes Cycles runs at every shading point for the layer
    node's links (the others fold into constants when it compiles the shader: a linked input,
    a texture, makes what reads it vary).  Counts the expressions of its Cycles output."""
    lay = graph_of(node)
    vals, linked = inputs_of(node)
    known = set(vals) - {graph_input_name(name) for name in linked}
    wanted = []
    for t in layer_graph.walk(lay.cycles):
        if isinstance(t, layer_graph.Slot):
            wanted += [e for e in t.writes.values() if hasattr(e, "op")]
        elif not t.add:
            wanted.append(t.factor)
    wanted = [e for e in wanted if hasattr(e, "op") and not e.is_const]
    value = _cycles_constants(lay.graph, wanted, vals, known)
    seen, nodes, stack = set(), set(), [e for e in wanted if value(e) is None]
    while stack:
        e = stack.pop()
        if e.index in seen or e.is_const or e.op == "input" or value(e) is not None:
            continue
        seen.add(e.index)
        # (the lanes of one vector are one Separate Color node)
        nodes.add(("separate", e.args[0].index) if e.op == "SEPARATE" else e.index)
        stack.extend(e.args)
    return len(nodes)


#: Operand positions whose constant zero makes a Math result a constant in Cycles' folding
#: (scene/constant_fold.cpp fold_math: 0 x = x 0 = 0, 0 / x = 0), and POWER's x^0 = 1^x = 1.
_ZERO_MAKES_CONSTANT = {"MULTIPLY": (0, 1), "DIVIDE": (0,), "VMULTIPLY": (0, 1),
                        "VSCALE": (0, 1), "VDOT_PRODUCT": (0, 1)}


def _cycles_constants(graph, outputs, vals, known):
    """value(expr): what Cycles' constant folding makes of an expression of ``outputs`` (their
    value), or None where it keeps computing it per shading point: the graph's inputs in
    ``known`` are constants (the node's unlinked inputs), lookups (TABLE) never fold, a Mix
    node with a constant factor of 0 or 1 is its kept operand, and 0 x, x 0, 0 / x, x^0, 1^x
    fold whatever x is.  Values come from one evaluation with 0.5 for the other inputs (those
    identities hold for any finite x)."""
    used = graph.used(outputs)
    fill = {}
    for e in used:
        if e.op == "input":
            v = vals.get(e.name, 0.5) if e.name in known else 0.5
            fill[e.name] = (np.broadcast_to(np.asarray(v, np.float32), (3,)) if e.vector
                            else np.float32(v if np.ndim(v) == 0 else v[0]))
    got = evaluate_graph(used, fill, graph.tables) if used else []
    at = {e.index: np.asarray(v, np.float64) for e, v in zip(used, got)}
    const = {}

    def is_const(a):
        return a.is_const or const.get(a.index, False)

    def v(a):
        return np.asarray(a.value, np.float64) if a.is_const else at[a.index]

    for e in used:
        if e.op == "input":
            const[e.index] = e.name in known
        elif e.op == "TABLE":
            const[e.index] = False
        elif e.op in ("MIX", "VMIX") and is_const(e.args[0]):
            t = v(e.args[0])
            keep = e.args[1] if np.all(t == 0.0) else e.args[2] if np.all(t == 1.0) else None
            const[e.index] = is_const(keep) if keep is not None else all(map(is_const, e.args))
        elif any(is_const(e.args[k]) and np.all(v(e.args[k]) == 0.0)
                 for k in _ZERO_MAKES_CONSTANT.get(e.op, ())):
            const[e.index] = True
        elif e.op == "POWER" and ((is_const(e.args[1]) and np.all(v(e.args[1]) == 0.0)) or
                                  (is_const(e.args[0]) and np.all(v(e.args[0]) == 1.0))):
            const[e.index] = True
        else:
            const[e.index] = all(map(is_const, e.args))
    return lambda e: v(e) if is_const(e) else None


def values(node):
    """What the layer's group computes from the node's unlinked input values (the panel's
    Physical Values; the graph evaluated in numpy with Blender's node semantics)."""
    return evaluate(node, graph_of(node).shown)


def input_fingerprint(node):
    """A hash of what a copy of ``node`` must follow: its inputs (values, and the sockets
    linked into them through links that render) and its enum settings (the export fallback is
    rebuilt when it changes)."""
    into = {}
    for link in node.id_data.links:  # (one pass: a socket's ``links`` scans them all)
        if link.to_node == node and not link.is_muted and link.is_valid:
            into[link.to_socket.identifier] = link.from_socket
    items = []
    for s in node.inputs:
        src = into.get(s.identifier)
        if src is not None:
            items.append((s.identifier, "L", src.node.name, src.identifier))
        elif hasattr(s, "default_value"):
            v = s.default_value
            items.append((s.identifier, tuple(v) if hasattr(v, "__len__") else v))
    items += [(p, getattr(node, p)) for p in ("distribution", "subsurface_method", "fresnel_type")
              if hasattr(node, p)] + [node.mute]
    return hash(tuple(items))


def plain(v):
    """A socket value as plain Python (lists for vectors and colours), for records."""
    if hasattr(v, "__len__") and not isinstance(v, str):
        return [float(x) for x in v]
    if isinstance(v, bool):
        return v
    return float(v) if isinstance(v, (int, float)) else v


def input_record(node, names):
    """{input name: {"link": node name} | {"value": v}} of ``node``'s inputs ``names``."""
    out = {}
    for name in names:
        s = node.inputs.get(name)
        if s is None:
            continue
        if s.is_linked:
            out[name] = {"link": s.links[0].from_node.name}
        elif hasattr(s, "default_value"):
            out[name] = {"value": plain(s.default_value)}
    return out


def baked_changes(was, node):
    """Inputs of a converted layer node that no longer hold what its maps were computed from
    (``was``: the input_record made when they were)."""
    now = input_record(node, list(was))
    changed = []
    for name, rec in was.items():
        cur = now.get(name)
        if cur is None or set(cur) != set(rec):
            changed.append(name)
        elif "link" in rec and cur["link"] != rec["link"]:
            changed.append(name)
        elif "value" in rec and not np.allclose(np.atleast_1d(cur["value"]),
                                                np.atleast_1d(rec["value"]), rtol=1e-6, atol=1e-7):
            changed.append(name)
    return changed


def converted_map_nodes(node):
    """The Image Textures a conversion linked into a baked layer node's Converted Maps that
    feed nothing else (Remove Haze takes them with the layer)."""
    if node is None or not group_config(node).get("baked"):
        return []
    out = []
    for sock in node.inputs:
        for link in sock.links:
            tex = link.from_node
            ours = str(ownership.role(tex) or "").startswith(K.CONVERTED_ROLE) or \
                tex.label.startswith("Converted ")  # (a file converted before roles)
            if tex.bl_idname == "ShaderNodeTexImage" and tex not in out and ours and \
                    all(l.to_node == node for o in tex.outputs for l in o.links):
                out.append(tex)
    return out
