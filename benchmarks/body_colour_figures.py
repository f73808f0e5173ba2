# SPDX-License-Identifier: GPL-3.0-or-later
"""Figures of docs/body-colour.md (bpy-free, a few seconds; not part of the test suite).

    .venv/bin/python benchmarks/body_colour_figures.py

Prints, from hazy_gloss.core.body_colour alone: how the Cycles generations differ in A, what
Multiscatter GGX changes, the body darkening of hazy Principled materials with and without the
compensation (haziness 0.1 and 0.5; white 0.8, red (0.8, 0.1, 0.1), dark 0.05), and the fit
error by polynomial degree.  The render-measured figures come from tests/blender
(out/measurements/body_colour.json).
"""
from __future__ import annotations

import itertools
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from hazy_gloss.core import body_colour as bc  # noqa: E402
from hazy_gloss.core.lobes import describe  # noqa: E402


def hazy(ior, roughness, haziness, distribution="GGX", extent=5.0):
    """(β, α_wide, IOR') of a Principled core as blender/model/layer.py computes them."""
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2
    d = describe("DIELECTRIC", distribution, core_reflectivity=(f0,) * 3, roughness=roughness,
                 haziness=haziness, haze_extent=extent)
    gain = float(d.mapping.reflectivity_max) / float(np.max(d.mapping.core_reflectivity))
    q = np.sqrt(min(f0 * gain, 1 - 2 ** -23))
    return float(d.beta), float(d.wide.roughness) ** 2, float((1 + q) / (1 - q))


def versions():
    r = np.linspace(0, 1, 41)[:, None, None]
    mu80 = np.cos(np.radians(np.linspace(0, 80, 33)))[None, :, None]
    mu = np.linspace(0, 1, 201)[None, :, None]
    ior = np.array([1.05, 1.33, 1.5, 2.0, 2.5, 5.0, 12.0, 40.0])
    print("## Generations (roughness 0-1, IOR 1.05-40)")
    for name, m in (("0-80 deg", mu80), ("0-90 deg", mu)):
        a45 = bc.specular_albedo(r * r, r * r, m, ior, version="4.5")
        a53 = bc.specular_albedo(r * r, r * r, m, ior, version="5.3")
        d = np.abs(a53 - a45)
        print(f"  |A(5.3) - A(4.5)| {name}: max {d.max():.2e}, median {np.median(d):.1e}; "
              f"relative to the body 1 - A: max {(d / (1 - a45)).max():.2e}")
    print("## Multiscatter GGX / GGX layer albedo (5.3)")
    for rough, i in itertools.product((0.3, 0.6, 1.0), (1.5, 5.0)):
        m = np.array([1.0, 0.5, 0.17])
        g = bc.specular_albedo(rough ** 2, rough ** 2, m, i)
        ms = bc.specular_albedo(rough ** 2, rough ** 2, m, i, distribution="MULTI_GGX")
        print(f"  R {rough} IOR {i}: A_ggx {np.round(g, 4)}, A_ms/A_ggx {np.round(ms / g, 4)}"
              " (mu 1, 0.5, 0.17)")


def darkening():
    print("## Body darkening, 5.3, GGX, IOR 1.5, degree 3 (face-on / 2mu-weighted average)")
    bases = {"white 0.8": (0.8, 0.8, 0.8), "red (0.8, 0.1, 0.1)": (0.8, 0.1, 0.1),
             "dark 0.05": (0.05, 0.05, 0.05)}
    for rough, h in itertools.product((0.1, 0.3, 0.6), (0.1, 0.5)):
        beta, aw, ior_h = hazy(1.5, rough, h)
        first = True
        for name, base in bases.items():
            c = bc.compensation(rough ** 2, 1.5, ior_h, beta, aw, base)
            if first:
                print(f"  R {rough} haziness {h}: beta {beta:.3f}, R_w {np.sqrt(aw):.3f}, "
                      f"IOR' {ior_h:.3f}; c(face-on) {c.c_face_on[0]:.3f}; uncompensated "
                      f"{100 * c.darkening_face_on[0]:.1f}% / {100 * c.darkening_average[0]:.1f}%;"
                      f" fit {100 * c.fit_error:.2f}% (0-80 deg), rms {100 * c.fit_rms:.2f}%")
                first = False
            res = " ".join(f"{100 * f:.1f}/{100 * a:.1f}"
                           for f, a in zip(c.residual_face_on, c.residual_average))
            print(f"     {name:20s} left by the clamp (R G B, %): {res}")


def degrees():
    print("## Fit error by degree (IOR 1.33-2.5, R 0.05-0.8, haziness 0.1 and 0.5; 5.3 and 4.5)")
    for deg in range(1, 6):
        errs, rms = [], []
        for v, i, rough, h in itertools.product(("5.3", "4.5"), (1.33, 1.5, 2.0, 2.5),
                                                (0.05, 0.1, 0.2, 0.3, 0.5, 0.8), (0.1, 0.5)):
            beta, aw, ior_h = hazy(i, rough, h)
            c = bc.compensation(rough ** 2, i, ior_h, beta, aw, degree=deg, version=v)
            errs.append(c.fit_error)
            rms.append(c.fit_rms)
        print(f"  degree {deg} ({deg + 3} nodes): 0-80 deg max {100 * max(errs):.2f}%, median "
              f"{100 * np.median(errs):.3f}%; hemisphere rms max {100 * max(rms):.2f}%, "
              f"median {100 * np.median(rms):.2f}%")


if __name__ == "__main__":
    versions()
    darkening()
    degrees()
