# SPDX-License-Identifier: GPL-3.0-or-later
"""No dead code in the shipped package: vulture (60 % confidence: every unused function, class,
method, property and variable) finds nothing in hazy_gloss/ beyond tests/pure/vulture_allow.py
and Blender's class attributes.

Attribute writes are not judged: setting an attribute on a Blender or expat object
(``node.label = ...``, ``parser.StartElementHandler = ...``) is how their APIs are driven, and
vulture cannot tell those objects from ours (our own records are NamedTuples and dataclasses,
whose fields it reports as variables).  Helpers only tests, benchmarks or scripts use belong
under tests/ (tests/blender/layer_probe.py, tests/pure/openpbr_measure.py), not here."""
from pathlib import Path

import vulture

ROOT = Path(__file__).resolve().parents[2]
#: What Blender reads from registered classes (operators, panels, menus, presets, file browsers,
#: the USD hook).
BLENDER_NAMES = ["bl_*", "invoke", "modal", "execute", "draw", "poll", "description",
                 "filter_glob", "filename_ext", "preset_menu", "preset_subdir", "preset_defines",
                 "preset_values", "preset_operator",
                 "on_material_export", "material_import_poll", "on_material_import"]  # USDHook


def test_no_dead_code():
    v = vulture.Vulture(ignore_names=BLENDER_NAMES)
    v.scavenge([str(ROOT / "hazy_gloss"), str(Path(__file__).with_name("vulture_allow.py"))])
    dead = [f"{item.filename.relative_to(ROOT)}:{item.first_lineno}: {item.message}"
            for item in v.get_unused_code(min_confidence=60) if item.typ != "attribute"]
    assert not dead, "\n".join(dead)
