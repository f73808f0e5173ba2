# SPDX-License-Identifier: GPL-3.0-or-later
"""The scripting API keeps the user's part of a material when it rebuilds the hazy nodes."""
import importlib

import pytest


@pytest.fixture
def api(hg, clean_file):
    return importlib.import_module(hg.__name__ + ".api")


def test_update_keeps_texture_links_and_downstream_links(api):
    mat = api.create_material("tex", shader_mapping=True, kind="CONDUCTOR", haziness=0.5)
    tree = mat.node_tree
    group = tree.nodes[api.GROUP_NODE]
    tex = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(tex.outputs["Fac"], group.inputs["Haziness"])
    # the user puts the hazy BSDF under a mix with something else
    mix = tree.nodes.new("ShaderNodeMixShader")
    out = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"][0]
    tree.links.new(group.outputs["BSDF"], mix.inputs[1])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])

    api.update_material(mat, haze_extent=9.0, core_reflectivity=(0.8, 0.5, 0.2))

    group = tree.nodes[api.GROUP_NODE]
    assert group.inputs["Haziness"].is_linked
    assert group.inputs["Haziness"].links[0].from_node == tex
    assert mix.inputs[1].is_linked and mix.inputs[1].links[0].from_node == group
    assert out.inputs["Surface"].links[0].from_node == mix
    assert api.read_parameters(mat)["haze_extent"] == (9.0, 9.0)


def test_constant_mapping_refused_while_textures_are_linked(api):
    mat = api.create_material("tex", shader_mapping=True, haziness=0.5)
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(tex.outputs["Fac"], tree.nodes[api.GROUP_NODE].inputs["Haziness"])
    with pytest.raises(ValueError, match="Haziness"):
        api.update_material(mat, shader_mapping=False)
    assert tree.nodes[api.GROUP_NODE].inputs["Haziness"].is_linked  # nothing was touched


def test_bad_values_raise_before_touching_the_tree(api):
    mat = api.create_material("m", haziness=0.5)
    names = sorted(n.name for n in mat.node_tree.nodes)
    for bad in (dict(haziness=1.0), dict(haziness=float("nan")), dict(roughness=-0.1),
                dict(core_reflectivity=(2.0, 0.5, 0.5)), dict(kind="PLASTIC"),
                dict(kind="DIELECTRIC", distribution="BECKMANN")):
        with pytest.raises(ValueError):
            api.update_material(mat, **bad)
    assert sorted(n.name for n in mat.node_tree.nodes) == names
    assert api.read_parameters(mat)["haziness"] == 0.5


def test_material_operators_are_in_menus(hg):
    """F3 menu search finds what menus list: the material operators are in Node > Hazy Gloss and
    the material specials menu; the entry leaves with the add-on."""
    import bpy
    ops = importlib.import_module(hg.__name__ + ".blender.ui.menus")
    for name in ("NODE_MT_node", "MATERIAL_MT_context_menu"):
        assert ops.draw_menu_entry in getattr(bpy.types, name)._dyn_ui_initialize()
    listed = []

    class Layout:
        def operator(self, idname, **kw):
            assert idname.split(".")[1] in dir(bpy.ops.hazy_gloss), idname
            listed.append(idname)

        def menu(self, idname, **kw):
            assert hasattr(bpy.types, idname), idname
            listed.append(idname)

    ops.HAZY_GLOSS_MT_material.draw(type("M", (), {"layout": Layout()})(), None)
    assert listed == ["hazy_gloss.make_hazy", "hazy_gloss.remove_haze", "hazy_gloss.new_material",
                      "hazy_gloss.import_two_lobe_mix", "hazy_gloss.convert_pbr_set",
                      "HAZY_GLOSS_MT_presets"]
