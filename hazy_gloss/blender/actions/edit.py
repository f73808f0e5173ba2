# SPDX-License-Identifier: GPL-3.0-or-later
"""Editing a hazy material's parameters: :func:`update_material` (api.update_material) and
:func:`edit_material` (what the panel's property setters call).

Above both kinds of hazy material: a haze layer (blender.model.layer) gets its haze values and then
what is built from it follows (sync.refresh_derived: the EEVEE-only output, the export
fallback); a material of the add-on's own (blender.model.material) adopts the user's node-editor edits
it can read back (blender.model.material_edits) and is rebuilt.
"""
from ...core.parameters import DEFAULTS, PARAMETERS, normalise, normalise_haze
from ..model import layer, material, material_edits, material_read, stamp
from . import messages, sync
from ..model.material_read import edit_problem
from .messages import plain_message

__all__ = ("REPLACED", "update_material", "edit_material", "forget_busy")

#: material session_uid -> the node-editor edits (as "node: input") the last update_material
#: could not read back and replaced (edit_material tells the user).
REPLACED = {}
_busy = set()  # as_pointer() of the materials edit_material is rebuilding


def update_material(mat, **changes):
    """Change some perceptual parameters of a hazy material.  Returns (HazeMapping, group
    inputs whose links had to be dropped because the new configuration has no such input)."""
    material_read.check_material(mat, "update_material")
    REPLACED.pop(mat.session_uid, None)
    if mat.library is not None:
        raise ValueError(f"material {mat.name!r} is linked from a library and cannot be edited")
    if layer.is_layered(mat):
        if layer.is_baked(mat):
            raise ValueError(material_read.baked_problem(mat))
        normalise_haze(changes)  # unknown names first (did you mean ...)
        problem = stamp.layer_problem(mat, layer.layer_state(mat)["problems"], fixing=changes)
        if problem is not None:  # only setting the damaged haze values repairs the stamp
            raise stamp.StampError(problem)
        h = normalise_haze(changes, layer.haze_of(mat))
        layer.apply(mat, h)
        sync.refresh_derived(mat)  # the export fallback and the EEVEE output follow
        return None, []
    unknown = {k: v for k, v in changes.items() if k not in PARAMETERS}
    if unknown:
        normalise(unknown)  # raises: unknown names, with "did you mean"
    values, problems = stamp.read_material(mat)
    if values is None:
        raise ValueError(f"material {mat.name!r} is not a hazy material (use Make Hazy or "
                         f"api.create_material)")
    damaged = set(PARAMETERS) if "*" in problems else set(problems)
    if damaged - set(changes):  # a change that sets every damaged value repairs the stamp
        raise stamp.StampError(stamp.material_problem(
            mat, {k: v for k, v in problems.items() if k == "*" or k not in changes}))
    merged = dict(DEFAULTS)
    merged.update(values)
    replaced = []
    if not problems:  # node-editor edits: read back where they can be, else replaced (said)
        read_back, replaced = material_edits.adopt_edits(mat, normalise(dict(merged), explicit=()))
        merged.update(read_back)
    REPLACED[mat.session_uid] = [str(e) for e in replaced]
    merged.update(changes)
    p = normalise(merged, explicit=changes)
    if not p["shader_mapping"]:
        textured = material.UserLinks(mat.node_tree).textured_inputs if mat.node_tree else []
        if textured:
            raise ValueError(f"Textures are connected to {', '.join(textured)}: constant mapping "
                             f"cannot use them. Keep in-shader mapping, or disconnect them first")
    return material.apply(mat, p)


def edit_material(mat, **changes):
    """Apply perceptual ``changes`` to the hazy material ``mat`` and rebuild its nodes.

    Returns ``(mapping, message)``: the HazeMapping and None, or None and the plain-language
    reason when the change was refused (also stored in :data:`messages.last_error`).  A
    re-entrant call for a material that is being rebuilt is ignored (returns (None, None))."""
    key = mat.as_pointer()
    if key in _busy:
        return None, None
    problem = edit_problem(mat)
    if problem is not None:
        messages.set_error(mat, problem)
        return None, problem
    _busy.add(key)
    try:
        m, dropped = update_material(mat, **changes)
    except (ValueError, TypeError) as exc:
        msg = plain_message(exc)
        messages.set_error(mat, msg)
        return None, msg
    finally:
        _busy.discard(key)
    said = []  # one line (the panel shows last_error as one label)
    if dropped:
        said.append("Disconnected (no such input any more): " + ", ".join(dropped))
    replaced = REPLACED.get(mat.session_uid)
    if replaced:
        said.append(f"Replaced node-editor edits these parameters cannot represent: "
                    f"{', '.join(replaced)} (Ctrl+Z brings them back)")
    if said:
        messages.set_error(mat, "; ".join(said))
    else:
        messages.clear_error(mat)
    return m, None


def forget_busy():
    """Unregistering: no edit is under way any more."""
    _busy.clear()
