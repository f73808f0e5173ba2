# SPDX-License-Identifier: GPL-3.0-or-later
"""Writes tests/data/animated_layer_4_5.blend: a haze layer node with keyframes and drivers on
its inputs, saved by bpy 4.5 beside a plain Principled BSDF of the same name (what triggers
Blender 5.2's shift of the layer node's curves, blender/actions/sync.THIN_WALL_SHIFT):

    .venv45/bin/python tests/data/make_animated_layer_45.py

Each material records the input every curve of its tree drives ("expected_curves", JSON:
[[data path, array index, input name], ...]) and the file is saved at frame 5, where the
inputs hold the curves' values.  tests/blender/test_layer_node.py opens it in each Blender."""
import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT)
import bpy  # noqa: E402

import hazy_gloss  # noqa: E402

bpy.ops.wm.read_homefile(use_empty=True)
hazy_gloss.register()
from hazy_gloss import api  # noqa: E402

plain = bpy.data.materials.new("Plain")
plain.use_nodes = True
plain.use_fake_user = True  # (its BSDF is named "Principled BSDF", as the layer node)
mat = bpy.data.materials.new("Animated layer")
mat.use_nodes = True
mat.use_fake_user = True
api.make_hazy(mat, haziness=0.3, coat_haziness=0.2)
node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup")
assert node.name == "Principled BSDF", node.name
keys = {"Base Color": ((1, (0.8, 0.1, 0.1, 1.0)), (10, (0.1, 0.2, 0.8, 1.0))),
        "Coat Weight": ((1, 0.2), (10, 0.9)), "Emission Strength": ((1, 0.0), (10, 2.0)),
        "Haziness": ((1, 0.1), (10, 0.7)), "Haze Extent X": ((1, 3.0), (10, 9.0)),
        "Haze Extent Y": ((1, 5.0), (10, 12.0))}
for name, frames in keys.items():
    for frame, value in frames:
        node.inputs[name].default_value = value
        node.inputs[name].keyframe_insert("default_value", frame=frame)
fc = node.inputs["Coat Roughness"].driver_add("default_value")
fc.driver.expression = "frame / 100"
scene = bpy.context.scene
mesh = bpy.data.meshes.new("Plane")
mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
mesh.materials.append(mat)
scene.collection.objects.link(bpy.data.objects.new("Plane", mesh))
scene.frame_set(5)  # (the object's material is evaluated: its inputs get frame 5's values)
if abs(node.inputs["Haze Extent X"].default_value - 9.0) < 1e-6:  # (frame 10's: not evaluated)
    print("the material was not evaluated at frame 5")
    sys.stdout.flush()
    os._exit(1)
tree = mat.node_tree
curves = list(tree.animation_data.drivers) + list(tree.animation_data.action.fcurves)
mat["expected_curves"] = json.dumps(
    [[c.data_path, c.array_index, tree.path_resolve(c.data_path.rsplit(".", 1)[0]).name]
     for c in curves])
out = os.path.join(ROOT, "tests", "data", "animated_layer_4_5.blend")
bpy.ops.wm.save_as_mainfile(filepath=out, compress=True)
if os.path.exists(out + "1"):
    os.remove(out + "1")
print("wrote", out, len(curves), "curves")
sys.stdout.flush()
os._exit(0)
