# SPDX-License-Identifier: GPL-3.0-or-later
"""core.thin_film against Cycles: the sensitivity table and rendered normal-incidence peaks.

Exact scene (scenes.plane_grid_scene): one unit plane per material seen straight down by an
orthographic camera, a delta sun along the normal, black world, 1 sample, the smallest pixel
filter, 0 bounces, distribution GGX: every pixel is f_r(n, n) cos θi = R(0) D(0) G / 4 with
D(0) = 1/(π α²), α = Roughness², G = 1.  The expected value uses core.thin_film's R(0) for the
running Blender.  Relative error |render / expected - 1|, with the expected R floored at 1e-3
(the truncated Airy series can clamp R to 0).
"""
import importlib
import itertools
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes
from measurements import record

VERSION = bpy.app.version
ROUGHNESS = 0.3
THICKNESS = (0.0, 0.05, 0.2, 0.5, 1.0, 5.0, 29.0, 31.0, 100.0, 250.0, 450.0, 700.0, 1000.0)
FILM_IOR = (1.0, 1.2, 1.33, 1.5, 2.0, 2.5)
METALS = (dict(base=(0.8, 0.8, 0.8), tint=(1.0, 1.0, 1.0)),
          dict(base=(0.95, 0.64, 0.54), tint=(0.9, 0.7, 0.5)),
          dict(base=(0.04, 0.5, 1.0), tint=(1.0, 1.0, 1.0)))
DIELECTRICS = (dict(ior=1.5, level=0.5, tint=(1.0, 1.0, 1.0)),
               dict(ior=1.45, level=0.8, tint=(1.0, 0.6, 0.3)),
               dict(ior=2.0, level=0.25, tint=(1.0, 1.0, 1.0)),
               dict(ior=1.0, level=0.5, tint=(1.0, 1.0, 1.0)),
               dict(ior=3.0, level=1.0, tint=(0.5, 0.8, 1.0)),
               dict(ior=1.5, level=0.5, tint=(3.0, 12.0, 30.0)))  # f0 tint saturates in blue
TOLERANCE = 1e-4


@pytest.fixture
def tf(hg, clean_file):
    return importlib.import_module(f"{hg.__name__}.core.thin_film")


def principled(name, **inputs):
    mat = scenes.new_material(name)
    tree = mat.node_tree
    for node in list(tree.nodes):
        if node.bl_idname != "ShaderNodeOutputMaterial":
            tree.nodes.remove(node)
    out = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"), None)
    out = out or tree.nodes.new("ShaderNodeOutputMaterial")
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.distribution = "GGX"
    values = {"Subsurface Weight": 0.0, "Coat Weight": 0.0, "Sheen Weight": 0.0,
              "Emission Strength": 0.0, "Transmission Weight": 0.0, "Anisotropic": 0.0,
              "Roughness": ROUGHNESS}
    values.update(inputs)
    for key, value in values.items():
        bsdf.inputs[key].default_value = value
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def metal(name, base, tint, thickness, film_ior):
    return principled(name, **{"Base Color": (*base, 1.0), "Metallic": 1.0, "IOR": 1.5,
                               "Specular Tint": (*tint, 1.0), "Thin Film Thickness": thickness,
                               "Thin Film IOR": film_ior})


def dielectric(name, ior, level, tint, thickness, film_ior):
    return principled(name, **{"Base Color": (0.0, 0.0, 0.0, 1.0), "Metallic": 0.0, "IOR": ior,
                               "Specular IOR Level": level, "Specular Tint": (*tint, 1.0),
                               "Thin Film Thickness": thickness, "Thin Film IOR": film_ior})


def render_grid(materials):
    """Pixel values (N, 3) of the materials, one plane each, rendered in one image."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    info = scenes.plane_grid_scene(materials)
    scenes.setup_render("CYCLES", samples=1, resolution=(info["side"], info["side"]), bounces=0)
    img = scenes.render_exr()[..., :3].astype(np.float64)
    out = np.zeros((len(materials), 3))
    for (row, col), i in np.ndenumerate(info["index"]):
        if i >= 0:
            out[i] = img[row, col]
    return out


def peak_scale():
    alpha = ROUGHNESS ** 2
    return 1.0 / (np.pi * alpha * alpha) / 4.0


def rel_error(pixels, reflectance):
    expected = reflectance * peak_scale()
    return np.abs(pixels - expected) / (np.maximum(np.abs(reflectance), 1e-3) * peak_scale())


def test_table_is_cycles_table(tf):
    """table_thin_film_cmf rebuilt from the CIE data = the wheel's ccl::table_thin_film_cmf,
    bit-exactly after Cycles' printing (%.7e) and float32 storage (5.0+; 4.5 has no table)."""
    if VERSION < (5, 0, 0):
        pytest.skip("Blender 4.5 uses the Gaussian fit, no table")
    root = Path(__file__).resolve().parents[2]
    sys.path.insert(0, str(root / "scripts"))
    try:
        elf = importlib.import_module("extract_ggx_tables")
    finally:
        sys.path.remove(str(root / "scripts"))
    so = next(p / "__init__.so" for p in Path(bpy.__file__).parents if (p / "__init__.so").exists())
    wheel = elf.read_symbol(so, "_ZN3cclL19table_thin_film_cmfE", 512 * 6).reshape(512, 6)
    ours = tf.cmf_fourier_table()
    printed = np.array([[float(f"{v: .7e}") for v in row] for row in ours], np.float32)
    assert np.array_equal(printed, wheel)
    record("thin_film", {"table_thin_film_cmf max |ours - wheel|":
                         float(np.abs(ours - wheel.astype(np.float64)).max())})


def _cases(kind):
    if kind == "metal":
        return [(p, d, n) for p in METALS for d, n in itertools.product(THICKNESS, FILM_IOR)]
    return [(p, d, n) for p in DIELECTRICS for d, n in itertools.product(THICKNESS, FILM_IOR)]


@pytest.mark.parametrize("kind", ["metal", "dielectric"])
def test_rendered_peak_matches_model(tf, kind):
    cases = _cases(kind)
    mats, expected = [], []
    for i, (p, d, n) in enumerate(cases):
        if kind == "metal":
            mats.append(metal(f"TF {i}", p["base"], p["tint"], d, n))
            expected.append(tf.metal_reflectance(p["base"], p["tint"], d, n, version=VERSION))
        else:
            mats.append(dielectric(f"TF {i}", p["ior"], p["level"], p["tint"], d, n))
            expected.append(tf.dielectric_reflectance(p["ior"], p["level"], p["tint"], d, n,
                                                      version=VERSION))
    pixels = render_grid(mats)
    err = rel_error(pixels, np.array(expected))
    worst = int(np.argmax(err.max(axis=1)))
    p, d, n = cases[worst]
    record("thin_film", {f"{kind} worst relative error": float(err.max()),
                         f"{kind} worst case": dict(p, thickness=d, film_ior=n),
                         f"{kind} cases": len(cases)})
    assert err.max() <= TOLERANCE, (err.max(), cases[worst], pixels[worst],
                                    np.array(expected[worst]) * peak_scale())
    # the film matters: the peak is not F0 (except 4.5's metals, which have no film)
    plain = np.array([p["base"] if kind == "metal" else np.minimum(
        np.array(p["tint"]) * 2 * p["level"] * ((p["ior"] - 1) / (p["ior"] + 1)) ** 2, 1.0)
        for p, _, _ in cases])
    moved = np.abs(pixels / peak_scale() - plain).max()
    if kind == "metal" and VERSION < (5, 0, 0):
        assert moved <= 1e-5
    else:
        assert moved > 0.05


@pytest.mark.parametrize("space", ["Linear Rec.2020", "ACEScg"])
def test_working_space(tf, space):
    """5.0+: the table follows the file's working space (bpy.data.colorspace.working_space)."""
    if VERSION < (5, 0, 0):
        pytest.skip("no working space setting before 5.0")
    old = bpy.data.colorspace.working_space
    bpy.ops.wm.set_working_color_space(working_space=space, convert_colors=False)
    assert bpy.data.colorspace.working_space == space
    try:
        cases = [(d, n) for d, n in itertools.product((250.0, 450.0, 1000.0), (1.33, 2.0))]
        mats = [metal(f"WS M {i}", (0.9, 0.6, 0.4), (1.0, 1.0, 1.0), d, n)
                for i, (d, n) in enumerate(cases)]
        mats += [dielectric(f"WS D {i}", 1.5, 0.5, (1.0, 1.0, 1.0), d, n)
                 for i, (d, n) in enumerate(cases)]
        pixels = render_grid(mats)
    finally:
        bpy.ops.wm.set_working_color_space(working_space=old, convert_colors=False)
    d, n = np.array(cases).T
    want = np.concatenate([
        tf.metal_reflectance((0.9, 0.6, 0.4), 1.0, d, n, version=VERSION, working_space=space),
        tf.dielectric_reflectance(1.5, 0.5, 1.0, d, n, version=VERSION, working_space=space)])
    other = np.concatenate([tf.metal_reflectance((0.9, 0.6, 0.4), 1.0, d, n, version=VERSION),
                            tf.dielectric_reflectance(1.5, 0.5, 1.0, d, n, version=VERSION)])
    err = rel_error(pixels, want)
    record("thin_film", {f"working space {space} worst relative error": float(err.max())})
    assert err.max() <= TOLERANCE, err.max()
    assert rel_error(pixels, other).max() > 10 * TOLERANCE  # Rec.709's table would be wrong


def test_inverse_renders_the_target(tf):
    """Base Color / IOR (+ Specular Tint) from the inverses render the asked-for peak."""
    target = np.array([0.55, 0.42, 0.30])
    films = [(250.0, 1.33), (450.0, 1.33), (700.0, 2.0)]
    mats, want = [], []
    for i, (d, n) in enumerate(films):
        base, ok = tf.metal_base_for_reflectance(target, 1.0, d, n, version=VERSION)
        if ok.all():
            mats.append(metal(f"Inv M {i}", tuple(base), (1.0, 1.0, 1.0), d, n))
            want.append(target)
        t = target * 0.2
        ior, ok = tf.dielectric_ior_for_reflectance(t, 0.5, 1.0, d, n, weights=(0.2126, 0.7152, 0.0722),
                                                    version=VERSION)
        tint, ok2 = tf.dielectric_tint_for_reflectance(t, ior, 0.5, d, n, version=VERSION)
        if ok and ok2.all():
            mats.append(dielectric(f"Inv D {i}", float(ior), 0.5, tuple(tint), d, n))
            want.append(t)
    assert len(mats) >= 4
    err = rel_error(render_grid(mats), np.array(want))
    record("thin_film", {"inverse render worst relative error": float(err.max())})
    assert err.max() <= TOLERANCE
