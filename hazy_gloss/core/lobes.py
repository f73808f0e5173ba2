# SPDX-License-Identifier: GPL-3.0-or-later
"""Perceptual parameters -> a renderer-neutral description of the two lobes of Eq. 1.

This is the one place where the add-on's conventions meet the haze mapping: every consumer
(lean material trees, texture conversion, the recomposite, plots, exporters) calls
:func:`describe` and reads the sockets' values from its result; none recomputes them.

Conventions applied here, for scalars and whole textures alike:
- roughness is Blender's R = √α, clamped to [0, 1] and raised to the mirror cut-off of the
  distribution (constants.min_roughness); haziness is limited to constants.MAX_HAZINESS;
- (α_x, α_y) from (R, anisotropy) with the Metallic/Principled convention
  (core.conventions.alpha_from_roughness);
- the haze mapping with Cycles' limits α <= 1 and aspect <= 10 (what the renderer draws);
- under Multiscatter GGX, β and r corrected for Cycles' energy factor (core.multiscatter), so
  the peak stays invariant there too;
- the wide lobe's (R, anisotropy, rotation) in the node convention of the kind (Metallic /
  Principled, or Glossy with its opposite sign).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import constants as K
from .conventions import (alpha_from_roughness, glossy_anisotropy, lobe_from_alpha,
                          metallic_anisotropy, metallic_to_glossy_anisotropy)
from .mapping import HazeMapping, haze_mapping
from .multiscatter import correct_mapping

#: The lobe type of core.multiscatter.correct_mapping each kind draws.
_MULTISCATTER_LOBE = {"CONDUCTOR": "CONDUCTOR", "DIELECTRIC": "DIELECTRIC", "LEGACY": "LEGACY"}

__all__ = ("Lobe", "HazyLobes", "describe", "check_kind")


def check_kind(kind, distribution):
    """Raise ValueError unless ``kind``'s node offers ``distribution``."""
    if kind not in K.KINDS:
        raise ValueError(f"kind must be one of {', '.join(K.KINDS)}; got {kind!r}")
    if distribution not in K.NODE_DISTRIBUTIONS[kind]:
        raise ValueError(f"{kind.lower()} lobes offer {', '.join(K.NODE_DISTRIBUTIONS[kind])}; "
                         f"got {distribution!r}")


@dataclass(frozen=True)
class Lobe:
    """One lobe in its node's convention.  ``anisotropy`` / ``rotation`` are None for an
    isotropic material (the node's inputs are then left alone)."""

    roughness: np.ndarray  #: R (Blender's roughness)
    anisotropy: object = None  #: node convention of the kind (Glossy: <= 0)
    rotation: object = None  #: turns


@dataclass(frozen=True)
class HazyLobes:
    """Everything a renderer needs for Eq. 1: the mix weight, the two lobes and the Fresnel
    inputs of the kind.  Arrays have the texel shape of the inputs (``()`` for one material).

    fresnel:
      CONDUCTOR   ior (..., 3) η, extinction (..., 3) κ  (Metallic BSDF, PHYSICAL_CONDUCTOR)
      DIELECTRIC  ior (...) η = (1+√r̂)/(1-√r̂), specular_tint (..., 3) chroma r_c / r̂_c
      LEGACY      colour_narrow (..., 3), colour_wide (..., 3)  (Glossy colours; no halo:
                  colour_narrow = r)
    """

    kind: str
    distribution: str
    beta: np.ndarray  #: Mix Shader factor β (Eq. 4)
    narrow: Lobe
    wide: object  #: Lobe, or None when there is no halo (one lobe is Eq. 1 exactly)
    fresnel: dict
    anisotropic: bool
    mapping: HazeMapping  #: the physical parameters (β, r, η, κ, α_w, p, ...)
    notes: tuple = field(default_factory=tuple)

    @property
    def clamped(self):
        return self.mapping.clamped


def _as(x, dtype):
    return np.asarray(x, dtype=dtype)


def describe(kind="CONDUCTOR", distribution="GGX", *, core_reflectivity, edge_tint=0.0,
             roughness, anisotropy=0.0, rotation=0.0, haziness, haze_extent,
             smoothness=None, anisotropic=None, strict=None, dtype=None,
             multiscatter=None) -> HazyLobes:
    """The lobes of a hazy material from its perceptual parameters.

    Scalars describe one material; arrays (textures) describe every texel (float32 arrays run
    in float32, as the mapping does).  ``haze_extent`` is a number/array or an (x, y) pair.
    ``anisotropic``: None decides from the values (anisotropy > 0 or λ_x != λ_y anywhere).
    ``strict``: see :func:`hazy_gloss.core.haze_mapping` (None: raise for one material, clamp
    and count for textures).  The edge tint is ignored (0) unless ``kind`` is CONDUCTOR.
    ``multiscatter``: under MULTI_GGX, the lobe type and keywords of
    core.multiscatter.correct_mapping when the lobes are not the kind's own nodes (e.g.
    ``dict(lobe="F82_TINT", tint=...)`` for a Principled BSDF's metallic part)."""
    kind = str(kind).upper()
    distribution = str(distribution).upper()
    check_kind(kind, distribution)
    if isinstance(haze_extent, (tuple, list)):
        lx, ly = haze_extent
    else:
        lx = ly = haze_extent
    if dtype is None:
        arrays = [v for v in (core_reflectivity, edge_tint, roughness, anisotropy, haziness, lx, ly)
                  if isinstance(v, np.ndarray)]
        dtype = np.float32 if arrays and all(a.dtype == np.float32 for a in arrays) else np.float64
    dtype = np.dtype(dtype)
    one_texel = all(np.ndim(v) == 0 for v in (roughness, anisotropy, haziness, lx, ly, rotation)) \
        and all(np.ndim(v) <= 1 for v in (core_reflectivity, edge_tint))
    if anisotropic is None:
        anisotropic = bool(np.any(_as(anisotropy, np.float64) > 0)) or (
            lx is not ly and bool(np.any(_as(lx, np.float64) != _as(ly, np.float64))))

    rough = np.maximum(np.minimum(_as(roughness, dtype), dtype.type(1)),
                       dtype.type(K.min_roughness(distribution)))
    ax64, ay64 = alpha_from_roughness(rough, anisotropy)
    ax, ay = ax64.astype(dtype), ay64.astype(dtype)
    g = edge_tint if kind == "CONDUCTOR" else 0.0
    if one_texel:  # one material: Python floats, bad values raise (the mapping's scalar mode)
        bh = float(haziness)
        if bh > K.MAX_HAZINESS and strict is not False:
            raise ValueError(f"haziness must be in [0, {K.MAX_HAZINESS}] (1 would break energy "
                             f"conservation), got {bh:g}")
        alpha, bh, extent = (float(ax), float(ay)), min(bh, K.MAX_HAZINESS), (float(lx), float(ly))
    else:  # textures: haziness above the cap is clamped (the caller counts bad texels)
        bh = np.minimum(_as(haziness, dtype), dtype.type(K.MAX_HAZINESS))
        alpha, extent = (ax, ay), (_as(lx, dtype), _as(ly, dtype))
    m = haze_mapping(core_reflectivity, g, alpha, bh, extent, distribution=distribution,
                     smoothness=smoothness, alpha_max=K.ALPHA_MAX, max_aspect=K.MAX_ASPECT,
                     strict=strict)

    wx, wy = m.alpha_wide
    r_w, ratio, swap = lobe_from_alpha(wx, wy)
    narrow = Lobe(roughness=rough if not one_texel else float(rough))
    wide = Lobe(roughness=_out(r_w, dtype, one_texel))
    if anisotropic:
        rot = _as(rotation, dtype)
        if kind == "LEGACY":
            a_n, a_w = metallic_to_glossy_anisotropy(anisotropy), glossy_anisotropy(ratio)
        else:
            a_n, a_w = _as(anisotropy, np.float64), metallic_anisotropy(ratio)
        narrow = Lobe(narrow.roughness, _out(a_n, dtype, one_texel), _out(rot, dtype, one_texel))
        wide = Lobe(wide.roughness, _out(a_w, dtype, one_texel),
                    _out(rot + np.where(swap, dtype.type(0.25), dtype.type(0)), dtype, one_texel))

    no_halo = one_texel and (float(m.beta) <= 0.0 or (float(wx) == float(ax) and float(wy) == float(ay)))
    if distribution == "MULTI_GGX" and not no_halo:
        # Deviation from the paper: Cycles scales each lobe by an energy factor S(R, F_ss), so
        # β and r are solved for r[(1-β)S_n + β p S_w] = r_c S_n(r_c) (docs/mapping.md).
        ms = dict(multiscatter or {})
        m = correct_mapping(m, ms.pop("lobe", _MULTISCATTER_LOBE[kind]), **ms)
    if kind == "CONDUCTOR":
        fresnel = dict(ior=m.ior, extinction=m.extinction)
    elif kind == "DIELECTRIC":
        # F(0) = F0(η) · tint = r: the tint is the chroma of r (= that of r_c, except where the
        # Multiscatter correction gives each channel its own peak ratio)
        rc = np.asarray(m.core_reflectivity if m.multiscatter is None else m.reflectivity)
        rc_max = rc.max(axis=-1, keepdims=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            tint = np.where(rc_max > 0, rc / rc_max, dtype.type(1)).astype(dtype)
        fresnel = dict(ior=m.dielectric_ior, specular_tint=tint)
    elif no_halo:
        fresnel = dict(colour_narrow=m.reflectivity)
    else:
        fresnel = dict(colour_narrow=m.weight_narrow, colour_wide=m.weight_wide)
    return HazyLobes(kind=kind, distribution=distribution,
                     beta=m.beta if not one_texel else float(m.beta),
                     narrow=narrow, wide=None if no_halo else wide, fresnel=fresnel,
                     anisotropic=anisotropic, mapping=m)


def _out(x, dtype, one_texel):
    a = np.asarray(x)
    return float(a) if one_texel else a.astype(dtype, copy=False)
