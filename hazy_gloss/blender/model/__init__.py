# SPDX-License-Identifier: GPL-3.0-or-later
"""The kinds of hazy material in Blender, each in a home of its own: a whole hazy material
(material, material_read, material_edits, groups), a haze layer on the artist's BSDF (layer,
layer_group, layer_values, layer_notes, layer_wiring, layer_parts, layer_animation,
group_copies), converted maps (convert_inputs, convert_outputs, convert_wiring), recomposite
(recomposite), imported surfaces (surface_build), the export fallback (fallback); and the
stamps (stamp)."""
