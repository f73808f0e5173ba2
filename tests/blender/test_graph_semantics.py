# SPDX-License-Identifier: GPL-3.0-or-later
"""The node kinds core.graph emits for speed (Clamp with constant and linked bounds, the colour
Mix with Clamp Result, the vector Mix with a per-lane factor), rendered by Cycles on special
values — NaN, ±inf, negative, in range, above range — and compared with Graph.evaluate.

The values are made in the shader (inf = 1e30 · 1e30, NaN = inf - inf), so nothing is folded
before the kernel sees them; each probe emits three lanes on a flat plane, 1 sample, no bounces.
"""
import importlib

import numpy as np
import pytest

import scenes

SPECIAL = {"nan": None, "inf": None, "-inf": None, "-2": -2.0, "0.1": 0.1, "0.6": 0.6, "5": 5.0}


@pytest.fixture
def g_mod(hg, clean_file):
    return (importlib.import_module(hg.__name__ + ".core.graph"),
            importlib.import_module(hg.__name__ + ".blender.nodes.emit"),
            importlib.import_module(hg.__name__ + ".blender.nodes.builder"),
            importlib.import_module(hg.__name__ + ".blender.compat"))


_math = scenes.math_node


def _special(tree, key):
    """A socket carrying ``key``'s value, computed per shading point."""
    tc = tree.nodes.new("ShaderNodeTexCoord")
    sep = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(tc.outputs["Object"], sep.inputs[0])
    zero = _math(tree, "MINIMUM", _math(tree, "MAXIMUM", sep.outputs[2], 0.0), 0.0)
    inf = _math(tree, "MULTIPLY", _math(tree, "ADD", zero, 1e30), 1e30)
    if key == "nan":
        return _math(tree, "SUBTRACT", inf, inf)
    if key == "inf":
        return inf
    if key == "-inf":
        return _math(tree, "MULTIPLY", inf, -1.0)
    return _math(tree, "ADD", zero, SPECIAL[key])


def _value(key):
    return {"nan": np.nan, "inf": np.inf, "-inf": -np.inf}.get(key, SPECIAL[key])


def _render(mods, build, key):
    graph, emit, builder, compat = mods
    mat = compat.new_material("probe")
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    g = graph.Graph()
    x = g.input("x")
    lanes = build(g, x)
    want = graph.evaluate(lanes, {"x": np.float32(_value(key))})
    sock = emit.emit(builder.TreeBuilder(tree), g, lanes, {"x": _special(tree, key)})
    em = tree.nodes.new("ShaderNodeEmission")
    tree.links.new(scenes.combine_xyz(tree, *sock), em.inputs["Color"])
    tree.links.new(em.outputs[0], out.inputs["Surface"])
    got = scenes.render_plane(mat, resolution=(2, 2), light_dir=(0.0, 0.0), strength=0.0)[0, 0]
    return got, np.array([float(w) for w in want])


def _clamp_constant(g, x):
    return [g.clamp(x, 0.25, 0.75), g.at_least(x, 0.25), g.at_most(x, 0.75)]


def _clamp_linked(g, x):
    """Bounds from the graph: Clamp(0.5, min x, max 1e3) = max_t(0.5, x) (NaN x: NaN, then
    1e3), Clamp(x, min h, max 1e3) and Clamp(x, min 0, max h), h = 0.5 computed from x."""
    h = g.clamp(g.add(g.mul(x, 0.0), 0.5), 0.5, 0.5)  # x · 0 is NaN for NaN, inf x: h = 0.5
    return [g.clamp(0.5, x, 1e3), g.clamp(x, h, 1e3), g.clamp(x, 0.0, h)]


def _saturate_and_mix(g, x):
    v = g.vclamp01(g.combine(x, 0.5, g.mul(x, -1.0)))
    r, _, b = g.separate(v)
    t = g.vclamp01(g.combine(x, 1.0, 0.5))  # a per-lane factor
    m = g.vmix(t, 1.0, g.combine(1e-6, 1e-6, 1e-6))  # lane 1: (1-1) 1 + 1e-6 exactly
    return [r, b, g.separate(m)[1]]


@pytest.mark.parametrize("build", [_clamp_constant, _clamp_linked, _saturate_and_mix],
                         ids=["clamp constant bounds", "clamp linked bounds", "saturate, vector mix"])
def test_cycles_evaluates_the_node_kinds_as_the_graph(g_mod, build):
    for key in SPECIAL:
        got, want = _render(g_mod, build, key)
        assert np.all(np.isfinite(got)), (key, got)
        assert np.allclose(got, want, rtol=1e-7, atol=0.0), (key, got, want)
