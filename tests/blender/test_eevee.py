# SPDX-License-Identifier: GPL-3.0-or-later
"""EEVEE renders the same hazy node trees without errors; its difference to Cycles is measured
(recorded in out/measurements/eevee_vs_cycles.json), not asserted equal: EEVEE approximates the
conductor Fresnel, uses LTC lights and ignores anisotropy (BLENDER-FACTS.md).

One EEVEE render for all materials (three planes in one frame): EEVEE's first render compiles
shaders (~30 s headless), so the suite keeps it to one."""
import importlib
import math

import bpy
import numpy as np

import scenes
from measurements import record

MATERIALS = {
    "conductor lean": dict(kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5),
                           haziness=0.8, haze_extent=5.0, roughness=0.3),
    "conductor in-shader": dict(kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5),
                                haziness=0.8, haze_extent=5.0, roughness=0.3, shader_mapping=True),
    "dielectric in-shader": dict(kind="DIELECTRIC", core_reflectivity=0.04, haziness=0.1, haze_extent=5.0,
                                 roughness=0.3, shader_mapping=True, smoothness=2.0),
}


def _scene(api):
    bpy.ops.wm.read_homefile(use_empty=True)
    for i, (name, params) in enumerate(MATERIALS.items()):
        mat = api.create_material(name, **params)
        # off-centre by a fraction of a pixel: a ray through a triangle diagonal can miss
        bpy.ops.mesh.primitive_plane_add(size=1.0, location=(1.2 * (i - 1) + 0.0137, 0.0213, 0.0))
        bpy.context.object.data.materials.append(mat)
    cam = bpy.data.cameras.new("cam")
    cam.type = "ORTHO"
    cam.ortho_scale = 3.6
    cam_obj = bpy.data.objects.new("cam", cam)
    bpy.context.scene.collection.objects.link(cam_obj)
    cam_obj.location = (0.0, 0.0, 5.0)
    bpy.context.scene.camera = cam_obj
    sun = bpy.data.lights.new("sun", "SUN")
    sun.angle = 0.0
    sun.energy = 1.0
    sun_obj = bpy.data.objects.new("sun", sun)
    bpy.context.scene.collection.objects.link(sun_obj)
    sun_obj.rotation_euler = (math.radians(25.0), 0.0, 0.0)


def _regions(img):
    w = img.shape[1]
    centres = [int(w / 2 + (i - 1) * 1.2 / 3.6 * w) for i in range(3)]
    h = img.shape[0] // 2
    return [img[h - 2:h + 2, c - 2:c + 2, :3].reshape(-1, 3).mean(axis=0) for c in centres]


def test_eevee_renders_and_difference_is_measured(hg, clean_file):
    api = importlib.import_module(hg.__name__ + ".api")
    _scene(api)
    scenes.setup_render("CYCLES", samples=1, resolution=(96, 32), bounces=0)
    cycles = _regions(scenes.render_exr())
    _scene(api)
    scenes.eevee_setup(samples=1, resolution=(96, 32))
    img = scenes.render_exr()
    assert np.isfinite(img).all()
    eevee = _regions(img)
    result = {}
    for name, c, e in zip(MATERIALS, cycles, eevee):
        assert c.min() > 0 and e.min() > 0, (name, c, e)  # both lit, nothing black or NaN
        result[name] = {"cycles": c.tolist(), "eevee": e.tolist(), "eevee/cycles": (e / c).tolist()}
    record("eevee_vs_cycles", result)
