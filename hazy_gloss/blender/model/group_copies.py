# SPDX-License-Identifier: GPL-3.0-or-later
"""Copies of the layer's groups and tables that an append of hazy materials from another file
brings ("<name>.001" beside the file's same ones): they give way to the file's."""
import bpy

from ... import constants as K
from . import layer_group as lg, stamp


def merge_copies():
    """Copies of the file's layer groups, section groups and tables that an append of hazy
    materials from another file brought ("<name>.001", the same as the file's own): their
    users get the file's, and the copies go.  Returns how many data-blocks went."""
    copy = lg.COPY_SUFFIX
    groups = [g for g in bpy.data.node_groups if g.library is None]
    ours = [g for g in groups if copy.search(g.name) and (stamp.group(g, K.GROUP_STAMP) or {})
            .get("kind") in ("layer", "layer part")]
    tables = [i for i in bpy.data.images if i.library is None and copy.search(i.name)
              and i.get("hazy_gloss_table") is not None]
    if not ours and not tables:
        return 0
    groups_before = [g for g in groups if g not in ours]
    images_before = [i for i in bpy.data.images if i not in tables]
    by_name = {g.name: g for g in groups_before}
    gone = []
    for c in [g for g in ours if lg.is_layer_group(g)]:
        o = by_name.get(copy.sub("", c.name))
        if o is not None and _same_layer_group(c, o):
            c.user_remap(o)
            gone.append(c)
    for ng in [g for g in groups if lg.is_layer_group(g) and g not in gone]:
        lg._share_parts(ng, groups_before, images_before, ours, tables)
    bpy.data.batch_remove(gone)
    n = len(gone)
    for kind in (ours, tables):  # (section groups first: they hold the tables)
        unused = [i for i in kind if i not in gone and i.users == 0]
        bpy.data.batch_remove(unused)
        gone += unused
        n += len(unused)
    return n


def _same_layer_group(new, old):
    """Whether ``new`` (a copy an append brought) is ``old``: the same stamp, the same nodes,
    and each section group and table the same as ``old``'s (from this code, not edited).  A copy
    whose sections are ``old``'s own is one the artist made (Make Single User): kept."""
    if not lg.is_layer_group(old) or old.library is not None or \
            stamp.group(new, K.GROUP_STAMP) != stamp.group(old, K.GROUP_STAMP) or \
            lg._fingerprint(new) != lg._fingerprint(old):
        return False
    copied = False
    for node in new.nodes:
        if node.bl_idname != "ShaderNodeGroup":
            continue
        twin = old.nodes.get(node.name)
        a, b = node.node_tree, getattr(twin, "node_tree", None)
        if a is b:
            continue
        copied = True
        if a is None or b is None or not lg._same_part(a, b) or \
                lg._fingerprint(a) != (stamp.group(a, K.GROUP_STAMP) or {}).get("print"):
            return False
        for inner in a.nodes:
            if inner.bl_idname in K.IMAGE_NODES:
                other = b.nodes.get(inner.name)
                img = getattr(other, "image", None)
                if inner.image is not img and (inner.image is None or img is None
                                               or not lg._same_table(inner.image, img)):
                    return False
    return copied
