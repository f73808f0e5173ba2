# SPDX-License-Identifier: GPL-3.0-or-later
"""The bpy-free part of the package never imports the Blender half or the facade (docs/
architecture.md, "The rule"): no module outside hazy_gloss/blender/ other than the entry points
(the package's ``__init__``, ``api``, ``__main__``) imports ``hazy_gloss.blender`` or
``hazy_gloss.api``, function-level imports included (read with tests/pure/layout_graph.py)."""
import layout_graph

ENTRY = {"hazy_gloss", "hazy_gloss.api", "hazy_gloss.__main__"}


def offenders(found):
    return [f"{i.source}:{i.line} imports {i.target}" for i in found
            if i.internal and i.source not in ENTRY and not i.source.startswith("hazy_gloss.blender")
            and (i.target == "hazy_gloss.api" or i.target == "hazy_gloss.blender"
                 or i.target.startswith("hazy_gloss.blender."))]


def test_bpy_free_part_imports_neither_blender_nor_api():
    bad = offenders(layout_graph.imports())
    assert not bad, bad


def test_the_check_sees_such_an_import():
    fake = layout_graph.Import("hazy_gloss.core.mapping", "hazy_gloss.blender.model.material", 3, True, True)
    assert offenders([fake]) == ["hazy_gloss.core.mapping:3 imports hazy_gloss.blender.model.material"]
