# SPDX-License-Identifier: GPL-3.0-or-later
"""What a haze layer node's group gives its BSDF slots, for tests, benchmarks and scripts (not
shipped: the add-on itself only renders the group).  ``layer_values`` is the add-on's module
that evaluates a layer node's group (``hazy_gloss.blender.model.layer_values`` of whichever copy of
the package the caller loaded: the test harness loads it as ``bl_ext.test_repo.hazy_gloss``)."""


def slot_values(layer_values, node, role):
    """{input: value} the group gives its BSDF slot ``role`` (core.layer_graph: "A narrow",
    ..., "EEVEE folded") for the node's unlinked input values (inputs it passes on are left
    out)."""
    lay = layer_values.graph_of(node)
    slot = next(s for tree in (lay.cycles, lay.eevee)
                for s in layer_values.layer_graph.slots_of(tree) if s.role == role)
    return layer_values.evaluate(node, slot.writes)[0]


def rendered_slots(layer_values, node):
    """How many BSDF slots of the layer node Cycles keeps: a Mix whose factor reads no linked
    input folds, and at 0 or 1 drops its other side.  Returns (count, exact): not exact where a
    factor varies per shading point (both sides counted)."""
    graph = layer_values.layer_graph
    lay = layer_values.graph_of(node)
    _, linked_names = layer_values.inputs_of(node)
    linked = {graph.input_name(n) for n in linked_names}
    linked |= {graph.haze_name(p) for p, (n, *_r) in layer_values.HAZE_SOCKETS.items()
               if n in linked_names}
    exact = [True]

    def count(t):
        if isinstance(t, graph.Slot):
            return 1
        f = None
        if not t.add and not {e.name for e in lay.graph.used({"f": t.factor})
                              if e.op == "input"} & linked:
            f = layer_values.evaluate(node, {"f": t.factor})[0]["f"]
        if f is None and not t.add:
            exact[0] = False
        return count(t.a) if f == 0.0 else count(t.b) if f == 1.0 else count(t.a) + count(t.b)
    return count(lay.cycles), exact[0]


def count_nodes(tree):
    """Every node of a node tree and of its groups (recursively): frames, group inputs and
    outputs included (how docs/node-groups.md and the benchmarks count a layer's group)."""
    return sum(1 + (count_nodes(n.node_tree) if n.bl_idname == "ShaderNodeGroup" and n.node_tree
                    else 0) for n in tree.nodes)
