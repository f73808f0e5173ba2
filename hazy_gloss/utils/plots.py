# SPDX-License-Identifier: GPL-3.0-or-later
"""Preview plots for the material panel, rasterised with numpy (bpy-free).

Two pictures, both returned as float32 RGBA arrays shaped (H, W, 4) with row 0 at the BOTTOM
(Blender's pixel order, so ``pixels.foreach_set(img.ravel())`` needs no flip):

- :func:`haze_plot`: the paper's Figure 3 (left): haze intensity k_h at θ_d = 0 against the core
  reflectivity r_c, with the positivity bound P (k_h <= r_c / p) and the energy bound E
  (k_h <= (1 - r_c) / (1 - p)) in red, the curve of the current haziness β_h (Eq. 7, or the
  Bézier of Eqs. 12-15 when a smoothness w is given) in white and the current material as a dot.
- :func:`brdf_plot`: a slice of the BRDF in the plane of incidence (the paper's Figure 2, right
  column): core F_c f_n (magenta), halo K_h g_h with g_h = f_w - p f_n (cyan) and their sum,
  the composite BRDF of Eq. 1 (red).  :func:`brdf_slice` returns the numbers.

Colours are display values (sRGB-encoded, what an icon shows); :func:`srgb_to_linear` converts
for a float image data-block, whose pixels are scene-linear.

Everything is computed from ``hazy_gloss.core`` (the same haze mapping the materials use).
"""
from __future__ import annotations

import numpy as np

from ..core import haze_intensity
from ..core.lobes import describe
from ..core.parameters import PARAMETERS, is_anisotropic, normalise

__all__ = ("Canvas", "haze_plot", "brdf_at", "brdf_slice", "brdf_plot", "srgb_to_linear",
           "mapping_for", "COLOURS")

#: Display colours (sRGB-encoded RGBA).
COLOURS = {
    "background": (0.17, 0.17, 0.17, 1.0),
    "frame": (0.55, 0.55, 0.55, 1.0),
    "grid": (0.26, 0.26, 0.26, 1.0),
    "bound": (0.90, 0.22, 0.20, 1.0),  # red: P and E (Figure 3)
    "curve": (0.95, 0.95, 0.95, 1.0),  # current β_h line
    "point": (1.00, 0.80, 0.15, 1.0),
    "total": (0.92, 0.25, 0.22, 1.0),  # red: f_r (Figure 2)
    "core": (0.85, 0.30, 0.85, 1.0),  # magenta: F_c f_n
    "halo": (0.25, 0.85, 0.90, 1.0),  # cyan: K_h g_h
    "mirror": (0.45, 0.45, 0.45, 1.0),
}


def srgb_to_linear(rgba):
    """sRGB-encoded display values -> linear (alpha untouched)."""
    out = np.array(rgba, dtype=np.float32, copy=True)
    c = out[..., :3]
    out[..., :3] = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return out


# --------------------------------------------------------------------------------------------
# A tiny anti-aliased rasteriser (supersampled coverage masks, "over" compositing)
# --------------------------------------------------------------------------------------------


class Canvas:
    """RGBA float image with a data -> pixel mapping.  Row 0 is the bottom row.

    Shapes are drawn as coverage on an ``ss`` x ``ss`` supersampled grid, averaged per pixel and
    composited over the image, so edges are anti-aliased and a polyline never blends twice
    with itself."""

    def __init__(self, width, height, *, xlim=(0.0, 1.0), ylim=(0.0, 1.0), margin=6, ss=3,
                 background=COLOURS["background"]):
        self.w, self.h, self.ss = int(width), int(height), int(ss)
        self.rgba = np.empty((self.h, self.w, 4), dtype=np.float32)
        self.rgba[...] = np.asarray(background, dtype=np.float32)
        self.margin = margin
        self.xlim, self.ylim = (float(xlim[0]), float(xlim[1])), (float(ylim[0]), float(ylim[1]))
        # supersampled pixel-centre coordinates (in output pixel units)
        s = self.ss
        self._xs = (np.arange(self.w * s) + 0.5) / s
        self._ys = (np.arange(self.h * s) + 0.5) / s

    # data <-> pixel
    def px(self, x):
        x0, x1 = self.xlim
        return self.margin + (np.asarray(x, dtype=np.float64) - x0) / (x1 - x0) * (
            self.w - 2 * self.margin)

    def py(self, y):
        y0, y1 = self.ylim
        return self.margin + (np.asarray(y, dtype=np.float64) - y0) / (y1 - y0) * (
            self.h - 2 * self.margin)

    def _window(self, x0, x1, y0, y1):
        """Output-pixel window [c0, c1) x [r0, r1) covering data-pixel ranges (clamped)."""
        c0 = int(np.clip(np.floor(x0), 0, self.w))
        c1 = int(np.clip(np.ceil(x1) + 1, 0, self.w))
        r0 = int(np.clip(np.floor(y0), 0, self.h))
        r1 = int(np.clip(np.ceil(y1) + 1, 0, self.h))
        return c0, c1, r0, r1

    def _composite(self, cover_ss, colour, c0=0, r0=0):
        """Blend a supersampled coverage mask whose top-left is output pixel (r0, c0)."""
        s = self.ss
        hh, ww = cover_ss.shape[0] // s, cover_ss.shape[1] // s
        if hh == 0 or ww == 0:
            return
        m = cover_ss.reshape(hh, s, ww, s)
        cover = m.sum(axis=3, dtype=np.uint16).sum(axis=1, dtype=np.uint16).astype(np.float32)
        col = np.asarray(colour, dtype=np.float32)
        a = cover * (col[3] / (s * s))
        dst = self.rgba[r0:r0 + hh, c0:c0 + ww]
        dst[..., :3] += (col[:3] - dst[..., :3]) * a[..., None]
        dst[..., 3] += (1.0 - dst[..., 3]) * a

    def curve(self, x, y, colour, width=1.5, *, dash=None):
        """A polyline through data points (x ascending), drawn as a function of x: each
        supersampled column is filled over the y range the curve spans there, widened by
        ``width`` pixels in both directions.  NaN / inf points leave gaps."""
        xp, yp = self.px(x), self.py(y)
        finite = np.isfinite(yp)
        if not np.any(finite):
            return
        s = self.ss
        hw = 0.5 * width
        c0, c1, _, _ = self._window(np.min(xp) - hw - 1, np.max(xp) + hw + 1, 0, 0)
        cols = self._xs[c0 * s:c1 * s]
        yc = np.interp(cols, xp[finite], yp[finite], left=np.nan, right=np.nan)
        if not np.all(finite):  # keep the gaps between finite points
            idx = np.searchsorted(xp, cols).clip(1, len(xp) - 1)
            yc[~(finite[idx] & finite[idx - 1])] = np.nan
        nxt = np.append(yc[1:], yc[-1])
        lo, hi = np.fmin(yc, nxt), np.fmax(yc, nxt)
        k = max(1, int(round(hw * s)))  # widen horizontally over ±hw pixels of columns
        pad_lo = np.pad(lo, k, constant_values=np.nan)
        pad_hi = np.pad(hi, k, constant_values=np.nan)
        n = len(lo)
        lo_w, hi_w = lo.copy(), hi.copy()
        for sh in range(2 * k + 1):
            lo_w = np.fmin(lo_w, pad_lo[sh:sh + n])
            hi_w = np.fmax(hi_w, pad_hi[sh:sh + n])
        ok = np.isfinite(lo_w)
        if not np.any(ok):
            return
        _, _, r0, r1 = self._window(0, 0, np.min(lo_w[ok]) - hw - 1, np.max(hi_w[ok]) + hw + 1)
        ys = self._ys[r0 * s:r1 * s, None]
        with np.errstate(invalid="ignore"):
            mask = (ys >= lo_w[None, :] - hw) & (ys <= hi_w[None, :] + hw)
        if dash is not None:  # dash pattern along x, in pixels (on, off)
            on, off = dash
            mask &= ((cols % (on + off)) < on)[None, :]
        self._composite(mask, colour, c0, r0)

    def hline(self, y, colour, width=1.0, *, x0=None, x1=None, dash=None):
        x0 = self.xlim[0] if x0 is None else x0
        x1 = self.xlim[1] if x1 is None else x1
        self.curve(np.array([x0, x1]), np.array([y, y]), colour, width, dash=dash)

    def vline(self, x, colour, width=1.0, *, y0=None, y1=None, dash=None):
        y0 = self.ylim[0] if y0 is None else y0
        y1 = self.ylim[1] if y1 is None else y1
        xp = float(self.px(x))
        yp0, yp1 = sorted((float(self.py(y0)), float(self.py(y1))))
        hw = 0.5 * width
        c0, c1, r0, r1 = self._window(xp - hw - 1, xp + hw + 1, yp0 - 1, yp1 + 1)
        s = self.ss
        xs, ys = self._xs[None, c0 * s:c1 * s], self._ys[r0 * s:r1 * s, None]
        mask = (np.abs(xs - xp) <= hw) & (ys >= yp0) & (ys <= yp1)
        if dash is not None:
            on, off = dash
            mask &= (ys % (on + off)) < on
        self._composite(mask, colour, c0, r0)

    def dot(self, x, y, radius, colour, *, ring=None):
        xp, yp = float(self.px(x)), float(self.py(y))
        if not (np.isfinite(xp) and np.isfinite(yp)):
            return
        rr = radius + (ring or 0.0)
        c0, c1, r0, r1 = self._window(xp - rr - 1, xp + rr + 1, yp - rr - 1, yp + rr + 1)
        s = self.ss
        d2 = (self._xs[None, c0 * s:c1 * s] - xp) ** 2 + (self._ys[r0 * s:r1 * s, None] - yp) ** 2
        if ring is not None:
            self._composite(d2 <= rr ** 2, COLOURS["background"], c0, r0)
        self._composite(d2 <= radius ** 2, colour, c0, r0)

    def frame(self, colour=COLOURS["frame"], width=1.0):
        x0, x1 = self.xlim
        y0, y1 = self.ylim
        self.hline(y0, colour, width)
        self.hline(y1, colour, width)
        self.vline(x0, colour, width)
        self.vline(x1, colour, width)


# --------------------------------------------------------------------------------------------
# Figure 3 (left): k_h against r_c
# --------------------------------------------------------------------------------------------


def haze_plot(core_max, peak_ratio, haziness, smoothness=None, *, size=(192, 192), samples=None):
    """k_h(r_c) at θ_d = 0 with the P and E bounds, the current β_h curve and the current point.

    core_max: r̂_c (max channel of the core reflectivity); peak_ratio: p; haziness: β_h;
    smoothness: None (Eq. 7) or the Bézier weight w.  Returns (H, W, 4) float32, row 0 bottom."""
    w_px, h_px = size
    p = float(np.clip(peak_ratio, 1e-9, 1.0))
    q = 1.0 - p
    c = Canvas(w_px, h_px, xlim=(0.0, 1.0), ylim=(0.0, 1.08))
    for g in (0.25, 0.5, 0.75):
        c.hline(g, COLOURS["grid"], 1.0)
        c.vline(g, COLOURS["grid"], 1.0)
    c.frame()
    n = samples or 4 * w_px
    rc = np.linspace(0.0, 1.0, n)
    # the bounds of Eq. 6: P on [0, p], E on [p, 1]; both reach k_h = 1 at r_c = p
    with np.errstate(divide="ignore", invalid="ignore"):
        bound_p = np.where(rc <= p, rc / p, np.nan)
        bound_e = np.where(rc >= p, (1.0 - rc) / q if q > 0 else np.nan, np.nan)
    c.vline(p, COLOURS["mirror"], 1.0, y0=0.0, y1=1.0, dash=(3, 3))
    c.curve(rc, bound_p, COLOURS["bound"], 1.6)
    if q > 0:
        c.curve(rc, bound_e, COLOURS["bound"], 1.6)
    pq = np.full_like(rc, p)
    qq = np.full_like(rc, q)
    kh, _ = haze_intensity(rc, pq, qq, float(haziness), smoothness)
    c.curve(rc, kh, COLOURS["curve"], 1.6)
    kh_now, _ = haze_intensity(np.array([float(core_max)]), np.array([p]), np.array([q]),
                               float(haziness), smoothness)
    c.dot(float(core_max), float(kh_now[0]), 3.2, COLOURS["point"], ring=1.2)
    return c.rgba


# --------------------------------------------------------------------------------------------
# Figure 2: BRDF slice in the plane of incidence
# --------------------------------------------------------------------------------------------


def _fresnel_conductor(cos_d, eta, kappa):
    """Exact unpolarised Fresnel reflectance for a complex index η + iκ (κ = 0: dielectric)."""
    n = np.asarray(eta, dtype=np.complex128) + 1j * np.asarray(kappa, dtype=np.float64)
    c = np.clip(np.asarray(cos_d, dtype=np.float64), 0.0, 1.0)
    s2 = 1.0 - c * c
    t = np.sqrt(n * n - s2)
    rs = (c - t) / (c + t)
    rp = (n * n * c - t) / (n * n * c + t)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


def _lambda(alpha, tan_t, distribution):
    """Smith Λ for a direction with tan θ (in the slice plane, so α is the x roughness)."""
    tan_t = np.abs(tan_t)
    if distribution == "BECKMANN":  # Walter et al. 2007 rational fit (what Cycles uses)
        with np.errstate(divide="ignore"):
            a = np.where(tan_t > 0, 1.0 / (alpha * tan_t), np.inf)
        lam = np.where(a < 1.6, (1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a), 0.0)
        return np.where(np.isfinite(a), lam, 0.0)
    return 0.5 * (np.sqrt(1.0 + (alpha * tan_t) ** 2) - 1.0)


def _microfacet(wi, wo, ax, ay, distribution):
    """D G2 / (4 cos θi cos θo) for directions in the x-z plane (y = 0): the slice along the
    tangent.  Height-correlated Smith G2 (Cycles); Ashikhmin-Shirley uses its own form."""
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    hx, hz = h[..., 0], h[..., 2]
    ci, co = wi[..., 2], wo[..., 2]
    if distribution == "ASHIKHMIN_SHIRLEY":
        ax_c, ay_c = max(ax, 1e-4), max(ay, 1e-4)
        nx, ny = 2.0 / ax_c ** 2 - 2.0, 2.0 / ay_c ** 2 - 2.0
        # the slice is along x: exponent n_x (φ_h = 0)
        d = np.sqrt((nx + 1.0) * (ny + 1.0)) / (2.0 * np.pi) * np.clip(hz, 0, 1) ** nx
        hdoti = np.sum(h * wi, axis=-1)
        return d / (4.0 * np.maximum(hdoti, 1e-9) * np.maximum(ci, co))
    if distribution == "BECKMANN":
        cos2 = hz * hz
        tan2 = (hx * hx) / np.maximum(cos2, 1e-300)
        d = np.exp(-tan2 / (ax * ax)) / (np.pi * ax * ay * cos2 * cos2)
    else:  # GGX / MULTI_GGX (single-scatter shape)
        d = 1.0 / (np.pi * ax * ay * ((hx / ax) ** 2 + hz * hz) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ti = np.sqrt(np.maximum(1.0 - ci * ci, 0.0)) / ci
        to = np.sqrt(np.maximum(1.0 - co * co, 0.0)) / co
    g2 = 1.0 / (1.0 + _lambda(ax, ti, distribution) + _lambda(ax, to, distribution))
    return d * g2 / (4.0 * ci * co)


def brdf_at(mapping, kind, theta_i, theta_o):
    """Core, halo and total BRDF (max channel of r) for a light at ``theta_i`` and views at
    ``theta_o`` (degrees, array) in the plane of incidence along the tangent.  Signed angles
    from the normal: the light sits on the +x side, a view at -theta_i is the mirror direction.

    mapping: a scalar ``HazeMapping``; kind: "CONDUCTOR", "DIELECTRIC" or "LEGACY".
    Returns a dict of float64 arrays: core = F_c f_n (Eq. 3 with P = p), halo = K_h g_h
    (Eq. 4, g_h = f_w - p f_n), total = ((1-β) f_n + β f_w) F_r (Eq. 1; = core + halo), narrow,
    wide (the weighted lobes of Eq. 1), and the scalars p, beta."""
    beta = float(np.asarray(mapping.beta))
    p = float(np.asarray(mapping.peak_ratio))
    ax, ay = (float(np.asarray(a)) for a in mapping.alpha)
    wx, wy = (float(np.asarray(a)) for a in mapping.alpha_wide)
    r = np.asarray(mapping.reflectivity, dtype=np.float64).reshape(3)
    ch = int(np.argmax(r))
    dist = mapping.distribution
    t_o = np.atleast_1d(np.asarray(theta_o, dtype=np.float64))
    ti = np.radians(float(theta_i))
    wi = np.array([np.sin(ti), 0.0, np.cos(ti)])[None, :].repeat(len(t_o), 0)
    to = np.radians(t_o)
    wo = np.stack([np.sin(to), np.zeros_like(to), np.cos(to)], axis=-1)
    f_n = _microfacet(wi, wo, ax, ay, dist)
    f_w = _microfacet(wi, wo, wx, wy, dist)
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    cos_d = np.sum(h * wi, axis=-1)
    if kind == "CONDUCTOR":
        eta = float(np.asarray(mapping.ior).reshape(3)[ch])
        kap = float(np.asarray(mapping.extinction).reshape(3)[ch])
        fr = _fresnel_conductor(cos_d, eta, kap)
    elif kind == "DIELECTRIC":
        fr = _fresnel_conductor(cos_d, float(np.asarray(mapping.dielectric_ior)), 0.0)
    else:  # LEGACY: no Fresnel, constant weights k_n + k_w = r
        fr = np.full_like(cos_d, r[ch])
    narrow = (1.0 - beta) * fr * f_n
    wide = beta * fr * f_w
    core = (1.0 - (1.0 - p) * beta) * fr * f_n  # Eq. 3 with P = p: F_c f_n
    halo = beta * fr * (f_w - p * f_n)  # Eq. 4: K_h g_h, g_h = f_w - p f_n
    return dict(theta_o=t_o, core=core, halo=halo, total=narrow + wide, narrow=narrow, wide=wide,
                p=p, beta=beta, channel=ch)


def brdf_slice(mapping, kind, *, theta_i=0.0, span=None, samples=361):
    """:func:`brdf_at` over a window of ``span`` degrees each side of the mirror direction
    (None: from the halo's roughness, 2 atan(3 α_w), between 2° and 90°)."""
    ax = float(np.asarray(mapping.alpha[0]))
    wx = float(np.asarray(mapping.alpha_wide[0]))
    if span is None:
        span = float(np.degrees(2.0 * np.arctan(3.0 * max(wx, ax))))
    span = float(np.clip(span, 2.0, 90.0))
    mirror = -float(theta_i)
    t_o = np.linspace(max(-89.5, mirror - span), min(89.5, mirror + span), samples)
    return brdf_at(mapping, kind, theta_i, t_o)


def brdf_plot(mapping, kind, *, theta_i=0.0, size=(192, 192), log=True, decades=3.0):
    """Figure 2 style picture of :func:`brdf_slice`: total (red), core (magenta), halo (cyan);
    log10 scale over ``decades`` below the peak (``log=False``: linear, scaled so the halo fills
    the picture and the core's peak is cut off — the view of Figure 2).  A dotted line marks the
    mirror direction.  Returns (H, W, 4) float32, row 0 bottom."""
    s = brdf_slice(mapping, kind, theta_i=theta_i, samples=4 * size[0])
    x = s["theta_o"]
    curves = [("halo", s["halo"]), ("core", s["core"]), ("total", s["total"])]
    if log:
        with np.errstate(divide="ignore", invalid="ignore"):
            top = np.log10(max(float(np.max(s["total"])), 1e-12)) + 0.1
            ys = {k: np.where(v > 0, np.log10(np.where(v > 0, v, 1.0)), np.nan) for k, v in curves}
        ylim = (top - decades, top)
    else:
        scale = max(float(np.max(s["halo"])), 0.05 * float(np.max(s["total"])), 1e-12)
        ys = dict(curves)
        ylim = (0.0, 2.5 * scale)
    c = Canvas(size[0], size[1], xlim=(x[0], x[-1]), ylim=ylim)
    c.vline(-float(theta_i), COLOURS["mirror"], 1.0, dash=(3, 3))
    c.frame()
    for name, _ in curves:
        y = np.clip(ys[name], ylim[0] - 1.0, ylim[1] + 1.0)  # keep off-range parts as edges
        c.curve(x, y, COLOURS[name], 1.6)
    # hide what fell outside the frame (curves were allowed to run past it)
    m = c.margin
    bg = np.asarray(COLOURS["background"], dtype=np.float32)
    c.rgba[:m, :, :] = bg
    c.rgba[-m:, :, :] = bg
    c.rgba[:, :m, :] = bg
    c.rgba[:, -m:, :] = bg
    return c.rgba


def mapping_for(params):
    """The HazeMapping api-style perceptual parameters render with (core.lobes.describe: the
    add-on's roughness floor, haziness cap and Cycles' limits), without bpy."""
    p = normalise({k: v for k, v in params.items() if k in PARAMETERS})
    return describe(p["kind"], p["distribution"], core_reflectivity=p["core_reflectivity"],
                    edge_tint=p["edge_tint"], roughness=p["roughness"], anisotropy=p["anisotropy"],
                    rotation=p["rotation"], haziness=p["haziness"], haze_extent=p["haze_extent"],
                    smoothness=p["smoothness"], anisotropic=is_anisotropic(p), strict=False).mapping
