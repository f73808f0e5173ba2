# SPDX-License-Identifier: GPL-3.0-or-later
"""Scripting mistakes get one clear line: core.parameters.normalise names the
parameter, says what would be valid and, where the mistake is a common one, how to write it."""
import math
import re

import pytest

from hazy_gloss.core.parameters import check_value, normalise, normalise_haze

CASES = [
    # (keywords, regex the message must match)
    (dict(core_reflectivity="0.9,0.6,0.3"),
     r"^core_reflectivity .*string '0\.9,0\.6,0\.3' \(write the tuple \(0\.9, 0\.6, 0\.3\)\)$"),
    (dict(core_reflectivity="0.9 0.6 0.3"), r"write the tuple \(0\.9, 0\.6, 0\.3\)"),
    (dict(roughness="0.2"), r"^roughness must be a number, got the string '0\.2' \(write 0\.2"),
    (dict(haze_extent="5, 3"), r"^haze_extent .*\(write the pair \(5, 3\)\)$"),
    (dict(core_reflectivity=(230, 100, 20)), r"core_reflectivity .*divide by 255"),
    (dict(kind="DIELECTRIC", base_color=(200, 120, 40)), r"base_color .*divide by 255"),
    (dict(haze_extent=(5,)), r"^haze_extent must be a number or an \(x, y\) pair, got 1 value "
                             r"\(5,\) \(for one extent in both directions write haze_extent=5\)$"),
    (dict(haze_extent=(5, 3, 1)), r"haze_extent .*got 3 values"),
    (dict(kind="CONDUCTOR", base_color=(0.2, 0.2, 0.2)),
     r"^base_color applies to dielectrics only; a conductor has no base layer"),
    (dict(kind="LEGACY", base_color=(0.2, 0.2, 0.2)), r"base_color applies to dielectrics only"),
    (dict(kind="DIELECTRIC", edge_tint=(1.0, 0.8, 0.6)),
     r"^edge_tint applies to conductors only; a dielectric has no edge tint"),
    (dict(kind="CONDUCTOR", transmission=0.5), r"^transmission applies to dielectrics only"),
    (dict(hazines=0.3), r"unknown hazy parameter 'hazines' \(did you mean 'haziness'\?\)"),
    (dict(roughnes=0.3, edge_tnt=0.1), r"'edge_tnt' \(did you mean 'edge_tint'\?\), 'roughnes' "
                                       r"\(did you mean 'roughness'\?\)"),
    (dict(kind="metal"), r"kind must be one of .*got 'metal' \(did you mean CONDUCTOR\?\)"),
    (dict(kind="plastic"), r"did you mean DIELECTRIC\?"),
    (dict(distribution="Beckman"), r"did you mean BECKMANN\?"),
    (dict(kind=7), r"^kind must be one of CONDUCTOR, DIELECTRIC, LEGACY \(a string\), got 7$"),
    (dict(rotation=math.inf), r"^rotation must be finite \(turns\), got inf$"),
    (dict(shader_mapping="yes"), r"^shader_mapping must be True or False, got 'yes'$"),
    (dict(core_reflectivity={"r": 1}), r"^core_reflectivity must be a number or an RGB triple"),
]


@pytest.mark.parametrize("kw, pattern", CASES, ids=[repr(c[0])[:40] for c in CASES])
def test_mistake_message(kw, pattern):
    with pytest.raises(ValueError) as e:
        normalise(kw)
    msg = str(e.value)
    assert "\n" not in msg and len(msg) < 300, msg
    assert re.search(pattern, msg), msg


def test_defaults_and_kind_changes_are_not_mistakes():
    """What is not set by the caller is not refused: a dielectric's stored base colour kept
    after switching kind, a zero edge tint or transmission given for any kind."""
    normalise(dict(kind="DIELECTRIC", edge_tint=0.0, transmission=0.0))
    normalise(dict(kind="CONDUCTOR", base_color=(0.0, 0.0, 0.0), transmission=0.0))
    kept = dict(kind="CONDUCTOR", base_color=(0.3, 0.2, 0.1), edge_tint=(1, 1, 1))
    assert normalise(kept, explicit={"kind"})["kind"] == "CONDUCTOR"
    d = normalise(dict(kind="DIELECTRIC", edge_tint=(1, 1, 1)), explicit={"kind"})
    assert d["edge_tint"] == (0.0, 0.0, 0.0)


def test_haze_layer_mistakes():
    with pytest.raises(ValueError, match=r"core_reflectivity of a haze layer belongs to its BSDF"):
        normalise_haze(dict(core_reflectivity=0.5))
    with pytest.raises(ValueError, match=r"'hazyness' \(did you mean 'haziness'\?\)"):
        normalise_haze(dict(hazyness=0.5))
    with pytest.raises(ValueError, match=r"coat_haze_extent must be a number .* got 0 values"):
        normalise_haze(dict(coat_haze_extent=[]))
    with pytest.raises(ValueError, match=r"haze_extent .*got 1 value"):
        normalise_haze(dict(haze_extent=(5,)))


@pytest.mark.parametrize("name, value, pattern", [
    ("haze_extent", [1.0], r"got 1 value"),
    ("kind", {"a": 1}, r"\(a string\), got \{'a': 1\}"),
    ("keep_body_colour", 7, r"True or False, got 7"),
    ("smoothness", -1.0, r"smoothness must be"),
    ("haziness", "x" * 500, r"got the string 'x+\.\.\.$"),  # long values are cut
])
def test_check_value(name, value, pattern):
    with pytest.raises(ValueError) as e:
        check_value(name, value)
    assert re.search(pattern, str(e.value)), str(e.value)
    assert len(str(e.value)) < 200
