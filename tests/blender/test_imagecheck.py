# SPDX-License-Identifier: GPL-3.0-or-later
"""The image check (OpenImageIO) against Blender: it accepts what Blender writes (every EXR
codec, multilayer, PNG 8/16-bit, JPEG) and refuses those files cut short; Blender loads what the
fuzz tests' pure-python writer writes (scanline and tiled EXR, PNG) with the same pixels, so
the fuzz bases are real files; and Blender loads every fuzzed file the check passes without a
crash (the check stands between a damaged file and Blender's loader)."""
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "pure"))
import fuzz_files as F  # noqa: E402

#: Lossless and lossy codecs Blender writes (HTJ2K from 5.0).
CODECS = ("NONE", "RLE", "ZIPS", "ZIP", "PIZ", "PXR24", "B44", "B44A", "DWAA", "DWAB", "HTJ2K")
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def ic(hg, clean_file):
    return importlib.import_module(hg.__name__ + ".conversion.imagecheck")


def _settings(file_format, depth, codec=None, mode="RGBA"):
    s = bpy.context.scene.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "MULTI_LAYER_IMAGE" if file_format == "OPEN_EXR_MULTILAYER" else "IMAGE"
    s.file_format = file_format
    s.color_depth = depth
    s.color_mode = mode
    if codec is not None:
        s.exr_codec = codec
    return s


def _image(w=37, h=23):
    img = bpy.data.images.new("HG check", w, h, float_buffer=True)
    rng = np.random.default_rng(2)
    img.pixels.foreach_set((rng.random((h, w, 4), dtype=np.float32) * 2).ravel())
    return img


def _assert_refused_when_cut(ic, path, tmp_path):
    """Cut in half, and by the last byte that holds pixels: a PNG's IEND (12 bytes) is not
    needed to decode every row (libpng, and Blender through it, stop before it)."""
    data = Path(path).read_bytes()
    last = len(data) - (13 if data.endswith(b"IEND\xaeB`\x82") else 1)
    for cut in (len(data) // 2, last):
        p = tmp_path / ("cut" + Path(path).suffix)
        p.write_bytes(data[:cut])
        with pytest.raises(ic.ImageFileError, match="cut"):
            ic.check_image_file(str(p))


def test_check_accepts_blender_exr_and_refuses_it_cut(ic, tmp_path):
    scenes.setup_render(samples=1, resolution=(37, 23), bounces=0)
    img = _image()
    codecs = [c for c in CODECS
              if c in bpy.types.ImageFormatSettings.bl_rna.properties["exr_codec"].enum_items]
    assert {"NONE", "ZIP", "PIZ", "DWAA"} <= set(codecs)
    for codec in codecs:
        _settings("OPEN_EXR", "32" if codec not in ("B44", "B44A") else "16", codec)
        path = str(tmp_path / f"img_{codec}.exr")
        img.save_render(path, scene=bpy.context.scene)
        assert ic.check_image_file(path) == ("OPEN_EXR", 37, 23), codec
        _assert_refused_when_cut(ic, path, tmp_path)


def test_check_accepts_blender_multilayer_render(ic, tmp_path):
    scenes.setup_render(samples=1, resolution=(12, 9), bounces=0)
    scenes._ortho_camera("HG camera", scenes.spherical_direction(0.0), 2.0)
    _settings("OPEN_EXR_MULTILAYER", "32", "ZIP")
    sc = bpy.context.scene
    sc.view_layers.new("Second")
    sc.render.filepath = str(tmp_path / "ml.exr")
    bpy.ops.render.render(write_still=True)
    assert ic.check_image_file(sc.render.filepath).format == "OPEN_EXR"
    _assert_refused_when_cut(ic, sc.render.filepath, tmp_path)


@pytest.mark.parametrize("depth", ["8", "16"])
def test_check_accepts_blender_png_and_refuses_it_cut(ic, tmp_path, depth):
    scenes.setup_render(samples=1, resolution=(37, 23), bounces=0)
    _settings("PNG", depth)
    path = str(tmp_path / f"img{depth}.png")
    _image().save_render(path, scene=bpy.context.scene)
    assert ic.check_image_file(path) == ("PNG", 37, 23)
    _assert_refused_when_cut(ic, path, tmp_path)


def _load(path):
    img = bpy.data.images.load(str(path), check_existing=False)
    img.colorspace_settings.name = "Non-Color"
    w, h = img.size
    buf = np.empty(w * h * img.channels, np.float32)
    img.pixels.foreach_get(buf)
    out = buf.reshape(h, w, img.channels)
    bpy.data.images.remove(img)
    return out


def test_blender_loads_the_fuzz_writer_files(ic, tmp_path):
    """The pure-python writer's files are real EXRs and PNGs: Blender reads the same pixels."""
    rng = np.random.default_rng(5)
    h, w = 19, 7
    ch = {c: (np.round(rng.random((h, w), dtype=np.float32) * 64) / 16).astype(np.float32)
          for c in "RGBA"}
    for comp in ("NONE", "RLE", "ZIPS", "ZIP"):
        data, _ = F.encode_exr([{"channels": ch, "compression": comp}])
        path = tmp_path / f"w_{comp}.exr"
        path.write_bytes(data)
        got = _load(path)
        assert np.array_equal(got, np.stack([ch[c] for c in "RGBA"], -1)), comp
    for levels in ("ONE", "MIPMAP", "RIPMAP"):  # Blender reads level 0 through the offset table
        tiled = tmp_path / f"w_tiled_{levels}.exr"
        tiled.write_bytes(F.encode_tiled_exr({c: ch[c] for c in "RGBA"}, tile=(4, 4), levels=levels))
        assert ic.check_image_file(str(tiled)) == ("OPEN_EXR", w, h)
        assert np.array_equal(_load(tiled), np.stack([ch[c] for c in "RGBA"], -1)), levels
    px = rng.integers(0, 256, (h, w, 4))
    png = tmp_path / "w.png"
    png.write_bytes(F.encode_png(px, idat_parts=3))
    got = _load(png)[::-1]  # Blender's row 0 is the bottom row; PNG's the top
    assert np.allclose(got * 255, px, atol=1e-3)


def test_check_accepts_blender_jpeg_and_refuses_it_cut(ic, tmp_path):
    scenes.setup_render(samples=1, resolution=(37, 23), bounces=0)
    _settings("JPEG", "8", mode="RGB")
    path = str(tmp_path / "img.jpg")
    _image().save_render(path, scene=bpy.context.scene)
    assert ic.check_image_file(path) == ("JPEG", 37, 23)
    _assert_refused_when_cut(ic, path, tmp_path)


def test_every_format_blender_writes_is_told_by_its_contents(ic, tmp_path):
    """Each file format Blender writes (named ``.img``, so only the contents can tell; TGA,
    which has no magic number, ``.tga``) is recognised as that format: the format table
    against real files."""
    scenes.setup_render(samples=1, resolution=(37, 23), bounces=0)
    img = _image()
    s = bpy.context.scene.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    seen = {}
    for fmt in ("BMP", "IRIS", "PNG", "JPEG", "JPEG2000", "TARGA", "TARGA_RAW", "CINEON", "DPX",
                "OPEN_EXR", "HDR", "TIFF", "WEBP"):
        if fmt not in s.bl_rna.properties["file_format"].enum_items:
            continue
        s.file_format = fmt
        s.color_mode = "RGB"
        want = "TARGA" if fmt.startswith("TARGA") else fmt
        path = tmp_path / (f"{fmt}.tga" if want == "TARGA" else f"{fmt}.img")
        try:
            img.save_render(str(path), scene=bpy.context.scene)
        except RuntimeError:  # e.g. JPEG 2000 where this build's writer fails
            continue
        got = ic.check_image_file(str(path))
        assert got.format == want and want in ic.FORMAT_NAMES, (fmt, got)
        if want in ("PNG", "JPEG", "OPEN_EXR"):
            assert got[1:] == (37, 23), (fmt, got)
        seen[fmt] = got.format
    assert {"PNG", "JPEG", "OPEN_EXR", "TIFF", "BMP", "TARGA", "HDR"} <= set(seen), seen


#: In a child process (a crash kills it, not the suite): every fuzzed EXR and PNG case through
#: the check; each one it passes loaded by Blender and its pixels read.
_LOAD_WHAT_PASSES = r"""
import json, os, sys
sys.path[:0] = [sys.argv[1], os.path.join(sys.argv[1], "tests", "pure")]
import bpy
import numpy as np
import fuzz_files as F
from hazy_gloss.conversion import imagecheck
folder = sys.argv[2]
cases = [(a, d, ".exr") for a, _, d, _ in F.all_cases()]
cases += [(a, m, ".png") for label, data in F.png_bases()
          for a, m in [("valid", data)] + list(F.png_mutations(label, data, 0)) if m is not None]
counts = {"refused": 0, "loaded": 0}
for i, (attack, data, ext) in enumerate(cases):
    path = os.path.join(folder, f"case{i % 2}{ext}")
    with open(path, "wb") as fh:
        fh.write(data)
    try:
        info = imagecheck.check_image_file(path)
    except imagecheck.ImageFileError:
        counts["refused"] += 1
        continue
    print(i, attack, file=sys.stderr, flush=True)  # the last case named if Blender dies
    img = bpy.data.images.load(path, check_existing=False)
    w, h = img.size
    assert (w, h) == (info.width, info.height) or info.format == "OPEN_EXR", (attack, (w, h), info)
    px = np.empty(w * h * img.channels, np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    counts["loaded"] += 1
print(json.dumps(counts))
"""


def test_blender_loads_every_fuzzed_file_the_check_passes(tmp_path):
    """The fuzz corpus (tests/pure/fuzz_files.py: 6000+ damaged EXRs, 800+ damaged PNGs): what
    the check refuses never reaches Blender, and Blender loads what it passes without dying."""
    r = subprocess.run([sys.executable, "-c", _LOAD_WHAT_PASSES, str(ROOT), str(tmp_path)],
                       capture_output=True, text=True, timeout=1800, cwd=str(tmp_path),
                       env=dict(os.environ, PYTHONDONTWRITEBYTECODE="1"))
    last = r.stderr.strip().splitlines()[-1:] if r.stderr.strip() else []
    assert r.returncode == 0, f"Blender died ({r.returncode}) after the check passed: {last}"
    counts = json.loads(next(ln for ln in reversed(r.stdout.splitlines())  # Blender may
                             if ln.startswith("{")))  # print after it
    assert counts["refused"] > 0 and counts["loaded"] > 0, counts
