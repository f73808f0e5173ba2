# SPDX-License-Identifier: GPL-3.0-or-later
"""Haze layers follow their core: after the user edits the BSDF a layer sits on (any input, link
or setting, in the node editor, the Properties editor, a driver or a script), the layer's copies
and node math are brought up to date.

A ``depsgraph_update_post`` handler (persistent across file loads) sees which materials were
updated; for a lean or in-shader one it reads the user's node-editor edits of the add-on's
nodes back into the stamp (material.adopt_node_edits); for a layered one whose core changed
since the layer last wrote it (a fingerprint of the core's inputs, links and settings),
:func:`sync` reruns the layer with its stamped haze.
The layer's own writes change the fingerprint only once: the handler then finds it unchanged
and stops.  Scripts that edit a material no object uses (no depsgraph update) call
``api.sync_haze(mat)``; rendering an edited material syncs it first (the render's depsgraph
update runs the handler).
"""
import bpy
from bpy.app.handlers import persistent

from .. import constants as K
from . import layer, material, properties, stamp
from .context import plain_message

_fingerprints = layer.FINGERPRINTS
_busy = False


def sync(mat, *, force=False):
    """Bring ``mat``'s haze layer up to date with its core; returns whether it was rerun.  For a
    lean / in-shader material: read the user's node-editor edits of the add-on's nodes back
    into its parameters (material.adopt_node_edits); returns whether there were any."""
    if mat is None or mat.library is not None:
        return False
    if not layer.is_layered(mat):
        if not material.is_hazy(mat):
            return False
        adopted, _ = material.adopt_node_edits(mat)
        return bool(adopted)
    state = layer.layer_state(mat) or {}
    problem = stamp.layer_problem(mat, state.get("problems", []))
    if problem is not None:  # rerunning would take the damaged values for the user's
        properties.last_error[mat.session_uid] = problem
        return False
    core = layer.find_core(mat.node_tree, state.get("core"))
    if core is None:
        properties.last_error[mat.session_uid] = (
            "The BSDF the haze layer sits on is gone: Remove Haze, then Make Hazy again")
        return False
    key = mat.session_uid
    if not force and _fingerprints.get(key) == layer.fingerprint(core):
        return False
    gaps = _baked_gaps(mat, state, core) if "baked" in state else []
    if gaps:  # the layer would have to rebuild them from maps it no longer knows
        properties.last_error[key] = (
            f"The haze layer of “{mat.name}” lists no baked map for {len(gaps)} of its values "
            f"(its stamp lost them): convert the maps again, or Remove Haze")
        return False
    try:
        layer.apply(mat, layer.haze_of(mat), core=core)  # records the new fingerprint
    except Exception as exc:  # noqa: BLE001  (a handler must never raise into Blender)
        properties.last_error[key] = plain_message(exc)
        layer.FINGERPRINTS[key] = layer.fingerprint(core)  # said once, not per update
        return False
    refresh_derived(mat)
    return True


def _needs_haze_map(expr, seen):
    """Whether ``expr`` reads a per-texel haze value (a graph input "haze:<name>")."""
    stack = [expr]
    while stack:
        e = stack.pop()
        if id(e) in seen:
            continue
        seen.add(id(e))
        if e.op == "input" and (e.name or "").startswith("haze:"):
            return True
        stack.extend(a for a in e.args if hasattr(a, "op"))
    return False


def _baked_gaps(mat, state, core):
    """The outputs of a baked layer that vary with a haze map but have no baked image."""
    baked = layer._baked_from_state(mat.node_tree, state) or {"maps": {}}
    plan = layer.Plan(core, layer.haze_of(mat), dict(state.get("base", {})))
    flat, _, _, _ = layer.output_keys(plan)
    return [k for k, e in flat.items() if k not in baked["maps"] and _needs_haze_map(e, set())]


def refresh_derived(mat):
    """What is built from a layer follows it after every layer.apply: the export fallback
    (blender/interchange.py, the user's BSDF at haziness 0) and the EEVEE-only output
    (blender/eevee_layer.py, when one was asked for).  Problems go to the panel, never up."""
    from . import eevee_layer
    try:
        if eevee_layer.requested_mode(mat) is not None:
            eevee_layer.sync_eevee_output(mat)
    except ValueError as exc:
        properties.last_error[mat.session_uid] = plain_message(exc)
    refresh_fallback(mat)


def refresh_fallback(mat):
    """The export fallback (if any) after the layer or its EEVEE output changed: its render
    output for EEVEE gives way to the EEVEE-only output, and comes back without it."""
    from . import interchange
    try:
        interchange.refresh_stamped_fallback(mat)
    except ValueError as exc:  # (a depsgraph handler: the panel shows it)
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
            try:
                sync(mat)
            except Exception as exc:  # noqa: BLE001 (a handler must not raise on every update)
                properties.last_error[mat.session_uid] = (
                    f"Hazy Gloss could not update the haze layer of “{mat.name}”: "
                    f"{plain_message(exc)}")
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
