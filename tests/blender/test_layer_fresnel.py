# SPDX-License-Identifier: GPL-3.0-or-later
"""White furnace for layered dielectrics: the Fresnel the haze mapping accounts for.

Cycles' Principled BSDF gives its dielectric specular lobe F_P = F0 + (1 - F0) s with
s = saturate((F_exact - F0) / (1 - F0)), i.e. F_P = max(F_exact, F0) for a white Specular Tint
(kernel/closure/bsdf_microfacet.h, generalized Schlick with exponent -η).  The project treats F_P
as the Fresnel of Eq. 1: the mapping only needs F(0) = r and F <= 1.  The coat lobe uses the
exact dielectric Fresnel (bsdf_microfacet_setup_fresnel_dielectric), and Cycles always adds
multiple-scattering energy compensation to it (even with distribution GGX): the coat case's
expected value includes that compensation (Kulla & Conty's formula, with exact integrals), and
how far it lies from the single-scattering Eq. 1 the coat's haze mapping assumes is recorded.

Set-up: a flat plane with a black base (no diffuse, no transmission), GGX, Specular Tint white,
an orthographic camera at view angle θ_o, a uniform white world of radiance 1 and no other light,
0 bounces.  Every pixel then estimates the directional albedo

    E(θ_o) = ∫ [(1 - β) f(α_n) + β f(α_w)] cos θ_i dω_i,   f = D G2 F / (4 cos θ_i cos θ_o),

which is evaluated here by deterministic quadrature (numpy, from the definitions: GGX D, Smith
height-correlated G2, Fresnel from Snell's law), with β, α_w and η from the paper's mapping as
transcribed in tests/pure/reference.py (mpmath; independent of hazy_gloss.core).  The renderer is
never asked: no expected value comes from the code under test.  Noise is measured, not assumed:
each case is rendered with several seeds and the spread of their means is reported and bounded.

Also recorded (out/measurements/layer_furnace.json): the albedo of Eq. 1 with the exact Fresnel
and single scattering, i.e. the deviation the product accepts by taking F_P as the model's
Fresnel (base) or by ignoring Cycles' coat energy compensation (coat).
"""
import functools
import importlib
import math
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes
from measurements import record

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "pure"))
import reference as R  # noqa: E402  (the paper's mapping in mpmath)

VIEWS = (0.0, 30.0, 60.0, 80.0)
SEEDS = (0, 1, 2, 3)
SAMPLES = 64
RESOLUTION = (64, 64)  # 4096 pixels x 64 samples x 4 seeds per view
TOLERANCE = 1e-3  # |mean pixel - E| (absolute; E is an albedo in [0, 1])
NOISE_MAX = 2e-4  # the measured standard error of the mean must stay well below TOLERANCE
CORE_IOR = 1.5  # r_c = F0(1.5) = 0.04

#: name -> (Principled inputs, haze keywords, which lobe hazes: "base" or "coat")
CASES = {
    "dielectric h=0.3": ({"Roughness": 0.3}, dict(haziness=0.3, haze_extent=5.0), "base"),
    "dielectric h=0.6": ({"Roughness": 0.3}, dict(haziness=0.6, haze_extent=5.0), "base"),
    "dielectric h=0.9": ({"Roughness": 0.3}, dict(haziness=0.9, haze_extent=5.0), "base"),
    "dielectric h=0.9, R=0.1, extent 10": ({"Roughness": 0.1}, dict(haziness=0.9, haze_extent=10.0),
                                            "base"),
    "coat only h=0.9": ({"Roughness": 0.5, "Specular IOR Level": 0.0, "Coat Weight": 1.0,
                         "Coat Roughness": 0.1, "Coat IOR": CORE_IOR},
                        dict(coat_haziness=0.9, coat_haze_extent=5.0), "coat"),
}


# --------------------------------------------------------------------------------------------
# The reference: directional albedo by quadrature (no project code)
# --------------------------------------------------------------------------------------------


def fresnel_exact(c, eta):
    """Unpolarised Fresnel reflectance of a dielectric of relative IOR eta > 1 seen from outside,
    at cos θ = c: Snell's law for the refracted cosine, then (R_s + R_p) / 2."""
    c = np.clip(c, 0.0, 1.0)
    ct = np.sqrt(np.maximum(1.0 - (1.0 - c * c) / (eta * eta), 0.0))
    rs = (c - eta * ct) / (c + eta * ct)
    rp = (eta * c - ct) / (eta * c + ct)
    return 0.5 * (rs * rs + rp * rp)


def f0_of(eta):
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def principled_fresnel(c, eta):
    """F_P: the exact Fresnel, never below its value at normal incidence."""
    return np.maximum(fresnel_exact(c, eta), f0_of(eta))


def _smith_lambda(alpha, cos):
    tan2 = np.maximum(1.0 / (cos * cos) - 1.0, 0.0)
    return 0.5 * (np.sqrt(1.0 + alpha * alpha * tan2) - 1.0)


def albedo(theta_o_deg, alpha, fresnel, n_xi=600, n_phi=384):
    """E(θ_o) = ∫ f cos θ_i dω_i of an isotropic GGX lobe with Fresnel ``fresnel(cos θ_d)``.

    Over the half vector h: f cos θ_i dω_i = D(h) G2 F (o·h) / cos θ_o dω_h, and
    D(h) cos θ_h dω_h = dξ dφ / 2π with tan² θ_h = α² ξ / (1 - ξ).  Gauss-Legendre in t with
    ξ = 1 - (1 - t)² (nodes denser towards grazing h), midpoint rule in φ (periodic).  At the
    defaults the result changes by < 2e-6 when both counts are halved."""
    to = math.radians(theta_o_deg)
    wo = np.array([math.sin(to), 0.0, math.cos(to)])
    x, w = np.polynomial.legendre.leggauss(n_xi)
    t = 0.5 * (x + 1.0)
    xi = 1.0 - (1.0 - t) ** 2
    dxi = 2.0 * (1.0 - t) * 0.5 * w
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2.0 * np.pi
    tan2 = alpha * alpha * xi / (1.0 - xi)
    ch = 1.0 / np.sqrt(1.0 + tan2)
    sh = np.sqrt(tan2) * ch
    h = np.stack([sh[:, None] * np.cos(phi)[None], sh[:, None] * np.sin(phi)[None],
                  np.broadcast_to(ch[:, None], (n_xi, n_phi))], -1)
    oh = h @ wo
    ci = (2.0 * oh[..., None] * h - wo)[..., 2]
    ok = (ci > 0.0) & (oh > 0.0)
    g2 = 1.0 / (1.0 + _smith_lambda(alpha, np.where(ok, ci, 1.0)) + _smith_lambda(alpha, wo[2]))
    val = np.where(ok, g2 * fresnel(np.clip(oh, 0.0, 1.0)) * oh / (wo[2] * ch[:, None]), 0.0)
    return float((val.mean(1) * dxi).sum())


def paper_mapping(roughness, haziness, extent):
    """β, α_n, α_w, η of a dielectric with r_c = F0(CORE_IOR), from the paper (mpmath)."""
    alpha = roughness ** 2
    m = R.haze_mapping(f0_of(CORE_IOR), 0.0, alpha, haziness, extent)
    return dict(beta=float(m["beta"]), alpha=alpha, alpha_wide=float(m["alpha_wide"][0]),
                eta=float(m["dielectric_ior"]))


def coat_under_multiscatter(lobes):
    """The coat's η under Cycles' energy compensation (mapping.md §11): the mapping's β, and
    the F(0) = r that keeps the normal-incidence peak, r [(1-β) S_n + β p S_w] = r_c S_0, each
    S this file's quadrature of the compensation (bisection in r)."""
    rc, b = f0_of(CORE_IOR), lobes["beta"]
    p = (lobes["alpha"] / lobes["alpha_wide"]) ** 2

    def eta(r):
        s = math.sqrt(r)
        return (1 + s) / (1 - s)

    target = rc * energy_compensation(0.0, lobes["alpha"], CORE_IOR)
    lo, hi = rc, 1.0 - 1e-12
    for _ in range(60):
        r = 0.5 * (lo + hi)
        e = eta(r)
        peak = r * ((1 - b) * energy_compensation(0.0, lobes["alpha"], e)
                    + b * p * energy_compensation(0.0, lobes["alpha_wide"], e))
        lo, hi = (r, hi) if peak < target else (lo, r)
    return dict(lobes, eta=eta(0.5 * (lo + hi)))


def _white(c):
    return np.ones_like(c)


@functools.lru_cache(maxsize=None)
def average_albedo(alpha, n_mu=24):
    """E_avg(α) = ∫ 2μ E(μ) dμ of the white lobe (μ = t², Gauss-Legendre in t)."""
    x, w = np.polynomial.legendre.leggauss(n_mu)
    t = 0.5 * (x + 1.0)
    return float(sum(0.5 * wk * 4.0 * tk ** 3 * albedo(math.degrees(math.acos(tk * tk)), alpha,
                                                       _white, n_xi=200, n_phi=128)
                     for tk, wk in zip(t, w)))


@functools.lru_cache(maxsize=None)
def average_fresnel(eta, n=400):
    """F_ss = ∫ 2μ F(μ) dμ (the hemispherical average of the exact Fresnel)."""
    x, w = np.polynomial.legendre.leggauss(n)
    mu = 0.5 * (x + 1.0)
    return float(np.sum(0.5 * w * 2.0 * mu * fresnel_exact(mu, eta)))


def energy_compensation(theta, alpha, eta):
    """Cycles' coat is GGX with multiple-scattering energy compensation and multi-bounce Fresnel
    (Kulla & Conty 2017, appendix; kernel/closure/bsdf_microfacet.h
    microfacet_ggx_preserve_energy): the single-scattering lobe times
    1 + F_ms (1 - E(μ_o)) / E(μ_o), F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)).  Here E, E_avg
    and F_ss are the exact integrals (Cycles reads E and E_avg from tables and F_ss from a fit)."""
    e = albedo(theta, alpha, _white)
    e_avg = average_albedo(alpha)
    fss = average_fresnel(eta)
    fms = fss * e_avg / (1.0 - fss * (1.0 - e_avg))
    return 1.0 + fms * (1.0 - e) / e


def expected(theta, lobes, fresnel, compensated=False):
    """The pixel value Eq. 1 predicts: (1 - β) E(α_n) + β E(α_w) with the lobes' Fresnel;
    ``compensated``: each lobe times Cycles' coat energy compensation."""
    b = lobes["beta"]
    out = 0.0
    for weight, a in ((1.0 - b, lobes["alpha"]), (b, lobes["alpha_wide"])):
        e = albedo(theta, a, fresnel)
        if compensated:
            e *= energy_compensation(theta, a, lobes["eta"])
        out += weight * e
    return out


def test_reference_quadrature_is_converged():
    """The quadrature itself: halving the node counts changes E by < 1e-5, and with F = 1 it
    reproduces the GGX white-furnace albedo of tests/pure/ggx_albedo.py (another quadrature)."""
    import ggx_albedo
    fp = lambda c: principled_fresnel(c, 39.6)  # noqa: E731
    for theta in VIEWS:
        for a in (0.01, 0.09, 0.54):
            full = albedo(theta, a, fp)
            half = albedo(theta, a, fp, n_xi=300, n_phi=192)
            assert abs(full - half) < 1e-5, (theta, a, full, half)
            white = albedo(theta, a, lambda c: np.ones_like(c))
            assert abs(white - ggx_albedo.albedo(math.cos(math.radians(theta)), a)) < 1e-5


# --------------------------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------------------------


def _material(inputs):
    mat = scenes.new_material("Furnace")
    b = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    b.distribution = "GGX"
    values = {"Base Color": (0.0, 0.0, 0.0, 1.0), "Metallic": 0.0, "IOR": CORE_IOR,
              "Specular IOR Level": 0.5, "Specular Tint": (1.0, 1.0, 1.0, 1.0),
              "Transmission Weight": 0.0, "Coat Weight": 0.0, "Sheen Weight": 0.0}
    values.update(inputs)
    for k, v in values.items():
        b.inputs[k].default_value = v
    return mat


def _furnace(mat, theta):
    scenes.setup_render("CYCLES", samples=SAMPLES, resolution=RESOLUTION, bounces=0)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    info = scenes.flat_plane_scene(mat, view_dir=(theta, 0.0))
    bpy.data.objects.remove(info["sun"])  # only the world lights the plane
    scenes.uniform_world(1.0)
    means, stds = [], []
    for seed in SEEDS:
        bpy.context.scene.cycles.seed = seed
        img = scenes.render_exr()[..., :3].astype(np.float64)
        means.append(float(img.mean()))
        stds.append(float(img.std()))
    means = np.asarray(means)
    return dict(mean=float(means.mean()),
                # the standard error of the mean of the seeds' means (measured)
                noise=float(means.std(ddof=1) / math.sqrt(len(SEEDS))),
                # what independent pixels would give (Cycles' samples are stratified across
                # pixels, so the measured noise is far lower)
                noise_iid=float(np.mean(stds) / math.sqrt(RESOLUTION[0] * RESOLUTION[1]
                                                           * len(SEEDS))))


@pytest.mark.parametrize("name", list(CASES))
def test_layered_dielectric_albedo_in_a_white_furnace(hg, clean_file, name):
    api = importlib.import_module(hg.__name__ + ".api")
    inputs, haze, lobe = CASES[name]
    mat = _material(inputs)
    api.make_hazy(mat, **haze)
    if lobe == "base":
        lobes = paper_mapping(inputs["Roughness"], haze["haziness"], haze["haze_extent"])
        fresnel = lambda c: principled_fresnel(c, lobes["eta"])  # noqa: E731
    else:
        # the coat is always energy-compensated: the paper's β, its F(0) raised to keep the
        # peak under the compensation
        lobes = coat_under_multiscatter(paper_mapping(
            inputs["Coat Roughness"], haze["coat_haziness"], haze["coat_haze_extent"]))
        fresnel = lambda c: fresnel_exact(c, lobes["eta"])  # noqa: E731  (Cycles' coat)
    exact = lambda c: fresnel_exact(c, lobes["eta"])  # noqa: E731
    coat = lobe == "coat"
    rows = {}
    worst = 0.0
    for theta in VIEWS:
        got = _furnace(mat, theta)
        want = expected(theta, lobes, fresnel, compensated=coat)
        # Eq. 1 as the mapping assumes it: single scattering, the exact Fresnel
        want_exact = expected(theta, lobes, exact)
        err = got["mean"] - want
        rows[f"{theta:g} deg"] = dict(render=got["mean"], expected=want, error=err,
                                      noise=got["noise"], noise_iid_bound=got["noise_iid"],
                                      albedo_exact_fresnel=want_exact,
                                      accepted_deviation=want - want_exact)
        assert got["noise"] <= NOISE_MAX, (theta, got)
        assert abs(err) <= TOLERANCE, (theta, got, want)
        worst = max(worst, abs(err))
    record("layer_furnace", {name: dict(eta=lobes["eta"], beta=lobes["beta"],
                                        alpha=lobes["alpha"], alpha_wide=lobes["alpha_wide"],
                                        worst_error=worst, views=rows)})
