# SPDX-License-Identifier: GPL-3.0-or-later
"""Reading the stamps the add-on keeps on materials, whatever they hold.

A stamp is an ID property (``mat["hazy_gloss"]``, a haze layer's ``mat["hazy_gloss"]["layer"]``,
the recomposite and export-fallback stamps), so anyone can change it: the custom-properties
panel, the Python console, another add-on, a damaged file.  Everything that reads one goes
through here, so a damaged stamp gives one line naming the key and what would be valid, and a
safe result, never a Python exception from deep inside:

- :func:`read_material`: the parameters of a lean / in-shader material, each key checked on its
  own (core.parameters.check_value) -> (valid values, {key: problem});
- :func:`check_layer_node`: a haze layer's record with what does not read left out (the layer
  node and the kept BSDF are then found by their tags);
- :func:`group`: any other stamp as a dict, or None when it is not one.

bpy-free apart from reading the ID properties handed in (duck-typed ``to_dict``/``to_list``).
"""
from __future__ import annotations

import math

from ... import constants as K
from ...core.lobes import check_kind
from ...core.parameters import HAZE_PARAMETERS, PARAMETERS, short_repr, check_value

__all__ = ("StampError", "plain", "group", "read_material", "check_layer_node",
           "material_problem")

#: Nesting beyond this is junk (the add-on's stamps are at most five levels deep).
MAX_DEPTH = 12


class StampError(ValueError):
    """A stamp that cannot be read (one line: the material, the key, what is valid)."""


def plain(value, depth=0):
    """An ID property value as plain Python (dict, list, str, int, float), recursively."""
    if depth > MAX_DEPTH:
        raise StampError("nested too deeply")
    if hasattr(value, "to_dict"):
        value = value.to_dict()
    elif hasattr(value, "to_list"):
        value = value.to_list()
    if isinstance(value, dict):
        return {str(k): plain(v, depth + 1) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v, depth + 1) for v in value]
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return value


def _kind_of(value):
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return f"the number {short_repr(value)}"
    if isinstance(value, str):
        return f"the string {short_repr(value)}"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    return f"a {type(value).__name__}"


def group(owner, key):
    """``owner[key]`` as a dict; None when absent or not a group (a damaged stamp of a kind
    that only ever holds a few names: callers treat it as absent)."""
    try:
        raw = owner.get(key)
    except (AttributeError, TypeError):
        return None
    if raw is None:
        return None
    try:
        d = plain(raw)
    except StampError:
        return None
    return d if isinstance(d, dict) else None


def _name(mat):
    return f"“{getattr(mat, 'name', mat)}”"


# --------------------------------------------------------------------------------------------
# A lean / in-shader material: mat["hazy_gloss"]
# --------------------------------------------------------------------------------------------


def raw_material(mat):
    """The stamp as plain Python: a dict, None (no stamp) or whatever else it holds."""
    raw = mat.get(K.STAMP)
    if raw is None:
        return None
    try:
        return plain(raw)
    except StampError:
        return "<nested too deeply>"


def read_material(mat):
    """(values, problems) of a material's stamp: ``values`` {key: normalised value} of every
    parameter that reads, ``problems`` {key: one-line reason} of those that do not ("*" when
    the stamp is not a group at all).  (None, {}) without a stamp.  A haze layer's stamp
    (``"layer"`` in it) is :func:`check_layer_node`'s."""
    d = raw_material(mat)
    if d is None:
        return None, {}
    if not isinstance(d, dict):
        return {}, {"*": f"the Hazy Gloss stamp of {_name(mat)} (mat[{K.STAMP!r}]) is "
                         f"{_kind_of(d)}, not a group of parameters"}
    values, problems = {}, {}
    for key in PARAMETERS:
        if key == "smoothness":
            use = d.get("use_smoothness", False)
            if not isinstance(use, (bool, int)) or isinstance(use, int) and use not in (0, 1):
                problems[key] = f"use_smoothness must be True or False, got {short_repr(use)}"
                continue
            if not use:
                values[key] = None
                continue
            key_value = d.get("smoothness")
        elif key not in d:
            problems[key] = f"{key} is missing"
            continue
        else:
            key_value = d[key]
        try:
            values[key] = check_value(key, key_value)
        except ValueError as exc:
            problems[key] = str(exc)
    if "kind" in values and "distribution" in values:
        try:
            check_kind(values["kind"], values["distribution"])
        except ValueError as exc:
            problems["distribution"] = str(exc)
            del values["distribution"]
    return values, problems


def material_problem(mat, problems):
    """One line for the first of ``problems`` (read_material's), naming the material."""
    key, why = next(iter(problems.items()))
    if key == "*":
        return f"{why[:1].upper()}{why[1:]}: apply a preset to reset it"
    more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
    return (f"The stored Hazy Gloss parameters of {_name(mat)} are damaged: {why}{more}; "
            f"apply a preset (or set it again) to reset it")


# --------------------------------------------------------------------------------------------
# A haze layer: mat["hazy_gloss"]["layer"]
# --------------------------------------------------------------------------------------------


def _finite_number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def describe(mat):
    """What the material's stamp is, in a few words (for "the stamp is ..., but ...")."""
    try:
        d = group(mat, K.STAMP)
    except StampError:
        d = None
    if d is None:
        return _kind_of(raw_material(mat)) if K.STAMP in mat else "missing"
    return "a group without its \"layer\" entry" if "layer" not in d else \
        "a group whose \"layer\" entry does not read"


def _finite_list(v, n):
    return isinstance(v, (list, tuple)) and len(v) == n and all(_finite_number(x) for x in v)


def check_layer_node(raw):
    """The record of a haze layer of today's form (blender.model.layer, LAYER_VERSION 2) with what
    does not read left out: the layer node and the kept BSDF are then found by their tags, and
    Remove Haze restores what the record still holds."""
    out = {"version": raw.get("version")}
    for key in ("node", "original"):
        if isinstance(raw.get(key), str) and raw[key]:
            out[key] = raw[key]
    restore = raw.get("restore")
    r = {}
    if isinstance(restore, dict):
        for key in ("name", "label", "parent"):
            if isinstance(restore.get(key), str):
                r[key] = restore[key]
        for key in ("hide", "mute", "use_custom_color"):
            if isinstance(restore.get(key), (bool, int)) and not isinstance(restore.get(key), float):
                r[key] = bool(restore[key])
        if _finite_list(restore.get("location"), 2):
            r["location"] = [float(x) for x in restore["location"]]
        if _finite_number(restore.get("width")) and 0.0 < float(restore["width"]) < 1e5:
            r["width"] = float(restore["width"])
        if _finite_list(restore.get("color"), 3):
            r["color"] = [min(max(float(x), 0.0), 1.0) for x in restore["color"]]
    out["restore"] = r
    baked_from = raw.get("baked_from")
    if isinstance(baked_from, dict):
        out["baked_from"] = {k: v for k, v in baked_from.items() if isinstance(k, str)
                             and isinstance(v, dict) and len(v) == 1
                             and (isinstance(v.get("link"), str) or _finite_number(v.get("value"))
                                  or any(_finite_list(v.get("value"), n) for n in (3, 4)))}
    baked_haze = raw.get("baked_haze")
    if isinstance(baked_haze, dict):
        out["baked_haze"] = {k: v for k, v in baked_haze.items() if _baked_value_reads(k, v)}
    return out


def _baked_value_reads(key, value):
    """Whether a baked layer's recorded haze value is one the API takes ("texture" where a map
    gave it; an extent's axes each)."""
    if key not in HAZE_PARAMETERS:
        return False
    if (key == "haze_extent") != (isinstance(value, list) and len(value) == 2):
        return False  # (an extent as its two axes, everything else one value)
    parts = value if key == "haze_extent" else [value]
    try:
        for v in parts:
            if v != K.TEXTURED:
                check_value(key, v if len(parts) == 1 else (v, v))
    except (ValueError, TypeError):
        return False
    return True


#: A layer problem's "keys" when its line says its own way out (a grouped or ungrouped layer
#: node: Remove Haze would refuse it, so "Remove Haze, then Make Hazy again" is no way out).
OWN_WAY_OUT = "its own way out"


def own_way_out(problems):
    """The line of a layer problem that says its own way out (OWN_WAY_OUT), or None."""
    return next((why for why, keys in problems if keys == OWN_WAY_OUT), None)


def layer_problem(mat, problems, fixing=()):
    """One line for the first problem not fixed by setting the haze parameters ``fixing``
    (None when every problem is), naming the material and the way out."""
    left = [(why, keys) for why, keys in problems
            if keys is None or keys == OWN_WAY_OUT or not set(keys) <= set(fixing)]
    if not left:
        return None
    why, keys = left[0]
    if keys == OWN_WAY_OUT:
        return f"The haze layer of {_name(mat)}: {why}"
    more = f" (and {len(left) - 1} more)" if len(left) > 1 else ""
    way = ("apply a preset (or set it in the panel) to reset it, or Remove Haze" if keys else
           "Remove Haze (it restores what it can), then Make Hazy again")
    return f"The haze layer stamp of {_name(mat)} is damaged: {why}{more}; {way}"


def damaged_haze(problems):
    """The haze parameters whose stored values do not read."""
    return sorted({k for _, keys in problems if keys and keys != OWN_WAY_OUT for k in keys})

