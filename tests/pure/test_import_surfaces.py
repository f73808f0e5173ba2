# SPDX-License-Identifier: GPL-3.0-or-later
"""The MaterialX importer on documents written the way material libraries write them
(tests/pure/mtlx_fixtures, generated libraries): OpenPBR 1.1 / 1.2, standard_surface, gltf_pbr
and UsdPreviewSurface surfaces as Principled BSDF specs, textures as nodes, damaged inputs read
as MaterialX 1.39.5 reads them, OpenPBR 1.2 haze as haze-layer parameters, progress.

Expected values come from the installed ``materialx`` package (what it parses, the nodedefs'
defaults, its own open_pbr_surface / standard_surface / gltf_pbr node graphs evaluated by
tests/pure/mx_eval.py), from Cycles' conventions written out here (α_x = R²/s, α_y = R² s,
s = √(1 - 0.9 A); a dielectric's F(0) = 2 · level · F0(IOR) · tint), and from the papers'
formulas (the layer keeps the peak: r_c = r [(1-β) + β p]) — not from the importer."""
import math
import random
from pathlib import Path

import MaterialX as mx
import numpy as np
import pytest

import mtlx_library
import mx_eval
import reference
from hazy_gloss import constants as K
from hazy_gloss.core.lobes import describe
from hazy_gloss.interchange import haze_blend
from hazy_gloss.interchange import materialx as M
from hazy_gloss.interchange import materialx_import as MI
from hazy_gloss.interchange.document import read_value
from hazy_gloss.interchange.surfaces import Link
from test_interchange import _load as _mx_doc

FIXTURES = Path(__file__).resolve().parent / "mtlx_fixtures"


@pytest.fixture(scope="module")
def lib():
    doc = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), doc)
    return doc


def _read(name):
    return {im.name: im for im in M.read(FIXTURES / name)}


def cycles_alpha(R, A):
    """Cycles' Principled / Metallic α (docs/blender-versions.md): s = √(1-0.9A), α_x = R²/s, α_y = R² s,
    each at most 1."""
    s = math.sqrt(1.0 - 0.9 * min(max(A, 0.0), 1.0))
    r2 = min(max(R, 0.0), 1.0) ** 2
    return min(r2 / s, 1.0), min(r2 * s, 1.0)


def f0_of(ior):
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def _walk(spec, value):
    """The TexNode a socket value links from (None for a constant)."""
    return spec.nodes[value.node] if isinstance(value, Link) else None


# --------------------------------------------------------------------------------------------
# Values: as MaterialX 1.39.5 reads them
# --------------------------------------------------------------------------------------------


def test_values_read_as_materialx_reads_them():
    """Random strings of number-like characters through MaterialX's own parser (an input's
    getValue()) and ours: the same value (float32 compared) or both refused."""
    rng = random.Random(7)
    alphabet = "0123456789..eE+-, \tnaif"
    doc = mx.createDocument()
    node = doc.addNode("open_pbr_surface", "s", "surfaceshader")
    fixed = ["0.1, 0.05, 0.025", "0.25abc", "nan", "inf", "1e39", "3.4028235e38", "1e-50", "1e",
             " 0.3", "1,2 3", "1,,3", "1 2 3 4", "-0", ".5", "+.5", "0x10", "true", ""]
    mismatches = []
    for typ in ("float", "color3", "vector2", "integer"):
        strings = fixed + ["".join(rng.choice(alphabet) for _ in range(rng.randrange(12)))
                           for _ in range(2500)]
        for k, text in enumerate(strings):
            inp = node.addInput(f"x{k}", typ)
            inp.setValueString(text)
            theirs = inp.getValue()
            node.removeInput(f"x{k}")
            ours, problem = read_value(text, typ)
            if theirs is None or ours is None:
                same = theirs is None and ours is None
            elif typ == "integer":
                same = ours == theirs
            else:
                same = np.array_equal(np.float32(ours), np.float32(tuple(theirs) if typ != "float" else theirs))
            if not same:
                mismatches.append((typ, text, theirs, ours))
            if ours is not None and problem is None:
                assert text.strip(" ,") != "" or typ == "float"
    assert not mismatches, mismatches[:10]
    assert read_value("0.1, 0.05, 0.025", "float")[0] == 0.1  # MaterialX reads 0.1
    for typ in ("boolean",):
        for text, want in (("true", True), ("false", False), ("True", None), ("1", None), (" true", None)):
            assert read_value(text, typ)[0] == want


# --------------------------------------------------------------------------------------------
# The fixtures: valid MaterialX (or invalid exactly where they are damaged), all read
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(p.name for p in FIXTURES.glob("*.mtlx")))
def test_fixtures_are_materialx_documents(name, lib):
    doc = _mx_doc(FIXTURES / name, lib)
    ok, msg = doc.validate()
    if name == "mixed_library_damaged.mtlx":  # the damage, and nothing else
        assert not ok
        lines = [line for line in msg.splitlines() if line.strip()]
        assert len(lines) == 3 and all(("rough" in x or "shininess" in x or "0.55, 0.56" in x) for x in lines), msg
    elif name == "openpbr_12_haze.mtlx":  # 1.2 is not in MaterialX 1.39: only the version fails
        assert all("version" in x or "output type" in x for x in msg.splitlines() if x.strip()), msg
    else:
        assert ok, msg
    assert len(doc.getMaterialNodes()) >= 1


@pytest.mark.parametrize("name", sorted(p.name for p in FIXTURES.glob("*.mtlx")))
def test_every_material_of_every_fixture_is_read(name):
    mats = M.read(FIXTURES / name)
    theirs = _mx_doc(FIXTURES / name).getMaterialNodes()
    assert sorted(im.name for im in mats) == sorted(m.getName() for m in theirs)
    for im in mats:
        if im.name == "Legacy_Disney":  # disney_principled: said, not read
            assert not im.ok and "disney_principled" in im.notes[0]
            continue
        assert im.ok and im.surface is not None, (im.name, im.notes)
        assert im.surface.bsdf == "ShaderNodeBsdfPrincipled"


# --------------------------------------------------------------------------------------------
# Mappings against MaterialX's own surface graphs
# --------------------------------------------------------------------------------------------


def _library_doc(kind, rows):
    """A document of one ``kind`` shader per row ({input: value})."""
    lines = ['<?xml version="1.0"?>', '<materialx version="1.39">']
    for i, row in enumerate(rows):
        lines.append(f'<{kind} name="s{i}" type="surfaceshader">')
        for k, v in row.items():
            t = "color3" if isinstance(v, tuple) else "float"
            val = ", ".join(repr(float(x)) for x in v) if isinstance(v, tuple) else repr(float(v))
            lines.append(f'<input name="{k}" type="{t}" value="{val}" />')
        lines.append(f'</{kind}><surfacematerial name="m{i}" type="material">'
                     f'<input name="surfaceshader" type="surfaceshader" nodename="s{i}" /></surfacematerial>')
    lines.append("</materialx>")
    return "\n".join(lines)


def _graph_values(lib, graph_name, rows, outputs):
    cols = {k: np.array([r[k] for r in rows], dtype=np.float64) for k in rows[0]}
    ev = mx_eval.Evaluator(lib.getNodeGraph(graph_name), len(rows), interface=cols, library=lib)
    return [ev.value(o).astype(np.float64) for o in outputs]


def test_openpbr_roughness_and_ior_are_what_its_graph_renders(lib, tmp_path):
    """OpenPBR's α (coat roughening, then open_pbr_anisotropy) and its base IOR under a coat
    (eta_s), from MaterialX 1.39's own open_pbr_surface graph, against Cycles' α and IOR of the
    imported Principled."""
    rng = np.random.default_rng(3)
    rows = []
    for _ in range(300):
        coat = rng.uniform() < 0.5
        rows.append(dict(specular_roughness=rng.uniform(0.02, 1.0),
                         specular_roughness_anisotropy=rng.uniform(0.0, 0.9),
                         coat_weight=float(coat) if rng.uniform() < 0.7 else rng.uniform(),
                         coat_roughness=rng.uniform(0.0, 0.3), specular_ior=rng.uniform(1.1, 3.0),
                         coat_ior=rng.uniform(1.2, 2.0)))
    path = tmp_path / "opbr.mtlx"
    path.write_text(_library_doc("open_pbr_surface", rows))
    alpha, eta = _graph_values(lib, "NG_open_pbr_surface_surfaceshader", rows, ("main_roughness", "eta_s"))
    got = {im.name: im.surface.inputs for im in M.read(path)}
    worst_a = worst_e = 0.0
    for i in range(len(rows)):
        ins = got[f"m{i}"]
        ax, ay = cycles_alpha(ins["Roughness"], ins["Anisotropic"])
        want = np.minimum(alpha[i], 1.0)  # the BSDFs clamp α at 1
        worst_a = max(worst_a, float(np.max(np.abs(np.array([ax, ay]) - want) / want)))
        worst_e = max(worst_e, abs(ins["IOR"] / eta[i] - 1.0))
    assert worst_a < 3e-6 and worst_e < 3e-6  # the graph runs in float32


def test_standard_surface_roughness_is_what_its_graph_renders(lib, tmp_path):
    """main_roughness of MaterialX's standard_surface graph (coat_affect_roughness, then
    roughness_anisotropy) against Cycles' α of the imported Principled; the tangent turn of
    specular_rotation (rotate3d by 360 · rotation, clockwise) as Cycles' rotation."""
    rng = np.random.default_rng(5)
    rows = [dict(specular_roughness=rng.uniform(0.05, 1.0), specular_anisotropy=rng.uniform(0.0, 0.9),
                 coat=rng.uniform(), coat_roughness=rng.uniform(0.0, 0.5),
                 coat_affect_roughness=rng.uniform()) for _ in range(300)]
    path = tmp_path / "std.mtlx"
    path.write_text(_library_doc("standard_surface", rows))
    (alpha,) = _graph_values(lib, "NG_standard_surface_surfaceshader_100", rows, ("main_roughness",))
    got = {im.name: im.surface.inputs for im in M.read(path)}
    err = max(float(np.max(np.abs(np.array(cycles_alpha(got[f"m{i}"]["Roughness"], got[f"m{i}"]["Anisotropic"]))
                                  - alpha[i]) / alpha[i])) for i in range(len(rows)))
    assert err < 3e-6
    (sat,) = [im for im in M.read(FIXTURES / "standard_surface_textured_138.mtlx") if im.name == "Satin"]
    assert sat.surface.inputs["Anisotropic Rotation"] == pytest.approx(-0.125)
    assert isinstance(sat.surface.inputs["Tangent"], Link)


def test_gltf_anisotropy_is_what_its_graph_renders(lib, tmp_path):
    """glTF's α_t = mix(α, 1, s²), α_b = α (MaterialX's gltf_pbr graph, roughness_uv) as
    Cycles' (α_x, α_y); the rotation (rotate3d by -degrees: counter-clockwise) in turns."""
    rng = np.random.default_rng(8)
    rows = [dict(roughness=rng.uniform(0.3, 1.0), anisotropy_strength=rng.uniform(0.0, 0.5),
                 anisotropy_rotation=rng.uniform(-3.0, 3.0)) for _ in range(300)]
    path = tmp_path / "gltf.mtlx"
    path.write_text(_library_doc("gltf_pbr", rows))
    (alpha,) = _graph_values(lib, "IMPL_gltf_pbr_surfaceshader", rows, ("roughness_uv",))
    got = {im.name: im.surface.inputs for im in M.read(path)}
    for i, row in enumerate(rows):
        ins = got[f"m{i}"]
        a = ins.get("Anisotropic", 0.0)
        ratio = alpha[i][1] / alpha[i][0]
        if ratio < 0.1:  # beyond Cycles' aspect 10: said
            continue
        assert np.allclose(cycles_alpha(ins["Roughness"], a), alpha[i], rtol=3e-6), i
        if a > 0:
            assert ins["Anisotropic Rotation"] == pytest.approx(row["anisotropy_rotation"] / (2 * math.pi))


def test_missing_inputs_take_the_nodedefs_defaults(lib, tmp_path):
    """An OpenPBR surface with no input is the nodedef's defaults (read from the installed
    library); standard_surface 1.0.0 has other defaults than 1.0.1 (base 0.8 / colour 1)."""
    nd = lib.getNodeDef("ND_open_pbr_surface_surfaceshader")
    d = {i.getName(): i.getValue() for i in nd.getActiveInputs() if i.getValueString()}
    ins = _read("openpbr_library.mtlx")["Defaults"].surface.inputs
    assert ins["Base Color"] == pytest.approx(tuple(np.multiply(tuple(d["base_color"]), d["base_weight"])))
    assert ins["Roughness"] == pytest.approx(d["specular_roughness"])  # isotropic: R = r
    assert ins["IOR"] == pytest.approx(d["specular_ior"])
    assert ins["Coat IOR"] == pytest.approx(d["coat_ior"])
    assert ins["Specular IOR Level"] == pytest.approx(0.5 * d["specular_weight"])
    assert ins["Subsurface Radius"] == pytest.approx(tuple(d["subsurface_radius_scale"]))
    assert ins["Alpha"] == pytest.approx(d["geometry_opacity"])
    text = ('<?xml version="1.0"?><materialx version="1.39">'
            '<standard_surface name="a" type="surfaceshader" version="1.0.0">'
            '<input name="base_color" type="color3" value="0.5, 0.5, 0.5" /></standard_surface>'
            '<standard_surface name="b" type="surfaceshader">'
            '<input name="base_color" type="color3" value="0.5, 0.5, 0.5" /></standard_surface>'
            '<surfacematerial name="old" type="material"><input name="surfaceshader" type="surfaceshader" nodename="a" /></surfacematerial>'
            '<surfacematerial name="new" type="material"><input name="surfaceshader" type="surfaceshader" nodename="b" /></surfacematerial>'
            '</materialx>')
    (tmp_path / "v.mtlx").write_text(text)
    got = {im.name: im.surface.inputs for im in M.read(tmp_path / "v.mtlx")}
    old = lib.getNodeDef("ND_standard_surface_surfaceshader_100").getActiveInput("base").getValue()
    new = lib.getNodeDef("ND_standard_surface_surfaceshader").getActiveInput("base").getValue()
    assert got["old"]["Base Color"] == pytest.approx((0.5 * old,) * 3)
    assert got["new"]["Base Color"] == pytest.approx((0.5 * new,) * 3)


def test_distribution_is_what_each_specification_means():
    """OpenPBR and glTF ask for multiple scattering (Multiscatter GGX); standard_surface's and
    UsdPreviewSurface's BRDFs are single-scattering GGX."""
    want = {"open_pbr_surface": "MULTI_GGX", "gltf_pbr": "MULTI_GGX", "standard_surface": "GGX",
            "UsdPreviewSurface": "GGX"}
    for im in M.read(FIXTURES / "mixed_library_damaged.mtlx"):
        if im.surface is not None:
            kind = im.surface.source.split(" ")[0]
            assert im.surface.props["distribution"] == want[kind], im.name


def test_metal_fresnel_is_the_conductor_at_82_degrees():
    """standard_surface's metal is Gulbrandsen's conductor (base colour r, edge colour g): the
    Principled's F82-tint Fresnel with the imported Specular Tint meets the exact conductor
    Fresnel at μ = 1 and μ̄ = 1/7 and stays within the noted error elsewhere."""
    gold = _read("standard_surface_textured_138.mtlx")["Polished_Gold"]
    ins = gold.surface.inputs
    r = np.array(ins["Base Color"])
    tint = np.array(ins["Specular Tint"])
    g = np.array([0.998, 0.981, 0.751])
    eta, kap = zip(*(reference.gulbrandsen(float(a), float(b)) for a, b in zip(r, g)))
    eta, kap = np.array(eta, float), np.array(kap, float)

    def conductor(mu):
        n = eta + 1j * kap
        s2 = 1.0 - mu * mu
        root = np.sqrt(n * n - s2)
        rs = np.abs((mu - root) / (mu + root)) ** 2
        rp = np.abs((n * n * mu - root) / (n * n * mu + root)) ** 2
        return 0.5 * (rs + rp)

    def f82(mu):  # Cycles' F82-tint (docs/blender-versions.md): b from F(μ̄) = tint · Schlick(μ̄)
        mb = 1.0 / 7.0
        sch = lambda m: r + (1 - r) * (1 - m) ** 5  # noqa: E731
        b = sch(mb) * (1 - tint) / (mb * (1 - mb) ** 6)
        return np.clip(sch(mu) - b * mu * (1 - mu) ** 6, 0, 1)

    assert f82(1.0) == pytest.approx(conductor(1.0), abs=1e-12)
    assert f82(1.0 / 7.0) == pytest.approx(conductor(1.0 / 7.0), abs=1e-9)
    err = max(float(np.max(np.abs(f82(m) - conductor(m)))) for m in np.linspace(0.01, 1, 200))
    noted = float([n for n in gold.notes if "max |ΔF|" in n][0].split("max |ΔF| ")[1].rstrip(")"))
    assert err <= noted + 2e-3 and err < 0.05


def test_usd_specular_workflow_keeps_f0_and_the_coat_ior():
    usd = _read("usd_preview_138.mtlx")
    ins = usd["Wood_Varnish"].surface.inputs
    f0 = 2.0 * ins["Specular IOR Level"] * f0_of(ins["IOR"]) * np.array(ins["Specular Tint"])
    assert f0 == pytest.approx([0.07, 0.06, 0.05], rel=1e-9)
    assert ins["Metallic"] == 0.0 and ins["Coat IOR"] == ins["IOR"] == 1.5
    fence = usd["Fence"].surface
    assert fence.inputs["Alpha"] == 1.0 and fence.alpha_clip == 0.5  # 0.8 >= the threshold


# --------------------------------------------------------------------------------------------
# Textures and node graphs
# --------------------------------------------------------------------------------------------


def test_image_nodes_become_image_textures_with_their_files():
    cu = _read("standard_surface_textured_138.mtlx")["Worn_Copper"].surface
    tex = _walk(cu, cu.inputs["Base Color"])
    assert tex.bl_idname == "ShaderNodeTexImage"
    assert tex.image["path"] == str(FIXTURES / "textures" / "worn_copper_basecolor.png")  # fileprefix
    assert tex.image["colorspace"] == "sRGB"
    mapping = _walk(cu, tex.inputs["Vector"])
    assert mapping.bl_idname == "ShaderNodeMapping" and mapping.inputs["Scale"] == (2.0, 3.0, 1.0)
    rough = _walk(cu, cu.inputs["Roughness"])  # multiply(image, 0.8)
    assert rough.bl_idname == "ShaderNodeMath" and rough.inputs["Value_001"] == 0.8
    sep = _walk(cu, rough.inputs["Value"])
    assert sep.bl_idname == "ShaderNodeSeparateXYZ" and rough.inputs["Value"].output == "X"
    assert _walk(cu, sep.inputs["Vector"]).image["colorspace"] == "Non-Color"
    assert _walk(cu, cu.inputs["Normal"]).bl_idname == "ShaderNodeNormalMap"


def test_channel_swizzles_read_one_channel_of_a_packed_map():
    radio = _read("gltf_orm_138.mtlx")["Radio"].surface
    for socket, channel in (("Metallic", "Z"), ("Roughness", "Y")):
        v = radio.inputs[socket]
        sep = _walk(radio, v)
        assert sep.bl_idname == "ShaderNodeSeparateXYZ" and v.output == channel
        img = _walk(radio, sep.inputs["Vector"])
        assert img.image["path"].endswith("radio/radio_occlusionRoughnessMetallic.png")
        assert img.image["colorspace"] == "Non-Color"
    assert radio.inputs["Emission Strength"] == 2.0
    assert _walk(radio, radio.inputs["Emission Color"]).image["colorspace"] == "sRGB"


def test_materialx_137_shaderrefs_are_read_as_138_has_them():
    tile = _read("standard_surface_137.mtlx")["Glazed_Tile"].surface
    scaled = _walk(tile, tile.inputs["Base Color"])  # base 0.9 × the texture
    assert scaled.bl_idname == "ShaderNodeVectorMath" and scaled.inputs["Vector_001"] == pytest.approx((0.9,) * 3)
    tex = _walk(tile, scaled.inputs["Vector"])
    assert tex.image["path"] == str(FIXTURES / "maps" / "tile_color.jpg")
    assert tex.image["colorspace"] == "sRGB"  # the node graph's colorspace
    assert tile.inputs["Coat Weight"] == 1.0 and tile.inputs["Coat Roughness"] == 0.02


def test_usd_normal_map_scale_and_bias_fold_into_the_normal_map():
    brick = _read("usd_preview_138.mtlx")["Brick"].surface
    nm = _walk(brick, brick.inputs["Normal"])
    assert nm.bl_idname == "ShaderNodeNormalMap"
    img = _walk(brick, nm.inputs["Color"])  # (tex · 2 - 1) · ½ + ½ = tex: no math node
    assert img.bl_idname == "ShaderNodeTexImage" and img.image["colorspace"] == "Non-Color"
    assert _walk(brick, img.inputs["Vector"]).bl_idname == "ShaderNodeUVMap"


# --------------------------------------------------------------------------------------------
# Damage
# --------------------------------------------------------------------------------------------


def test_one_damaged_input_does_not_lose_the_material_or_the_file(lib):
    """Each damaged input is read as MaterialX reads it (its getValue(), or the nodedef's default
    where MaterialX refuses it), said in the material's notes; every other material is read."""
    got = _read("mixed_library_damaged.mtlx")
    theirs = _mx_doc(FIXTURES / "mixed_library_damaged.mtlx")
    rough = theirs.getNode("SR_orange_peel").getInputValue("specular_roughness")
    assert np.float32(got["Orange_Peel"].surface.inputs["Roughness"]) == np.float32(rough)
    assert any("specular_roughness" in n and "read as 0.1" in n for n in got["Orange_Peel"].notes)
    assert theirs.getNode("SR_basalt").getInputValue("specular_roughness") is None
    dflt = lib.getNodeDef("ND_standard_surface_surfaceshader").getActiveInput("specular_roughness").getValue()
    assert got["Basalt"].surface.inputs["Roughness"] == pytest.approx(dflt)
    assert got["Basalt"].surface.inputs["IOR"] == pytest.approx(1.6)
    assert any("'rough'" in n for n in got["Basalt"].notes) and not got["Basalt"].exact
    dc = lib.getNodeDef("ND_gltf_pbr_surfaceshader").getActiveInput("base_color").getValue()
    assert got["Chrome"].surface.inputs["Base Color"] == pytest.approx(tuple(dc))
    assert any("shininess" in n for n in got["Chrome"].notes)
    assert got["Clay"].exact and got["Clay"].surface.inputs["Roughness"] == pytest.approx(0.9)


def test_a_float_list_in_a_generated_library_is_read_and_said(tmp_path):
    path = tmp_path / "lib.mtlx"
    n = mtlx_library.write_library(path, 400_000, seed=4)
    got = M.read(path)
    assert len(got) == n and all(im.ok for im in got)
    damaged = [im for im in got if any("as MaterialX reads it" in x for x in im.notes)]
    assert damaged, "the generator damages one material in two hundred"
    assert all(not im.exact for im in damaged)


# --------------------------------------------------------------------------------------------
# OpenPBR 1.2 haze as a haze layer
# --------------------------------------------------------------------------------------------


def _layer_renders(spec, target):
    """(β, F(0) of the narrow lobe) the haze layer renders with the imported parameters, by the
    paper's mapping as core.lobes.describe gives it (what blender/model/layer.py runs)."""
    ins, haze = spec.inputs, spec.haze
    lam = haze["haze_extent"] if isinstance(haze["haze_extent"], tuple) else (haze["haze_extent"],) * 2
    if ins["Metallic"] >= 0.5:
        rc = np.array(ins["Base Color"])
        ms = dict(lobe="F82_TINT", tint=tuple(ins["Specular Tint"]))
    else:
        rc = f0_of(ins["IOR"]) * 2 * ins["Specular IOR Level"] * np.array(ins["Specular Tint"])
        ms = None
    d = describe("DIELECTRIC", spec.props["distribution"], core_reflectivity=tuple(rc),
                 roughness=ins["Roughness"], anisotropy=ins["Anisotropic"], haziness=haze["haziness"],
                 haze_extent=lam, strict=False, multiscatter=ms)
    if ms is None:
        r = float(d.mapping.reflectivity_max) / float(np.max(d.mapping.core_reflectivity)) * rc
    else:
        r = np.array(d.mapping.reflectivity)
    return float(d.beta), r, float(d.wide.roughness)


@pytest.mark.parametrize("name, f0, beta, rough, spread", [
    ("Hazy_Plastic", (0.04, 0.04, 0.04), 0.35, 0.15, 0.3),
    ("Hazy_Brass", (0.9, 0.7, 0.35), 0.5, 0.2, 0.25)])
def test_openpbr_haze_becomes_a_layer_that_renders_the_same_blend(name, f0, beta, rough, spread):
    im = _read("openpbr_12_haze.mtlx")[name]
    spec = im.surface
    assert spec.haze is None and spec.haze_target["beta"] == beta  # solved when the material is made
    haze = MI.resolve_haze(spec)
    assert haze["haziness"] > 0
    got_beta, got_r, got_wide = _layer_renders(spec, spec.haze_target)
    assert got_beta == pytest.approx(beta, abs=1e-9)
    assert got_r == pytest.approx(f0, rel=1e-9)  # OpenPBR's F(0) (1.5 → 0.04; the metal's base colour)
    # OpenPBR: r_haze = lerp(r, 1, spread), α = r²; the layer's wide lobe: Eq. 8
    assert got_wide == pytest.approx(rough + (1 - rough) * spread, rel=1e-9)
    lam = haze["haze_extent"]
    assert lam == pytest.approx(((rough + (1 - rough) * spread) ** 2 - rough ** 2) / rough ** 2, rel=1e-9)
    assert spec.props["distribution"] == "MULTI_GGX"


def test_single_scatter_haze_keeps_the_papers_peak():
    """Under GGX the layer keeps the peak of the user's BSDF: r_c = F0 [(1-β) + β p] with
    p = α_n / α_w per axis (Barla et al. Eq. 3-5) — the closed form of the mapping's inverse."""
    for f0, beta, r, rw, a in (((0.04,) * 3, 0.3, 0.2, 0.44, 0.0), ((0.9, 0.6, 0.3), 0.6, 0.3, 0.6, 0.5),
                               ((0.5, 0.5, 0.5), 0.9, 0.1, 0.5, 0.0)):
        for part in ("DIELECTRIC", "METAL"):
            sol = haze_blend.solve(part, "GGX", f0, beta, r, a, rw)
            ax, ay = cycles_alpha(r, a)
            wx, wy = cycles_alpha(rw, a)
            p = (ax / wx) * (ay / wy)
            want = np.array(f0) * ((1 - beta) + beta * p)
            assert np.array(sol.core_reflectivity) == pytest.approx(want, rel=1e-9), (part, f0, beta)
            assert sol.error < 1e-12


def test_haze_beyond_the_mappings_bound_is_said(tmp_path):
    """specular_haze 1 (no core lobe left) needs β_h = 1, which the mapping excludes: the closest
    layer is made and the residual said."""
    text = ('<?xml version="1.0"?><materialx version="1.39">'
            '<open_pbr_surface name="s" type="surfaceshader" version="1.2">'
            '<input name="base_color" type="color3" value="0.99, 0.99, 0.99" />'
            '<input name="base_metalness" type="float" value="1" />'
            '<input name="specular_roughness" type="float" value="0.05" />'
            '<input name="specular_haze" type="float" value="1" />'
            '<input name="specular_haze_spread" type="float" value="1" /></open_pbr_surface>'
            '<surfacematerial name="m" type="material"><input name="surfaceshader" type="surfaceshader" nodename="s" />'
            '</surfacematerial></materialx>')
    (tmp_path / "h.mtlx").write_text(text)
    (im,) = M.read(tmp_path / "h.mtlx")
    MI.resolve_haze(im.surface)
    assert any("the mapping's bound" in n for n in im.surface.notes) and not im.surface.exact


# --------------------------------------------------------------------------------------------
# Progress
# --------------------------------------------------------------------------------------------


def test_progress_is_reported_and_never_goes_back(tmp_path):
    path = tmp_path / "lib.mtlx"
    mtlx_library.write_library(path, 3_000_000, seed=2)
    seen = []
    got = M.read(path, progress=lambda f, msg: seen.append((f, msg)))
    fr = [f for f, _ in seen]
    assert len(seen) >= 10 and fr == sorted(fr) and 0.0 <= fr[0] <= 0.5 and fr[-1] == 1.0
    assert {m for _, m in seen} == {"reading", "recognising materials"}
    assert len(got) > 3000


def test_cli_shows_progress_on_large_files_unless_quiet(tmp_path):
    import json
    import os
    import subprocess
    import sys
    root = Path(__file__).resolve().parents[2]
    path = tmp_path / "lib.mtlx"
    n = mtlx_library.write_library(path, 1_300_000, seed=3)
    env = dict(os.environ, PYTHONPATH=str(root))
    run = lambda *extra: subprocess.run(  # noqa: E731
        [sys.executable, "-m", "hazy_gloss", "import-materialx", str(path), *extra],
        capture_output=True, text=True, timeout=300, env=env, cwd=str(root))
    loud = run()
    assert loud.returncode == 0, loud.stderr
    steps = [line for line in loud.stderr.splitlines() if line.startswith("import-materialx:")]
    assert steps and steps[-1].startswith("import-materialx: 100%")
    assert len(loud.stdout.splitlines()) >= n  # one line per material (and its notes)
    quiet = run("--quiet", "--json")
    assert quiet.returncode == 0 and quiet.stderr == ""
    got = json.loads(quiet.stdout)
    assert len(got) == n and all(m["surface"]["bsdf"] == "ShaderNodeBsdfPrincipled" for m in got)
    small = subprocess.run([sys.executable, "-m", "hazy_gloss", "import-materialx",
                            str(FIXTURES / "openpbr_12_haze.mtlx"), "--json"],
                           capture_output=True, text=True, timeout=300, env=env, cwd=str(root))
    assert small.stderr == ""  # a small file: no bar
    haze = {m["name"]: m["surface"]["haze"] for m in json.loads(small.stdout)}
    assert haze["Hazy_Plastic"]["haziness"] > 0 and haze["No_Haze"] is None


def test_usd_preview_surface_networks_in_usd_files(tmp_path):
    """A USD material with only a UsdPreviewSurface network (what most USD pipelines write; no
    MaterialX network) is read like its MaterialX form."""
    from pxr import Sdf, Usd, UsdShade
    from hazy_gloss.interchange import usd
    T = Sdf.ValueTypeNames
    path = tmp_path / "preview.usda"
    stage = Usd.Stage.CreateNew(str(path))
    mat = UsdShade.Material.Define(stage, "/root/mtl/Painted_Metal")
    pv = UsdShade.Shader.Define(stage, "/root/mtl/Painted_Metal/PreviewSurface")
    pv.CreateIdAttr("UsdPreviewSurface")
    pv.CreateInput("metallic", T.Float).Set(1.0)
    pv.CreateInput("roughness", T.Float).Set(0.35)
    st = UsdShade.Shader.Define(stage, "/root/mtl/Painted_Metal/st")
    st.CreateIdAttr("UsdPrimvarReader_float2")
    st.CreateInput("varname", T.String).Set("st")
    tex = UsdShade.Shader.Define(stage, "/root/mtl/Painted_Metal/diffuse")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", T.Asset).Set("tex/paint.png")
    tex.CreateInput("sourceColorSpace", T.Token).Set("sRGB")
    tex.CreateInput("st", T.Float2).ConnectToSource(st.ConnectableAPI(), "result")
    pv.CreateInput("diffuseColor", T.Color3f).ConnectToSource(tex.ConnectableAPI(), "rgb")
    mat.CreateSurfaceOutput().ConnectToSource(pv.ConnectableAPI(), "surface")
    stage.GetRootLayer().Save()
    (im,) = usd.read(path)
    s = im.surface
    assert im.name == "Painted_Metal" and s.source == "UsdPreviewSurface"
    assert s.inputs["Metallic"] == 1.0 and s.inputs["Roughness"] == pytest.approx(0.35)
    img = _walk(s, s.inputs["Base Color"])
    assert img.image["path"] == str(tmp_path / "tex" / "paint.png") and img.image["colorspace"] == "sRGB"
    assert _walk(s, img.inputs["Vector"]).bl_idname == "ShaderNodeUVMap"


def test_the_blend_is_reached_across_materials():
    """OpenPBR 1.2's blend for grey and coloured metals and dielectrics, haze 0.1-0.95, spread
    0.1-1, core roughness 0.05-0.5, under Multiscatter GGX: the layer's forward mapping renders
    β and F(0) to 1e-9, or the blend is out of the layer's reach: a scan of the core's F(0) at
    the largest haziness (β grows with β_h) never renders its β with its F(0)."""
    rng = np.random.default_rng(21)
    reached = 0
    for _ in range(24):
        part = rng.choice(["DIELECTRIC", "METAL"])
        f0 = tuple(rng.uniform(0.02, 0.1, 3)) if part == "DIELECTRIC" else tuple(rng.uniform(0.3, 0.99, 3))
        if rng.uniform() < 0.3:
            f0 = (f0[0],) * 3  # grey: the channels tie
        beta, spread, r = rng.uniform(0.1, 0.95), rng.uniform(0.1, 1.0), rng.uniform(0.05, 0.5)
        rw = r + (1 - r) * spread
        sol = haze_blend.solve(str(part), "MULTI_GGX", f0, beta, r, 0.0, rw)
        b, got, _ = haze_blend.forward(str(part), "MULTI_GGX", sol.core_reflectivity, r, 0.0, 0.0,
                                       sol.haziness, sol.haze_extent)
        if b == pytest.approx(beta, abs=1e-9) and got == pytest.approx(f0, rel=1e-9):
            reached += 1
            continue
        assert sol.capped, (part, f0, beta, spread, r)
        k = int(np.argmax(f0))
        for scale in np.linspace(0.01, 1.0, 400):  # the brightest channel's r_c, f0's chroma
            rc = np.asarray(f0) / f0[k] * scale
            b_s, r_s, _ = haze_blend.forward(str(part), "MULTI_GGX", rc, r, 0.0, 0.0,
                                             K.MAX_HAZINESS, sol.haze_extent)
            assert not (b_s >= beta - 1e-6 and abs(r_s[k] / f0[k] - 1) <= 1e-3), (part, f0, beta, scale)
    assert reached >= 20, reached


def test_the_scalar_conductor_fresnel_is_the_vector_one():
    from hazy_gloss.interchange.brdf import fresnel_conductor, fresnel_conductor_at
    rng = np.random.default_rng(4)
    mu = rng.uniform(0.0, 1.0, 50)
    eta, kap = rng.uniform(0.05, 4.0, 3), rng.uniform(0.0, 6.0, 3)
    vec = fresnel_conductor(mu, eta, kap)
    for i, m in enumerate(mu):
        for ch in range(3):
            assert fresnel_conductor_at(m, eta[ch], kap[ch]) == pytest.approx(vec[i, ch], rel=1e-13, abs=1e-15)
