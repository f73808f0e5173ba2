# SPDX-License-Identifier: GPL-3.0-or-later
"""Looks: whole Principled materials with a haze layer (car paint, lacquered wood, ...), bpy-free.

A look is what an artist would build by hand — a Principled BSDF with its base, coat and a few
procedural textures — plus the haze Make Hazy puts on it (``haze``: base haziness / extent and
the coat's own).  ``hazy_gloss.blender.actions.looks.create_look`` builds one; applied as a preset to a
material that already has a haze layer, only ``haze`` is used (the material stays the artist's).

The values are ours (the paper's examples are in utils.presets): chosen to read as the named
material in the gallery, with haziness in the ranges the paper recommends (dielectrics about
0-0.1, coats and metals higher).
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ("Look", "LOOKS", "enum_items")


@dataclass(frozen=True)
class Look:
    id: str
    name: str
    description: str
    principled: dict  #: Principled BSDF input name -> value
    haze: dict  #: haze parameters of the layer (api.make_hazy keywords)
    textures: tuple = ()  #: procedural set-ups by name (blender.actions.looks.TEXTURES)
    extra: dict = field(default_factory=dict)


_LIST = (
    Look("CAR_PAINT", "Car Paint",
         "Red metallic base under a clear coat; haze on the coat (fine scratches, orange peel) "
         "and a little on the metal flakes",
         {"Metallic": 1.0, "Base Color": (0.45, 0.02, 0.03, 1.0), "Roughness": 0.32,
          "Coat Weight": 1.0, "Coat Roughness": 0.03, "Coat IOR": 1.5},
         dict(haziness=0.3, haze_extent=4.0, coat_haziness=0.35, coat_haze_extent=8.0),
         textures=("flakes",)),
    Look("LACQUERED_WOOD", "Lacquered Wood",
         "Wood under a glossy lacquer whose reflection carries a soft halo",
         {"Roughness": 0.55, "Coat Weight": 1.0, "Coat Roughness": 0.05, "Coat IOR": 1.5},
         dict(haziness=0.0, coat_haziness=0.3, coat_haze_extent=7.0),
         textures=("wood",)),
    Look("SATIN_VARNISH", "Satin Varnish",
         "A satin (half-gloss) varnish on painted wood: a sharp core in a wide, strong halo",
         {"Base Color": (0.55, 0.6, 0.5, 1.0), "Roughness": 0.5, "Coat Weight": 1.0,
          "Coat Roughness": 0.12, "Coat IOR": 1.5},
         dict(haziness=0.0, coat_haziness=0.6, coat_haze_extent=5.0)),
    Look("BRUSHED_ALUMINIUM", "Brushed Aluminium",
         "Anisotropic metal with a halo stretched along the brushing",
         {"Metallic": 1.0, "Base Color": (0.91, 0.92, 0.92, 1.0), "Roughness": 0.22,
          "Anisotropic": 0.6, "Specular Tint": (0.98, 0.98, 1.0, 1.0)},
         dict(haziness=0.7, haze_extent=(10.0, 2.0)),
         textures=("radial_tangent",)),
    Look("WORN_PLASTIC", "Worn Plastic",
         "Blue plastic, polished in places and dulled in others: a little haze on a textured "
         "roughness (the haze mapping runs per pixel)",
         {"Base Color": (0.05, 0.16, 0.5, 1.0), "Roughness": 0.3},
         dict(haziness=0.08, haze_extent=6.0),
         textures=("worn_roughness",)),
    Look("GLOSSY_PLASTIC", "Glossy Plastic",
         "Red plastic with a soft halo around its highlights; the body colour kept under the "
         "haze (Keep Body Colour)",
         {"Base Color": (0.5, 0.04, 0.03, 1.0), "Roughness": 0.12},
         dict(haziness=0.1, haze_extent=6.0, keep_body_colour=True)),
)

#: id -> Look, in menu order.
LOOKS = {look.id: look for look in _LIST}


def enum_items():
    """(identifier, name, description) triples for a bpy EnumProperty."""
    return [(look.id, look.name, look.description) for look in _LIST]
