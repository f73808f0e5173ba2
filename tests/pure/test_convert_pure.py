# SPDX-License-Identifier: GPL-3.0-or-later
"""Texture conversion, bpy-free part (hazy_gloss/conversion/convert.py).

The whole-image mapping must equal the one-texel description (core.lobes.describe on one
texel, float32: the single piece every path uses; tests/pure/test_lobes.py checks it against an
independent derivation) bit for bit; tiling must not change any bit; bad texels are clamped and counted
once per texel and per parameter; constants and argument errors raise ConversionError (a
ValueError) with a one-line message.
"""
import math

import numpy as np
import pytest

from hazy_gloss import constants as K
from hazy_gloss.conversion import convert as C
from hazy_gloss.core.lobes import describe

H, W = 12, 10


def _inputs(rng, *, aniso=True, kind="CONDUCTOR"):
    a = {
        "core_reflectivity": rng.random((H, W, 3), dtype=np.float32),
        "edge_tint": rng.random((H, W, 3), dtype=np.float32) if kind == "CONDUCTOR" else np.zeros(3, np.float32),
        "roughness": rng.random((H, W), dtype=np.float32),
        "anisotropy": rng.random((H, W), dtype=np.float32) if aniso else np.float32(0),
        "rotation": rng.random((H, W), dtype=np.float32) * 2 - 0.5,
        "haziness": rng.random((H, W), dtype=np.float32) * np.float32(0.99),
        "haze_extent_x": rng.random((H, W), dtype=np.float32) * np.float32(12),
    }
    a["haze_extent_y"] = rng.random((H, W), dtype=np.float32) * np.float32(12) if aniso else a["haze_extent_x"]
    return a


def _texel(a, i, j, name):
    v = a[name]
    if np.ndim(v) >= 2:
        return v[i, j]
    return v


def reference_texel(a, i, j, kind, distribution="GGX", smoothness=None):
    """core.lobes.describe for texel (i, j) alone, in float32.

    One texel held in shape-(1,) arrays: with numpy 1.x a 0-d float32 scalar combined with a
    Python float is promoted to float64 (value-based casting), so a 0-d call would not be a
    float32 computation; one-element arrays are (numpy 1 and 2 alike)."""
    def one(name, colour=False):
        v = np.asarray(_texel(a, i, j, name), np.float32)
        return v.reshape(1, 3) if colour else v.reshape(1)

    d = describe(kind, distribution, core_reflectivity=one("core_reflectivity", True),
                 edge_tint=one("edge_tint", True), roughness=one("roughness"),
                 anisotropy=one("anisotropy"), rotation=one("rotation"), haziness=one("haziness"),
                 haze_extent=(one("haze_extent_x"), one("haze_extent_y")), smoothness=smoothness,
                 anisotropic=True, strict=False)
    f32 = lambda x: np.asarray(x).astype(np.float32)[0]  # noqa: E731
    out = {"beta": f32(d.beta), "roughness": f32(d.narrow.roughness),
           "roughness_wide": f32(d.wide.roughness), "anisotropy": f32(d.narrow.anisotropy),
           "rotation": f32(d.narrow.rotation), "anisotropy_wide": f32(d.wide.anisotropy),
           "rotation_wide": f32(d.wide.rotation)}
    names = {"colour_narrow": "weight_narrow", "colour_wide": "weight_wide"}
    out.update({names.get(k, k): f32(v) for k, v in d.fresnel.items()})
    return out


@pytest.mark.parametrize("kind", K.KINDS)
@pytest.mark.parametrize("aniso", [False, True])
@pytest.mark.parametrize("smoothness", [None, 2.0])
def test_whole_image_equals_per_texel_mapping(kind, aniso, smoothness):
    rng = np.random.default_rng(7)
    a = _inputs(rng, aniso=aniso, kind=kind)
    out = C.map_textures(a, kind=kind, smoothness=smoothness, tile_texels=37)
    assert out.anisotropic == aniso
    assert [s.name for s in out.specs] == [s.name for s in C.output_specs(kind, aniso)]
    worst = 0.0
    for i in range(H):
        for j in range(W):
            ref = reference_texel(a, i, j, kind, smoothness=smoothness)
            for name, got in out.maps.items():
                g, r = np.asarray(got[i, j], np.float32), np.asarray(ref[name], np.float32)
                assert g.dtype == np.float32
                if not np.array_equal(g, r):
                    err = float(np.max(np.abs(g - r) / np.maximum(np.abs(r), 1e-30)))
                    worst = max(worst, err)
                    assert err <= 1e-6, (name, i, j, g, r)
    # measured bit-for-bit here (numpy 1.26, x86-64); 1e-6 is allowed for other SIMD paths
    assert worst <= 1e-6


def test_tiling_does_not_change_any_bit():
    rng = np.random.default_rng(3)
    a = _inputs(rng)
    ref = C.map_textures(a, tile_texels=1 << 30)
    for tile, threads in ((1, 1), (W, 2), (3 * W + 1, 3), (5 * W, 1), (5 * W, 4)):
        out = C.map_textures(a, tile_texels=tile, threads=threads)
        for name in ref.maps:
            assert np.array_equal(out.maps[name], ref.maps[name]), (tile, name)
        assert out.clamped == ref.clamped


def test_bad_texels_clamped_and_counted_once():
    rng = np.random.default_rng(1)
    a = _inputs(rng)
    a["haziness"][0, 0] = np.nan
    a["haziness"][0, 1] = 1.0
    a["haziness"][0, 2] = 7.0
    a["haziness"][0, 3] = -0.5
    a["core_reflectivity"][1, 0] = (np.nan, 2.0, -1.0)  # one texel, three bad channels
    a["core_reflectivity"][1, 1] = (0.5, 1.5, 0.5)
    a["roughness"][2, 0] = -np.inf
    a["roughness"][2, 1] = np.inf
    a["rotation"][3, 0] = np.nan
    a["haze_extent_x"][4, 0] = -3.0
    out = C.map_textures(a)
    c = out.clamped
    assert c["haziness is NaN (set to 0)"] == 1
    assert c["haziness > 0.9999"] == 2  # the one haziness cap (constants.MAX_HAZINESS)
    assert c["haziness < 0"] == 1
    assert c["core_reflectivity is NaN (set to 0)"] == 1
    assert c["core_reflectivity > 1"] == 2
    assert c["core_reflectivity < 0"] == 1
    assert c["roughness < 0"] == 1 and c["roughness > 1"] == 1
    assert c["rotation is not finite (set to 0)"] == 1
    assert c["haze_extent_x < 0"] == 1
    by = C.group_clamped(c)
    assert by["haziness"] == 4 and by["core_reflectivity"] == 4 and by["roughness"] == 2
    for name, v in out.maps.items():
        assert np.all(np.isfinite(v)), name
    # the clamped texel maps exactly like its clamped value
    b = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in a.items()}
    b["haziness"][0, 1] = np.nextafter(np.float32(1), np.float32(0))
    ref = reference_texel(b, 0, 1, "CONDUCTOR")
    assert np.array_equal(out.maps["beta"][0, 1], ref["beta"])
    assert out.maps["roughness"][2, 0] == np.float32(K.min_roughness("GGX"))
    assert out.maps["roughness"][2, 1] == 1.0
    assert out.maps["rotation"][3, 0] == 0.0


def test_shared_extent_counts_once():
    rng = np.random.default_rng(2)
    a = _inputs(rng, aniso=False)
    a["haze_extent_x"][0, 0] = np.nan
    out = C.map_textures(a)
    assert out.clamped["haze_extent_x is NaN (set to 0)"] == 1
    assert not any(k.startswith("haze_extent_y") for k in out.clamped)
    assert not out.anisotropic


def test_alpha_input_is_square_of_roughness():
    rng = np.random.default_rng(4)
    a = _inputs(rng, aniso=False)
    r = a["roughness"]
    with_alpha = dict(a, roughness=(r * r).astype(np.float32))
    out_r = C.map_textures(a)
    out_a = C.map_textures(with_alpha, alpha_given=True)
    # √(R²) may differ from R by an ulp: compare the lobes' roughness, then everything loosely
    assert np.allclose(out_a.maps["roughness"], out_r.maps["roughness"], rtol=2e-7, atol=0)
    for name in out_r.maps:
        np.testing.assert_allclose(out_a.maps[name], out_r.maps[name], rtol=3e-6, atol=1e-7)


# --------------------------------------------------------------------------------------------
# resolve_inputs
# --------------------------------------------------------------------------------------------


def test_resolve_defaults_and_aliases():
    specs, notes = C.resolve_inputs({"haziness": "h.png", "alpha": 0.04, "haze_extent": "e.exr"})
    assert specs["haziness"].source == "h.png" and not specs["haziness"].is_constant
    assert specs["roughness"].transform == "sqrt" and specs["roughness"].source == np.float32(0.04)
    assert specs["haze_extent_x"].source == specs["haze_extent_y"].source == "e.exr"
    assert specs["core_reflectivity"].given_as == "default"
    np.testing.assert_array_equal(specs["core_reflectivity"].source, np.float32([0.5] * 3))
    assert notes == []
    _, notes = C.resolve_inputs({"haziness": "h.png", "edge_tint": 0.3}, kind="DIELECTRIC")
    assert "ignored" in notes[0]


@pytest.mark.parametrize("inputs, kw, pattern", [
    ({"haziness": "h.png"}, dict(kind="METAL"), "kind must be one of"),
    ({"haziness": "h.png"}, dict(kind="DIELECTRIC", distribution="BECKMANN"), "distributions"),
    ({"haziness": "h.png"}, dict(file_format="TIFF"), "file_format"),
    ({"haziness": "h.png"}, dict(smoothness=0), "smoothness"),
    ({"haziness": "h.png", "glossiness": 1}, {}, "unknown input"),
    ({"haziness": "h.png", "alpha": 0.1, "roughness": 0.3}, {}, "not both"),
    ({"haziness": "h.png", "haze_extent": 1, "haze_extent_x": 2, "haze_extent_y": 2}, {}, "not both"),
    ({"haziness": "h.png", "haze_extent_x": 2}, {}, "both haze_extent_x"),
    ({"haziness": 0.5}, {}, "no image input"),
    ({"haziness": "h.png", "roughness": 1.5}, {}, r"roughness.*out of range"),
    ({"haziness": "h.png", "core_reflectivity": (0.1, 0.2)}, {}, "RGB triple"),
    ({"haziness": "h.png", "core_reflectivity": math.nan}, {}, "finite"),
    ({"roughness": "r.png", "haziness": 1.0}, {}, r"haziness.*\[0, 0.9999\]"),
    ({"haziness": "h.png", "haze_extent": -1}, {}, r"haze_extent.*out of range"),
])
def test_resolve_errors(inputs, kw, pattern):
    with pytest.raises(C.ConversionError, match=pattern) as info:
        C.resolve_inputs(inputs, **kw)
    assert isinstance(info.value, ValueError)
    assert "\n" not in str(info.value)


def test_check_sizes_names_every_image():
    C.check_sizes([("a", (4, 4)), ("b", (4, 4))])
    with pytest.raises(C.ConversionError, match=r"a 4x4, b 8x4"):
        C.check_sizes([("a", (4, 4)), ("b", (8, 4))])


# --------------------------------------------------------------------------------------------
# Encodings, colour, resampling
# --------------------------------------------------------------------------------------------


def test_png_encodings_round_trip_within_16_bit():
    x = np.float32([0.0, 0.2, 1.0, 1.5, 3.0, 9.0, 40.0])
    spec = {s.name: s for s in C.output_specs("CONDUCTOR", True)}
    e = C.encode_png(spec["ior"], x)
    assert np.all((e >= 0) & (e <= 1))
    q = np.round(e * 65535) / 65535  # what a 16-bit PNG stores
    d = C.decode_png(spec["ior"], q.astype(np.float32))
    # |dx| <= (1 + x)² / 2 / 65535
    assert np.all(np.abs(d - x) <= (1 + x) ** 2 / 65535)
    g = {s.name: s for s in C.output_specs("LEGACY", True)}["anisotropy"]
    a = np.float32([-0.99, -0.5, 0.0])
    np.testing.assert_array_equal(C.decode_png(g, C.encode_png(g, a)), a)
    rot = spec["rotation_wide"]
    r = np.float32([-0.25, 0.0, 0.3, 1.0, 1.25])
    np.testing.assert_allclose(C.encode_png(rot, r), [0.75, 0.0, 0.3, 0.0, 0.25], atol=1e-7)


def test_srgb_curve():
    k = np.arange(256, dtype=np.float32) / np.float32(255)
    lin = C.srgb_to_linear(k)
    assert lin.dtype == np.float32 and lin[0] == 0 and lin[-1] == 1
    assert abs(lin[128] - 0.2158605) < 1e-7
    assert np.all(np.diff(lin) > 0)
    np.testing.assert_allclose(C.linear_to_srgb(lin), k, atol=2e-7)


def test_srgb_bytes_table_equals_formula():
    k = (np.arange(256, dtype=np.float32) * np.float32(1 / 255)).reshape(16, 16)
    img = np.stack([k, k[::-1], k.T], axis=-1)
    np.testing.assert_array_equal(C.srgb_bytes_to_linear(img), C.srgb_to_linear(img))
    odd = img.copy()
    odd[0, 0, 0] = 0.5  # not a byte value: falls back to the formula
    np.testing.assert_array_equal(C.srgb_bytes_to_linear(odd), C.srgb_to_linear(odd))


def test_resample_bilinear():
    a = np.arange(12, dtype=np.float32).reshape(3, 4)
    assert C.resample_bilinear(a, (4, 3)) is not None
    np.testing.assert_array_equal(C.resample_bilinear(a, (4, 3)), a)
    up = C.resample_bilinear(a, (8, 6))
    assert up.shape == (6, 8) and up.dtype == np.float32
    assert up.min() >= a.min() and up.max() <= a.max()
    c = np.ones((3, 4, 3), np.float32) * np.float32([0.1, 0.5, 0.9])
    np.testing.assert_allclose(C.resample_bilinear(c, (2, 2)), np.ones((2, 2, 3)) * [0.1, 0.5, 0.9], rtol=1e-6)
    # a linear ramp stays linear in the interior
    ramp = np.tile(np.arange(4, dtype=np.float32), (2, 1))
    r2 = C.resample_bilinear(ramp, (8, 2))[0]
    np.testing.assert_allclose(np.diff(r2[1:-1]), 0.5, atol=1e-6)


# --------------------------------------------------------------------------------------------
# Without Blender
# --------------------------------------------------------------------------------------------

_BLOCK_BPY = """
import importlib.abc, sys
sys.path.insert(0, {root!r})
class _Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("bpy", "_bpy", "mathutils", "bmesh", "gpu"):
            raise ImportError("blocked for the test: " + name)
        return None
sys.meta_path.insert(0, _Block())
"""


def _run_blocked(body):
    import subprocess
    import sys
    from pathlib import Path
    root = str(Path(__file__).resolve().parents[2])
    return subprocess.run([sys.executable, "-c", _BLOCK_BPY.format(root=root) + body],
                          capture_output=True, text=True, timeout=120, cwd=root)


def test_numeric_part_needs_no_bpy():
    r = _run_blocked("import numpy as np\n"
                     "from hazy_gloss.conversion import convert as C\n"
                     "m = C.map_textures({**{k: np.float32(v) if np.ndim(v) == 0 else np.float32(v)"
                     " for k, v in C.DEFAULTS.items()}, 'haziness': np.full((4, 4), 0.3, np.float32),"
                     " 'core_reflectivity': np.full(3, 0.5, np.float32), 'edge_tint': np.zeros(3, np.float32)})\n"
                     "assert m.maps['beta'].shape == (4, 4)\n"
                     "assert 'bpy' not in sys.modules\n"
                     "print('OK')\n")
    assert r.returncode == 0 and r.stdout.strip() == "OK", r.stderr


def test_cli_without_bpy_exits_3_with_one_line():
    r = _run_blocked("import runpy\n"
                     "sys.argv = ['hazy_gloss', 'convert', '--haziness', 'h.png', '--out', 'x']\n"
                     "runpy.run_module('hazy_gloss', run_name='__main__')\n")
    assert r.returncode == 3, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hazy_gloss convert: error: bpy is not importable")
    h = _run_blocked("import runpy\nsys.argv = ['hazy_gloss', 'convert', '--help']\n"
                     "runpy.run_module('hazy_gloss', run_name='__main__')\n")
    assert h.returncode == 0 and "--haziness" in h.stdout
