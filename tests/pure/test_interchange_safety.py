# SPDX-License-Identifier: GPL-3.0-or-later
"""The bpy-free side of interchange safety (tests/blender/test_cli_safety.py runs the CLI):
what the exporters refuse to write over, and the importer's notes for includes and an IOR
below 1 (QA round: a document with xi:include blamed the shader input; specular_ior 0 imported
as IOR 0.0 with no note)."""
from hazy_gloss.interchange import materialx as M
from hazy_gloss.interchange.document import read_xml

_SURFACE = """<?xml version="1.0"?>
<materialx version="1.39" xmlns:xi="http://www.w3.org/2001/XInclude">{extra}
  <{cat} name="SR" type="surfaceshader">{inputs}
  </{cat}>
  <surfacematerial name="M" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR"/>
  </surfacematerial>
</materialx>
"""


def _read(cat="open_pbr_surface", inputs="", extra=""):
    (im,) = M.recognise(read_xml(_SURFACE.format(cat=cat, inputs=inputs, extra=extra), text=True))
    return im


def test_includes_are_named_in_one_note():
    im = _read("standard_surface", '\n    <input name="base_color" type="color3" nodegraph="NG_lib" '
                                   'output="out"/>', '\n  <xi:include href="sub/lib.mtlx"/>')
    assert len(im.notes) == 1 and "xi:include of sub/lib.mtlx" in im.notes[0], im.notes
    assert "SR.base_color" in im.notes[0] and not im.exact
    plain = _read("standard_surface", "", '\n  <xi:include href="sub/lib.mtlx"/>')
    assert plain.notes == [] and plain.exact  # (nothing of it was in the include)


def test_an_ior_below_1_is_made_valid_with_a_note():
    for cat, name, value, expect in (("open_pbr_surface", "specular_ior", 0.0, 1000.0),
                                     ("open_pbr_surface", "specular_ior", 0.5, 2.0),
                                     ("gltf_pbr", "ior", 0.0, 1000.0),
                                     ("standard_surface", "specular_IOR", -1.0, 1000.0)):
        im = _read(cat, f'\n    <input name="{name}" type="float" value="{value}"/>')
        assert abs(im.surface.inputs["IOR"] - expect) < 1e-9, (cat, im.surface.inputs["IOR"])
        assert not im.exact and any(f"{name} {value:g} is below 1" in n for n in im.notes), im.notes
    ok = _read("open_pbr_surface", '\n    <input name="specular_ior" type="float" value="1.33"/>')
    assert ok.surface.inputs["IOR"] == 1.33 and not any("below 1" in n for n in ok.notes)


def test_output_problem(tmp_path):
    doc = tmp_path / "old.mtlx"
    doc.write_text('<?xml version="1.0"?>\n<!-- ours -->\n<materialx version="1.39"/>\n')
    usda = tmp_path / "old.usda"
    usda.write_text("#usda 1.0\n")
    blend = tmp_path / "scene.blend"
    blend.write_bytes(b"BLENDER-v405" + bytes(32))
    (tmp_path / "empty.mtlx").write_bytes(b"")
    assert M.output_problem(doc) is None and M.output_problem(usda, "usd") is None
    assert M.output_problem(tmp_path / "empty.mtlx") is None  # (nothing to lose)
    assert M.output_problem(tmp_path / "new" / "deeper" / "x.mtlx") is None  # (made)
    for path, kind, why in ((blend, "mtlx", "is not a MaterialX document"),
                            (blend, "usd", "writes .usd, .usda, .usdc"),
                            (doc, "usd", "writes .usd, .usda, .usdc"),
                            (tmp_path / "x.usda", "mtlx", None),
                            (tmp_path / "x.usdz", "usd", "cannot create a .usdz"),
                            (tmp_path, "mtlx", "is a folder"),
                            (blend / "x.mtlx", "mtlx", "is a file, not a folder")):
        problem = M.output_problem(path, kind)
        if why is None:
            assert problem is None, problem
            continue
        assert problem is not None and why in problem and str(path) in problem, (path, problem)
    usda.rename(tmp_path / "fake.usda")
    (tmp_path / "fake.usda").write_text(doc.read_text())
    assert "is not a USD layer" in M.output_problem(tmp_path / "fake.usda", "usd")
