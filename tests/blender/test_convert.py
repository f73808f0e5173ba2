# SPDX-License-Identifier: GPL-3.0-or-later
"""Texture batch conversion through bpy (hazy_gloss.api.convert_maps, the operator, the CLI).

- converted maps equal the per-texel mapping (haze_mapping on one texel) bit for bit;
- a Cycles render of the baked material equals the render of the in-shader-mapping material
  fed the same textures (flat plane, light along the normal and at 30°), <= 1e-3 relative;
- inputs are never modified (file checksums, datablock pixels and settings), reruns are
  byte-identical, no temp file is left behind;
- NaN / negative / out-of-range texels are clamped and counted;
- 8-bit sRGB maps are decoded to linear (Image.pixels holds the encoded values), data maps read raw;
- errors (missing, empty, corrupt files, mismatched sizes, bad kind) are one-line ConversionErrors,
  and the CLI exits non-zero with a one-line reason.
Images are small (16x16 .. 32x32) so the whole file runs in seconds.
"""
import hashlib
import importlib
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes

REPO_ROOT = Path(__file__).resolve().parents[2]
N = 16


@pytest.fixture
def api(hg, clean_file):
    return importlib.import_module(hg.__name__ + ".api")


@pytest.fixture
def core(hg):
    return importlib.import_module(hg.__name__ + ".conversion.convert")


@pytest.fixture
def bconv(hg):
    return importlib.import_module(hg.__name__ + ".blender.actions.convert")


# --------------------------------------------------------------------------------------------
# Writing and reading test images (independent of the code under test where it matters)
# --------------------------------------------------------------------------------------------


def write_png(path, values, bits):
    """Integer ``values`` (H, W[, 3]) in Blender's row order (row 0 = bottom) -> RGB PNG of
    ``bits`` bits, written with zlib (no colour conversion anywhere)."""
    arr = np.asarray(values)
    if arr.ndim == 2:
        arr = np.repeat(arr[..., None], 3, axis=-1)
    arr = arr[::-1]  # PNG rows are top first
    h, w, _ = arr.shape
    dt = ">u2" if bits == 16 else "u1"
    raw = b"".join(b"\x00" + arr[y].astype(dt).tobytes() for y in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bits, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
    return str(path)


def write_exr(path, values):
    """float32 (H, W[, 3]) -> 32-bit float EXR (ZIP) through a Non-Color image."""
    values = np.asarray(values, np.float32)
    h, w = values.shape[:2]
    img = bpy.data.images.new("test input", w, h, float_buffer=True, is_data=True)
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = values[..., None] if values.ndim == 2 else values
    img.pixels.foreach_set(px.ravel())
    sc = bpy.data.scenes.new("test writer")
    s = sc.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format, s.color_mode, s.color_depth, s.exr_codec = "OPEN_EXR", "RGB", "32", "ZIP"
    img.save_render(str(path), scene=sc)
    bpy.data.scenes.remove(sc)
    bpy.data.images.remove(img)
    return str(path)


def read_raw(path):
    """(H, W, 4) float32 file values (Non-Color)."""
    img = bpy.data.images.load(str(path), check_existing=False)
    img.colorspace_settings.name = "Non-Color"
    w, h = img.size
    buf = np.empty(w * h * img.channels, np.float32)
    img.pixels.foreach_get(buf)
    bpy.data.images.remove(img)
    return buf.reshape(h, w, -1)


def sha(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def make_inputs(folder, *, n=N, seed=0, aniso=False, rc_bytes=256):
    """A set of perceptual maps in every input format: 8-bit sRGB PNG (core reflectivity),
    16-bit PNG (haziness), float EXR (roughness, extents, anisotropy).  Returns (paths, values)
    with values as the converter must read them (linear colour, raw data)."""
    rng = np.random.default_rng(seed)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rc8 = rng.integers(0, rc_bytes, (n, n, 3))
    haz16 = np.round(rng.uniform(0.0, 0.9, (n, n)) * 65535).astype(np.int64)
    rough = rng.uniform(0.05, 0.6, (n, n)).astype(np.float32)
    ext = rng.uniform(0.5, 8.0, (n, n)).astype(np.float32)
    paths = {"core_reflectivity": write_png(folder / "rc.png", rc8, 8),
             "haziness": write_png(folder / "haziness.png", haz16, 16),
             "roughness": write_exr(folder / "roughness.exr", rough)}
    values = {"core_reflectivity": rc8.astype(np.float32) * np.float32(1 / 255),
              "haziness": (haz16 / 65535).astype(np.float32), "roughness": rough}
    if aniso:
        ext_y = rng.uniform(0.0, 12.0, (n, n)).astype(np.float32)
        an = rng.uniform(0.0, 1.0, (n, n)).astype(np.float32)
        paths.update(haze_extent_x=write_exr(folder / "ext_x.exr", ext),
                     haze_extent_y=write_exr(folder / "ext_y.exr", ext_y),
                     anisotropy=write_exr(folder / "aniso.exr", an))
        values.update(haze_extent_x=ext, haze_extent_y=ext_y, anisotropy=an)
    else:
        paths["haze_extent"] = write_exr(folder / "ext.exr", ext)
        values["haze_extent_x"] = values["haze_extent_y"] = ext
    # the reference is what Blender reads (16-bit PNG: within an ulp of k/65535)
    for name, p in paths.items():
        raw = read_raw(p)
        got = raw[..., :3] if name == "core_reflectivity" else raw[..., 0]
        key = "haze_extent_x" if name == "haze_extent" else name
        np.testing.assert_allclose(got, values[key], rtol=2e-7, atol=0)
        values[key] = got
        if name == "haze_extent":
            values["haze_extent_y"] = got
    return paths, values


# --------------------------------------------------------------------------------------------
# Per-texel equality
# --------------------------------------------------------------------------------------------


def reference_texel(hg, v, i, j, kind, edge_tint, distribution="GGX"):
    """The lobes of one texel from core.lobes.describe (the one description every path uses),
    in float32 (one-element arrays: see the pure test), with the file's colour decoding."""
    lobes = importlib.import_module(hg.__name__ + ".core.lobes")
    core = importlib.import_module(hg.__name__ + ".conversion.convert")

    def one(name, default, colour=False):
        x = v.get(name)
        x = np.asarray(default if x is None else x[i, j], np.float32)
        return np.broadcast_to(x, (3,)).reshape(1, 3) if colour else x.reshape(1)

    d = lobes.describe(kind, distribution, core_reflectivity=core.srgb_to_linear(one("core_reflectivity", 0.5, True)),
                       edge_tint=np.asarray(edge_tint, np.float32).reshape(1, 3),
                       roughness=one("roughness", 0.1), anisotropy=one("anisotropy", 0.0),
                       rotation=np.zeros(1, np.float32), haziness=one("haziness", 0.5),
                       haze_extent=(one("haze_extent_x", 5.0), one("haze_extent_y", 5.0)),
                       anisotropic=True, strict=False)
    f = lambda x: np.asarray(x).astype(np.float32)[0]  # noqa: E731
    out = {"beta": f(d.beta), "roughness": f(d.narrow.roughness), "roughness_wide": f(d.wide.roughness),
           "anisotropy": f(d.narrow.anisotropy), "rotation": f(d.narrow.rotation),
           "anisotropy_wide": f(d.wide.anisotropy), "rotation_wide": f(d.wide.rotation)}
    names = {"colour_narrow": "weight_narrow", "colour_wide": "weight_wide"}
    out.update({names.get(k, k): f(val) for k, val in d.fresnel.items()})
    return out


@pytest.mark.parametrize("kind", ["CONDUCTOR", "DIELECTRIC", "LEGACY"])
@pytest.mark.parametrize("aniso", [False, True])
def test_maps_equal_per_texel_mapping(api, hg, tmp_path, kind, aniso):
    paths, values = make_inputs(tmp_path / "in", aniso=aniso)
    tint = (1.0, 0.8, 0.5) if kind == "CONDUCTOR" else (0.0, 0.0, 0.0)
    inputs = dict(paths)
    if kind == "CONDUCTOR":
        inputs["edge_tint"] = tint
    res = api.convert_maps(inputs, str(tmp_path / "out"), kind=kind)
    assert res.report.texels == N * N and res.report.size == (N, N)
    assert res.report.anisotropic == aniso
    maps = {name: read_raw(p) for name, p in res.items()}
    texels = [(i, j) for i in range(N) for j in range(N)]  # every texel
    diffs = 0
    for i, j in texels:
        ref = reference_texel(hg, values, i, j, kind, tint)
        for name, img in maps.items():
            spec = res.specs[name]
            got = img[i, j, :3] if spec.channels == 3 else img[i, j, 0]
            want = np.asarray(ref[name], np.float32)
            if not np.array_equal(got, want):
                diffs += 1
                np.testing.assert_allclose(got, want, rtol=1e-6, atol=0, err_msg=f"{name} {i},{j}")
            if spec.channels == 1:  # scalar maps are stored grey
                assert img[i, j, 0] == img[i, j, 1] == img[i, j, 2]
    assert diffs == 0  # measured bit-for-bit (1e-6 is allowed above for other platforms)


def test_srgb_byte_decode_matches_blender(core, tmp_path):
    """Image.pixels of an 8-bit sRGB PNG holds the ENCODED values (k/255), in 4.5 and 5.0; the
    converter decodes them with the IEC 61966-2-1 curve.  Blender's own (OCIO) decoding of the
    same values in a 16-bit PNG agrees to 2.5e-5 (OCIO's CPU path is approximate)."""
    k = np.arange(256).reshape(16, 16)
    p8 = write_png(tmp_path / "k8.png", k, 8)
    p16 = write_png(tmp_path / "k16.png", k * 257, 16)
    img8 = bpy.data.images.load(p8, check_existing=False)
    img16 = bpy.data.images.load(p16, check_existing=False)
    assert img8.colorspace_settings.name == img16.colorspace_settings.name == "sRGB"
    assert not img8.is_float and img16.is_float
    b8 = np.empty(256 * 4, np.float32)
    img8.pixels.foreach_get(b8)
    b16 = np.empty(256 * 4, np.float32)
    img16.pixels.foreach_get(b16)
    raw = b8.reshape(16, 16, 4)[..., 0]
    np.testing.assert_array_equal(raw, k.astype(np.float32) * np.float32(1 / 255))  # encoded
    blender_linear = b16.reshape(16, 16, 4)[..., 0]
    assert np.max(np.abs(core.srgb_to_linear(raw) - blender_linear)) <= 3e-5


# --------------------------------------------------------------------------------------------
# Baked render == in-shader render
# --------------------------------------------------------------------------------------------


def _full_frame_uvs(plane):
    """Map the camera's view of the plane (x, y in [-0.5, 0.5] with ortho_scale 1) onto UV
    [0, 1]^2, so each of the N x N render pixels samples one texel centre."""
    mesh = plane.data
    uv = mesh.uv_layers[0].data
    for loop in mesh.loops:
        co = mesh.vertices[loop.vertex_index].co
        uv[loop.index].uv = (co.x + 0.5, co.y + 0.5)


def _render(mat, light):
    scenes.setup_render("CYCLES", samples=1, resolution=(N, N), bounces=0)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    info = scenes.flat_plane_scene(mat, light_dir=light, strength=1.0, ortho_scale=1.0)
    _full_frame_uvs(info["plane"])
    return scenes.render_exr()[..., :3]


def _tex(tree, path, colour_space, *, split):
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(path, check_existing=False)
    tex.image.colorspace_settings.name = colour_space
    tex.image.alpha_mode = "CHANNEL_PACKED"
    tex.interpolation = "Closest"
    if not split:
        return tex.outputs["Color"]
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    tree.links.new(tex.outputs["Color"], sep.inputs[0])
    return sep.outputs[0]


def in_shader_material(api, paths, kind, aniso, edge_tint):
    mat = api.create_material("in-shader", kind=kind, edge_tint=edge_tint, shader_mapping=True,
                              anisotropy=0.5 if aniso else 0.0,
                              haze_extent=(5.0, 3.0) if aniso else 5.0)
    tree = mat.node_tree
    g = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeGroup")
    tree.links.new(_tex(tree, paths["core_reflectivity"], "sRGB", split=False),
                   g.inputs["Core Reflectivity"])
    for name, socket in (("roughness", "Roughness"), ("haziness", "Haziness"),
                         ("anisotropy", "Anisotropy"), ("haze_extent_x", "Haze Extent X"),
                         ("haze_extent_y", "Haze Extent Y"), ("haze_extent", "Haze Extent")):
        if name in paths:
            tree.links.new(_tex(tree, paths[name], "Non-Color", split=True), g.inputs[socket])
    return mat


@pytest.mark.parametrize("kind, aniso, fmt", [
    ("CONDUCTOR", False, "OPEN_EXR"), ("CONDUCTOR", True, "OPEN_EXR"),
    ("DIELECTRIC", False, "OPEN_EXR"), ("LEGACY", True, "OPEN_EXR"),
    ("CONDUCTOR", True, "PNG"), ("LEGACY", True, "PNG")])
def test_baked_render_equals_in_shader_render(api, tmp_path, kind, aniso, fmt, record_property):
    # r̂_c = 1 (byte 255) is left out: there the in-shader graph gives β = 1 (its safe divide
    # x/0 = 0 in σ = r̂_c q/(1-r̂_c)) where haze_mapping gives the limit β = 0 (no room for haze)
    paths, _ = make_inputs(tmp_path / "in", aniso=aniso, seed=5, rc_bytes=255)
    tint = (1.0, 0.8, 0.5) if kind == "CONDUCTOR" else 0.0
    ref_mat = in_shader_material(api, paths, kind, aniso, tint)
    baked = scenes.new_material("baked")
    inputs = dict(paths, edge_tint=tint) if kind == "CONDUCTOR" else dict(paths)
    res = api.convert_maps(inputs, str(tmp_path / "out"), kind=kind, file_format=fmt,
                           material=baked, interpolation="Closest")
    nodes = baked.node_tree.nodes
    assert not any(n.bl_idname == "ShaderNodeGroup" for n in nodes)  # no in-shader mapping
    assert sum(n.bl_idname == "ShaderNodeTexImage" for n in nodes) == len(res)
    worst = 0.0
    for light in ((0.0, 0.0), (30.0, 0.0)):
        a = _render(baked, light)
        b = _render(ref_mat, light)
        assert np.all(np.isfinite(a)) and b.max() > 0
        if fmt == "OPEN_EXR":  # per channel, relative
            err = np.abs(a - b) / (np.abs(b) + 1e-6 * b.max())
        else:
            # 16-bit PNG quantizes every map to 1/65535 (absolute): a dim channel of a colour
            # weight loses relative precision (measured 1.9e-2 per channel, 1.5e-5 of the pixel's
            # brightest channel), so compare with the brightest channel of each pixel
            err = np.abs(a - b) / (np.abs(b).max(axis=-1, keepdims=True) + 1e-6 * b.max())
        tol = 1e-3
        worst = max(worst, float(err.max()))
        assert err.max() <= tol, (light, float(err.max()))
        # the texture really varies across the frame
        assert np.ptp(b[..., 0]) > 0.1 * b[..., 0].max()
    record_property("baked_vs_in_shader_rel_error", worst)


# --------------------------------------------------------------------------------------------
# Inputs untouched, reruns identical, atomic writes
# --------------------------------------------------------------------------------------------


def test_inputs_unchanged_and_outputs_byte_identical(api, tmp_path):
    paths, _ = make_inputs(tmp_path / "in", aniso=True)
    before = {k: sha(p) for k, p in paths.items()}
    gen = bpy.data.images.new("painted", N, N, float_buffer=True)  # unsaved, sRGB-tagged float
    px = np.random.default_rng(3).random(N * N * 4).astype(np.float32)
    gen.pixels.foreach_set(px)
    gen_state = (gen.colorspace_settings.name, gen.alpha_mode, gen.source, gen.filepath)
    inputs = dict(paths, edge_tint=gen)
    out = tmp_path / "out"
    first = api.convert_maps(inputs, str(out))
    bytes1 = {k: Path(p).read_bytes() for k, p in first.items()}
    second = api.convert_maps(inputs, str(out))
    assert dict(first) == dict(second)
    for k, p in second.items():
        assert Path(p).read_bytes() == bytes1[k], f"{k} differs between runs"
    assert {k: sha(p) for k, p in paths.items()} == before
    after = np.empty_like(px)
    gen.pixels.foreach_get(after)
    assert np.array_equal(after, px)
    assert (gen.colorspace_settings.name, gen.alpha_mode, gen.source, gen.filepath) == gen_state
    assert sorted(os.listdir(out)) == sorted(os.path.basename(p) for p in first.values())
    # no image or scene datablocks left behind
    assert not [i for i in bpy.data.images if i.name.startswith(".hazy_gloss")]
    assert not [s for s in bpy.data.scenes if s.name.startswith(".hazy_gloss")]


def test_failed_write_leaves_old_output(api, bconv, tmp_path, monkeypatch):
    paths, _ = make_inputs(tmp_path / "in")
    out = tmp_path / "out"
    res = api.convert_maps(paths, str(out))
    old = {k: Path(p).read_bytes() for k, p in res.items()}

    def failing_replace(src, dst):
        raise OSError("replace failed")

    monkeypatch.setattr(bconv.os, "replace", failing_replace)
    with pytest.raises(bconv.ConversionError, match="replace failed.*folder is unchanged"):
        api.convert_maps(dict(paths, haziness=0.1), str(out))
    monkeypatch.undo()
    for k, p in res.items():  # the previous outputs are intact, no temp file is left
        assert Path(p).read_bytes() == old[k]
    assert sorted(os.listdir(out)) == sorted(os.path.basename(p) for p in res.values())
    assert not [s for s in bpy.data.scenes if s.name.startswith(".hazy_gloss")]


# --------------------------------------------------------------------------------------------
# Bad texels, bad input
# --------------------------------------------------------------------------------------------


def test_bad_texels_clamped_and_counted(api, tmp_path):
    rng = np.random.default_rng(2)
    haz = rng.uniform(0, 0.9, (N, N)).astype(np.float32)
    haz[0, 0], haz[0, 1], haz[0, 2], haz[0, 3] = np.nan, -1.0, 1.0, 5.0
    rc = rng.uniform(0, 1, (N, N, 3)).astype(np.float32)
    rc[1, 0] = (np.nan, -2.0, 3.0)
    rc[1, 1] = (0.2, 0.2, 1.5)
    rough = rng.uniform(0.05, 0.5, (N, N)).astype(np.float32)
    rough[2, 0] = -0.1
    rough[2, 1] = np.inf
    paths = {"haziness": write_exr(tmp_path / "h.exr", haz),
             "core_reflectivity": write_exr(tmp_path / "rc.exr", rc),
             "roughness": write_exr(tmp_path / "r.exr", rough)}
    res = api.convert_maps(paths, str(tmp_path / "out"))
    c = res.report.clamped
    assert c["haziness is NaN (set to 0)"] == 1
    assert c["haziness < 0"] == 1
    assert c["haziness > 0.9999"] == 2  # the one haziness cap (constants.MAX_HAZINESS)
    assert c["core_reflectivity is NaN (set to 0)"] == 1
    assert c["core_reflectivity > 1"] == 2
    assert c["core_reflectivity < 0"] == 1
    assert c["roughness < 0"] == 1 and c["roughness > 1"] == 1
    by = res.report.clamped_by_parameter
    assert by["haziness"] == 4 and by["core_reflectivity"] == 4 and by["roughness"] == 2
    for name, p in res.items():
        assert np.all(np.isfinite(read_raw(p))), name
    assert "haziness 4" in res.report.summary()


@pytest.mark.parametrize("case", ["missing", "empty", "corrupt", "sizes", "kind", "relative",
                                  "overwrite", "udim_mismatch"])
def test_errors_are_one_line(api, core, tmp_path, case):
    paths, _ = make_inputs(tmp_path / "in")
    out = str(tmp_path / "out")
    kw = {}
    if case == "missing":
        paths["haziness"] = str(tmp_path / "nope.png")
        pattern = r"haziness \(nope.png\): file not found: .*nope.png"
    elif case == "empty":
        (tmp_path / "empty.png").write_bytes(b"")
        paths["haziness"] = str(tmp_path / "empty.png")
        pattern = r"haziness \(empty.png\): .*empty.png is empty \(0 bytes\)"
    elif case == "corrupt":
        (tmp_path / "bad.png").write_bytes(b"this is not an image" * 4)
        paths["haziness"] = str(tmp_path / "bad.png")
        pattern = r"haziness \(bad.png\): .*bad.png is not an image file Blender reads \(PNG, "
    elif case == "sizes":
        paths["haziness"] = write_png(tmp_path / "small.png", np.zeros((8, 8), int), 16)
        pattern = r"different resolutions: .*small.png\) 8x8.*16x16"
    elif case == "kind":
        kw["kind"] = "METAL"
        pattern = "kind must be one of CONDUCTOR, DIELECTRIC, LEGACY"
    elif case == "relative":
        out = "//maps"
        pattern = "needs a saved .blend"
    elif case == "overwrite":
        out = str(tmp_path / "in")
        paths["roughness"] = write_exr(tmp_path / "in" / "roughness.exr", np.full((N, N), 0.2, np.float32))
        pattern = "would overwrite an input"
    else:
        for t in (1001, 1002):
            write_exr(tmp_path / f"h.{t}.exr", np.zeros((N, N), np.float32))
        write_exr(tmp_path / "r.1001.exr", np.zeros((N, N), np.float32))
        paths["haziness"] = str(tmp_path / "h.<UDIM>.exr")
        paths["roughness"] = str(tmp_path / "r.<UDIM>.exr")
        pattern = "UDIM inputs have different tiles"
    with pytest.raises(core.ConversionError, match=pattern) as info:
        api.convert_maps(paths, out, **kw)
    assert "\n" not in str(info.value)
    assert isinstance(info.value, ValueError)


def test_resample_option(api, tmp_path):
    paths, _ = make_inputs(tmp_path / "in")
    paths["haziness"] = write_exr(tmp_path / "h8.exr", np.full((8, 8), 0.3, np.float32))
    res = api.convert_maps(paths, str(tmp_path / "out"), resample=True)
    assert res.report.size == (N, N)
    assert any("resampled from 8x8 to 16x16" in w for w in res.report.warnings)
    const = api.convert_maps(dict(paths, haziness=0.3), str(tmp_path / "out2"))
    np.testing.assert_array_equal(read_raw(res["beta"]), read_raw(const["beta"]))


def test_data_map_tagged_srgb_warns_and_reads_raw(api, tmp_path):
    paths, values = make_inputs(tmp_path / "in")
    img = bpy.data.images.load(paths["haziness"], check_existing=False)  # 16-bit PNG: sRGB, float
    assert img.colorspace_settings.name == "sRGB"
    via_block = api.convert_maps(dict(paths, haziness=img), str(tmp_path / "a"))
    via_path = api.convert_maps(paths, str(tmp_path / "b"))
    assert any("tagged sRGB" in w for w in via_block.report.warnings)
    assert any("tagged sRGB" in w for w in via_path.report.warnings)
    assert img.colorspace_settings.name == "sRGB"  # the datablock is not modified
    assert img.users == 0 or img.name in bpy.data.images
    # the datablock's file is re-read privately as Non-Color: exactly the same values
    for k in via_path:
        np.testing.assert_array_equal(read_raw(via_block[k]), read_raw(via_path[k]), err_msg=k)


def test_packed_image_input(api, tmp_path):
    paths, _ = make_inputs(tmp_path / "in")
    ref = api.convert_maps(paths, str(tmp_path / "ref"))
    copy = tmp_path / "to_pack.png"
    copy.write_bytes(Path(paths["core_reflectivity"]).read_bytes())
    img = bpy.data.images.load(str(copy), check_existing=False)
    img.pack()
    copy.unlink()
    res = api.convert_maps(dict(paths, core_reflectivity=img), str(tmp_path / "packed"))
    assert img.packed_file is not None
    for k in ref:
        np.testing.assert_array_equal(read_raw(res[k]), read_raw(ref[k]), err_msg=k)


def test_numpy_array_inputs(api, core, tmp_path):
    paths, _ = make_inputs(tmp_path / "in")
    from_files = api.convert_maps(paths, str(tmp_path / "a"))
    # the values exactly as Blender reads the files (16-bit PNG: k x float32(1/65535))
    arrays = {k: read_raw(p)[..., 0] for k, p in paths.items() if k != "core_reflectivity"}
    arrays["core_reflectivity"] = core.srgb_to_linear(read_raw(paths["core_reflectivity"])[..., :3])
    from_arrays = api.convert_maps(arrays, str(tmp_path / "b"))
    for k in from_files:
        np.testing.assert_array_equal(read_raw(from_arrays[k]), read_raw(from_files[k]), err_msg=k)
    with pytest.raises(core.ConversionError, match=r"haziness \(array\): expected shape \(H, W\)"):
        api.convert_maps(dict(arrays, haziness=np.zeros((4, 4, 3), np.float32)), str(tmp_path / "c"))
    with pytest.raises(core.ConversionError, match="haziness: expected an image path"):
        api.convert_maps(dict(arrays, haziness={"not": "an image"}), str(tmp_path / "c"))


def test_udim_tiles(api, tmp_path):
    rng = np.random.default_rng(9)
    tiles = {}
    for t in (1001, 1002, 1011):
        tiles[t] = rng.uniform(0, 0.9, (N, N)).astype(np.float32)
        write_exr(tmp_path / f"haz.{t}.exr", tiles[t])
    rough = write_exr(tmp_path / "rough.exr", rng.uniform(0.1, 0.5, (N, N)).astype(np.float32))
    res = api.convert_maps({"haziness": str(tmp_path / "haz.<UDIM>.exr"), "roughness": rough},
                           str(tmp_path / "out"))
    assert res.report.tiles == [1001, 1002, 1011]
    assert res.report.texels == 3 * N * N
    assert res["beta"].endswith("beta.<UDIM>.exr")
    for t, haz in tiles.items():
        single = api.convert_maps({"haziness": str(tmp_path / f"haz.{t}.exr"), "roughness": rough},
                                  str(tmp_path / f"single{t}"))
        for k in res:
            np.testing.assert_array_equal(read_raw(res[k].replace("<UDIM>", str(t))),
                                          read_raw(single[k]), err_msg=f"{k} tile {t}")
    mat = scenes.new_material("udim")
    api.convert_maps({"haziness": str(tmp_path / "haz.<UDIM>.exr"), "roughness": rough},
                     str(tmp_path / "out"), material=mat)
    tex = mat.node_tree.nodes["HG Map beta"]
    assert tex.image.source == "TILED"
    assert sorted(t.number for t in tex.image.tiles) == [1001, 1002, 1011]


def test_udim_tiles_agree_in_anisotropy(api, tmp_path):
    """Tile 1001 isotropic, tile 1002 anisotropic: every tile gets the anisotropic map set."""
    ext = np.full((N, N), 3.0, np.float32)
    for t, ey in ((1001, 3.0), (1002, 6.0)):
        write_exr(tmp_path / f"ex.{t}.exr", ext)
        write_exr(tmp_path / f"ey.{t}.exr", np.full((N, N), ey, np.float32))
    res = api.convert_maps({"haze_extent_x": str(tmp_path / "ex.<UDIM>.exr"),
                            "haze_extent_y": str(tmp_path / "ey.<UDIM>.exr")}, str(tmp_path / "o"))
    assert res.report.anisotropic and res.report.texels == 2 * N * N
    for t in (1001, 1002):
        assert os.path.isfile(res["anisotropy_wide"].replace("<UDIM>", str(t)))
    a = read_raw(res["anisotropy_wide"].replace("<UDIM>", "1001"))
    assert np.all(a[..., 0] == 0)  # isotropic tile: wide anisotropy 0


# --------------------------------------------------------------------------------------------
# Wiring, operator, constants shared with the add-on
# --------------------------------------------------------------------------------------------


def test_rewire_replaces_only_our_nodes(api, tmp_path):
    paths, _ = make_inputs(tmp_path / "in", aniso=True)
    mat = api.create_material("hazy", roughness=0.2)
    tree = mat.node_tree
    keep = tree.nodes.new("ShaderNodeRGB")
    keep.name = "user node"
    api.convert_maps(paths, str(tmp_path / "out"), material=mat)
    n1 = len(tree.nodes)
    api.convert_maps(paths, str(tmp_path / "out"), material=mat)
    assert len(tree.nodes) == n1
    assert "user node" in tree.nodes
    assert "hazy_gloss" not in mat and mat["hazy_gloss_maps"]["kind"] == "CONDUCTOR"
    assert all(n.name.startswith("HG ") for n in tree.nodes
               if n.name != "user node" and n.bl_idname != "ShaderNodeOutputMaterial")
    for n in tree.nodes:
        if n.bl_idname == "ShaderNodeTexImage":
            assert n.image.colorspace_settings.name == "Non-Color"
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    assert out.inputs["Surface"].links[0].from_node.name == "HG Lobe mix"
    images = [i for i in bpy.data.images if "hazy" not in i.name and i.filepath]
    assert len(images) == len({i.filepath for i in images})  # re-wiring reuses the datablocks


def test_operator(hg, clean_file, tmp_path):
    paths, _ = make_inputs(tmp_path / "in")
    bpy.ops.mesh.primitive_plane_add()
    obj = bpy.context.object
    mat = scenes.new_material("target")
    obj.data.materials.append(mat)
    cls = bpy.types.HAZY_GLOSS_OT_convert_maps
    assert "UNDO" in cls.bl_options and "REGISTER" in cls.bl_options
    menu_funcs = getattr(bpy.types.NODE_MT_node.draw, "_draw_funcs", [])
    assert any(getattr(f, "__name__", "") == "draw_convert_entry" for f in menu_funcs)  # F3 menu search
    r = bpy.ops.hazy_gloss.convert_maps(haziness_path=paths["haziness"],
                                        roughness_path=paths["roughness"],
                                        core_reflectivity=(0.9, 0.6, 0.3), haze_extent=4.0,
                                        directory=str(tmp_path / "op"), interpolation="Closest")
    assert r == {"FINISHED"}
    assert sorted(os.listdir(tmp_path / "op")) == sorted(
        ["beta.exr", "roughness.exr", "roughness_wide.exr", "ior.exr", "extinction.exr"])
    assert "HG Map beta" in mat.node_tree.nodes
    # unsaved file + default '//hazy_maps/': a temp folder, with a warning
    img = bpy.data.images.load(paths["haziness"], check_existing=False)
    r = bpy.ops.hazy_gloss.convert_maps(haziness_image=img.name, wire=False)
    assert r == {"FINISHED"}
    import shutil
    import tempfile
    fallback = Path(tempfile.gettempdir()) / "hazy_gloss_maps" / "target"
    assert (fallback / "beta.exr").is_file()
    shutil.rmtree(fallback)
    with pytest.raises(RuntimeError, match="file not found"):
        bpy.ops.hazy_gloss.convert_maps(haziness_path=str(tmp_path / "nope.png"),
                                        directory=str(tmp_path / "op2"))


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------


def _cli(args, tmp_path):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"),
               PYTHONPATH=str(REPO_ROOT))
    return subprocess.run([sys.executable, "-m", "hazy_gloss", *args], cwd=str(tmp_path),
                          env=env, capture_output=True, text=True, timeout=300)


def test_cli_exit_codes(hg, clean_file, tmp_path):
    paths, _ = make_inputs(tmp_path / "in")
    ok = _cli(["convert", "--haziness", paths["haziness"], "--core-reflectivity", "0.9,0.6,0.3",
               "--roughness", paths["roughness"], "--out", str(tmp_path / "cli")], tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert (tmp_path / "cli" / "beta.exr").is_file()
    assert "texels" in ok.stdout
    small = write_exr(tmp_path / "small.exr", np.zeros((4, 4), np.float32))
    cases = {
        "file not found": ["--haziness", str(tmp_path / "missing.png")],
        "different resolutions": ["--haziness", paths["haziness"], "--roughness", small],
        "kind must be one of": ["--haziness", paths["haziness"], "--kind", "METAL"],
        "unrecognized arguments": ["--haziness", paths["haziness"], "--bogus", "1"],
    }
    for reason, args in cases.items():
        r = _cli(["convert", *args, "--out", str(tmp_path / "bad")], tmp_path)
        assert r.returncode == 2, (reason, r.stderr)
        last = [ln for ln in r.stderr.splitlines() if ln.startswith("hazy_gloss convert: error:")]
        assert len(last) == 1 and reason in last[0], r.stderr
    assert not (tmp_path / "bad").exists() or not os.listdir(tmp_path / "bad")


class _Layout:
    """Stand-in for UILayout in background mode (panels and dialogs are never drawn): checks the
    methods exist on bpy.types.UILayout and the properties on the operator."""

    def __init__(self, props, calls):
        self._props, self.calls = props, calls
        self.use_property_split = False

    def __getattr__(self, name):
        assert name in bpy.types.UILayout.bl_rna.functions, name

        def call(*args, **kw):
            if name in ("prop", "prop_search"):
                data, prop = args[0], args[1]
                if not isinstance(data, type(bpy.data)):
                    assert prop in self._props, prop
                if name == "prop_search":
                    assert args[3] == "images"
            self.calls.append((name, args[1] if len(args) > 1 else kw.get("text")))
            if name in ("box", "column", "row"):
                return _Layout(self._props, self.calls)
            return None
        return call


@pytest.mark.parametrize("kind", ["CONDUCTOR", "DIELECTRIC"])
def test_operator_dialog_draws(hg, clean_file, kind):
    from types import SimpleNamespace
    cls = bpy.types.HAZY_GLOSS_OT_convert_maps
    rna = bpy.ops.hazy_gloss.convert_maps.get_rna_type()
    props = {k: v for k, v in rna.properties.items()
             if k != "rna_type" and v.type not in ("POINTER", "COLLECTION")}
    values = {}
    for k, p in props.items():
        default = getattr(p, "default_array", None) if getattr(p, "is_array", False) else p.default
        values[k] = tuple(default) if getattr(p, "is_array", False) else default
    values.update(kind=kind, anisotropic_extent=True, use_smoothness=True)
    calls = []
    fake = SimpleNamespace(layout=_Layout(set(props), calls), **values)
    cls.draw(fake, bpy.context)
    drawn = {c[1] for c in calls}
    assert "haziness_image" in drawn and "haze_extent_y_path" in drawn and "directory" in drawn
    assert ("edge_tint_image" in drawn) == (kind == "CONDUCTOR")
    assert ("base_color" in drawn) == (kind == "DIELECTRIC")
