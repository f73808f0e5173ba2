# SPDX-License-Identifier: GPL-3.0-or-later
"""Built-in material presets: the paper's Table 3 and the examples of its figures (bpy-free).

Barla, Pacanowski & Vangorp 2018, "A Composite BRDF Model for Hazy Gloss".  The paper gives the
narrow roughness as α_n (the microfacet α); the add-on's ``roughness`` is Blender's R = √α, so
every preset stores the paper's α_n in ``alpha`` and :meth:`Preset.parameters` gives Blender's R.

Where the paper does not print a value (the colour of a "dark greenish Lambertian base", the
conductor reflectivity of Figure 3's bottom row, a single haziness for a figure that sweeps it)
the preset says so in ``notes``; those values are ours, chosen to look like the figure.

``parameters(preset_id)`` returns keyword arguments for ``hazy_gloss.api.create_material`` /
``update_material`` (every perceptual parameter, so applying a preset fully defines the look).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ("Preset", "PRESETS", "parameters", "enum_items", "roughness_from_alpha")


def roughness_from_alpha(alpha):
    """Blender's R = √α from the paper's α_n."""
    return math.sqrt(alpha)


@dataclass(frozen=True)
class Preset:
    id: str
    name: str
    source: str  #: where in the paper the values come from
    kind: str  #: CONDUCTOR / DIELECTRIC / LEGACY
    core_reflectivity: tuple  #: r_c (RGB, linear)
    edge_tint: tuple  #: g (RGB); (0, 0, 0) for dielectrics
    alpha: float  #: α_n as printed (the paper's roughness, NOT Blender's R)
    haziness: float  #: β_h
    haze_extent: tuple  #: (λ_h^x, λ_h^y)
    base_color: tuple = (0.0, 0.0, 0.0)  #: Lambertian base under a dielectric
    notes: str = ""  #: values that are not printed in the paper
    extra: dict = field(default_factory=dict)

    @property
    def description(self):
        rc = _fmt(self.core_reflectivity)
        text = (f"{self.source}: {self.kind.lower()}, r_c {rc}, g {_fmt(self.edge_tint)}, "
                f"α_n {self.alpha:g} (R {roughness_from_alpha(self.alpha):.4g}), "
                f"β_h {self.haziness:g}, λ_h {_fmt(self.haze_extent)}")
        return text + (f". {self.notes}" if self.notes else "")

    def parameters(self):
        p = dict(kind=self.kind, distribution="GGX", core_reflectivity=self.core_reflectivity,
                 edge_tint=self.edge_tint, roughness=roughness_from_alpha(self.alpha),
                 anisotropy=0.0, rotation=0.0, haziness=self.haziness,
                 haze_extent=self.haze_extent, smoothness=None, base_color=self.base_color,
                 transmission=0.0)
        p.update(self.extra)
        return p


def _fmt(v):
    v = tuple(v)
    if len(set(v)) == 1:
        return f"{v[0]:g}"
    return "[" + ", ".join(f"{x:g}" for x in v) + "]"


def _grey(x):
    return (float(x),) * 3


_DARK_GREEN = (0.010, 0.030, 0.012)  # "dark greenish Lambertian base" (not printed)
_PURPLE = (0.05, 0.012, 0.06)  # "purple Lambertian base" (not printed)

_LIST = (
    # ---- Table 3 (Figures 1 and 11) ---------------------------------------------------------
    Preset("PROBE_A", "Probe A (dielectric)", "Table 3 / Figure 1", "DIELECTRIC",
           _grey(0.02), _grey(0.0), 0.01, 0.1, (5.0, 5.0)),
    Preset("PROBE_B", "Probe B (achromatic conductor)", "Table 3 / Figure 1", "CONDUCTOR",
           _grey(0.5), _grey(1.0), 0.01, 0.99, (5.0, 5.0)),
    Preset("FERTILITY", "Fertility (coloured conductor)", "Table 3 / Figure 11", "CONDUCTOR",
           (0.5, 0.28, 0.1), (0.8, 0.06, 0.03), 0.03, 0.99, (5.0, 5.0)),
    Preset("VASE", "Vase (dielectric, green base)", "Table 3 / Figure 11", "DIELECTRIC",
           _grey(0.05), _grey(0.0), 0.01, 0.15, (7.0, 7.0), base_color=_DARK_GREEN,
           notes="Base colour not printed (\"dark greenish Lambertian base\")"),
    Preset("TEAPOT", "Teapot (anisotropic halo)", "Table 3 / Figure 11", "CONDUCTOR",
           (0.5, 0.12, 0.12), (0.0, 0.85, 1.0), 0.01, 0.99, (10.0, 1.0),
           notes="Isotropic core; halo extent 10 along the tangent, 1 across (needs a UV map)"),
    # ---- Figure examples ---------------------------------------------------------------------
    Preset("FIG3_DIELECTRIC", "Figure 3 dielectric", "Figure 3 (top row)", "DIELECTRIC",
           _grey(0.04), _grey(0.0), 0.01, 0.1, (7.0, 7.0), base_color=_DARK_GREEN,
           notes="The figure sweeps β_h; 0.1 is the paper's rule of thumb for dielectrics. "
                 "Base colour not printed (\"greenish Lambertian term\")"),
    Preset("FIG3_CONDUCTOR", "Figure 3 conductor", "Figure 3 (bottom row)", "CONDUCTOR",
           _grey(0.8), _grey(0.0), 0.01, 0.5, (7.0, 7.0),
           notes="r_c of the conductor row not printed (0.8 chosen); the figure sweeps β_h"),
    Preset("FIG4", "Figure 4 (haze extent)", "Figure 4", "DIELECTRIC",
           _grey(0.03), _grey(0.0), 0.01, 0.1, (5.0, 5.0),
           notes="The figure varies α_n and λ_h per row/column; 0.01 and 5 chosen"),
    Preset("FIG5", "Figure 5 (coloured conductor)", "Figure 5", "CONDUCTOR",
           (0.5, 0.3, 0.12), (0.6, 0.2, 0.8), 0.01, 0.5, (5.75, 5.75),
           notes="r̂ = 0.5, α_n 0.01, λ_h 5.75 printed; the colour, the purple edge tint of the "
                 "rightmost image and β_h are ours"),
    Preset("FIG9_SPEEDSHAPE", "Figure 9 (Speedshape)", "Figure 9", "DIELECTRIC",
           _grey(0.04), _grey(0.0), 0.03, 0.1, (5.0, 5.0), base_color=_PURPLE,
           notes="Base colour not printed (\"purple Lambertian base\")"),
    Preset("FIG10", "Figure 10 (haziness map)", "Figure 10", "CONDUCTOR",
           _grey(0.5), _grey(0.0), 0.026, 0.5, (5.0, 5.0),
           notes="The figure paints β_h in [0, 0.99]; 0.5 chosen"),
)

#: id -> Preset, in menu order.
PRESETS = {p.id: p for p in _LIST}


def parameters(preset_id):
    """api keyword arguments for a built-in preset (raises KeyError with the known ids)."""
    try:
        return PRESETS[preset_id].parameters()
    except KeyError:
        raise KeyError(f"unknown preset {preset_id!r}; known: {', '.join(PRESETS)}") from None


def enum_items():
    """(identifier, name, description) triples for a bpy EnumProperty."""
    return [(p.id, p.name, p.description) for p in _LIST]
