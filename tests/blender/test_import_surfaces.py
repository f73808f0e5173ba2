# SPDX-License-Identifier: GPL-3.0-or-later
"""MaterialX import inside Blender: library surfaces become Principled BSDF materials with their
textures (tests/pure/mtlx_fixtures, documents in the shapes public libraries write), OpenPBR
1.2's haze becomes a haze layer that renders OpenPBR's blend, and layered materials exported
by the add-on come back as the same layered material — checked by rendering (Cycles, delta
sun, orthographic camera, flat planes: tests/blender/scenes.py).

References are built here by hand from the documents' values (a Mix Shader of two Principled
BSDFs for OpenPBR's haze blend) or are the original materials; none comes from the importer."""
import importlib
import math
import os
import re
from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes

FIXTURES = Path(__file__).resolve().parents[1] / "pure" / "mtlx_fixtures"


@pytest.fixture
def api(hg, clean_file):
    return importlib.import_module(hg.__name__ + ".api")


def _principled(mat):
    return next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"
                and not n.name.startswith("HG "))


def _source(sock):
    return sock.links[0].from_node if sock.is_linked else None


def _value(sock):
    v = sock.default_value
    return tuple(v)[:3] if hasattr(v, "__len__") else float(v)


# --------------------------------------------------------------------------------------------
# Library surfaces as Principled materials
# --------------------------------------------------------------------------------------------


def test_fixtures_become_principled_materials_with_their_textures(api):
    res = api.import_materialx(FIXTURES / "standard_surface_textured_138.mtlx")
    mats = {im.name: im.material for im in res.report}
    assert set(mats) == {"Worn_Copper", "Polished_Gold", "Satin"} and all(mats.values())
    cu = _principled(mats["Worn_Copper"])
    assert cu.distribution == "GGX"  # standard_surface: single-scattering GGX
    tex = _source(cu.inputs["Base Color"])
    assert tex.bl_idname == "ShaderNodeTexImage"
    assert Path(bpy.path.abspath(tex.image.filepath)) == FIXTURES / "textures" / "worn_copper_basecolor.png"
    assert tex.image.colorspace_settings.name == "sRGB"
    mapping = _source(tex.inputs["Vector"])
    assert mapping.bl_idname == "ShaderNodeMapping" and tuple(mapping.inputs["Scale"].default_value) == (2, 3, 1)
    rough = _source(cu.inputs["Roughness"])  # multiply(roughness image, 0.8)
    assert rough.bl_idname == "ShaderNodeMath" and rough.operation == "MULTIPLY_ADD"
    assert rough.inputs[1].default_value == pytest.approx(0.8)
    img = _source(_source(rough.inputs[0]).inputs[0])
    assert img.image.colorspace_settings.name == "Non-Color"
    assert _source(cu.inputs["Normal"]).bl_idname == "ShaderNodeNormalMap"
    gold = _principled(mats["Polished_Gold"])
    assert _value(gold.inputs["Base Color"]) == pytest.approx((0.944, 0.776, 0.373), abs=1e-6)
    assert gold.inputs["Metallic"].default_value == 1.0
    satin = _principled(mats["Satin"])
    assert satin.inputs["Anisotropic"].default_value == pytest.approx(0.5 / 0.9, abs=1e-6)
    assert _source(satin.inputs["Tangent"]).bl_idname == "ShaderNodeTangent"
    assert mats["Satin"]["hazy_gloss_import"]["exact"] == 0  # the sheen is approximate: said


def test_several_surface_types_and_damaged_inputs_in_one_file(api):
    res = api.import_materialx(FIXTURES / "mixed_library_damaged.mtlx")
    made = {im.name: im for im in res.report if im.material is not None}
    assert set(made) == {"Orange_Peel", "Basalt", "Chrome", "Clay"}
    assert len(res) == 4 and "Legacy_Disney" in {im.name for im in res.report}
    assert _principled(made["Orange_Peel"].material).inputs["Roughness"].default_value == pytest.approx(0.1)
    assert _principled(made["Orange_Peel"].material).distribution == "MULTI_GGX"  # OpenPBR
    assert "read as 0.1" in made["Orange_Peel"].material["hazy_gloss_import"]["notes"]
    assert _principled(made["Clay"].material).distribution == "GGX"  # UsdPreviewSurface


def test_operator_imports_and_reports(api, hg):
    bpy.ops.hazy_gloss.import_materialx(filepath=str(FIXTURES / "gltf_orm_138.mtlx"))
    assert {"Radio", "Leaf_Cutout", "Hairline_Aluminium"} <= {m.name for m in bpy.data.materials}
    radio = _principled(bpy.data.materials["Radio"])
    sep = _source(radio.inputs["Metallic"])
    assert sep.bl_idname == "ShaderNodeSeparateXYZ" and radio.inputs["Metallic"].links[0].from_socket.name == "Z"
    assert radio.inputs["Emission Strength"].default_value == 2.0


# --------------------------------------------------------------------------------------------
# Rendering: what the imported materials draw
# --------------------------------------------------------------------------------------------

VIEWS = (((25.0, 0.0), (0.0, 0.0)), ((40.0, 0.0), (40.0, 180.0)), ((60.0, 90.0), (10.0, 0.0)))


def _renders(mats):
    """Per material: the peak (normal incidence, grid) and three off-peak pixels."""
    scenes.setup_render("CYCLES", samples=1, resolution=(4, 4), bounces=0)
    info = scenes.plane_grid_scene(mats)
    img = scenes.render_exr()[..., :3].astype(np.float64)
    peaks = {}
    for (r, c), i in np.ndenumerate(info["index"]):
        if i >= 0:
            peaks[i] = img[r, c]
    out = []
    for i, m in enumerate(mats):
        row = [peaks[i]]
        for light, view in VIEWS:
            px = scenes.render_plane(m, light_dir=light, view_dir=view, resolution=(4, 4))
            row.append(px[2, 2])
        out.append(np.array(row))
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    return out


def _reference_blend(name, base, metallic, tint, ior, r_core, r_haze, beta):
    """OpenPBR 1.2's plain blend built by hand: a Mix Shader (β) of two Multiscatter GGX
    Principled BSDFs with the document's values, at the core and the haze roughness."""
    mat = scenes.new_material(name)
    t = mat.node_tree
    for n in list(t.nodes):
        t.nodes.remove(n)
    out = t.nodes.new("ShaderNodeOutputMaterial")
    mix = t.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = beta
    for slot, r in ((1, r_core), (2, r_haze)):
        p = t.nodes.new("ShaderNodeBsdfPrincipled")
        p.distribution = "MULTI_GGX"
        p.inputs["Base Color"].default_value = tuple(base) + (1.0,)
        p.inputs["Metallic"].default_value = metallic
        p.inputs["Specular Tint"].default_value = tuple(tint) + (1.0,)
        p.inputs["IOR"].default_value = ior
        p.inputs["Roughness"].default_value = r
        t.links.new(p.outputs[0], mix.inputs[slot])
    t.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def test_openpbr_haze_renders_openpbr_s_blend(api):
    """The imported Principled with its haze layer draws OpenPBR 1.2's (1-w) f_core + w f_haze
    (F(0) of the document, r_haze = lerp(r, 1, spread)) to 1e-5 of the peak."""
    res = api.import_materialx(FIXTURES / "openpbr_12_haze.mtlx")
    got = {im.name: im.material for im in res.report}
    assert api.is_hazy(got["Hazy_Plastic"]) and api.is_hazy(got["Hazy_Brass"])
    assert not api.is_hazy(got["No_Haze"])
    refs = [_reference_blend("ref plastic", (0.08, 0.1, 0.12), 0.0, (1, 1, 1), 1.5, 0.15,
                             0.15 + 0.85 * 0.3, 0.35),
            _reference_blend("ref brass", (0.9, 0.7, 0.35), 1.0, (0.98, 0.95, 0.88), 1.5, 0.2,
                             0.2 + 0.8 * 0.25, 0.5)]
    mats = [got["Hazy_Plastic"], got["Hazy_Brass"]] + refs
    px = _renders(mats)
    for a, b in ((0, 2), (1, 3)):
        peak = float(np.max(px[b][0]))
        assert peak > 0
        assert np.max(np.abs(px[a] - px[b])) <= 1e-5 * peak, (mats[a].name, px[a], px[b])


def _textured_image(tmp_path):
    img = bpy.data.images.new("hg_import_tex", 4, 4, float_buffer=True)
    px = np.tile(np.array([[0.2, 0.5, 0.8, 1.0]], np.float32), (16, 1))
    px[::3] = (0.7, 0.3, 0.1, 1.0)
    img.pixels.foreach_set(px.ravel())
    img.filepath_raw = str(tmp_path / "hg_import_tex.png")
    img.file_format = "PNG"
    img.save()
    return bpy.data.images.load(str(tmp_path / "hg_import_tex.png"))


def _bsdf_material(name, bl_idname, **values):
    mat = scenes.new_material(name)
    t = mat.node_tree
    for n in list(t.nodes):
        t.nodes.remove(n)
    out = t.nodes.new("ShaderNodeOutputMaterial")
    b = t.nodes.new(bl_idname)
    for k, v in values.items():
        if k in ("distribution", "fresnel_type"):
            setattr(b, k, v)
        elif k == "tangent":
            tn = t.nodes.new("ShaderNodeTangent")
            tn.direction_type = "UV_MAP"
            t.links.new(tn.outputs[0], b.inputs["Tangent"])
        elif k == "image":
            tx = t.nodes.new("ShaderNodeTexImage")
            tx.image = v
            t.links.new(tx.outputs["Color"], b.inputs["Base Color"])
        else:
            s = b.inputs[k]
            s.default_value = tuple(v) + (1.0,) * (len(s.default_value) - len(v)) if isinstance(v, tuple) else v
    t.links.new(b.outputs[0], out.inputs["Surface"])
    return mat


def test_layered_exports_import_back_as_the_same_layer(api, tmp_path):
    """Make Hazy on Principled (dielectric GGX, metal Multiscatter GGX anisotropic, a coat with
    its own haze, a textured base colour), Metallic and Glossy cores; export; import: the same
    haze parameters and the same renders (peak and three off-peak views) to 1e-5 of the peak."""
    P, M_, G = "ShaderNodeBsdfPrincipled", "ShaderNodeBsdfMetallic", "ShaderNodeBsdfGlossy"
    img = _textured_image(tmp_path)
    cases = [
        ("plastic", P, dict(distribution="GGX", Roughness=0.25, IOR=1.45, **{"Base Color": (0.3, 0.1, 0.05)}),
         dict(haziness=0.5, haze_extent=4.0)),
        ("brushed", P, dict(distribution="MULTI_GGX", Metallic=1.0, Roughness=0.3, Anisotropic=0.4, tangent=True,
                            **{"Base Color": (0.9, 0.6, 0.3), "Specular Tint": (0.95, 0.9, 0.85),
                               "Anisotropic Rotation": 0.1}),
         dict(haziness=0.6, haze_extent=(3.0, 5.0))),
        ("car paint", P, dict(Roughness=0.4, **{"Base Color": (0.2, 0.3, 0.6), "Coat Weight": 1.0,
                                                "Coat Roughness": 0.05, "Coat IOR": 1.5}),
         dict(haziness=0.2, coat_haziness=0.5, coat_haze_extent=6.0)),
        ("printed", P, dict(Roughness=0.35, image=img), dict(haziness=0.4, haze_extent=5.0)),
        ("f82 metal", M_, dict(distribution="GGX", fresnel_type="F82", Roughness=0.2,
                               **{"Base Color": (0.95, 0.64, 0.54), "Edge Tint": (0.99, 0.9, 0.8)}),
         dict(haziness=0.7, haze_extent=3.0)),
        ("glossy", G, dict(distribution="GGX", Roughness=0.2, Color=(0.5, 0.5, 0.5)),
         dict(haziness=0.4, haze_extent=4.0)),
    ]
    originals = []
    for name, kind, values, haze in cases:
        m = _bsdf_material(name, kind, **values)
        api.make_hazy(m, **haze)
        originals.append(m)
    before = {m.name: api.read_parameters(m) for m in originals}
    rep = api.export_materialx(originals, str(tmp_path / "layers.mtlx"))
    assert rep.validated is True, rep.validation
    for m in originals:
        m.name = "orig " + m.name
    res = api.import_materialx(str(tmp_path / "layers.mtlx"))
    got = {im.name: im for im in res.report}
    assert set(got) == {c[0] for c in cases}
    imported = []
    for (name, kind, values, haze), orig in zip(cases, originals):
        im = got[name]
        assert im.source == "hazy_gloss layer" and im.exact, (name, im.notes)
        new, old = api.read_parameters(im.material), before[name]
        for k in ("haziness", "haze_extent", "coat_haziness", "coat_haze_extent", "distribution",
                  "core_reflectivity", "roughness", "anisotropy"):
            if k in old:
                assert np.allclose(np.asarray(new[k], float), np.asarray(old[k], float), rtol=1e-6, atol=1e-7) \
                    if not isinstance(old[k], str) else new[k] == old[k], (name, k, old[k], new[k])
        imported.append(im.material)
    px = _renders(originals + imported)
    n = len(originals)
    for i in range(n):
        peak = float(np.max(px[i][0]))
        assert peak > 0
        err = float(np.max(np.abs(px[i] - px[n + i])))
        assert err <= 1e-5 * peak, (cases[i][0], err / peak, px[i], px[n + i])


def test_older_layer_documents_are_said_not_misread(api, tmp_path):
    text = ('<?xml version="1.0"?><materialx version="1.39"><nodegraph name="NG_x">'
            '<open_pbr_surface name="Core" type="surfaceshader" />'
            '<output name="out" type="surfaceshader" nodename="Core" /></nodegraph>'
            '<surfacematerial name="x" type="material" hazygloss_flavour="layer" '
            'hazygloss_layer="{}"><input name="surfaceshader" type="surfaceshader" '
            'nodegraph="NG_x" output="out" /></surfacematerial></materialx>')
    (tmp_path / "old.mtlx").write_text(text)
    res = api.import_materialx(tmp_path / "old.mtlx")
    assert len(res) == 0 and "does not name its core" in res.report[0].notes[0]


def test_udim_textures_become_tiled_images(api, tmp_path):
    for tile, colour in ((1001, (0.9, 0.1, 0.1, 1.0)), (1002, (0.1, 0.1, 0.9, 1.0))):
        img = bpy.data.images.new(f"t{tile}", 2, 2)
        img.pixels.foreach_set(np.tile(np.array(colour, np.float32), 4))
        img.filepath_raw = str(tmp_path / f"paint.{tile}.png")
        img.file_format = "PNG"
        img.save()
        bpy.data.images.remove(img)
    (tmp_path / "u.mtlx").write_text(
        '<?xml version="1.0"?><materialx version="1.39"><image name="paint" type="color3">'
        '<input name="file" type="filename" value="paint.&lt;UDIM&gt;.png" colorspace="srgb_texture" />'
        '</image><standard_surface name="s" type="surfaceshader"><input name="base_color" '
        'type="color3" nodename="paint" /></standard_surface><surfacematerial name="Tiled" '
        'type="material"><input name="surfaceshader" type="surfaceshader" nodename="s" />'
        '</surfacematerial></materialx>')
    (m,) = api.import_materialx(tmp_path / "u.mtlx")
    img = _source(_principled(m).inputs["Base Color"]).image
    assert img.source == "TILED" and "<UDIM>" in img.filepath
    assert sorted(t.number for t in img.tiles) == [1001, 1002]


def _save_png(path, colour, size=8):
    img = bpy.data.images.new("hg_png", size, size)
    img.pixels.foreach_set(np.tile(np.array(colour, np.float32), size * size))
    img.filepath_raw = str(path)
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)


def test_damaged_texture_files_get_a_placeholder_and_a_note(api, tmp_path):
    """A texture cut off by a failed copy, a web page saved as .png, a UDIM set with one cut-off
    tile: each is refused by the image check before Blender's loader sees it (Blender loads a
    cut-off PNG as 0x0 and a cut-off EXR crashed 5.0.1), and is handled like a missing file:
    an Image that points at the path without loading it, and a note naming the defect; the
    good tile of the set is loaded."""
    _save_png(tmp_path / "good.png", (0.2, 0.5, 0.8, 1.0), size=64)
    data = (tmp_path / "good.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[:len(data) // 2])
    (tmp_path / "page.png").write_text("<html><body>404 Not Found</body></html>")
    _save_png(tmp_path / "paint.1001.png", (0.9, 0.1, 0.1, 1.0))
    tile = data[:len(data) - 20]  # IEND and the end of the image data lost
    (tmp_path / "paint.1002.png").write_bytes(tile)
    cases = {"Cut": ("cut.png", r"texture not loaded: .*cut\.png is a damaged PNG file \(cut "
                                r"off or corrupt: .*\): the Image Texture points at it"),
             "Page": ("page.png", r"texture not loaded: .*page\.png is not an image file "
                                  r"Blender reads"),
             "Tiles": ("paint.&lt;UDIM&gt;.png", r"tile 1002 not loaded: .*paint\.1002\.png is "
                                                 r"a damaged PNG file")}
    for name, (file, pattern) in cases.items():
        doc = tmp_path / f"{name}.mtlx"
        doc.write_text(
            '<?xml version="1.0"?><materialx version="1.39"><image name="paint" type="color3">'
            f'<input name="file" type="filename" value="{file}" colorspace="srgb_texture" />'
            '</image><standard_surface name="s" type="surfaceshader"><input name="base_color" '
            'type="color3" nodename="paint" /></standard_surface><surfacematerial '
            f'name="{name}" type="material"><input name="surfaceshader" type="surfaceshader" '
            'nodename="s" /></surfacematerial></materialx>')
        res = api.import_materialx(doc)
        (m,) = res
        notes = res.report[0].notes
        assert any(re.search(pattern, n) for n in notes), (name, notes)
        img = _source(_principled(m).inputs["Base Color"]).image
        if name == "Tiles":
            assert img.source == "TILED" and [t.number for t in img.tiles] == [1001]
        else:  # made by images.new(name, 1, 1), not images.load: 1 where load leaves 1024
            assert img.source == "FILE" and img.generated_width == 1, name
            assert Path(bpy.path.abspath(img.filepath)) == tmp_path / file


def test_layer_texture_maps_come_back_with_their_values(api, hg, tmp_path):
    """A metallic map (a colour EXR, Non-Color) and a colour texture into Roughness (sRGB PNG)
    of a hazy Principled: the export converts each colour to a float by a dotproduct with the
    luminance weights; imported into a fresh file, the same images feed Metallic and Roughness
    and Cycles reads the same values there as from the original links, per pixel; the metallic
    values are Rec.709 luminances of the texels (Blender's Color -> Float link)."""
    rng = np.random.default_rng(7)
    size = 32
    texels = rng.uniform(0.0, 1.0, (size, size, 3))
    texels[..., 1] *= 0.3  # channels unlike each other: the luminance is not their mean
    metal = bpy.data.images.new("hg_metal", size, size, float_buffer=True, is_data=True)
    metal.pixels.foreach_set(np.concatenate([texels, np.ones((size, size, 1))], -1)
                             .astype(np.float32).ravel())
    metal.filepath_raw, metal.file_format = str(tmp_path / "metal.exr"), "OPEN_EXR"
    metal.save()
    rough = bpy.data.images.new("hg_rough", size, size)
    rough.pixels.foreach_set(np.concatenate([texels[::-1, :, ::-1], np.ones((size, size, 1))], -1)
                             .astype(np.float32).ravel())
    rough.filepath_raw, rough.file_format = str(tmp_path / "rough.png"), "PNG"
    rough.save()
    mat = _bsdf_material("mapped", "ShaderNodeBsdfPrincipled", **{"Base Color": (0.9, 0.6, 0.3)})
    tree = mat.node_tree
    b = _principled(mat)
    texs = {}
    for key, img in (("Metallic", metal), ("Roughness", rough)):
        t = texs[key] = tree.nodes.new("ShaderNodeTexImage")
        t.image, t.interpolation = img, "Closest"
        tree.links.new(t.outputs["Color"], b.inputs[key])
    api.make_hazy(mat, haziness=0.5, haze_extent=4.0)
    rep = api.export_materialx(mat, str(tmp_path / "mapped.mtlx"))
    assert rep.validated is True, rep.validation
    res = 16  # the camera sees uv 0.375-0.625: texels 12-19, 2 x 2 pixels each
    scenes.setup_render("CYCLES", samples=1, resolution=(res, res), bounces=0)
    scenes.flat_plane_scene(mat)
    read_exr = importlib.import_module(hg.__name__ + ".conversion.imagecheck").read_exr
    want = scenes.render_aovs(read_exr, tree, {k: t.outputs["Color"] for k, t in texs.items()})

    bpy.ops.wm.read_homefile(use_empty=True)
    out = api.import_materialx(str(tmp_path / "mapped.mtlx"))
    (im,) = out.report
    assert im.exact, im.notes
    new = _principled(im.material)
    files = {"Metallic": "metal.exr", "Roughness": "rough.png"}
    for key, file in files.items():
        sock = new.inputs[key]
        assert sock.is_linked, (key, im.notes)
        stack, found = [sock.links[0].from_node], []
        while stack:  # the Image Texture upstream of the input
            n = stack.pop()
            if n.bl_idname == "ShaderNodeTexImage":
                found.append(Path(bpy.path.abspath(n.image.filepath)).resolve())
            stack += [lk.from_node for s in n.inputs for lk in s.links]
        assert found == [(tmp_path / file).resolve()], (key, found)
    scenes.setup_render("CYCLES", samples=1, resolution=(res, res), bounces=0)
    scenes.flat_plane_scene(im.material)
    probes = {k: new.inputs[k].links[0].from_socket for k in files}
    for i in range(3):  # Blender's luminance weights (from its colour config: ≈ Rec.709's)
        rgb = im.material.node_tree.nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = tuple(float(i == j) for j in range(3)) + (1.0,)
        probes[f"w{i}"] = rgb.outputs[0]
    got = scenes.render_aovs(read_exr, im.material.node_tree, probes)
    for key in files:
        assert np.max(np.abs(got[key] - want[key])) <= 1e-6, (key, got[key], want[key])
    weights = np.array([got[f"w{i}"][0, 0] for i in range(3)])
    assert np.allclose(weights, (0.2126, 0.7152, 0.0722), atol=1e-4), weights
    idx = 12 + np.arange(res) // 2  # (row 0: the bottom, in the image and in the render)
    luma = texels[idx][:, idx] @ weights
    assert np.max(np.abs(got["Metallic"] - luma)) <= 1e-6
    assert np.max(np.abs(got["Metallic"] - texels[idx][:, idx].mean(-1))) > 1e-2  # (not the mean)
