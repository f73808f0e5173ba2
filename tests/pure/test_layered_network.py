# SPDX-License-Identifier: GPL-3.0-or-later
"""Haze layers in MaterialX without Blender: the OpenPBR corrections against MaterialX's own
open_pbr_surface graph (evaluated from the installed library, tests/pure/mx_eval.py), the
node-math translation against Cycles' semantics (core.graph.evaluate), the writer on trees
built by hand, and the measured Principled / OpenPBR differences docs/interchange.md quotes."""
import math

import MaterialX as mx
import numpy as np
import pytest
from MaterialX import PyMaterialXGenGlsl as mx_glsl
from MaterialX import PyMaterialXGenShader as mx_gen

import mx_eval
import openpbr_measure as measure
from hazy_gloss.core.graph import Graph, evaluate, ramp_table
from hazy_gloss.interchange import layered as L
from hazy_gloss.interchange import materialx as M
from hazy_gloss.interchange.brdf import fresnel_dielectric


@pytest.fixture(scope="module")
def lib():
    doc = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), doc)
    return doc


def _openpbr(lib, n, **iface):
    return mx_eval.Evaluator(lib.getNodeGraph("NG_open_pbr_surface_surfaceshader"), n,
                             interface=iface, library=lib)


# --------------------------------------------------------------------------------------------
# The corrections: what we write, fed through MaterialX's own open_pbr_surface graph
# --------------------------------------------------------------------------------------------


def test_alpha_and_ior_corrections_invert_the_library_graph(lib):
    """specular_roughness / anisotropy / IOR written for a Principled BSDF give, in the library's
    open_pbr_surface (main_roughness: coat roughening then open_pbr_anisotropy; eta_s: the
    coat-relative IOR), Cycles' α_x = R²/s, α_y = R² s (s = √(1-0.9a), clamped at 1) and the
    Principled IOR."""
    rng = np.random.default_rng(11)
    n = 4000
    R, A = rng.uniform(0.0, 1.0, n), rng.uniform(0.0, 1.0, n)
    C = np.where(rng.uniform(size=n) < 0.5, 0.0, rng.uniform(0.0, 0.3, n))
    W = np.where(rng.uniform(size=n) < 0.3, 1.0, rng.uniform(0.0, 1.0, n))
    ETA, EC = rng.uniform(1.0, 8.0, n), rng.uniform(1.0, 9.0, n)
    rows = []
    for r, a, c, w, e, ec in zip(R, A, C, W, ETA, EC):
        ax, ay = L.principled_alpha(r, a)
        re_, ao = L.openpbr_inverse(ax, ay)
        ro, res_r = L.coat_roughness_inverse(re_, c, w)
        eo, res_e = L.coat_ior_inverse(e, ec, w)
        rows.append((ro, ao, eo, ax, ay, res_r, res_e))
    ro, ao, eo, ax, ay, res_r, res_e = map(np.array, zip(*rows))
    ev = _openpbr(lib, n, specular_roughness=ro, specular_roughness_anisotropy=ao, coat_roughness=C,
                  coat_weight=W, specular_ior=eo, coat_ior=EC)
    alpha = np.minimum(ev.value("main_roughness").astype(np.float64), 1.0)  # the BSDFs clamp α at 1
    eta = ev.value("eta_s").astype(np.float64)
    ok_r = np.abs(res_r) < 1e-12
    ok_e = np.abs(res_e) < 1e-9
    err_a = np.max(np.abs(alpha - np.stack([ax, ay], -1)) / np.stack([ax, ay], -1), axis=1)
    assert err_a[ok_r].max() < 2e-6  # float32 graph
    assert np.max(np.abs(eta[ok_e] / ETA[ok_e] - 1.0)) < 2e-6
    # coat weight 1 (the usual coat) is always reachable; where a coat this rough roughens the
    # base beyond its roughness, or a partial coat weight cannot make the IOR this low, the
    # residual is what the library's graph gives
    assert np.all(ok_e[W == 1.0]) and ok_r[C == 0.0].all()
    assert np.allclose(eta[~ok_e] - ETA[~ok_e], res_e[~ok_e], rtol=1e-5, atol=1e-5)
    assert ok_r.mean() > 0.9 and ok_e.mean() > 0.8


def test_coat_darkening_formula_is_the_librarys(lib):
    """The darkening coat_darkening = 0 turns off, as MaterialX's graph computes it."""
    n = 64
    rng = np.random.default_rng(2)
    base = rng.uniform(0.0, 1.0, (n, 3))
    ior = rng.uniform(1.2, 9.0, n)
    ev = _openpbr(lib, n, coat_ior=ior, base_color=base, specular_weight=np.ones(n),
                  subsurface_color=base, subsurface_weight=np.zeros(n), base_metalness=np.ones(n))
    got = ev.value("base_darkening").astype(np.float64)
    want = np.array([measure.coat_darkening_factor(b, e) for b, e in zip(base, ior)])
    assert np.allclose(got, want, rtol=1e-5)


# --------------------------------------------------------------------------------------------
# Trees by hand: the writer
# --------------------------------------------------------------------------------------------


def S(ident, type_, value=None, link=None, name=None):
    return L.Socket(ident, name or ident, type_, value, link)


def principled(name, core=False, **values):
    base = {"Base Color": (0.8, 0.8, 0.8, 1.0), "Metallic": 0.0, "Roughness": 0.5, "IOR": 1.5,
            "Alpha": 1.0, "Normal": (0.0, 0.0, 0.0), "Diffuse Roughness": 0.0,
            "Subsurface Weight": 0.0, "Subsurface Radius": (1.0, 0.2, 0.1), "Subsurface Scale": 0.05,
            "Subsurface Anisotropy": 0.0, "Specular IOR Level": 0.5,
            "Specular Tint": (1.0, 1.0, 1.0, 1.0), "Anisotropic": 0.0, "Anisotropic Rotation": 0.0,
            "Tangent": (0.0, 0.0, 0.0), "Transmission Weight": 0.0, "Coat Weight": 0.0,
            "Coat Roughness": 0.03, "Coat IOR": 1.5, "Coat Tint": (1.0, 1.0, 1.0, 1.0),
            "Coat Normal": (0.0, 0.0, 0.0), "Sheen Weight": 0.0, "Sheen Roughness": 0.5,
            "Sheen Tint": (1.0, 1.0, 1.0, 1.0), "Emission Color": (1.0, 1.0, 1.0, 1.0),
            "Emission Strength": 0.0, "Thin Film Thickness": 0.0, "Thin Film IOR": 1.33}
    links = values.pop("links", {})
    base.update(values)
    types = {k: ("RGBA" if isinstance(v, tuple) and len(v) == 4 else
                 "VECTOR" if isinstance(v, tuple) else "VALUE") for k, v in base.items()}
    ins = [S(k, types[k], v, links.get(k)) for k, v in base.items()]
    return L.BNode(name, "ShaderNodeBsdfPrincipled", ins, [S("BSDF", "SHADER")],
                   {"distribution": "GGX", "subsurface_method": "RANDOM_WALK"}, core=core)


def mix(name, fac, a, b):
    fac_s = S("Fac", "VALUE", fac if not isinstance(fac, tuple) else 0.5,
              fac if isinstance(fac, tuple) else None, name="Factor")
    return L.BNode(name, "ShaderNodeMixShader",
                   [fac_s, S("Shader", "SHADER", None, (a, "BSDF")), S("Shader_001", "SHADER", None, (b, "BSDF"))],
                   [S("Shader", "SHADER")])


def output(src, ident="BSDF"):
    return L.BNode("Material Output", "ShaderNodeOutputMaterial",
                   [S("Surface", "SHADER", None, (src, ident)), S("Volume", "SHADER"),
                    S("Displacement", "VECTOR", (0.0, 0.0, 0.0))], [], {"target": "ALL"})


def tree(*nodes, out):
    t = L.Tree("Hand", {n.name: n for n in nodes})
    t.nodes["Material Output"] = out
    t.output = "Material Output"
    return t


def write(t, tmp_path, lib):
    path = tmp_path / "hand.mtlx"
    rep = M.write([M.Source(t.name, layer=t)], path, validate_with_package=False)
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    doc.importLibrary(lib)
    ok, msg = doc.validate()
    assert ok, msg
    return doc, rep


def test_a_hand_made_layer_validates_and_generates(tmp_path, lib):
    core = principled("Core", core=True, Roughness=0.3, IOR=2.2, **{"Coat Weight": 1.0, "Coat IOR": 3.0,
                                                                   "Coat Roughness": 0.1, "Anisotropic": 0.4})
    wide = principled("HG layer dielectric wide", Roughness=0.7, IOR=2.2,
                      **{"Coat Weight": 1.0, "Coat IOR": 3.0, "Coat Roughness": 0.1, "Anisotropic": 0.4})
    t = tree(core, wide, mix("HG layer Mix dielectric", 0.3, "Core", "HG layer dielectric wide"),
             out=output("HG layer Mix dielectric", "Shader"))
    t.nodes["Material Output"].inputs[0].link = ("HG layer Mix dielectric", "Shader")
    doc, rep = write(t, tmp_path, lib)
    gen = mx_glsl.GlslShaderGenerator.create()
    ctx = mx_gen.GenContext(gen)
    ctx.registerSourceCodeSearchPath(mx.getDefaultDataSearchPath())
    m = [m for m in doc.getMaterialNodes() if not m.hasSourceUri()][0]
    assert gen.generate(m.getName(), m, ctx) is not None
    ng = doc.getNodeGraph("NG_Hand")
    mx_mix = ng.getNode("HG_layer_Mix_dielectric")
    assert mx_mix.getInput("fg").getConnectedNode().getName() == "HG_layer_dielectric_wide"
    assert mx_mix.getInput("bg").getConnectedNode().getName() == "Core"
    assert float(mx_mix.getInputValue("mix")) == pytest.approx(0.3)
    for name, r in (("Core", 0.3), ("HG_layer_dielectric_wide", 0.7)):
        n = ng.getNode(name)
        v = {i.getName(): i.getValue() for i in n.getInputs() if i.getValueString()}
        ev = _openpbr(lib, 1, **{k: np.array([v[k]]) for k in (
            "specular_roughness", "specular_roughness_anisotropy", "coat_roughness", "coat_weight",
            "specular_ior", "coat_ior")})
        assert np.allclose(ev.value("main_roughness")[0], L.principled_alpha(r, 0.4), rtol=2e-6)
        assert ev.value("eta_s")[0] == pytest.approx(2.2, rel=2e-6)
        assert v["coat_darkening"] == 0.0 and v["coat_ior"] == pytest.approx(3.0)
        assert n.getInput("geometry_tangent").getConnectedNode() is not None  # anisotropic
    assert not rep.notes


def _math(name, op, a, b=0.0, c=0.0, clamp=False):
    def sock(i, v):
        if isinstance(v, tuple) and isinstance(v[0], str):
            return S(f"Value_{i}" if i else "Value", "VALUE", 0.0, v, name="Value")
        return S(f"Value_{i}" if i else "Value", "VALUE", float(v), name="Value")
    return L.BNode(name, "ShaderNodeMath", [sock(0, a), sock(1, b), sock(2, c)],
                   [S("Value", "VALUE")], {"operation": op, "use_clamp": clamp})


OPS = [("ADD", 2), ("SUBTRACT", 2), ("MULTIPLY", 2), ("DIVIDE", 2), ("MULTIPLY_ADD", 3),
       ("POWER", 2), ("SQRT", 1), ("MINIMUM", 2), ("MAXIMUM", 2), ("LESS_THAN", 2),
       ("GREATER_THAN", 2), ("COMPARE", 3), ("ABSOLUTE", 1), ("FLOOR", 1), ("SINE", 1),
       ("COSINE", 1), ("EXPONENT", 1)]  # (EXPONENT: the export raised KeyError)


@pytest.mark.parametrize("op,arity", OPS)
@pytest.mark.parametrize("const_b", [None, 0.0, 2.0, 0.5, -1.0, 3.0])
def test_math_nodes_keep_cycles_semantics(tmp_path, lib, op, arity, const_b):
    """One Math node fed by a texture (an image node the evaluator is given) against
    core.graph.evaluate (Cycles' SVM semantics: safe division, safe power, square root of a
    negative = 0, COMPARE with ε), over values that hit the edge cases."""
    x = np.array([-2.0, -1.0, -0.5, 0.0, 0.0, 1e-7, 0.25, 0.5, 1.0, 2.0, 3.0], np.float32)
    y = np.array([0.0, 2.0, 0.5, 0.0, -3.0, 1e-7, 0.25, 0.0, 1.0, -0.5, 3.0], np.float32)
    img = L.BNode("tex", "ShaderNodeTexImage", [S("Vector", "VECTOR")],
                  [S("Color", "RGBA"), S("Alpha", "VALUE")],
                  {"interpolation": "Linear", "extension": "REPEAT", "projection": "FLAT"},
                  image=dict(name="t", path=str(tmp_path / "t.exr"), colorspace="Non-Color", is_data=True))
    img2 = L.BNode("tex2", "ShaderNodeTexImage", [S("Vector", "VECTOR")],
                   [S("Color", "RGBA"), S("Alpha", "VALUE")], {},
                   image=dict(name="u", path=str(tmp_path / "u.exr"), colorspace="Non-Color", is_data=True))
    b = ("tex2", "Color") if const_b is None else const_b
    node = _math("Math", op, ("tex", "Color"), b, 0.25, clamp=(op == "SUBTRACT"))
    core = principled("Core", core=True, links={"Roughness": ("Math", "Value")})
    t = tree(img, img2, node, core, out=output("Core"))
    doc, _ = write(t, tmp_path, lib)
    ng = doc.getNodeGraph("NG_Hand")
    ev = mx_eval.Evaluator(ng, x.size, {"tex": np.repeat(x[:, None], 3, 1), "tex2": np.repeat(y[:, None], 3, 1)})
    got = ev.value("Core", "specular_roughness").astype(np.float64)
    g = Graph()
    xa = g.input("x")
    yb = g.input("y") if const_b is None else const_b
    args = (xa, yb, 0.25)[:arity]
    e = g.math(op, *args, clamp=(op == "SUBTRACT"))
    want = np.clip(evaluate(e, {"x": x, "y": y}), 0.0, 1.0)  # the Principled saturates Roughness
    assert np.allclose(got, want, rtol=1e-6, atol=1e-7), (op, const_b, got, want)


def test_color_ramp_is_the_table_cycles_looks_up(tmp_path, lib):
    """A 32-stop linear Color Ramp (as the Multiscatter GGX node math has) against
    core.graph's 256-entry table lookup."""
    rng = np.random.default_rng(5)
    pos = np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0, 1, 30)]))
    cols = rng.uniform(0, 1, (32, 3))
    stops = tuple((float(p), tuple(float(c) for c in col)) for p, col in zip(pos.astype(np.float32), cols.astype(np.float32)))
    ramp = L.BNode("Ramp", "ShaderNodeValToRGB", [S("Fac", "VALUE", 0.0, ("tex", "Alpha"))],
                   [S("Color", "RGBA"), S("Alpha", "VALUE")],
                   ramp=dict(color_mode="RGB", interpolation="LINEAR",
                             elements=[(p, c + (1.0,)) for p, c in stops]))
    alpha = S("Alpha", "VALUE")
    alpha.linked = True  # the Alpha output: the Fac without a colour -> float conversion
    img = L.BNode("tex", "ShaderNodeTexImage", [S("Vector", "VECTOR")], [S("Color", "RGBA"), alpha], {},
                  image=dict(name="t", path=str(tmp_path / "t.exr"), colorspace="Non-Color", is_data=True))
    core = principled("Core", core=True, links={"Base Color": ("Ramp", "Color")})
    doc, _ = write(tree(img, ramp, core, out=output("Core")), tmp_path, lib)
    x = np.concatenate([np.linspace(-0.1, 1.1, 1201), pos]).astype(np.float32)
    ev = mx_eval.Evaluator(doc.getNodeGraph("NG_Hand"), x.size, {"tex": np.repeat(x[:, None], 4, 1)})
    got = ev.value("Core", "base_color").astype(np.float64)
    # Blender's 256-entry table (BKE_colorband_evaluate), interpolated as rgb_ramp_lookup does
    table = ramp_table(stops).astype(np.float64)
    f = np.clip(x.astype(np.float64), 0.0, 1.0) * 255.0
    i = np.minimum(f.astype(int), 255)
    t = (f - i)[:, None]
    exact = (1.0 - t) * table[i] + t * table[np.minimum(i + 1, 255)]
    assert np.max(np.abs(got - exact)) < 3e-7
    # Cycles computes f = x · 255 in float32 (core.graph does too): t is off by an ulp of f
    g = Graph()
    cycles = evaluate(g.ramp(g.input("x"), stops), {"x": x}).astype(np.float64)
    assert np.max(np.abs(got - cycles)) < 2e-5


def test_a_color_ramp_into_a_float_input_reads_its_luma(tmp_path, lib):
    """A Color Ramp's colour into Roughness: Blender converts a colour into a float socket by
    its Rec.709 luma; the export read the ramp as a vector (mean of the channels, 0.14 off on
    this ramp, QA)."""
    stops = ((0.0, (0.9, 0.1, 0.0)), (1.0, (0.0, 0.2, 1.0)))
    ramp = L.BNode("Ramp", "ShaderNodeValToRGB", [S("Fac", "VALUE", 0.0, ("tex", "Alpha"))],
                   [S("Color", "RGBA"), S("Alpha", "VALUE")],
                   ramp=dict(color_mode="RGB", interpolation="LINEAR",
                             elements=[(p, c + (1.0,)) for p, c in stops]))
    alpha = S("Alpha", "VALUE")
    alpha.linked = True
    img = L.BNode("tex", "ShaderNodeTexImage", [S("Vector", "VECTOR")], [S("Color", "RGBA"), alpha], {},
                  image=dict(name="t", path=str(tmp_path / "t.exr"), colorspace="Non-Color", is_data=True))
    core = principled("Core", core=True, links={"Roughness": ("Ramp", "Color")})
    doc, _ = write(tree(img, ramp, core, out=output("Core")), tmp_path, lib)
    x = np.linspace(0.0, 1.0, 11).astype(np.float32)
    ev = mx_eval.Evaluator(doc.getNodeGraph("NG_Hand"), x.size, {"tex": np.repeat(x[:, None], 4, 1)})
    got = ev.value("Core", "specular_roughness").astype(np.float64)
    colour = (1.0 - x[:, None]) * np.array(stops[0][1]) + x[:, None] * np.array(stops[1][1])
    want = colour @ np.array([0.2126, 0.7152, 0.0722])  # (ITU-R BT.709 luma, linear)
    assert np.max(np.abs(got - want)) < 1e-5
    assert np.max(np.abs(colour.mean(axis=1) - want)) > 0.1  # (the mean would be far off)


def test_unsupported_nodes_are_said_and_written_at_the_socket_value(tmp_path, lib):
    noise = L.BNode("Noise Texture", "ShaderNodeTexNoise", [S("Vector", "VECTOR")], [S("Fac", "VALUE")])
    core = principled("Core", core=True, Metallic=0.25, links={"Metallic": ("Noise Texture", "Fac")})
    for s in core.inputs:
        s.node = "Core"
    doc, rep = write(tree(noise, core, out=output("Core")), tmp_path, lib)
    assert any("“Metallic” of “Core” is linked from “Noise Texture”" in n and "0.25" in n
               for n in rep.notes), rep.notes
    v = doc.getNodeGraph("NG_Hand").getNode("Core").getInputValue("base_metalness")
    assert v == 0.25


# --------------------------------------------------------------------------------------------
# Measured differences (docs/interchange.md §5)
# --------------------------------------------------------------------------------------------


def test_principled_fresnel_is_max_of_exact_and_f0():
    mu = np.linspace(0.0, 1.0, 501)
    for eta in (1.3, 1.5, 2.5, 4.0, 6.0):
        f = measure.principled_fresnel(mu, eta)[:, 0]
        assert np.allclose(f, np.maximum(fresnel_dielectric(mu, eta), ((eta - 1) / (eta + 1)) ** 2))
    # the exact Fresnel only dips below F0 for the high IORs haze writes
    assert max(measure.fresnel_gap(e) for e in np.linspace(1.01, 3.0, 60)) < 1e-12
    assert measure.fresnel_gap(6.0) > 0.1


def test_specular_difference_keeps_the_peak():
    for h in (0.2, 0.5, 0.8):
        lob = measure.hazy_dielectric(1.5, roughness=0.3, haziness=h)
        e = measure.specular_error(lob, n_theta=80, n_phi=24)
        assert e["peak"] < 1e-12
        if lob["eta"] <= 3.0:
            assert e["max"] < 1e-9  # where F_η ≥ F0 everywhere the two Fresnels agree
    # the raised η of a hazy dielectric: the peak holds, the dip does not
    lob = measure.hazy_dielectric(1.5, roughness=0.3, haziness=0.5)
    assert lob["eta"] > 5.0 and measure.specular_error(lob, n_theta=80, n_phi=24)["max"] > 0.05


def test_coat_tint_factors():
    cy, op = measure.coat_tint_factor((0.8, 0.8, 0.8), 1.5, 1.0)
    assert np.allclose(cy, op)  # the same at normal incidence
    cy, op = measure.coat_tint_factor((0.8, 0.8, 0.8), 1.5, math.cos(math.radians(60.0)))
    assert cy[0] < op[0]


@pytest.mark.parametrize("values, word", [({"Transmission Weight": 1.0}, "transmission is approximate"),
                                          ({"Thin Film Thickness": 400.0}, "thin film")])
def test_exports_note_what_they_approximate(tmp_path, values, word):
    """A layer exported with transmission or a thin film says that MaterialX draws
    those with its own models (the export was silent)."""
    t = tree(principled("Core", core=True, **values), out=output("Core"))
    rep = M.write([M.Source(t.name, layer=t)], tmp_path / "n.mtlx", validate_with_package=False)
    assert any(word in n for n in rep.notes), rep.notes
    plain = tree(principled("Core", core=True), out=output("Core"))
    rep = M.write([M.Source(plain.name, layer=plain)], tmp_path / "p.mtlx", validate_with_package=False)
    assert not any(word in n for n in rep.notes)
