#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Demo (the README's main job): renders the gallery with Cycles (scripts/gallery.py: the paper's
Figure 3 rows and the Table 3 materials on spheres) to out/gallery.png, after printing the haze
mapping of the Table 3 materials.

    .venv/bin/python scripts/demo.py [--no-render] [gallery options, e.g. --samples 16]

The printed table gives the physical parameters of Eq. 1 that the perceptual parameters map to:
β (wide-lobe ratio), r (reflectivity F(0), RGB), η and κ (conductor Fresnel, RGB), α_w (wide
roughness, x/y), p (peak ratio f_w(n,n)/f_n(n,n)) and k̂_h (halo intensity).  bpy-free.

    .venv/bin/python scripts/demo.py
"""
import sys
import unicodedata
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hazy_gloss.core import haze_mapping  # noqa: E402

#: Table 3 of the paper: perceptual parameters of the materials in its figures.
#: r_c core reflectivity (RGB or grey), g edge tint (RGB or grey), α_n core roughness (α, not
#: Blender's R = √α), β_h haziness, λ_h haze extent (a scalar, or (x, y) when anisotropic).
TABLE3 = {
    "Probe A": dict(r_c=0.02, g=0.0, alpha_n=0.01, beta_h=0.1, lambda_h=5.0),
    "Probe B": dict(r_c=0.5, g=1.0, alpha_n=0.01, beta_h=0.99, lambda_h=5.0),
    "Fertility": dict(r_c=(0.5, 0.28, 0.1), g=(0.8, 0.06, 0.03), alpha_n=0.03, beta_h=0.99,
                      lambda_h=5.0),
    "Vase": dict(r_c=0.05, g=0.0, alpha_n=0.01, beta_h=0.15, lambda_h=7.0),
    "Teapot": dict(r_c=(0.5, 0.12, 0.12), g=(0.0, 0.85, 1.0), alpha_n=0.01, beta_h=0.99,
                   lambda_h=(10.0, 1.0)),
}


def _width(s):
    """Display width: combining marks (the hat of k̂) take no column."""
    return sum(not unicodedata.combining(c) for c in s)


def _pad(s, w):
    return s + " " * (w - _width(s))


def _rgb(v):
    return " ".join(f"{float(x):6.3f}" for x in v)


def main():
    header = ("material", "β", "r (RGB)", "η (RGB)", "κ (RGB)", "α_w x / y", "p", "k̂_h")
    rows = []
    for name, t in TABLE3.items():
        m = haze_mapping(t["r_c"], t["g"], t["alpha_n"], t["beta_h"], t["lambda_h"])
        wx, wy = m.alpha_wide
        rows.append((name, f"{float(m.beta):.4f}", _rgb(m.reflectivity), _rgb(m.ior),
                     _rgb(m.extinction), f"{float(wx):.4f} / {float(wy):.4f}",
                     f"{float(m.peak_ratio):.4f}", f"{float(m.halo_intensity):.4f}"))
    widths = [max(_width(r[i]) for r in rows + [header]) for i in range(len(header))]
    line = "  ".join("-" * w for w in widths)
    print("Haze mapping (Barla et al. 2018, Eq. 7, GGX) of the Table 3 materials")
    print("  ".join(_pad(h, w) for h, w in zip(header, widths)).rstrip())
    print(line)
    for r in rows:
        print("  ".join(_pad(c, w) for c, w in zip(r, widths)).rstrip())
    print()
    print("Inputs (r_c, g, α_n, β_h, λ_h):")
    for name, t in TABLE3.items():
        print(f"  {name:10s} r_c={t['r_c']}, g={t['g']}, α_n={t['alpha_n']}, "
              f"β_h={t['beta_h']}, λ_h={t['lambda_h']}")


if __name__ == "__main__":
    main()
    if "--no-render" not in sys.argv:
        import gallery  # scripts/ is on sys.path when run as a script

        gallery.main([a for a in sys.argv[1:] if a != "--no-render"])
