# SPDX-License-Identifier: GPL-3.0-or-later
"""Copies of the layer's groups and tables that an append of hazy materials from another file
brings ("<name>.001" beside the file's same ones): they give way to the file's."""
import bpy

from ... import constants as K
from . import layer_group as lg, stamp

__all__ = ("merge_copies",)


def merge_copies():
    """Copies of the file's layer groups and tables that an append of hazy materials from
    another file brought ("<name>.001", the same as the file's own): their users get the
    file's, and the copies go.  A copy the artist made (Make Single User: no link to the file
    it came from) stays theirs.  Returns how many data-blocks went."""
    copy = lg.COPY_SUFFIX
    groups = [g for g in bpy.data.node_groups if g.library is None]
    ours = [g for g in groups if copy.search(g.name) and lg.is_layer_group(g)
            and g.library_weak_reference is not None]
    tables = [i for i in bpy.data.images if i.library is None and copy.search(i.name)
              and i.get("hazy_gloss_table") is not None]
    if not ours and not tables:
        return 0
    by_name = {g.name: g for g in groups if g not in ours}
    gone = []
    for c in ours:
        o = by_name.get(copy.sub("", c.name))
        if o is not None and _same_layer_group(c, o):
            c.user_remap(o)
            gone.append(c)
    images_before = [i for i in bpy.data.images if i not in tables]
    for ng in [g for g in groups if lg.is_layer_group(g) and g not in gone]:
        lg.share_tables(ng, images_before, tables)
    bpy.data.batch_remove(gone)
    unused = [i for i in tables if i.users == 0]
    bpy.data.batch_remove(unused)
    return len(gone) + len(unused)


def _same_layer_group(new, old):
    """Whether ``new`` (a copy an append brought) is ``old``: the same stamp, both as this code
    built them (not edited since), and the same tables."""
    if old.library is not None or stamp.group(new, K.GROUP_STAMP) != stamp.group(old, K.GROUP_STAMP):
        return False
    if lg.edited_parts(new) or lg.edited_parts(old) or \
            new.get(K.GROUP_PRINT) != old.get(K.GROUP_PRINT):
        return False
    for node in new.nodes:
        if node.bl_idname in K.IMAGE_NODES:
            twin = old.nodes.get(node.name)
            img = getattr(twin, "image", None)
            if node.image is not img and (node.image is None or img is None
                                          or not lg.same_table(node.image, img)):
                return False
    return True
