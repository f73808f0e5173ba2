# SPDX-License-Identifier: GPL-3.0-or-later
"""OpenPBR against Cycles' Principled: the corrections a layered export applies (docs/interchange.md
§5), as plain functions of constants — α_x, α_y as Cycles renders them and their OpenPBR
inverse, and the base roughening and coat-relative IOR OpenPBR applies under a coat, undone.
(interchange/layered.py writes the same corrections as nodes for linked inputs.)
"""
from __future__ import annotations

import math

from .. import constants as K

__all__ = ("principled_alpha", "glossy_alpha", "openpbr_alpha", "openpbr_inverse",
           "coat_roughening", "coat_roughness_inverse", "coat_eta", "coat_ior_inverse")


# --------------------------------------------------------------------------------------------
# OpenPBR against Cycles' Principled: the corrections (constants; node forms in the Writer)
# --------------------------------------------------------------------------------------------


def principled_alpha(roughness, anisotropy):
    """(α_x, α_y) Cycles renders for a Principled / Metallic lobe (R, A saturated, s = √(1-0.9a),
    α_x = R²/s, α_y = R² s, each clamped to 1)."""
    r = min(max(float(roughness), 0.0), 1.0)
    a = min(max(float(anisotropy), 0.0), 1.0)
    s = math.sqrt(1.0 - 0.9 * a)
    return min(r * r / s, K.ALPHA_MAX), min(r * r * s, K.ALPHA_MAX)


def glossy_alpha(roughness, anisotropy):
    """(α_x, α_y) of a Glossy BSDF (a = clamp(A, ±0.99); a ≥ 0: α_x = R²(1-a), α_y = R²/(1-a))."""
    r = min(max(float(roughness), 0.0), 1.0) ** 2
    a = min(max(float(anisotropy), -0.99), 0.99)
    if abs(a) <= 1e-4:
        return min(r, 1.0), min(r, 1.0)
    if a < 0:
        return min(r / (1.0 + a), 1.0), min(r * (1.0 + a), 1.0)
    return min(r * (1.0 - a), 1.0), min(r / (1.0 - a), 1.0)


def openpbr_alpha(roughness, anisotropy):
    """MaterialX 1.39's open_pbr_anisotropy: α_x = r² √(2/(1+(1-a)²)), α_y = (1-a) α_x."""
    r, a = float(roughness), float(anisotropy)
    ax = r * r * math.sqrt(2.0 / (1.0 + (1.0 - a) ** 2))
    return ax, (1.0 - a) * ax


def openpbr_inverse(alpha_x, alpha_y):
    """(specular_roughness, specular_roughness_anisotropy) whose open_pbr_anisotropy is
    (α_x, α_y), α_x ≥ α_y (before any coat roughening)."""
    ax, ay = float(alpha_x), float(alpha_y)
    if ax <= 0.0:
        return 0.0, 0.0
    a = min(max(1.0 - ay / ax, 0.0), 1.0)
    return math.sqrt(ax / math.sqrt(2.0 / (1.0 + (1.0 - a) ** 2))), a


def coat_roughening(roughness, coat_roughness, coat_weight):
    """OpenPBR's base roughness under a coat (MaterialX 1.39 open_pbr_surface):
    mix(r, min(1, 2 r_c⁴ + r⁴)^¼, coat_weight)."""
    r, c, w = float(roughness), float(coat_roughness), float(coat_weight)
    return (1.0 - w) * r + w * min(1.0, 2.0 * c ** 4 + r ** 4) ** 0.25


def coat_roughness_inverse(target, coat_roughness, coat_weight):
    """(r, residual): the specular_roughness OpenPBR roughens into ``target`` under the coat
    (bisection: coat_roughening is increasing in r); residual ≠ 0 when even r = 0 is rougher."""
    w = min(max(float(coat_weight), 0.0), 1.0)
    t = float(target)
    if w == 0.0:
        return t, 0.0
    lo, hi = 0.0, max(t, 0.0)
    if coat_roughening(0.0, coat_roughness, w) >= t:
        return 0.0, coat_roughening(0.0, coat_roughness, w) - t
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if coat_roughening(mid, coat_roughness, w) < t:
            lo = mid
        else:
            hi = mid
    r = 0.5 * (lo + hi)
    return r, coat_roughening(r, coat_roughness, w) - t


def coat_eta(ior, coat_ior, coat_weight):
    """OpenPBR's base IOR under a coat: mix(η, max(η/η_c, η_c/η), coat_weight)."""
    e, c, w = float(ior), float(coat_ior), float(coat_weight)
    ratio = e / c
    return (1.0 - w) * e + w * (ratio if ratio > 1.0 else 1.0 / ratio)


def coat_ior_inverse(ior, coat_ior, coat_weight):
    """(specular_ior, residual) whose coat-relative IOR (coat_eta) is Cycles' ``ior`` (Cycles
    uses the Principled IOR for the base specular whatever the coat)."""
    e, c = float(ior), max(float(coat_ior), 1.0)
    w = min(max(float(coat_weight), 0.0), 1.0)
    if w == 0.0 or e <= 0.0:
        return e, 0.0
    x = e / ((1.0 - w) + w / c)  # the branch η_o ≥ η_c: linear
    if x >= c:
        return x, coat_eta(x, c, w) - e
    if w == 1.0:
        x = c / e
    else:  # η_o < η_c: (1-w) x² - e x + w c = 0; below its minimum 2√((1-w) w c): the minimum
        disc = e * e - 4.0 * (1.0 - w) * w * c
        x = ((e - math.sqrt(disc)) / (2.0 * (1.0 - w)) if disc >= 0.0
             else math.sqrt(w * c / (1.0 - w)))
    x = min(max(x, 1e-6), c)
    return x, coat_eta(x, c, w) - e
