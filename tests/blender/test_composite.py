# SPDX-License-Identifier: GPL-3.0-or-later
"""Edit haziness after the render (paper §4.3, Eq. 10-11).

One scene: a hazy conductor sphere (lean tree), a hazy dielectric sphere with a diffuse base
(in-shader mapping), a non-hazy diffuse sphere and a non-hazy ground plane, a delta sun.

- exact: black world, no bounces.  Every sample is deterministic given the seed, so the four
  layers line up sample for sample: recomposite == direct render to float precision, at the
  edited haziness and at the original one, edge pixels included (Blackman-Harris filter).
- noisy: a small environment and 2 bounces.  Sampling differs between the layers (different
  closures at the camera hit), so agreement is at noise level: measured against the seed-to-seed
  difference of two direct renders.
- the compositor group "Hazy Gloss Recomposite" run headless (Image nodes on the saved EXR, no
  scene render) == the numpy recomposite.
- the operators: setup, idempotence, clear.
"""
import importlib
import os
import time

import bpy
import numpy as np
import pytest

import scenes
from measurements import record

RES = (64, 48)
ORIGINAL = dict(conductor=0.3, dielectric=0.05)
EDITED = 0.7  # β_h for every hazy pixel after the edit




@pytest.fixture
def mods(hg, clean_file):
    api = importlib.import_module(hg.__name__ + ".api")
    comp = importlib.import_module(hg.__name__ + ".blender.model.recomposite")
    global rc  # the bpy-free recomposite (numpy), used by the helpers below too
    rc = importlib.import_module(hg.__name__ + ".recomposite")
    return api, comp


rc = None




def _diffuse(name, colour):
    mat = scenes.new_material(name)
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    mat.node_tree.nodes.remove(bsdf)
    d = mat.node_tree.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*colour, 1.0)
    out = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    mat.node_tree.links.new(d.outputs[0], out.inputs["Surface"])
    return mat


def build_scene(api, *, samples, bounces, world=0.0, res=RES, spread=0.62):
    """The test scene; returns the hazy materials {"conductor": mat, "dielectric": mat}."""
    scene = scenes.setup_render(samples=samples, resolution=res, bounces=bounces, seed=3)
    scene.cycles.pixel_filter_type = "BLACKMAN_HARRIS"
    scene.cycles.filter_width = 1.5  # anti-aliased edges: tests the mask normalisation
    if world:
        scenes.uniform_world(world, color=(0.6, 0.75, 1.0))
    mats = {
        "conductor": api.create_material("HG Test Conductor", kind="CONDUCTOR",
                                         core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5),
                                         roughness=0.15, haziness=ORIGINAL["conductor"],
                                         haze_extent=6.0),
        "dielectric": api.create_material("HG Test Dielectric", kind="DIELECTRIC",
                                          core_reflectivity=0.04, roughness=0.12,
                                          haziness=ORIGINAL["dielectric"], haze_extent=8.0,
                                          base_color=(0.05, 0.2, 0.08), shader_mapping=True),
    }
    scenes.analytic_sphere("Conductor", (-spread, 0.0, 0.5), mats["conductor"])
    scenes.analytic_sphere("Dielectric", (spread, 0.0, 0.5), mats["dielectric"])
    scenes.analytic_sphere("Plain", (0.0, 1.0, 0.3), _diffuse("Plain Diffuse", (0.7, 0.2, 0.2)), radius=0.3)
    plane = bpy.data.objects.new("Ground", scenes._plane_mesh("Ground", 8.0))
    scene.collection.objects.link(plane)
    plane.data.materials.append(_diffuse("Ground Diffuse", (0.5, 0.5, 0.5)))
    cam_data = bpy.data.cameras.new("Cam")
    cam_data.lens = 40
    cam = bpy.data.objects.new("Cam", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, -4.0, 1.6)
    cam.rotation_euler = (np.radians(72.0), 0.0, 0.0)
    scene.camera = cam
    scenes._sun(scenes.spherical_direction(40.0, -120.0), 3.0)
    return mats


def direct_render(scene, comp):
    """The ordinary render of the recomposite-mode materials (template layer only)."""
    layers = {vl.name: vl.use for vl in scene.view_layers}
    compositing = scene.render.use_compositing
    try:
        for vl in scene.view_layers:
            vl.use = vl.name not in rc.LAYERS
        scene.render.use_compositing = False
        return scenes.render_exr()
    finally:
        for vl in scene.view_layers:
            vl.use = layers[vl.name]
        scene.render.use_compositing = compositing
        comp._set_multilayer_exr(scene)


def passes_render(scene, comp, tmp_path, name="passes"):
    path = str(tmp_path / f"{name}.exr")
    scene.render.filepath = path
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return rc.passes_from_exr(path), time.perf_counter() - t0, path


def set_haziness(api, comp, mats, value):
    """A direct render at another haziness: rebuild the material, back to recomposite mode."""
    for kind, mat in mats.items():
        api.update_material(mat, haziness=value if np.isscalar(value) else value[kind])
        comp.convert_material(mat)


def _hazy(passes):
    return passes["mask"] > 0


# --------------------------------------------------------------------------------------------
# exact: delta sun, black world, no bounces
# --------------------------------------------------------------------------------------------
def test_recomposite_exact(mods, tmp_path):
    api, comp = mods
    scene = bpy.context.scene
    mats = build_scene(api, samples=4, bounces=0)
    report = comp.setup_recomposite(scene)
    assert sorted(report["converted"]) == sorted(m.name for m in mats.values()), report
    passes, _, _ = passes_render(scene, comp, tmp_path)
    hazy = _hazy(passes)
    assert hazy.sum() > 300 and (~hazy).sum() > 1000

    original = direct_render(scene, comp)
    same = rc.recomposite(passes)  # nothing edited
    err_same = np.abs(same - original).max()

    set_haziness(api, comp, mats, EDITED)
    edited_direct = direct_render(scene, comp)
    edited = rc.recomposite(passes, haziness=EDITED)
    err_edit = np.abs(edited - edited_direct).max()
    scale = edited_direct[..., :3].max()
    change = np.abs(edited_direct - original)[hazy].max()
    # non-hazy pixels are untouched: exactly the first buffer, and the direct render
    nonhazy = np.abs(edited - original)[~hazy].max()
    record("recomposite", {"exact scene: max |recomposite - direct| (edited)": err_edit,
                           "exact scene: max |recomposite - direct| (unchanged)": err_same,
                           "exact scene: peak pixel": scale, "exact scene: haziness change": change})
    assert change > 0.05 * scale  # the edit is visible
    assert err_edit <= 2e-5 * scale, err_edit
    assert err_same <= 2e-5 * scale, err_same
    assert nonhazy <= 2e-5 * scale, nonhazy


# --------------------------------------------------------------------------------------------
# noisy: environment light.  bounces=0: the only difference is sampling.  bounces=2: hazy
# objects also see each other, and Eq. 11 only re-weights what the camera sees directly — the
# reflection of the dielectric in the conductor keeps its original haziness (a real limit).
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("bounces", [0, 2])
def test_recomposite_noise_level(mods, tmp_path, bounces):
    api, comp = mods
    scene = bpy.context.scene
    mats = build_scene(api, samples=32, bounces=bounces, world=0.4)
    comp.setup_recomposite(scene)
    t0 = time.perf_counter()
    original = direct_render(scene, comp)
    t_direct = time.perf_counter() - t0
    passes, t_passes, _ = passes_render(scene, comp, tmp_path)
    hazy = _hazy(passes)

    same = rc.recomposite(passes)
    set_haziness(api, comp, mats, EDITED)
    edited_direct = direct_render(scene, comp)
    scene.cycles.seed = 4
    edited_direct_2 = direct_render(scene, comp)
    edited = rc.recomposite(passes, haziness=EDITED)

    def rms(a, b, m):
        """rms difference after x/(1+x) tone mapping: the sun's sub-pixel highlight (pixel
        values up to ~25, anti-aliasing noise of ±50%) would otherwise be the whole figure."""
        ta, tb = (x[..., :3] / (1.0 + x[..., :3]) for x in (a, b))
        return float(np.sqrt(np.mean((ta - tb)[m] ** 2)))

    noise = rms(edited_direct, edited_direct_2, hazy)  # two independent renders, same settings
    err_edit = rms(edited, edited_direct, hazy)
    err_same = rms(same, original, hazy)
    w = hazy.shape[1]
    left = hazy & (np.arange(w) < w // 2)[None, :]  # the conductor sphere
    right = hazy & (np.arange(w) >= w // 2)[None, :]  # the dielectric sphere
    bias = {name: float(np.mean(edited[..., :3][m]) / np.mean(edited_direct[..., :3][m]) - 1)
            for name, m in (("conductor", left), ("dielectric", right))}
    seed_bias = {name: float(np.mean(edited_direct_2[..., :3][m]) / np.mean(edited_direct[..., :3][m]) - 1)
                 for name, m in (("conductor", left), ("dielectric", right))}
    change = rms(edited_direct, original, hazy)
    nonhazy_same = np.abs(same - original)[~hazy].max()
    key = f"environment, {bounces} bounces, 32 spp (rms of x/(1+x))"
    record("recomposite", {
        f"{key}: rms recomposite - direct (edited), hazy pixels": err_edit,
        f"{key}: rms recomposite - direct (unchanged), hazy pixels": err_same,
        f"{key}: rms direct seed 3 - seed 4 (noise level)": noise,
        f"{key}: rms change of the edit": change,
        f"{key}: relative mean difference recomposite/direct - 1": bias,
        f"{key}: relative mean difference seed 4/seed 3 - 1": seed_bias,
        f"{key}: max |recomposite - direct| non-hazy (unchanged)": nonhazy_same,
        f"{key}: render time direct s": t_direct,
        f"{key}: render time original + 4 layers s": t_passes})
    assert change > 2 * noise  # the edit is larger than the noise
    assert err_same <= 1e-6, err_same  # unedited = the original layer, bit for bit
    # non-hazy pixels of the unedited recomposite are the original render's, exactly: their
    # paths never meet the per-layer switch (it acts on camera rays at hazy surfaces only)
    assert nonhazy_same <= 1e-5, nonhazy_same
    if bounces == 0:
        # the layers' sampling mostly lines up with the direct render: far below the noise
        assert err_edit <= 0.2 * noise, (err_edit, noise)
        assert max(abs(b) for b in bias.values()) <= 0.005, bias
    else:
        # inter-reflections keep the original haziness: a bias of a few percent, measured
        assert err_edit <= noise, (err_edit, noise)
        assert max(abs(b) for b in bias.values()) <= 0.08, bias
        # the holdout of non-hazy objects acts on camera rays only: where the camera sees only
        # hazy surfaces, the buffers are bit-identical without it (same paths, same light —
        # the held-out floor and sphere still shadow, light and appear in reflections)
        scene.cycles.seed = 3
        set_haziness(api, comp, mats, ORIGINAL)
        comp.setup_recomposite(scene, holdout=False)
        free, _, _ = passes_render(scene, comp, tmp_path, "no_holdout")
        inside = passes["mask"] >= 1.0
        for key in rc.BUFFER_KEYS:
            assert np.array_equal(free[key][inside], passes[key][inside]), key
        assert np.abs(free["narrow_delta"] - passes["narrow_delta"])[~hazy].max() > 0.01


# --------------------------------------------------------------------------------------------
# compositor group == numpy
# --------------------------------------------------------------------------------------------
def test_compositor_group_matches_numpy(mods, tmp_path):
    api, comp = mods
    scene = bpy.context.scene
    mats = build_scene(api, samples=4, bounces=0)
    comp.setup_recomposite(scene)
    # live: the group fed by Render Layers nodes runs at render time; the EXR gets "Composite"
    compat = importlib.import_module(api.__name__.rpartition(".")[0] + ".blender.compat")
    live = compat.compositor_tree(scene).nodes["HG RC Recomposite"]
    live.inputs["New Haziness"].default_value = 0.85
    live.inputs["Haziness Factor"].default_value = 1.0
    passes, _, path = passes_render(scene, comp, tmp_path)
    hazy = _hazy(passes)
    ch = rc.read_exr(path)
    live_img = np.stack([ch[f"Composite.Combined.{c}"] for c in "RGBA"], axis=-1)
    err_live = np.abs(live_img - rc.recomposite(passes, haziness=0.85)).max()
    assert err_live <= 1e-5 * max(passes["original"][..., :3].max(), 1.0), err_live
    # a haziness map and a core-reflectivity edit limited by a mask: left half only
    h, w = hazy.shape
    left = np.zeros((h, w), np.float32)
    left[:, : w // 2] = 1.0
    expected = rc.recomposite(passes, haziness=0.85, core_reflectivity=(0.4, 0.7, 0.9),
                                core_reflectivity_factor=left)

    group = comp.build_compositor(scene, source=path, haziness=0.85,
                                  core_reflectivity=(0.4, 0.7, 0.9))
    tree = group.id_data
    mask_img = bpy.data.images.new("HG left", w, h, float_buffer=True, is_data=True)
    buf = np.repeat(left[..., None], 4, axis=-1).astype(np.float32)
    mask_img.pixels.foreach_set(buf.ravel())
    mask_img.pack()
    mask_node = tree.nodes.new("CompositorNodeImage")
    mask_node.image = mask_img
    mask_node.name = "HG RC Test Mask"
    tree.links.new(mask_node.outputs["Alpha"], group.inputs["Core Reflectivity Factor"])
    t0 = time.perf_counter()
    got = scenes.render_exr()  # no Render Layers node: the compositor runs, the scene does not
    t_comp = time.perf_counter() - t0
    err = np.abs(got - expected).max()
    scale = expected[..., :3].max()
    record("recomposite", {"compositor vs numpy max abs": err, "compositor time s": t_comp,
                           "live compositor (render layers) vs numpy max abs": err_live})
    assert np.abs(expected - rc.recomposite(passes))[hazy].max() > 0.05 * scale
    assert err <= 1e-5 * max(scale, 1.0), err
    del mats


# --------------------------------------------------------------------------------------------
# recomposite mode = the normal material with Schlick's Fresnel: near normal incidence (θ_d = 10°,
# where every Fresnel is F(0) to ~1e-3) both render the same, which checks the lobes' roughness,
# anisotropy, rotation, tangent and β in both the lean and the in-shader path
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["CONDUCTOR", "DIELECTRIC", "LEGACY"])
@pytest.mark.parametrize("anisotropy", [0.0, 0.8])
@pytest.mark.parametrize("shader_mapping", [False, True])
def test_schlick_mode_matches_normal_material(mods, kind, anisotropy, shader_mapping):
    api, comp = mods
    params = dict(CONDUCTOR=dict(core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5),
                                 haziness=0.6),
                  DIELECTRIC=dict(core_reflectivity=0.04, haziness=0.1),
                  LEGACY=dict(core_reflectivity=(0.6, 0.5, 0.2), haziness=0.6))[kind]
    mat = api.create_material("HG Test Plane", kind=kind, roughness=0.3, anisotropy=anisotropy,
                              rotation=0.1, haze_extent=(4.0, 1.5), shader_mapping=shader_mapping,
                              **params)
    scenes.setup_render(samples=1, resolution=(4, 4), bounces=0)
    scenes.flat_plane_scene(mat, light_dir=(20.0, 30.0))
    normal = scenes.render_exr()[1:3, 1:3, :3].mean(axis=(0, 1))
    comp.convert_material(mat)
    schlick = scenes.render_exr()[1:3, 1:3, :3].mean(axis=(0, 1))
    rel = float(np.abs(schlick / normal - 1).max())
    record("recomposite", {f"schlick mode / normal - 1 at θd=10°: {kind} aniso={anisotropy} "
                           f"in-shader={shader_mapping}": rel})
    assert normal.max() > 0.01  # a highlight, not black
    assert rel <= 3e-3, (normal, schlick)


# --------------------------------------------------------------------------------------------
# operators and bookkeeping
# --------------------------------------------------------------------------------------------
def test_operators_setup_and_clear(mods):
    api, comp = mods
    scene = bpy.context.scene
    mats = build_scene(api, samples=1, bounces=0)
    legacy_as = api.create_material("HG Test AS", kind="LEGACY", distribution="ASHIKHMIN_SHIRLEY")
    scenes.analytic_sphere("AS", (0.0, -1.0, 0.3), legacy_as, radius=0.2)
    surface_before = {m.name: m.node_tree.nodes["Material Output"].inputs["Surface"].links[0].from_node.name
                      for m in (*mats.values(), legacy_as)}
    n_layers = len(scene.view_layers)
    file_format = scene.render.image_settings.file_format
    assert bpy.ops.hazy_gloss.setup_recomposite() == {"FINISHED"}
    assert bpy.ops.hazy_gloss.setup_recomposite() == {"FINISHED"}  # idempotent
    names = [vl.name for vl in scene.view_layers]
    assert names.count("HG Narrow Delta") == 1 and len(names) == n_layers + 4
    assert scene.view_layers[0].use  # the original render stays: V0 of the recomposite
    held = {o.name for o in bpy.data.collections[comp.HOLDOUT_COLLECTION].objects}
    # non-hazy objects only; the skipped hazy material (AS) stays visible in every layer, where
    # it cancels exactly (Σ of the weight differences is 0)
    assert held == {"Plain", "Ground"}, held
    assert all(scene.view_layers[n].layer_collection.children[comp.HOLDOUT_COLLECTION].holdout
               for n in rc.LAYERS)
    assert not scene.view_layers[0].layer_collection.children[comp.HOLDOUT_COLLECTION].holdout
    assert {a.name for a in scene.view_layers["HG Narrow Delta"].aovs} == {a for a, _, _ in rc.AOVS}
    assert scene.render.image_settings.file_format == "OPEN_EXR_MULTILAYER"
    for m in mats.values():
        assert comp.STAMP in m
        link = m.node_tree.nodes["Material Output"].inputs["Surface"].links[0]
        assert link.from_node.name.startswith("HG RC")
        lobes = [n for n in m.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfMetallic"
                 and n.name.startswith("HG RC")]
        assert len(lobes) == 2 and all(n.fresnel_type == "F82" for n in lobes)
    assert comp.STAMP not in legacy_as  # skipped: rendered as non-hazy
    assert bpy.data.node_groups.get(rc.GROUP_NAME) is not None

    assert bpy.ops.hazy_gloss.clear_recomposite() == {"FINISHED"}
    assert len(scene.view_layers) == n_layers and scene.view_layers[0].use
    assert comp.HOLDOUT_COLLECTION not in bpy.data.collections
    for m in (*mats.values(), legacy_as):
        assert comp.STAMP not in m
        assert not any(n.name.startswith("HG RC") for n in m.node_tree.nodes)
        link = m.node_tree.nodes["Material Output"].inputs["Surface"].links[0]
        assert link.from_node.name == surface_before[m.name]
    assert scene.render.image_settings.file_format == file_format


#: Every codec Blender writes (DWA and B44 lossy; HTJ2K from 5.0).
CODECS = ("NONE", "ZIP", "ZIPS", "RLE", "PIZ", "PXR24", "B44", "B44A", "DWAA", "DWAB", "HTJ2K")


def test_exr_reader_codecs(mods, tmp_path):
    """The bpy-free reader (OpenImageIO) against Blender's own loader, for every codec Blender
    writes: bit for bit, the lossy ones included (both decode with the OpenEXR library)."""
    _, comp = mods
    scenes.setup_render(samples=1, resolution=(23, 37), bounces=0)
    img = bpy.data.images.new("HG ramp", 23, 37, float_buffer=True)
    rng = np.random.default_rng(1)
    buf = rng.random((37, 23, 4), dtype=np.float32) * 4.0
    img.pixels.foreach_set(buf.ravel())
    s = bpy.context.scene.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format, s.color_mode = "OPEN_EXR", "RGBA"
    codecs = [c for c in CODECS if c in s.bl_rna.properties["exr_codec"].enum_items]
    assert {"ZIP", "PIZ", "DWAA", "DWAB"} <= set(codecs)
    for codec in codecs:
        s.color_depth = "16" if codec.startswith("B44") else "32"  # B44: half only
        s.exr_codec = codec
        path = str(tmp_path / f"ramp_{codec}.exr")
        img.save_render(path, scene=bpy.context.scene)
        ch = rc.read_exr(path)
        got = np.stack([ch[k] for k in ("R", "G", "B", "A")], axis=-1)
        loaded = bpy.data.images.load(path, check_existing=False)
        want = np.empty(37 * 23 * 4, np.float32)
        loaded.pixels.foreach_get(want)
        bpy.data.images.remove(loaded)
        assert np.array_equal(got, want.reshape(37, 23, 4)), codec
        if codec in ("NONE", "ZIP", "ZIPS", "RLE", "PIZ"):  # lossless: the pixels written
            assert np.array_equal(got, buf), codec
    os.remove(path)


def _weights(passes, **edit):
    """Per pixel and channel, Δc_k of Eq. 11 (out = V0 + Σ_k Δc_k V_k), read off the
    recomposite itself, which is linear in the five renders: V0 = 0, V_k = 1, the others 0."""
    zero = np.zeros_like(passes["original"])
    out = []
    for key in rc.BUFFER_KEYS:
        probe = dict(passes, original=zero, **{k: zero for k in rc.BUFFER_KEYS})
        probe[key] = np.ones_like(zero)
        out.append(rc.recomposite(probe, **edit)[..., :3])
    return out


def test_recomposite_reads_zip_piz_and_dwab_passes(mods, tmp_path):
    """The same render saved as ZIP, PIZ and DWAB (a farm's lossless and lossy codecs): PIZ
    reads back the ZIP passes bit for bit; DWAB's recomposite differs from ZIP's by no more
    than its passes do, carried through Eq. 11: with Δc_k the weights (from each file's AOVs),
    |out' - out| <= |δV0| + Σ_k |Δc'_k| |δV_k| + Σ_k |Δc'_k - Δc_k| |V_k| (exact algebra:
    out' - out = δV0 + Σ Δc'_k δV_k + Σ (Δc'_k - Δc_k) V_k), plus float32 rounding: each
    of the two evaluations rounds ~20 operations, each by at most 2^-24 of a magnitude below
    |V0| + 4 Σ_k |V_k| (the differences d12, d13, d34 and their products by β, r ≤ 1)."""
    api, comp = mods
    scene = bpy.context.scene
    build_scene(api, samples=4, bounces=0)
    comp.setup_recomposite(scene)
    passes = {}
    _, _, path = passes_render(scene, comp, tmp_path, "zip")
    passes["ZIP"] = rc.passes_from_exr(path)
    result = bpy.data.images["Render Result"]
    for codec in ("PIZ", "DWAB"):
        scene.render.image_settings.exr_codec = codec
        p = str(tmp_path / f"{codec}.exr")
        result.save_render(p, scene=scene)
        inp = importlib.import_module(api.__name__.rpartition(".")[0] + ".conversion.oiio").openimageio() \
            .ImageInput.open(p)
        assert inp.spec().get_string_attribute("compression").startswith(codec.lower()), codec
        inp.close()
        passes[codec] = rc.passes_from_exr(p)
    zip_, piz, dwab = passes["ZIP"], passes["PIZ"], passes["DWAB"]
    assert all(np.array_equal(piz[k], zip_[k]) for k in zip_), "PIZ is lossless"
    lossy = [k for k in rc.BUFFER_KEYS + ("original",) if not np.array_equal(dwab[k], zip_[k])]
    assert lossy, "DWAB stored the renders exactly: the bound below would test nothing"
    hazy = _hazy(zip_)
    for edit in ({}, {"haziness": EDITED}, {"haziness": 0.1, "core_reflectivity": (0.3, 0.5, 0.8)}):
        out = rc.recomposite(zip_, **edit)[..., :3]
        out_d = rc.recomposite(dwab, **edit)[..., :3]
        w, w_d = _weights(zip_, **edit), _weights(dwab, **edit)
        v = [zip_[k][..., :3] for k in rc.BUFFER_KEYS]
        v_d = [dwab[k][..., :3] for k in rc.BUFFER_KEYS]
        bound = np.abs(dwab["original"][..., :3] - zip_["original"][..., :3])
        for k in range(4):
            bound += np.abs(w_d[k]) * np.abs(v_d[k] - v[k]) + np.abs(w_d[k] - w[k]) * np.abs(v[k])
        size = np.abs(zip_["original"][..., :3]) + 4 * sum(np.abs(x) for x in v)
        size_d = np.abs(dwab["original"][..., :3]) + 4 * sum(np.abs(x) for x in v_d)
        bound += 20 * 2.0 ** -24 * (size + size_d)
        err = np.abs(out_d - out)
        assert (err <= bound).all(), (edit, float((err - bound).max()))
        assert edit == {} or np.abs(out - zip_["original"][..., :3])[hazy].max() > 0  # an edit
    record("recomposite", {"DWAB passes: max |recomposite(DWAB) - recomposite(ZIP)|, edited":
                           float(np.abs(rc.recomposite(dwab, haziness=EDITED)
                                        - rc.recomposite(zip_, haziness=EDITED)).max())})


def test_damaged_source_is_refused_before_blender_loads_it(mods, tmp_path):
    """A saved render cut off (interrupted while it was written): build_compositor raises one
    line naming the file before bpy.data.images.load sees it (it crashed bpy 5.0.1)."""
    _, comp = mods
    ic = importlib.import_module(comp.__name__.rpartition(".blender")[0] + ".conversion.imagecheck")
    scenes.setup_render(samples=1, resolution=(23, 37), bounces=0)
    img = bpy.data.images.new("HG ramp", 23, 37, float_buffer=True)
    img.pixels.foreach_set(np.random.default_rng(4).random(23 * 37 * 4, dtype=np.float32))
    s = bpy.context.scene.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format, s.color_depth, s.exr_codec = "OPEN_EXR", "32", "ZIP"
    whole = tmp_path / "whole.exr"
    img.save_render(str(whole), scene=bpy.context.scene)
    data = whole.read_bytes()
    cut = tmp_path / "cut.exr"
    cut.write_bytes(data[:len(data) // 2])
    with pytest.raises(ic.ImageFileError, match=r"cut\.exr is a damaged OpenEXR file"):
        comp.build_compositor(bpy.context.scene, source=str(cut), original="ViewLayer")
    assert not [i for i in bpy.data.images if i.filepath and "cut.exr" in i.filepath]


def test_recomposite_entry_points(hg):
    """The operators are reachable from Render > Hazy Gloss Recomposite (so F3 finds them) and a
    View Layer properties panel; both go away when the add-on is disabled."""
    ops = importlib.import_module(hg.__name__ + ".blender.ui.menus")
    assert ops.draw_render_menu in bpy.types.TOPBAR_MT_render._dyn_ui_initialize()
    assert hasattr(bpy.types, "HAZY_GLOSS_PT_recomposite")
    drawn = []

    class Layout:
        def column(self, align=False):
            return self

        def operator(self, idname, icon=None):
            assert idname.split(".")[1] in dir(bpy.ops.hazy_gloss), idname
            drawn.append(idname)

    ops.draw_recomposite_operators(Layout())
    assert drawn == ["hazy_gloss.setup_recomposite", "hazy_gloss.load_recomposite",
                     "hazy_gloss.clear_recomposite"]


def test_a_source_that_is_not_openexr_is_refused(mods, tmp_path):
    """A PNG of the render passed as the source (a natural slip): refused with one line, before
    Blender loads it into Image nodes whose layers it does not have (a black composite)."""
    _, comp = mods
    img = bpy.data.images.new("HG png source", 8, 8)
    path = tmp_path / "render.png"
    img.filepath_raw, img.file_format = str(path), "PNG"
    img.save()
    with pytest.raises(ValueError, match=r"render\.png is a PNG file: the recomposite source "
                                         r"must be the multilayer OpenEXR of a render"):
        comp.build_compositor(bpy.context.scene, source=str(path), original="ViewLayer")
    assert not [i for i in bpy.data.images if i.filepath and i.filepath.endswith("render.png")
                and i.name != "HG png source"]
