# SPDX-License-Identifier: GPL-3.0-or-later
"""The strip writers, the strip pipeline and the conversion's progress (bpy-free, issue 22).

The EXR writer is checked against the add-on's fuzzed EXR reader and the PNG writer against a
PNG decoder written here from the specification (zlib, then the five row filters undone one
byte at a time); Blender and OpenImageIO read the same files in tests/blender."""
import struct
import zlib

import numpy as np
import pytest

from hazy_gloss import convert as C
from hazy_gloss import exr, imagecheck
from hazy_gloss import imagestream as S


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


@pytest.mark.parametrize("codec", ["NONE", "ZIPS", "ZIP"])
@pytest.mark.parametrize("channels", [1, 3])
def test_exr_writer_round_trip(tmp_path, codec, channels):
    rng = np.random.default_rng(3)
    h, w = 53, 37
    v = rng.standard_normal((h, w, 3)).astype(np.float32) * 100
    v[0, 0] = [np.inf, -0.0, 1e-42]
    v[5:9] = 0.25  # rows that compress, beside rows that do not
    values = v if channels == 3 else v[..., 0]
    p = tmp_path / "m.exr"
    wr = S.ExrStripWriter(str(p), w, h, codec=codec)
    for y0 in range(0, h, 16):
        wr.append(wr.encode(y0, values[y0:y0 + 16]))
    wr.close()
    wr.verify(imagecheck.check_image_file)
    got = exr.read_exr(str(p))  # bottom row first
    want = values if values.ndim == 3 else np.repeat(values[..., None], 3, axis=-1)
    for i, c in enumerate("RGB"):
        assert np.array_equal(got[c][::-1].view(np.uint32), want[..., i].view(np.uint32)), c


def test_png_writer_round_trip_and_parallel_strips(tmp_path):
    rng = np.random.default_rng(4)
    h, w = 41, 23
    v = rng.uniform(-0.1, 1.1, (h, w, 3)).astype(np.float32)
    v[:, :5] = 0.5  # runs the filters predict exactly
    p = tmp_path / "m.png"
    wr = S.PngStripWriter(str(p), w, h)
    encoded = [wr.encode(y0, v[y0:y0 + 7]) for y0 in range(0, h, 7)][::-1]  # any order...
    for e in encoded[::-1]:  # ...appended in order
        wr.append(e)
    wr.close()
    wr.verify(imagecheck.check_image_file)
    codes = np.floor(np.clip(v, 0, 1) * 65535 + 0.5).astype(np.uint16)
    assert np.array_equal(_png_decode(str(p)), codes)


def test_verify_catches_a_changed_or_cut_file(tmp_path):
    p = tmp_path / "m.exr"
    wr = S.ExrStripWriter(str(p), 8, 20, codec="ZIP")
    for y0 in (0, 16):
        wr.append(wr.encode(y0, np.linspace(0, 1, 8 * min(16, 20 - y0), dtype=np.float32)
                            .reshape(-1, 8)))
    wr.close()
    wr.verify()
    data = bytearray(p.read_bytes())
    for at in (20, len(data) - 3):  # in the header, in the last chunk
        bad = bytearray(data)
        bad[at] ^= 1
        p.write_bytes(bytes(bad))
        with pytest.raises(S.StripError, match="read back differently"):
            wr.verify()
    p.write_bytes(bytes(data[:-1]))
    with pytest.raises(S.StripError, match="were written"):
        wr.verify()


def test_adler32_combine():
    rng = np.random.default_rng(5)
    for _ in range(50):
        a = rng.integers(0, 256, rng.integers(0, 3000), dtype=np.uint8).tobytes()
        b = rng.integers(0, 256, rng.integers(0, 70000), dtype=np.uint8).tobytes()
        assert S._adler32_combine(zlib.adler32(a), zlib.adler32(b), len(b)) == zlib.adler32(a + b)


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
