# SPDX-License-Identifier: GPL-3.0-or-later
"""Interchange inside Blender: MaterialX export / import of real Blender materials, USD through
usd-core, and the export fallback that makes Blender's own glTF and USD exporters write the
core lobe — read back with pygltflib and usd-core, with Cycles and EEVEE renders unchanged.

Expected values come from the perceptual parameters the test sets (the core lobe's look is
base colour r_c, roughness R), from Blender's nodes, or from the real ``materialx`` package;
none is taken from the code under test."""
import importlib
import json
import math
import os

import bpy
import numpy as np
import pytest
import pygltflib
import MaterialX as mx
from pxr import Usd, UsdShade

import scenes

CONDUCTOR = dict(kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.4), edge_tint=(1.0, 0.8, 0.6),
                 roughness=0.2, haziness=0.6, haze_extent=5.0)
DIELECTRIC = dict(kind="DIELECTRIC", core_reflectivity=(0.05, 0.04, 0.03), roughness=0.25,
                  haziness=0.2, haze_extent=5.0, base_color=(0.2, 0.3, 0.5))
LEGACY = dict(kind="LEGACY", core_reflectivity=0.5, roughness=0.3, haziness=0.5, haze_extent=4.0)
ANISO = dict(kind="CONDUCTOR", core_reflectivity=(0.6, 0.6, 0.65), edge_tint=(0.9, 0.9, 0.95),
             roughness=0.3, anisotropy=0.5, rotation=0.125, haziness=0.5, haze_extent=(6.0, 2.0))
MATERIALS = {"copper": CONDUCTOR, "varnish": DIELECTRIC, "legacy": LEGACY, "brushed": ANISO}


@pytest.fixture
def api(hg, clean_file):
    return importlib.import_module(hg.__name__ + ".api")


@pytest.fixture
def ix(hg):
    return importlib.import_module(hg.__name__ + ".blender.actions.interchange")


@pytest.fixture
def fallback(hg):
    return importlib.import_module(hg.__name__ + ".blender.model.fallback")


def _stdlib():
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    return lib


def _validate(path):
    """(the document as read by MaterialX, without the libraries; (ok, message) of
    Document.validate() with the standard libraries imported)."""
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    full = mx.createDocument()
    mx.readFromXmlFile(full, str(path))
    full.importLibrary(_stdlib())
    return doc, full.validate()


def _make(api):
    return {name: api.create_material(name, **p) for name, p in MATERIALS.items()}


def _cubes(mats):
    for i, m in enumerate(mats.values()):
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=(2.0 * i, 0.0, 0.0))
        bpy.context.active_object.data.materials.append(m)


def _tree_signature(mat):
    t = mat.node_tree
    return (sorted((n.name, n.bl_idname) for n in t.nodes),
            sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name,
                    l.to_socket.identifier) for l in t.links))


# --------------------------------------------------------------------------------------------
# MaterialX from Blender materials
# --------------------------------------------------------------------------------------------


def test_export_validates_and_comes_back_with_the_same_parameters(api, tmp_path):
    mats = _make(api)
    before = {n: api.read_parameters(m) for n, m in mats.items()}
    rep = api.export_materialx(list(mats.values()), str(tmp_path / "hazy.mtlx"))
    doc, (ok, msg) = _validate(rep.path)
    assert ok, msg
    assert rep.validated is True
    # every material is a surfacematerial -> surface -> BSDF mix whose weight is the β the
    # material renders with (Blender's Mix Shader factor)
    assert sorted(m.getName() for m in doc.getMaterialNodes()) == sorted(mats)
    for m in doc.getMaterialNodes():
        mixes = [e.getUpstreamElement() for e in m.traverseGraph()
                 if e.getUpstreamElement().getCategory() == "mix"
                 and e.getUpstreamElement().getType() == "BSDF"]
        assert len({x.getName() for x in mixes}) == 1
        beta = float(mixes[0].getInput("mix").getValueString())
        fac = mats[m.getName()].node_tree.nodes.get("HG Lobe mix")
        want = fac.inputs["Fac"].default_value if fac is not None else 0.0  # legacy: Add Shader
        if fac is not None:
            assert beta == pytest.approx(want, rel=1e-6)  # the socket is float32
        assert beta == pytest.approx(float(api.map_parameters(api.read_parameters(mats[m.getName()])).beta), rel=1e-12)
    res = api.import_materialx(rep.path)
    assert len(res) == len(mats)
    for im in res.report:
        assert im.exact and im.source == "hazy_gloss", im.notes
        new = api.read_parameters(im.material)
        old = before[im.name]
        for k in ("core_reflectivity", "edge_tint", "roughness", "anisotropy", "rotation",
                  "haziness", "haze_extent", "base_color", "transmission"):
            assert np.max(np.abs(np.subtract(new[k], old[k]))) <= 1e-5, (im.name, k)
        assert (new["kind"], new["distribution"]) == (old["kind"], old["distribution"])
        assert im.material["hazy_gloss_import"]["exact"] == 1



def test_map_driven_material_exports_image_nodes_with_raw_colour_space(api, hg, tmp_path):
    """A material wired to converted maps (convert_maps + material=...) is written with one
    image node per map file, colorspace raw (data), paths that resolve to the written maps;
    the document validates and imports back as a map-driven material."""
    mat = bpy.data.materials.new("maps")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    h = np.linspace(0.1, 0.9, 16, dtype=np.float32).reshape(4, 4)
    result = api.convert_maps({"haziness": h, "roughness": 0.2, "core_reflectivity": (0.9, 0.6, 0.4),
                               "edge_tint": 0.5, "anisotropy": 0.3}, str(tmp_path / "maps"),
                              kind="CONDUCTOR", material=mat)
    rep = api.export_materialx([mat], str(tmp_path / "maps.mtlx"))
    doc, (ok, msg) = _validate(rep.path)
    assert ok, msg
    images = [n for n in doc.traverseTree() if n.isA(mx.Node) and n.getCategory() == "image"]
    files = {}
    for img in images:
        f = img.getInput("file")
        assert f.getColorSpace() == "raw"
        files[os.path.normpath(os.path.join(str(tmp_path), f.getValueString()))] = img
    assert set(files) == {os.path.normpath(p) for p in result.values()}
    res = api.import_materialx(rep.path)
    assert len(res) == 1 and res.report[0].maps is not None
    new = res[0]
    loaded = sorted(os.path.normpath(bpy.path.abspath(n.image.filepath)) for n in new.node_tree.nodes
                    if n.bl_idname == "ShaderNodeTexImage")
    assert loaded == sorted(files)


def test_operator_exports_and_says_when_materialx_is_missing(api, hg, tmp_path, monkeypatch):
    reports = importlib.import_module(hg.__name__ + ".blender.ui.reports")
    mx_mod = importlib.import_module(hg.__name__ + ".interchange.materialx")
    api.create_material("m", **CONDUCTOR)
    path = str(tmp_path / "op.mtlx")
    assert bpy.ops.hazy_gloss.export_materialx(filepath=path) == {"FINISHED"}
    assert _validate(path)[1][0]

    def missing(_path):
        return None, "the materialx package is not installed"
    monkeypatch.setattr(mx_mod, "validate", missing)
    reports.last_reports.clear()
    assert bpy.ops.hazy_gloss.export_materialx(filepath=str(tmp_path / "op2.mtlx")) == {"FINISHED"}
    assert os.path.isfile(tmp_path / "op2.mtlx")  # the XML itself needs no package
    assert any(lvl == "WARNING" and "materialx package is not installed" in msg
               for lvl, msg in reports.last_reports)


def test_usd_operator_says_when_pxr_is_missing(api, hg, tmp_path, monkeypatch):
    reports = importlib.import_module(hg.__name__ + ".blender.ui.reports")
    usd_mod = importlib.import_module(hg.__name__ + ".interchange.usd")
    api.create_material("m", **CONDUCTOR)
    monkeypatch.setattr(usd_mod, "available", lambda: False)
    reports.last_reports.clear()
    with pytest.raises(RuntimeError, match="usd-core"):  # bpy.ops raises on an ERROR report
        bpy.ops.hazy_gloss.export_usd(filepath=str(tmp_path / "x.usda"))
    assert any(lvl == "ERROR" and "usd-core" in msg for lvl, msg in reports.last_reports)
    assert not os.path.exists(tmp_path / "x.usda")


def test_menus_list_the_interchange_operators(hg):
    menus = importlib.import_module(hg.__name__ + ".blender.ui.menus")
    ix = importlib.import_module(hg.__name__ + ".blender.ui.interchange_ops")
    entries = {(m, f.__name__) for m, f in menus.ENTRIES}
    assert ("TOPBAR_MT_file_export", "draw_export_menu") in entries
    assert ("TOPBAR_MT_file_import", "draw_import_menu") in entries
    for cls in ix.classes:  # (the USD hook is registered without a bpy.types name)
        assert cls.is_registered, cls
    assert hasattr(bpy.types, ix.HAZY_GLOSS_OT_export_usd.__name__)


# --------------------------------------------------------------------------------------------
# USD through usd-core
# --------------------------------------------------------------------------------------------


def test_usd_export_carries_the_materialx_network(api, tmp_path):
    mats = _make(api)
    path, done, skipped = api.export_usd(list(mats.values()), str(tmp_path / "hazy.usda"))
    stage = Usd.Stage.Open(path)
    found = {}
    for prim in stage.Traverse():
        if not prim.IsA(UsdShade.Material):
            continue
        m = UsdShade.Material(prim)
        src = m.GetSurfaceOutput("mtlx").GetConnectedSources()[0][0]
        assert UsdShade.Shader(src.source.GetPrim()).GetIdAttr().Get() == "ND_surface"
        ids = {UsdShade.Shader(p).GetIdAttr().Get() for p in Usd.PrimRange(prim) if p.IsA(UsdShade.Shader)}
        assert "ND_mix_bsdf" in ids
        # the preview surface is the core lobe: roughness R of the core, metallic for metals
        pv = m.ComputeSurfaceSource()[0]
        assert pv.GetIdAttr().Get() == "UsdPreviewSurface"
        found[json.loads(prim.GetCustomDataByKey("hazygloss"))["name"]] = pv
    assert set(found) == set(mats)
    for name, p in MATERIALS.items():
        pv = found[name]
        assert pv.GetInput("roughness").Get() == pytest.approx(p["roughness"], abs=1e-6)
        want = (1.0 if p["kind"] != "DIELECTRIC" else 0.0)
        assert pv.GetInput("metallic").Get() == want
        col = np.array(pv.GetInput("diffuseColor").Get())
        expect = p.get("base_color") if p["kind"] == "DIELECTRIC" else p["core_reflectivity"]
        assert np.allclose(col, np.broadcast_to(expect, 3), atol=1e-6)
    res = api.import_materialx(path)
    assert all(im.exact for im in res.report)


# --------------------------------------------------------------------------------------------
# The export fallback: Blender's glTF and USD exporters
# --------------------------------------------------------------------------------------------


def _gltf(path):
    g = pygltflib.GLTF2().load(path)
    return {m.name: m for m in g.materials}


def _usd_previews(path):
    stage = Usd.Stage.Open(path)
    out = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdShade.Material):
            s = UsdShade.Material(prim).ComputeSurfaceSource()[0]
            out[prim.GetName()] = ({i.GetBaseName(): i.Get() for i in s.GetInputs()} if s else None)
    return out


def _core_look(p):
    """What the core lobe looks like, from the perceptual parameters alone."""
    if p["kind"] == "DIELECTRIC":
        return 0.0, np.broadcast_to(p["base_color"], 3), p["roughness"]
    return 1.0, np.broadcast_to(p["core_reflectivity"], 3), p["roughness"]


def test_gltf_and_usd_exporters_get_the_core_lobe(api, tmp_path):
    mats = _make(api)
    _cubes(mats)
    for m in mats.values():
        api.add_export_fallback(m)
    glb = str(tmp_path / "scene.glb")
    usda = str(tmp_path / "scene.usda")
    bpy.ops.export_scene.gltf(filepath=glb, export_format="GLB")
    bpy.ops.wm.usd_export(filepath=usda, generate_preview_surface=True)
    gl = _gltf(glb)
    us = _usd_previews(usda)
    for name, p in MATERIALS.items():
        metallic, colour, rough = _core_look(p)
        pbr = gl[name].pbrMetallicRoughness
        assert pbr is not None, name
        assert pbr.metallicFactor == pytest.approx(metallic, abs=1e-6)
        assert np.allclose(pbr.baseColorFactor[:3], colour, atol=1e-6), name
        assert pbr.roughnessFactor == pytest.approx(rough, abs=1e-6), name  # the core, not the halo
        pv = us[name]
        assert pv is not None, name
        assert pv["metallic"] == pytest.approx(metallic, abs=1e-6)
        assert np.allclose(pv["diffuseColor"], colour, atol=1e-6), name
        assert pv["roughness"] == pytest.approx(rough, abs=1e-6), name
    assert "KHR_materials_anisotropy" in (gl["brushed"].extensions or {})


def test_without_fallback_the_exporters_lose_the_core(api, tmp_path):
    """The status quo the fallback fixes (measured, so a Blender that changes it is noticed):
    a conductor gets no PBR block in glTF and no preview surface in USD."""
    mats = {"copper": api.create_material("copper", **CONDUCTOR)}
    _cubes(mats)
    glb = str(tmp_path / "plain.glb")
    usda = str(tmp_path / "plain.usda")
    bpy.ops.export_scene.gltf(filepath=glb, export_format="GLB")
    bpy.ops.wm.usd_export(filepath=usda, generate_preview_surface=True)
    pbr = _gltf(glb)["copper"].pbrMetallicRoughness
    assert pbr is None or pbr.baseColorFactor in (None, [1.0, 1.0, 1.0, 1.0])
    assert _usd_previews(usda)["copper"] is None


def test_fallback_is_idempotent_and_removable(api, ix, fallback):
    mats = _make(api)
    for m in mats.values():
        before = _tree_signature(m)
        active = next(n.name for n in m.node_tree.nodes
                      if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output)
        api.add_export_fallback(m)
        once = _tree_signature(m)
        api.add_export_fallback(m)
        assert _tree_signature(m) == once
        assert fallback.has_export_fallback(m)
        assert api.remove_export_fallback(m)
        assert _tree_signature(m) == before
        assert [n.name for n in m.node_tree.nodes
                if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output] == [active]
        assert not fallback.has_export_fallback(m)


def test_fallback_survives_a_rebuild_when_added_again(api, ix, fallback):
    m = api.create_material("m", **CONDUCTOR)
    api.add_export_fallback(m)
    api.update_material(m, anisotropy=0.4)  # iso -> aniso: the hazy nodes are rebuilt
    surf = next(n for n in m.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"
                and not ix.material.is_ours(n)).inputs["Surface"]
    assert surf.is_linked  # the renderers' output still gets the hazy BSDF
    api.add_export_fallback(m)
    assert fallback.has_export_fallback(m)
    fb = ix.material.ours(m.node_tree)["Export fallback"]
    assert fb.inputs["Anisotropic"].default_value == pytest.approx(0.4)


def _scene_for_render(mats):
    for i, m in enumerate(mats.values()):
        bpy.ops.mesh.primitive_plane_add(size=1.0, location=(1.2 * (i - 1.5) + 0.0137, 0.0213, 0.0))
        bpy.context.object.data.materials.append(m)
        bpy.context.object.data.uv_layers.active  # UV tangent for the anisotropic one
    cam = bpy.data.cameras.new("cam")
    cam.type = "ORTHO"
    cam.ortho_scale = 4.8
    cam_obj = bpy.data.objects.new("cam", cam)
    bpy.context.scene.collection.objects.link(cam_obj)
    cam_obj.location = (0.0, 0.0, 5.0)
    bpy.context.scene.camera = cam_obj
    sun = bpy.data.lights.new("sun", "SUN")
    sun.angle = 0.05
    sun.energy = 3.0
    sun_obj = bpy.data.objects.new("sun", sun)
    bpy.context.scene.collection.objects.link(sun_obj)
    sun_obj.rotation_euler = (math.radians(20.0), math.radians(10.0), 0.0)
    scenes.uniform_world(0.3)


@pytest.mark.parametrize("engine", ["CYCLES", "EEVEE"])
def test_fallback_does_not_change_renders(api, engine):
    mats = _make(api)
    _scene_for_render(mats)
    if engine == "CYCLES":
        scenes.setup_render("CYCLES", samples=4, resolution=(96, 24), bounces=2)
    else:
        scenes.eevee_setup(samples=1, resolution=(96, 24))
    scenes.uniform_world(0.3)
    before = scenes.render_exr()
    for m in mats.values():
        api.add_export_fallback(m)
    after = scenes.render_exr()
    assert float(before[..., :3].max()) > 0.01  # something was rendered
    assert np.array_equal(before, after), float(np.abs(before - after).max())


def test_recomposite_mode_takes_the_fallback_out(api, ix, fallback, hg):
    composite = importlib.import_module(hg.__name__ + ".blender.model.recomposite")
    m = api.create_material("m", **CONDUCTOR)
    api.add_export_fallback(m)
    notes = composite.convert_material(m)
    assert not fallback.has_export_fallback(m)
    assert any("export fallback was removed" in n for n in notes)
    with pytest.raises(ValueError, match="recomposite"):
        api.add_export_fallback(m)
    composite.restore_material(m)


def _json_tail(text):
    """The JSON the CLI printed (Blender prints "Read blend: ..." before it)."""
    return json.loads(text[text.index("\n{") + 1:] if not text.startswith("{") else text)


def test_cli_exports_a_blend_and_reports_engines(api, hg, tmp_path, capsys):
    cli = importlib.import_module(hg.__name__ + ".__main__")
    _cubes(_make(api))  # used materials: a saved file drops ones without users
    blend = str(tmp_path / "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    out = str(tmp_path / "cli.mtlx")
    assert cli.main(["export-materialx", blend, out, "--json"]) == 0
    rep = _json_tail(capsys.readouterr().out)
    assert rep["validated"] is True and len(rep["materials"]) == len(MATERIALS)
    assert _validate(out)[1][0]
    assert cli.main(["export-materialx", blend, str(tmp_path / "cli.usda"), "--usd"]) == 0
    assert Usd.Stage.Open(str(tmp_path / "cli.usda")) is not None
    capsys.readouterr()
    assert cli.main(["engines", blend, "--json"]) == 0
    fits = _json_tail(capsys.readouterr().out)
    assert set(fits) == set(MATERIALS)
    assert all(set(f) == {"unity_stacklit", "ue_substrate", "filament", "openpbr_1_2"}
               for f in fits.values())


def test_fallback_of_in_shader_materials(api, tmp_path):
    """In-shader mapping (one group node holding the lobes): the exporters still get the core."""
    mats = {"varnish": api.create_material("varnish", shader_mapping=True, **DIELECTRIC),
            "brushed": api.create_material("brushed", shader_mapping=True, **ANISO)}
    _cubes(mats)
    for m in mats.values():
        api.add_export_fallback(m)
    glb = str(tmp_path / "g.glb")
    usda = str(tmp_path / "g.usda")
    bpy.ops.export_scene.gltf(filepath=glb, export_format="GLB")
    bpy.ops.wm.usd_export(filepath=usda, generate_preview_surface=True)
    gl, us = _gltf(glb), _usd_previews(usda)
    for name, p in (("varnish", DIELECTRIC), ("brushed", ANISO)):
        metallic, colour, rough = _core_look(p)
        pbr = gl[name].pbrMetallicRoughness
        assert pbr.roughnessFactor == pytest.approx(rough, abs=1e-6), name
        assert np.allclose(pbr.baseColorFactor[:3], colour, atol=1e-6), name
        assert us[name]["roughness"] == pytest.approx(rough, abs=1e-6), name
        assert np.allclose(us[name]["diffuseColor"], colour, atol=1e-6), name


def test_operator_adds_the_fallback_to_every_hazy_material(api, ix, fallback):
    mats = _make(api)
    bpy.data.materials.new("plain")  # not hazy: left alone
    assert bpy.ops.hazy_gloss.add_export_fallback(all_materials=True) == {"FINISHED"}
    assert all(fallback.has_export_fallback(m) for m in mats.values())
    assert not fallback.has_export_fallback(bpy.data.materials["plain"])
    assert bpy.ops.hazy_gloss.remove_export_fallback(material="copper") == {"FINISHED"}
    assert not fallback.has_export_fallback(mats["copper"])


def test_export_takes_one_material_and_a_path_object(api, tmp_path):
    m = api.create_material("one", **CONDUCTOR)
    rep = api.export_materialx(m, tmp_path / "one.mtlx")
    assert rep.validated and [x[0] for x in rep.materials] == ["one"]
    with pytest.raises(ValueError, match="not a hazy material"):
        api.export_materialx(bpy.data.materials.new("plain"), tmp_path / "none.mtlx")
