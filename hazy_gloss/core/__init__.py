# SPDX-License-Identifier: GPL-3.0-or-later
"""bpy-free core of hazy_gloss: the haze mapping (Barla et al. 2018) and its helpers.

Nothing here imports bpy, so pipelines, tests and the texture converter can use it anywhere.
"""
from .mapping import (  # noqa: F401
    DISTRIBUTIONS,
    HazeMapping,
    PerceptualParameters,
    dielectric_ior,
    gulbrandsen_inverse,
    gulbrandsen_ior,
    haze_intensity,
    haze_mapping,
    inverse_haze_mapping,
    peak_ratio,
    wide_roughness,
)
