# SPDX-License-Identifier: GPL-3.0-or-later
"""Independent reference for Cycles' Multiscatter GGX tables: the single-scatter GGX albedo by
deterministic quadrature (no Monte Carlo, no table), for tests/pure/test_multiscatter.py.

    E(μ, α) = ∫ f_ss(i, o) cos θ_o dω_o,   f_ss = D(h) G2(i, o) / (4 μ cos θ_o),  F = 1,

GGX D, height-correlated Smith G2 = 1 / (1 + Λ(i) + Λ(o)), Λ(ω) = (√(1 + α² tan²θ) - 1) / 2.
Integrated over the half vector: dω_o = 4 (i·h) dω_h and D(h) cos θ_h dω_h = du dφ / 2π with
tan²θ_h = α² u / (1 - u) (the GGX distribution of θ_h), so

    E = (1/2π) ∫ dφ ∫ du  G2 (i·h) / (μ cos θ_h)   over o = 2(i·h)h - i above the horizon.

With i = (sin θ_i, 0, μ), o_z = A cos(2θ_h - δ), δ = atan2(sin θ_i cos φ, μ): the horizon is the
integration limit θ_h < (δ + π/2)/2, not a discontinuity.  u = v² removes the √u behaviour at
u = 0; Gauss-Legendre panels are graded towards the limit.  At μ = 1 (i = n) the φ integral is
trivial: E(1, α) = ∫_0^{1/(1+α²)} du / (1 + Λ(o)), θ_o = 2θ_h.
E_avg(α) = ∫ 2μ E(μ, α) dμ, with μ = t² (the grazing end is steep in μ).
"""
import numpy as np


def _smith_lambda(a2_tan2):
    return 0.5 * (np.sqrt(1.0 + a2_tan2) - 1.0)


def _panels(a, b, n, count, ratio=0.25):
    """Composite Gauss-Legendre nodes and weights on [a, b], panels shrinking towards b."""
    x, w = np.polynomial.legendre.leggauss(n)
    edges = [a] + [b - (b - a) * ratio ** k for k in range(1, count)] + [b]
    nodes = [lo + 0.5 * (hi - lo) * (x + 1.0) for lo, hi in zip(edges[:-1], edges[1:])]
    weights = [0.5 * (hi - lo) * w for lo, hi in zip(edges[:-1], edges[1:])]
    return np.concatenate(nodes), np.concatenate(weights)


def albedo_normal(alpha, n=48, panels=12):
    """E(1, α): view along the normal (converged to ~1e-15; mpmath agrees)."""
    a2 = float(alpha) ** 2
    if a2 < 1e-12:  # E = 1 - O(α²); the end of the u range is not representable
        return 1.0
    v, wv = _panels(0.0, np.sqrt(1.0 / (1.0 + a2)), n, panels)
    u = v * v
    t2h = a2 * u / (1.0 - u)  # tan² θ_h
    t2o = 4.0 * t2h / (1.0 - t2h) ** 2  # tan² 2θ_h
    return float(np.sum(wv * 2.0 * v / (1.0 + _smith_lambda(a2 * t2o))))


def albedo(mu, alpha, n=16, panels=10):
    """E(μ, α) for 0 < μ <= 1 (converged to ~1e-8 for μ >= 1e-4 at the defaults)."""
    mu, a = float(mu), float(alpha)
    if mu >= 1.0:
        return albedo_normal(a)
    s = np.sqrt(1.0 - mu * mu)
    # φ in [0, π] (the integrand is even in φ), graded towards φ = π/2 where the cut is lowest
    p1, w1 = _panels(0.0, 0.5 * np.pi, n, panels)
    phi, wphi = np.concatenate([p1, np.pi - p1]), np.concatenate([w1, w1])
    delta = np.arctan2(s * np.cos(phi), mu)
    t2max = np.tan(0.5 * (delta + 0.5 * np.pi)) ** 2
    vmax = np.sqrt(t2max / (a * a + t2max))  # v = √u at θ_h = θ_max
    x, wx = _panels(0.0, 1.0, n, panels)
    v = vmax[:, None] * x[None, :]
    wv = vmax[:, None] * wx[None, :]
    u = v * v
    tan_h = a * np.sqrt(u / (1.0 - u))
    cos_h = 1.0 / np.sqrt(1.0 + tan_h * tan_h)
    sin_h = tan_h * cos_h
    hx, hy, hz = sin_h * np.cos(phi)[:, None], sin_h * np.sin(phi)[:, None], cos_h
    ih = s * hx + mu * hz
    ox, oy, oz = 2.0 * ih * hx - s, 2.0 * ih * hy, 2.0 * ih * hz - mu
    with np.errstate(divide="ignore", invalid="ignore"):
        lam_o = _smith_lambda(a * a * (ox * ox + oy * oy) / (oz * oz))
        g2 = np.where(oz > 0, 1.0 / (1.0 + _smith_lambda(a * a * s * s / (mu * mu)) + lam_o), 0.0)
    f = np.where(oz > 0, g2 * ih / (mu * cos_h) * 2.0 * v, 0.0)
    return float(np.sum(wphi[:, None] * wv * f) / np.pi)


def albedo_average(alpha, n_mu=20, **kw):
    """E_avg(α) = ∫_0^1 2μ E(μ, α) dμ = ∫_0^1 4t³ E(t², α) dt (defaults: within 1e-8 of a
    run with twice the nodes)."""
    t, w = np.polynomial.legendre.leggauss(n_mu)
    t = 0.5 * (t + 1.0)
    return float(sum(0.5 * wi * 4.0 * ti ** 3 * albedo(max(ti * ti, 1e-12), alpha, **kw)
                     for ti, wi in zip(t, w)))
