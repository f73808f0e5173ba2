# SPDX-License-Identifier: GPL-3.0-or-later
"""Names vulture cannot see used (tests/pure/test_dead_code.py scans hazy_gloss/ with this file):
each is read by Blender, by getattr, by the documentation or by the build tooling.  Blender's
class attributes (``bl_*``, operator callbacks, preset and file-browser settings) are passed to
vulture as ``ignore_names`` in the test instead."""
# flake8: noqa
_ = object()

# Properties Blender's UI and the preset files read by name (layout.prop(settings, "..."))
_.haze_extent_x, _.eevee_output
# Convert Maps' per-map operator properties, read as getattr(self, f"{name}_path" / "_image")
_.core_reflectivity_image, _.core_reflectivity_path, _.edge_tint_image, _.edge_tint_path
_.roughness_image, _.roughness_path, _.anisotropy_image, _.anisotropy_path, _.rotation_image
_.rotation_path, _.haziness_image, _.haziness_path, _.haze_extent_image, _.haze_extent_path
_.haze_extent_y_image, _.haze_extent_y_path, _.base_color_path, _.metallic_path, _.normal_path
_.coat_path, _.alpha_path
# Result fields (NamedTuples and dataclasses callers and tests read)
_.fit_error_hemisphere, _.fit_rms, _.c_max, _.darkening_face_on, _.darkening_average
_.energy_narrow, _.energy_wide, _.energy_reference, _.halo_max, _.compression, _.data_window
_.evaluations, _.physical, _.deviation
# Generated tables read with getattr(tables, f"..._V{version}")
_.IOR_S_V4, _.IOR_S_V53, _.E_V4, _.E_V53, _.GLASS_E_MU1_V4, _.GLASS_E_MU1_V53
# Documented API (docs/compositing.md, docs/body-colour.md), the asset library build
# (node_groups/build_library.py) and the layer groups the extension ships (scripts/build.py)
_.recomposite, _.compensated_base, _.catalog_definitions, _.CATALOG_FILE, _.write_shipped
# Schema columns only docs/parameters.md's generator reads (scripts/parameter_table.py)
_.symbol, _.doc_layer, _.range_note
# The node counts script (scripts/node_counts.py) and the benchmarks read it
_.varying_math
