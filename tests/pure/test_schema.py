# SPDX-License-Identifier: GPL-3.0-or-later
"""The one parameter schema (hazy_gloss/schema.py) and what is derived from it agree: the names,
defaults and ranges every module imports are those written by hand before the schema; each
haze parameter has its layer socket (same names and numbers, so the cached layer groups stay
valid), panel properties (same limits), a CLI flag and a docs row; one vocabulary of kinds,
distributions and tangents."""
import ast
import math
from pathlib import Path

import pytest

from hazy_gloss import __main__ as cli
from hazy_gloss import constants as K
from hazy_gloss import schema as S
from hazy_gloss.core import mapping, parameters

ROOT = Path(__file__).resolve().parents[2]

#: Written by hand in core/parameters.py before the schema (modules import these).
PARAMETERS = ("kind", "distribution", "core_reflectivity", "edge_tint", "roughness", "anisotropy",
              "rotation", "haziness", "haze_extent", "smoothness", "shader_mapping", "base_color",
              "transmission", "tangent")
DEFAULTS = dict(kind="CONDUCTOR", distribution="GGX", core_reflectivity=(0.5, 0.5, 0.5),
                edge_tint=(0.0, 0.0, 0.0), roughness=0.1, anisotropy=0.0, rotation=0.0,
                haziness=0.5, haze_extent=(5.0, 5.0), smoothness=None, shader_mapping=False,
                base_color=(0.0, 0.0, 0.0), transmission=0.0, tangent="UV_MAP")
HAZE_PARAMETERS = ("haziness", "haze_extent", "smoothness", "reflectivity_cap", "coat_haziness",
                   "coat_haze_extent", "keep_body_colour")
HAZE_DEFAULTS = dict(haziness=0.0, haze_extent=(5.0, 5.0), smoothness=None, reflectivity_cap=1.0,
                     coat_haziness=0.0, coat_haze_extent=5.0, keep_body_colour=False)
RANGES = {"core_reflectivity": (0.0, 1.0), "edge_tint": (0.0, 1.0), "base_color": (0.0, 1.0),
          "roughness": (0.0, 1.0), "anisotropy": (0.0, 1.0), "transmission": (0.0, 1.0),
          "haziness": (0.0, K.MAX_HAZINESS), "haze_extent": (0.0, None),
          "rotation": (-math.inf, math.inf), "smoothness": (K.MIN_SMOOTHNESS, math.inf),
          "coat_haziness": (0.0, K.MAX_HAZINESS), "coat_haze_extent": (0.0, None),
          "reflectivity_cap": (0.0, 1.0)}
#: The layer group's Haze panel as it was written by hand (constants.HAZE_SOCKETS): name,
#: default, min, max.  A change here changes every layer group: bump
#: blender/model/layer_group.py's LAYER_GROUP_VERSION with it.
SOCKETS = {"haziness": ("Haziness", 0.0, 0.0, K.MAX_HAZINESS),
           "haze_extent_x": ("Haze Extent X", 5.0, 0.0, 1000.0),
           "haze_extent_y": ("Haze Extent Y", 5.0, 0.0, 1000.0),
           "smoothness": ("Smoothness", 2.0, K.MIN_SMOOTHNESS, 1e6),
           "reflectivity_cap": ("Reflectivity Cap", 1.0, 0.0, 1.0),
           "coat_haziness": ("Coat Haziness", 0.0, 0.0, K.MAX_HAZINESS),
           "coat_haze_extent": ("Coat Haze Extent", 5.0, 0.0, 1000.0)}
#: The panel's properties as they were written by hand (blender/properties.py): constructor,
#: min, max, soft_min, soft_max, subtype, precision (None: not given).
PROPERTIES = {
    "kind": ("EnumProperty",) + (None,) * 6,
    "distribution": ("EnumProperty",) + (None,) * 6,
    "core_reflectivity": ("FloatVectorProperty", None, None, 0.0, 1.0, "COLOR", None),
    "edge_tint": ("FloatVectorProperty", None, None, 0.0, 1.0, "COLOR", None),
    "roughness": ("FloatProperty", 0.0, 1.0, None, None, "FACTOR", 3),
    "anisotropy": ("FloatProperty", 0.0, 1.0, None, None, "FACTOR", None),
    "rotation": ("FloatProperty", 0.0, 1.0, None, None, "FACTOR", None),
    "tangent": ("EnumProperty",) + (None,) * 6,
    "haziness": ("FloatProperty", 0.0, K.MAX_HAZINESS, 0.0, 0.99, "FACTOR", 3),
    "haze_extent_x": ("FloatProperty", 0.0, 1000.0, None, 20.0, None, None),
    "haze_extent_y": ("FloatProperty", 0.0, 1000.0, None, 20.0, None, None),
    "haze_extent_linked": ("BoolProperty",) + (None,) * 6,
    "use_smoothness": ("BoolProperty",) + (None,) * 6,
    "smoothness": ("FloatProperty", K.MIN_SMOOTHNESS, 1e6, 0.5, 16.0, None, None),
    "shader_mapping": ("BoolProperty",) + (None,) * 6,
    "base_color": ("FloatVectorProperty", None, None, 0.0, 1.0, "COLOR", None),
    "transmission": ("FloatProperty", 0.0, 1.0, None, None, "FACTOR", None),
    "coat_haziness": ("FloatProperty", 0.0, K.MAX_HAZINESS, None, 0.99, "FACTOR", 3),
    "coat_haze_extent": ("FloatProperty", 0.0, 1000.0, None, 20.0, None, None),
    "keep_body_colour": ("BoolProperty",) + (None,) * 6,
    "smoothness_memory": ("FloatProperty", K.MIN_SMOOTHNESS, None, None, None, None, None),
}


def _kept(derived, pinned):
    """``derived`` keeps every pinned entry, in the pinned order (a new parameter may add)."""
    if isinstance(pinned, dict):
        return {k: derived.get(k, "missing") for k in pinned} == pinned and \
            [k for k in derived if k in pinned] == list(pinned)
    return tuple(n for n in derived if n in pinned) == tuple(pinned)


def test_derived_names_defaults_and_ranges_are_the_hand_written_ones():
    assert parameters.PARAMETERS == S.PARAMETERS and _kept(parameters.PARAMETERS, PARAMETERS)
    assert parameters.DEFAULTS == S.DEFAULTS and _kept(parameters.DEFAULTS, DEFAULTS)
    assert list(parameters.DEFAULTS) == list(parameters.PARAMETERS)
    assert _kept(parameters.HAZE_PARAMETERS, HAZE_PARAMETERS)
    assert _kept(parameters.HAZE_DEFAULTS, HAZE_DEFAULTS)
    assert list(parameters.HAZE_DEFAULTS) == list(parameters.HAZE_PARAMETERS)
    assert {k: parameters.RANGES[k] for k in RANGES} == RANGES
    assert parameters.TANGENTS == K.TANGENTS == ("UV_MAP", "RADIAL_X", "RADIAL_Y", "RADIAL_Z")


def test_schema_records_are_complete():
    types = {"colour", "float", "extent", "bool", "enum"}
    assert len(S.SCHEMA_BY_NAME) == len(S.SCHEMA)
    for p in S.SCHEMA:
        assert p.type in types and p.where in (S.MATERIAL, S.LAYER, S.BOTH), p.name
        assert p.label and p.symbol and p.doc, p.name
        assert set(p.kinds) <= set(K.KINDS) and p.kinds, p.name
        assert (p.range is not None) == (p.type in ("colour", "float", "extent")), p.name
        assert (p.type == "enum") == bool(p.terms), p.name
        if p.type == "enum":
            assert p.default in {t.id for t in p.terms}, p.name
        if p.default is None:
            assert p.placeholder is not None and p.type == "float", p.name
        if p.panel:
            assert p.description or p.type == "enum", p.name


def test_every_haze_parameter_has_a_socket_a_property_a_flag_and_a_docs_row():
    docs = (ROOT / "docs" / "parameters.md").read_text(encoding="utf-8")
    props = {name for name, _, _ in S.property_specs()}
    flags = {name for name, _ in cli.INPUT_FLAGS}
    for p in S.SCHEMA:
        assert f"(`{p.name}`" in docs, f"{p.name}: no row in docs/parameters.md"
        if p.panel:
            assert set(S.property_names(p)) <= props, p.name
        if not p.on_layer:
            continue
        if p.type != "bool":  # a flag is a configuration of the group, not a socket
            keys = [f"{p.name}_x", f"{p.name}_y"] if p.type == "extent" else [p.name]
            assert all(k in S.HAZE_SOCKETS for k in keys), p.name
        assert set(S.map_inputs(p)) <= flags, p.name
    assert _kept(S.HAZE_MAP_INPUTS, ("haziness", "haze_extent", "haze_extent_x",
                                     "haze_extent_y", "coat_haziness", "coat_haze_extent"))


def test_layer_sockets_are_the_hand_written_ones():
    assert _kept({k: v[:4] for k, v in S.HAZE_SOCKETS.items()}, SOCKETS)  # and the panel order
    assert all(v[4] for v in S.HAZE_SOCKETS.values())
    assert len({v[0] for v in S.HAZE_SOCKETS.values()}) == len(S.HAZE_SOCKETS)
    for key, (_, default, lo, hi, _) in S.HAZE_SOCKETS.items():
        p = S.SCHEMA_BY_NAME[key[:-2] if key not in S.SCHEMA_BY_NAME else key]
        assert (lo, hi) == p.limits and lo >= p.range[0], key
        assert lo <= default <= hi, key


def test_panel_properties_are_the_hand_written_ones_and_follow_the_ranges():
    specs = S.property_specs()
    got = {name: (ctor,) + tuple(kw.get(k) for k in ("min", "max", "soft_min", "soft_max",
                                                     "subtype", "precision"))
           for name, ctor, kw in specs}
    assert _kept(got, {k: v for k, v in PROPERTIES.items() if k != "tangent"})
    assert got["tangent"] == PROPERTIES["tangent"]  # (it moved after transmission: harmless)
    for name, ctor, kw in specs:
        assert kw.get("name") or name.endswith("_memory"), name
        p = S.SCHEMA_BY_NAME.get(name.removesuffix("_x"))
        if p is not None and ctor == "FloatProperty":
            assert (kw["min"], kw["max"]) == p.limits, name
            assert kw["min"] >= p.range[0] and (p.range[1] is None or kw["max"] <= p.range[1]
                                                or name == "rotation"), name
        if ctor == "EnumProperty":
            assert kw["items"] == K.enum_items(p.terms), name


def test_preset_properties():
    """Those that pick the node configuration first (the hand-written order, but for tangent,
    now last); a new parameter adds its properties."""
    assert _kept(S.preset_properties(S.MATERIAL), (
        "kind", "distribution", "shader_mapping", "core_reflectivity", "edge_tint", "roughness",
        "anisotropy", "rotation", "haziness", "haze_extent_linked", "haze_extent_x",
        "haze_extent_y", "use_smoothness", "smoothness", "base_color", "transmission", "tangent"))
    assert _kept(S.preset_properties(S.LAYER), (
        "haziness", "haze_extent_linked", "haze_extent_x", "haze_extent_y", "use_smoothness",
        "smoothness", "coat_haziness", "coat_haze_extent", "keep_body_colour"))
    props = {name for name, _, _ in S.property_specs()}
    assert set(S.preset_properties(S.MATERIAL)) | set(S.preset_properties(S.LAYER)) <= props


def test_one_vocabulary():
    assert K.KINDS == ("CONDUCTOR", "DIELECTRIC", "LEGACY")
    assert K.DISTRIBUTIONS == mapping.DISTRIBUTIONS == ("GGX", "BECKMANN", "MULTI_GGX",
                                                        "ASHIKHMIN_SHIRLEY")
    assert K.NODE_DISTRIBUTIONS == {"CONDUCTOR": ("GGX", "BECKMANN", "MULTI_GGX"),
                                    "DIELECTRIC": ("GGX", "MULTI_GGX"),
                                    "LEGACY": ("GGX", "BECKMANN", "MULTI_GGX", "ASHIKHMIN_SHIRLEY")}
    assert K.label(K.DISTRIBUTION_TERMS, "MULTI_GGX") == "Multiscatter GGX"
    for terms in (K.KIND_TERMS, K.DISTRIBUTION_TERMS, K.TANGENT_TERMS):
        assert len({t.label for t in terms}) == len({t.id for t in terms}) == len(terms)
        assert all(t.description for t in terms)


def _literal_labels(path):
    """String literals spelling a distribution's or kind's label (or the old "Multi GGX")."""
    labels = {t.label for t in K.DISTRIBUTION_TERMS + K.KIND_TERMS if t.label != t.id}
    labels.add("Multi GGX")
    return [n.lineno for n in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
            if isinstance(n, ast.Constant) and n.value in labels]


def test_vocabulary_labels_are_written_once():
    """Menus, enum items, group names and docs take the labels from constants' vocabulary."""
    hits = [f"{p.relative_to(ROOT)}:{lines}" for p in (ROOT / "hazy_gloss").rglob("*.py")
            if p.name != "constants.py" for lines in [_literal_labels(p)] if lines]
    assert not hits, f"labels written outside constants.*_TERMS: {hits}"


@pytest.mark.parametrize("name", ["haziness", "coat_haze_extent", "keep_body_colour",
                                  "reflectivity_cap", "smoothness", "haze_extent"])
def test_check_value_of_each_haze_parameter(name):
    assert parameters.check_value(name, HAZE_DEFAULTS[name]) == HAZE_DEFAULTS[name]
    with pytest.raises(ValueError, match=name):
        parameters.check_value(name, "nonsense")


def test_layer_configurations_are_the_hand_written_ones():
    """blender/model/layer_group.haze_params and the maps texture conversion takes as they
    were written by hand (a new parameter may add to them)."""
    base = ["haziness", "haze_extent_x", "haze_extent_y"]
    for bsdf in ("PRINCIPLED", "METALLIC", "GLOSSY"):
        for smooth in (False, True):
            want = base + (["smoothness"] if smooth else []) + ["reflectivity_cap"] + (
                ["coat_haziness", "coat_haze_extent"] if bsdf == "PRINCIPLED" else [])
            assert _kept(S.layer_sockets(bsdf, smooth), want), (bsdf, smooth)
            assert set(S.layer_sockets(bsdf, smooth)) <= set(S.HAZE_SOCKETS)
    assert _kept(S.LAYER_MAP_INPUTS, ("coat_haziness", "coat_haze_extent"))
