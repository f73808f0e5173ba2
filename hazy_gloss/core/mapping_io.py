# SPDX-License-Identifier: GPL-3.0-or-later
"""What the haze mapping (core/mapping.py) gives and takes: its results (:class:`HazeMapping`,
perceptual -> physical, and :class:`PerceptualParameters`, back), and the handling of its
inputs (working dtype, (x, y) pairs, colours, the validator that clamps and counts).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ("HazeMapping", "PerceptualParameters", "working_dtype", "xy_pair", "colour_array",
           "Validator")


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class HazeMapping:
    """Physical parameters of Eq. 1 produced by :func:`haze_mapping`.

    Arrays have the texel shape ``S`` of the broadcast inputs (``()`` for a scalar call), colours
    ``S + (3,)``.  Paper symbols in brackets.
    """

    #: [β] mixture ratio of the wide lobe, Eq. 4: β = k̂_h / r̂.  Shape S, in [0, 1].
    beta: np.ndarray
    #: [r] global reflectivity F_r(0), RGB, Eq. 5 with the core's chroma: r = r_c + (1-p) k̂_h c.
    reflectivity: np.ndarray
    #: [η] real refractive index per channel (Gulbrandsen 2014 from r and g).  > 0.
    ior: np.ndarray
    #: [κ] extinction per channel (Gulbrandsen 2014); exactly 0 where g = 0 (dielectric).
    extinction: np.ndarray
    #: [α_n^x, α_n^y] narrow (core) roughness as the renderer uses it: as given, clamped if
    #: invalid or outside ``alpha_max`` / Ashikhmin-Shirley's [1e-4, 1] (counted).
    alpha: tuple
    #: [α_w^x, α_w^y] wide roughness, Eq. 8 (limited to ``alpha_max`` if one was given).
    alpha_wide: tuple
    #: [p] peak ratio f_w(n,n)/f_n(n,n) (Table 2 as Blender implements the distribution).
    peak_ratio: np.ndarray
    #: [1 - p] computed without cancellation (p -> 1 as λ_h -> 0).
    peak_complement: np.ndarray
    #: [k̂_h] halo intensity at θ_d = 0 for the max channel (Eq. 7 or Eq. 15).
    halo_intensity: np.ndarray
    #: [r̂] max channel of r (Eq. 5 applied to r̂_c).
    reflectivity_max: np.ndarray
    #: [r_c] core reflectivity RGB actually used (after clamping bad texels).
    core_reflectivity: np.ndarray
    #: [g] edge tint RGB actually used.
    edge_tint: np.ndarray
    #: [β_h] haziness actually used.
    haziness: np.ndarray
    #: [λ_h^x, λ_h^y] haze extent actually used.
    haze_extent: tuple
    #: [k_n = (1-β) r] legacy (no Fresnel) narrow weight, RGB.
    weight_narrow: np.ndarray
    #: [k_w = β r] legacy (no Fresnel) wide weight, RGB.
    weight_wide: np.ndarray
    #: [η from r̂] scalar dielectric index of the max channel, (1+√r̂)/(1-√r̂) (paper §2.4).
    dielectric_ior: np.ndarray
    #: Lobe distribution the peak ratio was computed for.
    distribution: str
    #: Bézier weight w, or None for the piecewise-linear Eq. 7.
    smoothness: object
    #: Counts of clamped texels per reason, e.g. ``{"haziness >= 1": 12}``.
    clamped: dict = field(default_factory=dict)
    #: None, or how the peak was kept under Cycles' Multiscatter GGX
    #: (:class:`hazy_gloss.core.multiscatter.MultiscatterPeak`, set by core.lobes.describe).
    multiscatter: object = None

    @property
    def warnings(self) -> tuple:
        """Plain-language messages, one per clamp reason, with the number of texels."""
        return tuple(f"{reason}: {count} texel{'s' if count != 1 else ''} clamped"
                     for reason, count in self.clamped.items())

    @property
    def anisotropic(self) -> bool:
        ax, ay = self.alpha_wide
        return bool(np.any(ax != ay))


@dataclass(frozen=True)
class PerceptualParameters:
    """Perceptual parameters recovered by :func:`inverse_haze_mapping`."""

    core_reflectivity: np.ndarray  #: [r_c] RGB
    edge_tint: np.ndarray  #: [g] RGB
    alpha: tuple  #: [α_n^x, α_n^y]
    haziness: np.ndarray  #: [β_h]
    haze_extent: tuple  #: [λ_h^x, λ_h^y]
    #: True where the physical input is reproduced exactly by the forward mapping of the result.
    exact: np.ndarray
    #: True where, in addition, no other perceptual point maps to the same physical one (False at
    #: r_c = 1, where β_h has no effect; r = 0, where g has none; α_n = 0, where λ_h has none).
    unique: np.ndarray
    clamped: dict = field(default_factory=dict)

    @property
    def warnings(self) -> tuple:
        return tuple(f"{reason}: {count} texel{'s' if count != 1 else ''} not representable"
                     for reason, count in self.clamped.items())


# --------------------------------------------------------------------------------------------
# Input handling
# --------------------------------------------------------------------------------------------


def working_dtype(*values):
    """float32 if every floating ndarray input is float32 (or float16), else float64."""
    kinds = [np.asarray(v).dtype for v in values
             if isinstance(v, (np.ndarray, np.generic)) and np.asarray(v).dtype.kind == "f"]
    if kinds and all(np.dtype(k).itemsize <= 4 for k in kinds):
        return np.dtype(np.float32)
    return np.dtype(np.float64)


def xy_pair(value, name):
    """``alpha``/``haze_extent``: a tuple or list of two entries is (x, y), else isotropic."""
    if isinstance(value, (tuple, list)):
        if len(value) != 2:
            raise ValueError(f"{name} must be a scalar/array or an (x, y) pair, got {len(value)} items")
        return value[0], value[1]
    return value, value


def colour_array(value, dtype, name):
    arr = np.asarray(value, dtype=dtype)
    if arr.ndim == 0:
        arr = np.broadcast_to(arr, (3,))
    elif arr.shape[-1] == 1:
        arr = np.broadcast_to(arr, arr.shape[:-1] + (3,))
    elif arr.shape[-1] != 3:
        raise ValueError(f"{name} must be a scalar (grey) or shaped (..., 3), got shape {arr.shape}")
    return arr


class Validator:
    """Clamps invalid entries to the nearest valid value and counts them (texture mode), or
    raises ValueError on the first one (scalar mode)."""

    def __init__(self, strict):
        self.strict = strict
        self.clamped = {}

    def _count(self, reason, bad):
        n = int(np.count_nonzero(bad))
        if n:
            if self.strict:
                raise ValueError(f"haze_mapping: {reason}")
            self.clamped[reason] = self.clamped.get(reason, 0) + n

    def check(self, arr, name, lo, hi, *, hi_open=False, lo_open=False, texel_axis=None):
        """Return ``arr`` with NaN -> lo, below -> lo, above -> hi; inf counts as out of range.

        ``texel_axis=-1`` counts a colour texel once however many channels are bad."""
        def per_texel(mask):
            return mask.any(axis=-1) if texel_axis is not None and mask.ndim else mask

        dtype = arr.dtype
        lo_v = dtype.type(lo)
        hi_v = dtype.type(hi)
        # every entry in range (a texture's usual case): one pass, nothing to count or clamp
        inside = (arr > lo_v) if lo_open else (arr >= lo_v)
        inside &= (arr < hi_v) if hi_open else (arr <= hi_v)
        if inside.all():
            return arr
        nan = np.isnan(arr)
        self._count(f"{name} is NaN" + ("" if self.strict else f" (set to {lo:g})"), per_texel(nan))
        below = (arr <= lo_v) if lo_open else (arr < lo_v)
        below &= ~nan
        if lo_open:
            lo_v = np.nextafter(lo_v, dtype.type(np.inf))
        self._count(f"{name} {'<=' if lo_open else '<'} {lo:g}", per_texel(below))
        above = (arr >= hi_v) if hi_open else (arr > hi_v)
        if hi_open:
            hi_v = np.nextafter(hi_v, dtype.type(-np.inf))
        inf = np.isposinf(arr)
        if np.any(inf) and not np.isinf(hi_v):  # say "inf", not "> 1.8e308"
            self._count(f"{name} is +inf", per_texel(inf & (hi_v == np.finfo(dtype).max)))
        self._count(f"{name} {'>=' if hi_open else '>'} {hi:g}",
                    per_texel(above & ~(inf & (hi_v == np.finfo(dtype).max))))
        if not (nan.any() or below.any() or above.any()):
            return arr
        out = np.where(nan | below, lo_v, arr)
        return np.where(above, hi_v, out).astype(dtype, copy=False)
