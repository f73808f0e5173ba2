# SPDX-License-Identifier: GPL-3.0-or-later
"""Materials built from measured values that no one here chose: the real-materials tests
(tests/blender/test_real_materials.py) and the measured report's "real materials" section
(benchmarks/real_materials.py) put haze on each and check what holds per class.

Sources (values read off the published tables, RGB = 650 / 550 / 450 nm):
- metals: complex refractive index n + ik from the refractive index database
  (refractiveindex.info; Johnson & Christy 1972 for Au, Ag, Cu; Rakić 1995/1998 for Al, Cr,
  Ni, Pt, Ti, W; Johnson & Christy 1974 for Fe), rounded to two or three digits;
- dielectrics: refractive indices at the sodium D line (589 nm) from the CRC Handbook of
  Chemistry and Physics and the glass makers' catalogues (Schott N-BK7 1.5168, SF11 1.7847);
- diffuse colours: the X-Rite ColorChecker Classic patches, sRGB 8-bit values as published by
  BabelColor (2012 average of measured charts), turned into linear Rec.709 here;
- thin films: typical coatings (MgF2 1.38 quarter-wave on glass, soap film 1.33, oil 1.47,
  TiO2 2.4 on titanium, nacre 1.53).
A metal's Principled Base Color (F0) is its n, k's normal-incidence reflectance (computed here),
except the out-of-gamut gold: spectral gold F0 taken to linear Rec.709 has red above 1.
"""
from __future__ import annotations

#: name -> (n RGB, k RGB)
METALS = {
    "gold": ((0.166, 0.35, 1.38), (3.15, 2.73, 1.91)),
    "silver": ((0.14, 0.12, 0.13), (4.15, 3.34, 2.58)),
    "copper": ((0.21, 1.02, 1.24), (3.67, 2.58, 2.40)),
    "aluminium": ((1.49, 0.96, 0.62), (7.82, 6.69, 5.47)),
    "iron": ((2.92, 2.87, 2.63), (3.08, 2.92, 2.83)),
    "chromium": ((3.18, 3.17, 2.45), (3.31, 3.30, 3.05)),
    "nickel": ((2.00, 1.80, 1.70), (3.80, 3.40, 2.90)),
    "platinum": ((2.38, 2.07, 1.86), (4.26, 3.72, 3.21)),
    "titanium": ((2.74, 2.54, 2.16), (3.80, 3.43, 2.98)),
    "tungsten": ((3.69, 3.49, 3.36), (2.82, 2.72, 2.55)),
}

#: Base Color (F0) of metals whose colour is at or near 1 (the "no room for haze" class).
BRIGHT_METALS = {
    "gold, out-of-gamut F0": (1.059, 0.773, 0.307),
    "silver F0": None,  # from METALS
    "sodium F0": (0.977, 0.962, 0.936),
}

#: ColorChecker Classic patches, sRGB 8-bit (BabelColor average).
COLORCHECKER = {
    "dark skin": (115, 82, 68), "light skin": (194, 150, 130), "blue sky": (98, 122, 157),
    "foliage": (87, 108, 67), "orange": (214, 126, 44), "purplish blue": (80, 91, 166),
    "moderate red": (193, 90, 99), "yellow green": (157, 188, 64), "cyan": (8, 133, 161),
    "white": (243, 243, 242), "neutral 5": (122, 122, 121), "black": (52, 52, 52),
}

#: Opaque dielectrics: (IOR, ColorChecker patch, roughness).
OPAQUE = {
    "ABS plastic, orange": (1.53, "orange", 0.25),
    "acrylic paint, blue sky": (1.49, "blue sky", 0.35),
    "car paint base, moderate red": (1.50, "moderate red", 0.3),
    "rubber, black": (1.52, "black", 0.5),
    "ceramic glaze, white": (1.54, "white", 0.15),
    "leaf, foliage": (1.45, "foliage", 0.4),
    "wood varnish, dark skin": (1.50, "dark skin", 0.2),
}

#: Transmissive dielectrics: (IOR, transmission tint as linear RGB, roughness).
TRANSMISSIVE = {
    "water": (1.333, (1.0, 1.0, 1.0), 0.05),
    "ice": (1.309, (0.97, 0.99, 1.0), 0.15),
    "ethanol": (1.361, (1.0, 1.0, 1.0), 0.05),
    "olive oil": (1.467, (0.85, 0.80, 0.25), 0.1),
    "honey": (1.504, (0.83, 0.57, 0.04), 0.1),
    "soda-lime glass": (1.52, (0.98, 0.99, 0.99), 0.05),
    "N-BK7 crown glass": (1.5168, (1.0, 1.0, 1.0), 0.1),
    "SF11 flint glass": (1.7847, (1.0, 1.0, 1.0), 0.1),
    "fused silica": (1.458, (1.0, 1.0, 1.0), 0.2),
    "acrylic (PMMA)": (1.491, (1.0, 1.0, 1.0), 0.25),
    "polycarbonate": (1.586, (1.0, 1.0, 1.0), 0.3),
    "quartz": (1.544, (1.0, 1.0, 1.0), 0.1),
    "sapphire": (1.768, (0.67, 0.76, 0.86), 0.1),
    "emerald": (1.577, (0.30, 0.80, 0.50), 0.1),
    "diamond": (2.417, (1.0, 1.0, 1.0), 0.05),
}

#: Thin films: (substrate, film thickness nm, film IOR); substrate "glass" (transmissive
#: N-BK7), "water" (transmissive), "black" / "white" (opaque, ColorChecker), a metal of METALS.
FILMS = {
    "MgF2 anti-reflection on glass": ("glass", 100.0, 1.38),
    "oil film on water": ("water", 300.0, 1.47),
    "nacre on white": ("white", 400.0, 1.53),
    "varnish film on black": ("black", 400.0, 1.33),
    "TiO2 on titanium": ("titanium", 120.0, 2.4),
}


def srgb_to_linear(c):
    """sRGB 8-bit -> linear Rec.709 (IEC 61966-2-1)."""
    out = []
    for v in c:
        x = v / 255.0
        out.append(x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4)
    return tuple(out)


def metal_f0(name):
    """Normal-incidence reflectance ((n-1)² + k²) / ((n+1)² + k²) per channel."""
    n, k = METALS[name]
    return tuple(((a - 1.0) ** 2 + b * b) / ((a + 1.0) ** 2 + b * b) for a, b in zip(n, k))


def base_colour(patch):
    return srgb_to_linear(COLORCHECKER[patch])
