# SPDX-License-Identifier: GPL-3.0-or-later
"""Writes tests/data/earlier_layers_4_5.blend: materials made hazy by the add-on as it was
before its layer groups held only the parts a material uses (commit 14be10a: one group of
about 1,200 nodes in section groups, stamp version 3), saved by bpy 4.5 (every supported
Blender opens it).  Run it from a checkout of that commit:

    git worktree add /tmp/hg_earlier 14be10a
    /tmp/hg_earlier/.venv45/bin/python tests/data/make_earlier_layers_45.py /tmp/hg_earlier

(the venv linked or made there).  tests/blender/test_layer_node.py opens it in each Blender:
it renders as saved, and each layer moves to today's group on its first haze edit."""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CHECKOUT = sys.argv[1] if len(sys.argv) > 1 else ROOT
sys.path.insert(0, CHECKOUT)
import bpy  # noqa: E402

import hazy_gloss  # noqa: E402

bpy.ops.wm.read_homefile(use_empty=True)
hazy_gloss.register()
from hazy_gloss import api  # noqa: E402


def principled(name, **inputs):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    mat.use_fake_user = True
    b = mat.node_tree.nodes["Principled BSDF"]
    b.distribution = inputs.pop("distribution", "GGX")
    for k, v in inputs.items():
        b.inputs[k].default_value = v
    return mat


plastic = principled("Earlier plastic", **{"Base Color": (0.1, 0.2, 0.5, 1.0), "Roughness": 0.3})
api.make_hazy(plastic, haziness=0.4, haze_extent=5.0)
paint = principled("Earlier car paint", distribution="MULTI_GGX",
                   **{"Metallic": 1.0, "Base Color": (0.6, 0.05, 0.05, 1.0), "Roughness": 0.35,
                      "Coat Weight": 1.0, "Coat Roughness": 0.05})
api.make_hazy(paint, haziness=0.3, coat_haziness=0.4)
out = os.path.join(ROOT, "tests", "data", "earlier_layers_4_5.blend")
bpy.ops.wm.save_as_mainfile(filepath=out, compress=True)
