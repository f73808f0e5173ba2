# SPDX-License-Identifier: GPL-3.0-or-later
"""A thin film's reflectance on a dielectric at normal incidence as node math (no bpy):
core.thin_film's dielectric model written against core.graph, so that a haze layer can raise
the F(0) of a filmed Principled specular through its Specular Tint exactly, for whatever feeds
the node (docs/thin-film.md, docs/mapping.md §13).

At normal incidence both polarizations are the same: R12 = ((n_f - 1)/(n_f + 1))²,
R23 = ((η/n_f - 1)/(η/n_f + 1))², the phasor is the real sign φ = -sign(1 - η/n_f) sign(1 - n_f)
(sign(0) = 1), OPD = 2 n_f d, and Cycles' Airy sum (iridescence_airy_summation_channel, m <= 3)
is, per channel,

    F = R12 + R_s + Σ_m 2 C_m φ^m S(m OPD),   R_s = (1 - R12)² R23 / (1 - R12 R23),
    C_m = (R_s - (1 - R12)) (R12 R23)^(m/2),

clamped to [0, 1].  S is the sensitivity's real part: 5.x reads it from the scene's LUT
(an RGB image here, the Linear Rec.709 table; core.thin_film builds it as Cycles does), 4.5
evaluates Belcour & Barla's Gaussian fit, whose shift m·π(…) is the same φ^m, converted to RGB
as Cycles does (M (S_xyz ⊙ M⁻¹ 1)), read here from a finer table of it
(core.thin_film.gauss_table): so both generations are this one sum.  The film IOR is
blended towards 1 below 1 nm (5.x) or 30 nm (4.5).
"""
from __future__ import annotations

import numpy as np

from . import thin_film as _tf

__all__ = ("dielectric_film", "THICKNESS_CUTOFF")

THICKNESS_CUTOFF = _tf.THICKNESS_CUTOFF


def _sign(g, x):
    """1 where x >= 0, else -1 (the sign of a Fresnel amplitude, as core.thin_film)."""
    return g.madd(g.less(x, 0.0), -2.0, 1.0)


def _sensitivity(g, name, table, opd, opd_per_u):
    """A sensitivity table's entry at ``opd`` (nm), per channel: entry i sits at OPD
    i opd_per_u, so u = (OPD / opd_per_u + ½) / n (texel centres; g.table clamps to them)."""
    n = table.shape[1]
    return g.table(name, table.T[None, :, :], g.madd(opd, 1.0 / (opd_per_u * n), 0.5 / n), 0.5)


def _lut_sensitivity(g, opd, working_space):
    """5.x: the LUT's real part, lookup_table_read at x = 2π OPD / 60000 nm (512 entries)."""
    table = _tf.sensitivity_table(working_space, version=(5, 3))[0]  # (3, 512) re
    return _sensitivity(g, f"thin film LUT {working_space}", table, opd,
                        60000.0 / (2.0 * np.pi * (table.shape[1] - 1)))


def _gauss_sensitivity(g, opd):
    """4.5: its Gaussian fit at shift 0 in RGB, from a table (core.thin_film.gauss_table:
    four Gaussians per order cost 28 nodes, a lookup 9)."""
    table = _tf.gauss_table()
    return _sensitivity(g, "thin film Gaussian fit", table, opd,
                        _tf.GAUSS_OPD_MAX / (table.shape[1] - 1))


def _smoothstep(g, x, e1):
    """smoothstep(0, e1, x) = (3 - 2t) t², t = clamp(x / e1, 0, 1)."""
    t = g.clamp(g.div(x, e1), 0.0, 1.0)
    return g.mul(g.madd(t, -2.0, 3.0), g.mul(t, t))


def dielectric_film(g, thickness, film_ior, eta, *, version=None, working_space="Linear Rec.709"):
    """F(0) per channel (a vector in [0, 1]) of a film of ``thickness`` nm and ``film_ior`` on a
    dielectric of IOR ``eta`` (the closure's: Principled's specular has Specular IOR Level
    applied), before Cycles' F0 scaling by the tint (generalized_schlick_fresnel)."""
    gauss = _tf.generation(version) == "GAUSS"
    d = g.at_least(thickness, 0.0)
    n_f = g.at_least(film_ior, 1e-5)
    blend = 30.0 if gauss else 1.0
    film = g.select(g.less(d, blend), g.madd(g.sub(n_f, 1.0), _smoothstep(g, d, blend), 1.0), n_f)
    r12 = g.math("POWER", g.div(g.sub(film, 1.0), g.add(film, 1.0)), 2.0)
    e23 = g.div(g.at_least(eta, 1e-5), film)
    r23 = g.math("POWER", g.div(g.sub(e23, 1.0), g.add(e23, 1.0)), 2.0)
    phasor = g.mul(g.mul(_sign(g, g.sub(1.0, e23)), _sign(g, g.sub(1.0, film))), -1.0)
    opd = g.mul(g.mul(film, d), 2.0)
    t121 = g.sub(1.0, r12)
    r123 = g.mul(r12, r23)
    sq = g.sqrt(r123)
    rs = g.div(g.mul(g.mul(t121, t121), r23), g.at_least(g.sub(1.0, r123), 1e-30))
    out = g.add(rs, r12)
    cm = g.sub(rs, t121)
    total = None
    for m in (1, 2, 3):
        cm = g.mul(cm, sq)
        coef = g.mul(g.mul(cm, 2.0), phasor if m % 2 else 1.0)
        o = g.mul(opd, float(m))
        s = _gauss_sensitivity(g, o) if gauss else _lut_sensitivity(g, o, working_space)
        term = g.vmath("SCALE", s, coef)
        total = term if total is None else g.vmath("ADD", total, term)
    return g.vclamp01(g.vmath("ADD", total, out), label="film F(0)")
