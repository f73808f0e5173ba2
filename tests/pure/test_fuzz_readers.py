# SPDX-License-Identifier: GPL-3.0-or-later
"""Fuzz the add-on's image files, read through OpenImageIO: hazy_gloss.conversion.imagecheck.read_exr,
check_image_file (EXR and PNG) and recomposite.passes_from_exr.

Valid files come from the pure-python writer in fuzz_files.py (NONE / RLE / ZIPS / ZIP, single
and multi-part, HALF / FLOAT / UINT; tests/blender/test_imagecheck.py checks that Blender loads
them, and loads every fuzzed file the check passes); every mutation is deterministic.  For each
case and reader: the only exception is the documented one (ImageFileError, a ValueError;
KeyError from passes_from_exr for a well-formed file without the passes), its message one line
naming the file, and read_exr's traced peak (its float32 arrays) stays under 64 MB; every
truncation is refused.  No case is timed: the counts go to out/measurements/fuzz_readers.json
(docs/verification.md).
"""
import json
import os
import resource
import tempfile
import zlib
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import fuzz_files as F
from hazy_gloss import recomposite
from hazy_gloss.conversion import imagecheck

PEAK_LIMIT = 64 << 20
RSS_LIMIT = 256 << 20
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


def _check(table, failures, path, attack, reader, outcome, detail, _seconds, peak):
    if outcome == "other exception":
        failures.append(f"{reader} / {attack}: {type(detail).__name__}: {detail}")
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
        got = imagecheck.read_exr(path)
        assert sorted(got) == sorted(channels), label
        for name, arr in channels.items():
            assert got[name].dtype == np.float32
            assert np.array_equal(got[name], arr.astype(np.float32)), (label, name)
        if label == "multi-part mixed":  # parts of different sizes: read, not for Blender
            with pytest.raises(imagecheck.ImageFileError, match=r"Blender cannot load \(part 1's "
                                                                r"data window 3x17 at \(-2, 5\)"):
                imagecheck.check_image_file(path)
        else:
            assert imagecheck.check_image_file(path).format == "OPEN_EXR"
        if recomp:
            passes = recomposite.passes_from_exr(path)
            assert passes["original"].shape == (6, 5, 4)


def test_fuzz_exr_readers(workdir):
    """Every mutation: a result or the documented exception in one line, read_exr's traced peak
    under 64 MB; every truncation refused; whatever read_exr accepts the check accepts too, but
    parts of different data windows (read, but not for Blender)."""
    table, failures = Counter(), []
    path = str(workdir / "case.exr")
    rss0 = _max_rss()
    n = 0
    for attack, label, data, recomp in F.all_cases():
        n += 1
        _write(path, data)
        res = F.run_case(imagecheck.read_exr, path, (imagecheck.ImageFileError,))
        _check(table, failures, path, attack, "read_exr", *res)
        chk = F.run_case(imagecheck.check_image_file, path, (imagecheck.ImageFileError,),
                         trace=False)
        _check(table, failures, path, attack, "check_image_file", *chk)
        if res[0] == "accepted":
            out = res[1]
            assert all(a.dtype == np.float32 and a.ndim == 2 for a in out.values()), attack
            if chk[0] != "accepted" and "Blender cannot load" not in str(chk[1]):
                failures.append(f"{attack}: read_exr accepted what the check refused: {chk[1]}")
        if attack == "truncate" and (res[0], chk[0]) != ("rejected", "rejected"):
            failures.append(f"{label}: a file cut to {len(data)} bytes was accepted")
        if recomp:
            rp = F.run_case(recomposite.passes_from_exr, path, (imagecheck.ImageFileError,
                                                                KeyError), trace=False)
            _check(table, failures, path, attack, "passes_from_exr", *rp)
    summary = {}
    for (reader, attack, outcome), count in sorted(table.items()):
        summary.setdefault(reader, {}).setdefault(attack, {})[outcome] = count
    totals = {reader: dict(Counter(o for (r, _, o), c in table.items() if r == reader
                                   for _ in range(c)))
              for reader in summary}
    _record("fuzz_readers", {"cases": n, "totals": totals, "by_attack": summary})
    print(f"\n{n} EXR cases: {totals}")
    assert not failures, "\n".join(failures[:20])
    assert totals["read_exr"]["rejected"] > 0.8 * n
    # read_exr's peak is traced per case; the check, passes_from_exr and the libraries' own
    # buffers by the process's high-water mark over the whole run: a few times the largest
    # case's header (5000 attributes in each of 33 parts, 1 MB), nowhere near the gigabytes a
    # header's sizes could ask for
    assert _max_rss() - rss0 < RSS_LIMIT


def _image_data_end(png):
    """The byte where a PNG's last IDAT chunk ends (its CRC included)."""
    end = 0
    for pos, length, ctype in F._png_chunks(png):
        if ctype == b"IDAT":
            end = pos + 12 + length
    return end


def test_fuzz_png_check(workdir):
    table, failures = Counter(), []
    path = str(workdir / "case.png")
    for label, data in F.png_bases():
        assert imagecheck.check_image_file(_write(path, data)).format == "PNG"
        pixels_end = _image_data_end(data)
        for attack, mutated in F.png_mutations(label, data, 0):
            if mutated is None:
                continue
            _write(path, mutated)
            res = F.run_case(imagecheck.check_image_file, path, (imagecheck.ImageFileError,),
                             trace=False)
            _check(table, failures, path, attack, "check_png", *res)
            # a cut into the image data loses pixels: refused (a cut after it loses only IEND,
            # which libpng does not need to decode every row)
            if attack == "png truncate" and len(mutated) < pixels_end and res[0] != "rejected":
                failures.append(f"{label}: cut to {len(mutated)} bytes was accepted")
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


# -- regressions: each of these failed on a reader before it was fixed ---------------------------


def _base(comp="ZIP"):
    ch = {"R": np.arange(32 * 32, dtype=np.float32).reshape(32, 32) % 7}
    return F.encode_exr([{"channels": ch, "compression": comp}])


def test_negative_attribute_size_is_refused(workdir):
    """Was an infinite loop in a hand-written reader (pos += negative size)."""
    data, layout = _base()
    _, start, size_pos, _, _, _ = layout["attrs"][1]
    # the size that points the parser back at the start of the same attribute
    path = _write(workdir / "neg.exr", F._set(data, size_pos, "<i", start - size_pos - 4))
    res = F.run_case(imagecheck.read_exr, path, (imagecheck.ImageFileError,))
    assert res[0] == "rejected" and str(path) in str(res[1]), res


def test_huge_data_window_is_refused_without_allocating(workdir):
    """Was a 14 GiB allocation (MemoryError) from a data window the file cannot hold."""
    data, layout = _base("NONE")
    dw = next(a for a in layout["attrs"] if a[0] == "dataWindow")
    path = _write(workdir / "huge.exr", F._set(data, dw[3] + 8, "<i", (1 << 31) - 1))
    res = F.run_case(imagecheck.read_exr, path, (imagecheck.ImageFileError,))
    assert res[0] == "rejected" and res[3] < 1 << 20, res
    assert str(path) in str(res[1])


@pytest.mark.parametrize("comp", ["NONE", "RLE", "ZIPS", "ZIP"])
def test_truncated_file_is_one_line(workdir, comp):
    """Every codec, cut in the header, the chunks or by one byte: one line naming the file (an
    uncompressed file cut in its last chunk reads without an error through OpenImageIO's
    default OpenEXR reader; hazy_gloss.conversion.oiio opens files with the classic one)."""
    data, _ = _base(comp)
    for cut in (4, 20, len(data) // 2, len(data) - 1):
        path = _write(workdir / "cut.exr", data[:cut])
        for read in (imagecheck.read_exr, imagecheck.check_image_file):
            with pytest.raises(imagecheck.ImageFileError, match=r"cut\.exr is ") as info:
                read(path)
            assert "\n" not in str(info.value)
            if cut > len(data) // 4:  # the header is whole: OpenEXR names the damage
                assert "is a damaged OpenEXR file" in str(info.value)


def test_oversized_chunk_and_zlib_bomb_are_refused(workdir):
    data, layout = _base()
    bomb = F._replace_chunk(data, layout, 0, zlib.compress(bytes(32 * 16 * 4 * 1000), 9))
    res = F.run_case(imagecheck.read_exr, _write(workdir / "bomb.exr", bomb),
                     (imagecheck.ImageFileError,))
    assert res[0] == "rejected" and res[3] < 8 << 20, res
    big = F._set(data, layout["chunks"][0][1], "<i", (1 << 31) - 1)
    with pytest.raises(imagecheck.ImageFileError, match="big.exr is a damaged OpenEXR"):
        imagecheck.read_exr(_write(workdir / "big.exr", big))


def test_check_image_file_formats(workdir):
    data, _ = _base()
    assert imagecheck.check_image_file(_write(workdir / "a.exr", data)) == ("OPEN_EXR", 32, 32)
    # the format is told by the contents, as Blender does (not by the name)
    png = F.encode_png(np.zeros((3, 5, 3), np.uint8))
    assert imagecheck.check_image_file(_write(workdir / "p.jpg", png)) == ("PNG", 5, 3)
    for name, content, pattern in (("e.exr", b"", r"e\.exr is empty"),
                                   ("j.exr", b"\xff\xd8\xff", r"j\.exr is a damaged JPEG file"),
                                   ("p.png", b"GIF89a", r"p\.png is not an image file Blender "
                                                       r"reads \(PNG, JPEG, OpenEXR"),
                                   ("s.png", b"\x89PNG", r"s\.png is not an image file Blender "
                                                         r"reads .*, or a damaged one"),
                                   ("t.tif", b"II*\x00" + bytes(60), r"t\.tif is a damaged TIFF"),
                                   ("a.txt", b"hello\n" * 9, r"a\.txt is not an image file")):
        with pytest.raises(imagecheck.ImageFileError, match=pattern):
            imagecheck.check_image_file(_write(workdir / name, content))
    with pytest.raises(imagecheck.ImageFileError, match="is a folder, not an image file"):
        imagecheck.check_image_file(str(workdir))
    with pytest.raises(OSError):
        imagecheck.check_image_file(str(workdir / "missing.exr"))
    with pytest.raises(imagecheck.ImageFileError, match=r"p\.jpg is a PNG file, not OpenEXR"):
        imagecheck.read_exr(str(workdir / "p.jpg"))


def test_tiled_exr_is_read_and_checked(workdir):
    """Tiled files (one level, mip- and rip-maps): level 0 (what Blender reads) read exactly;
    cut in it: refused."""
    ch = {c: np.arange(90, dtype=np.float32).reshape(10, 9) * (i + 1) for i, c in enumerate("BGR")}
    for levels in ("ONE", "MIPMAP", "RIPMAP"):
        data = F.encode_tiled_exr(ch, tile=(4, 4), levels=levels)
        path = _write(workdir / "tiled.exr", data)
        assert imagecheck.check_image_file(path) == ("OPEN_EXR", 9, 10)
        got = imagecheck.read_exr(path)
        assert all(np.array_equal(got[c], ch[c]) for c in "BGR"), levels
        if levels != "ONE":  # (a cut in a smaller level is not read: Blender reads level 0)
            continue
        for cut in (len(data) // 2, len(data) - 1):
            with pytest.raises(imagecheck.ImageFileError, match="tiled.exr is a damaged"):
                imagecheck.check_image_file(_write(workdir / "tiled.exr", data[:cut]))


def test_passes_from_exr_inconsistent_file(workdir):
    """passes_from_exr: a file without the passes -> KeyError naming the file; damaged ->
    ImageFileError."""
    data, _ = _base()
    with pytest.raises(KeyError, match="base.exr"):
        recomposite.passes_from_exr(_write(workdir / "base.exr", data))
    with pytest.raises(imagecheck.ImageFileError):
        recomposite.passes_from_exr(_write(workdir / "base.exr", data[:100]))
    rng = np.random.default_rng(3)
    parts = F.recomposite_parts(rng, shape=(4, 3))
    parts[2]["channels"] = {k: np.zeros((5, 3), np.float32) for k in parts[2]["channels"]}
    with pytest.raises(imagecheck.ImageFileError, match="sizes"):
        recomposite.passes_from_exr(_write(workdir / "mixed.exr", F.encode_exr(parts)[0]))


def test_first_half_of_zip_exr_is_refused_by_check(workdir):
    """The file that segfaults bpy 5.0.1: the first half of a 32x32 ZIP EXR."""
    data, _ = _base()
    path = _write(workdir / "trunc.exr", data[:len(data) // 2])
    with pytest.raises(imagecheck.ImageFileError, match="trunc.exr is a damaged OpenEXR file"):
        imagecheck.check_image_file(path)
