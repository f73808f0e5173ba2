# SPDX-License-Identifier: GPL-3.0-or-later
"""QA findings on the UI, each checked the way the artist meets it:

- New Hazy Material with a paper preset and any Kind: every combination makes a material; the
  preset's values the chosen kind has no control for are left out and named in a note.
- A haze layer's panel: Physical Values and the "looks like a metal" warning follow the
  Principled BSDF's Metallic (a pure metal has no dielectric part, Metallic 0 no metal part).
- User presets: a whole material's preset on a haze layer applies its haze and says in one line
  (UI labels) what it did not apply; a layer's preset stores Reflectivity Cap.
- A Shader Editor showing a World's or a Light's nodes: no Hazy Gloss node is added there and
  the material operators refuse instead of editing the active object's material.
- The same words for a missing material everywhere; a batch conversion with no set converted
  is an error.
"""
import importlib
import os
from types import SimpleNamespace

import bpy
import pytest


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    mod("blender.ui.reports").last_reports.clear()
    return SimpleNamespace(api=mod("api"), presets=mod("utils.presets"),
                           reports=mod("blender.ui.reports"), panels=mod("blender.ui.panels"),
                           layer=mod("blender.model.layer"), menus=mod("blender.ui.menus"),
                           ops=mod("blender.ui.operators"), context=mod("blender.ui.context"),
                           props=mod("blender.ui.properties"),
                           messages=mod("blender.actions.messages"))


def _object():
    obj = bpy.data.objects.new("Obj", bpy.data.meshes.new("Obj"))
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    return obj


def _principled(name, metallic=0.0, coat=0.0):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Coat Weight"].default_value = coat
    bsdf.inputs["Roughness"].default_value = 0.2
    return mat


def _messages(env):
    return [m for _, m in env.reports.last_reports]


# ------------------------------------------------------------------------------------------------
# 1. New Hazy Material: Preset x Kind
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["CONDUCTOR", "DIELECTRIC", "LEGACY"])
def test_new_material_any_preset_with_any_kind(env, kind):
    obj = _object()
    labels = {"edge_tint": "Edge Tint", "base_color": "Base Color", "transmission": "Transmission"}
    for pid, preset in env.presets.PRESETS.items():
        env.reports.last_reports.clear()
        assert bpy.ops.hazy_gloss.new_material(preset=pid, kind=kind) == {"FINISHED"}, pid
        mat = obj.active_material
        p = env.api.read_parameters(mat)
        assert p["kind"] == kind, pid
        assert p["haziness"] == pytest.approx(preset.haziness), pid  # the rest is the preset's
        assert tuple(p["haze_extent"]) == pytest.approx(preset.haze_extent), pid
        want = env.presets.parameters(pid)
        if kind == preset.kind == "CONDUCTOR":
            assert tuple(p["edge_tint"]) == pytest.approx(preset.edge_tint), pid
        notes = [m for m in _messages(env) if "left out" in m]
        for key, label in labels.items():
            has = (key == "edge_tint") == (kind == "CONDUCTOR") and kind != "LEGACY"
            had = want[key] > 0 if key == "transmission" else any(want[key])
            assert any(label in n for n in notes) == (had and not has), (pid, notes)
        for note in notes:  # one line, the preset as the dialog names it, no API names
            assert preset.name in note and "\n" not in note and "_" not in note, note


# ------------------------------------------------------------------------------------------------
# 2. A haze layer's Physical Values and warnings follow Metallic
# ------------------------------------------------------------------------------------------------


def _layer_info(env, metallic, link=False):
    mat = _principled(f"M{metallic}{link}", metallic=metallic)
    if link:
        tree = mat.node_tree
        value = tree.nodes.new("ShaderNodeValue")
        tree.links.new(value.outputs[0], tree.nodes["Principled BSDF"].inputs["Metallic"])
    env.api.make_hazy(mat, haziness=0.5)
    return env.layer.summary(mat)


@pytest.mark.parametrize("metallic, link, dielectric, metal", [
    (1.0, False, False, True), (0.0, False, True, False), (0.5, False, True, True),
    (1.0, True, True, True)])
def test_layer_values_follow_metallic(env, metallic, link, dielectric, metal):
    info = _layer_info(env, metallic, link)
    rows = [label for label, _ in env.panels.layer_rows(info)]
    assert any(r.startswith("Dielectric:") for r in rows) == dielectric, rows
    assert any(r.startswith("Metal:") for r in rows) == metal, rows
    warns = env.panels.layer_warnings(info, bpy.context)
    assert any("look like a metal" in w for w in warns) == dielectric, warns  # r = 0.52 here


# ------------------------------------------------------------------------------------------------
# 3. User presets on a haze layer
# ------------------------------------------------------------------------------------------------


def _preset_file(name):
    for folder in bpy.utils.preset_paths(bpy.types.HAZY_GLOSS_MT_presets.preset_subdir):
        for f in os.listdir(folder):
            if f.lower() == name.lower().replace(" ", "_") + ".py":
                return os.path.join(folder, f)
    raise FileNotFoundError(name)


def _run_preset(path):
    return bpy.ops.script.execute_preset(filepath=path, menu_idname="HAZY_GLOSS_MT_presets")


def test_whole_material_preset_on_a_haze_layer(env, capsys):
    obj = _object()
    assert bpy.ops.hazy_gloss.new_material(name="Whole", kind="DIELECTRIC") == {"FINISHED"}
    whole = bpy.data.materials["Whole"]
    whole.hazy_gloss_settings.haziness = 0.07
    with bpy.context.temp_override(material=whole, object=obj):
        assert bpy.ops.hazy_gloss.preset_add(name="QA Whole") == {"FINISHED"}
    path = _preset_file("QA Whole")
    lay = _principled("Lay", metallic=1.0)
    env.api.make_hazy(lay, haziness=0.0)
    roughness = lay.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value
    capsys.readouterr()
    try:
        with bpy.context.temp_override(material=lay, object=obj):
            assert _run_preset(path) == {"FINISHED"}
    finally:
        os.remove(path)
    p = env.api.read_parameters(lay)
    assert p["haziness"] == pytest.approx(0.07)  # the haze is applied
    assert p["roughness"] == pytest.approx(roughness)  # the BSDF's stay
    err = env.messages.error_for(lay)
    # one line naming what was not applied as the panel labels it, no API names
    assert err and "\n" not in err and "QA Whole" in err
    for label in ("Core Reflectivity", "Roughness", "In-Shader Mapping", "Tangent"):
        assert label in err, err
    assert "Haziness" not in err and "_" not in err, err
    out = capsys.readouterr().out
    assert "belongs to its BSDF node" not in out and out.count("Hazy Gloss:") <= 1, out


def test_layer_preset_stores_reflectivity_cap(env):
    obj = _object()
    lay = _principled("Lay", coat=1.0)
    env.api.make_hazy(lay, haziness=0.2)
    env.api.update_material(lay, reflectivity_cap=0.9)
    with bpy.context.temp_override(material=lay, object=obj):
        assert bpy.ops.hazy_gloss.preset_add(name="QA Layer") == {"FINISHED"}
    path = _preset_file("QA Layer")
    other = _principled("Other", coat=1.0)
    env.api.make_hazy(other, haziness=0.0)
    try:
        with open(path) as f:
            assert "reflectivity_cap" in f.read()
        with bpy.context.temp_override(material=other, object=obj):
            assert _run_preset(path) == {"FINISHED"}
    finally:
        os.remove(path)
    p = env.api.read_parameters(other)
    assert p["reflectivity_cap"] == pytest.approx(0.9) and p["haziness"] == pytest.approx(0.2)
    assert env.messages.error_for(other) is None  # a layer's preset fits a layer


# ------------------------------------------------------------------------------------------------
# 4. A World's or a Light's shader tree
# ------------------------------------------------------------------------------------------------


def _foreign_contexts(obj):
    world = bpy.data.worlds.new("W")
    light = bpy.data.lights.new("L", "POINT")
    for owner in (world, light):
        if not getattr(owner, "node_tree", None):
            owner.use_nodes = True
        space = SimpleNamespace(type="NODE_EDITOR", tree_type="ShaderNodeTree", id=owner,
                                edit_tree=owner.node_tree, shader_type="WORLD"
                                if owner == world else "OBJECT", cursor_location=(0.0, 0.0))
        yield owner, SimpleNamespace(space_data=space, object=obj, active_object=obj,
                                     material=None, active_node=None)


def _fake_op(**props):
    said = []
    op = SimpleNamespace(material="", node="", report=lambda level, msg: said.append(msg),
                         properties=SimpleNamespace(is_property_set=lambda k: False), **props)
    return op, said


def test_world_and_light_trees_are_refused(env):
    obj = _object()
    mat = _principled("ObjMat")
    obj.data.materials.append(mat)
    for owner, ctx in _foreign_contexts(obj):
        before = [n.bl_idname for n in owner.node_tree.nodes]
        op, said = _fake_op(kind="CONDUCTOR", distribution="GGX", anisotropic=False,
                            smooth=False)
        assert env.menus.HAZY_GLOSS_OT_add_node.execute(op, ctx) == {"CANCELLED"}
        assert [n.bl_idname for n in owner.node_tree.nodes] == before
        assert len(said) == 1 and owner.name in said[0] and "material" in said[0], said
        assert env.context.target_material(ctx) is None
        op, said = _fake_op()
        assert env.ops.HAZY_GLOSS_OT_make_hazy.execute(op, ctx) == {"CANCELLED"}
        assert len(said) == 1 and owner.name in said[0] and "\n" not in said[0], said
        assert not env.api.is_hazy(mat)  # the active object's material is not touched


# ------------------------------------------------------------------------------------------------
# 5. Consistent words; a batch with nothing converted is an error
# ------------------------------------------------------------------------------------------------


def test_missing_material_said_the_same_way(env):
    said = []
    for op in ("make_hazy", "remove_haze", "add_haziness_map", "apply_preset", "upgrade_layers",
               "plot_to_image"):
        with pytest.raises(RuntimeError):
            getattr(bpy.ops.hazy_gloss, op)(material="Nope")
        said.append(env.reports.last_reports[-1][1])
    assert set(said) == {"No material named “Nope”"}, said
    # and with no material at all (the export fallback raised AttributeError on None)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    with pytest.raises(RuntimeError, match="^Error: No active material"):
        bpy.ops.hazy_gloss.add_export_fallback()
    with pytest.raises(RuntimeError, match="^Error: No material named “Nope”"):
        bpy.ops.hazy_gloss.add_export_fallback(material="Nope")


def test_batch_with_no_set_converted_is_an_error(env, tmp_path):
    broken = tmp_path / "lib" / "Broken"
    broken.mkdir(parents=True)
    (broken / "Broken_Color.png").write_bytes(b"not a png")
    (broken / "Broken_Roughness.png").write_bytes(b"not a png either")
    with pytest.raises(RuntimeError, match="Hazy maps"):
        bpy.ops.hazy_gloss.convert_pbr_set(folder=str(tmp_path / "lib"), batch=True,
                                           directory=str(tmp_path / "out") + os.sep)
