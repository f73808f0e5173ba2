# SPDX-License-Identifier: GPL-3.0-or-later
"""One model: the haze layer on the kind's own BSDF renders the whole hazy material.

``api.create_material`` builds the paper's two lobes with values from Python (a whole hazy
material); Make Hazy puts the haze layer on an artist's BSDF. This test builds the BSDF an
artist would for the same perceptual parameters, from the paper's and Blender's relations
written out here (not the add-on's functions): a Metallic BSDF in Physical Conductor mode with
Gulbrandsen's printed η, κ; a Principled BSDF with IOR (1+√r̂)/(1-√r̂) of the max channel r̂
and Specular Tint r_c/r̂; a Glossy BSDF with colour r_c and the Glossy node's anisotropy for the same
α_x, α_y. Both are rendered on the plane of test_render_claims (each pixel is f_r cos θ
exactly) from five light directions. So that agreement cannot come from haze that shows
nowhere, the BSDF without its layer must render differently, and so must the whole material
without the case's feature (anisotropy, the Bézier halo).

Where the two agree to float32 rounding, the layer renders what the whole material renders;
test_render_claims holds the whole material to an independent Eq. 1 (test_analytic_agreement)
and to peak invariance, so the layer carries the paper's model for that kind
(docs/architecture.md, "One model"). Transmission is left out on purpose: the
whole material refracts at the raised IOR of its lobes, the layer keeps the artist's IOR and
raises F(0) through the Specular Tint (docs/mapping.md §13), so the two differ there by design
(1.2e-2 at Transmission Weight 0.5).
"""
import importlib
import math

import numpy as np
import pytest

import scenes
from measurements import record

#: the largest relative difference between the two forms (float32 rounding: 6.1e-7 measured);
#: what the haze and each case's feature change must be far larger
TOL = 1e-5
LIGHTS = [(0.0, 0.0), (10.0, 0.0), (25.0, 30.0), (40.0, 90.0), (60.0, 200.0)]
ROUGHNESS = 0.3
RC_METAL, EDGE = (0.9, 0.6, 0.3), (1.0, 0.8, 0.5)
RC_GLOSSY = (0.6, 0.5, 0.2)

#: id -> (kind, distribution, anisotropy, extra keywords of both forms)
CASES = {
    "conductor": ("CONDUCTOR", "GGX", 0.0, {}),
    "conductor, Multiscatter GGX": ("CONDUCTOR", "MULTI_GGX", 0.0, {}),
    "conductor, anisotropic": ("CONDUCTOR", "GGX", 0.6, {"haze_extent": (6.0, 2.0)}),
    "conductor, Beckmann": ("CONDUCTOR", "BECKMANN", 0.0, {}),
    "conductor, Bezier halo": ("CONDUCTOR", "GGX", 0.0, {"smoothness": 0.5}),
    "dielectric": ("DIELECTRIC", "GGX", 0.0, {}),
    "dielectric, Multiscatter GGX, anisotropic": ("DIELECTRIC", "MULTI_GGX", 0.6, {}),
    "dielectric, coloured r_c": ("DIELECTRIC", "GGX", 0.0, {"core_reflectivity": (0.06, 0.04, 0.02)}),
    "dielectric, base colour (diffuse body)": ("DIELECTRIC", "GGX", 0.0,
                                               {"base_color": (0.2, 0.4, 0.1)}),
    "glossy": ("LEGACY", "GGX", 0.0, {}),
    "glossy, Multiscatter GGX, anisotropic": ("LEGACY", "MULTI_GGX", 0.6, {}),
    "glossy, anisotropic halo": ("LEGACY", "GGX", 0.8, {"haze_extent": (7.0, 2.0)}),
    "dielectric, anisotropic halo": ("DIELECTRIC", "GGX", 0.6, {"haze_extent": (7.0, 2.0)}),
}


@pytest.fixture
def env(hg, clean_file):
    return importlib.import_module(f"{hg.__name__}.api")


def gulbrandsen(r, g):
    """Gulbrandsen 2014's printed (r, g) -> (η, κ), per channel."""
    r, g = np.asarray(r, np.float64), np.asarray(g, np.float64)
    eta = g * (1 - r) / (1 + r) + (1 - g) * (1 + np.sqrt(r)) / (1 - np.sqrt(r))
    kappa = np.sqrt((r * (eta + 1) ** 2 - (eta - 1) ** 2) / (1 - r))
    return eta, kappa


def glossy_anisotropy(a):
    """The Glossy BSDF's Anisotropy with the α_x, α_y of a Metallic / Principled Anisotropy a:
    those have α_y/α_x = 1 - 0.9 a; the Glossy node, for A < 0, α_y/α_x = (1 - |A|)²."""
    return -(1.0 - math.sqrt(1.0 - 0.9 * a))


def render_plane(mat, light):
    return scenes.centre(scenes.render_plane(mat, resolution=(4, 4), light_dir=light))


def artists_bsdf(kind, distribution, anisotropy, extra):
    """The BSDF an artist builds for these perceptual parameters."""
    mat, out = scenes.empty_material(f"artist {kind}")
    tree = mat.node_tree
    if kind == "CONDUCTOR":
        b = tree.nodes.new("ShaderNodeBsdfMetallic")
        b.fresnel_type = "PHYSICAL_CONDUCTOR"
        eta, kappa = gulbrandsen(RC_METAL, EDGE)
        values = {"IOR": tuple(map(float, eta)), "Extinction": tuple(map(float, kappa)),
                  "Anisotropy": anisotropy}
    elif kind == "DIELECTRIC":
        b = tree.nodes.new("ShaderNodeBsdfPrincipled")
        base = extra.get("base_color", (0.0, 0.0, 0.0))
        rc = np.broadcast_to(np.asarray(extra.get("core_reflectivity", 0.05), np.float64), 3)
        r_hat = float(rc.max())  # the IOR sets F(0) of the max channel, the tint the others
        values = {"IOR": (1 + math.sqrt(r_hat)) / (1 - math.sqrt(r_hat)),
                  "Base Color": base + (1.0,), "Specular IOR Level": 0.5,
                  "Specular Tint": tuple(float(c) for c in rc / r_hat) + (1.0,),
                  "Anisotropic": anisotropy}
    else:
        b = tree.nodes.new("ShaderNodeBsdfGlossy")
        values = {"Color": RC_GLOSSY + (1.0,),
                  "Anisotropy": glossy_anisotropy(anisotropy)}
    b.distribution = distribution
    values["Roughness"] = ROUGHNESS
    for name, v in values.items():
        b.inputs[name].default_value = v
    if anisotropy:
        t = tree.nodes.new("ShaderNodeTangent")
        t.direction_type = "UV_MAP"
        tree.links.new(t.outputs[0], b.inputs["Tangent"])
    tree.links.new(b.outputs[0], out.inputs["Surface"])
    return mat


def max_rel(a, b):
    return float(np.abs(b - a).max() / max(float(np.abs(a).max()), 1e-12))


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_layer_renders_the_whole_hazy_material(env, case):
    api = env
    kind, distribution, anisotropy, extra = CASES[case]
    haze = {"haziness": 0.08 if kind == "DIELECTRIC" else 0.6,
            "haze_extent": extra.get("haze_extent", 4.0)}
    if "smoothness" in extra:
        haze["smoothness"] = extra["smoothness"]
    own = {"CONDUCTOR": dict(core_reflectivity=RC_METAL, edge_tint=EDGE),
           "DIELECTRIC": dict(core_reflectivity=extra.get("core_reflectivity", 0.05),
                              base_color=extra.get("base_color", (0.0, 0.0, 0.0))),
           "LEGACY": dict(core_reflectivity=RC_GLOSSY)}[kind]
    shared = dict(kind=kind, distribution=distribution, roughness=ROUGHNESS, **own)
    whole = api.create_material("whole", anisotropy=anisotropy, **shared, **haze)
    plain = artists_bsdf(kind, distribution, anisotropy, extra)
    layered = artists_bsdf(kind, distribution, anisotropy, extra)
    notes = api.make_hazy(layered, **haze)
    # what the case's feature changes: without it the whole material renders otherwise
    without = None
    if anisotropy:
        without = api.create_material("isotropic", anisotropy=0.0, **shared,
                                      **dict(haze, haze_extent=4.0))
    elif "smoothness" in extra:
        without = api.create_material("Eq. 7", anisotropy=0.0, **shared,
                                      **{k: v for k, v in haze.items() if k != "smoothness"})
    worst, haze_shows, feature_shows, brightest = 0.0, 0.0, 0.0, 0.0
    for light in LIGHTS:
        a, b, c = (render_plane(m, light) for m in (whole, layered, plain))
        brightest = max(brightest, float(a.max()))
        worst = max(worst, max_rel(a, b))
        haze_shows = max(haze_shows, max_rel(a, c))
        if without is not None:
            feature_shows = max(feature_shows, max_rel(a, render_plane(without, light)))
    record("one_model", {case: worst})
    assert brightest > 0.05, brightest  # a lit render, not black
    assert haze_shows > 100 * TOL, haze_shows  # the haze changes the render
    if without is not None:
        assert feature_shows > 100 * TOL, feature_shows
    assert math.isfinite(worst) and worst <= TOL, (worst, list(notes))
    # and the layer reads back the perceptual parameters the whole material was made with
    read, made = api.read_parameters(layered), api.read_parameters(whole)
    assert read["kind"] == made["kind"]
    for key in ("core_reflectivity", "edge_tint", "roughness", "anisotropy", "haziness",
                "haze_extent"):
        np.testing.assert_allclose(np.asarray(read[key], float), np.asarray(made[key], float),
                                   rtol=0, atol=2e-6, err_msg=key)


@pytest.mark.parametrize("glossy, roughness", [(-0.471, 0.3), (-0.471, 0.95), (0.3, 0.9), (-0.995, 0.5)])
def test_a_glossy_layer_reads_back_the_perceptual_anisotropy(env, glossy, roughness):
    """read_parameters gives a Glossy core's anisotropy in the Metallic / Principled convention:
    the same axis ratio, (1 - |A|)² = 1 - 0.9 a (Glossy's A clamped to ±0.99, a to [0, 1]), the
    long axis along x (a positive A stretches y: a quarter turn more), whatever the roughness
    (Cycles clamps each α to 1 after, which the ratio does not see)."""
    mat, out = scenes.empty_material("glossy core")
    tree = mat.node_tree
    b = tree.nodes.new("ShaderNodeBsdfGlossy")
    b.inputs["Roughness"].default_value = roughness
    b.inputs["Anisotropy"].default_value = glossy
    b.inputs["Rotation"].default_value = 0.1
    tree.links.new(b.outputs[0], out.inputs["Surface"])
    env.make_hazy(mat, haziness=0.5)
    p = env.read_parameters(mat)
    k = 1.0 - min(abs(glossy), 0.99)
    want = min((1.0 - k * k) / 0.9, 1.0)
    assert p["anisotropy"] == pytest.approx(want, abs=1e-6)
    assert p["rotation"] == pytest.approx(0.1 + (0.25 if glossy > 0 else 0.0), abs=1e-6)
    assert p["roughness"] == pytest.approx(roughness, abs=1e-6)
