# SPDX-License-Identifier: GPL-3.0-or-later
"""Which nodes of a tree are the add-on's: a role (constants.ROLE, a node custom property that
survives renaming) or, in files written before roles existed, a name starting with "HG "."""
from ... import constants as K

__all__ = ("role", "is_ours", "ours", "remove_roles", "engine_output", "output_node")


def role(node):
    """The role of one of the add-on's nodes, or None for the user's nodes."""
    r = node.get(K.ROLE)
    if isinstance(r, str):
        return r
    if node.name.startswith(K.NODE_PREFIX + " "):  # files written before roles existed
        return node.name[len(K.NODE_PREFIX) + 1:]
    return None


def is_ours(node):
    """A node the add-on built (and updates); everything else in the tree is the user's."""
    return role(node) is not None


def ours(tree):
    """{role: node} of the add-on's nodes.  A copy the user made of one of them (Shift+D keeps
    the custom property) becomes the user's: only the first of a role is ours."""
    found = {}
    for n in tree.nodes:
        r = role(n)
        if r is None:
            continue
        if r in found:
            if n.name == f"{K.NODE_PREFIX} {r}":  # the original kept its name: it is ours
                found[r], n = n, found[r]
            if K.ROLE in n:
                del n[K.ROLE]
            continue
        found[r] = n
    return found


def remove_roles(tree, prefix):
    """Remove the add-on's nodes whose role starts with ``prefix``; returns whether there were
    any."""
    found = [n for r, n in ours(tree).items() if r.startswith(prefix)]
    for n in found:
        tree.nodes.remove(n)
    return bool(found)


def engine_output(tree, engine):
    """The Material Output ``engine`` ("CYCLES" or "EEVEE") renders, as Blender picks it
    (ntreeShaderOutputNode): one of that target over one of All, the active one among equals;
    None when there is none."""
    best = None
    for n in tree.nodes:
        if n.bl_idname != "ShaderNodeOutputMaterial" or n.target not in ("ALL", engine):
            continue
        if best is None or (n.target == engine and best.target == "ALL") or (
                n.target == best.target and n.is_active_output and not best.is_active_output):
            best = n
    return best


def output_node(tree, create=True):
    outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    for n in outs:
        if n.is_active_output:
            return n
    if outs or not create:
        return outs[0] if outs else None
    n = tree.nodes.new("ShaderNodeOutputMaterial")
    n.location = (1400, 0)
    return n
