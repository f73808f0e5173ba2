# SPDX-License-Identifier: GPL-3.0-or-later
"""Scripting mistakes through the API and ``mat.hazy_gloss_settings``.

Blender prints and swallows an exception raised in a property setter (measured in 4.5, 5.2,
5.3: the assignment returns normally, sys.excepthook sees the exception), so a refused setting
cannot raise at the assignment.  What a pipeline gets instead: ``api.last_error(mat)`` (the
reason of the last refused change of that material, None after one that went through) and
``api.strict_settings()``, a block that raises ValueError when it ends if a setting in it was
refused.  The colour properties have soft limits only: a hard min/max makes Blender clamp a
vector before the setter sees it, so (230, 100, 20) became white without a word.
"""
import importlib
import sys
from types import SimpleNamespace

import bpy
import pytest

import scenes


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return SimpleNamespace(api=mod("api"), props=mod("blender.ui.properties"))


def one_line(msg):
    assert msg and "\n" not in msg.strip(), msg
    return msg


def test_setter_exceptions_are_swallowed_by_blender(env):
    """The premise: an exception in a setter does not reach the assignment."""
    seen = []
    hook, sys.excepthook = sys.excepthook, lambda t, v, tb: seen.append(t)
    try:
        mat = scenes.new_material("Plain")
        mat.hazy_gloss_settings.roughness = 0.5  # refused (not hazy): recorded, no exception
    finally:
        sys.excepthook = hook
    assert seen == []  # the add-on's setter does not raise either: it records


def test_refused_setting_reaches_the_pipeline(env):
    api = env.api
    mat = api.create_material("M", roughness=0.2)
    s = mat.hazy_gloss_settings
    s.roughness = 2.0
    msg = one_line(api.last_error(mat))
    assert "roughness must be in [0, 1], got 2" in msg.lower()
    assert api.read_parameters(mat)["roughness"] == pytest.approx(0.2)
    with pytest.raises(ValueError, match=r"^M: roughness must be in \[0, 1\]"):
        with api.strict_settings():
            s.roughness = 2.0
    with api.strict_settings():  # nothing refused: no exception, the error is cleared
        s.roughness = 0.3
    assert api.last_error(mat) is None and api.read_parameters(mat)["roughness"] == pytest.approx(0.3)
    with pytest.raises(ValueError, match=r"and 1 more refused"):
        with api.strict_settings():
            s.haziness = 1.5
            s.transmission = 0.5  # a conductor transmits no light


def test_setting_on_a_non_hazy_material(env):
    api = env.api
    plain = scenes.new_material("Plain")
    plain.hazy_gloss_settings.haziness = 0.4
    assert "not a hazy material" in one_line(api.last_error(plain))
    with pytest.raises(ValueError, match="Plain: .*not a hazy material"):
        with api.strict_settings():
            plain.hazy_gloss_settings.kind = "DIELECTRIC"
    assert "hazy_gloss" not in plain


def test_colours_in_0_255_through_the_settings(env):
    api = env.api
    mat = api.create_material("C")
    mat.hazy_gloss_settings.core_reflectivity = (230, 100, 20)
    assert "divide by 255" in one_line(api.last_error(mat))
    assert api.read_parameters(mat)["core_reflectivity"] == (0.5, 0.5, 0.5)  # unchanged


def test_material_arguments_that_are_not_materials(env):
    api = env.api
    mat = api.create_material("By name")
    for fn, args in ((api.update_material, {"haziness": 0.2}), (api.read_parameters, {}),
                     (api.make_hazy, {}), (api.remove_haze, {}), (api.sync_haze, {}),
                     (api.add_export_fallback, {}), (api.last_error, {})):
        with pytest.raises(TypeError, match=r"expects a bpy.types.Material, got str \(look it "
                                            r"up first: .*bpy.data.materials\['By name'\]"):
            fn("By name", **args)
    obj = bpy.data.objects.new("O", None)
    with pytest.raises(TypeError, match="an object: pass obj.active_material"):
        api.update_material(obj, haziness=0.2)
    assert api.read_parameters(mat)["haziness"] == 0.5


def test_api_mistakes_name_the_parameter(env):
    api = env.api
    with pytest.raises(ValueError, match=r"core_reflectivity .*write the tuple \(0.9, 0.6, 0.3\)"):
        api.create_material("S", core_reflectivity="0.9,0.6,0.3")
    with pytest.raises(ValueError, match=r"haze_extent .*got 1 value"):
        api.create_material("S", haze_extent=(5,))
    mat = api.create_material("Metal")
    for bad, pattern in ((dict(base_color=(0.3, 0.2, 0.1)), r"base_color applies to dielectrics"),
                         (dict(edge_tint=1.0, kind="LEGACY"), r"edge_tint applies to conductors"),
                         (dict(hazines=0.2), r"did you mean 'haziness'"),
                         (dict(kind="metal"), r"did you mean CONDUCTOR")):
        with pytest.raises(ValueError, match=pattern):
            api.update_material(mat, **bad)
    assert "S" not in bpy.data.materials  # nothing created by a refused call
    lay = scenes.new_material("Layer")
    api.make_hazy(lay, haziness=0.3)
    with pytest.raises(ValueError, match=r"'haze_extnt' \(did you mean 'haze_extent'\?\)"):
        api.update_material(lay, haze_extnt=4.0)
