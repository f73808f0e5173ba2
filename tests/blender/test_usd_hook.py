# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's own File > Export / Import > USD with the add-on: its USDHook puts each hazy
material's network and haze values on the exported Material, and brings a hazy material back
on import, which renders as the one exported.  Blender's preview surface stays (the user's
BSDF at haziness 0); its MaterialX translation of the layer's group goes.  A failing hook
leaves Blender's own export whole.  (tests/blender/test_usd_export.py: the export finishes,
with and without the add-on.)"""
import importlib
from types import SimpleNamespace

import bpy
import numpy as np
import pytest
from pxr import Usd, UsdShade

import test_layer as TL


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return SimpleNamespace(api=mod("api"), layer=mod("blender.model.layer"), exr=mod("conversion.imagecheck"),
                           hook=mod("blender.actions.usd_hook"), hg=hg)


def _uv_image(mat, name, pixels, non_color=True):
    """An Image Texture on the UV map (MaterialX reads textures by UV; Window coordinates,
    which tests/blender/test_layer.py uses, have no MaterialX node)."""
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation = TL.image(name, pixels, non_color=non_color), "Closest"
    return tex


def _textured_plastic():
    """A plastic with Base Color and Roughness maps (generated images: written as tables
    beside the USD file), Multiscatter GGX (the Principled's default)."""
    mat, b = TL.principled("Textured Plastic", distribution="MULTI_GGX")
    rng = np.random.default_rng(11)
    col = np.concatenate([rng.uniform(0.05, 0.8, (4, 4, 3)), np.ones((4, 4, 1))], -1)
    tree = mat.node_tree
    tree.links.new(_uv_image(mat, "colour", col, False).outputs["Color"], b.inputs["Base Color"])
    rough = TL.grey(rng.uniform(0.1, 0.5, (4, 4)))
    tree.links.new(_uv_image(mat, "rough", rough).outputs["Color"], b.inputs["Roughness"])
    return mat


def _metallic_map():
    mat, b = TL.principled("Metallic Map", **{"Base Color": (0.9, 0.6, 0.3, 1.0),
                                              "Roughness": 0.25, "IOR": 1.6})
    tex = _uv_image(mat, "metallic", TL.grey(TL.METALLIC_MAP))
    mat.node_tree.links.new(tex.outputs["Color"], b.inputs["Metallic"])
    return mat


MATERIALS = {"textured plastic": _textured_plastic, "car paint": TL.car_paint,
             "metallic map": _metallic_map}
HAZE = {"haziness": 0.4, "coat_haziness": 0.3}


def _clear():
    for coll in (bpy.data.objects, bpy.data.materials, bpy.data.node_groups, bpy.data.images):
        for item in list(coll):
            coll.remove(item)


def _haze_values(env, mat):
    """The layer node's unlinked input values, flat: {(input, lane): value}."""
    node = env.layer.layer_node(mat)
    out = {}
    for s in node.inputs:
        if not s.is_linked and hasattr(s, "default_value"):
            v = s.default_value
            for i, x in enumerate(v if hasattr(v, "__len__") else (v,)):
                out[(s.name, i)] = float(x)
    return out


@pytest.mark.parametrize("materialx", [True, False])
@pytest.mark.parametrize("label", sorted(MATERIALS))
def test_usd_export_carries_the_haze_and_import_brings_it_back(env, tmp_path, label, materialx):
    mat = MATERIALS[label]()
    TL.make_hazy(env, mat, **HAZE)
    TL.render(env, mat)  # (the scene: a plane with the material, exported below)
    values, name = _haze_values(env, mat), mat.name
    path = tmp_path / "hazy.usda"
    assert bpy.ops.wm.usd_export(filepath=str(path), export_materials=True,
                                 generate_materialx_network=materialx) == {"FINISHED"}
    stage = Usd.Stage.Open(str(path))
    prim = next(p for p in stage.Traverse() if p.IsA(UsdShade.Material) and p.GetName() ==
                name.replace(" ", "_"))
    assert prim.GetAttribute("userProperties:hazy_gloss:layered").Get() is True
    assert prim.GetAttribute("userProperties:hazy_gloss:haziness").Get() == pytest.approx(0.4)
    m = UsdShade.Material(prim)
    network = m.ComputeSurfaceSource("mtlx")[0]
    assert network and network.GetPath().HasPrefix(prim.GetPath().AppendChild("NG"))
    preview = m.ComputeSurfaceSource()[0]  # Blender's: the user's BSDF at haziness 0
    assert preview.GetIdAttr().Get() == "UsdPreviewSurface"
    # what Blender translated of the layer's group is gone: only the network and the preview
    names = [c.GetName() for c in prim.GetChildren()]
    assert "NG" in names and not [n for n in names if n == "NodeGraphs" or
                                  n.startswith("bnode__") or n.endswith("_mtlx1")], names

    # imported into the same file (as “… .001”), both rendered in the scene the import leaves
    assert bpy.ops.wm.usd_import(filepath=str(path)) == {"FINISHED"}
    got = next((m for m in bpy.data.materials if m.name.startswith(name + ".")), None)
    assert got is not None, [m.name for m in bpy.data.materials]
    assert env.layer.layer_node(got) is not None
    assert _haze_values(env, got) == pytest.approx(values)
    before, after = TL.render(env, mat)["combined"], TL.render(env, got)["combined"]
    assert np.abs(after - before).max() <= 1e-6 * max(1.0, float(np.abs(before).max())), (got.name, [m.name for m in bpy.data.materials])


def test_a_material_without_haze_is_blenders_own(env, tmp_path):
    plain, _ = TL.principled("Plain", **{"Base Color": (0.2, 0.4, 0.6, 1.0)})
    TL.render(env, plain)
    path = tmp_path / "plain.usda"
    bpy.ops.wm.usd_export(filepath=str(path), export_materials=True, generate_materialx_network=True)
    stage = Usd.Stage.Open(str(path))
    prim = next(p for p in stage.Traverse() if p.IsA(UsdShade.Material))
    assert not prim.HasAttribute("userProperties:hazy_gloss:layered")
    assert "NG" not in [c.GetName() for c in prim.GetChildren()]
    _clear()
    bpy.ops.wm.usd_import(filepath=str(path))
    got = bpy.data.materials["Plain"]
    assert env.layer.layer_node(got) is None
    bsdf = next(n for n in got.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    assert tuple(bsdf.inputs["Base Color"].default_value)[:3] == pytest.approx((0.2, 0.4, 0.6))


def test_a_failing_hook_leaves_blenders_export_whole(env, tmp_path, monkeypatch, capfd):
    """An exception in the hook would make Blender's export report an error (and a script's
    bpy.ops call raise): the hook says it in one line and Blender's own material is written."""
    mat = TL.car_paint()
    TL.make_hazy(env, mat, **HAZE)
    TL.render(env, mat)

    def broken(*args, **kwargs):
        raise ValueError("the snapshot could not be read")
    monkeypatch.setattr(env.hook, "export_material", broken)
    path = tmp_path / "hazy.usda"
    assert bpy.ops.wm.usd_export(filepath=str(path), export_materials=True,
                                 generate_materialx_network=True) == {"FINISHED"}
    stage = Usd.Stage.Open(str(path))
    prim = next(p for p in stage.Traverse() if p.IsA(UsdShade.Material))
    assert not prim.HasAttribute("userProperties:hazy_gloss:layered")
    assert UsdShade.Material(prim).ComputeSurfaceSource()[0]  # Blender's preview is there
    said = [ln for ln in capfd.readouterr().out.splitlines() if "Hazy Gloss" in ln]
    assert said == ["Hazy Gloss: “Car Paint” is in the USD file without its haze: The "
                    "snapshot could not be read"], said


def test_a_failing_import_leaves_blenders_reading(env, tmp_path, monkeypatch, capfd):
    """The hook claims the material and fails: Blender reads its preview surface (the user's
    BSDF at haziness 0), and the hook says so in one line."""
    mat = TL.car_paint()
    TL.make_hazy(env, mat, **HAZE)
    TL.render(env, mat)
    path = tmp_path / "hazy.usda"
    bpy.ops.wm.usd_export(filepath=str(path), export_materials=True, generate_materialx_network=True)
    _clear()

    def broken(*args, **kwargs):
        raise ValueError("the network could not be read")
    monkeypatch.setattr(env.hook, "import_material", broken)
    capfd.readouterr()
    assert bpy.ops.wm.usd_import(filepath=str(path)) == {"FINISHED"}
    (got,) = bpy.data.materials
    assert env.layer.layer_node(got) is None
    bsdf = next(n for n in got.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    assert tuple(bsdf.inputs["Base Color"].default_value)[:3] == pytest.approx((0.6, 0.05, 0.05))
    said = [ln for ln in capfd.readouterr().out.splitlines() if "Hazy Gloss" in ln]
    assert len(said) == 1 and said[0].endswith("The network could not be read"), said
