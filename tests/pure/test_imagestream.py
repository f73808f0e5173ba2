# SPDX-License-Identifier: GPL-3.0-or-later
"""The strip writer (through OpenImageIO), the strip pipeline and the conversion's progress
(bpy-free).

The PNG writer is checked against a PNG decoder written here from the specification (zlib,
then the five row filters undone one byte at a time), the EXR writer against OpenImageIO's
reader and the pure-python EXR writer of fuzz_files; Blender reads the same files in
tests/blender."""
import struct
import zlib

import numpy as np
import pytest

import fuzz_files as F
from hazy_gloss.conversion import convert as C
from hazy_gloss.conversion import imagecheck
from hazy_gloss.conversion import imagestream as S
from hazy_gloss.conversion.oiio import openimageio


def _png_decode(path):
    """(H, W, 3) uint16 of a 16-bit RGB PNG: the specification's unfiltering, byte by byte."""
    data = open(path, "rb").read()
    pos, idat, w, h = 8, b"", None, None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        assert zlib.crc32(kind + body) == struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])[0]
        if kind == b"IHDR":
            w, h, depth, colour = struct.unpack(">IIBB", body[:10])
            assert (depth, colour) == (16, 2)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = zlib.decompress(idat)  # checks the zlib stream and its Adler-32
    stride, bpp = w * 6, 6
    out, prev = [], bytearray(stride)
    for r in range(h):
        f, line = raw[r * (stride + 1)], bytearray(raw[r * (stride + 1) + 1:(r + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out.append(np.frombuffer(bytes(line), ">u2").reshape(w, 3))
        prev = line
    return np.stack(out)


def _write_strips(path, values, fmt="OPEN_EXR", codec="ZIP", channels=3, rows=16):
    h, w = values.shape[:2]
    wr = S.OiioStripWriter(openimageio(), str(path), w, h, fmt, codec, channels)
    encoded = [wr.encode(y0, values[y0:y0 + rows]) for y0 in range(0, h, rows)]
    for e in encoded:  # encoded in any order on the pool, appended in order
        wr.append(e)
    wr.close()
    return wr


@pytest.mark.parametrize("codec", ["NONE", "ZIP", "PIZ", "RLE"])
@pytest.mark.parametrize("channels", [1, 3])
def test_exr_writer_round_trip(tmp_path, codec, channels):
    rng = np.random.default_rng(3)
    h, w = 53, 37
    v = rng.standard_normal((h, w, 3)).astype(np.float32) * 100
    v[0, 0] = [np.inf, -0.0, 1e-42]
    v[5:9] = 0.25  # rows that compress, beside rows that do not
    values = v if channels == 3 else v[..., 0]
    p = tmp_path / "m.exr"
    wr = _write_strips(p, values, codec=codec, channels=channels)
    wr.verify()
    assert imagecheck.check_image_file(str(p)) == ("OPEN_EXR", w, h)
    got = imagecheck.read_exr(str(p))  # bottom row first
    want = values if values.ndim == 3 else values[..., None]
    assert len(got) == channels
    names = sorted(got) if channels == 1 else ["R", "G", "B"]
    for i, c in enumerate(names):
        assert np.array_equal(got[c][::-1].view(np.uint32), want[..., i].view(np.uint32)), c
    # the same values through the pure-python writer read the same: the file is a plain EXR
    ref, _ = F.encode_exr([{"channels": {n: np.ascontiguousarray(want[::-1, :, i])
                                         for i, n in enumerate(names)}, "compression": "ZIP"}])
    (tmp_path / "ref.exr").write_bytes(ref)
    again = imagecheck.read_exr(str(tmp_path / "ref.exr"))
    assert all(np.array_equal(again[n].view(np.uint32), got[n].view(np.uint32)) for n in names)


def test_png_writer_round_trip(tmp_path):
    rng = np.random.default_rng(4)
    h, w = 41, 23
    v = rng.uniform(-0.1, 1.1, (h, w, 3)).astype(np.float32)
    v[:, :5] = 0.5  # runs the filters predict exactly
    p = tmp_path / "m.png"
    _write_strips(p, v, fmt="PNG", rows=7).verify()
    codes = np.floor(np.clip(v, 0, 1) * 65535 + 0.5).astype(np.uint16)
    assert np.array_equal(_png_decode(str(p)), codes)


def test_rewriting_gives_the_same_bytes(tmp_path):
    """No date or counter in the files: the same values give byte-identical files."""
    v = np.random.default_rng(6).random((40, 30, 3), dtype=np.float32)
    for fmt, ext in (("OPEN_EXR", "exr"), ("PNG", "png")):
        _write_strips(tmp_path / f"a.{ext}", v, fmt=fmt)
        _write_strips(tmp_path / f"b.{ext}", v, fmt=fmt, rows=8)
        assert (tmp_path / f"a.{ext}").read_bytes() == (tmp_path / f"b.{ext}").read_bytes(), fmt


def test_verify_catches_a_changed_or_cut_file(tmp_path):
    v = np.linspace(0, 1, 8 * 20, dtype=np.float32).reshape(20, 8)
    for fmt, ext, codec in (("OPEN_EXR", "exr", "NONE"), ("OPEN_EXR", "exr", "ZIP"),
                            ("PNG", "png", None)):
        p = tmp_path / f"m.{ext}"
        wr = _write_strips(p, v, fmt=fmt, codec=codec or "ZIP")
        wr.verify()
        data = p.read_bytes()
        bad = bytearray(data)
        bad[len(data) - 30] ^= 0x40  # in the last rows' data
        p.write_bytes(bytes(bad))
        with pytest.raises(S.StripError, match=r"m\.(exr|png)"):
            wr.verify()
        p.write_bytes(data[:-20])
        with pytest.raises(S.StripError, match=r"m\.(exr|png)"):
            wr.verify()


def test_lossy_codec_is_verified_as_finite_values(tmp_path):
    v = np.random.default_rng(2).random((64, 64, 3), dtype=np.float32)
    wr = _write_strips(tmp_path / "d.exr", v, codec="DWAB")
    assert not wr.exact
    wr.verify()  # values differ from those written; all finite
    got = imagecheck.read_exr(str(tmp_path / "d.exr"))
    assert not np.array_equal(got["R"][::-1], v[..., 0])


def test_run_strips_keeps_order_and_bounds_the_strips_in_flight():
    out, live, peak = [], [0], [0]

    def read(y0, y1):
        live[0] += 1
        peak[0] = max(peak[0], live[0])
        return (y0, y1)

    def compute(y0, y1, data):
        return sum(range(y0, y1))

    def write(y0, y1, result):
        live[0] -= 1
        out.append((y0, result))

    steps = list(S.run_strips(1000, 7, read, compute, write, workers=2))
    assert [y for y, _ in out] == list(range(0, 1000, 7))
    assert [r for _, r in out] == [sum(range(y, min(1000, y + 7))) for y in range(0, 1000, 7)]
    assert steps[-1] == (1000, 1000) and peak[0] <= 3


def test_progress_status_eta_and_cancel():
    t = [0.0]
    p = C.Progress(clock=lambda: t[0])
    p.begin(200)
    t[0] = 10.0
    p.advance(50, "mapping and writing")
    assert p.fraction == 0.25 and p.seconds_left() == pytest.approx(30.0)
    assert p.status() == "mapping and writing 25%, 30 s left"
    p.next_item(1, 4, "Wood")  # a batch: set 2 of 4 at 0 %
    assert p.fraction == 0.25 and p.status().startswith("set Wood (2 of 4): ")
    p.next_item(1, 2, 1002, key="tile")  # its second UDIM tile, half done
    p.begin(10)
    p.advance(5, "mapping and writing")
    assert p.fraction == pytest.approx((1 + (1 + 0.5) / 2) / 4)
    assert p.status().startswith("set Wood (2 of 4), tile 1002 (2 of 2): mapping and writing 44%")
    assert C.progress_bar(p, width=8).startswith("[####----] ")
    p.cancel()
    with pytest.raises(C.ConversionCancelled):
        p.advance(1)
    assert C.format_seconds(3725) == "1 h 02 min" and C.format_seconds(65) == "1 min 05 s"


def test_udim_sets_in_a_folder():
    names = ["a_BaseColor.1001.png", "a_BaseColor.1002.png", "a_Rough_1001.exr",
             "a_Rough_1011.exr", "a_Normal.png", "scan.0999.png", "a_Metal.2001.png"]
    assert C.udim_sets(names) == ["a_BaseColor.<UDIM>.png", "a_Rough_<UDIM>.exr", "a_Normal.png",
                                  "scan.0999.png", "a_Metal.2001.png"]
    assert C.detect_pbr_set(names[:4])["roughness"] == "a_Rough_<UDIM>.exr"
