# SPDX-License-Identifier: GPL-3.0-or-later
"""The conversion's guarantees under attack.

- no file reaches ``bpy.data.images.load`` unchecked: truncated EXR / PNG and non-images are one
  line (Blender 5.0.1 segfaults on a truncated EXR);
- all or nothing: a failure or an interruption at any point (a write cut off by a full disk,
  a failing rename after k files, an output that would overwrite an input in a later UDIM
  tile, a read-only folder, KeyboardInterrupt, SIGINT and SIGTERM from outside) leaves the
  output folder byte for byte as it was; stale temporaries of killed runs are cleaned; a rerun
  after a failure gives the bytes of a clean run;
- CLI and API errors are one line (rc 2 in the CLI) naming the parameter or file and what
  would be valid; the operator's temp-folder fallback stays inside its folder.
Every test here failed on the code before their fixes (the rerun test only because the
failed run raised a raw OSError there).
"""
import importlib
import os
import signal
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes
from test_convert import N, make_inputs, read_raw, write_exr, write_png

REPO_ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def api(hg, clean_file):
    return importlib.import_module(hg.__name__ + ".api")


@pytest.fixture
def core(hg):
    return importlib.import_module(hg.__name__ + ".conversion.convert")


@pytest.fixture
def binputs(hg):
    """blender/model/convert_inputs.py: check_readable, the readers."""
    return importlib.import_module(hg.__name__ + ".blender.model.convert_inputs")


@pytest.fixture
def boutputs(hg):
    """blender/model/convert_outputs.py: _MapFile, the transaction."""
    return importlib.import_module(hg.__name__ + ".blender.model.convert_outputs")


def snapshot(folder):
    """{file name: bytes} of every file in ``folder`` (hidden ones included)."""
    folder = Path(folder)
    if not folder.exists():
        return None
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def one_line(exc):
    text = str(exc)
    assert "\n" not in text and text.strip() == text, text
    return text


def old_set(api, tmp_path, fmt="OPEN_EXR"):
    """Inputs and an output folder holding an earlier conversion (haziness 0.2), whose files the
    tests' conversions (haziness from a map) would replace."""
    paths, _ = make_inputs(tmp_path / "in")
    out = tmp_path / "out"
    api.convert_maps(dict(paths, haziness=0.2), str(out), file_format=fmt)
    return paths, out, snapshot(out)


# --------------------------------------------------------------------------------------------
# 1. Files are checked before Blender sees them
# --------------------------------------------------------------------------------------------


def _exr_bytes(tmp_path, n=32, codec="ZIP"):
    p = tmp_path / f"full_{codec}.exr"
    rng = np.random.default_rng(4)
    values = rng.uniform(0, 0.9, (n, n)).astype(np.float32)
    img = bpy.data.images.new("src", n, n, float_buffer=True, is_data=True)
    px = np.ones((n, n, 4), np.float32)
    px[..., :3] = values[..., None]
    img.pixels.foreach_set(px.ravel())
    sc = bpy.data.scenes.new("w")
    s = sc.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format, s.color_mode, s.color_depth, s.exr_codec = "OPEN_EXR", "RGB", "32", codec
    img.save_render(str(p), scene=sc)
    bpy.data.scenes.remove(sc)
    bpy.data.images.remove(img)
    return p.read_bytes()


def test_truncated_exr_is_one_clear_error_not_a_crash(api, core, tmp_path):
    """The issue's case: the first half of a 32x32 ZIP EXR (5.0.1 segfaults on it)."""
    data = _exr_bytes(tmp_path)
    trunc = tmp_path / "trunc.exr"
    trunc.write_bytes(data[:len(data) // 2])
    out = tmp_path / "o"
    with pytest.raises(core.ConversionError, match=r"haziness \(trunc.exr\): .*trunc.exr is a "
                                                   r"damaged OpenEXR file") as info:
        api.convert_maps({"haziness": str(trunc)}, str(out))
    one_line(info.value)
    assert not out.exists()  # checked before the output folder is even created
    # an image datablock of that file (not loaded yet) is checked the same way
    img = bpy.data.images.load(str(trunc), check_existing=False)
    with pytest.raises(core.ConversionError, match="damaged OpenEXR"):
        api.convert_maps({"haziness": img}, str(out))


def _jpeg_bytes(tmp_path, n=40):
    """An 8-bit JPEG from Blender's writer (Blender fills a cut-off JPEG with grey silently)."""
    img = bpy.data.images.new("src", n, n)
    px = np.random.default_rng(5).random((n, n, 4)).astype(np.float32)
    img.pixels.foreach_set(px.ravel())
    sc = bpy.data.scenes.new("w")
    s = sc.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format = "JPEG"
    img.save_render(str(tmp_path / "full.jpg"), scene=sc)
    bpy.data.scenes.remove(sc)
    bpy.data.images.remove(img)
    return (tmp_path / "full.jpg").read_bytes()


@pytest.mark.parametrize("fmt", ["exr", "png", "jpg"])
def test_every_cut_of_a_file_is_refused_and_whole_files_pass(binputs, tmp_path, fmt):
    if fmt == "exr":
        data = _exr_bytes(tmp_path, n=40)
    elif fmt == "jpg":
        data = _jpeg_bytes(tmp_path)
    else:
        p = write_png(tmp_path / "full.png", np.arange(40 * 40).reshape(40, 40) * 37 % 65536, 16)
        data = Path(p).read_bytes()
    whole = tmp_path / f"whole.{fmt}"
    whole.write_bytes(data)
    assert binputs.check_readable(str(whole), "x") == {"exr": "OpenEXR", "png": "PNG",
                                                      "jpg": "JPEG"}[fmt]
    (tmp_path / f"trailing.{fmt}").write_bytes(data + b"\0" * 4096)  # data after the end: fine
    assert binputs.check_readable(str(tmp_path / f"trailing.{fmt}"), "x")
    cut = tmp_path / f"cut.{fmt}"
    # every cut loses pixels, but a PNG's after its last IDAT (only IEND: libpng has decoded
    # every row by then, and so does Blender)
    end = len(data) - 12 if fmt == "png" else len(data)
    accepted = []
    for n in sorted(set(range(1, end, max(1, len(data) // 400))) | {end - 1}):
        cut.write_bytes(data[:n])
        try:
            binputs.check_readable(str(cut), "x")
            accepted.append(n)
        except binputs.ConversionError as exc:
            one_line(exc)
            assert "damaged" in str(exc), str(exc)
    assert accepted == []


def test_every_blender_exr_codec_passes_the_check(binputs, tmp_path):
    codecs = ["NONE", "ZIP", "ZIPS", "PIZ", "RLE", "PXR24", "DWAA", "DWAB"]
    if bpy.app.version >= (5, 0, 0):
        codecs.append("HTJ2K")
    for codec in codecs:
        p = tmp_path / f"{codec}.exr"
        p.write_bytes(_exr_bytes(tmp_path, n=300, codec=codec))  # > 256 lines: several chunks
        assert binputs.check_readable(str(p), codec) == "OpenEXR"


def test_headers_claiming_huge_images_are_refused(binputs, tmp_path):
    """A 300-byte PNG claiming 40000x40000 (Blender would try to allocate 25.6 GB) and an EXR
    whose data window is 2^30 wide: refused by the check."""
    import zlib

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))

    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 40000, 40000, 16, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(b"\0" * 240001)) + chunk(b"IEND", b""))
    (tmp_path / "big.png").write_bytes(png)
    with pytest.raises(binputs.ConversionError, match=r"claims 40000x40000 pixels, which \d+ "
                                                      r"bytes cannot hold"):
        binputs.check_readable(str(tmp_path / "big.png"), "x")
    data = bytearray(_exr_bytes(tmp_path))
    at = data.index(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
    data[at:at + 16] = struct.pack("<4i", 0, 0, (1 << 30) - 1, 31)
    (tmp_path / "wide.exr").write_bytes(bytes(data))
    # (OpenEXR's classic reader refuses the header itself; its reason is in the line)
    with pytest.raises(binputs.ConversionError, match=r"wide\.exr is a damaged OpenEXR file"):
        binputs.check_readable(str(tmp_path / "wide.exr"), "x")


@pytest.mark.parametrize("case", ["png_cut", "not_image", "folder", "nul"])
def test_bad_files_are_one_line(api, core, tmp_path, case):
    paths, _ = make_inputs(tmp_path / "in")
    if case == "png_cut":
        bad = tmp_path / "h.png"
        bad.write_bytes(Path(paths["haziness"]).read_bytes()[:-40])  # into the image data
        pattern = r"haziness \(h.png\): .*h.png is a damaged PNG file \(cut off or corrupt: "
    elif case == "not_image":
        bad = tmp_path / "h.exr"
        bad.write_bytes(b"<html>not found</html>")
        pattern = r"h.exr is not an image file Blender reads \(PNG, JPEG, OpenEXR"
    elif case == "folder":
        bad = tmp_path / "dir.png"
        bad.mkdir()
        pattern = "dir.png is a folder, not an image file"
    else:
        bad = str(tmp_path / "h\0.png")
        pattern = "haziness: .* contains a NUL character"
    with pytest.raises(core.ConversionError, match=pattern) as info:
        api.convert_maps(dict(paths, haziness=str(bad)), str(tmp_path / "out"))
    one_line(info.value)
    assert not (tmp_path / "out").exists()


def test_operator_reports_truncated_exr(hg, clean_file, tmp_path):
    data = _exr_bytes(tmp_path)
    trunc = tmp_path / "trunc.exr"
    trunc.write_bytes(data[:len(data) // 2])
    with pytest.raises(RuntimeError, match="damaged OpenEXR"):  # the ERROR report
        bpy.ops.hazy_gloss.convert_maps(haziness_path=str(trunc), wire=False,
                                        directory=str(tmp_path / "op"))
    assert not (tmp_path / "op").exists()


# --------------------------------------------------------------------------------------------
# 3. All or nothing
# --------------------------------------------------------------------------------------------


def test_write_cut_off_by_a_full_disk_is_caught_and_undone(api, boutputs, tmp_path, monkeypatch):
    """A file cut off after it was written (Blender's PNG writer reported success on a file cut
    off by a full disk): simulated by cutting the third file once it is complete.  The
    decode that proves each map catches it; nothing changes."""
    paths, out, before = old_set(api, tmp_path, fmt="PNG")
    real = boutputs.MapFile.close_file
    calls = []

    def full_disk(self):
        real(self)
        calls.append(self.tmp)
        if len(calls) >= 3:
            data = Path(self.tmp).read_bytes()
            Path(self.tmp).write_bytes(data[:len(data) // 2])

    monkeypatch.setattr(boutputs.MapFile, "close_file", full_disk)
    with pytest.raises(boutputs.ConversionError, match=r"could not write .*roughness_wide.png "
                                                    r"\(disk full\?\): .*roughness_wide.*png: .*"
                                                    r"cannot be read") as info:
        api.convert_maps(paths, str(out), file_format="PNG")
    one_line(info.value)
    assert snapshot(out) == before


@pytest.mark.parametrize("fmt, where", [("OPEN_EXR", 0.5), ("OPEN_EXR", 0.01), ("PNG", 0.5)])
def test_write_that_reads_back_different_is_caught(api, boutputs, tmp_path, monkeypatch, fmt, where):
    """A complete file with one other byte (a failing device; in the pixels, or in the EXR
    header): the decode that proves each map catches it (other values, or no file at all)."""
    paths, out, before = old_set(api, tmp_path, fmt=fmt)
    real = boutputs.MapFile.close_file

    def flip(self):
        real(self)
        data = bytearray(Path(self.tmp).read_bytes())
        data[int(len(data) * where)] ^= 0x10
        Path(self.tmp).write_bytes(bytes(data))

    monkeypatch.setattr(boutputs.MapFile, "close_file", flip)
    with pytest.raises(boutputs.ConversionError, match=r"could not write .*beta.(exr|png) \(disk "
                                                    r"full\?\): .*(cannot be read|reads back)"):
        api.convert_maps(paths, str(out), file_format=fmt)
    assert snapshot(out) == before


@pytest.mark.parametrize("k", [0, 1, 3, 4])
def test_rename_failing_after_k_files_restores_the_old_set(api, boutputs, tmp_path, monkeypatch, k):
    """A rename of a new map into place fails after k succeeded (the commit is k/5 done): the k
    replaced maps are restored from their backups."""
    paths, out, before = old_set(api, tmp_path)
    real = os.replace
    done = []

    def replace(src, dst):
        if ".tmp." in os.path.basename(src):
            if len(done) == k:
                raise OSError(28, "No space left on device", dst)
            done.append(dst)
        return real(src, dst)

    monkeypatch.setattr(boutputs.os, "replace", replace)
    with pytest.raises(boutputs.ConversionError, match="No space left on device.*output folder is "
                                                    "unchanged") as info:
        api.convert_maps(paths, str(out))
    monkeypatch.undo()
    one_line(info.value)
    assert snapshot(out) == before


def test_rerun_after_failure_gives_the_bytes_of_a_clean_run(api, boutputs, tmp_path, monkeypatch):
    paths, out, _ = old_set(api, tmp_path)
    clean = api.convert_maps(paths, str(tmp_path / "clean"))
    real = os.replace

    def replace(src, dst):
        if os.path.basename(dst) == "roughness_wide.exr":
            raise OSError(5, "Input/output error", dst)
        return real(src, dst)

    monkeypatch.setattr(boutputs.os, "replace", replace)
    with pytest.raises(boutputs.ConversionError):
        api.convert_maps(paths, str(out))
    monkeypatch.undo()
    api.convert_maps(paths, str(out))
    assert snapshot(out) == snapshot(tmp_path / "clean")
    assert sorted(os.listdir(out)) == sorted(os.path.basename(p) for p in clean.values())


def test_overwrite_of_an_input_in_a_later_tile_writes_nothing(api, core, tmp_path):
    """Tile 1002's beta map would overwrite an input: refused before tile 1001 is written."""
    folder = tmp_path / "work"
    folder.mkdir()
    for t in (1001, 1002):
        write_exr(folder / f"haz.{t}.exr", np.full((N, N), 0.3, np.float32))
    rough = write_exr(folder / "beta.1002.exr", np.full((N, N), 0.2, np.float32))
    before = snapshot(folder)
    with pytest.raises(core.ConversionError, match=r"output .*beta.1002.exr would overwrite an "
                                                   "input") as info:
        api.convert_maps({"haziness": str(folder / "haz.<UDIM>.exr"), "roughness": rough},
                         str(folder))
    one_line(info.value)
    assert snapshot(folder) == before


def test_read_only_output_folder(api, boutputs, tmp_path, monkeypatch):
    paths, out, before = old_set(api, tmp_path)
    os.chmod(out, 0o555)
    try:
        probe = out / "probe"
        try:
            probe.write_bytes(b"")
            probe.unlink()
            enforced = False  # root ignores the mode bits: simulate the refusal
        except PermissionError:
            enforced = True
        if not enforced:
            real_open = os.open

            def deny(path, *a, **k):
                if os.path.dirname(os.fspath(path)) == str(out):
                    raise PermissionError(13, "Permission denied", path)
                return real_open(path, *a, **k)
            monkeypatch.setattr(boutputs.os, "open", deny)
        with pytest.raises(boutputs.ConversionError, match=r"output folder .*out is not writable: "
                                                        "Permission denied") as info:
            api.convert_maps(paths, str(out))
        one_line(info.value)
    finally:
        monkeypatch.undo()
        os.chmod(out, 0o755)
    assert snapshot(out) == before


def test_output_folder_that_cannot_be_created(api, core, tmp_path, monkeypatch):
    paths, _ = make_inputs(tmp_path / "in")
    blocker = tmp_path / "file"
    blocker.write_bytes(b"x")
    with pytest.raises(core.ConversionError, match=r"output folder .*file/sub: .*file is a file"):
        api.convert_maps(paths, str(blocker / "sub"))
    with pytest.raises(core.ConversionError, match="cannot create the output folder /proc/"):
        api.convert_maps(paths, "/proc/hazy_gloss_test_out")
    # a failed run removes the folders it created (here: the write of the first map fails)
    boutputs = importlib.import_module(api.__name__.rsplit(".", 1)[0] + ".blender.model.convert_outputs")
    monkeypatch.setattr(boutputs.MapFile, "close_file", lambda self: (_ for _ in ()).throw(
        OSError(5, "simulated")))
    with pytest.raises(core.ConversionError, match="could not write .*beta.exr: simulated"):
        api.convert_maps(paths, str(tmp_path / "new" / "deeper"))
    assert not (tmp_path / "new").exists()


def test_keyboard_interrupt_while_writing(api, tmp_path):
    paths, out, before = old_set(api, tmp_path)

    def progress(done, total, message):
        if message == "wrote roughness":
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        api.convert_maps(paths, str(out), progress=progress)
    assert snapshot(out) == before
    assert not [s for s in bpy.data.scenes if s.name.startswith(".hazy_gloss")]
    assert not [i for i in bpy.data.images if i.name.startswith(".hazy_gloss")]


def test_sigint_while_renaming_is_undone(api, boutputs, tmp_path, monkeypatch):
    """A real SIGINT between two renames of the commit: held, then handled where the whole set
    can still be undone."""
    paths, out, before = old_set(api, tmp_path)
    real = os.replace
    n = []

    def replace(src, dst):
        real(src, dst)
        if ".tmp." in os.path.basename(src):
            n.append(dst)
            if len(n) == 2:
                os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(boutputs.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        api.convert_maps(paths, str(out))
    monkeypatch.undo()
    assert snapshot(out) == before
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_stale_temporaries_of_killed_runs_are_removed(api, tmp_path):
    paths, out, _ = old_set(api, tmp_path)
    old = time.time() - 3600
    stale = [".beta.0123456789ab.tmp.exr", ".roughness_wide.00000000abcd.bak.exr",
             ".beta.1001.0123456789ab.tmp.png", ".hazy_gloss_probe.0123456789ab.tmp.png"]
    kept = [".notes.0123456789ab.tmp.exr",  # not one of our map names
            "beta.tmp.exr", ".beta.xyz.tmp.exr", ".beta.0123456789ab.tmp.txt"]
    for name in stale + kept:
        (out / name).write_bytes(b"partial")
        os.utime(out / name, (old, old))
    fresh = out / ".ior.fedcba987654.tmp.exr"  # newer than the run: perhaps another run's
    fresh.write_bytes(b"partial")
    future = time.time() + 3600
    os.utime(fresh, (future, future))
    res = api.convert_maps(paths, str(out))
    names = set(os.listdir(out))
    assert not names & set(stale)
    assert set(kept) | {fresh.name} <= names
    assert any("removed 4 temporary file(s)" in w for w in res.report.warnings)


def test_udim_tiles_of_a_larger_earlier_set_are_retired(api, tmp_path):
    """Tiles 1001-1003 converted, then 1001-1002: beta.1003.exr would join the new tiled image;
    it is removed with the commit (and restored if the commit fails)."""
    src = tmp_path / "src"
    src.mkdir()
    for t in (1001, 1002, 1003):
        write_exr(src / f"h.{t}.exr", np.full((N, N), 0.1 * (t - 1000), np.float32))
    out = tmp_path / "out"
    api.convert_maps({"haziness": str(src / "h.<UDIM>.exr")}, str(out))
    assert (out / "beta.1003.exr").is_file()
    (src / "h.1003.exr").unlink()
    mat = bpy.data.materials.new("udim")
    res = api.convert_maps({"haziness": str(src / "h.<UDIM>.exr")}, str(out), material=mat)
    assert not any(".1003." in n for n in os.listdir(out))
    assert any("beta.1003.exr" in w for w in res.report.warnings)
    img = mat.node_tree.nodes["HG Map beta"].image
    assert sorted(t.number for t in img.tiles) == [1001, 1002]


# --------------------------------------------------------------------------------------------
# Signals from outside, in a real CLI process
# --------------------------------------------------------------------------------------------

_DRIVER = r"""
import os, signal, sys, time
from hazy_gloss.blender.model import convert_outputs as bc
mode, signum, k = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
real_write, real_replace, count = bc.MapFile.finish, os.replace, []

def write(self, *a, **kw):
    real_write(self, *a, **kw)
    count.append(1)
    print("WROTE", len(count), flush=True)
    if mode == "slow":
        time.sleep(1.0)

def replace(src, dst):
    real_replace(src, dst)
    if ".tmp." in os.path.basename(src):
        count.append(1)
        if len(count) == k:
            os.kill(os.getpid(), signum)

bc.MapFile.finish = write
if mode == "commit":
    bc.MapFile.finish = real_write
    os.replace = replace
from hazy_gloss.__main__ import main
sys.exit(main(sys.argv[4:]))
"""


def _cli_env(tmp_path):
    return dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"),
                PYTHONPATH=str(REPO_ROOT), PYTHONDONTWRITEBYTECODE="1")


@pytest.mark.parametrize("fmt", ["PNG", "OPEN_EXR"])
def test_real_file_size_limit_in_the_cli(api, tmp_path, fmt):
    """Not simulated: the CLI runs under RLIMIT_FSIZE = 64 KiB, which cuts every larger file
    as a full disk does.  Blender's PNG writer reports success on the cut file (before the fix
    it was renamed into place: exit 0 with a 61440-byte beta.png); now exit 2, one line, and
    the earlier set is untouched."""
    import resource
    rng = np.random.default_rng(8)
    noisy = write_png(tmp_path / "noisy.png", rng.integers(0, 58000, (256, 256)), 16)
    out = tmp_path / "out"
    api.convert_maps({"haziness": 0.2, "roughness": write_png(
        tmp_path / "r.png", np.full((256, 256), 9000), 16)}, str(out), file_format=fmt)
    before = snapshot(out)
    limit = 64 << 10
    assert max(len(b) for b in before.values()) < limit

    def cap():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    r = subprocess.run([sys.executable, "-m", "hazy_gloss", "convert", "--haziness", noisy,
                        "--format", fmt, "--out", str(out)], cwd=str(tmp_path),
                       env=_cli_env(tmp_path), capture_output=True, text=True, timeout=300,
                       preexec_fn=cap)
    assert r.returncode == 2, (r.returncode, r.stderr)
    line = _error_line(r)
    assert "could not write" in line and "beta" in line, line
    assert r.stdout.strip() == ""
    assert snapshot(out) == before


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_from_outside_during_the_cli_run(api, tmp_path, sig, code):
    paths, out, before = old_set(api, tmp_path)
    args = ["convert", "--haziness", paths["haziness"], "--roughness", paths["roughness"],
            "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "-c", _DRIVER, "slow", "0", "0", *args],
                            cwd=str(tmp_path), env=_cli_env(tmp_path), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 120
        while time.time() < deadline:
            line = proc.stdout.readline()
            if not line or line.startswith("WROTE 2"):
                break
        assert line.startswith("WROTE 2"), proc.stderr.read()
        os.kill(proc.pid, sig)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err
    lines = [ln for ln in err.splitlines() if ln.startswith("hazy_gloss convert:")]
    assert len(lines) == 1 and f"interrupted ({signal.Signals(sig).name})" in lines[0], err
    assert "Traceback" not in err
    assert snapshot(out) == before


@pytest.mark.parametrize("sig, code, k", [(signal.SIGTERM, 143, 1), (signal.SIGINT, 130, 3),
                                          (signal.SIGTERM, 143, 5)])
def test_signal_during_the_commit_is_undone(api, tmp_path, sig, code, k):
    """SIGTERM / SIGINT raised by the process itself right after its k-th rename (of 5)."""
    paths, out, before = old_set(api, tmp_path)
    args = ["convert", "--haziness", paths["haziness"], "--out", str(out)]
    r = subprocess.run([sys.executable, "-c", _DRIVER, "commit", str(int(sig)), str(k), *args],
                       cwd=str(tmp_path), env=_cli_env(tmp_path), capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == code, r.stderr
    assert "Traceback" not in r.stderr
    assert snapshot(out) == before


def test_signals_at_any_time_leave_the_old_or_the_new_set(api, tmp_path):
    """SIGINT / SIGTERM at 8 moments spread over a whole CLI run (during ``import bpy``, reading,
    writing, renaming, printing, exiting): exit 0 with the complete new set, or 130 / 143 with
    one line and the folder as it was (or, after the last rename, the complete new set) —
    never a mixed set, a temporary, a traceback or a death by the signal."""
    paths, _ = make_inputs(tmp_path / "in", aniso=True)
    args = ["convert", "--haziness", paths["haziness"], "--roughness", paths["roughness"],
            "--anisotropy", paths["anisotropy"], "--out"]
    env = _cli_env(tmp_path)
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "hazy_gloss", *args, str(tmp_path / "new")], env=env,
                   capture_output=True, timeout=300, check=True)
    runtime = time.perf_counter() - t
    new = snapshot(tmp_path / "new")
    for i in range(8):
        out = tmp_path / f"o{i}"
        api.convert_maps(dict(paths, haziness=0.3), str(out))
        old = snapshot(out)
        sig = (signal.SIGINT, signal.SIGTERM)[i % 2]
        proc = subprocess.Popen([sys.executable, "-m", "hazy_gloss", *args, str(out)], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(runtime * (0.15 + 0.13 * i))
        proc.send_signal(sig)
        so, se = proc.communicate(timeout=120)
        now = snapshot(out)
        assert now in (old, new), (i, sorted(now))
        assert "Traceback" not in se, se
        if proc.returncode == 0:
            assert now == new and se.strip() == ""
            continue
        assert proc.returncode == {signal.SIGINT: 130, signal.SIGTERM: 143}[sig], (i, proc.returncode, se)
        lines = [ln for ln in se.splitlines() if ln.strip()]
        assert len(lines) == 1 and "interrupted" in lines[0], se
        assert (now == new) == ("new maps are in place" in lines[0]), (i, lines)


# --------------------------------------------------------------------------------------------
# 7. CLI and API errors; exit codes
# --------------------------------------------------------------------------------------------


def _cli(args, tmp_path, cwd=None):
    return subprocess.run([sys.executable, "-m", "hazy_gloss", *args], cwd=str(cwd or tmp_path),
                          env=_cli_env(tmp_path), capture_output=True, text=True, timeout=300)


def _error_line(r):
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("hazy_gloss convert: error: "), r.stderr
    return lines[0]


def test_cli_exit_codes_and_one_line_errors(hg, clean_file, tmp_path):
    paths, _ = make_inputs(tmp_path / "in")
    data = _exr_bytes(tmp_path)
    (tmp_path / "trunc.exr").write_bytes(data[:len(data) // 2])
    (tmp_path / "afile").write_bytes(b"x")
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    cases = {  # reason in the one line -> arguments
        "trunc.exr is a damaged OpenEXR file": ["--haziness", str(tmp_path / "trunc.exr"),
                                                  "--out", str(tmp_path / "o")],
        "cannot create the output folder /proc/": ["--haziness", paths["haziness"],
                                                   "--out", "/proc/hazy_gloss_test/x"],
        "afile is a file, not a folder": ["--haziness", paths["haziness"],
                                          "--out", str(tmp_path / "afile" / "sub")],
        "is not writable": ["--haziness", paths["haziness"], "--out", "/proc/self"],
        "--out must name a folder, got ''": ["--haziness", paths["haziness"], "--out", ""],
        "prefix must be a plain file-name prefix": ["--haziness", paths["haziness"],
                                                    "--prefix", "../up", "--out", str(tmp_path / "o")],
        "--exr-codec must be one of NONE, ZIP": ["--haziness", paths["haziness"], "--exr-codec",
                                                 "FOO", "--out", str(tmp_path / "o")],
        # (the parameters named as the flags typed; the range as make_hazy's)
        "--haze-extent: constant -1.0 is out of range: it must be >= 0": [
            "--haziness", paths["haziness"], "--haze-extent", "-1", "--out", str(tmp_path / "o")],
        "--smoothness must be >= 0.0001 and finite (the Bézier weight w; leaving it out": [
            "--haziness", paths["haziness"], "--smoothness", "inf", "--out", str(tmp_path / "o")],
        "--smoothness must be >= 0.0001": ["--haziness", paths["haziness"], "--smoothness",
                                           "1e-9", "--out", str(tmp_path / "o")],
        "give both --haze-extent-x and --haze-extent-y (or --haze-extent": [
            "--haziness", paths["haziness"], "--haze-extent-x", "3", "--out", str(tmp_path / "o")],
        "colours are 0-1, not 0-255": ["--haziness", paths["haziness"], "--core-reflectivity",
                                       "255,128,0", "--out", str(tmp_path / "o")],
        "did you mean": ["--haziness", paths["haziness"], "--kind", "CONDUCTR",
                         "--out", str(tmp_path / "o")],
    }
    for reason, args in cases.items():
        r = _cli(["convert", *args], tmp_path, cwd=cwd)
        assert r.returncode == 2, (reason, r.returncode, r.stderr)
        assert reason in _error_line(r), (reason, r.stderr)
    assert os.listdir(cwd) == []  # --out "" wrote nothing into the current folder
    assert not (tmp_path / "o").exists()
    ok = _cli(["convert", "--haziness", paths["haziness"], "--out", str(tmp_path / "ok")], tmp_path)
    assert ok.returncode == 0 and ok.stderr.strip() == "", ok.stderr


@pytest.mark.parametrize("w", [float("inf"), 1e-9, 0.0, float("nan"), "2"])
def test_convert_maps_refuses_the_smoothness_make_hazy_refuses(api, core, tmp_path, w):
    paths, _ = make_inputs(tmp_path / "in")
    with pytest.raises(ValueError) as made:
        api.make_hazy(scenes.new_material("M"), smoothness=w)
    with pytest.raises(core.ConversionError) as info:
        api.convert_maps(paths, str(tmp_path / "out"), smoothness=w)
    assert str(info.value) == str(made.value)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("prefix", ["a\0b", "../x", "a/b", "a\\b", "..", ".hidden", "x\ny", 7])
def test_bad_prefix_is_one_line(api, core, tmp_path, prefix):
    paths, _ = make_inputs(tmp_path / "in")
    with pytest.raises(core.ConversionError, match="prefix must be") as info:
        api.convert_maps(paths, str(tmp_path / "out"), prefix=prefix)
    one_line(info.value)
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob("*beta*"))


def test_api_os_errors_are_conversion_errors(api, core, tmp_path):
    """Paths relative to a deleted current folder, NUL in a path: ConversionError, one line."""
    paths, _ = make_inputs(tmp_path / "in")
    gone = tmp_path / "gone"
    gone.mkdir()
    cwd = os.getcwd()
    os.chdir(gone)
    try:
        gone.rmdir()
        for inputs, out in ((paths, "relative_out"), ({"haziness": "h.png"}, str(tmp_path / "o"))):
            with pytest.raises(core.ConversionError, match="is relative and the current folder "
                                                           "cannot be read") as info:
                api.convert_maps(inputs, out)
            one_line(info.value)
    finally:
        os.chdir(cwd)
    with pytest.raises(core.ConversionError, match="out_dir .* contains a NUL character"):
        api.convert_maps(paths, str(tmp_path / "o\0x"))
    for bad in ("", "   ", None, 5):
        with pytest.raises(core.ConversionError, match="out_dir"):
            api.convert_maps(paths, bad)


def test_operator_fallback_folder_stays_inside(hg, clean_file, tmp_path, monkeypatch):
    """An unsaved file and a '//' folder: maps go to <temp>/hazy_gloss_maps/<material>; a
    material named '..' must not send them up one level."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "systmp"))
    (tmp_path / "systmp").mkdir()
    paths, _ = make_inputs(tmp_path / "in")
    base = tmp_path / "systmp" / "hazy_gloss_maps"
    for name, folder in (("..", "maps"), ("...", "maps"), (".hidden", "hidden"), ("a/../b", "a_.._b")):
        bpy.ops.wm.read_homefile(use_empty=True)
        bpy.ops.mesh.primitive_plane_add()
        mat = bpy.data.materials.new(name)
        bpy.context.object.data.materials.append(mat)
        assert bpy.ops.hazy_gloss.convert_maps(haziness_path=paths["haziness"]) == {"FINISHED"}
        assert (base / folder / "beta.exr").is_file(), (name, list(base.iterdir()))
    assert sorted(os.listdir(tmp_path / "systmp")) == ["hazy_gloss_maps"]


# --------------------------------------------------------------------------------------------
# 8. Scripting mistakes: one line naming the parameter and what is valid
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("change, pattern", [
    (dict(core_reflectivity="0.9,0.6,0.3"), r"core_reflectivity: '0.9,0.6,0.3' is a string and no "
                                            r"such file exists; .*core_reflectivity=\(0.9, 0.6, 0.3\)"),
    (dict(haziness="0.5"), r"haziness: '0.5' is a string .* haziness=0.5"),
    (dict(core_reflectivity=(255, 128, 0)), r"must be in \[0, 1\] \(colours are 0-1, not 0-255: .*"
                                            r"\(1.0, 0.502, 0.0\)"),
    (dict(edge_tint=(1, 0.5, 0.2, 1)), "RGB triple, got .* \\(drop alpha\\)"),
    (dict(haze_extent=(5, 3)), "haze_extent: expected a number, got .*haze_extent_x and "
                               "haze_extent_y"),
    (dict(hazyness=0.5), "unknown input 'hazyness' \\(did you mean 'haziness'\\?\\); accepted: "),
    (dict(haziness=np.zeros((N, N), np.uint8) + 200), r"haziness \(array\): integer array "
                                                      r"\(uint8\) .*divide by 255"),
    (dict(core_reflectivity=np.zeros((N, N, 4), np.float32)), r"expected shape \(H, W, 3\), got "
                                                               r"\(16, 16, 4\) \(drop alpha"),
    (dict(haziness=[[0.5]]), "haziness: expected an image path, .*got list"),
])
def test_input_mistakes_are_one_line(api, core, tmp_path, change, pattern):
    paths, _ = make_inputs(tmp_path / "in")
    with pytest.raises(core.ConversionError, match=pattern) as info:
        api.convert_maps(dict(paths, **change), str(tmp_path / "out"))
    one_line(info.value)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("options, pattern", [
    (dict(prefx="a_"), "unknown option 'prefx' \\(did you mean 'prefix'\\?\\); options: "),
    (dict(material="Gold"), r"material must be a bpy.types.Material or None, got str 'Gold' "
                            r"\(use bpy.data.materials\['Gold'\]\)"),
    (dict(interpolation="Bogus"), "interpolation must be one of Linear, Closest, Cubic"),
    (dict(progress=3), "progress must be None or a callable"),
    (dict(exr_codec="B44"), "exr_codec must be one of .*\\(lossless: NONE, ZIP"),
    (dict(resample="yes"), "resample must be True or False"),
    (dict(tile_texels=0), "tile_texels must be a positive integer"),
])
def test_option_mistakes_are_one_line_and_write_nothing(api, core, tmp_path, options, pattern):
    paths, _ = make_inputs(tmp_path / "in")
    with pytest.raises(core.ConversionError, match=pattern) as info:
        api.convert_maps(paths, str(tmp_path / "out"), **options)
    one_line(info.value)
    if "prefx" in options:
        assert isinstance(info.value, TypeError)
    assert not (tmp_path / "out").exists()


#: the add-on's Python calls and loop iterations one file check may take (work_bound): the
#: most a case takes is 281 (bpy 5.3); a check over 20000 has gone round in circles (a reader
#: rewritten to loop in Python per byte of a 40 x 40 image would pass it still: it bounds
#: hangs, not speed)
CHECK_WORK = 20_000


def fuzzed(data, rng):
    """``data`` (an image file's bytes) mutated once: cut short, a few bytes changed, or a random
    int32 where header fields live (benchmarks/time_limits.py times the same mutations)."""
    data = bytearray(data)
    op = rng.integers(4)
    if op == 0:
        data = data[:rng.integers(1, len(data))]
    elif op == 1:
        for _ in range(rng.integers(1, 8)):
            data[rng.integers(len(data))] = rng.integers(256)
    else:
        at = int(rng.integers(4, min(len(data), 400) - 4))
        data[at:at + 4] = struct.pack("<i", int(rng.integers(-2 ** 31, 2 ** 31)))
    return bytes(data)


def test_file_check_fuzz(binputs, hg, tmp_path):
    """4000 mutations (cuts, byte flips, random 32-bit fields) of an EXR, a PNG and a JPEG: the
    check returns or raises ConversionError, each within CHECK_WORK counted operations (the
    seconds are benchmarks/time_limits.py's), never anything else."""
    from stamp_fuzz import work_bound
    rng = np.random.default_rng(14)
    exr = _exr_bytes(tmp_path, n=40)
    png = Path(write_png(tmp_path / "f.png", np.arange(1600).reshape(40, 40) % 256, 8)).read_bytes()
    jpg = _jpeg_bytes(tmp_path)
    p = tmp_path / "fuzz.bin"
    outcomes = {"ok": 0, "refused": 0}
    most = 0
    with work_bound.Counter(only=[os.path.dirname(hg.__file__) + os.sep]) as work:
        for i in range(4000):
            p.write_bytes(fuzzed((exr, png, jpg)[i % 3], rng))
            try:
                work.run(binputs.check_readable, str(p), "fuzz", limit=CHECK_WORK)
                outcomes["ok"] += 1
            except binputs.ConversionError as exc:
                one_line(exc)
                outcomes["refused"] += 1
            most = max(most, work.count)
    assert outcomes["refused"] > 1000, outcomes
