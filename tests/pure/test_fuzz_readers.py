# SPDX-License-Identifier: GPL-3.0-or-later
"""Fuzz every file reader the add-on owns: hazy_gloss.exr.read_exr, exr_header_check (through
hazy_gloss.imagecheck.check_image_file), recomposite.passes_from_exr and check_image_file's PNG
check.

Valid files come from the pure-python writer in fuzz_files.py (NONE / RLE / ZIPS / ZIP, single
and multi-part, HALF / FLOAT / UINT; tests/blender/test_composite.py checks that Blender loads
them); every mutation is deterministic.  For each case and reader: the only exception is the
documented one (ExrError / ImageFileError, both ValueError; KeyError from passes_from_exr for a
well-formed file without the passes), it returns within 2 s, and its peak traced memory stays
under 64 MB.  The counts go to out/measurements/fuzz_readers.json (docs/verification.md).
"""
import json
import os
import struct
import tempfile
import time
import resource
import zlib
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import fuzz_files as F
from hazy_gloss import exr, imagecheck, recomposite

PEAK_LIMIT = 64 << 20
CASE_TIME = 2.0
OUT = Path(__file__).resolve().parents[2] / "out" / "measurements"


@pytest.fixture(scope="module")
def workdir():
    base = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None
    with tempfile.TemporaryDirectory(prefix="hg_fuzz_", dir=base) as d:
        yield Path(d)


def _max_rss():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux: KiB


def _write(path, data):
    with open(path, "wb") as fh:
        fh.write(data)
    return str(path)


def _record(name, data):
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"{name}.json").write_text(json.dumps(data, indent=1))


WORST = {"seconds": 0.0, "peak_mb": 0.0}


def _check(table, failures, path, attack, reader, outcome, detail, seconds, peak):
    WORST["seconds"] = max(WORST["seconds"], seconds)
    WORST["peak_mb"] = max(WORST["peak_mb"], peak / 2 ** 20)
    if outcome == "other exception":
        failures.append(f"{reader} / {attack}: {type(detail).__name__}: {detail}")
    elif outcome == "hang" or seconds > CASE_TIME:
        failures.append(f"{reader} / {attack}: took {seconds:.1f} s")
    elif peak > PEAK_LIMIT:
        failures.append(f"{reader} / {attack}: peak memory {peak / 2**20:.0f} MB")
    elif outcome == "rejected":
        msg = str(detail)
        if "\n" in msg or path not in msg:
            failures.append(f"{reader} / {attack}: not one line naming the file: {msg!r}")
    table[(reader, attack, outcome)] += 1


def test_writer_round_trip(workdir):
    """The fuzz bases are valid: read back exactly, accepted by the check, passes found."""
    for label, data, _, channels, recomp in F.base_files():
        path = _write(workdir / "base.exr", data)
        got = exr.read_exr(path)
        assert sorted(got) == sorted(channels), label
        for name, arr in channels.items():
            assert got[name].dtype == np.float32
            assert np.array_equal(got[name], arr.astype(np.float32)), (label, name)
        info = imagecheck.check_image_file(path)
        assert info.format == "OPEN_EXR"
        if recomp:
            passes = recomposite.passes_from_exr(path)
            assert passes["original"].shape == (6, 5, 4)


def test_fuzz_exr_readers(workdir):
    """Every mutation: documented exception or a result, within 2 s and 64 MB (read_exr's peak
    traced per case); whatever read_exr accepts the header check accepts too."""
    table, failures = Counter(), []
    path = str(workdir / "case.exr")
    rss0 = _max_rss()
    t0, c0 = time.perf_counter(), time.process_time()  # (CPU time: the budget, load aside)
    n = 0
    for attack, label, data, recomp in F.all_cases():
        n += 1
        _write(path, data)
        res = F.run_case(exr.read_exr, path, (exr.ExrError,), time_limit=CASE_TIME)
        _check(table, failures, path, attack, "read_exr", *res)
        chk = F.run_case(imagecheck.check_image_file, path, (imagecheck.ImageFileError,),
                         time_limit=CASE_TIME, trace=False)
        _check(table, failures, path, attack, "exr_header_check", *chk)
        if res[0] == "accepted":
            out = res[1]
            assert all(a.dtype == np.float32 and a.ndim == 2 for a in out.values()), attack
            if chk[0] != "accepted":
                failures.append(f"{attack}: read_exr accepted what the check refused: {chk[1]}")
        if recomp:
            rp = F.run_case(recomposite.passes_from_exr, path, (exr.ExrError, KeyError),
                            time_limit=CASE_TIME, trace=False)
            _check(table, failures, path, attack, "passes_from_exr", *rp)
    elapsed, cpu = time.perf_counter() - t0, time.process_time() - c0
    summary = {}
    for (reader, attack, outcome), count in sorted(table.items()):
        summary.setdefault(reader, {}).setdefault(attack, {})[outcome] = count
    totals = {reader: dict(Counter(o for (r, _, o), c in table.items() if r == reader
                                   for _ in range(c)))
              for reader in summary}
    _record("fuzz_readers", {"cases": n, "seconds": round(elapsed, 1), "totals": totals,
                             "slowest_case_s": round(WORST["seconds"], 3),
                             "read_exr_peak_mb": round(WORST["peak_mb"], 2), "by_attack": summary})
    print(f"\n{n} EXR cases in {elapsed:.1f} s: {totals}")
    assert not failures, "\n".join(failures[:20])
    assert totals["read_exr"]["rejected"] > 0.8 * n
    assert cpu < 30, f"fuzz run took {cpu:.0f} s of CPU ({elapsed:.0f} s wall)"
    # read_exr's peak is traced per case; the check (reads) and passes_from_exr (read_exr plus
    # stacking) are bounded by the process's high-water mark over the whole run
    assert _max_rss() - rss0 < PEAK_LIMIT


def test_fuzz_png_check(workdir):
    table, failures = Counter(), []
    path = str(workdir / "case.png")
    for label, data in F.png_bases():
        assert imagecheck.check_image_file(_write(path, data)).format == "PNG"
        for attack, mutated in F.png_mutations(label, data, 0):
            if mutated is None:
                continue
            _write(path, mutated)
            res = F.run_case(imagecheck.check_image_file, path, (imagecheck.ImageFileError,),
                             time_limit=CASE_TIME, trace=False)
            _check(table, failures, path, attack, "check_png", *res)
    counts = dict(Counter(o for (_, _, o), c in table.items() for _ in range(c)))
    rec = OUT / "fuzz_readers.json"
    old = json.loads(rec.read_text()) if rec.exists() else {}
    by_attack = {}
    for (_, a, o), c in table.items():
        by_attack.setdefault(a, {})[o] = c
    old["png"] = {"totals": counts, "by_attack": by_attack}
    _record("fuzz_readers", old)
    print(f"\nPNG: {counts}")
    assert not failures, "\n".join(failures[:20])
    # truncating a PNG anywhere loses IEND: always refused
    assert all(o == "rejected" for (_, a, o) in table if a == "png truncate")


# -- regressions: each of these failed on the reader before the fix ------------------------------


def _base(comp="ZIP"):
    ch = {"R": np.arange(32 * 32, dtype=np.float32).reshape(32, 32) % 7}
    return F.encode_exr([{"channels": ch, "compression": comp}])


def test_negative_attribute_size_is_refused(workdir):
    """Was an infinite loop (pos += negative size)."""
    data, layout = _base()
    _, start, size_pos, _, _, _ = layout["attrs"][1]
    # the size that points the parser back at the start of the same attribute
    path = _write(workdir / "neg.exr", F._set(data, size_pos, "<i", start - size_pos - 4))
    res = F.run_case(exr.read_exr, path, (exr.ExrError,), time_limit=2.0)
    assert res[0] == "rejected" and "negative size" in str(res[1]), res


def test_huge_data_window_is_refused_without_allocating(workdir):
    """Was a 14 GiB allocation (MemoryError) from a data window the file cannot hold."""
    data, layout = _base("NONE")
    dw = next(a for a in layout["attrs"] if a[0] == "dataWindow")
    path = _write(workdir / "huge.exr", F._set(data, dw[3] + 8, "<i", (1 << 31) - 1))
    res = F.run_case(exr.read_exr, path, (exr.ExrError,), time_limit=2.0)
    assert res[0] == "rejected" and res[3] < 1 << 20, res
    assert str(path) in str(res[1])


@pytest.mark.parametrize("comp", ["NONE", "RLE", "ZIPS", "ZIP"])
def test_truncated_file_raises_exr_error(workdir, comp):
    """Was struct.error / IndexError / zlib.error; now one line naming the file."""
    data, _ = _base(comp)
    for cut in (4, 20, len(data) // 2, len(data) - 1):
        path = _write(workdir / "cut.exr", data[:cut])
        with pytest.raises(exr.ExrError, match=r"cut\.exr: ") as info:
            exr.read_exr(path)
        assert "\n" not in str(info.value)
        with pytest.raises(imagecheck.ImageFileError, match=r"cut\.exr is a truncated OpenEXR "):
            imagecheck.check_image_file(path)


def test_oversized_chunk_and_zlib_bomb_are_refused(workdir):
    data, layout = _base()
    bomb = F._replace_chunk(data, layout, 0, zlib.compress(bytes(32 * 16 * 4 * 1000), 9))
    res = F.run_case(exr.read_exr, _write(workdir / "bomb.exr", bomb), (exr.ExrError,))
    assert res[0] == "rejected" and "zlib" in str(res[1]) and res[3] < 8 << 20, res
    big = F._set(data, layout["chunks"][0][1], "<i", (1 << 31) - 1)
    with pytest.raises(exr.ExrError, match="claims"):
        exr.read_exr(_write(workdir / "big.exr", big))


def test_check_image_file_formats(workdir):
    data, _ = _base()
    assert imagecheck.check_image_file(_write(workdir / "a.exr", data)) == ("OPEN_EXR", 32, 32)
    parts = exr.exr_header_check(str(workdir / "a.exr"))
    assert parts[0].compression == "ZIP" and parts[0].chunks == 2
    # the format is told by the contents, as Blender does (not by the name)
    for name, content, pattern in (("e.exr", b"", r"e\.exr is empty"),
                                   ("j.exr", b"\xff\xd8\xff", r"j\.exr is a truncated JPEG"),
                                   ("p.png", b"GIF89a", r"p\.png is not an image file Blender "
                                                       r"reads \(PNG, JPEG, OpenEXR"),
                                   ("x.jpg", b"\xff\xd8\xff", r"x\.jpg is a truncated JPEG"),
                                   ("s.png", b"\x89PNG", r"s\.png is a truncated PNG file")):
        with pytest.raises(imagecheck.ImageFileError, match=pattern):
            imagecheck.check_image_file(_write(workdir / name, content))
    # formats without a structural check: their leading bytes only
    assert imagecheck.check_image_file(_write(workdir / "t.tif", b"II*\x00" + bytes(60))) == \
        ("TIFF", None, None)
    assert imagecheck.check_image_file(_write(workdir / "w.webp", b"RIFF\x10\0\0\0WEBPVP8 ")) \
        == ("WEBP", None, None)
    tga = bytes([0, 0, 2]) + bytes(15)  # no magic number: told by the extension and the header
    assert imagecheck.check_image_file(_write(workdir / "a.tga", tga)).format == "TARGA"
    with pytest.raises(imagecheck.ImageFileError, match="not an image file"):
        imagecheck.check_image_file(_write(workdir / "a.bin", tga))
    with pytest.raises(imagecheck.ImageFileError, match="is a folder, not an image file"):
        imagecheck.check_image_file(str(workdir))
    with pytest.raises(OSError):
        imagecheck.check_image_file(str(workdir / "missing.exr"))


def test_tiled_exr_checked_not_read(workdir):
    ch = {c: np.full((10, 9), i, np.float32) for i, c in enumerate("BGR")}
    data = F.encode_tiled_exr(ch, tile=(4, 4))
    path = _write(workdir / "tiled.exr", data)
    (part,) = exr.exr_header_check(path)
    assert (part.type, part.width, part.height, part.chunks) == ("tiledimage", 9, 10, 9)
    with pytest.raises(exr.ExrError, match="only scanline"):
        exr.read_exr(path)
    with pytest.raises(exr.ExrError, match="truncated"):
        exr.exr_header_check(_write(workdir / "tiled_cut.exr", data[:-5]))
    # mip and rip levels (rounding down): 9 x 10 pixels in 4 x 4 tiles
    for levels, chunks in (("MIPMAP", 9 + 2 + 1 + 1), ("RIPMAP", None)):  # 9x10, 4x5, 2x2, 1x1
        data = F.encode_tiled_exr(ch, tile=(4, 4), levels=levels)
        (part,) = exr.exr_header_check(_write(workdir / "mip.exr", data))
        assert chunks is None or part.chunks == chunks
        with pytest.raises(exr.ExrError):
            exr.exr_header_check(_write(workdir / "mip.exr", data[:-1]))


def test_passes_from_exr_inconsistent_file(workdir):
    """passes_from_exr: a file without the passes -> KeyError naming the file; damaged -> ExrError."""
    data, _ = _base()
    with pytest.raises(KeyError, match="base.exr"):
        recomposite.passes_from_exr(_write(workdir / "base.exr", data))
    with pytest.raises(exr.ExrError):
        recomposite.passes_from_exr(_write(workdir / "base.exr", data[:100]))
    rng = np.random.default_rng(3)
    parts = F.recomposite_parts(rng, shape=(4, 3))
    parts[2]["channels"] = {k: np.zeros((5, 3), np.float32) for k in parts[2]["channels"]}
    with pytest.raises(exr.ExrError, match="sizes"):
        recomposite.passes_from_exr(_write(workdir / "mixed.exr", F.encode_exr(parts)[0]))


def test_first_half_of_zip_exr_is_refused_by_check(workdir):
    """The file that segfaults bpy 5.0.1 (issue 14 item 1): the first half of a 32x32 ZIP EXR."""
    data, _ = _base()
    path = _write(workdir / "trunc.exr", data[:len(data) // 2])
    with pytest.raises(imagecheck.ImageFileError, match="trunc.exr is a truncated OpenEXR file"):
        imagecheck.check_image_file(path)
    assert struct.unpack_from("<i", data, 0)[0] == 20000630
