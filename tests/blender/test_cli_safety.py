# SPDX-License-Identifier: GPL-3.0-or-later
"""The interchange CLI (and the API under it) never loses, overwrites or half-writes a user's
file: bad output paths are one line and exit 2 before anything is written, a failed or
interrupted export leaves nothing behind, and what an import makes survives the save
(QA round: import --blend saved no materials, export over the input .blend, a .mtlx replaced
by a .blend, tracebacks and leftover temporaries / _tables folders)."""
import importlib
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

from test_convert import write_png

REPO_ROOT = Path(__file__).resolve().parents[2]

#: Two library surfaces; the glTF one reads a texture that is not there.
MTLX = """<?xml version="1.0"?>
<materialx version="1.39">
  <nodegraph name="NG">
    <image name="gone" type="color3">
      <input name="file" type="filename" value="does_not_exist.png"/>
    </image>
    <output name="out" type="color3" nodename="gone"/>
  </nodegraph>
  <gltf_pbr name="SR_tex" type="surfaceshader">
    <input name="base_color" type="color3" nodegraph="NG" output="out"/>
    <input name="roughness" type="float" value="0.4"/>
  </gltf_pbr>
  <surfacematerial name="M_tex" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR_tex"/>
  </surfacematerial>
  <standard_surface name="SR_plain" type="surfaceshader">
    <input name="base_color" type="color3" value="0.8, 0.2, 0.1"/>
  </standard_surface>
  <surfacematerial name="M_plain" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR_plain"/>
  </surfacematerial>
</materialx>
"""


@pytest.fixture
def api(hg, clean_file):
    return importlib.import_module(hg.__name__ + ".api")


@pytest.fixture
def cli(hg, clean_file):
    return importlib.import_module(hg.__name__ + ".__main__")


@pytest.fixture
def hazy_blend(api, tmp_path):
    """A saved .blend with a hazy material and a haze layer (whose export writes tables: its
    thin film's part reads the film's lookup table)."""
    api.create_material("Gold", kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3), haziness=0.5)
    layered = _filmed_material()
    api.make_hazy(layered, haziness=0.4)
    for m in bpy.data.materials:
        m.use_fake_user = True
    path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def _filmed_material():
    """A Principled material with a thin film: its haze layer's group reads a lookup table."""
    layered = bpy.data.materials.new("Layered")
    if bpy.app.version < (5, 0, 0):
        layered.use_nodes = True
    bsdf = next(n for n in layered.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Thin Film Thickness"].default_value = 300.0
    return layered


def _mtlx(tmp_path, name="lib.mtlx", text=MTLX):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _one_error(err, command):
    """The single line the CLI printed about a refusal (Blender's own chatter aside)."""
    assert "Traceback" not in err and "Error in '" not in err, err
    lines = [ln for ln in err.splitlines() if ln.startswith("hazy_gloss ")]
    assert len(lines) == 1 and lines[0].startswith(f"hazy_gloss {command}: error: "), err
    return lines[0]


def _listing(folder):
    return sorted(os.listdir(folder))


# --------------------------------------------------------------------------------------------
# import-materialx --blend
# --------------------------------------------------------------------------------------------


def test_import_blend_saves_the_materials(cli, api, tmp_path, capsys):
    """The saved file holds the imported materials (it held none: 0 users, no fake user); an
    existing --blend is added to; the API's materials survive a save of their own."""
    src = _mtlx(tmp_path)
    out = tmp_path / "imported.blend"
    assert cli.main(["import-materialx", str(src), "--blend", str(out), "--quiet"]) == 0
    bpy.ops.wm.open_mainfile(filepath=str(out))
    assert {"M_tex", "M_plain"} <= set(bpy.data.materials.keys())
    mine = bpy.data.materials.new("Mine")
    mine.use_fake_user = True
    bpy.ops.wm.save_as_mainfile(filepath=str(out))
    assert cli.main(["import-materialx", str(src), "--blend", str(out), "--quiet"]) == 0
    bpy.ops.wm.open_mainfile(filepath=str(out))
    assert "Mine" in bpy.data.materials and "M_plain" in bpy.data.materials
    bpy.ops.wm.read_homefile(use_empty=True)
    res = api.import_materialx(str(src))
    assert res and all(m.use_fake_user for m in res)
    again = tmp_path / "api.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(again))
    bpy.ops.wm.open_mainfile(filepath=str(again))
    assert {"M_tex", "M_plain"} <= set(bpy.data.materials.keys())


def test_import_blend_that_is_the_input_or_not_a_blend_is_refused(cli, tmp_path, capsys):
    src = _mtlx(tmp_path)
    before = src.read_bytes()
    (tmp_path / "sub").mkdir()
    for blend in (str(src), str(tmp_path / "sub" / ".." / "lib.mtlx"), str(tmp_path / "out.mtlx"),
                  str(tmp_path / "out.png")):
        capsys.readouterr()
        assert cli.main(["import-materialx", str(src), "--blend", blend]) == 2, blend
        _one_error(capsys.readouterr().err, "import-materialx")
        assert src.read_bytes() == before
    assert _listing(tmp_path) == ["lib.mtlx", "sub"]


def test_a_missing_texture_is_not_exact(cli, api, tmp_path, capsys):
    src = _mtlx(tmp_path)
    res = api.import_materialx(str(src))
    tex = next(im for im in res.report if im.name == "M_tex")
    assert any("not found" in n for n in tex.notes), tex.notes
    assert tex.exact is False and not tex.material["hazy_gloss_import"]["exact"]
    plain = next(im for im in res.report if im.name == "M_plain")
    assert plain.exact is True  # (nothing missing: still exact)
    capsys.readouterr()
    assert cli.main(["import-materialx", str(src), "--blend", str(tmp_path / "o.blend")]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("M_tex:"))
    assert "approximate" in line and "exact" not in line, line


# --------------------------------------------------------------------------------------------
# export-materialx: outputs refused before anything is written
# --------------------------------------------------------------------------------------------


def test_export_over_the_input_blend_is_refused(cli, hazy_blend, tmp_path, capsys):
    before = hazy_blend.read_bytes()
    for argv in (["export-materialx", str(hazy_blend), str(hazy_blend)],
                 ["export-materialx", str(hazy_blend), str(hazy_blend), "--usd"]):
        capsys.readouterr()
        assert cli.main(argv) == 2, argv
        _one_error(capsys.readouterr().err, "export-materialx")
        assert hazy_blend.read_bytes() == before
    assert _listing(tmp_path) == ["scene.blend"]


def test_export_over_a_file_of_another_kind_is_refused(cli, hazy_blend, tmp_path, capsys):
    """An existing file that is not the kind of document being written stays; re-exporting
    over an earlier export is allowed."""
    notes = tmp_path / "notes.mtlx"
    notes.write_text("my notes, not XML\n")
    image = tmp_path / "pic.usda"
    image.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(64))
    mtlx_as_usd = tmp_path / "doc.usda"
    mtlx_as_usd.write_text(MTLX)
    for out, extra in ((notes, []), (image, ["--usd"]), (mtlx_as_usd, ["--usd"])):
        before = out.read_bytes()
        capsys.readouterr()
        assert cli.main(["export-materialx", str(hazy_blend), str(out), *extra]) == 2, out
        line = _one_error(capsys.readouterr().err, "export-materialx")
        assert str(out) in line and "not overwritten" in line, line
        assert out.read_bytes() == before
    for out, extra in ((tmp_path / "x.mtlx", []), (tmp_path / "x.usda", ["--usd"])):
        for _ in range(2):  # the second run writes over the first export
            assert cli.main(["export-materialx", str(hazy_blend), str(out), *extra]) == 0, out
    assert not [n for n in os.listdir(tmp_path) if ".tmp" in n or n.endswith(".partial")]


def test_export_to_a_folder_or_a_bad_usd_name_leaves_nothing(cli, hazy_blend, tmp_path, capsys):
    folder = tmp_path / "outdir"
    folder.mkdir()
    for out, extra in ((folder, []), (folder, ["--usd"]), (tmp_path / "u.txt", ["--usd"]),
                       (tmp_path / "u.mtlx", ["--usd"]), (tmp_path / "u.usdz", ["--usd"])):
        capsys.readouterr()
        assert cli.main(["export-materialx", str(hazy_blend), str(out), *extra]) == 2, out
        line = _one_error(capsys.readouterr().err, "export-materialx")
        assert str(out) in line and ".tmp" not in line, line
    assert _listing(tmp_path) == ["outdir", "scene.blend"] and not os.listdir(folder)


@pytest.mark.parametrize("kind", ["mtlx", "usda"])
def test_a_failed_export_removes_what_it_wrote(api, hg, tmp_path, monkeypatch, kind):
    """A write that fails after the tables (the .mtlx's text cannot be encoded once its
    temporary exists; USD raises): the temporary, the tables this run wrote and the folder it
    made are removed; a tables folder that was there before stays, with its files."""
    ix = importlib.import_module(hg.__name__ + ".blender.actions.interchange")
    mx = importlib.import_module(hg.__name__ + ".interchange.materialx")
    usd = importlib.import_module(hg.__name__ + ".interchange.usd")
    document = importlib.import_module(hg.__name__ + ".interchange.document")
    layered = _filmed_material()
    api.make_hazy(layered, haziness=0.4)
    for module in (mx, document):  # (the writer's text, wherever it is taken from)
        monkeypatch.setattr(module, "to_xml_string", lambda doc: "<materialx>\ud800</materialx>",
                            raising=False)

    def broken(*args, **kw):
        raise RuntimeError("the USD network could not be made")

    monkeypatch.setattr(usd, "build_document", broken)
    export = api.export_usd if kind == "usda" else api.export_materialx
    out = tmp_path / "new" / f"x.{kind}"
    assert ix.write_tables([ix.source_of(layered)[0]], str(tmp_path / "probe.mtlx"))  # (has tables)
    shutil.rmtree(tmp_path / "probe_tables")
    with pytest.raises((ValueError, RuntimeError)):
        export(None, str(out))
    assert _listing(tmp_path) == []  # (the folder it made too)
    kept = tmp_path / "x_tables"
    kept.mkdir()
    (kept / "mine.txt").write_text("mine")
    with pytest.raises((ValueError, RuntimeError)):
        export(None, str(tmp_path / f"x.{kind}"))
    assert _listing(tmp_path) == ["x_tables"] and _listing(kept) == ["mine.txt"]


# --------------------------------------------------------------------------------------------
# convert --blend (PBR sets)
# --------------------------------------------------------------------------------------------


def _pbr_args(tmp_path):
    colour = write_png(tmp_path / "set_basecolor.png", np.full((16, 16), 30000), 16)
    return ["convert", "--base-color", colour, "--haziness", "0.3", "--out", str(tmp_path / "maps")]


def test_convert_blend_checked_before_converting(cli, tmp_path, capsys):
    """--blend in no folder (traceback, exit 1, 10 maps left), a non-.blend file (traceback from
    open_mainfile) and a damaged .blend: one line, exit 2, nothing written."""
    args = _pbr_args(tmp_path)
    (tmp_path / "pic.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(64))
    (tmp_path / "bad.blend").write_bytes(b"BLENDER-garbage")
    before = {p: (tmp_path / p).read_bytes() for p in ("pic.png", "bad.blend")}
    for blend in (tmp_path / "nofolder" / "x.blend", tmp_path / "pic.png", tmp_path / "bad.blend"):
        capsys.readouterr()
        assert cli.main([*args, "--blend", str(blend)]) == 2, blend
        _one_error(capsys.readouterr().err, "convert")
        assert not (tmp_path / "maps").exists() or not os.listdir(tmp_path / "maps"), blend
    assert {p: (tmp_path / p).read_bytes() for p in before} == before
    assert not (tmp_path / "nofolder").exists()


# --------------------------------------------------------------------------------------------
# Damaged USD, and a real CLI process interrupted by SIGINT
# --------------------------------------------------------------------------------------------


def test_garbage_usd_is_one_line(cli, tmp_path, capsys):
    bad = tmp_path / "bad.usda"
    bad.write_text("garbage here\nmore garbage\n")
    for argv in (["import-materialx", str(bad)], ["engines", str(bad)]):
        capsys.readouterr()
        assert cli.main(argv) == 2, argv
        line = _one_error(capsys.readouterr().err, argv[0])
        assert str(bad) in line and "not a valid usda layer" in line, line


_DRIVER = r"""
import os, signal, sys
from hazy_gloss.blender.actions import interchange as ix
from hazy_gloss.interchange import materialx as mx
real_tables, real_validate = ix.write_tables, mx.validate

def write_tables(*a, **kw):  # Ctrl+C once the tables are written, before the document
    out = real_tables(*a, **kw)
    os.kill(os.getpid(), signal.SIGINT)
    return out

def validate(path):  # Ctrl+C once the document is in place
    os.kill(os.getpid(), signal.SIGINT)
    return real_validate(path)

if sys.argv[1] == "tables":
    ix.write_tables = write_tables
else:
    mx.validate = validate
from hazy_gloss.__main__ import main
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize("when", ["tables", "validate"])
def test_export_interrupted_by_sigint(hazy_blend, tmp_path, when):
    """SIGINT during the export: one line, exit 130, no traceback; before the document is in
    place nothing is left (x_tables/ was), after it the export is complete and says so."""
    out = tmp_path / "s.mtlx"
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"),
               PYTHONPATH=str(REPO_ROOT), PYTHONDONTWRITEBYTECODE="1")
    r = subprocess.run([sys.executable, "-c", _DRIVER, when, "export-materialx", str(hazy_blend),
                        str(out)], cwd=str(tmp_path), env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 128 + signal.SIGINT, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("hazy_gloss ")]
    assert len(lines) == 1 and "interrupted (SIGINT)" in lines[0], r.stderr
    left = sorted(n for n in os.listdir(tmp_path) if n.startswith("s") and n != "scene.blend")
    if when == "tables":
        assert left == [] and "nothing was written" in lines[0], (left, lines)
    else:
        assert left == ["s.mtlx", "s_tables"] and "it is complete" in lines[0], (left, lines)
        assert "<materialx" in out.read_text()
