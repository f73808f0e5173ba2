# SPDX-License-Identifier: GPL-3.0-or-later
"""A PBR texture set (base colour, metallic, roughness, normal, coat, alpha) plus haze maps
converted into a Principled material with a baked haze layer: per texel it
renders what the live layer (node math) renders, and what pure hazy materials give, mixed by
the metallic map."""
import importlib
import os
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

import scenes
import test_layer as L
from measurements import record


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return SimpleNamespace(api=mod("api"), layer=mod("blender.model.layer"), exr=mod("conversion.imagecheck"),
                           convert=mod("conversion.convert"), material=mod("blender.model.material"))


def write_image(path, values):
    """A float OpenEXR (or 8-bit PNG for .png) written by Blender; values (H, W) or (H, W, 3)."""
    h, w = values.shape[:2]
    png = path.endswith(".png")
    img = bpy.data.images.new(os.path.basename(path), w, h, alpha=False, float_buffer=not png,
                              is_data=not png)  # (a float image not tagged as data is saved
    #                                               with the sRGB curve applied)
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = values if values.ndim == 3 else values[..., None]
    img.pixels.foreach_set(px.ravel())
    img.filepath_raw = path
    img.file_format = "PNG" if png else "OPEN_EXR"
    img.save()
    bpy.data.images.remove(img)
    return path


N = 4
RNG = np.random.default_rng(7)
BASE = RNG.uniform(0.05, 0.9, (N, N, 3))
ROUGH = RNG.uniform(0.15, 0.5, (N, N))
HAZE = RNG.uniform(0.1, 0.8, (N, N))
METALLIC = L.METALLIC_MAP


def pbr_set(tmp_path, ext=".exr", haze=True):
    d = dict(base_color=write_image(str(tmp_path / f"set_basecolor{ext}"), BASE),
             metallic=write_image(str(tmp_path / f"set_metallic{ext}"), METALLIC),
             roughness=write_image(str(tmp_path / f"set_roughness{ext}"), ROUGH))
    if haze:
        d["haziness"] = write_image(str(tmp_path / f"set_haziness{ext}"), HAZE)
    return d


def window(mat):
    """Every Image Texture of the material at Window coordinates, Closest (texel = 2x2 px)."""
    tree = mat.node_tree
    coord = tree.nodes.new("ShaderNodeTexCoord")
    for n in tree.nodes:
        if n.bl_idname == "ShaderNodeTexImage":
            n.interpolation = "Closest"
            tree.links.new(coord.outputs["Window"], n.inputs["Vector"])


def texel(img, i, j):
    return img[2 * i:2 * i + 2, 2 * j:2 * j + 2].mean(axis=(0, 1))


VIEWS = [((30.0, 0.0), (0.0, 0.0)), ((50.0, 20.0), (20.0, 200.0))]


def test_pbr_set_is_exact_per_texel(env, tmp_path):
    """Every texel of the converted material renders the pure dielectric and pure metal hazy
    materials of that texel's base colour, roughness and haziness (the layer's float64 mapping
    on constants, rendered one by one), mixed by its metallic value."""
    res = env.api.convert_maps(pbr_set(tmp_path), str(tmp_path / "out"), name="PBR Set",
                               interpolation="Closest")
    mat = res.material
    assert env.api.is_hazy(mat) and env.layer.is_baked(mat)
    assert all(os.path.isfile(p) for p in res.values())
    assert {"beta_dielectric", "beta_metal"} <= set(res)  # each part its own β per texel
    core = env.layer.layer_node(mat)
    assert core.inputs["Base Color"].is_linked and core.inputs["Roughness"].is_linked
    assert core.inputs["Metallic"].is_linked  # the map is the user's
    window(mat)
    got = [L.render(env, mat, *v)["combined"] for v in VIEWS]
    worst = 0.0
    for i in range(N):
        for j in range(N):
            parts = []
            for m in (0.0, 1.0):
                pure, _ = L.principled(f"pure {i}{j} {m}", **{
                    "Base Color": tuple(BASE[i, j]) + (1.0,), "Roughness": float(ROUGH[i, j]),
                    "Metallic": m})
                env.api.make_hazy(pure, haziness=float(HAZE[i, j]))
                parts.append([texel(L.render(env, pure, *v)["combined"], i, j) for v in VIEWS])
                bpy.data.materials.remove(pure)
            mu = METALLIC[i, j]
            for k in range(len(VIEWS)):
                want = (1.0 - mu) * parts[0][k] + mu * parts[1][k]
                err = float(np.abs(texel(got[k], i, j) - want).max() / max(np.abs(want).max(), 1e-3))
                worst = max(worst, err)
    record("convert_pbr", {"max_rel_vs_pure_texels": worst, "seconds": res.report.seconds})
    assert worst <= 2e-5, worst


def test_baked_equals_live_node_math(env, tmp_path):
    """With a constant haziness the same set can carry a live layer (node math in the shader):
    the baked maps render the same to float32 rounding."""
    paths = pbr_set(tmp_path, haze=False)
    paths["haziness"] = 0.45
    paths["haze_extent"] = 7.0
    baked = env.api.convert_maps(paths, str(tmp_path / "out"), name="Baked").material
    live = env.api.convert_maps(paths, str(tmp_path / "out2"), name="Live").material
    env.api.remove_haze(live)
    env.api.make_hazy(live, haziness=0.45, haze_extent=7.0)
    assert not env.layer.is_baked(live)
    for mat in (baked, live):
        window(mat)
    worst = 0.0
    for v in VIEWS:
        a = L.render(env, baked, *v)["combined"]
        b = L.render(env, live, *v)["combined"]
        worst = max(worst, L.rel_diff(a, b))
    record("convert_pbr", {"baked_vs_live": worst})
    assert worst <= 1e-5, worst


def test_pbr_set_into_the_users_material(env, tmp_path):
    """The user's own Principled material takes the maps in its empty inputs; its other nodes
    and links stay; a linked input is refused, the material and folder untouched."""
    mat, bsdf = L.principled("Mine", **{"Coat Weight": 0.5, "Sheen Weight": 0.3})
    tree = mat.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs["Fac"], bsdf.inputs["Specular IOR Level"])
    sig = L.signature(mat)
    out = tmp_path / "mine"
    with pytest.raises(env.convert.ConversionError, match="Specular IOR Level.*cannot evaluate"):
        env.api.convert_maps(pbr_set(tmp_path), str(out), material=mat)
    assert L.signature(mat) == sig and not out.exists()
    tree.links.remove(bsdf.inputs["Specular IOR Level"].links[0])
    tree.links.new(noise.outputs["Fac"], bsdf.inputs["Roughness"])
    sig = L.signature(mat)
    with pytest.raises(env.convert.ConversionError, match="Roughness.*already linked"):
        env.api.convert_maps(pbr_set(tmp_path), str(out), material=mat)
    assert L.signature(mat) == sig
    tree.links.remove(bsdf.inputs["Roughness"].links[0])
    res = env.api.convert_maps(dict(pbr_set(tmp_path), coat_haziness=0.4), str(out), material=mat)
    assert res.material == mat and env.layer.is_baked(mat)
    assert "noise" not in [n.bl_idname for n in tree.nodes] or noise.name in tree.nodes
    assert bsdf.inputs["Coat Weight"].default_value == 0.5
    assert env.layer.layer_node(mat).name == "Principled BSDF" and env.layer.original_node(mat) == bsdf
    with pytest.raises(ValueError, match="was converted into its maps"):
        env.api.update_material(mat, haziness=0.2)


def test_cli_converts_a_pbr_set_into_a_blend(env, tmp_path):
    import subprocess
    import sys
    from pathlib import Path
    paths = pbr_set(tmp_path, ext=".png")  # as texture libraries ship them: 8-bit PNG
    write_image(str(tmp_path / "set_normal.png"), np.full((N, N, 3), (0.5, 0.5, 1.0)))
    blend = tmp_path / "library.blend"
    repo = Path(__file__).resolve().parents[2]
    cmd = [sys.executable, "-m", "hazy_gloss", "convert", "--base-color", paths["base_color"],
           "--metallic", paths["metallic"], "--roughness", paths["roughness"],
           "--normal", str(tmp_path / "set_normal.png"), "--haziness", "0.3", "--opacity", "1",
           "--out", str(tmp_path / "maps"), "--blend", str(blend), "--name", "Crate"]
    proc = subprocess.run(cmd, cwd=str(repo), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "beta_dielectric" in proc.stdout
    check = ("import bpy, sys; bpy.ops.wm.open_mainfile(filepath=sys.argv[1]); m = bpy.data.materials['Crate']; "
             "n = m.node_tree.nodes; g = n['Principled BSDF'].node_tree['hazy_gloss_group']; "
             "print('OK', 'layer' in m['hazy_gloss'] and g['baked'] == 1, "
             "n['Principled BSDF'].inputs['Normal'].is_linked)")
    proc = subprocess.run([sys.executable, "-c", check, str(blend)], capture_output=True, text=True,
                          timeout=300)
    assert "OK True True" in proc.stdout, proc.stdout[-2000:] + proc.stderr[-2000:]
    # a flag of the perceptual form is refused for a PBR set, in one line
    proc = subprocess.run(cmd[:4] + ["--kind", "DIELECTRIC", "--out", str(tmp_path / "m2")],
                          cwd=str(repo), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr


def test_operator_converts_a_library_folder(env, tmp_path):
    """The operator on a texture library: one set per subfolder, named as libraries name them;
    a broken set is refused with its reason while the others convert."""
    lib = tmp_path / "library"
    for name, suffixes in (("Wood049", ("Color", "NormalGL", "NormalDX", "Roughness")),
                           ("rusty_metal", ("diff_1k", "rough_1k", "metal_1k", "nor_gl_1k")),
                           ("Broken", ("NormalDX",))):
        (lib / name).mkdir(parents=True)
        for sfx in suffixes:
            vals = np.full((N, N, 3), 0.5) if "Color" in sfx or "diff" in sfx else ROUGH
            if "Normal" in sfx or "nor" in sfx:
                vals = np.full((N, N, 3), (0.5, 0.5, 1.0))
            write_image(str(lib / name / f"{name}_{sfx}.png"), vals)
    assert bpy.ops.hazy_gloss.convert_pbr_set(folder=str(lib), batch=True, haziness=0.2,
                                               directory=str(tmp_path / "maps")) == {"FINISHED"}
    wood, rusty = bpy.data.materials["Wood049"], bpy.data.materials["rusty_metal"]
    assert "Broken" not in bpy.data.materials
    for mat in (wood, rusty):
        core = env.layer.layer_node(mat)
        assert env.layer.is_baked(mat) and core.inputs["Normal"].is_linked
        assert mat.use_fake_user
    assert env.layer.layer_node(rusty).inputs["Metallic"].is_linked  # metallic map kept
    assert os.path.isdir(tmp_path / "maps" / "Wood049")


def test_baked_layer_after_an_edit_that_needs_new_maps(env, tmp_path):
    """The user links a new texture into an input the baked maps depend on: the maps do not
    follow without converting again; the layer says so (read_parameters' notes, the panel)
    and nothing in the tree changes."""
    res = env.api.convert_maps(pbr_set(tmp_path), str(tmp_path / "out"), name="Set")
    mat = res.material
    core = env.layer.layer_node(mat)
    assert not env.layer.notes(mat)
    noise = mat.node_tree.nodes.new("ShaderNodeTexNoise")
    mat.node_tree.links.new(noise.outputs["Color"], core.inputs["Specular Tint"])
    sig = L.signature(mat)
    assert env.api.sync_haze(mat) is False
    said = " ".join(env.api.read_parameters(mat)["notes"])
    assert "Specular Tint" in said and "convert the maps again" in said
    assert L.signature(mat) == sig


def test_a_baked_layer_reports_its_haze_refuses_haze_edits_and_goes_whole(env, tmp_path):
    """A converted layer's haze is in its maps: read_parameters gives what they were converted
    with (it said haziness 0), a haze edit is refused in one line naming it (it changed nothing
    and said nothing), and Remove Haze takes the Image Textures of the converted maps with the
    layer (ten stayed, unlinked); the set's own maps stay on the BSDF, the files on disk."""
    paths = pbr_set(tmp_path, haze=False)
    paths.update(haziness=0.45, haze_extent=7.0)
    mat = env.api.convert_maps(paths, str(tmp_path / "out"), name="Baked").material
    p = env.api.read_parameters(mat)
    assert (p["haziness"], p["haze_extent"], p["coat_haziness"]) == (0.45, (7.0, 7.0), 0.0)
    mapped = env.api.convert_maps(pbr_set(tmp_path), str(tmp_path / "m"), name="Mapped").material
    assert env.api.read_parameters(mapped)["haziness"] == "texture"
    sig = L.signature(mat)
    for edit in (lambda: env.api.make_hazy(mat, haziness=0.9),
                 lambda: env.api.update_material(mat, haze_extent=2.0)):
        with pytest.raises(ValueError, match=r"^the haze of “Baked” was converted into its maps "
                                             r"\(haziness 0.45\): convert the maps again"):
            edit()
        assert L.signature(mat) == sig
    own = {n.image.name for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"
           and not n.label.startswith("Converted ")}
    files = sorted(os.listdir(tmp_path / "out"))
    env.api.remove_haze(mat)
    left = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"]
    assert {n.image.name for n in left} == own and all(n.outputs["Color"].is_linked for n in left)
    assert sorted(os.listdir(tmp_path / "out")) == files


def test_converting_again_replaces_the_baked_layer(env, tmp_path):
    """A second conversion into the same material (another set: no metallic or haze map now)
    is fine: the metallic image the material still has linked is read as a map too."""
    res = env.api.convert_maps(pbr_set(tmp_path), str(tmp_path / "a"), name="Again")
    mat = res.material
    paths = pbr_set(tmp_path, haze=False)
    del paths["metallic"]
    paths["haziness"] = 0.3
    res2 = env.api.convert_maps(paths, str(tmp_path / "b"), material=mat)
    assert res2.material == mat and env.layer.is_baked(mat)
    assert "beta_metal" in res2  # the material's own metallic texture still splits it


def test_converting_into_maps_another_material_reads_is_refused(env, tmp_path):
    """A second conversion into the folder of a first (a batch run again with other haze):
    the first material would render the new maps while its panel shows its own haze (QA: its
    β went from 0.435 to 0.792, the panel still said 0.2). Refused before anything is written,
    naming the material; the same material converted again, or another folder, is fine."""
    first = env.api.convert_maps(pbr_set(tmp_path), str(tmp_path / "out"), name="First")
    files = sorted(os.listdir(tmp_path / "out"))
    before = {f: (tmp_path / "out" / f).read_bytes() for f in files}
    paths = dict(pbr_set(tmp_path, haze=False), haziness=0.9)
    with pytest.raises(env.convert.ConversionError, match="the material “First” of this file "
                       "reads the maps there .*: convert into another folder, or delete it first"):
        env.api.convert_maps(paths, str(tmp_path / "out"), name="Second")
    assert {f: (tmp_path / "out" / f).read_bytes() for f in os.listdir(tmp_path / "out")} == before
    assert "Second" not in bpy.data.materials
    again = env.api.convert_maps(paths, str(tmp_path / "out"), material=first.material)
    assert again.material == first.material
    env.api.convert_maps(paths, str(tmp_path / "other"), name="Second")
