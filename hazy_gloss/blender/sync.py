# SPDX-License-Identifier: GPL-3.0-or-later
"""Haze layers follow their core: after the user edits the BSDF a layer sits on (any input, link
or setting, in the node editor, the Properties editor, a driver or a script), the layer's copies
and node math are brought up to date.

A ``depsgraph_update_post`` handler (persistent across file loads) sees which materials were
updated; for a layered one whose core changed since the layer last wrote it (a fingerprint of
the core's inputs, links and settings), :func:`sync` reruns the layer with its stamped haze.
The layer's own writes change the fingerprint only once: the handler then finds it unchanged
and stops.  Scripts that edit a material no object uses (no depsgraph update) call
``api.sync_haze(mat)``; rendering an edited material syncs it first (the render's depsgraph
update runs the handler).
"""
import bpy
from bpy.app.handlers import persistent

from .. import constants as K
from . import layer, properties
from .context import plain_message

_fingerprints = layer.FINGERPRINTS
_busy = False


def sync(mat, *, force=False):
    """Bring ``mat``'s haze layer up to date with its core; returns whether it was rerun."""
    if not layer.is_layered(mat) or mat.library is not None:
        return False
    state = layer.layer_state(mat) or {}
    core = layer.find_core(mat.node_tree, state.get("core"))
    if core is None:
        properties.last_error[mat.session_uid] = (
            f"The BSDF the haze layer sits on is gone: Remove Haze, then Make Hazy again")
        return False
    key = mat.session_uid
    if not force and _fingerprints.get(key) == layer.fingerprint(core):
        return False
    try:
        layer.apply(mat, layer.haze_of(mat), core=core)  # records the new fingerprint
    except Exception as exc:  # noqa: BLE001  (a handler must never raise into Blender)
        properties.last_error[key] = plain_message(exc)
        layer.FINGERPRINTS[key] = layer.fingerprint(core)  # said once, not per update
        return False
    refresh_derived(mat)
    return True


def refresh_derived(mat):
    """What is built from a layer follows it after every layer.apply: the export fallback
    (blender/interchange.py, the user's BSDF at haziness 0) and the EEVEE-only output
    (blender/eevee_layer.py, when one was asked for).  Problems go to the panel, never up."""
    from . import eevee_layer, interchange
    try:
        if interchange.FALLBACK_STAMP in mat:
            interchange.refresh_export_fallback(mat)
        if eevee_layer.requested_mode(mat) is not None:
            eevee_layer.sync_eevee_output(mat)
    except ValueError as exc:
        properties.last_error[mat.session_uid] = plain_message(exc)


@persistent
def on_depsgraph_update(scene, depsgraph):
    global _busy
    if _busy:
        return
    mats = []
    for update in depsgraph.updates:
        idd = getattr(update.id, "original", update.id)
        if isinstance(idd, bpy.types.Material) and K.STAMP in idd and idd not in mats:
            mats.append(idd)
    if not mats:
        return
    _busy = True
    try:
        for mat in mats:
            sync(mat)
    finally:
        _busy = False


@persistent
def on_load(_dummy=None):
    _fingerprints.clear()


def register():
    if on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)
    if on_load not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(on_load)


def unregister():
    for handlers, fn in ((bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
                         (bpy.app.handlers.load_post, on_load)):
        while fn in handlers:
            handlers.remove(fn)
    _fingerprints.clear()
