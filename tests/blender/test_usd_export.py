# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's own USD export with MaterialX networks finishes on hazy materials.

Blender's MaterialX writer recomputes a node for every path that reaches it when the node's
value is a constant: a deep reconvergent chain of math on constant inputs takes exponential
time, and Blender hung on the earlier layer group.  Each material is saved and exported by a
child Blender (the export may hang: a hang must fail the test, not stop the suite), with the
add-on enabled and without it (a farm, a pipeline machine).  How long an export takes is
measured in benchmarks/perf_layer_edit.py; here a generous timeout catches a hang.
"""
import json
import os
import subprocess
import sys

import bpy
import pytest

from test_layer import car_paint, metallic_map, principled

#: Seconds a child Blender gets to open the file and export it (the exports take well under
#: a second: docs/performance.md): anything near this is a hang.
TIMEOUT = 120

_CHILD = r'''
import json, sys, time
import bpy
blend, out, addon_dir = sys.argv[1], sys.argv[2], sys.argv[3]
if addon_dir:
    sys.path.insert(0, addon_dir)
    import hazy_gloss
    hazy_gloss.register()
bpy.ops.wm.open_mainfile(filepath=blend)
t = time.perf_counter()
bpy.ops.wm.usd_export(filepath=out, generate_materialx_network=True, export_materials=True)
print("INFO " + json.dumps({"seconds": time.perf_counter() - t}))
if addon_dir:  # (bpy 4.5 hangs at exit with a class registered once a file was opened)
    hazy_gloss.unregister()
'''


def _every_feature():
    mat, b = principled("Every Feature", **{"Coat Weight": 1.0, "Thin Film Thickness": 300.0,
                                             "Transmission Weight": 0.5, "Sheen Weight": 0.5,
                                             "Anisotropic": 0.5})
    return mat


MATERIALS = {
    "plastic": lambda: principled("Plastic", **{"Base Color": (0.2, 0.3, 0.6, 1.0),
                                                "Roughness": 0.3})[0],
    "plastic, Multiscatter GGX": lambda: principled("MS Plastic", distribution="MULTI_GGX")[0],
    "car paint": car_paint,
    "metallic map": metallic_map,
    "every feature": _every_feature,
}


@pytest.mark.parametrize("label", sorted(MATERIALS))
def test_usd_export_with_materialx_finishes(hg, clean_file, tmp_path, label):
    api = __import__(hg.__name__ + ".api", fromlist=["api"])
    mat = MATERIALS[label]()
    bpy.ops.mesh.primitive_uv_sphere_add()
    bpy.context.object.data.materials.append(mat)
    api.make_hazy(mat, haziness=0.4, coat_haziness=0.3)
    blend = str(tmp_path / "hazy.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    script = tmp_path / "export.py"
    script.write_text(_CHILD)
    env = dict(os.environ)
    env["BLENDER_USER_RESOURCES"] = str(tmp_path / "user")
    env.pop("PYTHONPATH", None)
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    for addon in ("", repo):  # without the add-on, then with it
        out = tmp_path / f"hazy{'_addon' if addon else ''}.usda"
        try:
            proc = subprocess.run([sys.executable, str(script), blend, str(out), addon],
                                  cwd=str(tmp_path), env=env, capture_output=True, text=True,
                                  timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            pytest.fail(f"Blender's USD export of {label} did not finish in {TIMEOUT} s "
                        f"({'with' if addon else 'without'} the add-on)")
        line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("INFO ")), None)
        assert proc.returncode == 0 and line, proc.stdout[-2000:] + proc.stderr[-2000:]
        json.loads(line[5:])
        text = out.read_text()
        assert "def Material" in text and "ND_" in text  # a material with a MaterialX network
