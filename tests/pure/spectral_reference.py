# SPDX-License-Identifier: GPL-3.0-or-later
"""Thin-film reflectance by direct spectral integration (no bpy, no project code but the CIE data).

Written from the optics, not from Cycles or core.thin_film, so the Fourier approximations of
Cycles (Belcour & Barla 2017: the Airy series truncated after 3 path differences, the CMFs on a
coarse frequency grid, the LUT interpolated in OPD) can be measured against it.

At normal incidence, ambient index 1, a film of real index n_f and thickness d on a substrate
of complex index N = n + iκ (Heavens; e^{-iωt} convention):

    r_ij = (N_i - N_j) / (N_i + N_j),    β = 2π n_f d / λ,
    r    = (r_12 + r_23 e^{2iβ}) / (1 + r_12 r_23 e^{2iβ}),    R(λ) = |r|²,

with wavelength-independent indices (what Cycles assumes per RGB channel).  A channel c of a
working space with XYZ -> RGB matrix M has the colour matching function
cmf_c(λ) = Σ_j M_cj (x̄, ȳ, z̄)_j(λ); its reflectance is the normalised integral

    R_c = ∫ R(λ) cmf_c(λ) dλ / ∫ cmf_c(λ) dλ

(trapezoid rule on the CIE 1 nm grid, 360 - 830 nm: illuminant E, as Cycles' table).
"""
from __future__ import annotations

import numpy as np

from hazy_gloss.core.tables import cie_1931

#: config.ocio (5.x): CIE XYZ D65 -> Linear Rec.709 (the Cycles matrix is this to ~1e-6).
XYZ_TO_REC709 = np.array([[3.2409699, -1.5373832, -0.4986108],
                          [-0.9692436, 1.8759675, 0.0415551],
                          [0.0556301, -0.2039770, 1.0569715]])


def wavelengths():
    return cie_1931.START_NM + cie_1931.STEP_NM * np.arange(len(cie_1931.X_BAR), dtype=float)


def channel_cmfs(xyz_to_rgb=XYZ_TO_REC709):
    """(3, L): the RGB colour matching functions on the 1 nm grid."""
    xyz = np.array([cie_1931.X_BAR, cie_1931.Y_BAR, cie_1931.Z_BAR])
    return np.asarray(xyz_to_rgb) @ xyz


def airy_reflectance(wavelength_nm, thickness_nm, film_ior, substrate_n, substrate_k=0.0):
    """R(λ) of the film stack at normal incidence (all arguments broadcast)."""
    lam = np.asarray(wavelength_nm, float)
    nf = np.asarray(film_ior, float)
    ns = np.asarray(substrate_n, float) + 1j * np.asarray(substrate_k, float)
    r12 = (1.0 - nf) / (1.0 + nf)
    r23 = (nf - ns) / (nf + ns)
    e = np.exp(2j * (2.0 * np.pi * nf * np.asarray(thickness_nm, float) / lam))
    r = (r12 + r23 * e) / (1.0 + r12 * r23 * e)
    return np.abs(r) ** 2


def rgb_reflectance(thickness_nm, film_ior, substrate_n, substrate_k=0.0,
                    xyz_to_rgb=XYZ_TO_REC709):
    """(..., 3): R_c for scalars (...) or per-channel substrates (..., 3)."""
    lam = wavelengths()
    cmf = channel_cmfs(xyz_to_rgb)  # (3, L)
    d = np.asarray(thickness_nm, float)[..., None, None]
    nf = np.asarray(film_ior, float)[..., None, None]
    n = np.asarray(substrate_n, float)
    k = np.asarray(substrate_k, float)
    n = (n if n.ndim and n.shape[-1] == 3 else n[..., None] * np.ones(3))[..., None]
    k = (k if k.ndim and k.shape[-1] == 3 else k[..., None] * np.ones(3))[..., None]
    R = airy_reflectance(lam, d, nf, n, k)  # (..., 3, L)
    return np.trapezoid(R * cmf, lam, axis=-1) / np.trapezoid(cmf, lam, axis=-1)


def airy_series(wavelength_nm, thickness_nm, film_ior, substrate_n, substrate_k=0.0, orders=3):
    """Belcour & Barla's Eq. 10: R(λ) = C0 + 2 Σ_{m=1..orders} C_m cos(m (φ + 2β)),
    C0 = R12 + T12² R23 / (1 - R12 R23),  C_m = (T12² R23/(1 - R12 R23) - T12) √(R12 R23)^m,
    e^{iφ} = (-r12/|r12|)(r23/|r23|).  ``orders`` = ∞ (None) is the exact |r|²."""
    if orders is None:
        return airy_reflectance(wavelength_nm, thickness_nm, film_ior, substrate_n, substrate_k)
    lam = np.asarray(wavelength_nm, float)
    nf = np.asarray(film_ior, float)
    ns = np.asarray(substrate_n, float) + 1j * np.asarray(substrate_k, float)
    r12 = (1.0 - nf) / (1.0 + nf)
    r23 = (nf - ns) / (nf + ns)
    R12, R23 = r12 ** 2, np.abs(r23) ** 2
    T12 = 1.0 - R12
    rs = T12 ** 2 * R23 / (1.0 - R12 * R23)
    phi = np.angle(-r12 + 0j) + np.angle(r23)
    delta = 4.0 * np.pi * nf * np.asarray(thickness_nm, float) / lam
    out = R12 + rs
    for m in range(1, orders + 1):
        out = out + 2.0 * (rs - T12) * np.sqrt(R12 * R23) ** m * np.cos(m * (phi + delta))
    return out


def truncation_bound(film_ior, substrate_n, substrate_k=0.0, orders=3):
    """|exact - series(orders)| <= 2 |C_1/√(R12 R23)| q^{orders+1} / (1 - q), q = √(R12 R23)."""
    nf = np.asarray(film_ior, float)
    ns = np.asarray(substrate_n, float) + 1j * np.asarray(substrate_k, float)
    R12 = ((1.0 - nf) / (1.0 + nf)) ** 2
    R23 = np.abs((nf - ns) / (nf + ns)) ** 2
    T12 = 1.0 - R12
    q = np.sqrt(R12 * R23)
    return 2.0 * np.abs(T12 ** 2 * R23 / (1.0 - R12 * R23) - T12) * q ** (orders + 1) / (1.0 - q)


def rgb_series(thickness_nm, film_ior, substrate_n, substrate_k=0.0, orders=3,
               xyz_to_rgb=XYZ_TO_REC709):
    """:func:`rgb_reflectance` of :func:`airy_series` (``orders=None``: exact)."""
    lam = wavelengths()
    cmf = channel_cmfs(xyz_to_rgb)
    d = np.asarray(thickness_nm, float)[..., None, None]
    nf = np.asarray(film_ior, float)[..., None, None]
    n = np.asarray(substrate_n, float)
    k = np.asarray(substrate_k, float)
    n = (n if n.ndim and n.shape[-1] == 3 else n[..., None] * np.ones(3))[..., None]
    k = (k if k.ndim and k.shape[-1] == 3 else k[..., None] * np.ones(3))[..., None]
    R = airy_series(lam, d, nf, n, k, orders)
    return np.trapezoid(R * cmf, lam, axis=-1) / np.trapezoid(cmf, lam, axis=-1)
