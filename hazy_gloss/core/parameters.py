# SPDX-License-Identifier: GPL-3.0-or-later
"""The perceptual parameters of a hazy material: validation (bpy-free).

Their names, defaults and ranges are derived from the one schema, hazy_gloss.schema (re-exported
here: PARAMETERS, DEFAULTS, HAZE_PARAMETERS, HAZE_DEFAULTS, RANGES).  :func:`normalise` checks
the parameters of one material (the scripting API, the panel, presets) and raises ValueError
with one line naming the parameter and what would be valid; :func:`sanitise` clamps and counts
bad texels of a map (texture conversion) with the same ranges.
"""
from __future__ import annotations

import difflib
import math

import numpy as np

from .. import constants as K
from ..schema import (DEFAULTS, HAZE_DEFAULTS, HAZE_PARAMETERS, PARAMETERS, RANGES, SCHEMA,
                      SCHEMA_BY_NAME)
from .lobes import check_kind

__all__ = ("PARAMETERS", "DEFAULTS", "TANGENTS", "HAZE_PARAMETERS", "HAZE_DEFAULTS", "RANGES",
           "normalise", "normalise_haze", "check_value", "sanitise", "is_anisotropic", "short_repr")

TANGENTS = K.TANGENTS

_COLOURS = tuple(p.name for p in SCHEMA if p.type == "colour")
_IDS = {p.name: tuple(t.id for t in p.terms) for p in SCHEMA if p.type == "enum"}
#: A hazy material's parameters by how normalise checks them (after kind and distribution).
_M = [p for p in SCHEMA if p.on_material]
_M_EXTENTS = tuple(p.name for p in _M if p.type == "extent")
_M_NUMBERS = tuple(p.name for p in _M if p.type == "float" and p.default is not None)
_M_OPTIONAL = tuple(p.name for p in _M if p.type == "float" and p.default is None)
_M_FLAGS = tuple(p.name for p in _M if p.type == "bool")
_M_CHOICES = tuple(p.name for p in _M if p.type == "enum" and p.name not in ("kind", "distribution"))
_WHY = {p.name: p.why for p in SCHEMA if p.why}


def _fail(msg):
    raise ValueError(msg)


def short_repr(value, limit=60):
    """repr(value), cut to ``limit`` characters (messages stay one short line)."""
    text = repr(value).replace("\n", " ")
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _numbers_in(text):
    """The numbers a string such as "0.9, 0.6, 0.3" or "5" spells, or None."""
    parts = [t for t in text.replace(",", " ").replace("(", " ").replace(")", " ").split() if t]
    try:
        return [float(t) for t in parts] if parts else None
    except ValueError:
        return None


def _refuse_string(name, text, expected, group=None):
    """Fail on a string given where ``expected`` (words) belongs, with a hint how to write the
    number, or the ``group`` = (word, size) of numbers (e.g. ("triple", 3)), the string spells."""
    nums = _numbers_in(text)
    hint = ""
    if nums and group is not None and len(nums) == group[1]:
        hint = f" (write the {group[0]} ({', '.join(f'{v:g}' for v in nums)}))"
    elif nums and len(nums) == 1:
        hint = f" (write {nums[0]:g}, a number, not a string)"
    _fail(f"{name} must be {expected}, got the string {short_repr(text)}{hint}")


def _number(name, value):
    if isinstance(value, str):
        _refuse_string(name, value, "a number")
    if isinstance(value, bool) or value is None:
        _fail(f"{name} must be a number, got {short_repr(value)}")
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        _fail(f"{name} must be a number, got {short_repr(value)}")
    if math.isnan(x):
        _fail(f"{name} is NaN")
    return x


def _in_range(name, x):
    lo, hi = RANGES[name]
    unbounded = hi is None or math.isinf(hi)  # then the message says "finite": inf is refused
    if x < lo or (hi is not None and x > hi) or (unbounded and math.isinf(x)) or \
            (name == "rotation" and math.isinf(x)):
        rng = f"[{lo:g}, {hi:g}]" if hi is not None and not math.isinf(hi) else f">= {lo:g} and finite"
        if name == "rotation":
            rng = "finite (turns)"
        _fail(f"{name} must be {'in ' if rng.startswith('[') else ''}{rng}{_WHY.get(name, '')}, "
              f"got {x:g}")
    return x


def _colour(name, value):
    if isinstance(value, str):
        _refuse_string(name, value, "a number or an RGB triple of numbers", ("tuple", 3))
    if isinstance(value, dict) or value is None:
        _fail(f"{name} must be a number or an RGB triple of numbers, got {short_repr(value)}")
    if np.ndim(value) == 0 and not isinstance(value, (list, tuple)):
        rgb = (_number(name, value),) * 3
    else:
        try:
            items = list(value)
        except TypeError:
            _fail(f"{name} must be a number or an RGB triple, got {short_repr(value)}")
        if len(items) == 4:  # RGBA from a colour socket or FloatVectorProperty: alpha ignored
            items = items[:3]
        if len(items) != 3:
            _fail(f"{name} must be a number or an RGB triple, got {len(items)} "
                  f"value{'s' if len(items) != 1 else ''} {short_repr(tuple(items))}")
        rgb = tuple(_number(name, v) for v in items)
    lo, hi = RANGES[name]
    if any(x < lo or x > hi for x in rgb):
        hint = ""
        if max(rgb) > 1.0 and all(0.0 <= x <= 255.0 for x in rgb):
            hint = " (0-255 colours: divide by 255; linear, not sRGB)"
        _fail(f"{name} must be linear RGB in [0, 1], got {tuple(rgb)}{hint}")
    return tuple(float(x) for x in rgb)


def _extent(value, name="haze_extent"):
    if isinstance(value, str):
        _refuse_string(name, value, "a number or an (x, y) pair of numbers", ("pair", 2))
    if isinstance(value, (tuple, list, np.ndarray)):
        if len(value) != 2:
            hint = f" (for one extent in both directions write {name}={short_repr(value[0])})" \
                if len(value) == 1 else ""
            _fail(f"{name} must be a number or an (x, y) pair, got {len(value)} "
                  f"value{'s' if len(value) != 1 else ''} {short_repr(tuple(value))}{hint}")
        x, y = (_in_range(name, _number(name, v)) for v in value)
        return (x, y)
    x = _in_range(name, _number(name, value))
    return (x, x)


#: Words people use for a kind, and the kind they mean.
_KIND_WORDS = {"METAL": "CONDUCTOR", "METALLIC": "CONDUCTOR", "PLASTIC": "DIELECTRIC",
               "GLASS": "DIELECTRIC", "VARNISH": "DIELECTRIC", "GLOSSY": "LEGACY"}


def _choice(name, value, options):
    if not isinstance(value, str):
        _fail(f"{name} must be one of {', '.join(options)} (a string), got {short_repr(value)}")
    v = value.upper().replace(" ", "_").replace("-", "_")
    if v in ("MULTISCATTER_GGX", "MULTI_SCATTER_GGX"):
        v = "MULTI_GGX"
    if v not in options:
        close = difflib.get_close_matches(v, options, n=1)
        if not close and name == "kind" and v in _KIND_WORDS:
            close = [_KIND_WORDS[v]]
        hint = f" (did you mean {close[0]}?)" if close else ""
        _fail(f"{name} must be one of {', '.join(options)}, got {short_repr(value)}{hint}")
    return v


def _refuse_unknown(what, unknown, valid):
    """Fail on the ``unknown`` names (of a ``what``), each with the closest ``valid`` one."""
    parts = []
    for name in unknown:
        close = difflib.get_close_matches(str(name), valid, n=1)
        parts.append(f"{name!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
    _fail(f"unknown {what}{'s' if len(unknown) > 1 else ''} {', '.join(parts)}; "
          f"valid: {', '.join(valid)}")


def normalise(params, explicit=None):
    """Fill the defaults and check one material's parameters; returns a new dict.

    ``explicit``: the names the caller set (default: all of ``params``); only those are refused
    for not applying to the kind (a base colour kept from a dielectric is not an error).
    Raises ValueError with one line naming the parameter and what is valid."""
    if not isinstance(params, dict):
        _fail(f"parameters must be a dict, got {type(params).__name__}")
    unknown = sorted(set(params) - set(PARAMETERS))
    if unknown:
        _refuse_unknown("hazy parameter", unknown, PARAMETERS)
    p = dict(DEFAULTS)
    p.update(params)
    p["kind"] = _choice("kind", p["kind"], _IDS["kind"])
    p["distribution"] = _choice("distribution", p["distribution"], _IDS["distribution"])
    check_kind(p["kind"], p["distribution"])
    for name in _COLOURS:
        p[name] = _colour(name, p[name])
    if p["kind"] != "CONDUCTOR":
        p["edge_tint"] = (0.0, 0.0, 0.0)
    explicit = set(params) if explicit is None else set(explicit)
    if p["kind"] != "DIELECTRIC" and p["base_color"] != (0.0, 0.0, 0.0) and "base_color" in explicit:
        _fail(f"base_color applies to dielectrics only; a {p['kind'].lower()} has no base layer "
              f"(its colour is core_reflectivity{' and edge_tint' if p['kind'] == 'CONDUCTOR' else ''})")
    if p["kind"] != "CONDUCTOR" and "edge_tint" in explicit and \
            _colour("edge_tint", params["edge_tint"]) != (0.0, 0.0, 0.0):
        _fail(f"edge_tint applies to conductors only; a {p['kind'].lower()} has no edge tint "
              f"(set kind='CONDUCTOR', or leave edge_tint out)")
    for name in _M_EXTENTS:
        p[name] = _extent(p[name], name)
    for name in _M_NUMBERS:
        p[name] = _in_range(name, _number(name, p[name]))
    if p["kind"] != "DIELECTRIC" and p["transmission"] != 0.0 and "transmission" in explicit:
        _fail(f"transmission applies to dielectrics only; a {p['kind'].lower()} transmits no light")
    for name in _M_OPTIONAL:
        if p[name] is not None:
            p[name] = _in_range(name, _number(name, p[name]))
    for name in _M_FLAGS:
        p[name] = _flag(name, p[name])
    for name in _M_CHOICES:
        p[name] = _choice(name, p[name], _IDS[name])
    return p


def normalise_haze(params, current=None):
    """The haze parameters of a layer: ``current`` (default HAZE_DEFAULTS) updated with
    ``params`` and checked; ValueError names the parameter (and points the core's own
    parameters to the core node)."""
    unknown = sorted(set(params) - set(HAZE_PARAMETERS))
    if unknown:
        core = [n for n in unknown if n in PARAMETERS]
        if core:
            _fail(f"{', '.join(core)} of a haze layer belong{'s' if len(core) == 1 else ''} to "
                  f"its BSDF node: edit the node itself (Hazy Gloss follows it); the layer's own "
                  f"parameters are {', '.join(HAZE_PARAMETERS)}")
        _refuse_unknown("haze parameter", unknown, HAZE_PARAMETERS)
    h = dict(HAZE_DEFAULTS if current is None else current)
    h.update(params)
    for name in HAZE_PARAMETERS:
        if name not in params and _textured(h[name]):  # (a link feeds it: kept as it is)
            continue
        h[name] = check_value(name, h[name])
    return h


def _textured(value):
    return (isinstance(value, str) and value == K.TEXTURED) or \
        (isinstance(value, tuple) and K.TEXTURED in value)


def _flag(name, value):
    if isinstance(value, (bool, np.bool_)) or (isinstance(value, (int, np.integer))
                                               and value in (0, 1)):
        return bool(value)
    _fail(f"{name} must be True or False, got {short_repr(value)}")


def check_value(name, value):
    """The normalised form of one parameter's value on its own (material or haze layer), or
    ValueError with one line naming it and what is valid.  Used for values read back from a
    stamp, where each key is checked separately (kind-dependent rules are normalise's)."""
    p = SCHEMA_BY_NAME.get(name)
    if p is None:
        _fail(f"unknown hazy parameter {name!r}")
    if p.type == "enum":
        return _choice(name, value, _IDS[name])
    if p.type == "colour":
        return _colour(name, value)
    if p.type == "extent":
        return _extent(value, name)
    if name == "coat_haze_extent":
        if isinstance(value, (tuple, list, np.ndarray)) and not isinstance(value, str):
            if len(value) != 1:
                _fail(f"coat_haze_extent must be a number (the coat's halo is isotropic), got "
                      f"{len(value)} values {short_repr(tuple(value))}")
            value = value[0]
        return _in_range(name, _number(name, value))
    if p.type == "bool":
        return _flag(name, value)
    if p.default is None and value is None:  # optional (smoothness: None selects Eq. 7)
        return None
    return _in_range(name, _number(name, value))


def is_anisotropic(p):
    """Whether one material needs anisotropic lobes (anisotropy > 0 or λ_h^x != λ_h^y)."""
    return p["anisotropy"] > 0.0 or p["haze_extent"][0] != p["haze_extent"][1]


def sanitise(values, name, clamped, *, range_name=None, above_reason=None):
    """A float32 map of parameter ``name`` with NaN -> the lower bound and out-of-range texels
    clamped; adds the counts per reason to ``clamped`` (a colour texel counts once)."""
    a = np.asarray(values, dtype=np.float32)
    lo, hi = RANGES[range_name or name]
    if name == "rotation":  # any finite number of turns; NaN and ±inf -> 0
        bad = ~np.isfinite(a)
        n = int(np.count_nonzero(bad))
        if n:
            reason = "rotation is not finite (set to 0)"
            clamped[reason] = clamped.get(reason, 0) + n
            a = np.where(bad, np.float32(0), a).astype(np.float32)
        return a
    per_texel = (lambda m: m.any(axis=-1)) if a.ndim == 3 else (lambda m: m)
    lo_v = np.float32(lo)
    hi_v = np.float32(hi if hi is not None else np.finfo(np.float32).max)
    nan = np.isnan(a)
    below = a < lo_v
    above = a > hi_v
    if not (nan.any() or below.any() or above.any()):  # the common case: no per-texel pass
        return a
    if above_reason is None:
        above_reason = f"{name} > {hi:g}" if hi is not None else f"{name} is +inf"
    for reason, mask in ((f"{name} is NaN (set to {lo:g})", nan), (f"{name} < {lo:g}", below),
                         (above_reason, above)):
        n = int(np.count_nonzero(per_texel(mask))) if mask.any() else 0
        if n:
            clamped[reason] = clamped.get(reason, 0) + n
    return np.clip(np.where(nan, lo_v, a), lo_v, hi_v).astype(np.float32)
