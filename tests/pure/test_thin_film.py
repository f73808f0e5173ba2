# SPDX-License-Identifier: GPL-3.0-or-later
"""core.thin_film: Cycles' Principled thin-film reflectance at normal incidence (no bpy).

Independent checks: the spline against exact cubics; the Fourier table against a direct DFT;
the reflectance against direct spectral integration of the Airy reflectance with the CIE
curves (spectral_reference), to the accuracy Cycles' approximations allow (the Airy series
truncated after m = 3, the coarse frequency grid and the OPD interpolation of the LUT, or 4.5's
Gaussian fit; the measured bounds are asserted); exact invariants (film IOR 1, film = substrate);
inverse round trips; garbage inputs.  The renders are in tests/blender/test_thin_film.py.
"""
import itertools

import numpy as np
import pytest

import spectral_reference as sr
from hazy_gloss.core import thin_film as tf

VERSIONS = ("4.5", "5.2", "5.3")
THICK = np.array([1.5, 5, 10, 20, 30, 50, 100, 150, 200, 300, 400, 500, 700, 1000.0])
FILM = (1.2, 1.33, 1.5, 2.0, 2.5)


def gulbrandsen_nk(f0, tint=1.0):
    """Cycles' n, k estimate for the metal (written out again, from Gulbrandsen 2014)."""
    f0 = np.asarray(f0, float)
    r = np.minimum(f0, 0.999)
    g = (f0 + (1 - f0) * (6 / 7) ** 5) * tint
    n = (1 - g) * (1 + np.sqrt(r)) / (1 - np.sqrt(r)) + g * (1 - r) / (1 + r)
    k = np.sqrt(np.maximum((r * (n + 1) ** 2 - (n - 1) ** 2) / (1 - r), 0))
    return n, k


def negative_lobe_factor():
    """∫|cmf_c| / ∫cmf_c: how much a per-λ error bound grows in channel c's integral."""
    lam, cmf = sr.wavelengths(), sr.channel_cmfs()
    return np.trapezoid(np.abs(cmf), lam, axis=-1) / np.trapezoid(cmf, lam, axis=-1)


# ------------------------------------------------------------------------------------------------
# The table
# ------------------------------------------------------------------------------------------------


def test_spline_is_exact_on_cubics():
    """Not-a-knot cubic splines reproduce any cubic exactly (scipy's CubicSpline default)."""
    x = np.sort(np.random.default_rng(0).uniform(0, 10, 40))
    x[0], x[-1] = 0.0, 10.0
    cubic = np.stack([1 + 2 * x - 0.3 * x ** 2 + 0.05 * x ** 3, 0.7 * x ** 3], axis=1)
    f = tf._not_a_knot_spline(x, cubic)
    t = np.linspace(0, 10, 333)
    want = np.stack([1 + 2 * t - 0.3 * t ** 2 + 0.05 * t ** 3, 0.7 * t ** 3], axis=1)
    assert np.abs(f(t) - want).max() <= 1e-10
    assert np.isnan(f(np.array([-0.1, 10.1]))).all()  # extrapolate=False


def test_fourier_table_is_the_dft_of_the_resampled_cmfs():
    """Entry k = Σ_n w(ν_n) e^{-2πi k n / 1022}, w = cmf(1000/ν)/ν², ν_n = n π/60 µm⁻¹: checked
    by a direct sum (the nodes inside 359-831 nm only)."""
    t = tf.cmf_fourier_table()
    assert t.shape == (512, 6)
    nu = np.arange(1022) * np.pi / 60.0
    with np.errstate(divide="ignore"):
        lam = 1000.0 / nu
    inside = np.flatnonzero((lam >= 359) & (lam <= 831))
    assert 25 <= inside.size <= 35  # the visible range is ~31 frequency samples
    # the CMFs at those wavelengths, by the module's spline (its exactness is tested above)
    spl = tf._not_a_knot_spline(
        np.arange(359.0, 832.0),
        np.concatenate([np.zeros((1, 3)), np.stack([tf.cie_1931.X_BAR, tf.cie_1931.Y_BAR,
                                                    tf.cie_1931.Z_BAR], 1), np.zeros((1, 3))]))
    w = spl(lam[inside]) / (nu[inside] ** 2)[:, None]
    for k in (0, 1, 7, 100, 511):
        s = (w * np.exp(-2j * np.pi * k * inside / 1022.0)[:, None]).sum(axis=0)
        assert np.allclose(t[k, :3], s.real, rtol=0, atol=1e-12 * np.abs(s).max())
        assert np.allclose(t[k, 3:], s.imag, rtol=0, atol=1e-12 * np.abs(s).max())


@pytest.mark.parametrize("space", tf.WORKING_SPACES)
def test_sensitivity_table_dc_is_one(space):
    tab = tf.sensitivity_table(space, "5.3")
    assert tab.shape == (2, 3, 512)
    assert np.allclose(tab[0, :, 0], 1.0) and np.allclose(tab[1, :, 0], 0.0)


def test_xyz_to_rgb_maps_d65_white_to_one():
    """Cycles' matrix for Blender's config sends D65 white to RGB (1, 1, 1): OCIO's D65
    (0.95045592705167, 1, 1.08905775075988) in 5.x, the 4-digit (0.95047, 1, 1.08883) of the
    4.5 config's Rec.709 matrix in 4.5; the two differ by <= 2.4e-4 (the configs' matrices)."""
    d65 = {"LUT": np.array([0.95045592705167, 1.0, 1.08905775075988]),
           "GAUSS": np.array([0.95047, 1.0, 1.08883])}
    for v in VERSIONS:
        white = tf.xyz_to_rgb_matrix("Linear Rec.709", v) @ d65[tf.generation(v)]
        assert np.allclose(white, 1.0, atol=1e-5), (v, white)
    assert np.abs(tf.xyz_to_rgb_matrix(version="4.5") - tf.xyz_to_rgb_matrix(version="5.3")).max() < 1e-3
    with pytest.raises(ValueError):
        tf.xyz_to_rgb_matrix("ACEScg", "4.5")
    with pytest.raises(ValueError):
        tf.xyz_to_rgb_matrix("sRGB", "5.3")


# ------------------------------------------------------------------------------------------------
# Against direct spectral integration
# ------------------------------------------------------------------------------------------------

#: Measured: 5.x LUT vs the spectral m <= 3 series: <= 2.1e-3 (dielectric), 2.5e-3 (metal); the
#: rest of the error against the exact Airy reflectance is the truncation.
LUT_TOL = 3e-3
#: Measured: 4.5's Gaussian fit vs the spectral m <= 3 series, films >= 30 nm: <= 0.06.
GAUSS_TOL = 0.08


@pytest.mark.parametrize("version", ["5.3", "4.5"])
def test_dielectric_matches_spectral_integration(version):
    worst_series = worst_exact = 0.0
    amp = negative_lobe_factor()
    thick = THICK if version != "4.5" else THICK[THICK >= 30]  # 4.5 blends the film below 30 nm
    for fi, eta in itertools.product(FILM, (1.2, 1.5, 2.0, 3.0)):
        got = tf.dielectric_reflectance(eta, 0.5, 1.0, thick, fi, version=version)
        series = np.clip(sr.rgb_series(thick, fi, eta), 0, 1)
        exact = np.clip(sr.rgb_reflectance(thick, fi, eta), 0, 1)
        worst_series = max(worst_series, np.abs(got - series).max())
        bound = sr.truncation_bound(fi, eta) * amp
        worst_exact = max(worst_exact, (np.abs(got - exact) - bound).max())
    tol = LUT_TOL if version != "4.5" else GAUSS_TOL
    assert worst_series <= tol, worst_series
    assert worst_exact <= tol, worst_exact


def test_metal_matches_spectral_integration():
    amp = negative_lobe_factor()
    worst_series = worst_exact = 0.0
    for f0 in ([0.8, 0.6, 0.4], [0.95, 0.64, 0.54], [0.05, 0.2, 0.99]):
        for tint in (1.0, 0.7):
            n, k = gulbrandsen_nk(f0, tint)
            for fi in (1.2, 1.5, 2.0, 2.5):
                got = tf.metal_reflectance(f0, tint, THICK, fi, version="5.3")
                series = np.clip(sr.rgb_series(THICK, fi, n, k), 0, 1)
                exact = np.clip(sr.rgb_reflectance(THICK, fi, n, k), 0, 1)
                worst_series = max(worst_series, np.abs(got - series).max())
                bound = sr.truncation_bound(fi, n, k) * amp
                worst_exact = max(worst_exact, (np.abs(got - exact) - bound).max())
    assert worst_series <= LUT_TOL, worst_series
    assert worst_exact <= LUT_TOL, worst_exact
    # the phase convention matters: the conjugate index (n - iκ) is far off
    n, k = gulbrandsen_nk([0.8, 0.6, 0.4])
    wrong = np.clip(sr.rgb_reflectance(THICK, 1.5, n, -k), 0, 1)
    assert np.abs(tf.metal_reflectance([0.8, 0.6, 0.4], 1.0, THICK, 1.5) - wrong).max() > 0.1


# ------------------------------------------------------------------------------------------------
# Exact invariants and version behaviour
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("version", VERSIONS)
def test_no_film_is_f0(version):
    rng = np.random.default_rng(1)
    bc, tint = rng.uniform(0, 1, (50, 3)), rng.uniform(0, 1, (50, 3))
    for d in (0.0, 0.1, -5.0):
        assert np.array_equal(tf.metal_reflectance(bc, tint, d, 1.8, version=version), bc)
        ior, lvl = rng.uniform(1.01, 3, 50), rng.uniform(0, 1, 50)
        got = tf.dielectric_reflectance(ior, lvl, tint, d, 1.8, version=version)
        f0 = ((ior - 1) / (ior + 1)) ** 2 * 2 * lvl
        assert np.allclose(got, f0[:, None] * tint, rtol=1e-12, atol=0)
        big = tf.dielectric_reflectance(1.5, 0.5, [3.0, 12.0, 30.0], d, 1.8, version=version)
        assert np.allclose(big, [0.12, 0.48, 1.0], rtol=1e-12)  # Cycles saturates f0 tint


@pytest.mark.parametrize("version", ["5.2", "5.3"])
def test_film_of_index_one_is_invisible(version):
    """Film IOR 1: R12 = 0, so R = R23 = F0 of the substrate, at every thickness."""
    rng = np.random.default_rng(2)
    bc, tint = rng.uniform(0, 0.999, (40, 3)), rng.uniform(0, 1, (40, 3))
    d = rng.uniform(1, 1000, 40)
    assert np.allclose(tf.metal_reflectance(bc, tint, d, 1.0, version=version), bc,
                       rtol=1e-9, atol=1e-12)
    ior, lvl = rng.uniform(1.05, 3, 40), rng.uniform(0.1, 1, 40)
    f0 = ((ior - 1) / (ior + 1)) ** 2 * 2 * lvl
    got = tf.dielectric_reflectance(ior, lvl, tint, d, 1.0, version=version)
    assert np.allclose(got, f0[:, None] * tint, rtol=1e-9, atol=1e-12)


def test_film_matching_the_substrate_is_a_single_interface():
    """Film IOR = substrate IOR: R23 = 0, R = F0(film) for any thickness (5.x, 4.5)."""
    for v in VERSIONS:
        got = tf.dielectric_reflectance(1.7, 0.5, 1.0, [50.0, 333.0, 900.0], 1.7, version=v)
        assert np.allclose(got, ((1.7 - 1) / 2.7) ** 2, rtol=1e-12)


def test_versions():
    args = ([0.8, 0.6, 0.4], 0.9, [100.0, 450.0], 1.33)
    assert np.array_equal(tf.metal_reflectance(*args, version="5.2"),
                          tf.metal_reflectance(*args, version="5.3"))
    assert np.array_equal(tf.metal_reflectance(*args, version="4.5"),
                          np.broadcast_to([0.8, 0.6, 0.4], (2, 3)))  # no film on 4.5 metals
    d52 = tf.dielectric_reflectance(1.5, 0.5, 1.0, THICK, 1.33, version="5.2")
    d45 = tf.dielectric_reflectance(1.5, 0.5, 1.0, THICK, 1.33, version="4.5")
    assert np.array_equal(d52, tf.dielectric_reflectance(1.5, 0.5, 1.0, THICK, 1.33,
                                                         version="5.3"))
    assert 1e-4 < np.abs(d52 - d45).max() < 0.05
    assert tf.generation("4.5") == "GAUSS" and tf.generation("5.0") == "LUT"


def test_the_measured_case_moves_the_peak():
    """The brief's case: metal Base Color 0.8, 450 nm, film IOR 1.33: R(0) is not F0."""
    r = tf.metal_reflectance(0.8, 1.0, 450.0, 1.33, version="5.3")
    assert np.abs(r - 0.8).max() > 0.05


def test_broadcasting():
    r = tf.metal_reflectance(np.full((4, 1, 3), 0.5), 1.0, np.linspace(0, 900, 5), 1.4)
    assert r.shape == (4, 5, 3)
    r = tf.dielectric_reflectance(np.linspace(1.1, 2, 6)[:, None], 0.5, [1, 0.5, 0.2],
                                  np.linspace(0, 900, 7), 1.4)
    assert r.shape == (6, 7, 3)
    assert tf.metal_reflectance(0.5, 1.0, 300.0, 1.5).shape == (3,)


GARBAGE = (np.nan, np.inf, -np.inf, -1.0, 0.0, 1e-30, 1e30, -1e30)


@pytest.mark.parametrize("version", VERSIONS)
def test_garbage_inputs_stay_finite(version):
    vals = np.array(list(itertools.product(GARBAGE, repeat=4)))
    a, b, c, d = vals.T
    with np.errstate(all="raise", under="ignore"):
        m = tf.metal_reflectance(a[:, None], b[:, None], c, d, version=version)
        g = tf.dielectric_reflectance(a, b, c[:, None], d, a, version=version)
    for out in (m, g):
        assert np.isfinite(out).all() and (out >= 0).all()
    assert (m <= 1).all()
    x, ok = tf.metal_base_for_reflectance(a[:64, None], b[:64, None], c[:64], d[:64],
                                          version=version)
    assert np.isfinite(x).all() and x.min() >= 0 and x.max() <= 1 and ok.dtype == bool
    io, ok = tf.dielectric_ior_for_reflectance(a[:64, None], b[:64], c[:64, None], d[:64],
                                               a[:64], version=version)
    assert np.isfinite(io).all() and io.min() >= 1
    t, ok = tf.dielectric_tint_for_reflectance(a[:64, None], b[:64], c[:64], d[:64], a[:64],
                                               version=version)
    assert np.isfinite(t).all() and t.min() >= 0


# ------------------------------------------------------------------------------------------------
# Inverses
# ------------------------------------------------------------------------------------------------


def _random_metal(n, seed):
    rng = np.random.default_rng(seed)
    return (rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1000, n),
            rng.uniform(1, 2.5, n))


@pytest.mark.parametrize("version", ["5.3", "4.5"])
def test_metal_inverse_round_trip(version):
    bc, tint, d, n = _random_metal(1500, 3)
    r = tf.metal_reflectance(bc, tint, d, n, version=version)
    x, ok = tf.metal_base_for_reflectance(r, tint, d, n, version=version)
    assert ok.all()
    assert np.abs(tf.metal_reflectance(x, tint, d, n, version=version) - r).max() <= 1e-10
    # with the true base colour as the hint it comes back (R need not be monotone in F0)
    x, ok = tf.metal_base_for_reflectance(r, tint, d, n, near=bc, version=version)
    assert ok.all() and np.abs(x - bc).max() <= 1e-9


def test_metal_inverse_unreachable():
    """Targets above the reachable maximum: the nearest reachable value, flagged."""
    x, ok = tf.metal_base_for_reflectance([1.0, 1.0, 1.0], 1.0, 450.0, 2.5)
    assert not ok.any()
    f = np.linspace(0, 1, 4001)[:, None] * np.ones(3)
    best = tf.metal_reflectance(f, 1.0, 450.0, 2.5).max(axis=0)
    got = tf.metal_reflectance(x, 1.0, 450.0, 2.5)
    assert np.all(got >= best - 1e-9)


def test_metal_inverse_non_monotone_picks_the_hint():
    """Where R(F0) is not monotone several F0 give the target: ``near`` chooses.  (300 nm,
    film IOR 2.5: red R(F0) falls from 0.62 at F0 = 0 to ~0.2 and rises again.)"""
    f = np.linspace(0, 1, 2001)
    r = tf.metal_reflectance(f[:, None] * np.ones(3), 1.0, 300.0, 2.5)[:, 0]
    target = 0.5 * (r[0] + r.min())
    crossings = f[1:][np.sign(r[1:] - target) != np.sign(r[:-1] - target)]
    assert crossings.size >= 2
    for c in crossings[[0, -1]]:
        x, ok = tf.metal_base_for_reflectance(target, 1.0, 300.0, 2.5, near=c)
        assert ok[0] and abs(x[0] - c) < 1e-3, (c, x)


@pytest.mark.parametrize("version", ["5.3", "4.5"])
def test_dielectric_inverse_round_trip(version):
    rng = np.random.default_rng(4)
    n = 800
    ior, lvl = rng.uniform(1.05, 3.0, n), rng.uniform(0.1, 1.0, n)
    tint, d, fi = rng.uniform(0.2, 1.5, (n, 3)), rng.uniform(0, 1000, n), rng.uniform(1, 2.5, n)
    r = tf.dielectric_reflectance(ior, lvl, tint, d, fi, version=version)
    got, ok = tf.dielectric_ior_for_reflectance(r, lvl, tint, d, fi, version=version)
    assert got.shape == (n, 3) and ok.all()
    back = np.stack([tf.dielectric_reflectance(got[:, c], lvl, tint, d, fi, version=version)[:, c]
                     for c in range(3)], axis=-1)
    assert np.abs(back - r).max() <= 1e-9
    got, ok = tf.dielectric_ior_for_reflectance(r, lvl, tint, d, fi, near=ior, version=version)
    assert ok.all() and np.abs(got - ior[:, None]).max() <= 1e-9
    w = np.array([0.2126, 0.7152, 0.0722])
    got, ok = tf.dielectric_ior_for_reflectance(r, lvl, tint, d, fi, weights=w, version=version)
    assert got.shape == (n,) and ok.all()
    back = tf.dielectric_reflectance(got, lvl, tint, d, fi, version=version) @ w
    assert np.abs(back - r @ w).max() <= 1e-9


def test_dielectric_tint_fixes_every_channel():
    """IOR from the luminance-weighted target, then Specular Tint per channel: all channels met."""
    target = tf.metal_reflectance([0.9, 0.5, 0.3], 1.0, 300.0, 1.4) * 0.1  # some colour
    w = np.array([0.2126, 0.7152, 0.0722])
    ior, ok = tf.dielectric_ior_for_reflectance(target, 0.5, 1.0, 300.0, 1.4, weights=w)
    assert ok
    tint, ok = tf.dielectric_tint_for_reflectance(target, ior, 0.5, 300.0, 1.4)
    assert ok.all()
    got = tf.dielectric_reflectance(ior, 0.5, tint, 300.0, 1.4)
    assert np.abs(got - target).max() <= 1e-12


def test_dielectric_inverse_unreachable():
    ior, ok = tf.dielectric_ior_for_reflectance([0.999] * 3, 0.5, 1.0, 200.0, 1.3)
    assert not ok.any() and np.isfinite(ior).all()
