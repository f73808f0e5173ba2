# SPDX-License-Identifier: GPL-3.0-or-later
"""Measure the accuracy of hazy_gloss.core.haze_mapping against the mpmath reference and
tabulate where the inverse mapping is a bijection.

    .venv/bin/python tests/pure/measure_errors.py [--samples N] [--seed S]

Prints
1. float64: worst RELATIVE error per output field (random inputs over the domain + the stiff
   cases of hg_support.stiff_cases()) and where it occurs;
2. float32: worst ABSOLUTE error of k_h, β, r, p (inputs rounded to float32; reference of the
   float32 inputs);
3. Eq. 7 near its branch point as p -> 1: error vs λ_h at r_c within ulps of p;
4. the bijection table of inverse_haze_mapping (where it holds / breaks, flagged or not).

η/κ "(raw)" are end-to-end relative errors (asserted since c4fe0fd, which computes 1 - r without
cancellation); "/cond" divides them by the condition number 1/(1-r) of η(r), κ(r); "@r" compares
with the reference Gulbrandsen at the code's reported (rounded) r — only meaningful for an
implementation that derives η, κ from that rounded r, so since c4fe0fd it shows the rounding
of r amplified by 1/(1-r) (reported, not asserted).
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
for _p in (str(_HERE.parents[1]), str(_HERE)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import mpmath  # noqa: E402
import numpy as np  # noqa: E402

import hg_support as S  # noqa: E402
import reference as R  # noqa: E402
from hazy_gloss.core import haze_mapping, inverse_haze_mapping  # noqa: E402


def random_cases(rng, n):
    cases = []
    for _ in range(n):
        u = rng.uniform
        rc = tuple(u(0, 1, 3) * u(0, 1)) if u() < 0.5 else float(u(0, 1))
        if u() < 0.05:
            rc = 10 ** u(-200, -1)
        g = 0.0 if u() < 0.3 else (tuple(u(0, 1, 3)) if u() < 0.5 else float(u(0, 1)))
        a = 10 ** u(-8, 0.5, 2)
        alpha = (float(a[0]), float(a[1])) if u() < 0.5 else float(a[0])
        lam = 10 ** u(-9, 9, 2)
        lam = (float(lam[0]), float(lam[1])) if u() < 0.5 else float(lam[0])
        bh = float(u(0, 1)) if u() < 0.9 else float(1 - 10 ** u(-15, -1))
        w = [None, math.inf, float(10 ** u(-8, 15))][int(rng.integers(3))]
        dist = S.DISTS[int(rng.integers(4))]
        am = None if u() < 0.7 else 1.0
        cases.append(("random", dict(core_reflectivity=rc, edge_tint=g, alpha=alpha, haziness=bh,
                                     haze_extent=lam, distribution=dist, smoothness=w,
                                     alpha_max=am)))
    return cases


def measure64(cases):
    worst = S.Worst()
    for label, kw in cases:
        out = haze_mapping(**kw)
        errs = S.errors64(out, S.reference_for(kw))
        for f, e in errs.items():
            worst.add("float64", f, e, f"{label} | {S.describe(kw)}")
    return worst


def measure32(cases):
    worst = S.Worst()
    for label, kw in cases:
        kw = S.to_float32(kw)
        out = haze_mapping(**kw)
        ref = S.reference_for(kw, eps=S.EPS32)
        errs = S.errors32(out, ref)
        for f, e in errs.items():
            worst.add("float32", f, e, f"{label} | {S.describe(kw)}")
    return worst


def branch_defect_table():
    rows = []
    for dtype, lams in ((np.float64, (1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14, 1e-17)),
                        (np.float32, (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-7, 1e-10))):
        t = dtype
        eps = S.EPS32 if t is np.float32 else S.EPS64
        for lam in lams:
            p = R.haze_mapping(0.5, 0.0, t(0.01), 0.5, t(lam))["peak_ratio"]
            worst = (0.0, None)
            start = t(float(p))
            cands = []
            for k in range(-8, 9):
                x = start
                for _ in range(abs(k)):
                    x = np.nextafter(x, t(1) if k > 0 else t(0))
                cands.append(x)
            cands.append(t(1.0))
            for rc in cands:
                out = haze_mapping(t(rc), t(0.0), t(0.01), t(0.9), t(lam))
                ref = R.haze_mapping(t(rc), 0.0, t(0.01), t(0.9), t(lam), eps=eps)
                e = (S.rel_err(out.halo_intensity, ref["halo_intensity"]) if t is np.float64
                     else S.abs_err(out.halo_intensity, ref["halo_intensity"]))
                if e > worst[0]:
                    worst = (e, (repr(float(rc)), float(out.halo_intensity),
                                 mpmath.nstr(ref["halo_intensity"], 10)))
            rows.append((np.dtype(t).name, lam, worst))
    return rows


def _inv_row(name, inv, recovered):
    exact = bool(np.all(inv.exact))
    unique = getattr(inv, "unique", None)
    unique = "-" if unique is None else str(bool(np.all(unique)))
    flags = "; ".join(f"{k}: {v}" for k, v in inv.clamped.items()) or "-"
    return (name, "yes" if recovered else "NO", "True" if exact else "False", unique, flags)


def bijection_table():
    rows = []
    # holds: Eq. 7 and Bézier, conductor and legacy
    for w in (None, 2.0):
        for mode in ("legacy", "conductor"):
            kw = dict(core_reflectivity=(0.9, 0.5, 0.2), edge_tint=0.0 if mode == "legacy" else 0.4,
                      alpha=(0.02, 0.05), haziness=0.3, haze_extent=(5.0, 2.0), smoothness=w)
            out = haze_mapping(**kw)
            if mode == "legacy":
                inv = inverse_haze_mapping(out.beta, (0.02, 0.05), out.alpha_wide,
                                           reflectivity=out.reflectivity, smoothness=w)
            else:
                inv = inverse_haze_mapping(out.beta, (0.02, 0.05), out.alpha_wide, ior=out.ior,
                                           extinction=out.extinction, smoothness=w)
            err = max(float(np.max(np.abs(inv.core_reflectivity - np.array([0.9, 0.5, 0.2])))),
                      abs(float(inv.haziness) - 0.3),
                      abs(float(inv.haze_extent[0]) - 5.0), abs(float(inv.haze_extent[1]) - 2.0))
            rows.append(_inv_row(f"generic r_c, {mode}, w={w} (max err {err:.1e})", inv,
                                 err < 1e-9))
    # r_c = 1
    out = haze_mapping(1.0, 0.5, 0.1, 0.6, 2.0)
    inv = inverse_haze_mapping(out.beta, 0.1, out.alpha_wide, ior=out.ior,
                               extinction=out.extinction)
    rows.append(_inv_row("r_c = 1, β_h = 0.6 (-> β = 0), via η, κ", inv,
                         abs(float(inv.haziness) - 0.6) < 1e-9))
    inv = inverse_haze_mapping(out.beta, 0.1, out.alpha_wide, reflectivity=out.reflectivity)
    rows.append(_inv_row("r_c = 1, β_h = 0.6 (-> β = 0), via r", inv,
                         abs(float(inv.haziness) - 0.6) < 1e-9))
    inv = inverse_haze_mapping(0.3, 0.1, 0.3, reflectivity=1.0)
    rows.append(_inv_row("physical r = 1, β = 0.3", inv, False))
    # α_w at alpha_max / AS clamp
    out = haze_mapping(0.3, 0.0, 0.2, 0.4, 9.0, alpha_max=1.0)
    inv = inverse_haze_mapping(out.beta, 0.2, out.alpha_wide, reflectivity=out.reflectivity,
                               alpha_max=1.0)
    rows.append(_inv_row("α_w limited by alpha_max=1 (λ_h = 9)", inv,
                         abs(float(inv.haze_extent[0]) - 9) < 1e-9))
    out = haze_mapping(0.3, 0.0, 0.2, 0.4, 9.0, distribution="ASHIKHMIN_SHIRLEY")
    inv = inverse_haze_mapping(out.beta, 0.2, out.alpha_wide, reflectivity=out.reflectivity,
                               distribution="ASHIKHMIN_SHIRLEY")
    rows.append(_inv_row("α_w at Cycles' AS clamp 1 (λ_h = 9)", inv,
                         abs(float(inv.haze_extent[0]) - 9) < 1e-9))
    # β_h >= 1
    out = haze_mapping(0.5, 0.0, 0.1, 0.99, (1.0, 0.0))
    inv = inverse_haze_mapping(out.beta, 0.1, out.alpha_wide, reflectivity=out.reflectivity,
                               smoothness=1.0)
    rows.append(_inv_row("Eq. 7 point outside the Bézier (w=1) reach", inv, False))
    inv = inverse_haze_mapping(1.0, 0.1, 0.4, reflectivity=0.5)
    rows.append(_inv_row("β = 1 (β_h would be 1)", inv, False))
    # α_w < α_n
    inv = inverse_haze_mapping(0.2, (0.1, 0.2), (0.05, 0.3), reflectivity=0.4)
    rows.append(_inv_row("α_w < α_n on x", inv, False))
    # off manifold / boundary of the manifold
    inv = inverse_haze_mapping(0.2, 0.1, 0.3, ior=0.5, extinction=0.1)
    rows.append(_inv_row("(η, κ) = (0.5, 0.1): off Gulbrandsen's manifold", inv, False))
    out = haze_mapping(0.875, 0.0, 0.1, 0.0, 1.0)
    inv = inverse_haze_mapping(out.beta, 0.1, out.alpha_wide, ior=out.ior,
                               extinction=out.extinction)
    rows.append(_inv_row("dielectric g = 0 given as η, κ=0 (r = 0.875)", inv,
                         float(np.max(np.abs(inv.edge_tint))) < 1e-12))
    out = haze_mapping(0.9953090836814844, 0.0, 0.5, 0.0, 0.0)
    inv = inverse_haze_mapping(out.beta, 0.5, out.alpha_wide, ior=out.ior,
                               extinction=out.extinction)
    rows.append(_inv_row("dielectric g = 0 given as η, κ=0 (r = 0.99531)", inv,
                         float(np.max(np.abs(inv.edge_tint))) < 1e-12))
    # r = 0: g has no effect
    out = haze_mapping(0.0, 0.7, 0.1, 0.3, 2.0)
    inv = inverse_haze_mapping(out.beta, 0.1, out.alpha_wide, ior=out.ior,
                               extinction=out.extinction)
    rows.append(_inv_row("r_c = 0, g = 0.7 (η = 1, κ = 0 for every g)", inv,
                         abs(float(inv.edge_tint[0]) - 0.7) < 1e-9))
    # λ_h = 0 and α_n = 0
    out = haze_mapping(0.4, 0.0, 0.0, 0.3, 5.0)
    inv = inverse_haze_mapping(out.beta, 0.0, out.alpha_wide, reflectivity=out.reflectivity)
    rows.append(_inv_row("α_n = 0 (λ_h = 5 has no effect on α_w = 0)", inv,
                         abs(float(inv.haze_extent[0]) - 5) < 1e-9))
    inv = inverse_haze_mapping(0.3, 0.0, (0.1, 0.1), reflectivity=0.5)
    rows.append(_inv_row("physical α_n = 0 < α_w = 0.1 (not reproducible)", inv, False))
    # texture call
    try:
        inv = inverse_haze_mapping(np.full(4, 0.2), 0.1, 0.3, reflectivity=np.full((4, 3), 0.5))
        one = inverse_haze_mapping(0.2, 0.1, 0.3, reflectivity=0.5)
        rows.append(_inv_row("texture call, 4 texels (= scalar call)", inv,
                             bool(np.all(inv.haziness == one.haziness))))
    except ValueError as exc:
        rows.append(("texture call, 4 texels", "NO", "-", "-", f"ValueError: {str(exc)[:60]}"))
    return rows


def _print_worst(title, worst):
    print(title)
    for line in worst.lines() or ["  (none)"]:
        print(line)
    print()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=1500)
    ap.add_argument("--seed", type=int, default=2018)
    args = ap.parse_args(argv)
    t0 = time.time()
    rng = np.random.default_rng(args.seed)
    stiff = S.stiff_cases()
    rand = random_cases(rng, args.samples)

    w64 = measure64(rand + stiff)
    _print_worst(f"== float64 relative errors ({len(rand)} random + {len(stiff)} stiff cases; "
                 f"tolerance {S.REL64:g}; /cond tolerance {S.COND_TOL64:.2g}) ==", w64)
    w32 = measure32(rand[: len(rand) // 2] + stiff[::2])
    _print_worst(f"== float32 absolute errors (tolerance {S.ABS32:g}) ==", w32)

    print("== Eq. 7 branch selection as p -> 1 (β_h = 0.9, α = 0.01, r_c within 8 ulp of p "
          "or = 1; was wrong before 274b5d0) ==")
    print(f"  {'dtype':<8s} {'λ_h':>8s}  {'worst k_h error':>16s}  at r_c, code k_h, reference k_h")
    for dt, lam, (e, where) in branch_defect_table():
        kind = "rel" if dt == "float64" else "abs"
        print(f"  {dt:<8s} {lam:8.0e}  {e:12.3e} {kind}  {where}")
    print()

    print("== inverse_haze_mapping: where the bijection holds / breaks ==")
    rows = bijection_table()
    w0 = max(len(r[0]) for r in rows)
    print(f"  {'case':<{w0}s}  recovered  exact  unique  flags (clamped)")
    for name, rec, exact, unique, flags in rows:
        print(f"  {name:<{w0}s}  {rec:<9s}  {exact:<5s}  {unique:<6s}  {flags}")
    print(f"\n({time.time() - t0:.1f} s)")


if __name__ == "__main__":
    main()
