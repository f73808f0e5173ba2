# SPDX-License-Identifier: GPL-3.0-or-later
"""Independent reference for the layering albedo of the Principled specular: deterministic
quadrature (no Monte Carlo, no table), for tests/pure/test_body_colour.py.

The quantity Cycles tabulates as ggx_gen_schlick_ior_s (cycles_precompute.cpp: importance
sampling of GGX visible normals, a sample counting 0 when the reflected direction is below the
horizon, the mean of the per-sample ratio eval.x / eval.y of a Fresnel with f0 = (0, 1),
f90 = (1, 1)) is

    s(μ, α, η) = ∫ D_i(h) s_F(i·h) [o_z > 0] dω_h,    D_i = G1(i) (i·h) D(h) / μ,
    s_F(c) = saturate((F_dielectric(c, η) - F0(η)) / (1 - F0(η))),

the mean over visible normals of the remapped real Fresnel.  The GGX BRDF's own albedo with the
generalized Schlick Fresnel F = f0 + (1 - f0) s_F is instead

    R(μ) = ∫ D_i(h) (G2(i, o) / G1(i)) F(i·h) [o_z > 0] dω_h = f0 E(μ) + (1 - f0) ∫ D_i G2/G1 s_F

(E the single-scatter albedo): Cycles' estimate f0 + (1 - f0) s assumes an energy-conserving
microfacet model (G2/G1 -> 1).  Both are integrated here with the parametrisation of
ggx_albedo.py (half vector by u = tan²θ_h / (α² + tan²θ_h), horizon as the upper limit).
"""
import numpy as np

from ggx_albedo import _panels, _smith_lambda


def fresnel_dielectric(c, eta):
    """Unpolarised dielectric Fresnel reflectance (textbook form, ambient index 1)."""
    c = np.abs(np.asarray(c, np.float64))
    g2 = eta * eta - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
        f = 0.5 * a * a * (1.0 + b * b)
    return np.where(g2 > 0.0, np.where(np.isfinite(f), f, 1.0), 1.0)


def remapped_fresnel(c, eta):
    """s_F(c) = saturate((F(c, η) - F0) / (1 - F0)): the Principled's generalized Schlick
    interpolation weight at the microfacet cosine c."""
    f0 = ((eta - 1.0) / (eta + 1.0)) ** 2
    return np.clip((fresnel_dielectric(c, eta) - f0) / (1.0 - f0), 0.0, 1.0)


def _half_vector_quadrature(mu, alpha, n, panels):
    """Nodes (i·h, G1(i), G2(i, o)) and weights of ∫ D_i(h) g [o_z > 0] dω_h."""
    s = np.sqrt(max(1.0 - mu * mu, 0.0))
    p1, w1 = _panels(0.0, 0.5 * np.pi, n, panels)
    phi, wphi = np.concatenate([p1, np.pi - p1]), np.concatenate([w1, w1])
    delta = np.arctan2(s * np.cos(phi), mu)
    t2max = np.tan(0.5 * (delta + 0.5 * np.pi)) ** 2
    vmax = np.sqrt(t2max / (alpha * alpha + t2max))
    x, wx = _panels(0.0, 1.0, n, panels)
    v = vmax[:, None] * x[None, :]
    wv = vmax[:, None] * wx[None, :]
    u = v * v
    tan_h = alpha * np.sqrt(u / (1.0 - u))
    cos_h = 1.0 / np.sqrt(1.0 + tan_h * tan_h)
    sin_h = tan_h * cos_h
    hx, hy, hz = sin_h * np.cos(phi)[:, None], sin_h * np.sin(phi)[:, None], cos_h
    ih = s * hx + mu * hz
    ox, oy, oz = 2.0 * ih * hx - s, 2.0 * ih * hy, 2.0 * ih * hz - mu
    lam_i = _smith_lambda(alpha * alpha * s * s / (mu * mu))
    with np.errstate(divide="ignore", invalid="ignore"):
        lam_o = _smith_lambda(alpha * alpha * (ox * ox + oy * oy) / (oz * oz))
        g2 = np.where(oz > 0, 1.0 / (1.0 + lam_i + lam_o), 0.0)
    g1 = 1.0 / (1.0 + lam_i)
    # D_i dω_h = G1 (i·h) / (μ cos θ_h) · du dφ / 2π; φ over [0, π] twice (even integrand)
    weight = np.where(oz > 0, wphi[:, None] * wv * 2.0 * v * ih / (mu * cos_h) / np.pi, 0.0)
    return ih, g1, g2, weight


def s_mean(mu, alpha, eta, n=16, panels=10):
    """s(μ, α, η): the mean of s_F over visible normals, horizon-cut (the tabulated quantity).
    A mirror (α² < 1e-12) gives s_F(μ)."""
    mu, alpha, eta = float(mu), float(alpha), float(eta)
    if eta == 1.0:  # F = F0 = 0: s_F = 0 (the generator's float32 value)
        return 0.0
    if alpha * alpha < 1e-12:
        return float(remapped_fresnel(mu, eta))
    ih, g1, _, w = _half_vector_quadrature(mu, alpha, n, panels)
    return float(np.sum(w * g1 * remapped_fresnel(ih, eta)))


def brdf_albedo(mu, alpha, eta, f0, n=16, panels=10):
    """R(μ): the GGX BRDF's directional albedo with F = f0 + (1 - f0) s_F (single scattering,
    height-correlated Smith)."""
    mu, alpha, eta = float(mu), float(alpha), float(eta)
    if alpha * alpha < 1e-12:
        return float(f0 + (1.0 - f0) * remapped_fresnel(mu, eta))
    ih, _, g2, w = _half_vector_quadrature(mu, alpha, n, panels)
    return float(np.sum(w * g2 * (f0 + (1.0 - f0) * remapped_fresnel(ih, eta))))


def ior_from_f0(f0, dtype=np.float64):
    """cycles_precompute's ior_from_F0 (F0 clamped to <= 0.99) in ``dtype``.  The 4.5/5.2
    table was made in float32, where z = 0 gives η = 1 exactly (F0 = 1e-16, √F0 = 1e-8 vanishes
    against 1: s = 0 on that slice); the 5.3 table's z = 0 slice matches η = 1 + 2e-8, i.e. the
    same formula without that rounding (s -> 1 at grazing there)."""
    one = dtype(1.0)
    q = np.sqrt(np.clip(dtype(f0), dtype(0.0), dtype(0.99)))
    return float((one + q) / (one - q))


def table_node(i, j, k, n, sqrt_mu):
    """(μ, α, η) of table node (x = i, y = j, z = k) of an n³ table, as cycles_precompute
    places it: roughness and y clamped to >= 1e-4, z to [1e-4, 0.99], η = ior_from_F0(z⁴);
    4.5/5.2 (``sqrt_mu`` False): μ = y, η in float32; 5.3: μ = y², η without rounding."""
    r = max(i / (n - 1), 1e-4)
    y = max(j / (n - 1), 1e-4)
    z = min(max(k / (n - 1), 1e-4), 0.99)
    return (y * y if sqrt_mu else y), r * r, ior_from_f0(z ** 4, np.float64 if sqrt_mu else np.float32)
