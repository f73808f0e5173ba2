# SPDX-License-Identifier: GPL-3.0-or-later
"""Cycles' Principled BSDF thin-film reflectance at normal incidence, and its inverse (no bpy).

With Thin Film Thickness > 0.1 nm the normal-incidence reflectance of Principled's specular
lobes is the film's interference result, per RGB channel, not F0 (docs/thin-film.md):

- metallic lobe (F82-tint, 5.0+): F0 = Base Color, F82 tint = Specular Tint are turned into a
  complex IOR n + ik (Gulbrandsen's r, g) and the film sits on that conductor;
  :func:`metal_reflectance`.  Blender 4.5 has no thin film on metals: R = Base Color.
- dielectric lobe (generalized Schlick): IOR adjusted by Specular IOR Level, the film on that
  dielectric, then Cycles' per-channel "F0 scaling" by Specular Tint;
  :func:`dielectric_reflectance`.

Reproduced from the kernel sources shipped in the bpy wheels (kernel/closure/bsdf_util.h
``fresnel_iridescence_channel``, ``iridescence_airy_summation_channel``,
``fresnel_conductor_polarized``; kernel/closure/bsdf_microfacet.h ``microfacet_fresnel``,
``generalized_schlick_fresnel``; kernel/svm/closure.h, Principled) and the host code that
builds the sensitivity table (scene/shader.cpp ``compute_thin_film_table``, from
``table_thin_film_cmf`` of doc/precompute/thin_film_table.py).  Versions:

- 5.0 - 5.3 ("LUT"): the Fourier-space sensitivity LUT of the scene's working colour space,
  built here from the CIE 1931 CMFs (:mod:`cie_1931`) exactly as Cycles does; film IOR blended
  towards 1 below 1 nm.
- 4.5 ("GAUSS"): Belcour & Barla's Gaussian fit of the XYZ sensitivities, converted to RGB with
  the white point; blended below 30 nm; dielectric only.

Arithmetic is float64 (Cycles runs float32).  Inputs are clipped to finite ranges where Cycles
would produce inf/NaN (:data:`LIMITS`); outputs are always finite.  Every function broadcasts:
colours are (..., 3) (a scalar means grey), scalars are (...); results are (..., 3).
"""
from __future__ import annotations

import functools

import numpy as np

from .tables import cie_1931
from .multiscatter import cycles_version

__all__ = ("THICKNESS_CUTOFF", "WORKING_SPACES", "LIMITS", "generation", "xyz_to_rgb_matrix",
           "sensitivity_table", "cmf_fourier_table", "metal_reflectance",
           "dielectric_reflectance", "film_active", "metal_base_for_reflectance",
           "dielectric_ior_for_reflectance", "dielectric_tint_for_reflectance")

#: kernel/svm/types.h THINFILM_THICKNESS_CUTOFF (nm): thinner films are off.
THICKNESS_CUTOFF = 0.1
#: kernel/types.h THIN_FILM_TABLE_SIZE
TABLE_SIZE = 512
#: Working colour spaces Blender offers (bpy.data.colorspace.working_space, 5.0+).
WORKING_SPACES = ("Linear Rec.709", "Linear Rec.2020", "ACEScg")
#: Clips applied to the inputs (Cycles' own clamps, widened to finite bounds).
LIMITS = dict(thickness=(-1e9, 1e7), film_ior=(1e-5, 1e4), ior=(1e-5, 1e4),
              specular_ior_level=(0.0, 1e4), specular_tint=(0.0, 1e4), base_color=(0.0, 1.0))


def generation(version=None):
    """Cycles generation: "LUT" (5.0+: sensitivity LUT, thin film on metals) or "GAUSS" (4.5)."""
    return "LUT" if cycles_version(version) >= (5, 0) else "GAUSS"


# --------------------------------------------------------------------------------------------
# Colour space: Cycles' xyz_to_rgb (scene/shader.cpp init_xyz_transforms; 5.x
# util/colorspace.cpp get_xyz_to_scene_linear_rgb) with Blender's OCIO config
# --------------------------------------------------------------------------------------------

#: Cycles' hard-coded "UTILITY - ACES-AP0_to_CIE-XYZ-D65_BFD" (shader.cpp / colorspace.cpp).
_AP0_TO_XYZ_CYCLES = np.array([[0.938280, -0.004451, 0.016628],
                               [0.337369, 0.729522, -0.066890],
                               [0.001174, -0.003711, 1.091595]])
#: datafiles/colormanagement/config.ocio: XYZ D65 -> Linear Rec.709 (4.5 / 5.x configs) and
#: -> Linear Rec.2020 (5.x).
_XYZ_TO_REC709_CONFIG = {
    "GAUSS": np.array([[3.2404373564920070, -1.5371305409000549, -0.4985288240756933],
                       [-0.9692674982687597, 1.8760136862977035, 0.0415560804587997],
                       [0.0556434463874256, -0.2040259700872272, 1.0572254813610864]]),
    "LUT": np.array([[3.2409699, -1.5373832, -0.4986108],
                     [-0.9692436, 1.8759675, 0.0415551],
                     [0.0556301, -0.2039770, 1.0569715]]),
}
_XYZ_TO_REC2020_CONFIG = np.array([[1.7166512, -0.3556708, -0.2533663],
                                   [-0.6666844, 1.6164812, 0.0157685],
                                   [0.0176399, -0.0427706, 0.9421031]])
# OpenColorIO transforms/builtins/ColorMatrixHelpers.cpp: primaries (x, y) of R, G, B, white.
_AP0 = ((0.7347, 0.2653), (0.0, 1.0), (0.0001, -0.0770), (0.32168, 0.33767))
_AP1 = ((0.713, 0.293), (0.165, 0.830), (0.128, 0.044), (0.32168, 0.33767))
_D65_XYZ = np.array([0.95045592705167, 1.0, 1.08905775075988])
_BRADFORD = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367],
                      [0.0389, -0.0685, 1.0296]])


def _rgb_to_xyz(prims):
    """ColorMatrixHelpers.cpp rgb2xyz_from_xy."""
    m = np.array([[x for x, _ in prims[:3]], [y for _, y in prims[:3]],
                  [1.0 - x - y for x, y in prims[:3]]])
    wx, wy = prims[3]
    gains = np.linalg.solve(m, np.array([wx / wy, 1.0, (1.0 - wx - wy) / wy]))
    return m * gains


def _ap0_to_xyz_d65():
    """OCIO builtin "UTILITY - ACES-AP0_to_CIE-XYZ-D65_BFD" (ACES.cpp:
    build_conversion_matrix_to_XYZ_D65(ACES_AP0, ADAPTATION_BRADFORD))."""
    m = _rgb_to_xyz(_AP0)
    src = m @ np.ones(3)
    scale = (_BRADFORD @ _D65_XYZ) / (_BRADFORD @ src)
    return np.linalg.inv(_BRADFORD) @ np.diag(scale) @ _BRADFORD @ m


@functools.lru_cache(maxsize=None)
def _xyz_to_rgb(working_space, gen):
    if working_space not in WORKING_SPACES:
        raise ValueError(f"working_space must be one of {WORKING_SPACES}, not {working_space!r}")
    if gen == "GAUSS" and working_space != "Linear Rec.709":
        raise ValueError("Blender 4.5 has no working space setting (Linear Rec.709 only)")
    b = _ap0_to_xyz_d65()
    if working_space == "Linear Rec.709":
        aces_to_rgb = _XYZ_TO_REC709_CONFIG[gen] @ b
    elif working_space == "Linear Rec.2020":
        aces_to_rgb = _XYZ_TO_REC2020_CONFIG @ b
    else:  # ACEScg: builtin ACEScg_to_ACES2065-1, inverted
        aces_to_rgb = np.linalg.inv(_rgb_to_xyz(_AP1)) @ _rgb_to_xyz(_AP0)
    m = aces_to_rgb @ np.linalg.inv(_AP0_TO_XYZ_CYCLES)
    m.setflags(write=False)
    return m


def xyz_to_rgb_matrix(working_space="Linear Rec.709", version=None):
    """Cycles' XYZ (D65) -> scene-linear RGB matrix for Blender's config: aces_to_rgb (from the
    OCIO config) times the inverse of Cycles' 6-digit AP0 -> XYZ matrix."""
    return _xyz_to_rgb(working_space, generation(version)).copy()


# --------------------------------------------------------------------------------------------
# The 5.x sensitivity LUT (doc/precompute/thin_film_table.py, scene/shader.cpp)
# --------------------------------------------------------------------------------------------

def _not_a_knot_spline(x, y):
    """scipy.interpolate.CubicSpline(x, y, extrapolate=False) (default not-a-knot ends), in
    numpy: solves for the second derivatives; NaN outside [x0, xn]."""
    n = len(x) - 1
    h = np.diff(x)
    a = np.zeros((n + 1, n + 1))
    rhs = np.zeros((n + 1,) + y.shape[1:])
    i = np.arange(1, n)
    a[i, i - 1], a[i, i], a[i, i + 1] = h[:-1], 2.0 * (h[:-1] + h[1:]), h[1:]
    rhs[1:n] = 6.0 * (np.diff(y, axis=0)[1:] / h[1:, None] - np.diff(y, axis=0)[:-1] / h[:-1, None])
    a[0, :3] = -1.0 / h[0], 1.0 / h[0] + 1.0 / h[1], -1.0 / h[1]  # S''' continuous at x1
    a[n, n - 2:] = -1.0 / h[n - 2], 1.0 / h[n - 2] + 1.0 / h[n - 1], -1.0 / h[n - 1]
    m = np.linalg.solve(a, rhs)

    def f(t):
        t = np.asarray(t, np.float64)
        inside = (t >= x[0]) & (t <= x[-1])
        tc = np.where(inside, t, x[0])
        k = np.clip(np.searchsorted(x, tc, side="right") - 1, 0, n - 1)
        hk, lo, hi = h[k][:, None], (x[k + 1] - tc)[:, None], (tc - x[k])[:, None]
        s = ((m[k] * lo ** 3 + m[k + 1] * hi ** 3) / (6.0 * hk)
             + (y[k] / hk - m[k] * hk / 6.0) * lo + (y[k + 1] / hk - m[k + 1] * hk / 6.0) * hi)
        return np.where(inside[:, None], s, np.nan)
    return f


@functools.lru_cache(maxsize=1)
def _cmf_fourier():
    cmf = np.stack([cie_1931.X_BAR, cie_1931.Y_BAR, cie_1931.Z_BAR], axis=1)
    wl = cie_1931.START_NM + cie_1931.STEP_NM * np.arange(len(cmf), dtype=np.float64)
    wl = np.concatenate([[wl[0] - 1.0], wl, [wl[-1] + 1.0]])  # Cycles pads 359 and 831 nm with 0
    cmf = np.concatenate([np.zeros((1, 3)), cmf, np.zeros((1, 3))])
    spline = _not_a_knot_spline(wl, cmf)
    n_real, end_freq = 2 * TABLE_SIZE - 2, 60.0  # 1022 samples, 0 - 60 µm
    freq = np.maximum(np.linspace(0.0, np.pi * (n_real - 1) / end_freq, n_real), 1e-40)
    with np.errstate(all="ignore"):
        s = np.nan_to_num(spline(1000.0 / freq) / (freq * freq)[:, None])
    sp = np.fft.rfft(s, axis=0)
    out = np.concatenate([sp.real, sp.imag], axis=1)
    out.setflags(write=False)
    return out


def cmf_fourier_table():
    """Cycles' ``table_thin_film_cmf`` (512, 6): the FFT of the CIE XYZ CMFs resampled on a
    uniform frequency grid (re X, Y, Z, im X, Y, Z), float64."""
    return _cmf_fourier().copy()


@functools.lru_cache(maxsize=None)
def _table(working_space, gen):
    t = _cmf_fourier()
    m = _xyz_to_rgb(working_space, gen)
    re, im = m @ t[:, :3].T, m @ t[:, 3:].T  # (3, 512)
    norm = 1.0 / re[:, :1]  # DC term -> 1
    out = np.stack([re * norm, im * norm])  # (2, 3, 512)
    out.setflags(write=False)
    return out


def sensitivity_table(working_space="Linear Rec.709", version=None):
    """The kernel's ``thin_film_table`` as (2, 3, 512): [re, im][channel][entry] (5.0+)."""
    if generation(version) != "LUT":
        raise ValueError("Blender 4.5 has no thin-film table (Gaussian fit)")
    return _table(working_space, "LUT").copy()


def _lookup(table, ch, opd):
    """iridescence_lookup_sensitivity_channel: x = 2π OPD / 60000 nm, lookup_table_read."""
    u = np.clip(2.0 * np.pi * opd / 60000.0, 0.0, 1.0) * (TABLE_SIZE - 1)
    i = np.minimum(u.astype(np.int64), TABLE_SIZE - 1)
    t = u - i
    j = np.minimum(i + 1, TABLE_SIZE - 1)
    re, im = table[0], table[1]
    return ((1.0 - t) * re[ch, i] + t * re[ch, j], (1.0 - t) * im[ch, i] + t * im[ch, j])


def _gauss_sensitivity(opd, shift):
    """4.5 iridescence_lookup_sensitivity: Gaussian fit of the XYZ sensitivities, (..., 3)."""
    phase = (2.0 * np.pi * opd * 1e-9)[..., None]
    shift = shift[..., None]
    val = np.array([5.4856e-13, 4.4201e-13, 5.2481e-13])
    pos = np.array([1.6810e+06, 1.7953e+06, 2.2084e+06])
    var = np.array([4.3278e+09, 9.3046e+09, 6.6121e+09])
    xyz = val * np.sqrt(2.0 * np.pi * var) * np.cos(pos * phase + shift) * np.exp(-phase ** 2 * var)
    x = 1.64408e-8 * np.cos(2.2399e+06 * phase[..., 0] + shift[..., 0]) * np.exp(
        -4.5282e+09 * phase[..., 0] ** 2)
    xyz[..., 0] += x
    return xyz / 1.0685e-7


#: 4.5's sensitivity tabulated for node lookups (gauss_table): OPD from 0 to GAUSS_OPD_MAX nm
#: in GAUSS_ENTRIES steps of 2.4 nm, where its fastest cosine turns by 0.034 rad (linear
#: interpolation: ≤ 1.5e-4 of the amplitude); beyond, the Gaussians are below 1e-7.
GAUSS_OPD_MAX = 10000.0
GAUSS_ENTRIES = 4096


def gauss_table(working_space="Linear Rec.709"):
    """4.5's sensitivity at shift 0 converted to RGB as its film's XYZ is (M (S ⊙ M⁻¹ 1)), at
    OPD = i GAUSS_OPD_MAX / (GAUSS_ENTRIES - 1): (3, GAUSS_ENTRIES), float64."""
    opd = np.linspace(0.0, GAUSS_OPD_MAX, GAUSS_ENTRIES)
    m = _xyz_to_rgb(working_space, "GAUSS")
    white = np.linalg.inv(m) @ np.ones(3)
    return ((_gauss_sensitivity(opd, np.zeros_like(opd)) * white) @ m.T).T


# --------------------------------------------------------------------------------------------
# Fresnel pieces at normal incidence (cos θ = 1)
# --------------------------------------------------------------------------------------------

def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return np.where(x < e0, 0.0, np.where(x >= e1, 1.0, (3.0 - 2.0 * t) * t * t))


def _dielectric_polarized(eta):
    """fresnel_dielectric_polarized(1, eta): R_s, R_p and the signs of r_s, r_p (cos φ)."""
    r_s = (1.0 - eta) / (1.0 + eta)  # cos θt = -1
    r_p = (eta - 1.0) / (eta + 1.0)
    return r_s * r_s, r_p * r_p, np.where(r_s >= 0.0, 1.0, -1.0), np.where(r_p >= 0.0, 1.0, -1.0)


def _conductor_polarized(film, n, k):
    """fresnel_conductor_polarized(1, film, n + ik, F82 >= 0): R_s = R_p = F0 of (n, k)/film
    (the F82 model at cos = 1 is F0), phasors exp(iφ_s), exp(iφ_p) from u, v."""
    nr, kr = n / film, k / film
    f0 = ((nr - 1.0) ** 2 + kr * kr) / ((nr + 1.0) ** 2 + kr * kr)
    r = np.clip(f0, 0.0, 1.0)
    t1 = n * n - k * k
    t2 = np.sqrt(t1 * t1 + (2.0 * n * k) ** 2)
    u2, v2 = np.maximum(0.5 * (t2 + t1), 0.0), np.maximum(0.5 * (t2 - t1), 0.0)
    u, v = np.sqrt(u2), np.sqrt(v2)

    def unit(re, im):
        mag = np.hypot(re, im)
        ok = mag != 0.0
        safe = np.where(ok, mag, 1.0)
        return np.where(ok, re / safe, 1.0), np.where(ok, im / safe, 0.0)

    ps = unit(-u2 - v2 + film * film, -2.0 * film * v)
    pp = unit((n * n + k * k) ** 2 - film * film * (u2 + v2),
              2.0 * film * (2.0 * n * k * u - (n * n - k * k) * v))
    return r, r, ps, pp


def _airy(r12, r23, opd, phasor, ch, table):
    """iridescence_airy_summation_channel (m <= 3), one polarization, complex phasor."""
    t121 = 1.0 - r12
    r123 = r12 * r23
    sq = np.sqrt(r123)
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = np.where(r123 < 1.0, t121 * t121 * r23 / np.where(r123 < 1.0, 1.0 - r123, 1.0), 0.0)
    out = rs + r12
    cm = rs - t121
    acc_re, acc_im = phasor
    for m in (1, 2, 3):
        cm = cm * sq
        s_re, s_im = _lookup(table, ch, m * opd)
        out = out + cm * 2.0 * (acc_re * s_re + acc_im * s_im)
        acc_re, acc_im = (acc_re * phasor[0] - acc_im * phasor[1],
                          acc_re * phasor[1] + acc_im * phasor[0])
    return out


def _iridescence_lut(ch, thickness, film_ior, substrate, table):
    """fresnel_iridescence_channel (5.x) at cos θ1 = 1, ambient IOR 1.  ``substrate``:
    ("dielectric", n) or ("conductor", n, k)."""
    film = np.where(thickness < 1.0, 1.0 + (film_ior - 1.0) * _smoothstep(0.0, 1.0, thickness),
                    film_ior)
    r12_s, r12_p, c12_s, c12_p = _dielectric_polarized(film)
    if substrate[0] == "conductor":
        r23_s, r23_p, p23_s, p23_p = _conductor_polarized(film, substrate[1], substrate[2])
    else:
        r23_s, r23_p, c_s, c_p = _dielectric_polarized(substrate[1] / film)
        p23_s, p23_p = (c_s, 0.0 * c_s), (c_p, 0.0 * c_p)
    opd = 2.0 * film * thickness  # -2 n d cos θ2, cos θ2 = -1
    ph_s = (p23_s[0] * -c12_s, p23_s[1] * -c12_s)
    ph_p = (p23_p[0] * -c12_p, p23_p[1] * -c12_p)
    r = 0.5 * (_airy(r12_s, r23_s, opd, ph_s, ch, table) + _airy(r12_p, r23_p, opd, ph_p, ch, table))
    tir = (r12_s == 1.0) & (r12_p == 1.0)
    if substrate[0] != "conductor":
        tir = tir | ((r23_s == 1.0) & (r23_p == 1.0))
    return np.where(tir, 1.0, np.clip(r, 0.0, 1.0))


def _iridescence_gauss(thickness, film_ior, eta3, xyz_to_rgb):
    """4.5 fresnel_iridescence(kg, 1, film, eta3, cos = 1, thickness) -> RGB (..., 3)."""
    eta2 = np.where(thickness < 30.0,
                    1.0 + (film_ior - 1.0) * _smoothstep(0.0, 30.0, thickness), film_ior)
    r12_s, r12_p, c12_s, c12_p = _dielectric_polarized(eta2)
    r23_s, r23_p, c23_s, c23_p = _dielectric_polarized(eta3 / eta2)
    opd = 2.0 * eta2 * thickness
    total = 0.0
    for r12, r23, c12, c23 in ((r12_s, r23_s, c12_s, c23_s), (r12_p, r23_p, c12_p, c23_p)):
        phi = np.pi - np.where(c12 < 0.0, np.pi, 0.0) + np.where(c23 < 0.0, np.pi, 0.0)
        t121 = 1.0 - r12
        r123 = r12 * r23
        sq = np.sqrt(r123)
        with np.errstate(divide="ignore", invalid="ignore"):
            rs = np.where(r123 < 1.0, t121 * t121 * r23 / np.where(r123 < 1.0, 1.0 - r123, 1.0),
                          0.0)
        acc = (r12 + rs)[..., None] * np.ones(3)
        cm = rs - t121
        for m in (1, 2, 3):
            cm = cm * sq
            acc = acc + (cm * 2.0)[..., None] * _gauss_sensitivity(m * opd, m * phi)
        acc = np.where((r23 == 1.0)[..., None], 1.0, acc)
        total = total + 0.5 * acc
    white = np.linalg.inv(xyz_to_rgb) @ np.ones(3)
    rgb = (total * white) @ xyz_to_rgb.T
    tir = ((r12_s == 1.0) & (r12_p == 1.0)) | ((r23_s == 1.0) & (r23_p == 1.0))
    return np.where(tir[..., None], 1.0, np.clip(rgb, 0.0, 1.0))


# --------------------------------------------------------------------------------------------
# Public forward model
# --------------------------------------------------------------------------------------------

def _clean(value, name, default):
    lo, hi = LIMITS[name]
    a = np.asarray(value, np.float64)
    return np.clip(np.nan_to_num(a, nan=default, posinf=hi, neginf=lo), lo, hi)


def _colour(value, name, default):
    a = _clean(value, name, default)
    return a[..., None] * np.ones(3) if a.ndim == 0 else a


def film_active(thickness):
    """Whether Cycles applies the film: thickness > THINFILM_THICKNESS_CUTOFF (0.1 nm)."""
    return _clean(thickness, "thickness", 0.0) > THICKNESS_CUTOFF


def _channel_grid(*arrays):
    """Broadcast (..., 3) colours and (...) scalars (given as (..., 1)) to (..., 3) plus the
    channel index of every element."""
    out = np.broadcast_arrays(*arrays, np.arange(3))
    return out[:-1], out[-1]


def _metal_flat(f0, tint, d, film, ch, table):
    """Metallic lobe, channel ``ch`` (arrays of one shape; inputs already clipped, 5.x)."""
    # bsdf_microfacet.h microfacet_fresnel, F82_TINT with thin film: Gulbrandsen n, k from
    # r = min(F0, 0.999), g = F82(1/7) = F_schlick(6/7) tint (fresnel_f82tint_B, fresnel_f82).
    r = np.minimum(f0, 0.999)
    s5 = (6.0 / 7.0) ** 5
    schlick = f0 + (1.0 - f0) * s5
    b = np.where(tint == 1.0, 0.0, schlick * (7.0 / (s5 * 6.0 / 7.0)) * (1.0 - tint))
    g = np.clip(schlick - b * (1.0 / 7.0) * s5 * (6.0 / 7.0), 0.0, 1.0)
    sqrt_r = np.sqrt(r)
    n = (1.0 - g) * (1.0 + sqrt_r) / (1.0 - sqrt_r) + g * (1.0 - r) / (1.0 + r)
    k = np.sqrt(np.maximum((r * (n + 1.0) ** 2 - (n - 1.0) ** 2) / (1.0 - r), 0.0))
    filmed = _iridescence_lut(ch, d, film, ("conductor", n, k), table)
    return np.where(d > THICKNESS_CUTOFF, filmed, f0)


def metal_reflectance(base_color, specular_tint=1.0, thickness=0.0, film_ior=1.33, *,
                      version=None, working_space="Linear Rec.709"):
    """Normal-incidence reflectance R(0) of Principled's metallic lobe (F82-tint), (..., 3).

    ``base_color``, ``specular_tint``: (..., 3) or scalars; ``thickness`` (nm), ``film_ior``:
    (...).  Without a film (thickness <= 0.1 nm, or Blender 4.5) R(0) = clamp(Base Color)."""
    f0 = _colour(base_color, "base_color", 0.0)
    tint = np.minimum(_colour(specular_tint, "specular_tint", 1.0), 1.0)  # f82 = min(tint, 1)
    d = _clean(thickness, "thickness", 0.0)[..., None]
    film = _clean(film_ior, "film_ior", 1.0)[..., None]
    (f0, tint, d, film), ch = _channel_grid(f0, tint, d, film)
    if generation(version) != "LUT":
        return f0.copy()
    return _metal_flat(f0, tint, d, film, ch, _table(working_space, "LUT"))


def _dielectric_eta(ior, level):
    """svm/closure.h "Apply IOR adjustment": eta and f0 = F0(IOR) * 2 level (unclamped)."""
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2
    scaled = f0 * 2.0 * level
    sq = np.sqrt(np.clip(scaled, 0.0, 0.99))
    eta = (1.0 + sq) / (1.0 - sq)  # ior_from_F0
    eta = np.where(ior < 1.0, 1.0 / eta, eta)
    same = level == 0.5
    return np.where(same, ior, eta), np.where(same, f0, scaled)


def _dielectric_flat(ior, level, tint, d, film, gen, working_space):
    """Dielectric lobe: scalars (...), ``tint`` (..., 3); inputs clipped.  -> (..., 3)."""
    ior, level, d, film = (a[..., None] for a in (ior, level, d, film))
    (ior, level, tint, d, film), ch = _channel_grid(ior, level, tint, d, film)
    eta, f0 = _dielectric_eta(ior, level)
    f0_tint = np.clip(f0 * tint, 0.0, 1.0)  # bsdf_microfacet_setup_fresnel_generalized_schlick
    plain = f0_tint  # generalized_schlick_fresnel, exponent < 0 branch at cos = 1: s = 0
    on = d > THICKNESS_CUTOFF
    if gen == "LUT":
        f = _iridescence_lut(ch, d, film, ("dielectric", eta), _table(working_space, "LUT"))
    else:
        f = _iridescence_gauss(d[..., 0], film[..., 0], eta[..., 0],
                               _xyz_to_rgb("Linear Rec.709", "GAUSS"))
    # generalized_schlick_fresnel "Apply F0 scaling" (per channel, skipped when F == 1 in all)
    f0_real = ((eta - 1.0) / (eta + 1.0)) ** 2
    ok = (f0_real > 1e-5) & ~np.all(f == 1.0, axis=-1, keepdims=True)
    safe = np.where(ok & (f0_real != 1.0), f0_real, 0.5)
    s = np.clip((f - 1.0) / (safe - 1.0), 0.0, 1.0)
    scaled = np.where(ok, f * (1.0 + s * (f0_tint / safe - 1.0)), f)
    return np.where(on, scaled, np.where(eta == 1.0, 0.0, plain))


def dielectric_reflectance(ior=1.5, specular_ior_level=0.5, specular_tint=1.0, thickness=0.0,
                           film_ior=1.33, *, version=None, working_space="Linear Rec.709"):
    """Normal-incidence reflectance R(0) of Principled's dielectric specular lobe, (..., 3).

    ``ior``, ``specular_ior_level``, ``thickness`` (nm), ``film_ior``: (...);
    ``specular_tint``: (..., 3) or scalar.  Without a film R(0) = min(F0(IOR) 2 level · tint, 1)
    (0 when the adjusted IOR is 1: Cycles then makes no specular lobe)."""
    gen = generation(version)
    if gen == "GAUSS" and working_space != "Linear Rec.709":
        _xyz_to_rgb(working_space, gen)  # raises
    return _dielectric_flat(_clean(ior, "ior", 1.5),
                            _clean(specular_ior_level, "specular_ior_level", 0.5),
                            _colour(specular_tint, "specular_tint", 1.0),
                            _clean(thickness, "thickness", 0.0),
                            _clean(film_ior, "film_ior", 1.0), gen, working_space)


# --------------------------------------------------------------------------------------------
# Inverses (may be non-monotone or unreachable: nearest reachable value + a mask; never NaN)
# --------------------------------------------------------------------------------------------

_GRID = 65
_CHUNK = 1 << 16


def _solve(fun, target, lo, hi, near, grid=_GRID, iters=52):
    """Flat problems i: x in [lo_i, hi_i] with fun(x, i) = target_i.

    1. ``near_i`` itself, if it solves the problem (flat, clamped stretches of R);
    2. else the sign changes of fun - target on a uniform grid, nearest to ``near_i`` first,
       refined by bisection and kept if the residual is <= 1e-10 (1 + |target|) (a sign change
       can be a jump of Cycles' model, e.g. where F0_real crosses 1e-5);
    3. else golden-section search for min |fun - target| on the two cells around the best
       grid node; if that extremum crosses the target (two roots inside one cell) bisection
       between it and a neighbouring node.
    Reachable = the final residual is <= 1e-10 (1 + |target|); otherwise x is the nearest
    reachable value found.  ``fun(x, rows)`` evaluates the problems ``rows`` (shaped like x)."""
    m = target.size
    x_out, ok_out = np.empty(m), np.zeros(m, bool)
    u = np.linspace(0.0, 1.0, grid)
    step = max(1, _CHUNK // grid)
    for start in range(0, m, step):
        rows = np.arange(start, min(m, start + step))
        xs = lo[rows, None] + (hi - lo)[rows, None] * u
        vals = fun(xs, np.broadcast_to(rows[:, None], xs.shape)) - target[rows, None]
        cross = np.sign(vals[:, :-1]) * np.sign(vals[:, 1:]) <= 0.0
        dist = np.where(cross, np.abs(0.5 * (xs[:, :-1] + xs[:, 1:]) - near[rows, None]), np.inf)
        found = np.zeros(len(rows), bool)
        x = np.empty(len(rows))
        for _ in range(4):  # a sign change can be a jump of Cycles' model: try the next one
            todo = np.flatnonzero(~found & np.isfinite(dist.min(axis=1)))
            if not todo.size:
                break
            j = np.argmin(dist[todo], axis=1)
            sub = rows[todo]
            a, b, fa = xs[todo, j], xs[todo, j + 1], vals[todo, j]
            for _ in range(iters):
                c = 0.5 * (a + b)
                fc = fun(c, sub) - target[sub]
                left = (np.sign(fc) == np.sign(fa)) & (fa != 0.0)
                a, fa, b = np.where(left, c, a), np.where(left, fc, fa), np.where(left, b, c)
            root = np.where(fa == 0.0, a, 0.5 * (a + b))
            good = np.abs(fun(root, sub) - target[sub]) <= 1e-10 * (1.0 + np.abs(target[sub]))
            x[todo] = root
            found[todo] = good
            dist[todo[~good], j[~good]] = np.inf
        lost = np.flatnonzero(~found)
        if lost.size:
            sub, jb = rows[lost], np.argmin(np.abs(vals[lost]), axis=1)
            xa, xb = xs[lost, np.maximum(jb - 1, 0)], xs[lost, np.minimum(jb + 1, grid - 1)]
            ga, gb = xa, xb
            phi = 0.5 * (np.sqrt(5.0) - 1.0)
            for _ in range(iters):  # golden section for min |f - target| on the two cells
                c1, c2 = gb - phi * (gb - ga), ga + phi * (gb - ga)
                first = np.abs(fun(c1, sub) - target[sub]) <= np.abs(fun(c2, sub) - target[sub])
                ga, gb = np.where(first, ga, c1), np.where(first, c2, gb)
            best = 0.5 * (ga + gb)
            e = fun(best, sub) - target[sub]
            node, e_node = xs[lost, jb], vals[lost, jb]
            best = np.where(np.abs(e) <= np.abs(e_node), best, node)
            e = np.where(np.abs(e) <= np.abs(e_node), e, e_node)
            # two roots inside one cell: the extremum crossed the target; bisect on its side
            # nearer to ``near`` (between the extremum and the neighbouring node).
            tol = 1e-13 * (1.0 + np.abs(target[sub]))
            close = np.abs(e) <= tol  # golden section may land on a root itself
            hit = (np.sign(e) != np.sign(e_node)) | close
            other = np.where(best > node, xb, xa)
            side_a = np.abs(0.5 * (node + best) - near[sub]) <= np.abs(0.5 * (best + other)
                                                                       - near[sub])
            a = best
            b = np.where(side_a, node, other)
            fa = e
            for _ in range(iters):
                c = 0.5 * (a + b)
                fc = fun(c, sub) - target[sub]
                left = (np.sign(fc) == np.sign(fa)) & (fa != 0.0)
                a, fa, b = np.where(left, c, a), np.where(left, fc, fa), np.where(left, b, c)
            x[lost] = np.where(close, best,
                               np.where(hit, np.where(fa == 0.0, a, 0.5 * (a + b)), best))
            found[lost] = np.abs(fun(x[lost], sub) - target[sub]) <= 1e-10 * (
                1.0 + np.abs(target[sub]))
        at_near = np.abs(fun(near[rows], rows) - target[rows]) <= 1e-13 * (1.0 + np.abs(target[rows]))
        at_near &= (near[rows] >= lo[rows]) & (near[rows] <= hi[rows])
        x_out[rows] = np.where(at_near, near[rows], x)  # flat (clamped) stretches: keep the hint
        ok_out[rows] = found | at_near
    return x_out, ok_out


def metal_base_for_reflectance(target, specular_tint=1.0, thickness=0.0, film_ior=1.33, *,
                               near=None, version=None, working_space="Linear Rec.709"):
    """Base Color (F0, per channel in [0, 1]) whose filmed R(0) (:func:`metal_reflectance`)
    equals ``target`` (..., 3).  Returns (base_color, reachable), both (..., 3).

    R(0) need not be monotone in F0: of several solutions the one nearest to ``near`` (a base
    colour; default ``target``, the solution without film) is returned.  Unreachable targets
    give the F0 of the reachable R(0) nearest to the target, reachable False.  Without a film
    (or in 4.5) the base colour is the clamped target."""
    tgt = _colour(target, "base_color", 0.0)
    tint = np.minimum(_colour(specular_tint, "specular_tint", 1.0), 1.0)
    d = _clean(thickness, "thickness", 0.0)[..., None]
    film = _clean(film_ior, "film_ior", 1.0)[..., None]
    hint = tgt if near is None else _colour(near, "base_color", 0.0)
    (tgt, tint, d, film, hint), ch = _channel_grid(tgt, tint, d, film, hint)
    if generation(version) != "LUT":
        return tgt.copy(), np.ones(tgt.shape, bool)
    table = _table(working_space, "LUT")
    t_, tint_, d_, film_, hint_, ch_ = (a.reshape(-1) for a in (tgt, tint, d, film, hint, ch))

    def fun(x, rows):
        return _metal_flat(x, tint_[rows], d_[rows], film_[rows], ch_[rows], table)

    x, ok = _solve(fun, t_, np.zeros_like(t_), np.ones_like(t_), hint_)
    return np.clip(x, 0.0, 1.0).reshape(tgt.shape), ok.reshape(tgt.shape)


#: Search range of the dielectric inverse: F0(IOR) in [0, 0.99] (IOR 1 - 399).
_F0_MAX = 0.99


def _ior_from_f0(f0):
    sq = np.sqrt(np.clip(f0, 0.0, _F0_MAX))
    return (1.0 + sq) / (1.0 - sq)


def dielectric_ior_for_reflectance(target, specular_ior_level=0.5, specular_tint=1.0,
                                   thickness=0.0, film_ior=1.33, *, weights=None, near=None,
                                   version=None, working_space="Linear Rec.709"):
    """IOR (>= 1) whose filmed dielectric R(0) (:func:`dielectric_reflectance`) meets
    ``target`` (..., 3).  Returns (ior, reachable).

    ``weights=None``: one IOR per channel, (..., 3) each.  ``weights=(w_r, w_g, w_b)``: one IOR
    per element, (...), for the weighted sum Σ w_c R_c = Σ w_c target_c (one IOR cannot meet
    three channels in general; :func:`dielectric_tint_for_reflectance` then fixes them).
    The search runs over F0(IOR) in [0, 0.99]; of several solutions the one nearest to ``near``
    (an IOR, (...) or (..., 3); default the solution without film, F0(IOR) 2 level tint =
    target) is returned; unreachable -> the IOR of the nearest reachable value, reachable
    False."""
    gen = generation(version)
    tgt = _colour(target, "base_color", 0.0)
    level = _clean(specular_ior_level, "specular_ior_level", 0.5)
    tint = _colour(specular_tint, "specular_tint", 1.0)
    d = _clean(thickness, "thickness", 0.0)
    film = _clean(film_ior, "film_ior", 1.0)
    w = None if weights is None else np.nan_to_num(np.asarray(weights, np.float64).reshape(3))
    shape = np.broadcast_shapes(tgt.shape, level.shape + (1,), tint.shape, d.shape + (1,),
                                film.shape + (1,))
    tgt, tint = np.broadcast_to(tgt, shape), np.broadcast_to(tint, shape)
    level, d, film = (np.broadcast_to(a[..., None], shape)[..., 0] for a in (level, d, film))
    if near is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            guess = np.nan_to_num(tgt / (2.0 * level[..., None] * tint), nan=0.0, posinf=1.0)
        guess = np.clip(guess, 0.0, _F0_MAX)
    else:
        ni = _clean(near, "ior", 1.5)
        ni = ni if ni.ndim and ni.shape[-1] == 3 and ni.ndim == len(shape) else ni[..., None]
        guess = np.broadcast_to(((ni - 1.0) / (ni + 1.0)) ** 2, shape)
    if w is not None:
        tgt = np.sum(tgt * w, axis=-1, keepdims=True)
        guess = np.sum(guess * np.abs(w), axis=-1, keepdims=True) / max(np.abs(w).sum(), 1e-300)
        cols = 1
    else:
        cols = 3
    flat = [np.broadcast_to(a, shape[:-1] + (cols,)).reshape(-1) for a in
            (tgt, level[..., None], d[..., None], film[..., None], guess)]
    t_, lv_, d_, fi_, g_ = flat
    ch_ = np.broadcast_to(np.arange(cols), shape[:-1] + (cols,)).reshape(-1)
    tint_ = np.broadcast_to(tint[..., None, :], shape[:-1] + (cols, 3)).reshape(-1, 3)

    def fun(f0, rows):
        out = _dielectric_flat(_ior_from_f0(f0), lv_[rows], tint_[rows], d_[rows], fi_[rows],
                               gen, working_space)
        if w is None:
            return np.take_along_axis(out, ch_[rows][..., None], axis=-1)[..., 0]
        return out @ w

    x, ok = _solve(fun, t_, np.zeros_like(t_), np.full_like(t_, _F0_MAX), g_)
    out_shape = shape[:-1] + (cols,)
    ior, ok = _ior_from_f0(x).reshape(out_shape), ok.reshape(out_shape)
    return (ior, ok) if w is None else (ior[..., 0], ok[..., 0])


def dielectric_tint_for_reflectance(target, ior, specular_ior_level=0.5, thickness=0.0,
                                    film_ior=1.33, *, version=None,
                                    working_space="Linear Rec.709"):
    """Specular Tint (per channel, >= 0) that makes the filmed dielectric R(0) equal
    ``target`` (..., 3) at the given IOR.  Returns (tint, reachable), (..., 3).

    Cycles saturates f0 · tint (f0 = F0(IOR) 2 level), and R_c is affine in f0 · tint_c below 1
    (the F0 scaling F_c (1 + s_c (f0 tint_c / F0_real - 1)); without a film f0 tint_c), so
    tint_c = t_sat (target_c - R_c(0)) / (R_c(t_sat) - R_c(0)) with t_sat = 1/f0.  Where R_c
    does not depend on the tint (s_c = 0) the tint is 1, reachable iff R_c already is the
    target.  Unreachable (a negative tint, or one past t_sat, needed) -> the nearest tint in
    [0, t_sat], reachable False."""
    tgt = _colour(target, "base_color", 0.0)
    _, f0 = _dielectric_eta(_clean(ior, "ior", 1.5), _clean(specular_ior_level,
                                                            "specular_ior_level", 0.5))
    t_sat = np.minimum(1.0 / np.maximum(f0, 1e-300), LIMITS["specular_tint"][1])[..., None]
    r0 = dielectric_reflectance(ior, specular_ior_level, 0.0, thickness, film_ior,
                                version=version, working_space=working_space)
    r1 = dielectric_reflectance(ior, specular_ior_level, t_sat, thickness, film_ior,
                                version=version, working_space=working_space)
    tgt, r0, r1, t_sat = np.broadcast_arrays(tgt, r0, r1, t_sat)
    slope = r1 - r0
    live = np.abs(slope) > 1e-12
    u = np.where(live, (tgt - r0) / np.where(live, slope, 1.0), 0.0)
    tint = np.where(live, np.clip(u, 0.0, 1.0) * t_sat, np.minimum(1.0, t_sat))
    ok = np.where(live, (u >= 0.0) & (u <= 1.0),
                  np.abs(r0 - tgt) <= 1e-12 * (1.0 + np.abs(tgt)))  # tint has no effect
    return tint, ok
