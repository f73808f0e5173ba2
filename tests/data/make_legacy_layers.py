# SPDX-License-Identifier: GPL-3.0-or-later
"""Writes tests/data/legacy_layers_v1.blend: materials with the haze layer of the add-on as it was
at commit c06288a (loose nodes in the artist's tree, LAYER_VERSION 1), saved by bpy 4.5 so that
every supported Blender opens it.  It only runs against that commit's code:

    git worktree add /tmp/hg_c06288a c06288a
    /tmp/hg_c06288a/.venv45/bin/python tests/data/make_legacy_layers.py /tmp/hg_c06288a

tests/blender/test_layer_upgrade.py opens the file and checks that it renders the same before and
after the layer is upgraded to the node group."""
import importlib
import os
import sys

root = os.path.abspath(sys.argv[1])
sys.path.insert(0, root)
sys.path.insert(0, os.path.join(root, "tests", "blender"))
import bpy  # noqa: E402

import hazy_gloss  # noqa: E402

bpy.ops.wm.read_homefile(use_empty=True)
hazy_gloss.register()
api = importlib.import_module("hazy_gloss.api")
sys.modules.setdefault("measurements", type(sys)("measurements"))
sys.modules["measurements"].record = lambda *a, **k: None
T = importlib.import_module("test_layer")

made = {
    "legacy metallic map": (T.metallic_map(name="legacy metallic map"),
                            dict(haziness=0.5, coat_haziness=0.0)),
    "legacy car paint": (T.car_paint(), dict(haziness=0.4, coat_haziness=0.3, coat_haze_extent=4.0)),
    "legacy rusty metal": (T.rusty_metal(), dict(haziness=0.3, haze_extent=(6.0, 6.0))),
    "legacy Metallic F82": (T.metallic_node("F82"), dict(haziness=0.6)),
    "legacy Glossy": (T.glossy_node(), dict(haziness=0.5)),
    "legacy Multiscatter": (T.multiscatter_metal(), dict(haziness=0.7)),
}
for name, (mat, haze) in made.items():
    mat.name = name
    api.make_hazy(mat, **haze)
    mat.use_fake_user = True
for img in bpy.data.images:  # generated test images keep their pixels only when packed
    img.pack()
out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "legacy_layers_v1.blend")
bpy.ops.wm.save_as_mainfile(filepath=out, compress=True)
if os.path.exists(out + "1"):
    os.remove(out + "1")
print("wrote", out, sorted(made))
sys.stdout.flush()
os._exit(0)  # (that code's interpreter exit can hang on its timer)
