# SPDX-License-Identifier: GPL-3.0-or-later
"""Whether a layer node renders, in plain words for blender.model.layer.notes: the Material
Output must reach it through shader links, un-muted (a muted group node has no shader to pass:
the material renders black), and not through the kept BSDF or a copy of the layer node instead
(Shift+D copies its tag; the panel and haze edits change the layer node only); and how many
closures Cycles counts for the material (its limit is 64: the layer's BSDF copies count)."""
from __future__ import annotations

from ... import constants as K
from ...core import layer_graph
from . import layer_group, layer_values, stamp
from ..nodes import ownership

__all__ = ("upstream", "copies_of", "misplaced_layer", "wiring_problems", "CLOSURES",
           "MAX_CLOSURES", "closure_count")


def upstream(sock):
    """Names of the nodes whose closures reach ``sock`` (through shader links; a muted node is
    passed through to its inputs, and named)."""
    seen, queue = set(), [sock]
    while queue:
        s = queue.pop()
        for link in s.links:
            if link.is_muted or not link.is_valid:
                continue
            n = link.from_node
            if n.name in seen:
                continue
            seen.add(n.name)
            if n.mute:
                queue.extend(n.inputs)  # a muted node passes its first matching input
            else:
                queue.extend(i for i in n.inputs if i.type == "SHADER" or n.bl_idname == "NodeReroute")
    return seen


def copies_of(tree, node):
    """Other group nodes on a layer group or with the layer node's tag: copies the artist made
    (Shift+D, or a Group node given the layer's group)."""
    return [n for n in tree.nodes if n != node and n.bl_idname == "ShaderNodeGroup"
            and (n.get(K.LAYER_NODE_KEY) or layer_group.is_layer_group(n.node_tree))]


def misplaced_layer(tree):
    """Where a layer node no longer in ``tree`` went, in one line, or None: grouped with other
    nodes (Ctrl+G: a layer group node inside one of the tree's node groups) or ungrouped
    (Ctrl+Alt+G: the layer group's frames among the tree's nodes).  Either way it still
    renders, so Remove Haze must not report it gone."""
    frames = [n.label for n in tree.nodes if n.bl_idname == "NodeFrame" and n.label.startswith(
        layer_group.LOBES_FRAME)]
    if frames:
        return (f"its layer node was ungrouped: its nodes (the frame “{frames[0]}” and those "
                f"beside it) are in the tree and still render; undo the ungroup (Ctrl+Z), or "
                f"delete them and connect the BSDF yourself")
    path = _grouped_layer(tree, [], set())
    if path:
        return (f"its layer node “{path[-1]}” is inside the group node "
                f"{' > '.join(f'“{p}”' for p in path[:-1])} and still renders: ungroup it "
                f"(Ctrl+Alt+G) to edit or remove the haze")
    return None


def _grouped_layer(tree, path, seen):
    """[group node names..., layer node name] of a layer group node nested in ``tree``'s
    (user) node groups, or []."""
    for n in tree.nodes:
        ng = getattr(n, "node_tree", None) if n.bl_idname == "ShaderNodeGroup" else None
        if ng is None or ng.name in seen:
            continue
        if layer_group.is_layer_group(ng):
            if path:
                return path + [n.name]
            continue
        seen.add(ng.name)
        found = _grouped_layer(ng, path + [n.name], seen)
        if found:
            return found
    return []


def wiring_problems(mat, node, original):
    """[one line] on why the layer node ``node`` does not render as the panel shows it."""
    tree = mat.node_tree
    out = ownership.engine_output(tree, "CYCLES")
    if out is None:
        return ["the material has no Material Output"]
    reached = upstream(out.inputs["Surface"])
    eevee = ownership.engine_output(tree, "EEVEE")
    if eevee is not None and eevee != out:  # (its own output for EEVEE: each engine's counts)
        seen_by_eevee = upstream(eevee.inputs["Surface"])
        for engine, o, sees, other in (("Cycles", out, reached, seen_by_eevee),
                                       ("EEVEE", eevee, seen_by_eevee, reached)):
            if node.name not in sees and node.name in other:
                return [f"{engine} renders the Material Output “{o.name}”, which does not reach "
                        f"the layer node “{node.name}”: no haze in {engine}"]
        reached = reached | seen_by_eevee
    copies = [n for n in copies_of(tree, node) if n.name in reached]
    found = []
    if copies:
        names = ", ".join(f"“{n.name}”" for n in copies)
        verb = "render" if len(copies) > 1 else "renders"
        found.append(f"{names}, a copy of the layer node “{node.name}”, {verb} "
                     f"{'too' if node.name in reached else 'instead'}: the panel and haze edits "
                     f"change “{node.name}” only (delete the copy, or use two materials)")
    if node.name in reached:
        if node.mute:
            found.append(f"the layer node “{node.name}” is muted: the material renders without "
                         f"it (black where it was the only shader); un-mute it (M)")
    elif original is not None and original.name in reached:
        found.append(f"“{original.name}” (the BSDF as it was before haze) is connected instead "
                     f"of the layer node “{node.name}”: no haze renders")
    elif not copies:
        found.append(f"the layer node “{node.name}” is not connected to the Material Output: "
                     f"no haze renders")
    return found


#: What Cycles counts for a closure node (ShaderGraph::get_num_closures in
#: intern/cycles/scene/shader_graph.cpp); a node not named here counts 1.
CLOSURES = {"ShaderNodeBsdfPrincipled": 12, "ShaderNodeSubsurfaceScattering": 3,
            "ShaderNodeBsdfGlass": 2, "ShaderNodeBsdfHairPrincipled": 2,
            "ShaderNodeVolumeScatter": 32, "ShaderNodeVolumeAbsorption": 32,
            "ShaderNodeVolumePrincipled": 32, "ShaderNodeVolumeCoefficients": 32}
#: Cycles' MAX_CLOSURE: closures past it at a shading point are dropped.
MAX_CLOSURES = 64
_NOT_CLOSURES = {"ShaderNodeMixShader", "ShaderNodeAddShader", "NodeReroute", "ShaderNodeGroup",
                 "NodeGroupInput", "ShaderNodeEeveeSpecular", "ShaderNodeShaderToRGB"}


def _slot_closures(node):
    """What Cycles counts for one BSDF copy of the layer node's group."""
    cfg = layer_values.group_config(node)
    bsdf = {"PRINCIPLED": "ShaderNodeBsdfPrincipled"}.get(cfg.get("bsdf"), "")
    multi = cfg.get("settings", {}).get("distribution") == "MULTI_GGX"
    return CLOSURES.get(bsdf, 2 if multi else 1)


def closure_count(tree, fold=True):
    """How many closures Cycles counts for the material ``tree`` (its limit MAX_CLOSURES): the
    closure nodes the Surface and Volume of the output Cycles renders reach through un-muted
    shader links, inside groups too (each group node is its own copy); a layer node's copies as
    Cycles folds its Mix Shaders (layer_values.cycles_closures).  The artist's own Mix Shaders
    are counted with both branches: an upper bound where their factor folds to 0 or 1.
    ``fold`` False: every copy of the layer counted (a quicker upper bound)."""
    out = ownership.engine_output(tree, "CYCLES")
    if out is None:
        return 0
    total, queue = 0, [(tree, s, ()) for s in (out.inputs.get("Surface"), out.inputs.get("Volume"))
                       if s is not None]
    seen = set()
    while queue:
        t, sock, path = queue.pop()
        for link in sock.links:
            if link.is_muted or not link.is_valid:
                continue
            n = link.from_node
            key = (path, t.name, n.name, link.from_socket.identifier)
            if key in seen:
                continue
            seen.add(key)
            shader_ins = [i for i in n.inputs if i.type == "SHADER" or n.bl_idname == "NodeReroute"]
            if n.mute:  # (a muted Mix Shader passes one input: both counted, an upper bound)
                queue += [(t, i, path) for i in shader_ins[:2]]
            elif n.bl_idname == "ShaderNodeGroup" and link.from_socket.name == "BSDF" and \
                    layer_group.is_layer_group(n.node_tree):
                per_slot = _slot_closures(n)
                total += layer_values.cycles_closures(n, per_slot) if fold else \
                    per_slot * len(layer_graph.slots_of(layer_values.graph_of(n).cycles))
            elif n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None:
                inner = n.node_tree
                gout = next((g for g in inner.nodes if g.bl_idname == "NodeGroupOutput"
                             and g.is_active_output), None)
                s = gout.inputs.get(link.from_socket.name) if gout is not None else None
                if s is not None:
                    queue.append((inner, s, path + (n.name,)))
            elif n.bl_idname in _NOT_CLOSURES:
                queue += [(t, i, path) for i in shader_ins]
            elif n.outputs and n.outputs[0].type == "SHADER":
                distribution = getattr(n, "distribution", "")
                total += CLOSURES.get(n.bl_idname, 2 if distribution == "MULTI_GGX" else 1)
    return total
