# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/numerics.md: a catalogue of the haze mapping's numerically hard cases.

For every case the worst error against the mpmath reference of the paper's formulas
(tests/pure/reference.py, at the exact inputs each path was given) is measured for:
- float64 numpy   hazy_gloss.core.haze_mapping as api.map_parameters calls it (α <= 1,
                  aspect <= 10, R raised to the mirror cut-off 0.004);
- float32 numpy   the same with float32 inputs (what texture conversion runs);
- float32 shader  the in-shader mapping graph rendered by Cycles (benchmarks/shader_probe.py);
- printed f64/f32 a direct transcription of the printed formulas (benchmarks/printed.py).
Writes out/report/numerics.{json,md} and docs/img/num_*.png.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(C.ROOT / "tests" / "pure"))
import reference as R  # noqa: E402  (mpmath reference, another helper's)
import mpmath  # noqa: E402

import printed  # noqa: E402

MIN_R = 0.004  # product: roughness raised to just above Cycles' mirror cut-off
SH_MAX_HAZINESS = float(np.float32(0.9999))
SH_MIN_W = float(np.float32(1e-4))
F32 = np.float32
FIELDS = ("beta", "halo_intensity", "peak_ratio", "alpha_wide_x", "alpha_wide_y",
          "reflectivity", "ior", "extinction")
GOLD = (0.9, 0.6, 0.3)
GOLD_TINT = (1.0, 0.8, 0.5)


def case(rc=GOLD, g=GOLD_TINT, R=0.3, a=0.0, bh=0.6, lam=5.0, w=None, raw_alpha=False):
    rc = tuple(float(x) for x in np.broadcast_to(np.asarray(rc, float), (3,)))
    g = tuple(float(x) for x in np.broadcast_to(np.asarray(g, float), (3,)))
    lx, ly = lam if isinstance(lam, tuple) else (lam, lam)
    return dict(rc=rc, g=g, R=float(R), a=float(a), bh=float(bh), lx=float(lx), ly=float(ly),
                w=None if w is None else float(w), raw_alpha=raw_alpha)


def _r_star(p, w):
    return (0.5 - w * p) / (1.0 - w)


def rows():
    """The catalogue: (key, title, cases, product behaviour, visible effect)."""
    out = []
    # b ≈ 1: r_c = r*_c (+ a few offsets), r*_c = (1/2 - w p)/(1 - w) inside (0, 1)
    cs = []
    for lam, w in ((0.3, 4.0), (0.5, 3.0), (3.0, 0.2), (1.0, 0.5)):
        p = 1.0 / (1.0 + lam) ** 2
        rs = _r_star(p, w)
        if not 0 < rs < 1:
            continue
        for d in (0.0, 1e-9, -1e-9, 1e-7, -1e-7, 1e-5, -1e-5, 1e-3):
            cs.append(case(rc=(rs + d, (rs + d) * 0.8, (rs + d) * 0.5), lam=lam, w=w))
    out.append(("b1", "b ≈ 1 in the Bézier inversion (r_c at r*_c ± 0 .. 1e-3)", cs,
                "exact (closed form without b - 1)", "none (see the plot)"))
    cs = [case(rc=rc, w=w) for w in (1e-8, 1e-6, 1e-4, 1e-2) for rc in (0.02, 0.5, 0.95)]
    out.append(("w0", "w -> 0 (Bézier weight 1e-8 .. 1e-2)", cs,
                "exact in numpy; shader clamps w >= 1e-4 (silent)", "none: k_h -> 0 either way"))
    lam1 = math.sqrt(2) - 1  # p = 1/2: b = 2p = 1 for every r_c at w = 1
    cs = [case(rc=rc, w=w, lam=lam) for w in (1 - 1e-7, 1.0, 1 + 1e-7) for rc in (0.05, 0.5, 0.9)
          for lam in (5.0, lam1)]
    out.append(("w1", "w -> 1 (w = 1 ± 1e-7, incl. p = 1/2 where b ≡ 1)", cs,
                "exact", "none"))
    cs = [case(rc=rc, w=w) for w in (1e3, 1e6, 1e12, 1e30) for rc in (0.02, 0.5, 0.95)]
    out.append(("winf", "w -> ∞ (1e3 .. 1e30; Eq. 7 in the limit)", cs, "exact", "none"))
    cs = [case(rc=(x, x / 2, x / 4), w=w) for x in (1e-30, 1e-12, 1e-6, 1e-3) for w in (None, 2.0)]
    out.append(("rc0", "r_c -> 0 (1e-30 .. 1e-3, Eq. 7 and Bézier)", cs,
                "exact (β uses its limit β_h/(p + (1-p)β_h))", "none"))
    cs = [case(rc=(x, x * 0.9, x * 0.8), g=g, w=w, bh=0.6)
          for x in (1 - 1e-3, 1 - 1e-5, 1 - 2.0 ** -24, 1.0) for w in (None, 2.0)
          for g in (0.0, 1.0)]
    out.append(("rc1", "r_c -> 1 (1 - 1e-3 .. 1; g = 0 and 1)", cs,
                "clamps r <= 1 - ε before Gulbrandsen (η, κ finite; warns in numpy); β = 0 at "
                "r̂_c = 1 (no room for haze)",
                "none if both paths agree at r̂_c = 1 (figure)"))
    cs = []
    for lam in (0.5, 3.0):
        p = 1.0 / (1.0 + lam) ** 2
        for d in (0.0, 2.0 ** -40, -(2.0 ** -40), 1e-7, -1e-7):
            cs.append(case(rc=(p + d, (p + d) / 2, (p + d) / 3), lam=lam))
    out.append(("rcp", "r_c = p (the kink of Eq. 7)", cs, "exact", "none"))
    cs = [case(lam=lam, rc=rc, w=w) for lam in (1e-12, 1e-8, 1e-4) for rc in (0.3, 0.9999)
          for w in (None, 2.0)]
    out.append(("lam0", "λ_h -> 0 (p -> 1, 1 - p without cancellation)", cs, "exact",
                "none: the halo vanishes continuously"))
    cs = [case(lam=lam, R=R) for lam in (1e2, 1e4, 1e8, 1e30) for R in (0.05, 0.3)]
    out.append(("laminf", "λ_h -> ∞ (1e2 .. 1e30)", cs,
                "clamps α_w <= 1 (Cycles' limit), p from the clamped α_w; warns in numpy",
                "yes: halo width saturates (figure)"))
    cs = [case(R=R) for R in (0.0, 1e-6, 1e-3, 0.00376, 0.004, 0.01)]
    out.append(("an0", "α_n -> 0 and the mirror cut-off (R = 0 .. 0.01, product)", cs,
                "clamps R >= 0.004 (api and shader, silent): Cycles turns R < 0.00376 into a "
                "mirror", "yes: below the cut-off the core would be a delta (no highlight from "
                "small lights); the clamp keeps it a lobe"))
    cs = [case(R=R, raw_alpha=True) for R in (0.0, 1e-150, 1e-20, 1e-6, 1e-3)]
    out.append(("an0core", "α_n -> 0 in the core alone (no Blender clamp; α = R² down to 0)",
                cs, "exact: p is the limit 1/(1+λ)² at α_n = 0", "n/a (not reachable in Blender)"))
    cs = []
    for R in (0.3, 0.7, 0.95, 1.0):
        al = R * R
        for target in (0.99, 1.0, 1.01, 2.0):
            cs.append(case(R=R, lam=max(target / al - 1.0, 0.0)))
    cs += [case(R=0.9, a=0.9, lam=1.0), case(R=1.0, a=1.0, lam=(0.5, 2.0))]
    out.append(("aw1", "α_w hitting α <= 1 (α_w = 0.99 .. 2 before the clamp)", cs,
                "clamps α_w <= 1, p recomputed from the clamped value; warns in numpy",
                "yes: larger λ_h no longer widens the halo (figure)"))
    cs = [case(R=0.2, a=a, lam=lam) for a in (0.0, 0.8, 1.0)
          for lam in ((10.0, 1.0), (50.0, 1.0), (1.0, 50.0), (1000.0, 0.0))]
    out.append(("aspect", "anisotropy beyond 10:1 (λ_x/λ_y up to 1000:0)", cs,
                "clamps the halo's aspect to 10:1 (Metallic/Principled limit); warns in numpy",
                "yes: beyond 10:1 the halo stops stretching (figure)"))
    cs = [case(bh=bh, w=w) for bh in (0.99, 0.9999, 1 - 2.0 ** -24, 1 - 1e-12, 1.0)
          for w in (None, 2.0)]
    out.append(("bh1", "β_h -> 1 (0.99 .. 1)", cs,
                "clamps β_h < 1 (numpy: largest float below 1, raises for a scalar call, warns "
                "for textures; shader: 0.9999, silent)", "none (β_h = 0.9999 vs 1 - 2^-24 "
                "changes k_h by 1e-4 relative)"))
    cs = [case(rc=(0.9, 0.85, 0.8), g=g, bh=1 - d, lam=5.0) for d in (1e-2, 1e-4, 1e-6)
          for g in (0.0, 0.5, 1.0)]
    out.append(("r1", "r -> 1 in Gulbrandsen (haze pushes r to 1 - 1e-3 .. 1 - 1e-7)", cs,
                "exact (κ as a sum of non-negative terms); r <= 1 - ε", "none"))
    return out


# --------------------------------------------------------------------------------------------
# Paths
# --------------------------------------------------------------------------------------------


def _alpha(c, dtype):
    from hazy_gloss.core.conventions import alpha_from_roughness
    R_ = c["R"] if c["raw_alpha"] else max(c["R"], MIN_R)
    ax, ay = alpha_from_roughness(R_, c["a"])
    return np.asarray(ax, np.float64).astype(dtype), np.asarray(ay, np.float64).astype(dtype)


def run_core(c, dtype):
    from hazy_gloss.core import haze_mapping
    ax, ay = _alpha(c, dtype)
    t = np.dtype(dtype).type
    w = None if c["w"] is None else t(c["w"])
    # 1-element arrays, not 0-d: numpy 1.x computes 0-d float32 with Python floats in float64
    one = lambda x: np.full(1, x, dtype)  # noqa: E731
    m = haze_mapping(np.asarray(c["rc"], dtype)[None], np.asarray(c["g"], dtype)[None],
                     (one(ax), one(ay)), one(c["bh"]), (one(c["lx"]), one(c["ly"])),
                     smoothness=None if w is None else one(w), alpha_max=1.0, max_aspect=10.0,
                     strict=False)
    out = {"beta": m.beta[0], "halo_intensity": m.halo_intensity[0], "peak_ratio": m.peak_ratio[0],
           "alpha_wide_x": m.alpha_wide[0][0], "alpha_wide_y": m.alpha_wide[1][0],
           "reflectivity": m.reflectivity[0], "ior": m.ior[0], "extinction": m.extinction[0]}
    used = dict(rc=np.asarray(m.core_reflectivity)[0], g=np.asarray(m.edge_tint)[0], ax=ax, ay=ay,
                bh=np.asarray(m.haziness)[0], lx=np.asarray(m.haze_extent[0])[0],
                ly=np.asarray(m.haze_extent[1])[0], w=None if w is None else float(w))
    return out, used, dict(m.clamped)


def run_printed(used, dtype):
    return printed.mapping(used["rc"], used["g"], used["ax"], used["ay"], used["bh"], used["lx"],
                           used["ly"], used["w"], dtype)


def shader_inputs(c):
    """The float32 texel values the shader reads, and the exact inputs of its reference (after
    the shader's own clamps)."""
    rc = np.asarray(c["rc"], F32)
    g = np.asarray(c["g"], F32)
    v = dict(rc=rc, g=g, R=F32(c["R"]), a=F32(c["a"]), bh=F32(c["bh"]), lx=F32(c["lx"]),
             ly=F32(c["ly"]), w=None if c["w"] is None else F32(c["w"]))
    mp = mpmath.mp
    with mp.workdps(60):
        Rm = min(max(R.mpf(v["R"]), R.mpf(F32(MIN_R))), 1)
        am = min(max(R.mpf(v["a"]), 0), 1)
        s = mp.sqrt(1 - R.mpf(F32(0.9)) * am) if am > 0 else mp.mpf(1)
        ax = min(Rm * Rm / s, 1)
        ay = Rm * Rm * s
    used = dict(rc=[min(max(R.mpf(x), 0), 1) for x in rc], g=[min(max(R.mpf(x), 0), 1) for x in g],
                ax=ax, ay=ay, bh=min(max(R.mpf(v["bh"]), 0), R.mpf(SH_MAX_HAZINESS)),
                lx=max(R.mpf(v["lx"]), 0), ly=max(R.mpf(v["ly"]), 0),
                w=None if v["w"] is None else max(float(v["w"]), SH_MIN_W))
    return v, used


def reference(used, eps):
    """mpmath reference of the printed formulas at exactly these inputs (Blender limits:
    α <= 1 and aspect <= 10, the latter by shortening the long halo axis as the product does)."""
    mp = mpmath.mp
    rc = [R.mpf(x) for x in np.ravel(used["rc"])] if not isinstance(used["rc"], list) else used["rc"]
    g = [R.mpf(x) for x in np.ravel(used["g"])] if not isinstance(used["g"], list) else used["g"]
    ax, ay = R.mpf(used["ax"]), R.mpf(used["ay"])
    lx, ly = R.mpf(used["lx"]), R.mpf(used["ly"])
    with mp.workdps(80):
        root = mp.sqrt(ax * ay)
        wx, wy = min(ax + lx * root, 1), min(ay + ly * root, 1)
        if wx > 10 * wy and root > 0:
            lx = (max(10 * wy, ax) - ax) / root
        elif wy > 10 * wx and root > 0:
            ly = (max(10 * wx, ay) - ay) / root
    w = used["w"]
    if w is not None and not math.isfinite(w):
        w = None
    ref = R.haze_mapping(rc, g, (ax, ay), R.mpf(used["bh"]), (lx, ly), smoothness=w,
                         alpha_max=1.0, eps=eps)
    out = dict(ref)
    out["alpha_wide_x"], out["alpha_wide_y"] = ref["alpha_wide"]
    return out


def errors(got, ref, eps=2.0 ** -52):
    with mpmath.mp.workdps(60):
        return _errors(got, ref, eps)


def _errors(got, ref, eps):
    """Worst relative error over the fields (absolute where the reference is 0) ->
    (err, field, err_conditioned): the last divides the η and κ errors by their condition number
    1/(1-r) (a relative rounding of r moves η, κ by that factor more), other fields as is."""
    worst, where, worst_c = -1.0, "", -1.0
    r_ref = [min(x, 1 - R.mpf(eps)) for x in ref["reflectivity"]]
    for f in FIELDS:
        g = np.ravel(np.asarray(got[f], np.float64))
        r = ref[f] if isinstance(ref[f], (list, tuple)) else [ref[f]]
        for i, (gi, ri) in enumerate(zip(g, r)):
            if not math.isfinite(gi):
                e = math.inf
            elif ri == 0:
                e = abs(gi)
            else:
                e = float(abs(R.mpf(gi) - ri) / abs(ri))
            if e > worst:
                worst, where = e, f
            ec = e * float(1 - r_ref[i]) if f in ("ior", "extinction") else e
            worst_c = max(worst_c, ec)
    return worst, where, worst_c


# --------------------------------------------------------------------------------------------
# Runs
# --------------------------------------------------------------------------------------------


def catalogue(shader):
    res = []
    for key, title, cases, product, visible in rows():
        t0 = time.perf_counter()
        cols = {k: [-1.0, "", -1.0] for k in ("f64", "f32", "shader", "printed64", "printed32")}
        clamped = {}

        def upd(col, e):
            if e[0] > cols[col][0]:
                cols[col][:2] = e[:2]
            cols[col][2] = max(cols[col][2], e[2])

        sh_cases = []
        bad_shader = []
        for c in cases:
            for dtype, col, eps in ((np.float64, "f64", 2.0 ** -52), (np.float32, "f32", 2.0 ** -23)):
                got, used, cl = run_core(c, dtype)
                for k_, v_ in cl.items():
                    clamped[k_] = clamped.get(k_, 0) + v_
                ref = reference(used, eps)
                upd(col, errors(got, ref, eps))
                upd("printed" + col[1:], errors(run_printed(used, dtype), ref, eps))
            if not c["raw_alpha"]:
                sh_cases.append(c)
        if shader and sh_cases:
            for smooth in (False, True):
                group = [c for c in sh_cases if (c["w"] is not None) == smooth]
                if not group:
                    continue
                aniso = any(c["a"] > 0 or c["lx"] != c["ly"] for c in group)
                ins = [shader_inputs(c) for c in group]
                got = _probe([v for v, _ in ins], aniso, smooth)
                for i, (_, used) in enumerate(ins):
                    ref = reference(used, 2.0 ** -23)
                    e = errors({f: got[f][i] for f in FIELDS}, ref, 2.0 ** -23)
                    upd("shader", e)
                    if e[2] > 1e-3:
                        bad_shader.append(dict(case={k: v for k, v in group[i].items()},
                                               err=e[0], field=e[1],
                                               got=np.ravel(got[e[1]][i]).tolist(),
                                               ref=[float(x) for x in np.ravel(
                                                   ref[e[1]] if isinstance(ref[e[1]], list)
                                                   else [ref[e[1]]])]))
        else:
            cols["shader"] = [None, "n/a", None]
        for v in cols.values():
            if v[0] is not None and v[0] <= 0:
                v[0] = 0.0
            if v[2] is not None and v[2] <= 0:
                v[2] = 0.0
        res.append(dict(key=key, title=title, n=len(cases), cols=cols, product=product,
                        visible=visible, clamped=clamped, bad_shader=bad_shader, seconds=time.perf_counter() - t0))
        print(f"[numerics] {key}: " + ", ".join(
            f"{k} {C.sci(v[0])}" for k, v in cols.items()), flush=True)
    return res


def _probe(values, aniso, smooth):
    import shader_probe
    n = len(values)
    cases = dict(core_reflectivity=np.stack([v["rc"] for v in values]),
                 edge_tint=np.stack([v["g"] for v in values]),
                 roughness=np.array([v["R"] for v in values], F32),
                 anisotropy=np.array([v["a"] for v in values], F32),
                 haziness=np.array([v["bh"] for v in values], F32),
                 haze_extent_x=np.array([v["lx"] for v in values], F32),
                 haze_extent_y=np.array([v["ly"] for v in values], F32),
                 smoothness=np.array([v["w"] if v["w"] is not None else 0 for v in values], F32)
                 if smooth else None)
    assert len(cases["roughness"]) == n
    return shader_probe.probe(cases, anisotropic=aniso, smooth=smooth)


def bezier_sweep(shader):
    """k_h near r*_c: printed (Eqs. 12-14 + Taylor window) vs stable, float32/float64, shader."""
    with mpmath.mp.workdps(120):
        return _bezier_sweep(shader)


def _bezier_sweep(shader):
    from hazy_gloss.core.mapping import haze_intensity
    lam, w, bh = 0.3, 4.0, 0.6
    p_exact = R.mpf(1) / (1 + R.mpf(lam)) ** 2
    out = {}
    offsets = sorted({s * 2.0 ** k for k in range(0, 60, 2) for s in (1, -1)} | {0.0})
    for dtype, name in ((np.float64, "64"), (np.float32, "32")):
        t = np.dtype(dtype).type
        p = t(float(p_exact))
        q = t(1) - p  # exact: p in [1/2, 1]
        rs = (R.mpf(0.5) - R.mpf(w) * R.mpf(p)) / (1 - R.mpf(w))
        rs_d = t(float(rs))
        ulp = float(np.spacing(rs_d))
        xs, e_st, e_pr = [], [], []
        for k in offsets:
            d = k * ulp
            if abs(d) > 0.2:
                continue
            rc = t(float(rs_d) + d)
            ref = R.haze_intensity_bezier(R.mpf(rc), R.mpf(p), R.mpf(bh), R.mpf(w))
            one = lambda x: np.full(1, x, dtype)  # noqa: E731  (1-d: stays float32)
            kh_st = haze_intensity(one(rc), one(p), one(q), one(bh), smoothness=one(w))[0][0]
            kh_pr = printed.bezier_kh(printed.bezier_u(rc, p, w, dtype), w, bh, dtype)
            ref_t = ref if t(bh) == bh else R.haze_intensity_bezier(R.mpf(rc), R.mpf(p), R.mpf(t(bh)), R.mpf(w))
            xs.append(float(abs(R.mpf(rc) - rs)))
            e_st.append(_rel(kh_st, ref_t))
            e_pr.append(_rel(kh_pr, ref_t))
        out[f"stable{name}"] = (xs, e_st)
        out[f"printed{name}"] = (xs, e_pr)
    out["r_star"] = float((R.mpf(0.5) - R.mpf(w) * p_exact) / (1 - R.mpf(w)))
    if shader:
        import shader_probe
        rs32 = F32(out["r_star"])
        ulp = float(np.spacing(rs32))
        ks = [k for k in offsets if abs(k * ulp) <= 0.2]
        rc = np.array([F32(float(rs32) + k * ulp) for k in ks], F32)
        n = len(rc)
        Rr = F32(0.3)
        cases = dict(core_reflectivity=np.repeat(rc[:, None], 3, 1), edge_tint=np.zeros((n, 3), F32),
                     roughness=np.full(n, Rr, F32), anisotropy=np.zeros(n, F32),
                     haziness=np.full(n, bh, F32), haze_extent_x=np.full(n, lam, F32),
                     haze_extent_y=np.full(n, lam, F32), smoothness=np.full(n, w, F32))
        got = shader_probe.probe(cases, anisotropic=False, smooth=True,
                                 packs={"scalars": ("beta", "halo_intensity", "peak_ratio")})
        # exact p of the shader's inputs: α cancels, p = 1/(1+λ)² with λ = float32(0.3)
        p_sh = 1 / (1 + R.mpf(F32(lam))) ** 2
        rs_sh = (R.mpf(0.5) - R.mpf(w) * p_sh) / (1 - R.mpf(w))
        xs, es = [], []
        for i in range(n):
            ref = R.haze_intensity_bezier(R.mpf(rc[i]), p_sh, R.mpf(F32(bh)), R.mpf(w))
            xs.append(float(abs(R.mpf(rc[i]) - rs_sh)))
            es.append(_rel(got["halo_intensity"][i], ref))
        out["shader32"] = (xs, es)
    return out


def gulbrandsen_sweep():
    """κ (and η) of Gulbrandsen near r = 1: printed vs stable, float32 / float64."""
    from hazy_gloss.core.mapping import gulbrandsen_ior
    out = {}
    for g in (0.5, 1.0):
        for dtype, name in ((np.float64, "64"), (np.float32, "32")):
            t = np.dtype(dtype).type
            eps = float(np.finfo(dtype).eps)
            xs, e_st, e_pr = [], [], []
            for e in np.geomspace(eps, 0.5, 40):
                r = t(1 - e)
                if r >= 1:
                    continue
                ref = R.gulbrandsen_at(float(r), float(g))[1]
                _, k_st = gulbrandsen_ior(np.full(1, r, dtype), np.full(1, g, dtype))
                k_st = k_st[0]
                _, k_pr = printed.gulbrandsen(r, t(g), dtype)
                xs.append(float(1 - R.mpf(r)))
                e_st.append(_rel(k_st, ref))
                e_pr.append(_rel(k_pr, ref))
            out[f"g={g} stable{name}"] = (xs, e_st)
            out[f"g={g} printed{name}"] = (xs, e_pr)
    return out


def _rel(x, ref):
    x = float(np.ravel(np.asarray(x))[0])
    if not math.isfinite(x):
        return math.inf
    if ref == 0:
        return abs(x)
    with mpmath.mp.workdps(60):
        return float(abs(R.mpf(x) - ref) / abs(ref))


# --------------------------------------------------------------------------------------------
# Bad texels and 8-bit quantisation
# --------------------------------------------------------------------------------------------

BAD = (("NaN", math.nan), ("+inf", math.inf), ("-inf", -math.inf), ("-1", -1.0), ("2", 2.0))
PARAMS = ("core_reflectivity", "edge_tint", "roughness", "haziness", "haze_extent", "anisotropy",
          "smoothness")


def bad_texels(shader):
    """Each input in turn set to NaN / ±inf / -1 / 2 (others: gold, R 0.3, β_h 0.6, λ 5, w 2)."""
    base = dict(core_reflectivity=np.array(GOLD, F32), edge_tint=np.array(GOLD_TINT, F32),
                roughness=F32(0.3), haziness=F32(0.6), haze_extent=F32(5.0), anisotropy=F32(0.3),
                smoothness=F32(2.0))
    items = []
    for param in PARAMS:
        for label, val in BAD:
            v = dict(base)
            v[param] = np.full(3, val, F32) if param in ("core_reflectivity", "edge_tint") else F32(val)
            items.append((param, label, v))
    res = []
    # numpy: the texture-conversion path (hazy_gloss.conversion.convert.map_textures, float32, clamp+count)
    from hazy_gloss.conversion import convert as hconv
    for param, label, v in items:
        arrays = {"core_reflectivity": v["core_reflectivity"].reshape(1, 1, 3),
                  "edge_tint": v["edge_tint"].reshape(1, 1, 3),
                  "roughness": np.full((1, 1), v["roughness"], F32),
                  "anisotropy": np.full((1, 1), v["anisotropy"], F32),
                  "rotation": np.zeros((1, 1), F32),
                  "haziness": np.full((1, 1), v["haziness"], F32),
                  "haze_extent_x": np.full((1, 1), v["haze_extent"], F32)}
        arrays["haze_extent_y"] = arrays["haze_extent_x"]
        try:
            mm = hconv.map_textures(arrays, kind="CONDUCTOR", smoothness=float(v["smoothness"]))
            outs = np.concatenate([np.ravel(x) for x in mm.maps.values()])
            res.append(dict(param=param, value=label, numpy_finite=bool(np.all(np.isfinite(outs))),
                            numpy_warnings="; ".join(f"{k}" for k in mm.clamped) or "none",
                            numpy_beta=float(mm.maps["beta"][0, 0])))
        except ValueError as exc:
            res.append(dict(param=param, value=label, numpy_finite=True,
                            numpy_warnings=f"raises: {exc}", numpy_beta=math.nan))
    if shader:
        import shader_probe
        n = len(items)
        cases = dict(core_reflectivity=np.stack([v["core_reflectivity"] for _, _, v in items]),
                     edge_tint=np.stack([v["edge_tint"] for _, _, v in items]),
                     roughness=np.array([v["roughness"] for _, _, v in items], F32),
                     anisotropy=np.array([v["anisotropy"] for _, _, v in items], F32),
                     haziness=np.array([v["haziness"] for _, _, v in items], F32),
                     haze_extent_x=np.array([v["haze_extent"] for _, _, v in items], F32),
                     haze_extent_y=np.array([v["haze_extent"] for _, _, v in items], F32),
                     smoothness=np.array([v["smoothness"] for _, _, v in items], F32))
        got = shader_probe.probe(cases, anisotropic=True, smooth=True)
        # what Cycles reads from a texel holding a non-finite value next to finite ones
        nan, inf = math.nan, math.inf
        texels = [(nan, 0.6, 5.0), (0.5, nan, 5.0), (0.5, 0.6, nan), (inf, 0.6, 5.0),
                  (0.5, inf, 5.0), (0.5, 0.6, -inf)]
        tx = np.array(texels, F32)
        m = len(texels)
        raw = shader_probe.probe(dict(core_reflectivity=np.zeros((m, 3), F32),
                                      edge_tint=np.zeros((m, 3), F32), roughness=tx[:, 0],
                                      anisotropy=np.zeros(m, F32), haziness=tx[:, 1],
                                      haze_extent_x=tx[:, 2], haze_extent_y=tx[:, 2],
                                      smoothness=None),
                                 anisotropic=True, smooth=False, packs={"raw": ("texel_s1",)})
        readback = [(list(t), [float(x) for x in raw["texel_s1"][i]]) for i, t in enumerate(texels)]
        for i in range(n):
            vals = np.concatenate([np.ravel(got[f][i]) for f in FIELDS])
            res[i]["shader_finite"] = bool(np.all(np.isfinite(vals)))
            res[i]["shader_beta"] = float(got["beta"][i])
        res.append({"readback": readback})
    return res


def srgb_to_linear(x):
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x):
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0), 1 / 2.4) - 0.055)


def q8_linear(x, scale=1.0):
    return np.round(np.clip(x / scale, 0, 1) * 255) / 255 * scale


def q8_srgb(x):
    return srgb_to_linear(np.round(linear_to_srgb(np.clip(x, 0, 1)) * 255) / 255)


def quantisation():
    """Worst relative change of each output when one input map is stored in 8 bits."""
    from hazy_gloss.core import haze_mapping
    from hazy_gloss.core.conventions import alpha_from_roughness
    n = 2001
    specs = [  # (input, encoding, sweep, quantiser)
        ("core_reflectivity", "8-bit sRGB (colour map)", np.linspace(0.0, 1.0, n), q8_srgb),
        ("core_reflectivity", "8-bit linear", np.linspace(0.0, 1.0, n), q8_linear),
        ("edge_tint", "8-bit sRGB (colour map)", np.linspace(0.0, 1.0, n), q8_srgb),
        ("roughness", "8-bit linear (Non-Color)", np.linspace(MIN_R, 1.0, n), q8_linear),
        ("haziness", "8-bit linear (Non-Color)", np.linspace(0.0, 0.999, n), q8_linear),
        ("haze_extent", "8-bit of λ/20 (Non-Color)", np.linspace(0.0, 20.0, n),
         lambda x: q8_linear(x, 20.0)),
        ("anisotropy", "8-bit linear (Non-Color)", np.linspace(0.0, 1.0, n), q8_linear),
    ]
    outs = ("beta", "halo_intensity", "reflectivity", "ior", "extinction", "alpha_wide")
    res = []
    for name, enc, sweep, quant in specs:
        def mapped(x):
            v = dict(core_reflectivity=np.array(GOLD) * 0 + 0.6, edge_tint=np.array(GOLD_TINT),
                     roughness=0.3, haziness=0.6, haze_extent=5.0, anisotropy=0.3)
            if name in ("core_reflectivity", "edge_tint"):
                v[name] = np.repeat(np.asarray(x)[:, None], 3, 1)
            else:
                v[name] = np.asarray(x)
            R_ = np.maximum(np.asarray(v["roughness"], float), MIN_R)
            ax, ay = alpha_from_roughness(R_, v["anisotropy"])
            m = haze_mapping(v["core_reflectivity"], v["edge_tint"], (ax, ay), v["haziness"],
                             v["haze_extent"], alpha_max=1.0, max_aspect=10.0, strict=False)
            return {"beta": m.beta, "halo_intensity": m.halo_intensity,
                    "reflectivity": m.reflectivity[..., 0], "ior": m.ior[..., 0],
                    "extinction": m.extinction[..., 0], "alpha_wide": m.alpha_wide[0]}
        a = mapped(sweep)
        b = mapped(quant(sweep))
        row = {"input": name, "encoding": enc, "worst": {}}
        for o in outs:
            x, y = np.broadcast_to(a[o], sweep.shape), np.broadcast_to(b[o], sweep.shape)
            with np.errstate(divide="ignore", invalid="ignore"):
                if o in ("beta", "halo_intensity", "reflectivity"):  # in [0, 1]: absolute
                    rel = np.abs(y - x)
                else:
                    rel = np.where(np.abs(x) > 1e-12, np.abs(y - x) / np.abs(x), np.abs(y - x))
            i = int(np.nanargmax(rel))
            row["worst"][o] = (float(rel[i]), float(sweep[i]))
        res.append(row)
    return res


# --------------------------------------------------------------------------------------------
# Renders of visible effects
# --------------------------------------------------------------------------------------------


def visible_renders():
    """Plane from above under a small point light 1 m above its centre (camera along the
    normal): α_w clamp (λ = 5, 10, 30, 300 at R = 0.3), the 10:1 aspect clamp (λ = (3, 1),
    (10, 1), (50, 1) at R = 0.2) and r_c = 1 (lean vs in-shader)."""
    import bpy
    from mathutils import Vector
    from hazy_gloss import api
    import scenes
    C.clean_file()
    scenes.setup_render("CYCLES", samples=16, resolution=(96, 96), bounces=0)
    plane = bpy.data.objects.new("HG vis plane", scenes._plane_mesh("HG vis plane", 4.0))
    bpy.context.scene.collection.objects.link(plane)
    scenes._ortho_camera("HG vis cam", Vector((0.0, 0.0, 1.0)), 4.0)
    light = bpy.data.lights.new("HG vis point", "POINT")
    light.energy = 60.0
    light.shadow_soft_size = 0.0
    lo = bpy.data.objects.new("HG vis point", light)
    bpy.context.scene.collection.objects.link(lo)
    lo.location = (0.0, 0.0, 1.0)
    base = dict(kind="CONDUCTOR", core_reflectivity=GOLD, edge_tint=GOLD_TINT, haziness=0.9)
    sets = {
        "aw": [(f"λ_h = {x:g}", dict(base, roughness=0.3, haze_extent=x))
               for x in (5.0, 10.0, 30.0, 300.0)],
        "aspect": [(f"λ_h = {x}", dict(base, roughness=0.2, haze_extent=x))
                   for x in ((3.0, 1.0), (10.0, 1.0), (50.0, 1.0))],
        "rc1": [("lean, r_c = (0.999, 0.9, 0.8)", dict(base, roughness=0.2, haze_extent=5.0,
                                                       core_reflectivity=(0.999, 0.9, 0.8))),
                ("lean, r_c = (1, 0.9, 0.8)", dict(base, roughness=0.2, haze_extent=5.0,
                                                   core_reflectivity=(1.0, 0.9, 0.8))),
                ("in-shader, r_c = (1, 0.9, 0.8)", dict(base, roughness=0.2, haze_extent=5.0,
                                                        core_reflectivity=(1.0, 0.9, 0.8),
                                                        shader_mapping=True))],
    }
    out = {}
    for key, ps in sets.items():
        imgs = []
        for _, p in ps:
            mat = api.create_material("vis", **p)
            plane.data.materials.clear()
            plane.data.materials.append(mat)
            imgs.append(scenes.render_exr()[..., :3])
        out[key] = imgs
    return out, {k: [lab for lab, _ in v] for k, v in sets.items()}


# --------------------------------------------------------------------------------------------


def main():
    shader = True
    C.start_blender()
    C.clean_file()
    t0 = time.perf_counter()
    cat = catalogue(shader)
    bez = bezier_sweep(shader)
    gul = gulbrandsen_sweep()
    bad = bad_texels(shader)
    qua = quantisation()
    vis, vis_sets = visible_renders()
    res = {"catalogue": cat, "bad": bad, "quant": qua, "r_star": bez["r_star"],
           "seconds": time.perf_counter() - t0}
    res["fig_bezier"] = _plot_sweep(bez, "Eq. 12-15 near b = 1: relative error of k̂_h",
                                    "|r_c - r*_c|", "num_bezier.png",
                                    order=["printed32", "printed64", "stable32", "stable64",
                                           "shader32"])
    res["fig_gulbrandsen"] = _plot_sweep(gul, "Gulbrandsen κ near r = 1: relative error",
                                         "1 - r", "num_gulbrandsen.png", order=list(gul))
    res["bez_summary"] = {k: _window_max(v) for k, v in bez.items() if k != "r_star"}
    res["gul_summary"] = {k: max(v[1]) for k, v in gul.items()}
    res["vis"] = _plot_vis(vis, vis_sets)
    C.write_json("numerics", res)
    (C.OUT / "numerics.md").write_text(_markdown(res))


def _window_max(series):
    xs, es = series
    near = [e for x, e in zip(xs, es) if x <= 1e-3]
    return {"worst_near": max(near) if near else None, "worst": max(es)}


def _plot_sweep(data, title, xlabel, name, order):
    plt = C.pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for k in order:
        if k not in data or not isinstance(data[k], tuple):
            continue
        xs, es = data[k]
        xs = np.maximum(np.asarray(xs), 1e-30)
        es = np.clip(np.asarray(es, float), 1e-18, 1e3)
        o = np.argsort(xs)
        ls = "--" if "printed" in k else "-"
        ax.loglog(xs[o], es[o], ls=ls, marker=".", ms=4, label=k.replace("32", " float32")
                  .replace("64", " float64"))
    ax.set_xlabel(xlabel)
    ax.set_ylabel("relative error (clipped to [1e-18, 1e3])")
    ax.set_title(title)
    ax.legend(fontsize=7)
    return C.save_fig(fig, name)


def _plot_vis(vis, labels):
    """Each set: the renders (exposure high enough to show the halo; the core saturates) and
    the radiance profile through the centre row(s), log scale."""
    plt = C.pyplot()
    out = {}
    for key, imgs in vis.items():
        n = len(imgs)
        fig, axes = plt.subplots(1, n + 1, figsize=(2.3 * n + 3.6, 2.6),
                                 gridspec_kw={"width_ratios": [1] * n + [1.8]})
        h = imgs[0].shape[0]
        for ax, img, lab in zip(axes, imgs, labels[key]):
            x = np.clip(np.nan_to_num(img) * 8.0, 0, None)
            x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.minimum(x, 1), 1 / 2.4) - 0.055)
            ax.imshow(np.clip(x[::-1], 0, 1))
            ax.set_title(lab, fontsize=7)
            ax.axis("off")
            prof = img[h // 2 - 1:h // 2 + 1].mean(axis=(0, 2))
            axes[-1].semilogy(np.linspace(-2, 2, len(prof)), np.maximum(prof, 1e-6), label=lab)
        axes[-1].set_xlabel("x on the plane (m); light 1 m above x = 0")
        axes[-1].set_ylabel("radiance")
        axes[-1].legend(fontsize=6)
        out[key] = {"fig": C.save_fig(fig, f"num_{key}.png"),
                    "max_rel_diff_last_two": float(np.max(np.abs(imgs[-1] - imgs[-2]))
                                                   / max(float(np.max(imgs[-2])), 1e-12)),
                    "peaks": [float(np.max(i)) for i in imgs],
                    "labels": labels[key]}
    return out


def _summary(res):
    """Worst condition-normalised error per path over the catalogue, and the printed form's
    failures."""
    cols = ("f64", "f32", "shader", "printed64", "printed32")
    worst = {}
    for c in cols:
        vals = [r["cols"][c][2] for r in res["catalogue"] if r["cols"][c][2] is not None]
        worst[c] = max(vals) if vals else None
    bad_rows = {c: [r["title"].split(" (")[0] for r in res["catalogue"]
                    if r["cols"][c][0] is not None and r["cols"][c][0] > 1e-2]
                for c in cols}
    return worst, bad_rows


def _markdown(res):
    worst, bad_rows = _summary(res)
    n_bug = sum(len(r.get("bad_shader", [])) for r in res["catalogue"])
    L = ["## Summary\n"]
    L.append(f"Worst error over every case, with the η, κ errors divided by their condition "
             f"number 1/(1-r) (see below): float64 numpy {C.sci(worst['f64'])}, float32 numpy "
             f"{C.sci(worst['f32'])}, float32 shader {C.sci(worst['shader'])}"
             + (f" (including {n_bug} case(s) of the r_c = 1 fault below; without them the "
                f"shader stays near float32 rounding)" if n_bug else "")
             + f". The printed formulas: float64 {C.sci(worst['printed64'])}, float32 "
             f"{C.sci(worst['printed32'])}; they lose more than 1e-2 (or give inf/NaN) in: "
             f"float64 {', '.join(bad_rows['printed64']) or 'none'}; float32 "
             f"{', '.join(bad_rows['printed32']) or 'none'}.\n")
    L.append("## Catalogue\n")
    L.append("Each row is a family of cases (count in brackets). Error = the worst relative error "
             "over β, k̂_h, p, α_w (x, y), r, η, κ (RGB) against the mpmath reference of the "
             "paper's printed formulas (tests/pure/reference.py, 80+ digits) evaluated at exactly "
             "the inputs each path received after its own clamps; the field where the worst "
             "error occurred is named. Columns: **f64** = `core.haze_mapping` in float64 as "
             "`api.map_parameters` calls it; **f32** = the same in float32 (the texture "
             "conversion path); **shader** = the in-shader mapping graph rendered by Cycles "
             "(float32), inputs from float32 textures, outputs as emission; **printed** = a direct "
             "transcription of the printed formulas (benchmarks/printed.py: Eq. 12-14 with a "
             f"{printed.WINDOW_ULPS}-ulp Taylor window, 1 - p by subtraction, Gulbrandsen's "
             "printed κ) in float64 / float32.\n")
    header = ["case", "f64", "f32", "shader f32", "printed f64", "printed f32", "product does",
              "visible effect"]
    rows = []

    def cell(v):
        if v[0] is None:
            return "n/a"
        txt = f"{C.sci(v[0])} ({v[1]})" if v[0] else "0"
        if v[1] in ("ior", "extinction") and v[2] is not None and v[2] < v[0] / 10:
            txt += f"; {C.sci(v[2])} ÷ cond"
        return txt

    for r in res["catalogue"]:
        cl = r["cols"]
        rows.append([f"{r['title']} [{r['n']}]", cell(cl["f64"]), cell(cl["f32"]),
                     cell(cl["shader"]), cell(cl["printed64"]), cell(cl["printed32"]),
                     r["product"], r["visible"]])
    L.append(C.md_table(header, rows) + "\n")
    bad = [(r["title"], b) for r in res["catalogue"] for b in r.get("bad_shader", [])]
    if bad:
        L.append("**Shader cases whose error is not explained by conditioning** (error > 1e-3 "
                 "after dividing the η, κ errors by 1/(1-r)):\n")
        rows = []
        for title, b in bad:
            c = b["case"]
            desc = (f"r_c={tuple(round(x, 6) for x in c['rc'])}, g={c['g'][0]:g}, R={c['R']:g}, "
                    f"β_h={c['bh']:g}, λ=({c['lx']:g}, {c['ly']:g}), w={c['w']}")
            rows.append([title.split(" (")[0], desc, b["field"],
                         ", ".join(f"{x:.6g}" for x in b["got"]),
                         ", ".join(f"{x:.6g}" for x in b["ref"])])
        L.append(C.md_table(["row", "case", "field", "shader", "reference"], rows) + "\n")
    L.append("η and κ grow like 1/(1-r): an implementation that forms r and then subtracts it "
             "from 1 loses 2^-24 · r/(1-r) relative in float32 (~6e-3 at r = 1 - 1e-5). Cells "
             "marked '÷ cond' give, after the raw worst error, the worst error with the η, κ "
             "errors divided by that condition number 1/(1-r); where no such mark appears the "
             "path computes 1 - r without cancellation.\n")
    L.append("### b ≈ 1: the printed root against the stable form\n")
    L.append(f"λ_h = 0.3 (p = 1/1.69), w = 4, β_h = 0.6, so r*_c = {res['r_star']:.6f}; r_c "
             "steps away from r*_c by 0, 1, 4, 16, ... ulp of each precision. The printed root "
             "(b - √Δ)/(2(b-1)) cancels as b -> 1 and its Taylor window covers only a few ulp; "
             "the stable form has no b - 1 at all.\n")
    L.append(f"![Bézier error near r*_c]({res['fig_bezier']})\n")
    rows = [[k, C.sci(v["worst_near"]), C.sci(v["worst"])] for k, v in res["bez_summary"].items()]
    L.append(C.md_table(["path", "worst rel. error of k̂_h, |r_c - r*_c| <= 1e-3",
                         "worst over the sweep"], rows) + "\n")
    L.append("### Gulbrandsen near r = 1\n")
    L.append(f"![Gulbrandsen κ error]({res['fig_gulbrandsen']})\n")
    rows = [[k, C.sci(v)] for k, v in res["gul_summary"].items()]
    L.append(C.md_table(["path", "worst rel. error of κ, 1 - r from ε to 0.5"], rows) + "\n")
    L.append("### NaN, infinite and out-of-range texels\n")
    L.append("One input at a time set to a bad value (others: gold r_c, g, R 0.3, anisotropy "
             "0.3, β_h 0.6, λ_h 5, w 2). numpy = the float32 texture path (strict=False: clamp "
             "and count); shader = what Cycles computes from a float32 texture holding the value "
             "(the anisotropic smooth graph).\n")
    rows = []
    readback = next((b["readback"] for b in res["bad"] if "readback" in b), None)
    for b in res["bad"]:
        if "readback" in b:
            continue
        rows.append([b["param"], b["value"], "yes" if b["numpy_finite"] else "**no**",
                     f"{b['numpy_beta']:.4g}", b["numpy_warnings"],
                     ("yes" if b.get("shader_finite") else "**no**") if "shader_finite" in b else "-",
                     f"{b['shader_beta']:.4g}" if "shader_beta" in b else "-"])
    L.append(C.md_table(["input", "value", "numpy outputs finite", "numpy β", "numpy warning",
                         "shader outputs finite", "shader β"], rows) + "\n")
    if readback:
        L.append("The shader never sees a non-finite value: Cycles replaces non-finite texels of a "
                 "float image by 0 when it loads it, and sometimes the other channels of the same "
                 "texel too (the probe packs roughness, haziness and λ_x in one RGB texel; "
                 "written -> read by Cycles: " + "; ".join(
                     f"({', '.join(f'{x:g}' for x in a)}) -> ({', '.join(f'{x:g}' for x in b)})"
                     for a, b in readback) + "). So a NaN in one packed map can zero its "
                 "neighbours: a haze map with NaN texels renders those texels without haze "
                 "(β_h = 0), where the numpy conversion clamps channel by channel. Where both "
                 "paths see the same (clamped) value they agree.\n")
    L.append("### 8-bit quantisation of each input map\n")
    L.append("Each input swept over its range (2001 values; others as above, grey r_c 0.6) and "
             "stored as an 8-bit texel; the table gives the worst change of each output (absolute "
             "for β, k̂_h, r, which live in [0, 1]; relative for η, κ, α_w) in the float64 "
             "mapping, and the input value where it happens. Physical outputs move by "
             "about one quantisation step times their sensitivity; the large entries are where an "
             "output is ill-conditioned (η, κ near r = 1, k̂_h near r_c = 1).\n")
    outs = ("beta", "halo_intensity", "reflectivity", "ior", "extinction", "alpha_wide")
    rows = []
    for q in res["quant"]:
        rows.append([q["input"], q["encoding"]] + [f"{C.sci(q['worst'][o][0])} @ {q['worst'][o][1]:.3g}"
                                                    for o in outs])
    L.append(C.md_table(["input", "encoding", "β (abs)", "k̂_h (abs)", "r (abs)", "η (rel)",
                         "κ (rel)", "α_w (rel)"], rows) + "\n")
    L.append("The largest entries are where an output is ill-conditioned: η and κ as r -> 1 (one "
             "8-bit step of r_c or haziness near 1 changes 1 - r, hence η, κ ∝ 1/(1 - r), by a "
             "large factor), and α_w at the mirror cut-off (R's first code 1/255 = 0.0039 is "
             "raised to 0.004, the next is 0.0078: α differs by 4x). Store r_c and haziness "
             "maps that approach 1 in 16 bits or float. Haze extent in 8 bits (here λ/20) moves β "
             "by a few 1e-2 at small λ, where p changes fastest.\n")
    L.append("### Visible effects\n")
    v = res["vis"]
    L.append("A plane seen from above under a small point light 1 m above its centre (hazy gold "
             "conductor, β_h 0.9, Cycles 16 spp); images at +3 stops so the halo shows (the core "
             "saturates), right: radiance through the centre, log scale.\n")
    L.append(f"α_w clamp, R = 0.3 (α = 0.09): α_w reaches Cycles' limit 1 at λ_h ≈ 10; beyond it "
             f"the halo no longer widens (λ_h 30 and 300 differ by "
             f"{C.sci(v['aw']['max_rel_diff_last_two'])} of the peak).\n")
    L.append(f"![α_w clamp]({v['aw']['fig']})\n")
    L.append(f"Aspect clamp, R = 0.2: past 10:1 the halo stops stretching (10:1 and 50:1 differ "
             f"by {C.sci(v['aspect']['max_rel_diff_last_two'])} of the peak).\n")
    L.append(f"![aspect clamp]({v['aspect']['fig']})\n")
    pk = v["rc1"]["peaks"]
    agree = abs(pk[2] / pk[1] - 1) < 1e-2
    if agree:
        L.append(f"r_c = 1 exactly (e.g. a white 8-bit texel), lean (numpy mapping) and "
                 f"in-shader: both give β = 0 (no room for haze), the core alone; peaks "
                 f"{', '.join(f'{x:.4g}' for x in pk)} (lean r_c = 0.999, lean r_c = 1, in-shader "
                 f"r_c = 1).\n")
    else:
        L.append(f"r_c = 1 exactly (e.g. a white 8-bit texel): the lean and in-shader materials "
                 f"disagree (peaks {', '.join(f'{x:.4g}' for x in pk)}: lean r_c = 0.999, lean "
                 f"r_c = 1, in-shader r_c = 1); see the shader cases listed under the "
                 f"catalogue.\n")
    L.append(f"![r_c = 1]({v['rc1']['fig']})\n")
    return "\n".join(L)


if __name__ == "__main__":
    main()
