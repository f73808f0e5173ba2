# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's roughness and anisotropy conventions (docs/blender-versions.md; Cycles svm/closure.h),
bpy-free so the mapping code and the tests share one definition.

Roughness R -> α = R² (R clamped to [0, 1]); after anisotropy each α is clamped to <= 1.
Metallic / Principled: a = saturate(A), s = sqrt(1 - 0.9 a), α_x = R²/s, α_y = R² s  (aspect <= 10).
Glossy:               a = clamp(A, -0.99, 0.99); a >= 0: α_x = R²(1-a), α_y = R²/(1-a); a < 0 mirrored.
"""
import numpy as np

from ..constants import ALPHA_MAX

__all__ = ("alpha_from_roughness", "lobe_alphas", "lobe_from_alpha", "metallic_anisotropy",
           "glossy_anisotropy", "metallic_to_glossy_anisotropy")


def alpha_from_roughness(roughness, anisotropy=0.0):
    """(α_x, α_y) the renderer uses for a Metallic/Principled lobe with (R, A)."""
    r = np.clip(np.asarray(roughness, dtype=np.float64), 0.0, 1.0)
    a = np.clip(np.asarray(anisotropy, dtype=np.float64), 0.0, 1.0)
    s = np.sqrt(1.0 - 0.9 * a)
    alpha = r * r
    return np.minimum(alpha / s, ALPHA_MAX), np.minimum(alpha * s, ALPHA_MAX)


def lobe_alphas(roughness, anisotropy, rotation, glossy):
    """(α_x, α_y, rotation in turns in [0, 1)) of one lobe node's Roughness, Anisotropy and
    Rotation: a Glossy BSDF's convention when ``glossy``, else the Metallic / Principled one;
    the long axis along x (a quarter turn more when it was y)."""
    rough = float(np.clip(roughness, 0.0, 1.0))
    if glossy:
        a = float(np.clip(anisotropy, -0.99, 0.99))
        k = 1.0 - abs(a)
        ax, ay = (rough * rough / k, rough * rough * k) if a <= 0 else \
            (rough * rough * k, rough * rough / k)
        ax, ay = min(ax, ALPHA_MAX), min(ay, ALPHA_MAX)
    else:
        ax, ay = (float(v) for v in alpha_from_roughness(rough, anisotropy))
    if ax < ay:
        ax, ay, rotation = ay, ax, rotation + 0.25
    return ax, ay, rotation % 1.0


def lobe_from_alpha(alpha_x, alpha_y):
    """(R, ratio, swap): R = (α_x α_y)^(1/4), ratio = short/long axis in (0, 1], swap = True when
    the long axis is y (then the lobe's rotation needs +0.25 turn)."""
    ax = np.asarray(alpha_x, dtype=np.float64)
    ay = np.asarray(alpha_y, dtype=np.float64)
    rough = np.sqrt(np.sqrt(ax) * np.sqrt(ay))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(np.maximum(ax, ay) > 0, np.minimum(ax, ay) / np.maximum(ax, ay), 1.0)
    return rough, ratio, ax < ay


def metallic_anisotropy(ratio):
    """Metallic/Principled Anisotropy giving α_y/α_x = ratio (s² = 1 - 0.9 a)."""
    return np.clip((1.0 - np.asarray(ratio, dtype=np.float64)) / 0.9, 0.0, 1.0)


def glossy_anisotropy(ratio):
    """Glossy Anisotropy giving α_y/α_x = ratio with α_x >= α_y (negative branch: 1-|a| = √ratio)."""
    return -np.clip(1.0 - np.sqrt(np.asarray(ratio, dtype=np.float64)), 0.0, 0.99)


def metallic_to_glossy_anisotropy(anisotropy):
    """The Glossy Anisotropy with the same α_x, α_y as a Metallic lobe with Anisotropy A."""
    a = np.clip(np.asarray(anisotropy, dtype=np.float64), 0.0, 1.0)
    return glossy_anisotropy(1.0 - 0.9 * a)
