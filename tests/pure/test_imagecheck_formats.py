# SPDX-License-Identifier: GPL-3.0-or-later
"""hazy_gloss.imagecheck.check_image_file beyond the fuzzing (test_fuzz_readers.py): the JPEG
check, the PNG CRC rule (critical chunks only), deep OpenEXR refused, the texel bound of an EXR
data window.  Every file is built here from the format's specification (ITU T.81 for JPEG, the
PNG spec, the OpenEXR file layout), not from the checker's code; the Blender-written files are
in tests/blender/test_imagecheck.py."""
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
