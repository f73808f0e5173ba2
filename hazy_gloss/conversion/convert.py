# SPDX-License-Identifier: GPL-3.0-or-later
"""Texture batch conversion, the bpy-free part: perceptual maps -> physical maps in numpy.

The paper (§2.4) notes that the haze mapping "may be applied ... as a batch process to convert
textures storing variations of these parameters".  This module does the numeric half of that:

- :func:`resolve_inputs` checks and canonicalises the user's inputs (names, aliases, constants);
- :func:`map_textures` applies Blender's conventions exactly as ``api.map_parameters`` does
  (roughness R = √α, raised to the mirror cut-off; Metallic anisotropy; α <= 1; aspect <= 10),
  validates every texel (NaN, out of range: clamped and counted), runs
  :func:`hazy_gloss.core.lobes.describe` over whole images in float32, tile by tile to bound the
  temporaries, and returns the physical maps in the convention of the lean node tree;
- :func:`encode_png` / :func:`decode_png` give the documented 16-bit PNG encodings of the maps
  that do not fit in [0, 1] (η, κ, Glossy anisotropy, rotation);
- it also names :func:`srgb_to_linear` / :func:`linear_to_srgb` (IEC 61966-2-1, the curve
  Blender's OCIO "sRGB" uses) and :func:`resample_bilinear` of :mod:`.pixels`.

Image files are read and written through OpenImageIO (imagestream.py), datablocks through bpy
(blender/model/convert_inputs.py).  Images here are
arrays shaped (H, W) for scalar maps and (H, W, 3) for colours, in Blender's row order (row 0 is
the bottom row); nothing here depends on the order.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from .. import constants as K
from ..core.lobes import describe
from ..core.parameters import (DEFAULTS as _API_DEFAULTS, RANGES as _API_RANGES, check_value,
                               sanitise)
# The conversion's callers import this one module: it also names the errors and progress, the
# pixel helpers and the PBR texture sets, which live in modules of their own.
from .status import (ConversionCancelled, ConversionError, ConversionOptionError,
                     Progress, did_you_mean, drain, format_seconds, progress_bar)
from .pbr_sets import PBR_NAME_PARTS, detect_pbr_set, udim_sets
from .pixels import (linear_to_srgb, resample_axis, resample_block, resample_bilinear,
                     srgb_bytes_to_linear, srgb_to_linear)

__all__ = ("ConversionError", "ConversionOptionError", "InputSpec", "MapSpec", "MappedMaps",
           "PARAMETERS", "DEFAULTS", "FILE_FORMATS", "resolve_inputs", "output_specs",
           "map_textures", "encode_png", "decode_png", "srgb_to_linear", "srgb_bytes_to_linear",
           "linear_to_srgb", "resample_bilinear", "check_sizes", "group_clamped", "ConversionReport",
           "ConversionResult", "ConversionCancelled", "Progress", "drain", "sanitise_inputs",
           "is_anisotropic", "describe_maps", "did_you_mean", "format_seconds", "progress_bar",
           "resample_axis", "resample_block", "PBR_NAME_PARTS", "udim_sets", "detect_pbr_set",
           "add_counts")

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
        raise ConversionError(f"{label}: constant {value!r} is out of range: it must be "
                              f"{'in ' if rng.startswith('[') else ''}{rng}{hint}")
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
    try:  # (the range make_hazy and create_material take: one check)
        check_value("smoothness", smoothness)
    except ValueError as exc:
        raise ConversionError(str(exc)) from None
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


def add_counts(total, new):
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
    (blender/actions/convert.py) runs the same three steps (:func:`sanitise_inputs`,
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
        add_counts(clamped, c)
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
