# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy materials in and out of Blender: MaterialX, USD and other engines (bpy-free).

- :mod:`.materialx` writes each hazy material as an exact Eq. 1 graph of the MaterialX 1.39
  standard ``pbr`` library (xml.etree: the ``materialx`` package is not needed);
  :mod:`.materialx_import` reads documents back (:mod:`.document`'s streaming reader, values
  as MaterialX 1.39.5 reads them): Eq. 1 graphs as hazy materials, the surfaces material
  libraries ship (OpenPBR 1.1 / 1.2, standard_surface, gltf_pbr, UsdPreviewSurface) as
  Principled BSDF specs (:mod:`.surfaces`), OpenPBR 1.2's haze as haze-layer parameters
  (:mod:`.haze_blend`), the add-on's layered exports as their layer;
- :mod:`.layered` writes a material with a haze layer (Make Hazy) as its own network:
  OpenPBR surfaces / pbr BSDFs mixed by β as the Blender tree mixes them, textures and the
  layer's node math included;
- :mod:`.usd` writes the same network as UsdShade (usd-core's ``pxr``, only when installed) with
  a UsdPreviewSurface of the core lobe, and reads it back;
- :mod:`.engines` gives the closest Unity StackLit / Unreal Substrate / Filament / OpenPBR 1.2
  parameters with their BRDF error against Eq. 1 (:mod:`.brdf`, numpy).

Every path starts from :func:`hazy_gloss.core.lobes.describe`; see docs/interchange.md.
"""
