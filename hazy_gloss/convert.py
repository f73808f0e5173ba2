# SPDX-License-Identifier: GPL-3.0-or-later
"""Texture batch conversion, the bpy-free part: perceptual maps -> physical maps in numpy.

The paper (§2.4) notes that the haze mapping "may be applied ... as a batch process to convert
textures storing variations of these parameters".  This module does the numeric half of that:

- :func:`resolve_inputs` checks and canonicalises the user's inputs (names, aliases, constants);
- :func:`map_textures` applies Blender's conventions exactly as ``api.map_parameters`` does
  (roughness R = √α, raised to the mirror cut-off; Metallic anisotropy; α <= 1; aspect <= 10),
  validates every texel (NaN, out of range: clamped and counted), runs
  :func:`hazy_gloss.core.haze_mapping` over whole images in float32, tile by tile to bound the
  temporaries, and returns the physical maps in the convention of the lean node tree;
- :func:`encode_png` / :func:`decode_png` give the documented 16-bit PNG encodings of the maps
  that do not fit in [0, 1] (η, κ, Glossy anisotropy, rotation);
- :func:`srgb_to_linear` / :func:`linear_to_srgb` (IEC 61966-2-1, the curve Blender's OCIO
  "sRGB" uses) and :func:`resample_bilinear`.

Reading and writing images goes through bpy (hazy_gloss/blender/convert.py).  Images here are
arrays shaped (H, W) for scalar maps and (H, W, 3) for colours, in Blender's row order (row 0 is
the bottom row); nothing here depends on the order.
"""
from __future__ import annotations

import difflib
import os
import re
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from . import constants as K
from .core.lobes import describe
from .core.parameters import DEFAULTS as _API_DEFAULTS, RANGES as _API_RANGES, sanitise

__all__ = (
    "ConversionError",
    "ConversionOptionError",
    "InputSpec",
    "MapSpec",
    "MappedMaps",
    "PARAMETERS",
    "DEFAULTS",
    "FILE_FORMATS",
    "resolve_inputs",
    "output_specs",
    "map_textures",
    "encode_png",
    "decode_png",
    "srgb_to_linear",
    "srgb_bytes_to_linear",
    "linear_to_srgb",
    "resample_bilinear",
    "check_sizes",
    "group_clamped",
    "ConversionReport",
    "ConversionResult",
    "ConversionCancelled",
    "Progress",
    "drain",
    "sanitise_inputs",
    "is_anisotropic",
    "describe_maps",
)

FILE_FORMATS = ("OPEN_EXR", "PNG")

#: Perceptual parameters a map (or a constant) can give, with their role: colour maps are
#: decoded from their colour space to linear, data maps are read raw (Non-Color).
PARAMETERS = {
    "core_reflectivity": "colour",
    "edge_tint": "colour",
    "roughness": "data",
    "anisotropy": "data",
    "rotation": "data",
    "haziness": "data",
    "haze_extent_x": "data",
    "haze_extent_y": "data",
}
#: Accepted spellings that are folded into PARAMETERS by resolve_inputs.
ALIASES = ("alpha", "haze_extent")
#: Values of the parameters the user does not give: those of one material
#: (core.parameters.DEFAULTS), grey colours as one number.
DEFAULTS = dict(core_reflectivity=_API_DEFAULTS["core_reflectivity"][0],
                edge_tint=_API_DEFAULTS["edge_tint"][0], roughness=_API_DEFAULTS["roughness"],
                anisotropy=_API_DEFAULTS["anisotropy"], rotation=_API_DEFAULTS["rotation"],
                haziness=_API_DEFAULTS["haziness"], haze_extent_x=_API_DEFAULTS["haze_extent"][0],
                haze_extent_y=_API_DEFAULTS["haze_extent"][1])


class ConversionError(ValueError):
    """Bad input to a conversion (missing file, mismatched sizes, bad kind...): the message is
    one line meant for the user (several lines given are joined with '; ')."""

    def __init__(self, message=""):
        text = str(message)
        if "\n" in text or "\r" in text:
            text = "; ".join(p.strip() for p in text.splitlines() if p.strip())
        super().__init__(text)


class ConversionOptionError(ConversionError, TypeError):
    """An unknown keyword argument of a conversion (a ConversionError and a TypeError)."""


def did_you_mean(word, choices):
    """' (did you mean 'x'?)' for the closest of ``choices``, or ''."""
    close = difflib.get_close_matches(str(word), list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------


@dataclass
class InputSpec:
    """One canonical input: ``source`` is what the user gave (a path, an image datablock, or a
    constant); ``transform`` is "sqrt" when the user gave α (alpha) rather than R."""

    name: str
    role: str
    source: object
    given_as: str
    transform: str = ""

    @property
    def is_constant(self):
        return _is_constant(self.source)


def _is_constant(value):
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return True
    if isinstance(value, (tuple, list)) and value and all(
            isinstance(v, (int, float, np.integer, np.floating)) for v in value):
        return True
    return isinstance(value, np.ndarray) and value.ndim <= 1 and value.size in (1, 3)


def _constant(label, range_key, role, value):
    """A checked float32 constant (scalar, or RGB for colours).  Raises on bad values: unlike
    texels, a constant is typed by hand."""
    try:
        arr = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise ConversionError(f"{label}: not a number: {value!r}") from None
    if role == "colour":
        if arr.size == 1:
            arr = np.repeat(arr, 3)
        if arr.size != 3:
            hint = " (drop alpha)" if arr.size == 4 else ""
            raise ConversionError(f"{label}: a colour constant is a number or an RGB triple, got "
                                  f"{value!r}{hint}")
    elif arr.size != 1:
        hint = ""
        if label == "haze_extent" and arr.size == 2:
            hint = " (for one extent per axis give haze_extent_x and haze_extent_y)"
        raise ConversionError(f"{label}: expected a number, got {value!r}{hint}")
    if not np.all(np.isfinite(arr)):
        raise ConversionError(f"{label}: constant must be finite, got {value!r}")
    lo, hi = _range(range_key)
    if np.any(arr < lo) or (hi is not None and np.any(arr > hi)):
        rng = f"[{lo:g}, {hi:g}]" if hi is not None and np.isfinite(hi) else f">= {lo:g}"
        hint = ""
        if role == "colour" and arr.min() >= 0 and arr.max() <= 255:
            scaled = tuple(round(float(v) / 255, 4) for v in arr)
            hint = f" (colours are 0-1, not 0-255: divide 8-bit values by 255, e.g. {scaled})"
        raise ConversionError(f"{label}: constant {value!r} is outside {rng}{hint}")
    out = arr.astype(np.float32)
    return out if role == "colour" else out[0]


#: Valid range of each input: one material's ranges (core.parameters.RANGES), α like R.
def _range(key):
    if key == "alpha":
        return _API_RANGES["roughness"]
    return _API_RANGES["haze_extent" if key.startswith("haze_extent") else key]


def resolve_inputs(inputs, kind="CONDUCTOR", distribution="GGX", smoothness=None,
                   file_format="OPEN_EXR"):
    """Check the conversion arguments and return (specs, notes).

    ``inputs`` maps parameter names to sources.  Accepted names: core_reflectivity, edge_tint,
    roughness (Blender's R) or alpha (α = R², converted with R = √α), anisotropy, rotation,
    haziness, haze_extent (both axes) or haze_extent_x + haze_extent_y.  Parameters not given take
    DEFAULTS.  ``specs`` has one InputSpec per canonical parameter; constants are checked here
    (a bad constant raises, a bad texel is clamped and counted later).  ``notes`` lists harmless
    oddities (an edge tint given to a non-conductor)."""
    kind = str(kind).upper()
    if kind not in K.KINDS:
        raise ConversionError(f"kind must be one of {', '.join(K.KINDS)}; got {kind!r}"
                              f"{did_you_mean(kind, K.KINDS)}")
    distribution = str(distribution).upper()
    if distribution not in K.NODE_DISTRIBUTIONS[kind]:
        raise ConversionError(f"{kind.lower()} maps support the distributions "
                              f"{', '.join(K.NODE_DISTRIBUTIONS[kind])}; got {distribution!r}"
                              f"{did_you_mean(distribution, K.NODE_DISTRIBUTIONS[kind])}")
    if str(file_format).upper() not in FILE_FORMATS:
        raise ConversionError(f"file_format must be one of {', '.join(FILE_FORMATS)}; got "
                              f"{file_format!r}{did_you_mean(str(file_format).upper(), FILE_FORMATS)}")
    if smoothness is not None:
        try:
            w = float(smoothness)
        except (TypeError, ValueError):
            raise ConversionError(f"smoothness must be None or a number > 0, got {smoothness!r}") from None
        if not w > 0:
            raise ConversionError(f"smoothness must be None or a number > 0, got {smoothness!r}")
    if not isinstance(inputs, dict):
        raise ConversionError("inputs must be a dict of parameter name -> image path, image or constant")
    allowed = set(PARAMETERS) | set(ALIASES)
    unknown = sorted((k for k in inputs if k not in allowed), key=repr)
    if unknown:
        desc = ", ".join(f"{k!r}{did_you_mean(k, allowed)}" for k in unknown)
        raise ConversionError(f"unknown input{'s' if len(unknown) > 1 else ''} {desc}; accepted: "
                              f"{', '.join(sorted(allowed))}")
    given = {k: v for k, v in inputs.items() if v is not None}
    if "alpha" in given and "roughness" in given:
        raise ConversionError("give either roughness (R) or alpha (α = R²), not both")
    if "haze_extent" in given and ({"haze_extent_x", "haze_extent_y"} & set(given)):
        raise ConversionError("give either haze_extent or haze_extent_x + haze_extent_y, not both")
    if ("haze_extent_x" in given) != ("haze_extent_y" in given):
        raise ConversionError("give both haze_extent_x and haze_extent_y (or haze_extent for both axes)")

    notes = []
    specs = {}
    for name, role in PARAMETERS.items():
        src, given_as, transform = DEFAULTS[name], "default", ""
        if name == "roughness" and "alpha" in given:
            src, given_as, transform = given["alpha"], "alpha", "sqrt"
        elif name in ("haze_extent_x", "haze_extent_y") and "haze_extent" in given:
            src, given_as = given["haze_extent"], "haze_extent"
        elif name in given:
            src, given_as = given[name], name
        if name == "edge_tint" and kind != "CONDUCTOR":
            if given_as != "default":
                notes.append(f"edge_tint is ignored for {kind.lower()} maps")
            src, given_as = 0.0, "default"
        if _is_constant(src):
            label = name if given_as == "default" else given_as
            src = _constant(label, "alpha" if transform else name, role, src)
        specs[name] = InputSpec(name=name, role=role, source=src, given_as=given_as,
                                transform=transform)
    if all(s.is_constant for s in specs.values()):
        raise ConversionError("no image input: give at least one map (for constants alone use "
                              "api.create_material)")
    return specs, notes


def check_sizes(named_sizes):
    """named_sizes: list of (label, (width, height)).  Raises ConversionError naming every image
    when they differ."""
    sizes = {tuple(s) for _, s in named_sizes}
    if len(sizes) > 1:
        desc = ", ".join(f"{label} {s[0]}x{s[1]}" for label, s in named_sizes)
        raise ConversionError(f"input images have different resolutions: {desc} "
                              "(resize them, or pass resample=True / --resample)")


# --------------------------------------------------------------------------------------------
# Colour
# --------------------------------------------------------------------------------------------


def srgb_to_linear(x):
    """IEC 61966-2-1 sRGB decoding (piecewise, 0.04045 / 12.92 / 2.4), computed in float64,
    returned as float32.  Blender's OCIO "sRGB" colour space uses this curve (measured: a 16-bit
    PNG tagged sRGB decodes to it)."""
    x = np.asarray(x, dtype=np.float64)
    out = np.where(x <= 0.04045, x / 12.92, ((np.maximum(x, 0.04045) + 0.055) / 1.055) ** 2.4)
    return out.astype(np.float32)


def srgb_bytes_to_linear(x):
    """:func:`srgb_to_linear` of the float values Blender gives for an 8-bit image (k/255 as
    float32), through a 256-entry table: identical results, float32 memory only (the general
    function's float64 temporaries would take ~8x the image for a 4K map)."""
    x = np.asarray(x, dtype=np.float32)
    k = np.arange(256, dtype=np.float32) * np.float32(1 / 255)  # Blender's byte -> float
    lut = srgb_to_linear(k)
    idx = np.rint(x * np.float32(255))
    np.clip(idx, 0, 255, out=idx)
    idx = idx.astype(np.uint8)
    if not np.array_equal(np.take(k, idx), x):
        return srgb_to_linear(x)  # not 8-bit values: the general (exact) path
    return np.take(lut, idx)


def linear_to_srgb(x):
    """Inverse of :func:`srgb_to_linear` (recovers the file values of a float image Blender
    decoded from sRGB)."""
    x = np.asarray(x, dtype=np.float64)
    out = np.where(x <= 0.0031308, x * 12.92,
                   1.055 * np.maximum(x, 0.0031308) ** (1.0 / 2.4) - 0.055)
    return out.astype(np.float32)


def resample_axis(n_out, n_in):
    """(i0, i1, f) of bilinear resampling along one axis: output texel k reads input texels i0
    and i1 with weight f of i1 (texel centres aligned, edges clamped)."""
    x = (np.arange(n_out, dtype=np.float64) + 0.5) * (n_in / n_out) - 0.5
    x = np.clip(x, 0.0, n_in - 1)
    i0 = np.floor(x).astype(np.intp)
    i1 = np.minimum(i0 + 1, n_in - 1)
    return i0, i1, (x - i0).astype(np.float32)


def resample_block(arr, y0, y1, fy, xs):
    """Rows of a bilinear resampling: ``arr`` the input rows, ``y0``/``y1``/``fy`` the rows
    (indices into ``arr``) and weights of each output row, ``xs`` = resample_axis along x."""
    x0, x1, fx = xs
    if arr.ndim == 3:
        fx = fx[:, None]
    top = arr[y0][:, x0] * (1 - fx) + arr[y0][:, x1] * fx
    bot = arr[y1][:, x0] * (1 - fx) + arr[y1][:, x1] * fx
    fy = fy[:, None, None] if arr.ndim == 3 else fy[:, None]
    return (top * (1 - fy) + bot * fy).astype(np.float32)


def resample_bilinear(arr, size):
    """Resample an (H, W[, C]) array to ``size`` = (width, height), texel centres aligned
    (the convention of image editors), edges clamped.  float32 in and out."""
    w, h = int(size[0]), int(size[1])
    arr = np.asarray(arr, dtype=np.float32)
    h0, w0 = arr.shape[:2]
    if (h0, w0) == (h, w):
        return arr
    y0, y1, fy = resample_axis(h, h0)
    return resample_block(arr, y0, y1, fy, resample_axis(w, w0))


# --------------------------------------------------------------------------------------------
# Outputs
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MapSpec:
    """One physical output map.  ``png``: how 16-bit PNG stores it (values must be in [0, 1]):
    "identity", "ratio" (x/(1+x) for unbounded x >= 0, decoded e/(1-e)), "negate" (Glossy
    anisotropy in [-0.99, 0] stored as -a) or "wrap" (rotation in turns, stored modulo 1)."""

    name: str
    channels: int
    png: str
    doc: str


_COMMON = (
    MapSpec("beta", 1, "identity", "β, mix factor of the wide lobe (Eq. 4)"),
    MapSpec("roughness", 1, "identity", "narrow lobe roughness R (clamped to [mirror cut-off, 1])"),
    MapSpec("roughness_wide", 1, "identity", "wide lobe roughness R_w = (α_w^x α_w^y)^¼"),
)
_ANISO = {
    "node": (
        MapSpec("anisotropy", 1, "identity", "narrow lobe anisotropy (node convention)"),
        MapSpec("rotation", 1, "wrap", "narrow lobe rotation (turns)"),
        MapSpec("anisotropy_wide", 1, "identity", "wide lobe anisotropy (node convention)"),
        MapSpec("rotation_wide", 1, "wrap", "wide lobe rotation: rotation + ¼ where α_w^y > α_w^x"),
    ),
    "glossy": (
        MapSpec("anisotropy", 1, "negate", "narrow lobe anisotropy (Glossy convention, <= 0)"),
        MapSpec("rotation", 1, "wrap", "narrow lobe rotation (turns)"),
        MapSpec("anisotropy_wide", 1, "negate", "wide lobe anisotropy (Glossy convention, <= 0)"),
        MapSpec("rotation_wide", 1, "wrap", "wide lobe rotation: rotation + ¼ where α_w^y > α_w^x"),
    ),
}
#: Map name -> HazyLobes.fresnel key, where they differ.
_FRESNEL_KEY = {"weight_narrow": "colour_narrow", "weight_wide": "colour_wide"}
_FRESNEL = {
    "CONDUCTOR": (
        MapSpec("ior", 3, "ratio", "η per channel (Gulbrandsen from r and g)"),
        MapSpec("extinction", 3, "ratio", "κ per channel (Gulbrandsen from r and g)"),
    ),
    "DIELECTRIC": (
        MapSpec("ior", 1, "ratio", "η = (1+√r̂)/(1-√r̂)"),
        MapSpec("specular_tint", 3, "identity", "chroma c = r_c / r̂_c (Principled Specular Tint)"),
    ),
    "LEGACY": (
        MapSpec("weight_narrow", 3, "identity", "k_n = (1-β) r, Glossy colour of the narrow lobe"),
        MapSpec("weight_wide", 3, "identity", "k_w = β r, Glossy colour of the wide lobe"),
    ),
}


def output_specs(kind, anisotropic):
    """The maps a conversion writes, in writing order."""
    specs = list(_COMMON)
    if anisotropic:
        specs += _ANISO["glossy" if kind == "LEGACY" else "node"]
    specs += _FRESNEL[kind]
    return specs


def encode_png(spec, values):
    """Values of ``spec`` -> [0, 1] for a 16-bit PNG (see MapSpec.png)."""
    v = np.asarray(values, dtype=np.float32)
    if spec.png == "ratio":
        v = v / (np.float32(1) + v)
    elif spec.png == "negate":
        v = -v
    elif spec.png == "wrap":
        v = np.mod(v, np.float32(1))
        v = np.where(v >= 1, np.float32(0), v)
    return np.clip(v, 0, 1).astype(np.float32)


def decode_png(spec, encoded):
    """Inverse of :func:`encode_png` (what the node tree computes after the Image Texture)."""
    e = np.asarray(encoded, dtype=np.float32)
    if spec.png == "ratio":
        return (e / (np.float32(1) - e)).astype(np.float32)
    if spec.png == "negate":
        return -e
    return e


# --------------------------------------------------------------------------------------------
# Mapping whole images
# --------------------------------------------------------------------------------------------


@dataclass
class MappedMaps:
    """Result of :func:`map_textures`."""

    maps: dict  # name -> float32 (H, W) or (H, W, 3)
    specs: list  # MapSpec in writing order
    anisotropic: bool
    texels: int
    clamped: dict = field(default_factory=dict)  # reason -> texel count


def _add_counts(total, new):
    for k, v in new.items():
        total[k] = total.get(k, 0) + int(v)


def sanitise_inputs(arrays, clamped, *, alpha_given=False):
    """Every input of ``arrays`` (canonical name -> array or constant) checked per texel: NaN
    and out-of-range texels clamped and counted in ``clamped`` (a haze extent shared by both
    axes, the same array object, counts once).  Returns the clean dict (R = sqrt(alpha) when
    ``alpha_given``).  Per texel only: a strip gives the rows of the whole image's result."""
    clean = {}
    seen = {}
    for name in PARAMETERS:
        a = arrays[name]
        if np.ndim(a) < 2:
            clean[name] = np.asarray(a, dtype=np.float32)
            continue
        if id(a) in seen:
            clean[name] = clean[seen[id(a)]]
            continue
        seen[id(a)] = name
        if name == "roughness" and alpha_given:
            clean[name] = sanitise(a, "alpha", clamped, range_name="roughness")
        elif name == "haziness":
            clean[name] = sanitise(a, name, clamped, above_reason=f"haziness > {K.MAX_HAZINESS}")
        else:
            clean[name] = sanitise(a, name, clamped,
                                   range_name="haze_extent" if name.startswith("haze_extent") else None)
    if alpha_given:  # R = sqrt(alpha)
        clean["roughness"] = np.sqrt(clean["roughness"]).astype(np.float32)
    return clean


def is_anisotropic(clean):
    """Whether clean inputs need the anisotropic map set: some anisotropy > 0, or λ_x != λ_y."""
    aniso_in = clean["anisotropy"]
    lx_in, ly_in = clean["haze_extent_x"], clean["haze_extent_y"]
    return bool(np.any(aniso_in > 0)) or (lx_in is not ly_in and bool(np.any(lx_in != ly_in)))


def describe_maps(clean, *, kind, distribution, smoothness, anisotropic, shape):
    """The physical maps of clean inputs (whole images, strips or tiles of them; ``shape`` =
    (rows, W)): ({map name: float32 (rows, W) or (rows, W, 3)}, clamp counts of the renderer
    limits).  Every operation is per texel (core.lobes.describe in float32)."""
    lx = clean["haze_extent_x"]
    ly = lx if clean["haze_extent_y"] is clean["haze_extent_x"] else clean["haze_extent_y"]
    d = describe(kind, distribution, core_reflectivity=clean["core_reflectivity"],
                 edge_tint=clean["edge_tint"], roughness=clean["roughness"],
                 anisotropy=clean["anisotropy"], rotation=clean["rotation"],
                 haziness=clean["haziness"], haze_extent=(lx, ly), smoothness=smoothness,
                 anisotropic=anisotropic, strict=False, dtype=np.float32)
    shape = tuple(shape)
    out = {"beta": d.beta, "roughness": d.narrow.roughness, "roughness_wide": d.wide.roughness}
    if anisotropic:
        out.update(anisotropy=d.narrow.anisotropy, rotation=d.narrow.rotation,
                   anisotropy_wide=d.wide.anisotropy, rotation_wide=d.wide.rotation)
    for spec in _FRESNEL[kind]:
        out[spec.name] = d.fresnel[spec.name if spec.name in d.fresnel else _FRESNEL_KEY[spec.name]]
    for spec in output_specs(kind, anisotropic):
        want = shape + ((3,) if spec.channels == 3 else ())
        out[spec.name] = np.broadcast_to(np.asarray(out[spec.name], np.float32), want)
    return out, d.clamped


def map_textures(arrays, *, kind="CONDUCTOR", distribution="GGX", smoothness=None,
                 tile_texels=K.STRIP_TEXELS, alpha_given=False, anisotropic=None, threads=None):
    """Perceptual maps -> physical maps for the lean node tree, whole images in memory.

    ``arrays``: canonical name (PARAMETERS) -> float32 array (H, W) / (H, W, 3) or a checked
    constant (from resolve_inputs).  ``alpha_given``: the roughness entry holds α (R = √α).
    Every texel goes through :func:`hazy_gloss.core.lobes.describe` in float32, as one material
    does.  Bad texels are clamped and counted in ``clamped`` (reason -> texels).
    Tiles of ``tile_texels`` texels run on ``threads`` threads (default: one per CPU, at most 8);
    the result does not depend on either (every operation is per texel).
    ``anisotropic``: None decides from the data (any anisotropy > 0 or λ_x != λ_y); True forces
    the anisotropic map set (UDIM tiles of one set must agree).  The conversion of files
    (blender/convert.py) runs the same three steps (:func:`sanitise_inputs`,
    :func:`is_anisotropic`, :func:`describe_maps`) on strips instead.
    """
    kind = str(kind).upper()
    distribution = str(distribution).upper()
    shapes = {n: np.shape(a)[:2] for n, a in arrays.items() if np.ndim(a) >= 2}
    if not shapes:
        raise ConversionError("no image input")
    hw = set(shapes.values())
    if len(hw) != 1:
        raise ConversionError("input arrays have different shapes: " +
                              ", ".join(f"{n} {s}" for n, s in shapes.items()))
    (h, w), = hw
    clamped = {}
    clean = sanitise_inputs(arrays, clamped, alpha_given=alpha_given)
    anisotropic = bool(anisotropic) or is_anisotropic(clean)
    specs = output_specs(kind, anisotropic)
    maps = {s.name: np.empty((h, w, 3) if s.channels == 3 else (h, w), np.float32) for s in specs}

    rows = max(1, int(tile_texels) // max(w, 1))

    def run_tile(r0):
        """Map rows r0 .. r0 + rows into the preallocated outputs; returns its clamp counts."""
        r1 = min(h, r0 + rows)
        tile = {n: (a[r0:r1] if a.ndim >= 2 else a) for n, a in clean.items()}
        if clean["haze_extent_y"] is clean["haze_extent_x"]:
            tile["haze_extent_y"] = tile["haze_extent_x"]
        out, counts = describe_maps(tile, kind=kind, distribution=distribution,
                                    smoothness=smoothness, anisotropic=anisotropic,
                                    shape=(r1 - r0, w))
        for name, values in out.items():
            maps[name][r0:r1] = values
        return counts

    starts = list(range(0, h, rows))
    workers = max(1, min(int(threads or os.cpu_count() or 1), len(starts), 8))
    if workers == 1:
        counts = [run_tile(r0) for r0 in starts]
    else:  # numpy releases the GIL in its loops; tiles write disjoint rows
        with ThreadPoolExecutor(max_workers=workers) as pool:
            counts = list(pool.map(run_tile, starts))
    for c in counts:  # in tile order: the report does not depend on the thread schedule
        _add_counts(clamped, c)
    return MappedMaps(maps=maps, specs=specs, anisotropic=anisotropic, texels=h * w,
                      clamped=clamped)


def group_clamped(clamped):
    """reason -> count  =>  parameter -> count (texels counted once per reason)."""
    out = {}
    for reason, n in clamped.items():
        param = reason.split()[0].split(".")[0]
        out[param] = out.get(param, 0) + int(n)
    return out


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------


@dataclass
class ConversionReport:
    """What a conversion did.  ``clamped``: reason -> texels (summed over UDIM tiles);
    ``clamped_by_parameter``: the same grouped by parameter."""

    kind: str
    distribution: str
    file_format: str
    size: tuple = (0, 0)
    tiles: list = field(default_factory=list)
    texels: int = 0
    anisotropic: bool = False
    clamped: dict = field(default_factory=dict)
    seconds: float = 0.0
    warnings: list = field(default_factory=list)

    @property
    def clamped_by_parameter(self):
        return group_clamped(self.clamped)

    def summary(self, n_maps=None):
        maps = f"{n_maps} maps, " if n_maps is not None else ""
        tiles = f" in {len(self.tiles)} UDIM tiles" if self.tiles else ""
        clamp = ", ".join(f"{k} {v}" for k, v in self.clamped_by_parameter.items()) or "none"
        return (f"{self.kind.lower()} {self.size[0]}x{self.size[1]}{tiles}: {self.texels} texels, "
                f"{maps}{self.seconds:.2f} s; clamped texels: {clamp}")


class ConversionResult(dict):
    """``{map name: written path}`` (UDIM sets use the ``<UDIM>`` token), with ``.report``
    (a ConversionReport) and ``.specs`` (MapSpec by name)."""

    def __init__(self, paths, report, specs):
        super().__init__(paths)
        self.report = report
        self.specs = {s.name: s for s in specs}


# --------------------------------------------------------------------------------------------
# Progress and cancel
# --------------------------------------------------------------------------------------------


class ConversionCancelled(ConversionError):
    """The conversion was cancelled (Esc in the operator, :meth:`Progress.cancel`); like any
    failure, nothing of it is left in the output folder."""


class Progress:
    """How far a conversion is, and its cancel flag.

    The conversion calls :meth:`begin` with its total work (rows of every tile of every set)
    and :meth:`advance` after each strip; :meth:`advance` raises :class:`ConversionCancelled`
    once :meth:`cancel` was called (between two strips: the run is then undone like a failed
    one).  ``callback(done, total, message)`` is called on every step (the API's
    ``progress=``).  :meth:`status` is the one line the operator and the CLI show: what is
    being done (map or step, UDIM tile, set), percent and time left."""

    def __init__(self, callback=None, clock=None):
        self.callback = callback
        self.clock = clock or time.monotonic
        self.total = 0
        self.done = 0
        self.message = ""
        self.levels = []
        self.cancelled = False
        self.started = self.clock()

    def cancel(self):
        """Ask the running conversion to stop at its next strip (and undo itself)."""
        self.cancelled = True

    def check(self):
        if self.cancelled:
            raise ConversionCancelled("cancelled; the output folder is unchanged")

    def begin(self, total):
        self.total += max(0, int(total))

    def next_item(self, index, count, name, key="set"):
        """Item ``index`` of ``count`` starts: a set of a library batch (``key`` "set") or a
        UDIM tile of a set ("tile"); the fraction is then (items done + this item's fraction)
        / count at each level, and the rows of the item start from 0."""
        keep = [lv for lv in self.levels if lv[0] == "set"] if key != "set" else []
        self.levels = keep + [(key, int(index), max(1, int(count)), str(name))]
        self.total = self.done = 0

    def advance(self, units=0, message=None):
        self.done = min(self.total, self.done + max(0, int(units)))
        if message is not None:
            self.message = message
        if self.callback is not None:
            self.callback(self.done, max(self.total, 1), self.message)
        self.check()

    levels = ()

    @property
    def fraction(self):
        f = self.done / self.total if self.total else 0.0
        for _, i, n, _ in reversed(self.levels):
            f = (i + f) / n
        return min(1.0, f)

    def seconds_left(self):
        """Time left, extrapolated from the rate so far (None before the first strip)."""
        f = self.fraction
        if f <= 0:
            return None
        spent = self.clock() - self.started
        return spent * (1 - f) / f

    def status(self):
        left = self.seconds_left()
        eta = "" if left is None else f", {format_seconds(left)} left"
        parts = [f"{key} {name} ({i + 1} of {n})" for key, i, n, name in self.levels]
        where = f"{', '.join(parts)}: " if parts else ""
        return f"{where}{self.message} {100 * self.fraction:.0f}%{eta}".strip()


def format_seconds(s):
    """'12 s', '3 min 05 s', '2 h 04 min'."""
    s = max(0, int(round(s)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def progress_bar(progress, width=30):
    """A text progress bar of a :class:`Progress` (the CLI's): '[#####-----]  50% ...'."""
    n = int(round(width * progress.fraction))
    return f"[{'#' * n}{'-' * (width - n)}] {progress.status()}"


def drain(steps):
    """Run a conversion generator to its end; returns its result (what the blocking API does,
    where the modal operator steps the same generator between events)."""
    while True:
        try:
            next(steps)
        except StopIteration as stop:
            return stop.value


# --------------------------------------------------------------------------------------------
# PBR texture sets: which file is which map
# --------------------------------------------------------------------------------------------

#: Name parts texture libraries use for each map of a PBR set (lower case, matched as whole
#: words between separators: "crate_BaseColor_2k.png", "Wood049_4K-PNG_Roughness.png").
PBR_NAME_PARTS = {
    "base_color": ("basecolor", "base_color", "albedo", "diffuse", "diff", "color", "col"),
    "metallic": ("metallic", "metalness", "metal"),
    "roughness": ("roughness", "rough"),
    "normal": ("normal", "normalgl", "nor_gl", "norm", "nrm", "nor"),
    "coat": ("coat", "clearcoat"),
    "alpha": ("opacity", "alpha", "mask"),
    "haziness": ("haziness", "haze"),
}
_PBR_IMAGE_EXT = (".png", ".jpg", ".jpeg", ".exr", ".tif", ".tiff", ".tga", ".bmp", ".webp", ".hdr")


_UDIM_FILE = None


def udim_sets(filenames):
    """File names with the tiles of a UDIM set (``name.1001.png``, ``name_1002.png``: a 4-digit
    tile 1001-2000 before the extension) folded into one ``name.<UDIM>.png``; others as they
    are."""
    global _UDIM_FILE
    if _UDIM_FILE is None:
        _UDIM_FILE = re.compile(r"\A(?P<head>.*[._])(?P<tile>\d{4})(?P<ext>\.[^.]+)\Z")
    out = []
    for fn in filenames:
        m = _UDIM_FILE.match(os.path.basename(fn))
        if m and 1001 <= int(m["tile"]) <= 2000:
            fn = os.path.join(os.path.dirname(fn), f"{m['head']}<UDIM>{m['ext']}")
        if fn not in out:
            out.append(fn)
    return out


def detect_pbr_set(filenames):
    """{map name: file name} for the files of one PBR set, by the name parts texture libraries
    use (PBR_NAME_PARTS; UDIM tiles are one ``<UDIM>`` name, :func:`udim_sets`); a DirectX normal map ("NormalDX") is skipped for the OpenGL one, and
    refused when it is the only normal map (Blender's Normal Map node reads OpenGL normals).
    Raises ConversionError when two files claim one map or none is found."""
    found, clash, directx = {}, {}, []
    named = {}
    for fn in sorted(udim_sets(filenames)):
        stem, ext = os.path.splitext(os.path.basename(fn))
        if ext.lower() in _PBR_IMAGE_EXT:
            named[fn] = [w for w in re.split(r"[^a-z0-9]+", re.sub(
                r"([a-z])([A-Z])", r"\1_\2", stem).lower()) if w]
    # the set's name is the words every file starts with; the resolution ("2k") the words
    # every file ends with, unless they name a map
    lists = list(named.values())
    pre = 0
    while len(lists) > 1 and all(len(w) > pre for w in lists) and \
            len({w[pre] for w in lists}) == 1:
        pre += 1
    post = 0
    map_words = {p for parts in PBR_NAME_PARTS.values() for p in parts}
    while len(lists) > 1 and all(len(w) > pre + post for w in lists) and \
            len({w[-1 - post] for w in lists}) == 1 and lists[0][-1 - post] not in map_words:
        post += 1
    def which(words):
        joined = {a + b for a, b in zip(words, words[1:])} | {a + "_" + b for a, b in zip(words, words[1:])}
        return next((name for name, parts in PBR_NAME_PARTS.items()
                     if any(p in words or p in joined for p in parts)), None)

    for fn, all_words in named.items():
        words = all_words[pre:len(all_words) - post] or all_words
        if "dx" in all_words and ({"normal", "nor", "nrm"} & set(all_words)):
            directx.append(fn)  # green down: Blender's Normal Map node reads OpenGL normals
            continue
        name = which(words)
        if name is None:
            continue
        if name in found and found[name] != fn:
            clash.setdefault(name, [found[name]]).append(fn)
        found.setdefault(name, fn)
    if clash:
        raise ConversionError("more than one file for " + "; ".join(
            f"{k}: {', '.join(v)}" for k, v in clash.items()) + " (pass the maps by name)")
    if directx and "normal" not in found:
        raise ConversionError(f"{directx[0]}: a DirectX normal map (green down); Blender's "
                              f"Normal Map node reads OpenGL normals: use the set's OpenGL "
                              f"normal map")
    if not found:
        raise ConversionError("no map of a PBR set found (names with basecolor, metallic, "
                              "roughness, normal, ...)")
    return found
