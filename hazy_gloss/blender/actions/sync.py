# SPDX-License-Identifier: GPL-3.0-or-later
"""Node-editor edits of the add-on's own materials, read back.

A haze layer (blender.model.layer) needs nothing here: its node group computes everything from the
layer node's inputs, whatever changes them.  A ``depsgraph_update_post`` handler (persistent
across file loads) sees which materials were updated; for a lean or in-shader one it reads the
user's node-editor edits of the add-on's nodes back into the stamp
(blender.model.material_edits.adopt_node_edits).  Scripts that edit a material no object
uses (no depsgraph update) call ``api.sync_haze(mat)``.  When the file's node groups change in number (an append), the copies of the layer's groups and
tables an append of hazy materials brought give way to the file's (group_copies.merge_copies);
a layer node whose inputs now reach another part of the haze mapping moves to the group that
holds it (``follow_parts``: on every update, before a save and, in the background, before
each frame); before a save, painted
haziness maps are packed again (``save_pre``); after a load, the layer
nodes' curves Blender 5.2's versioning moved are put back (``repair_thin_wall_shift``).
"""
import bpy
from bpy.app.handlers import persistent

from ... import constants as K
from . import eevee_output, messages
from ..model import (fallback, group_copies, layer, layer_animation, layer_group, layer_values,
                     material_edits, material_read)
from .messages import plain_message

__all__ = ("sync", "follow_parts", "refresh_derived", "refresh_fallback", "on_depsgraph_update",
           "parts_on_frame_change", "on_load", "THIN_WALL_SHIFT", "repair_thin_wall_shift",
           "repack_painted_maps", "parts_before_save", "register", "unregister")

_fingerprints = {}  # ("fallback", material session_uid) -> fingerprint of the layer node's inputs
_busy = False
_group_count = -1  # node groups in the file at the last update (merge_copies when it changes)


def sync(mat, *, force=False):
    """For a lean / in-shader material: read the user's node-editor edits of the add-on's nodes
    back into its parameters (material_edits.adopt_node_edits); returns whether there were any.
    A haze layer: its group computes everything; what is built from it follows (the parts its
    inputs reach, the EEVEE-only output, the export fallback; ``force``: rebuild the fallback);
    returns whether something moved."""
    if mat is None or mat.library is not None:
        return False
    if _todays_layer(mat):
        if follow_parts(mat):
            refresh_derived(mat)
            return True
        if eevee_output.requested_mode(mat) is not None and not eevee_output.follows_the_user(mat):
            refresh_derived(mat)  # (the artist switched outputs: EEVEE renders their new one)
            return True
        return _follow_fallback(mat, force)
    if not layer.is_layered(mat):
        if not material_read.is_hazy(mat):
            return False
        adopted, _ = material_edits.adopt_node_edits(mat)
        return bool(adopted)
    return _follow_fallback(mat, force)


def follow_parts(mat):
    """The layer node moves to the group of the parts its inputs reach now (layer_parts): an
    input linked, keyed, driven or set where the group has no part for it brings the part in,
    and the part goes when nothing needs it.  Only between this add-on's groups of today: an
    outdated group (another Blender's, an earlier add-on's) holds every part, and moves on
    the next haze edit or Upgrade Haze Layers.  Returns whether it moved."""
    node = layer.layer_node(mat)
    if node is None or node.node_tree is None or node.node_tree.library is not None:
        return False
    want = layer.wanted_group(node)
    if want is None or layer_group.fits(node.node_tree, *want) or \
            not layer_group.fits(node.node_tree, *want[:5], parts=layer_group.parts_of(node.node_tree)):
        return False
    layer.swap_group(node, layer_group.ensure_group(*want))
    return True


def _todays_layer(mat):
    """A cheap look at the stamp (every edit of a layered material asks): a record of today's
    layer node.  Anything else (damaged, no layer) takes the full reading."""
    try:
        rec = mat.get(K.STAMP, {}).get("layer")
        return rec is not None and rec.get("version") == layer.LAYER_VERSION
    except (AttributeError, TypeError):
        return False


def _follow_fallback(mat, force):
    """A layer's export fallback (a copy of the user's BSDF for glTF / USD, not rendered)
    follows edits of the layer node's inputs.  Returns whether it was refreshed."""
    if fallback.FALLBACK_STAMP not in mat:
        return False
    node = layer.layer_node(mat)
    if node is None:
        return False
    key = ("fallback", mat.session_uid)
    now = layer_values.input_fingerprint(node)
    if not force and _fingerprints.get(key) == now:
        return False
    _fingerprints[key] = now
    refresh_fallback(mat)
    return True


def refresh_derived(mat):
    """What is built from a layer follows it after every layer.apply: the export fallback
    (blender/model/fallback.py, the user's BSDF at haziness 0) and the EEVEE-only output
    (blender/actions/eevee_output.py, when one was asked for).  Problems go to the panel, never up."""
    try:
        if eevee_output.requested_mode(mat) is not None:
            eevee_output.sync_eevee_output(mat)
    except ValueError as exc:
        messages.last_error[mat.session_uid] = plain_message(exc)
    refresh_fallback(mat)


def refresh_fallback(mat):
    """The export fallback (if any) after the layer or its EEVEE output changed: its render
    output for EEVEE gives way to the EEVEE-only output, and comes back without it."""
    try:
        fallback.refresh_stamped_fallback(mat)
    except ValueError as exc:  # (a depsgraph handler: the panel shows it)
        messages.last_error[mat.session_uid] = plain_message(exc)


@persistent
def on_depsgraph_update(scene, depsgraph):
    global _busy, _group_count
    if _busy:
        return
    if len(bpy.data.node_groups) != _group_count:  # (an append may have brought copies)
        _busy = True
        try:
            group_copies.merge_copies()
        except Exception:  # noqa: BLE001 (a handler must not raise; the copies just stay)
            pass
        finally:
            _busy = False
            _group_count = len(bpy.data.node_groups)
    mats = []
    for update in depsgraph.updates:
        idd = getattr(update.id, "original", update.id)
        if isinstance(idd, bpy.types.NodeTree):
            if not idd.is_embedded_data:
                layer_group.forget_edits()  # (a group edited: the panel's note on edited groups)
                continue
            idd = _owner(idd)  # (a driver added to a node reports only the material's tree)
        if isinstance(idd, bpy.types.Material) and K.STAMP in idd and idd not in mats:
            mats.append(idd)
    if not mats:
        return
    _busy = True
    try:
        for mat in mats:
            try:
                sync(mat)
            except Exception as exc:  # noqa: BLE001 (a handler must not raise on every update)
                messages.last_error[mat.session_uid] = (
                    f"Hazy Gloss could not update the haze layer of “{mat.name}”: "
                    f"{plain_message(exc)}")
    finally:
        _busy = False


def _owner(tree):
    """The material whose node tree ``tree`` is, or None."""
    return next((m for m in bpy.data.materials if m.node_tree == tree), None)


@persistent
def parts_on_frame_change(_scene=None, _depsgraph=None):
    """A script or a farm with the add-on (in the background): before a frame is evaluated,
    each layer moves to the group of the parts its inputs reach (a key added since the last
    update counts; no depsgraph update need have run).  Not on render_pre: a group moved as a
    render starts crashes Cycles in 5.2 and 5.3.  In the UI the depsgraph handler does it."""
    if bpy.app.background:
        parts_before_save()


@persistent
def on_load(_dummy=None):
    _fingerprints.clear()
    repair_thin_wall_shift()


#: Blender 5.2's versioning of a file older than 5.2.36 (the Principled BSDF gained Thin Wall
#: at input 5) moves the curves at nodes["X"].inputs[5..30] up by one for every name X of a
#: Principled BSDF in the file, in every material: a layer node named as a Principled
#: elsewhere is moved too, though its inputs did not move (5.3 moves the Principled's own).
#: Measured in 5.2.3; the versions it is repaired in.
THIN_WALL_SHIFT = {"blender": ((5, 2, 0), (5, 2, 3)), "file_before": (5, 2, 36),
                   "orig": 5, "offset": 1, "total": 31}


def repair_thin_wall_shift():
    """After a file from before 5.2.36 is opened in 5.2: the layer nodes' input curves Blender
    moved (THIN_WALL_SHIFT) go back to their inputs.  Returns {material name: [inputs whose
    curve could not be told apart]} of the materials repaired."""
    lo, hi = THIN_WALL_SHIFT["blender"]
    if not lo <= tuple(bpy.app.version) <= hi or \
            tuple(bpy.data.version) >= THIN_WALL_SHIFT["file_before"]:
        return {}
    names = {n.name for t in _shader_trees() for n in t.nodes
             if n.bl_idname == "ShaderNodeBsdfPrincipled"}
    frame = bpy.context.scene.frame_current if bpy.context.scene is not None else 1
    done = {}
    for mat in bpy.data.materials:
        if mat.library is not None or K.STAMP not in mat or mat.node_tree is None:
            continue
        node = layer.layer_node(mat)
        if node is None or node.name not in names:
            continue
        unsure = layer_animation.unshift_inputs(
            mat.node_tree, node, THIN_WALL_SHIFT["orig"], THIN_WALL_SHIFT["offset"],
            THIN_WALL_SHIFT["total"], frame)
        done[mat.name] = unsure
        if unsure:
            messages.last_error[mat.session_uid] = (
                f"Blender {bpy.app.version_string} moved the keyframes of this file's layer "
                f"node “{node.name}” when it opened it; the curve now on "
                f"{', '.join(unsure)} may be the one of the input before it: check it")
    return done


def _shader_trees():
    """Every shader node tree of the file (materials', worlds', lights' and node groups)."""
    for coll in (bpy.data.materials, bpy.data.worlds, bpy.data.lights):
        for idb in coll:
            if getattr(idb, "node_tree", None) is not None:
                yield idb.node_tree
    for ng in bpy.data.node_groups:
        if ng.bl_idname == "ShaderNodeTree":
            yield ng


@persistent
def repack_painted_maps(_dummy=None):
    """Before a save: the haziness maps Add Haziness Map made (packed images) are packed again
    when painted since (Blender saves a packed image's old bytes, and the paint is lost)."""
    for img in bpy.data.images:
        if img.library is None and K.PAINTED_MAP in img and img.packed_file is not None \
                and img.is_dirty:
            try:
                img.pack()
            except RuntimeError as exc:  # (a handler must not raise: the save goes on)
                print(f"Hazy Gloss: could not pack the painted map “{img.name}”: {exc}")


@persistent
def parts_before_save(_dummy=None):
    """Every layer's group holds the parts its inputs reach (a key added since the last update
    counts): the saved file renders every frame of its animation without the add-on."""
    global _busy
    _busy = True
    try:
        for mat in bpy.data.materials:
            if mat.library is None and K.STAMP in mat and _todays_layer(mat):
                try:
                    if follow_parts(mat):
                        refresh_derived(mat)
                except Exception as exc:  # noqa: BLE001 (a save must never fail on it)
                    messages.last_error[mat.session_uid] = plain_message(exc)
    finally:
        _busy = False


def register():
    if parts_on_frame_change not in bpy.app.handlers.frame_change_pre:
        bpy.app.handlers.frame_change_pre.append(parts_on_frame_change)
    if parts_before_save not in bpy.app.handlers.save_pre:
        bpy.app.handlers.save_pre.append(parts_before_save)
    if on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)
    if on_load not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(on_load)
    if repack_painted_maps not in bpy.app.handlers.save_pre:
        bpy.app.handlers.save_pre.append(repack_painted_maps)


def unregister():
    for handlers, fn in ((bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
                         (bpy.app.handlers.load_post, on_load),
                         (bpy.app.handlers.save_pre, repack_painted_maps),
                         (bpy.app.handlers.save_pre, parts_before_save),
                         (bpy.app.handlers.frame_change_pre, parts_on_frame_change)):
        while fn in handlers:
            handlers.remove(fn)
    _fingerprints.clear()
