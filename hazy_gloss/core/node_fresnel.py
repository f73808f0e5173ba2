# SPDX-License-Identifier: GPL-3.0-or-later
"""Conductor Fresnel as node math: Gulbrandsen's (r, g) <-> (η, κ) on a
:class:`hazy_gloss.core.graph.Graph` (the numpy forms are core.mapping's ``gulbrandsen_ior``
and ``gulbrandsen_inverse``).  Shared by the haze mapping (core.node_math), its Multiscatter GGX
correction (core.node_multiscatter) and the haze layer (core.layer_graph).
"""
from __future__ import annotations

from .. import constants as K

__all__ = ("TINY", "gulbrandsen", "gulbrandsen_inverse")

#: 2^-23: 1 - r is kept >= this (r <= 1 - ε) where it divides.
TINY = 1.0 - K.ONE_MINUS_ULP32


def gulbrandsen(g, r, omr_v, edge_tint):
    """Gulbrandsen 2014 (η, κ) from r, 1 - r and g per channel, κ in non-negative terms
    (docs/mapping.md §7): with A = g/(1+r) and B = (1-g)(1+√r)²/(1-r),
    η = A (1-r) + B and κ = 2 √(r A (A + 2 B/(1-r)))."""
    gt = g.vclamp01(edge_tint, label="g")
    s = g.vsqrt(r, label="√r")
    opr = g.vmath("ADD", r, 1.0)
    a = g.vmath("DIVIDE", gt, opr, label="A = g/(1+r)")
    ops2 = g.vmath("MULTIPLY_ADD", s, 2.0, opr, label="(1+√r)² = 2√r + 1 + r")
    b = g.vmath("DIVIDE", g.vmix(gt, ops2, 0.0), omr_v, label="B")  # (1-g) (1+√r)² / (1-r)
    eta = g.vmath("MULTIPLY_ADD", a, omr_v, b, label="η")
    inner = g.vmul(a, g.vmath("MULTIPLY_ADD", g.vmath("DIVIDE", b, omr_v), 2.0, a))
    kappa = g.vmul(2.0, g.vsqrt(g.vmul(inner, r)), label="κ")
    return eta, kappa


def gulbrandsen_inverse(g, eta, kappa):
    """(r, g) per channel from (η, κ) (core.mapping.gulbrandsen_inverse):
    r = ((η-1)² + κ²)/((η+1)² + κ²), g = (n_d - η)/(n_d - n_m) with n_d = (1+√r)²/(1-r) and
    n_m = (1-r)/(1+r); η, κ < 0 read as 0 (the Metallic BSDF clamps them)."""
    eta = g.vmath("MAXIMUM", eta, 0.0)
    k2 = g.vmath("MULTIPLY", kappa, kappa)
    em, ep = g.vmath("SUBTRACT", eta, 1.0), g.vmath("ADD", eta, 1.0)
    num = g.vmath("MULTIPLY_ADD", em, em, k2)
    den = g.vmath("MULTIPLY_ADD", ep, ep, k2)
    r = g.vmath("MINIMUM", g.vmath("DIVIDE", num, den), K.ONE_MINUS_ULP32, label="r")
    # 1 - r = 4η / ((η+1)² + κ²): no cancellation
    omr = g.vmath("MAXIMUM", g.vmath("DIVIDE", g.vmath("SCALE", eta, 4.0), den), TINY)
    ops = g.vmath("ADD", g.vsqrt(r), 1.0)
    n_d = g.vmath("DIVIDE", g.vmath("MULTIPLY", ops, ops), omr)
    n_m = g.vmath("DIVIDE", omr, g.vmath("ADD", r, 1.0))
    tint = g.vmath("DIVIDE", g.vmath("SUBTRACT", n_d, eta), g.vmath("SUBTRACT", n_d, n_m))
    return r, g.vclamp01(tint, label="g")
