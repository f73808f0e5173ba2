# SPDX-License-Identifier: GPL-3.0-or-later
"""hazy_gloss.imagecheck.check_image_file beyond the fuzzing (test_fuzz_readers.py): the JPEG
check, the PNG CRC rule (critical chunks only), deep OpenEXR refused, the texel bound of an EXR
data window.  Every file is built here from the format's specification (ITU T.81 for JPEG, the
PNG spec, the OpenEXR file layout), not from the checker's code; the Blender-written files are
in tests/blender/test_imagecheck.py."""
import re
import struct
import time
import zlib

import numpy as np
import pytest

import fuzz_files as F
from hazy_gloss import imagecheck


def _write(path, data):
    path.write_bytes(data)
    return str(path)


# -- JPEG (ITU T.81, annex B) ---------------------------------------------------------------

def _segment(marker, payload):
    """A marker segment: FF, marker, 2-byte length (itself included), payload."""
    return bytes([0xFF, marker]) + struct.pack(">H", len(payload) + 2) + payload


def _jpeg(w=16, h=8, *, sof=0xC0, scans=1, eoi=True, data=b"\x12\x34\xff\x00\x56" * 20):
    """Baseline-shaped JPEG: SOI, APP0 (JFIF), DQT, SOFn, DHT, then ``scans`` x (SOS, entropy
    data with a stuffed FF 00 and a restart marker), EOI.  Structure only: the entropy data is
    not a decodable image (the check does not decode)."""
    out = b"\xff\xd8"
    out += _segment(0xE0, b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00")
    out += _segment(0xDB, b"\x00" + bytes(range(1, 65)))
    out += _segment(sof, struct.pack(">BHHB", 8, h, w, 1) + b"\x01\x11\x00")
    out += _segment(0xC4, b"\x00" + bytes([1] + [0] * 15) + b"\x00")
    for _ in range(scans):
        out += _segment(0xDA, b"\x01\x01\x00\x00\x3f\x00") + data + b"\xff\xd0" + data
    return out + (b"\xff\xd9" if eoi else b"")


def test_jpeg_whole_files_pass_with_their_size(tmp_path):
    assert imagecheck.check_image_file(_write(tmp_path / "a.jpg", _jpeg(33, 17))) == \
        ("JPEG", 33, 17)
    # progressive (SOF2, several scans), fill bytes before a marker, data after EOI
    prog = _jpeg(5, 300, sof=0xC2, scans=3).replace(b"\xff\xdb", b"\xff\xff\xff\xdb", 1)
    assert imagecheck.check_image_file(_write(tmp_path / "p.jpg", prog + bytes(100))) == \
        ("JPEG", 5, 300)
    # the name does not decide the format (Blender reads by contents)
    assert imagecheck.check_image_file(_write(tmp_path / "j.png", _jpeg())).format == "JPEG"


def test_jpeg_every_cut_is_refused(tmp_path):
    data = _jpeg()
    p = tmp_path / "cut.jpg"
    for n in range(1, len(data) - 1):  # the last byte of EOI: the marker FF D9 is cut
        p.write_bytes(data[:n])
        with pytest.raises(imagecheck.ImageFileError, match=r"cut\.jpg is a truncated "
                                                            r"(JPEG|or corrupt JPEG)"):
            imagecheck.check_image_file(str(p))


@pytest.mark.parametrize("case, pattern", [
    ("no eoi", r"truncated JPEG \(no end-of-image marker"),
    ("eoi before scan", r"corrupt JPEG \(it ends before its image data"),
    ("no frame", r"corrupt JPEG \(no frame header"),
    ("zero height", r"corrupt JPEG \(frame header: 16x0"),
    ("huge", r"corrupt JPEG \(frame header: 65535x65535"),
    ("garbage between segments", r"corrupt JPEG \(no marker at byte"),
    ("length past the end", r"truncated JPEG \(segment at byte \d+ needs"),
    ("length 1", r"corrupt JPEG \(segment at byte \d+ has length 1"),
])
def test_jpeg_damage_is_named(tmp_path, case, pattern):
    whole = _jpeg()
    sos, sof = whole.index(b"\xff\xda"), whole.index(b"\xff\xc0")
    sof_end = sof + 2 + struct.unpack_from(">H", whole, sof + 2)[0]
    data = {
        "no eoi": _jpeg(eoi=False),
        "eoi before scan": whole[:sos] + b"\xff\xd9",
        "no frame": whole[:sof] + whole[sof_end:],
        "zero height": _jpeg(16, 0),
        "huge": _jpeg(65535, 65535),
        "garbage between segments": whole[:20] + b"\x00" + whole[20:],  # after APP0
        "length past the end": whole[:2] + b"\xff\xe1\xff\xf0" + bytes(20),
        "length 1": whole[:2] + b"\xff\xe1\x00\x01" + whole[2:],
    }[case]
    with pytest.raises(imagecheck.ImageFileError, match=pattern):
        imagecheck.check_image_file(_write(tmp_path / "d.jpg", data))


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
    for ctype, _, end in _chunks(png):  # IHDR, tEXt, IDAT, IEND
        broken = bytearray(png)
        broken[end - 1] ^= 0x01
        path = _write(tmp_path / "c.png", bytes(broken))
        if ctype[:1].isupper():  # critical (the case of the first letter, PNG spec 5.4)
            kinds.add("critical")
            with pytest.raises(imagecheck.ImageFileError, match=rf"corrupt PNG \(CRC mismatch "
                                                                rf"in chunk {ctype.decode()}"):
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
    with pytest.raises(imagecheck.ImageFileError, match="cannot hold 40000x20000"):
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
    texels-per-byte bound, before the offset table is looked at."""
    data, layout = F.encode_exr([{"channels": {"R": np.zeros((32, 32), np.float32)},
                                  "compression": "ZIP"}])
    at = data.index(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
    wide = data[:at] + struct.pack("<4i", 0, 0, (1 << 20) - 1, 511) + data[at + 16:]
    with pytest.raises(imagecheck.ImageFileError,
                       match=rf"w\.exr is a corrupt OpenEXR file \(part 0: data window "
                             rf"1048576x512 in {len(wide)} bytes\)"):
        imagecheck.check_image_file(_write(tmp_path / "w.exr", wide))


# -- crafted files: the check's time is bounded --------------------------------------------


def _png_chunk(ctype, payload=b""):
    return (struct.pack(">I", len(payload)) + ctype + payload
            + struct.pack(">I", zlib.crc32(ctype + payload)))


def test_png_with_more_chunks_than_the_limit_is_refused_quickly(tmp_path):
    """2^20 + 1 empty ancillary chunks (12 MB; no image is stored so): refused by count, in
    about a second, not walked to the end."""
    n = 1 << 20
    png = (b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 0, 0, 0, 0))
           + _png_chunk(b"tEXt") * n + _png_chunk(b"IDAT", zlib.compress(b"\x00\x00"))
           + _png_chunk(b"IEND"))
    path = _write(tmp_path / "many.png", png)
    t0 = time.perf_counter()
    with pytest.raises(imagecheck.ImageFileError, match=r"many\.png is a corrupt PNG \(more than "
                                                        r"1048576 chunks\)"):
        imagecheck.check_image_file(path)
    assert time.perf_counter() - t0 < 10.0


def test_jpeg_with_millions_of_fill_bytes_is_refused_quickly(tmp_path):
    """T.81 B.1.1.2 allows any number of FF fill bytes before a marker: 2^21 of them after SOI
    are refused by count, not walked byte by byte to the end."""
    jpeg = b"\xff\xd8" + b"\xff" * (1 << 21) + _jpeg()[2:]
    path = _write(tmp_path / "fill.jpg", jpeg)
    t0 = time.perf_counter()
    with pytest.raises(imagecheck.ImageFileError, match=r"fill\.jpg is a corrupt JPEG \(more "
                                                        r"than 1048576 markers"):
        imagecheck.check_image_file(path)
    assert time.perf_counter() - t0 < 10.0


# -- the file is read, never memory-mapped (a mapped file cut short raises SIGBUS) ----------

def _valid_files(tmp_path):
    """{name: path} of a valid PNG, JPEG, scanline (two-part) and tiled OpenEXR."""
    rng = np.random.default_rng(3)
    exr, _ = F.encode_exr([{"channels": {"R": rng.random((40, 30), np.float32)}, "name": "a"},
                           {"channels": {"G": rng.random((9, 7), np.float32)}, "name": "b",
                            "compression": "RLE"}])
    tiled = F.encode_tiled_exr({"Y": rng.random((20, 24), np.float32)}, levels="MIPMAP")
    files = {"a.png": F.encode_png(rng.integers(0, 256, (50, 40, 3)), idat_parts=3),
             "a.jpg": _jpeg(33, 17), "a.exr": exr, "t.exr": tiled}
    return {name: _write(tmp_path / name, data) for name, data in files.items()}


def test_the_checker_never_memory_maps_the_file(tmp_path, monkeypatch):
    import mmap

    def refuse(*args, **kwargs):
        raise AssertionError("check_image_file memory-mapped a file")

    monkeypatch.setattr(mmap, "mmap", refuse)
    found = {name: imagecheck.check_image_file(path)
             for name, path in _valid_files(tmp_path).items()}
    assert found == {"a.png": ("PNG", 40, 50), "a.jpg": ("JPEG", 33, 17),
                     "a.exr": ("OPEN_EXR", 30, 40), "t.exr": ("OPEN_EXR", 24, 20)}


#: Runs check_image_file(argv[1]) with the file cut to argv[2] bytes at the checker's first
#: header field (struct.unpack_from): after it opened the file and took its length.
_CUT_WHILE_CHECKED = """
import os, struct, sys
from hazy_gloss import imagecheck
path, keep = sys.argv[1], int(sys.argv[2])
real = struct.unpack_from
def cut_then_unpack(*args):
    if os.path.getsize(path) > keep:
        os.truncate(path, keep)
    return real(*args)
struct.unpack_from = cut_then_unpack
try:
    imagecheck.check_image_file(path)
except imagecheck.ImageFileError as exc:
    print("ImageFileError:", exc)
else:
    print("passed")
"""


@pytest.mark.parametrize("name, pattern", [
    ("cut.png", r"is a truncated PNG \(the file was cut off while it was read: bytes \d+\.\.\d+ "),
    ("cut.jpg", r"is a truncated JPEG \(the file was cut off while it was read: bytes \d+\.\.\d+ "),
    ("cut.exr", r"is a truncated OpenEXR file \(the file was cut off while it was read: bytes "),
])
def test_a_file_cut_short_while_it_is_checked_is_refused_not_a_crash(tmp_path, name, pattern):
    """Another process truncates the file after the checker opened it.  A memory-mapped file
    then raises SIGBUS on the next touch of a page past the new end, killing the process (the
    old checker: the child dies with -7); the reads here say "truncated" in one line."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    rng = np.random.default_rng(5)
    if name.endswith(".png"):  # ~1 MB of incompressible pixels in 4 IDATs
        data = F.encode_png(rng.integers(0, 256, (600, 600, 3)), idat_parts=4)
    elif name.endswith(".jpg"):  # 1 MB of entropy-coded data (no FF) before EOI
        data = _jpeg(data=rng.integers(0, 255, 1 << 20, np.uint8).tobytes())
    else:  # 1.5 MB, uncompressed: chunk headers all through the file
        data, _ = F.encode_exr([{"channels": {c: rng.random((512, 256), np.float32)
                                              for c in "BGR"}, "compression": "NONE"}])
    path = _write(tmp_path / name, data)
    keep = len(data) // 3 & ~0xFFFF  # on a page boundary: the next page is wholly gone
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-c", _CUT_WHILE_CHECKED, path, str(keep)],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path,
                         env=dict(os.environ, PYTHONPATH=str(root), PYTHONDONTWRITEBYTECODE="1"))
    assert run.returncode == 0, f"the check died with {run.returncode}: {run.stderr[-500:]}"
    assert os.path.getsize(path) == keep  # the cut happened during the check
    out = run.stdout.strip()
    assert out.startswith(f"ImageFileError: {path} ") and "\n" not in out, out
    assert re.search(pattern, out), out


def test_file_bytes_reads_like_bytes_and_refuses_a_range_cut_off(tmp_path, monkeypatch):
    """FileBytes (tiny windows and pieces, so every boundary is crossed) gives what ``bytes``
    gives over a real file and over BytesIO; after the file is cut short, a range that is
    gone raises FileShrankError instead of short data, a range still there reads."""
    import io
    import os
    import random

    from hazy_gloss import filebytes

    monkeypatch.setattr(filebytes, "WINDOW", 7)
    monkeypatch.setattr(filebytes, "JUMP", 3)
    monkeypatch.setattr(filebytes, "PIECE", 5)
    rnd = random.Random(1)
    data = bytes(rnd.choice(b"ab\xff\xd9") for _ in range(300))
    path = _write(tmp_path / "b.bin", data)
    with open(path, "rb") as fh:
        for fb in (filebytes.FileBytes(fh), filebytes.FileBytes(io.BytesIO(data))):
            assert len(fb) == len(data)
            for _ in range(400):
                a, b = rnd.randrange(-5, 310), rnd.randrange(-5, 310)
                sub = bytes(rnd.choice(b"ab\xff\xd9") for _ in range(rnd.randrange(1, 4)))
                assert fb[a:b] == data[a:b]
                assert fb.find(sub, a, b) == data.find(sub, a, b)
                assert fb.find(sub, a) == data.find(sub, a)
                if 0 <= a < len(data):
                    assert fb[a] == data[a]
                    if a + 2 <= len(data):
                        assert fb.unpack_from(">H", a) == struct.unpack_from(">H", data, a)
                    else:
                        with pytest.raises(struct.error):
                            fb.unpack_from(">H", a)
                if 0 <= a <= b <= len(data):
                    assert fb.crc32(a, b) == zlib.crc32(data[a:b])
    with open(path, "rb") as fh:
        fb = filebytes.FileBytes(fh)
        assert fb[0:4] == data[:4]
        os.truncate(path, 100)
        assert fb[90:100] == data[90:100]
        for read in (lambda: fb[95:105], lambda: fb[200], lambda: fb.unpack_from("<I", 98),
                     lambda: fb.find(b"\xff\xd9\xd9\xd9", 50), lambda: fb.crc32(0, 300)):
            with pytest.raises(filebytes.FileShrankError, match=r"the file was cut off while "
                                                                r"it was read: bytes \d+\.\.\d+ "
                                                                r"are gone, it had 300$"):
                read()
