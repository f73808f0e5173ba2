# SPDX-License-Identifier: GPL-3.0-or-later
"""A small in-memory MaterialX document (nodes, node graphs, connections) with its XML form,
bpy-free and without the ``materialx`` package (xml.etree).

The exporters build a :class:`Document`, the XML writer and the USD writer (interchange/usd.py)
serialise the same object, and both readers produce one, so recognising a hazy material
(interchange/materialx.py) works on one representation whatever the file was.

:data:`NODEDEFS` lists the standard-library nodedefs the add-on writes or reads (MaterialX 1.39,
checked against the installed library by tests/pure/test_interchange.py): their category,
output type, input types and the defaults the reader needs (the package is not required).
"""
from __future__ import annotations

import io
import math
import os
import re
import xml.etree.ElementTree as ET  # writing
from dataclasses import dataclass, field
from xml.parsers import expat  # reading

from .. import constants as K

__all__ = ("Input", "Node", "NodeGraph", "Document", "NODEDEFS", "format_value", "parse_value",
           "valid_name", "read_xml", "write_xml", "to_xml_string", "OPENPBR_12_INPUTS",
           "OPENPBR_INPUTS", "OPENPBR_UNSUPPORTED")

# --------------------------------------------------------------------------------------------
# The nodedefs used (name -> category, output type, {input: (type, default)})
# --------------------------------------------------------------------------------------------

_N3 = "Nworld"
_T3 = "Tworld"
_IMAGE_UV = {"texcoord": ("vector2", "UV0"), "uaddressmode": ("string", "periodic"),
             "vaddressmode": ("string", "periodic")}
NODEDEFS = {
    "ND_conductor_bsdf": ("conductor_bsdf", "BSDF", {
        "weight": ("float", 1.0), "ior": ("color3", (0.183, 0.421, 1.373)),
        "extinction": ("color3", (3.424, 2.346, 1.77)), "roughness": ("vector2", (0.05, 0.05)),
        "retroreflective": ("boolean", False), "thinfilm_thickness": ("float", 0.0),
        "thinfilm_ior": ("float", 1.5), "normal": ("vector3", _N3), "tangent": ("vector3", _T3),
        "distribution": ("string", "ggx")}),
    "ND_dielectric_bsdf": ("dielectric_bsdf", "BSDF", {
        "weight": ("float", 1.0), "tint": ("color3", (1.0, 1.0, 1.0)), "ior": ("float", 1.5),
        "roughness": ("vector2", (0.05, 0.05)), "retroreflective": ("boolean", False),
        "thinfilm_thickness": ("float", 0.0), "thinfilm_ior": ("float", 1.5),
        "normal": ("vector3", _N3), "tangent": ("vector3", _T3), "distribution": ("string", "ggx"),
        "scatter_mode": ("string", "R")}),
    "ND_generalized_schlick_bsdf": ("generalized_schlick_bsdf", "BSDF", {
        "weight": ("float", 1.0), "color0": ("color3", (1.0, 1.0, 1.0)),
        "color82": ("color3", (1.0, 1.0, 1.0)), "color90": ("color3", (1.0, 1.0, 1.0)),
        "exponent": ("float", 5.0), "roughness": ("vector2", (0.05, 0.05)),
        "retroreflective": ("boolean", False), "thinfilm_thickness": ("float", 0.0),
        "thinfilm_ior": ("float", 1.5), "normal": ("vector3", _N3), "tangent": ("vector3", _T3),
        "distribution": ("string", "ggx"), "scatter_mode": ("string", "R")}),
    "ND_oren_nayar_diffuse_bsdf": ("oren_nayar_diffuse_bsdf", "BSDF", {
        "weight": ("float", 1.0), "color": ("color3", (0.18, 0.18, 0.18)),
        "roughness": ("float", 0.0), "normal": ("vector3", _N3),
        "energy_compensation": ("boolean", False)}),
    "ND_mix_bsdf": ("mix", "BSDF", {"fg": ("BSDF", None), "bg": ("BSDF", None), "mix": ("float", 0.0)}),
    "ND_layer_bsdf": ("layer", "BSDF", {"top": ("BSDF", None), "base": ("BSDF", None)}),
    "ND_add_bsdf": ("add", "BSDF", {"in1": ("BSDF", None), "in2": ("BSDF", None)}),
    "ND_surface": ("surface", "surfaceshader", {
        "bsdf": ("BSDF", None), "edf": ("EDF", None), "opacity": ("float", 1.0),
        "thin_walled": ("boolean", False)}),
    "ND_surfacematerial": ("surfacematerial", "material", {
        "surfaceshader": ("surfaceshader", None), "backsurfaceshader": ("surfaceshader", None),
        "displacementshader": ("displacementshader", None)}),
    "ND_image_float": ("image", "float", {"file": ("filename", ""), "default": ("float", 0.0),
                                           "filtertype": ("string", "linear"), **_IMAGE_UV}),
    "ND_image_color3": ("image", "color3", {"file": ("filename", ""),
                                             "default": ("color3", (0.0, 0.0, 0.0)),
                                             "filtertype": ("string", "linear"), **_IMAGE_UV}),
    "ND_image_color4": ("image", "color4", {"file": ("filename", ""),
                                             "default": ("color4", (0.0, 0.0, 0.0, 0.0)),
                                             "filtertype": ("string", "linear"), **_IMAGE_UV}),
    "ND_tangent_vector3": ("tangent", "vector3", {"space": ("string", "object"), "index": ("integer", 0)}),
    "ND_normal_vector3": ("normal", "vector3", {"space": ("string", "object")}),
    "ND_position_vector3": ("position", "vector3", {"space": ("string", "object")}),
    "ND_rotate3d_vector3": ("rotate3d", "vector3", {
        "in": ("vector3", (0.0, 0.0, 0.0)), "amount": ("float", 0.0), "axis": ("vector3", (0.0, 1.0, 0.0))}),
    "ND_crossproduct_vector3": ("crossproduct", "vector3", {
        "in1": ("vector3", (0.0, 0.0, 0.0)), "in2": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_normalize_vector3": ("normalize", "vector3", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_transformvector_vector3": ("transformvector", "vector3", {
        "in": ("vector3", (0.0, 0.0, 0.0)), "fromspace": ("string", ""), "tospace": ("string", "")}),
    "ND_roughness_anisotropy": ("roughness_anisotropy", "vector2", {
        "roughness": ("float", 0.0), "anisotropy": ("float", 0.0)}),
    "ND_add_float": ("add", "float", {"in1": ("float", 0.0), "in2": ("float", 0.0)}),
    "ND_add_color3": ("add", "color3", {"in1": ("color3", (0.0, 0.0, 0.0)), "in2": ("color3", (0.0, 0.0, 0.0))}),
    "ND_subtract_float": ("subtract", "float", {"in1": ("float", 0.0), "in2": ("float", 0.0)}),
    "ND_subtract_color3": ("subtract", "color3", {"in1": ("color3", (0.0, 0.0, 0.0)), "in2": ("color3", (0.0, 0.0, 0.0))}),
    "ND_multiply_float": ("multiply", "float", {"in1": ("float", 0.0), "in2": ("float", 1.0)}),
    "ND_divide_float": ("divide", "float", {"in1": ("float", 0.0), "in2": ("float", 1.0)}),
    "ND_divide_color3": ("divide", "color3", {"in1": ("color3", (0.0, 0.0, 0.0)), "in2": ("color3", (1.0, 1.0, 1.0))}),
    "ND_mix_float": ("mix", "float", {"fg": ("float", 0.0), "bg": ("float", 0.0), "mix": ("float", 0.0)}),
    "ND_mix_surfaceshader": ("mix", "surfaceshader", {
        "fg": ("surfaceshader", None), "bg": ("surfaceshader", None), "mix": ("float", 0.0)}),
    # haze layers (interchange/layered.py): the user's shading network, OpenPBR surfaces
    "ND_uniform_edf": ("uniform_edf", "EDF", {"color": ("color3", (1.0, 1.0, 1.0))}),
    "ND_texcoord_vector2": ("texcoord", "vector2", {"index": ("integer", 0)}),
    "ND_normalmap_float": ("normalmap", "vector3", {"in": ("vector3", (0.5, 0.5, 1.0)),
        "scale": ("float", 1.0), "normal": ("vector3", "Nworld"),
        "tangent": ("vector3", "Tworld"), "bitangent": ("vector3", "Bworld")}),
    "ND_viewdirection_vector3": ("viewdirection", "vector3", {"space": ("string", "world")}),
    "ND_add_vector3": ("add", "vector3", {"in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_subtract_vector3": ("subtract", "vector3", {"in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_multiply_vector3": ("multiply", "vector3", {"in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("vector3", (1.0, 1.0, 1.0))}),
    "ND_divide_vector3": ("divide", "vector3", {"in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("vector3", (1.0, 1.0, 1.0))}),
    "ND_multiply_color3": ("multiply", "color3", {"in1": ("color3", (0.0, 0.0, 0.0)),
        "in2": ("color3", (1.0, 1.0, 1.0))}),
    "ND_multiply_color3FA": ("multiply", "color3", {"in1": ("color3", (0.0, 0.0, 0.0)),
        "in2": ("float", 1.0)}),
    "ND_multiply_vector3FA": ("multiply", "vector3", {"in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("float", 1.0)}),
    "ND_power_float": ("power", "float", {"in1": ("float", 0.0), "in2": ("float", 1.0)}),
    "ND_power_vector3": ("power", "vector3", {"in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("vector3", (1.0, 1.0, 1.0))}),
    "ND_sqrt_float": ("sqrt", "float", {"in": ("float", 0.0)}),
    "ND_sqrt_vector3": ("sqrt", "vector3", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_min_float": ("min", "float", {"in1": ("float", 0.0), "in2": ("float", 0.0)}),
    "ND_max_float": ("max", "float", {"in1": ("float", 0.0), "in2": ("float", 0.0)}),
    "ND_min_vector3": ("min", "vector3", {"in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_max_vector3": ("max", "vector3", {"in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_clamp_float": ("clamp", "float", {"in": ("float", 0.0), "low": ("float", 0.0),
        "high": ("float", 1.0)}),
    "ND_clamp_vector3": ("clamp", "vector3", {"in": ("vector3", (0.0, 0.0, 0.0)),
        "low": ("vector3", (0.0, 0.0, 0.0)), "high": ("vector3", (1.0, 1.0, 1.0))}),
    "ND_absval_float": ("absval", "float", {"in": ("float", 0.0)}),
    "ND_absval_vector3": ("absval", "vector3", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_floor_float": ("floor", "float", {"in": ("float", 0.0)}),
    "ND_sin_float": ("sin", "float", {"in": ("float", 0.0)}),
    "ND_sin_vector3": ("sin", "vector3", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_cos_float": ("cos", "float", {"in": ("float", 0.0)}),
    "ND_cos_vector3": ("cos", "vector3", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_acos_float": ("acos", "float", {"in": ("float", 0.0)}),
    "ND_atan2_float": ("atan2", "float", {"iny": ("float", 0.0), "inx": ("float", 1.0)}),
    "ND_floor_vector3": ("floor", "vector3", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_sign_float": ("sign", "float", {"in": ("float", 0.0)}),
    "ND_modulo_float": ("modulo", "float", {"in1": ("float", 0.0), "in2": ("float", 1.0)}),
    "ND_sign_vector3": ("sign", "vector3", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_exp_float": ("exp", "float", {"in": ("float", 0.0)}),
    "ND_exp_vector3": ("exp", "vector3", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_ifgreater_float": ("ifgreater", "float", {"value1": ("float", 1.0),
        "value2": ("float", 0.0), "in1": ("float", 0.0), "in2": ("float", 0.0)}),
    "ND_ifgreater_vector3": ("ifgreater", "vector3", {"value1": ("float", 1.0),
        "value2": ("float", 0.0), "in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_ifgreatereq_float": ("ifgreatereq", "float", {"value1": ("float", 1.0),
        "value2": ("float", 0.0), "in1": ("float", 0.0), "in2": ("float", 0.0)}),
    "ND_ifequal_float": ("ifequal", "float", {"value1": ("float", 0.0), "value2": ("float", 0.0),
        "in1": ("float", 0.0), "in2": ("float", 0.0)}),
    "ND_mix_vector3": ("mix", "vector3", {"fg": ("vector3", (0.0, 0.0, 0.0)),
        "bg": ("vector3", (0.0, 0.0, 0.0)), "mix": ("float", 0.0)}),
    "ND_mix_vector3_vector3": ("mix", "vector3", {"fg": ("vector3", (0.0, 0.0, 0.0)),
        "bg": ("vector3", (0.0, 0.0, 0.0)), "mix": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_mix_color3": ("mix", "color3", {"fg": ("color3", (0.0, 0.0, 0.0)),
        "bg": ("color3", (0.0, 0.0, 0.0)), "mix": ("float", 0.0)}),
    "ND_extract_vector3": ("extract", "float", {"in": ("vector3", (0.0, 0.0, 0.0)),
        "index": ("integer", 0)}),
    "ND_extract_color4": ("extract", "float", {"in": ("color4", (0.0, 0.0, 0.0, 0.0)),
        "index": ("integer", 0)}),
    "ND_combine3_vector3": ("combine3", "vector3", {"in1": ("float", 0.0), "in2": ("float", 0.0),
        "in3": ("float", 0.0)}),
    "ND_convert_float_color3": ("convert", "color3", {"in": ("float", 0.0)}),
    "ND_convert_float_vector3": ("convert", "vector3", {"in": ("float", 0.0)}),
    "ND_convert_vector3_color3": ("convert", "color3", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_convert_color3_vector3": ("convert", "vector3", {"in": ("color3", (0.0, 0.0, 0.0))}),
    "ND_convert_color4_color3": ("convert", "color3", {"in": ("color4", (0.0, 0.0, 0.0, 0.0))}),
    "ND_convert_vector3_vector2": ("convert", "vector2", {"in": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_dotproduct_vector3": ("dotproduct", "float", {"in1": ("vector3", (0.0, 0.0, 0.0)),
        "in2": ("vector3", (0.0, 0.0, 0.0))}),
    "ND_mix_edf": ("mix", "EDF", {"fg": ("EDF", None), "bg": ("EDF", None), "mix": ("float", 0.0)}),
    "ND_add_edf": ("add", "EDF", {"in1": ("EDF", None), "in2": ("EDF", None)}),
    # surfaces material libraries ship (interchange/surfaces.py reads them as Principled BSDFs)
    "ND_standard_surface_surfaceshader": ("standard_surface", "surfaceshader", {
        "base": ("float", 1.0), "base_color": ("color3", (0.8, 0.8, 0.8)),
        "diffuse_roughness": ("float", 0.0), "metalness": ("float", 0.0),
        "specular": ("float", 1.0), "specular_color": ("color3", (1.0, 1.0, 1.0)),
        "specular_roughness": ("float", 0.2), "specular_IOR": ("float", 1.5),
        "specular_anisotropy": ("float", 0.0), "specular_rotation": ("float", 0.0),
        "transmission": ("float", 0.0), "transmission_color": ("color3", (1.0, 1.0, 1.0)),
        "transmission_depth": ("float", 0.0),
        "transmission_scatter": ("color3", (0.0, 0.0, 0.0)),
        "transmission_scatter_anisotropy": ("float", 0.0),
        "transmission_dispersion": ("float", 0.0),
        "transmission_extra_roughness": ("float", 0.0), "subsurface": ("float", 0.0),
        "subsurface_color": ("color3", (1.0, 1.0, 1.0)),
        "subsurface_radius": ("color3", (1.0, 1.0, 1.0)), "subsurface_scale": ("float", 1.0),
        "subsurface_anisotropy": ("float", 0.0), "sheen": ("float", 0.0),
        "sheen_color": ("color3", (1.0, 1.0, 1.0)), "sheen_roughness": ("float", 0.3),
        "coat": ("float", 0.0), "coat_color": ("color3", (1.0, 1.0, 1.0)),
        "coat_roughness": ("float", 0.1), "coat_anisotropy": ("float", 0.0),
        "coat_rotation": ("float", 0.0), "coat_IOR": ("float", 1.5),
        "coat_normal": ("vector3", "Nworld"), "coat_affect_color": ("float", 0.0),
        "coat_affect_roughness": ("float", 0.0), "thin_film_thickness": ("float", 0.0),
        "thin_film_IOR": ("float", 1.5), "emission": ("float", 0.0),
        "emission_color": ("color3", (1.0, 1.0, 1.0)), "opacity": ("color3", (1.0, 1.0, 1.0)),
        "thin_walled": ("boolean", False), "normal": ("vector3", "Nworld"),
        "tangent": ("vector3", "Tworld")}),
    "ND_gltf_pbr_surfaceshader": ("gltf_pbr", "surfaceshader", {
        "base_color": ("color3", (1.0, 1.0, 1.0)), "metallic": ("float", 1.0),
        "roughness": ("float", 1.0), "normal": ("vector3", "Nworld"),
        "tangent": ("vector3", "Tworld"), "occlusion": ("float", 1.0),
        "transmission": ("float", 0.0), "specular": ("float", 1.0),
        "specular_color": ("color3", (1.0, 1.0, 1.0)), "ior": ("float", 1.5),
        "alpha": ("float", 1.0), "alpha_mode": ("integer", 0), "alpha_cutoff": ("float", 0.5),
        "iridescence": ("float", 0.0), "iridescence_ior": ("float", 1.3),
        "iridescence_thickness": ("float", 100.0), "sheen_color": ("color3", (0.0, 0.0, 0.0)),
        "sheen_roughness": ("float", 0.0), "clearcoat": ("float", 0.0),
        "clearcoat_roughness": ("float", 0.0), "clearcoat_normal": ("vector3", "Nworld"),
        "emissive": ("color3", (0.0, 0.0, 0.0)), "emissive_strength": ("float", 1.0),
        "thickness": ("float", 0.0), "attenuation_distance": ("float", None),
        "attenuation_color": ("color3", (1.0, 1.0, 1.0)), "anisotropy_strength": ("float", 0.0),
        "anisotropy_rotation": ("float", 0.0), "dispersion": ("float", 0.0)}),
    "ND_UsdPreviewSurface_surfaceshader": ("UsdPreviewSurface", "surfaceshader", {
        "diffuseColor": ("color3", (0.18, 0.18, 0.18)),
        "emissiveColor": ("color3", (0.0, 0.0, 0.0)), "useSpecularWorkflow": ("integer", 0),
        "specularColor": ("color3", (0.0, 0.0, 0.0)), "metallic": ("float", 0.0),
        "roughness": ("float", 0.5), "clearcoat": ("float", 0.0),
        "clearcoatRoughness": ("float", 0.01), "opacity": ("float", 1.0),
        "opacityMode": ("integer", 0), "opacityThreshold": ("float", 0.0), "ior": ("float", 1.5),
        "normal": ("vector3", (0.0, 0.0, 1.0)), "displacement": ("float", 0.0),
        "occlusion": ("float", 1.0)}),
    "ND_open_pbr_surface_surfaceshader": ("open_pbr_surface", "surfaceshader", {
        "base_weight": ("float", 1.0), "base_color": ("color3", (0.8, 0.8, 0.8)),
        "base_diffuse_roughness": ("float", 0.0), "base_metalness": ("float", 0.0),
        "specular_weight": ("float", 1.0), "specular_color": ("color3", (1.0, 1.0, 1.0)),
        "specular_roughness": ("float", 0.3), "specular_ior": ("float", 1.5),
        "specular_roughness_anisotropy": ("float", 0.0), "transmission_weight": ("float", 0.0),
        "transmission_color": ("color3", (1.0, 1.0, 1.0)), "transmission_depth": ("float", 0.0),
        "transmission_scatter": ("color3", (0.0, 0.0, 0.0)),
        "transmission_scatter_anisotropy": ("float", 0.0),
        "transmission_dispersion_scale": ("float", 0.0),
        "transmission_dispersion_abbe_number": ("float", 20.0),
        "subsurface_weight": ("float", 0.0), "subsurface_color": ("color3", (0.8, 0.8, 0.8)),
        "subsurface_radius": ("float", 1.0),
        "subsurface_radius_scale": ("color3", (1.0, 0.5, 0.25)),
        "subsurface_scatter_anisotropy": ("float", 0.0), "fuzz_weight": ("float", 0.0),
        "fuzz_color": ("color3", (1.0, 1.0, 1.0)), "fuzz_roughness": ("float", 0.5),
        "coat_weight": ("float", 0.0), "coat_color": ("color3", (1.0, 1.0, 1.0)),
        "coat_roughness": ("float", 0.0), "coat_roughness_anisotropy": ("float", 0.0),
        "coat_ior": ("float", 1.6), "coat_darkening": ("float", 1.0),
        "thin_film_weight": ("float", 0.0), "thin_film_thickness": ("float", 0.5),
        "thin_film_ior": ("float", 1.4), "emission_luminance": ("float", 0.0),
        "emission_color": ("color3", (1.0, 1.0, 1.0)), "geometry_opacity": ("float", 1.0),
        "geometry_thin_walled": ("boolean", False), "geometry_normal": ("vector3", "Nworld"),
        "geometry_coat_normal": ("vector3", "Nworld"), "geometry_tangent": ("vector3", "Tworld"),
        "geometry_coat_tangent": ("vector3", "Tworld")}),
}

# standard_surface 1.0.0 (version="1.0.0"): 1.0.1 with the older base defaults; MaterialX's
# 1.0.1 nodedef inherits from it the same way
NODEDEFS["ND_standard_surface_surfaceshader_100"] = ("standard_surface", "surfaceshader", dict(
    NODEDEFS["ND_standard_surface_surfaceshader"][2], base=("float", 0.8),
    base_color=("color3", (1.0, 1.0, 1.0))))

#: OpenPBR surface inputs the add-on writes or reads, with the spec's defaults (OpenPBR 1.1/1.2).
OPENPBR_INPUTS = {
    "base_weight": ("float", 1.0), "base_color": ("color3", (0.8, 0.8, 0.8)),
    "base_metalness": ("float", 0.0), "specular_weight": ("float", 1.0),
    "specular_color": ("color3", (1.0, 1.0, 1.0)), "specular_roughness": ("float", 0.3),
    "specular_ior": ("float", 1.5), "specular_roughness_anisotropy": ("float", 0.0),
    "transmission_weight": ("float", 0.0), "geometry_normal": ("vector3", _N3),
    "geometry_tangent": ("vector3", _T3),
}
#: OpenPBR 1.2 additions (dev_1.2 spec §"Specular haze").
OPENPBR_12_INPUTS = {"specular_haze": ("float", 0.0), "specular_haze_spread": ("float", 0.3)}
#: OpenPBR inputs that change the look when not at their default and that a hazy material
#: cannot hold (the importer reports them).
OPENPBR_UNSUPPORTED = {"coat_weight": 0.0, "fuzz_weight": 0.0, "thin_film_weight": 0.0,
                       "subsurface_weight": 0.0, "emission_luminance": 0.0}


# --------------------------------------------------------------------------------------------
# Values
# --------------------------------------------------------------------------------------------

_VECTOR = {"color3": 3, "color4": 4, "vector2": 2, "vector3": 3, "vector4": 4}


def _num(x):
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"MaterialX values must be finite, got {x!r}")
    r = repr(x)  # shortest string that reads back as the same float64
    return "0" if r in ("0.0", "-0.0") else r


def format_value(value, type_):
    """A value as MaterialX writes it: floats with 17 significant digits at most (repr)."""
    if type_ in _VECTOR:
        vals = list(value) if hasattr(value, "__len__") else [value] * _VECTOR[type_]
        if len(vals) != _VECTOR[type_]:
            raise ValueError(f"a {type_} needs {_VECTOR[type_]} values, got {len(vals)}")
        return ", ".join(_num(v) for v in vals)
    if type_ == "float":
        return _num(value)
    if type_ == "integer":
        return str(int(value))
    if type_ == "boolean":
        return "true" if value else "false"
    return str(value)


#: MaterialX 1.39 stores floats in float32 and refuses a number that rounds beyond its largest
#: value (``std::istream >> float`` overflows): 2¹²⁸ - 2¹⁰³ is where rounding reaches infinity.
_F32_LIMIT = 2.0 ** 128 - 2.0 ** 103
#: What ``std::istream >> float`` accumulates (libstdc++ num_get): sign, digits, one decimal
#: point, an exponent; the longest such prefix after leading white space is converted.
_FLOAT_PREFIX = re.compile(r"[ \t\n\v\f\r]*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d*)?)")
_INT_PREFIX = re.compile(r"[ \t\n\v\f\r]*([+-]?\d+)")
#: MaterialX's ARRAY_VALID_SEPARATORS: vector components split on commas and spaces.
_SPLIT = re.compile(r"[, ]+")
_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_PLAIN = re.compile(_NUM)
_PLAIN_VECTOR = re.compile(rf"[, ]*{_NUM}(?:[, ]+{_NUM})*[, ]*")


def _float_token(tok):
    """A number as MaterialX 1.39.5 reads it (``std::istream >> float``): the longest numeric
    prefix, so "0.1, 0.05" is 0.1 and "0.25abc" 0.25; None when there is none, when it
    overflows float32 or is nan / inf (which the stream does not read).  Kept in float64 (our
    own files hold 17 digits)."""
    m = _FLOAT_PREFIX.match(tok)
    if m is None:
        return None
    num = m.group(1)
    if num[-1] in "eE+-":  # "1e", "1e+": the stream's conversion fails
        return None
    x = float(num)
    return x if abs(x) < _F32_LIMIT else None


def read_value(text, type_):
    """(value, problem): a value string read the way MaterialX 1.39.5 reads it
    (``Value::createValueFromStrings``).  A value MaterialX reads partly (a float written as a
    list, trailing characters) comes back as MaterialX reads it, with ``problem`` saying so; one
    it refuses (``getValue()`` is None, ``validate()`` False) gives value None and the problem."""
    if text is None:
        return None, None
    if type_ == "float" and _PLAIN.fullmatch(text):  # the common case: one plain number
        x = float(text)
        if abs(x) < _F32_LIMIT:
            return x, None
    if type_ in _VECTOR:
        n = _VECTOR[type_]
        plain = _PLAIN_VECTOR.fullmatch(text) is not None
        toks = [t for t in text.replace(",", " ").split(" ") if t] if plain \
            else [t for t in _SPLIT.split(text) if t]
        if plain and len(toks) == n:
            vals = tuple(map(float, toks))
            if all(abs(v) < _F32_LIMIT for v in vals):
                return vals, None
        if len(toks) != n:
            return None, (f"value {_clip(text)} is not {n} numbers (type {type_}): ignored, as "
                          f"MaterialX ignores it")
        vals = tuple(_float_token(t) for t in toks)
        if any(v is None for v in vals):
            return None, f"value {_clip(text)} is not {n} numbers (type {type_}): ignored, as MaterialX ignores it"
        exact = all(_FLOAT_PREFIX.fullmatch(t) for t in toks)
        return vals, None if exact else f"value {_clip(text)} read as {_show(vals)}, as MaterialX reads it"
    if type_ == "float":
        v = _float_token(text)
        if v is None:
            return None, f"value {_clip(text)} is not a number (type float): ignored, as MaterialX ignores it"
        exact = _FLOAT_PREFIX.fullmatch(text.strip(" \t\n\v\f\r") or "x") is not None
        return v, None if exact else f"value {_clip(text)} read as {_show(v)}, as MaterialX reads it"
    if type_ == "integer":
        m = _INT_PREFIX.match(text)
        if m is None or abs(int(m.group(1))) > 2 ** 31 - 1:
            return None, f"value {_clip(text)} is not an integer: ignored, as MaterialX ignores it"
        v = int(m.group(1))
        exact = m.end() == len(text.rstrip(" \t\n\v\f\r"))
        return v, None if exact else f"value {_clip(text)} read as {v}, as MaterialX reads it"
    if type_ == "boolean":
        if text in ("true", "false"):
            return text == "true", None
        return None, f"value {_clip(text)} is not true or false: ignored, as MaterialX ignores it"
    return text, None


def _clip(text):
    return repr(text if len(text) <= 40 else text[:37] + "...")


def _show(v):
    return ", ".join(f"{x:.9g}" for x in v) if isinstance(v, tuple) else f"{v:.9g}"


def parse_value(text, type_):
    """A value string as MaterialX 1.39.5 reads it (:func:`read_value`); ValueError where
    MaterialX refuses it."""
    v, problem = read_value(text, type_)
    if v is None and problem is not None:
        raise ValueError(problem)
    return v


_NAME_RX = re.compile(r"[^A-Za-z0-9_]")


def valid_name(text, taken=None):
    """A MaterialX element name from any text ([A-Za-z_][A-Za-z0-9_]*), unique within ``taken``."""
    name = _NAME_RX.sub("_", str(text)) or "material"
    if not (name[0].isalpha() or name[0] == "_"):
        name = "M_" + name
    if taken is not None:
        base, i = name, 1
        while name in taken:
            i += 1
            name = f"{base}_{i}"
        taken.add(name)
    return name


# --------------------------------------------------------------------------------------------
# Elements
# --------------------------------------------------------------------------------------------


@dataclass(slots=True)
class Input:
    name: str
    type: str
    value: object = None
    nodename: str = None
    nodegraph: str = None
    output: str = None
    interfacename: str = None
    colorspace: str = None
    #: MaterialX 1.37/1.38 swizzle of the connected output ("z", "rgb"...)
    channels: str = None
    #: what was wrong with the written value (read_value), None when it read cleanly
    problem: str = None

    @property
    def connected(self):
        return bool(self.nodename or self.nodegraph or self.interfacename)


@dataclass(slots=True)
class Node:
    name: str
    category: str
    type: str
    inputs: dict = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)  #: other XML attributes (version, hazygloss_...)
    #: the nodedef's name when (category, type) does not say it (ND_multiply_color3FA, ...):
    #: the USD writer's info:id; not written to XML (MaterialX resolves it from the input types)
    nodedef: str = None

    def set(self, name, type_, value=None, *, node=None, output=None, nodegraph=None,
            interface=None, colorspace=None):
        """Add an input: a value, or a connection to ``node`` (a Node or its name)."""
        nodename = node.name if isinstance(node, Node) else node
        self.inputs[name] = Input(name, type_, value, nodename, nodegraph, output, interface,
                                  colorspace)
        return self.inputs[name]

    def value(self, name, default=None):
        i = self.inputs.get(name)
        return default if i is None or i.value is None else i.value


@dataclass
class NodeGraph:
    name: str
    nodes: dict = field(default_factory=dict)  #: name -> Node, in writing order
    outputs: dict = field(default_factory=dict)  #: name -> Input (type, nodename, output)
    inputs: dict = field(default_factory=dict)  #: interface inputs: name -> Input
    attrs: dict = field(default_factory=dict)

    def add(self, node):
        if node.name in self.nodes:
            raise ValueError(f"duplicate node name {node.name!r} in {self.name}")
        self.nodes[node.name] = node
        return node


@dataclass
class Document:
    """Top-level nodes (surface shaders, materials), node graphs and raw extra elements
    (nodedefs and their implementations) of one MaterialX document."""

    nodes: dict = field(default_factory=dict)
    graphs: dict = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)
    extra: list = field(default_factory=list)  #: xml.etree Elements written before the rest
    comments: list = field(default_factory=list)
    source: str = ""  #: file path it was read from (resolves relative texture paths)

    def materials(self):
        return [n for n in self.nodes.values() if n.category == "surfacematerial"]

    def resolve(self, inp, graph=None):
        """Follow one input to what feeds it: ("value", value, type) or ("node", Node, graph).

        ``graph``: the NodeGraph the input belongs to (None: top level).  Connections to a node
        graph's output and interface inputs are followed; an unconnected input gives its value
        (None when not authored)."""
        seen = 0
        while True:
            seen += 1
            if seen > 64:
                raise ValueError("MaterialX connection cycle")
            if inp is None:
                return ("value", None, None)
            if inp.interfacename and graph is not None:
                inp = graph.inputs.get(inp.interfacename)
                graph = None  # interface inputs are set from outside; we only read their value
                continue
            if inp.nodegraph:
                g = self.graphs.get(inp.nodegraph)
                if g is None:
                    return ("value", None, inp.type)
                out = g.outputs.get(inp.output) if inp.output else next(iter(g.outputs.values()), None)
                if out is None:
                    return ("value", None, inp.type)
                inp, graph = out, g
                continue
            if inp.nodename:
                scope = graph.nodes if graph is not None else self.nodes
                node = scope.get(inp.nodename)
                if node is None:
                    return ("value", None, inp.type)
                return ("node", node, graph)
            return ("value", inp.value, inp.type)


# --------------------------------------------------------------------------------------------
# XML
# --------------------------------------------------------------------------------------------

_INPUT_ATTRS = ("nodename", "nodegraph", "output", "interfacename", "colorspace")


def _input_element(parent, inp, tag="input"):
    e = ET.SubElement(parent, tag, name=inp.name, type=inp.type)
    for a in _INPUT_ATTRS:
        v = getattr(inp, a)
        if v:
            e.set(a, v)
    if inp.value is not None and not inp.connected:
        e.set("value", format_value(inp.value, inp.type))
    return e


def _node_element(parent, node):
    e = ET.SubElement(parent, node.category, name=node.name, type=node.type)
    for k, v in node.attrs.items():
        e.set(k, str(v))
    for inp in node.inputs.values():
        _input_element(e, inp)
    return e


def to_xml_string(doc):
    root = ET.Element("materialx", version=K.MATERIALX_VERSION)
    root.set("colorspace", doc.attrs.get("colorspace", K.MATERIALX_COLORSPACE))
    for k, v in doc.attrs.items():
        if k != "colorspace":
            root.set(k, str(v))
    for c in doc.comments:
        root.append(ET.Comment(f" {c} "))
    for e in doc.extra:
        root.append(e)
    for g in doc.graphs.values():
        ge = ET.SubElement(root, "nodegraph", name=g.name)
        for k, v in g.attrs.items():
            ge.set(k, str(v))
        for inp in g.inputs.values():
            _input_element(ge, inp)
        for n in g.nodes.values():
            _node_element(ge, n)
        for out in g.outputs.values():
            _input_element(ge, out, tag="output")
    for n in doc.nodes.values():
        _node_element(root, n)
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def write_xml(doc, path):
    """Write ``doc`` to ``path`` through a temporary beside it, renamed into place and removed
    whatever stops the write (an error, Ctrl+C): ``path`` is the old file or the new one,
    never a part.  An OSError names ``path``, not the temporary."""
    text = to_xml_string(doc)
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except OSError as exc:
        raise OSError(exc.errno, f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        if os.path.lexists(tmp):
            os.remove(tmp)
    return path


def _input_of(a):
    """An Input from an <input> element's attributes."""
    t = a.get("type", "")
    text = a.get("value")
    value, problem = read_value(text, t) if text is not None else (None, None)
    if text is not None:
        if not t:
            problem = "has no type: ignored, as MaterialX ignores it"
        if len(a) == 3:  # name, type, value: the common case, nothing else to look up
            return Input(a.get("name", ""), t, value, None, None, None, None, None, None, problem)
    return Input(a.get("name", ""), t, value, a.get("nodename"), a.get("nodegraph"),
                 a.get("output"), a.get("interfacename"), a.get("colorspace"),
                 a.get("channels"), problem)


#: child elements read as a node's inputs (1.37 wrote uniform ones as <parameter>, and
#: shaderrefs' as <bindinput> / <bindparam>)
_INPUT_TAGS = frozenset(("input", "parameter", "bindinput", "bindparam"))
_SKIP = frozenset(("nodedef", "implementation", "typedef", "look", "collection", "geominfo",
                   "propertyset", "variantset", "backdrop", "token", "unit", "unittypedef",
                   "attributedef", "targetdef", "materialassign", "lookgroup", "variant", "member",
                   "propertysetassign"))
_CHUNK = 1 << 20  # bytes fed to the parser at a time (and the progress step)
_NOT_ATTRS = ("name", "type")


def read_xml(path_or_text, *, text=False, progress=None):
    """Parse a MaterialX document (file path, or the XML itself with ``text=True``), streaming
    with expat: elements become Nodes / NodeGraphs / Inputs as they are read, no XML tree is
    kept, so memory follows the document's content.  Includes (xi:include) are not followed;
    nodedefs and implementations are skipped.  ``progress``: callable(fraction, message),
    called as the bytes are read (fraction in [0, 1], non-decreasing).

    MaterialX 1.37 materials (``<material>`` with a ``<shaderref>`` and ``<bindinput>``s) are read
    as the surfacematerial + shader node 1.38 made of them (MaterialX upgrades them the same
    way); ``channels`` swizzles and ``fileprefix`` / ``colorspace`` scopes are kept for the
    importer.  expat expands no external entity and refuses entity amplification."""
    where = "the document" if text else str(path_or_text)
    if text:
        data = path_or_text.encode("utf-8") if isinstance(path_or_text, str) else path_or_text
        stream, size = io.BytesIO(data), len(data)
    else:
        try:
            stream = open(path_or_text, "rb")
        except OSError as exc:
            raise ValueError(f"{where}: cannot be read ({exc.strerror or exc})") from None
        size = os.fstat(stream.fileno()).st_size
    doc = Document(source="" if text else str(path_or_text))
    reader = _Reader(doc)
    parser = expat.ParserCreate()
    parser.buffer_text = True
    parser.StartElementHandler = reader.start
    parser.EndElementHandler = reader.end
    done = 0
    try:
        with stream:
            while True:
                chunk = stream.read(_CHUNK)
                if not chunk:
                    break
                parser.Parse(chunk, False)
                done += len(chunk)
                if progress is not None and size:
                    progress(min(done / size, 1.0), "reading")
            parser.Parse(b"", True)
    except expat.ExpatError as exc:
        raise ValueError(f"{where}: not a well-formed XML file ({expat.errors.messages.get(exc.code, exc)}: "
                         f"line {exc.lineno}, column {exc.offset})") from None
    except RecursionError:
        raise ValueError(f"{where}: nested too deeply to be a MaterialX document") from None
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    if not reader.rooted:
        raise ValueError(f"{where}: not a well-formed XML file (no root element)")
    return doc


class _Reader:
    """expat handlers building the Document: depth 1 the <materialx> root, depth 2 top-level
    nodes / node graphs / 1.37 materials, depth 3 their inputs, outputs and nodes, depth 4 the
    inputs of nodes inside node graphs (and of 1.37 shaderrefs)."""

    def __init__(self, doc):
        self.doc = doc
        self.rooted = False
        self.depth = 0
        self.top = None  #: the Node / NodeGraph / (material Node, [shaderrefs]) being read
        self.kind = None  #: "node", "graph", "material", "skip"
        self.inner = None  #: a node inside a graph, or a shaderref, being read

    def start(self, tag, a):
        self.depth += 1
        d = self.depth
        if d == 1:
            if tag != "materialx":
                raise ValueError(f"not a MaterialX document (root element <{tag}>)")
            self.rooted = True
            self.doc.attrs = dict(a)
        elif d == 2:
            if tag in _SKIP or (tag == "nodegraph" and a.get("nodedef")):
                self.kind = "skip"
            elif tag == "nodegraph":
                self.kind = "graph"
                self.top = NodeGraph(a.get("name", ""), attrs={k: v for k, v in a.items() if k != "name"})
            elif tag == "material":  # MaterialX 1.37: shaderrefs bound to the material
                self.kind = "material"
                self.top = (Node(a.get("name", ""), "surfacematerial", "material",
                                 attrs={k: v for k, v in a.items() if k not in _NOT_ATTRS}), [])
            else:
                self.kind = "node"
                self.top = Node(a.get("name", ""), tag, a.get("type", ""),
                                attrs={k: v for k, v in a.items() if k not in _NOT_ATTRS})
        elif d == 3:
            k = self.kind
            if k == "node":
                if tag in _INPUT_TAGS:
                    i = _input_of(a)
                    self.top.inputs[i.name] = i
            elif k == "graph":
                if tag in _INPUT_TAGS:
                    i = _input_of(a)
                    self.top.inputs[i.name] = i
                elif tag == "output":
                    i = _input_of(a)
                    self.top.outputs[i.name] = i
                elif tag not in _SKIP:
                    self.inner = Node(a.get("name", ""), tag, a.get("type", ""),
                                      attrs={k2: v for k2, v in a.items() if k2 not in _NOT_ATTRS})
            elif k == "material" and tag == "shaderref":
                cat = a.get("node", "")
                self.inner = Node(a.get("name", ""), cat, a.get("type") or "surfaceshader",
                                  attrs={k2: v for k2, v in a.items() if k2 not in ("name", "type", "node")})
        elif d == 4 and self.inner is not None and tag in _INPUT_TAGS:
            i = _input_of(a)
            self.inner.inputs[i.name] = i

    def end(self, tag):
        d = self.depth
        self.depth -= 1
        if d == 3 and self.inner is not None:
            if self.kind == "graph":
                self.top.nodes[self.inner.name] = self.inner
            elif self.kind == "material":
                self.top[1].append(self.inner)
            self.inner = None
        elif d == 2:
            k, top = self.kind, self.top
            self.kind = self.top = None
            if k == "graph":
                self.doc.graphs[top.name] = top
            elif k == "node":
                self.doc.nodes[top.name] = top
            elif k == "material":
                self.material_137(*top)

    def material_137(self, mat, refs):
        doc = self.doc
        name = mat.name
        for shader in refs:
            sname = shader.name or f"SR_{name}"
            while sname in doc.nodes:
                sname += "_"
            shader.name = sname
            doc.nodes[sname] = shader
            key = "displacementshader" if shader.type == "displacementshader" else "surfaceshader"
            mat.inputs.setdefault(key, Input(key, shader.type, nodename=sname))
        while name in doc.nodes:
            name += "_"
        mat.name = name
        doc.nodes[name] = mat
