# SPDX-License-Identifier: GPL-3.0-or-later
"""hazy_gloss.conversion.imagecheck.check_image_file beyond the fuzzing (test_fuzz_readers.py): JPEG cut or
damaged, the PNG CRC rule (critical chunks only), deep OpenEXR refused, the texel bound of a
header, crafted files, a file cut short while it is read.  Files are built here from the
formats' specifications (the PNG spec, the OpenEXR file layout) or written by OpenImageIO
(JPEG, which the check now decodes); the Blender-written files are in
tests/blender/test_imagecheck.py."""
import re
import struct
import zlib

import numpy as np
import pytest

import fuzz_files as F
from hazy_gloss.conversion import imagecheck
from hazy_gloss.conversion.oiio import openimageio


def _write(path, data):
    path.write_bytes(data)
    return str(path)


# -- JPEG -----------------------------------------------------------------------------------

def _segment(marker, payload):
    """A marker segment: FF, marker, 2-byte length (itself included), payload (ITU T.81 B.1)."""
    return bytes([0xFF, marker]) + struct.pack(">H", len(payload) + 2) + payload


def _jpeg(path, w=33, h=17):
    """A real JPEG of noise (written by OpenImageIO), its bytes."""
    oiio = openimageio()
    px = np.random.default_rng(7).integers(0, 256, (h, w, 3)).astype(np.uint8)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(w, h, 3, oiio.UINT8))
    assert out.write_image(px)
    out.close()
    return path.read_bytes()


def test_jpeg_whole_files_pass_with_their_size(tmp_path):
    data = _jpeg(tmp_path / "a.jpg")
    assert imagecheck.check_image_file(str(tmp_path / "a.jpg")) == ("JPEG", 33, 17)
    # data after the end of the image, and a name that does not say JPEG (Blender reads by
    # contents)
    assert imagecheck.check_image_file(_write(tmp_path / "j.png", data + bytes(100))) == \
        ("JPEG", 33, 17)


def test_jpeg_every_cut_is_refused(tmp_path):
    """Blender fills a cut-off JPEG with grey without an error; libjpeg says "premature end",
    which the check turns into one line."""
    data = _jpeg(tmp_path / "a.jpg")
    p = tmp_path / "cut.jpg"
    for n in range(1, len(data) - 1, 7):
        p.write_bytes(data[:n])
        with pytest.raises(imagecheck.ImageFileError, match=r"cut\.jpg is (a damaged JPEG|not an "
                                                            r"image file)") as info:
            imagecheck.check_image_file(str(p))
        assert "\n" not in str(info.value)


@pytest.mark.parametrize("case", ["no eoi", "eoi before scan", "no frame", "zero height",
                                  "garbage in the header", "length past the end"])
def test_jpeg_damage_is_named(tmp_path, case):
    whole = _jpeg(tmp_path / "a.jpg")
    sos, sof = whole.index(b"\xff\xda"), whole.index(b"\xff\xc0")
    sof_end = sof + 2 + struct.unpack_from(">H", whole, sof + 2)[0]
    data = {
        "no eoi": whole[:-2],
        "eoi before scan": whole[:sos] + b"\xff\xd9",
        "no frame": whole[:sof] + whole[sof_end:],
        "zero height": whole[:sof + 5] + b"\0\0" + whole[sof + 7:],
        "garbage in the header": whole[:2] + b"\x00" * 8 + whole[2:],
        "length past the end": whole[:2] + b"\xff\xe1\xff\xf0" + bytes(20),
    }[case]
    with pytest.raises(imagecheck.ImageFileError, match=r"d\.jpg is (a damaged JPEG file|not an "
                                                        r"image file Blender reads)") as info:
        imagecheck.check_image_file(_write(tmp_path / "d.jpg", data))
    assert "\n" not in str(info.value)


# -- PNG: critical CRCs only ----------------------------------------------------------------

def _chunks(png):
    """[(type, start, end)] of a PNG's chunks (read here, by the spec's layout)."""
    out, pos = [], 8
    while pos < len(png):
        length, ctype = struct.unpack_from(">I4s", png, pos)
        out.append((ctype, pos, pos + 12 + length))
        pos += 12 + length
    return out


def test_png_bad_crc_of_an_ancillary_chunk_passes_of_a_critical_one_is_refused(tmp_path):
    png = F.encode_png(np.arange(7 * 9 * 3).reshape(7, 9, 3) % 256)
    ihdr_end = _chunks(png)[0][2]
    text = b"Comment\x00made elsewhere"
    bad_text = struct.pack(">I", len(text)) + b"tEXt" + text + b"\xde\xad\xbe\xef"
    third_party = png[:ihdr_end] + bad_text + png[ihdr_end:]
    assert imagecheck.check_image_file(_write(tmp_path / "t.png", third_party)) == ("PNG", 9, 7)
    kinds = set()
    for ctype, _, end in _chunks(png)[:-1]:  # IHDR, tEXt, IDAT (libpng stops before IEND)
        broken = bytearray(png)
        broken[end - 1] ^= 0x01
        path = _write(tmp_path / "c.png", bytes(broken))
        if ctype[:1].isupper():  # critical (the case of the first letter, PNG spec 5.4)
            kinds.add("critical")
            with pytest.raises(imagecheck.ImageFileError, match=rf"c\.png is (a damaged PNG|not "
                                                                rf"an image).*{ctype.decode()}: "
                                                                rf"CRC error"):
                imagecheck.check_image_file(path)
        else:
            kinds.add("ancillary")
            assert imagecheck.check_image_file(path) == ("PNG", 9, 7)
    assert kinds == {"critical", "ancillary"}


def test_png_image_data_too_small_for_its_size(tmp_path):
    """IHDR claims 40000 x 20000 RGB 8-bit (2.4 GB of filtered rows) over 1 KB of zlib data."""
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 40000, 20000, 8, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(bytes(1 << 20))) + chunk(b"IEND", b""))
    with pytest.raises(imagecheck.ImageFileError, match=r"big\.png is a damaged PNG file \(cut off "
                                                        r"or corrupt: its header claims "
                                                        r"40000x20000 pixels, which \d+ bytes "
                                                        r"cannot hold\)"):
        imagecheck.check_image_file(_write(tmp_path / "big.png", png))


# -- OpenEXR: deep data, the data window's texels per byte -----------------------------------

def _attr(name, typ, data):
    return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(data)) + data


def _deep_header(part_type, extra=b"", w=4, h=3):
    win = struct.pack("<4i", 0, 0, w - 1, h - 1)
    return (_attr("channels", "chlist", b"Z\0" + struct.pack("<iB3xii", 2, 0, 1, 1) + b"\0")
            + _attr("compression", "compression", b"\x00") + _attr("dataWindow", "box2i", win)
            + _attr("displayWindow", "box2i", win) + _attr("lineOrder", "lineOrder", b"\0")
            + _attr("pixelAspectRatio", "float", struct.pack("<f", 1))
            + _attr("screenWindowCenter", "v2f", struct.pack("<2f", 0, 0))
            + _attr("screenWindowWidth", "float", struct.pack("<f", 1))
            + _attr("type", "string", part_type.encode()) + _attr("version", "int", b"\1\0\0\0")
            + _attr("chunkCount", "int", struct.pack("<i", h))
            + _attr("maxSamplesPerPixel", "int", b"\1\0\0\0") + extra + b"\0")


def test_deep_exr_is_refused_as_a_file_blender_cannot_load(tmp_path):
    """Single-part deep scanline (version flag bit 11) and a multi-part file with a deep tiled
    part: the header is enough to refuse them (the chunks are not looked at)."""
    single = struct.pack("<ii", 20000630, 2 | 0x800) + _deep_header("deepscanline") + bytes(200)
    tiled = _attr("tiles", "tiledesc", struct.pack("<IIB", 4, 4, 0)) + _attr("name", "string", b"d")
    multi = struct.pack("<ii", 20000630, 2 | 0x1000) + _deep_header("deeptile", tiled) + b"\0" \
        + bytes(200)  # the empty header ends the list of headers
    for name, data in (("single.exr", single), ("multi.exr", multi)):
        with pytest.raises(imagecheck.ImageFileError,
                           match=rf"{name} is an OpenEXR file Blender cannot load \(part 0 "
                                 r"holds deep data"):
            imagecheck.check_image_file(_write(tmp_path / name, data))


def test_exr_data_window_larger_than_the_file_can_hold(tmp_path):
    """A 32x32 ZIP file (a few hundred bytes) whose data window says 2^20 x 2^9: refused by the
    bound on what its bytes can hold, before a pixel is read."""
    data, layout = F.encode_exr([{"channels": {"R": np.zeros((32, 32), np.float32)},
                                  "compression": "ZIP"}])
    at = data.index(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
    wide = data[:at] + struct.pack("<4i", 0, 0, (1 << 20) - 1, 511) + data[at + 16:]
    with pytest.raises(imagecheck.ImageFileError,
                       match=r"w\.exr is a damaged OpenEXR file \(cut off or corrupt: its header "
                             r"claims 1048576x512 pixels, which \d+ bytes cannot hold\)"):
        imagecheck.check_image_file(_write(tmp_path / "w.exr", wide))


# -- crafted files: an answer, never a crash ---------------------------------------------------


def _png_chunk(ctype, payload=b""):
    return (struct.pack(">I", len(payload)) + ctype + payload
            + struct.pack(">I", zlib.crc32(ctype + payload)))


def test_png_with_a_million_ancillary_chunks_is_answered(tmp_path):
    """2^20 + 1 empty ancillary chunks before a 1x1 image (12 MB): libpng walks them (keeping at
    most its chunk cache's worth); the check answers: a valid image, or one line."""
    n = 1 << 20
    png = (b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 0, 0, 0, 0))
           + _png_chunk(b"tEXt") * n + _png_chunk(b"IDAT", zlib.compress(b"\x00\x00"))
           + _png_chunk(b"IEND"))
    path = _write(tmp_path / "many.png", png)
    try:
        assert imagecheck.check_image_file(path) == ("PNG", 1, 1)
    except imagecheck.ImageFileError as exc:
        assert str(exc).startswith(f"{path} is a damaged PNG file") and "\n" not in str(exc)


def test_jpeg_with_millions_of_fill_bytes_is_answered(tmp_path):
    """T.81 B.1.1.2 allows any number of FF fill bytes before a marker: 2^21 of them after SOI."""
    whole = _jpeg(tmp_path / "a.jpg")
    jpeg = b"\xff\xd8" + b"\xff" * (1 << 21) + whole[2:]
    path = _write(tmp_path / "fill.jpg", jpeg)
    try:
        assert imagecheck.check_image_file(path) == ("JPEG", 33, 17)
    except imagecheck.ImageFileError as exc:
        assert str(exc).startswith(f"{path} is") and "\n" not in str(exc)


# -- a file cut short while it is read ------------------------------------------------------

def _valid_files(tmp_path):
    """{name: path} of a valid PNG, JPEG, scanline (two-part) and tiled OpenEXR."""
    rng = np.random.default_rng(3)
    exr, _ = F.encode_exr([{"channels": {"R": rng.random((40, 30), np.float32)}, "name": "a"},
                           {"channels": {"G": rng.random((40, 30), np.float32)}, "name": "b",
                            "compression": "RLE"}])
    tiled = F.encode_tiled_exr({"Y": rng.random((20, 24), np.float32)}, levels="MIPMAP")
    files = {"a.png": F.encode_png(rng.integers(0, 256, (50, 40, 3)), idat_parts=3),
             "a.exr": exr, "t.exr": tiled}
    out = {name: _write(tmp_path / name, data) for name, data in files.items()}
    _jpeg(tmp_path / "a.jpg")
    out["a.jpg"] = str(tmp_path / "a.jpg")
    return out


def test_valid_files_pass_with_their_size(tmp_path):
    found = {name: imagecheck.check_image_file(path)
             for name, path in _valid_files(tmp_path).items()}
    assert found == {"a.png": ("PNG", 40, 50), "a.jpg": ("JPEG", 33, 17),
                     "a.exr": ("OPEN_EXR", 30, 40), "t.exr": ("OPEN_EXR", 24, 20)}


#: Runs check_image_file(argv[1]) with the file cut to argv[2] bytes right after OpenImageIO
#: opened it (it has read the header and taken the file's length).
_CUT_WHILE_CHECKED = """
import os, sys
from hazy_gloss.conversion import imagecheck, oiio
path, keep = sys.argv[1], int(sys.argv[2])
real = oiio.open_input
def open_then_cut(*args):
    opened = real(*args)
    os.truncate(path, keep)
    return opened
imagecheck.open_input = open_then_cut
try:
    imagecheck.check_image_file(path)
except imagecheck.ImageFileError as exc:
    print("ImageFileError:", exc)
else:
    print("passed")
"""


@pytest.mark.parametrize("name", ["cut.png", "cut.jpg", "cut.exr"])
def test_a_file_cut_short_while_it_is_checked_is_refused_not_a_crash(tmp_path, name):
    """Another process truncates the file after the check opened it: a reader that had mapped
    it would die of SIGBUS on the next page past the new end; the check says "damaged" in one
    line."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    rng = np.random.default_rng(5)
    if name.endswith(".png"):  # ~1 MB of incompressible pixels in 4 IDATs
        data = F.encode_png(rng.integers(0, 256, (600, 600, 3)), idat_parts=4)
        path = _write(tmp_path / name, data)
    elif name.endswith(".jpg"):  # noise: ~1 MB
        data = _jpeg(tmp_path / name, 900, 600)
        path = str(tmp_path / name)
    else:  # 1.5 MB, uncompressed: chunk headers all through the file
        data, _ = F.encode_exr([{"channels": {c: rng.random((512, 256), np.float32)
                                              for c in "BGR"}, "compression": "NONE"}])
        path = _write(tmp_path / name, data)
    keep = len(data) // 3 & ~0xFFFF  # on a page boundary: the next page is wholly gone
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-c", _CUT_WHILE_CHECKED, path, str(keep)],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path,
                         env=dict(os.environ, PYTHONPATH=str(root), PYTHONDONTWRITEBYTECODE="1"))
    assert run.returncode == 0, f"the check died with {run.returncode}: {run.stderr[-500:]}"
    assert os.path.getsize(path) == keep  # the cut happened during the check
    out = run.stdout.strip()
    assert out.startswith(f"ImageFileError: {path} is a damaged ") and "\n" not in out, out
    assert re.search(r"is a damaged (PNG|JPEG|OpenEXR) file \(cut off or corrupt: ", out), out
