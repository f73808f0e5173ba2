# SPDX-License-Identifier: GPL-3.0-or-later
"""The mapping's node math (core/node_math.py on core/graph.py), without rendering.

The graph is evaluated with Blender's node semantics in float32 (core.graph.evaluate: safe
divide, clamps, the Mix node) and compared with the numpy mapping (core.lobes.describe, float64)
of the same float32 inputs, over a grid of stiff values: r_c and β_h at 0 and 1, the Eq. 7
branch point r_c = p, λ_h -> 0 (p -> 1) and λ_h -> ∞ (p -> 0), roughness at the mirror cut-off
and at 1, the aspect limit, Bézier weights from 1e-4 to 1e6.  tests/blender/test_render_claims.py
renders the same graph once in Cycles (the backend's semantics).  Also: the graph machinery
(folding, shared sub-expressions, signatures) and finiteness on garbage texels.
"""
import itertools

import numpy as np
import pytest

from graph_signature import signature
from hazy_gloss import constants as K
from hazy_gloss.core import node_math
from hazy_gloss.core.graph import Graph, evaluate
from hazy_gloss.core.lobes import describe

F32 = np.float32


def _grid(aniso, smooth, dist, seed):
    """Float32 input arrays: every combination of the stiff values, shuffled and subsampled."""
    rcs = [(0.0,) * 3, (1e-7,) * 3, (0.04,) * 3, (0.5, 0.2, 0.1), (0.999,) * 3, (1.0, 0.5, 0.2),
           (1.0,) * 3, (1 - 2 ** -23,) * 3]
    gs = [(0.0,) * 3, (0.5, 0.9, 0.2), (1.0,) * 3]
    rough = [0.0, 0.004, 0.0101, 0.05, 0.3, 0.99, 1.0]
    aniso_v = [0.0, 0.4, 1.0] if aniso else [0.0]
    bhs = [0.0, 1e-7, 0.3, 0.99, K.MAX_HAZINESS]
    lams = [0.0, 1e-7, 1e-3, 0.5, 5.0, 1e3, 1e6]
    lam_pairs = [(a, b) for a in lams for b in lams] if aniso else [(a, a) for a in lams]
    ws = [1e-4, 0.5, 1.0, 2.0, 1e6] if smooth else [1.0]
    combos = list(itertools.product(range(len(rcs)), range(len(gs)), rough, aniso_v, bhs,
                                    range(len(lam_pairs)), ws))
    rng = np.random.default_rng(seed)
    pick = rng.permutation(len(combos))[:6000]
    rows = [combos[i] for i in pick]
    col = lambda idx, table: np.array([table[r[idx]] for r in rows], F32)  # noqa: E731
    lx = np.array([lam_pairs[r[5]][0] for r in rows], F32)
    ly = np.array([lam_pairs[r[5]][1] for r in rows], F32)
    # the Eq. 7 branch point r̂_c = p, and one ulp either side
    return dict(core_reflectivity=col(0, rcs), edge_tint=col(1, gs),
                roughness=np.array([r[2] for r in rows], F32),
                anisotropy=np.array([r[3] for r in rows], F32),
                rotation=rng.random(len(rows), dtype=F32),
                haziness=np.array([r[4] for r in rows], F32), haze_extent_x=lx, haze_extent_y=ly,
                smoothness=np.array([r[6] for r in rows], F32))


def _branch_points(dist):
    """Inputs with r̂_c exactly at the float32 p of the texel, and its neighbours."""
    n = 400
    rng = np.random.default_rng(3)
    rough = rng.uniform(0.01, 0.6, n).astype(F32)
    lam = (10.0 ** rng.uniform(-3, 2, n)).astype(F32)
    d = describe("LEGACY", dist, core_reflectivity=np.full((n, 3), 0.5, F32), edge_tint=0.0,
                 roughness=rough, haziness=np.full(n, 0.5, F32), haze_extent=lam, strict=False,
                 dtype=np.float32)
    p = np.asarray(d.mapping.peak_ratio, F32)
    step = np.array([-1, 0, 1] * (n // 3 + 1), np.int32)[:n]
    rc = np.nextafter(p, np.where(step < 0, F32(0), F32(1))).astype(F32)
    rc = np.where(step == 0, p, rc)
    return dict(core_reflectivity=np.repeat(rc[:, None], 3, -1), edge_tint=np.full((n, 3), 0.5, F32),
                roughness=rough, anisotropy=np.zeros(n, F32), rotation=np.zeros(n, F32),
                haziness=rng.uniform(0, K.MAX_HAZINESS, n).astype(F32), haze_extent_x=lam,
                haze_extent_y=lam, smoothness=np.ones(n, F32))


def _graph(kind, aniso, smooth, dist):
    g = Graph()
    src = {k: g.input(k, vector=v) for k, v in node_math.INPUTS.items()}
    return g, node_math.mapping(g, src, kind=kind, anisotropic=aniso, smooth=smooth,
                                distribution=dist)


def _reference(kind, dist, x, aniso, smooth):
    """The numpy mapping, float64, of the float32 inputs (haziness capped as the graph does)."""
    f64 = {k: np.asarray(v, np.float64) for k, v in x.items()}
    return describe(kind, dist, core_reflectivity=f64["core_reflectivity"], edge_tint=f64["edge_tint"],
                    roughness=f64["roughness"], anisotropy=f64["anisotropy"], rotation=f64["rotation"],
                    haziness=f64["haziness"], haze_extent=(f64["haze_extent_x"], f64["haze_extent_y"]),
                    smoothness=f64["smoothness"] if smooth else None, anisotropic=aniso,
                    strict=False, dtype=np.float64)


#: (graph output, reference, tolerance, relative?) — for η and κ the relative error divided by
#: their condition number 1 / (1 - r) (float32 inputs carry ε32 of error into 1 - r, e.g. through
#: p at the Eq. 7 branch point); absolute for the rest (values in [0, 1] or a few units).
def _pairs(kind, d, aniso):
    m = d.mapping
    pairs = [("beta", m.beta, 2e-6, False), ("peak_ratio", m.peak_ratio, 1e-6, False),
             ("peak_complement", m.peak_complement, 1e-6, False),
             ("halo_intensity", m.halo_intensity, 2e-6, False),
             ("reflectivity", m.reflectivity, 1e-6, False),
             ("roughness", d.narrow.roughness, 1e-7, False),
             ("roughness_wide", d.wide.roughness, 1e-6, False)]
    if aniso:
        pairs += [("anisotropy_wide", d.wide.anisotropy, 2e-5, False),
                  ("rotation_wide", d.wide.rotation, 1e-6, False)]
    if kind == "CONDUCTOR":
        pairs += [("ior", m.ior, 1e-6, True), ("extinction", m.extinction, 1e-6, True)]
    elif kind == "DIELECTRIC":
        pairs += [("ior", m.dielectric_ior, 1e-6, True), ("specular_tint", d.fresnel["specular_tint"], 1e-6, False)]
    else:
        pairs += [("colour_narrow", m.weight_narrow, 2e-6, False), ("colour_wide", m.weight_wide, 2e-6, False)]
    return pairs


WORST = {}


@pytest.mark.parametrize("kind", K.KINDS)
@pytest.mark.parametrize("aniso", [False, True])
@pytest.mark.parametrize("smooth", [False, True])
def test_graph_equals_numpy_mapping_on_stiff_inputs(kind, aniso, smooth):
    dists = {"CONDUCTOR": ("GGX", "BECKMANN"), "DIELECTRIC": ("GGX",),
             "LEGACY": ("GGX", "ASHIKHMIN_SHIRLEY")}[kind]
    for dist in dists:
        g, out = _graph(kind, aniso, smooth, dist)
        inputs = [_grid(aniso, smooth, dist, seed=len(kind) + aniso + 2 * smooth)]
        if not aniso and not smooth:
            inputs.append(_branch_points(dist))
        for x in inputs:
            got = evaluate(out, x)
            d = _reference(kind, dist, x, aniso, smooth)
            for name, want, tol, relative in _pairs(kind, d, aniso):
                a = np.asarray(got[name], np.float64)
                b = np.broadcast_to(np.asarray(want, np.float64), a.shape)
                assert np.all(np.isfinite(a)), (name, dist)
                # r = 1 (a perfect mirror): both sides cap 1 - r at their own ε; only the
                # index's size matters there (F = 1 - O(1/η)): compare away from it
                keep = np.ones(a.shape, bool)
                if name in ("beta", "halo_intensity", "colour_narrow", "colour_wide"):
                    # α_w = α_n within float32 rounding (q ≈ 0): the two lobes are one and β has
                    # no effect on the BRDF (at r̂_c = 1 it is even 0/0); checked as k_n + k_w
                    q = np.asarray(d.mapping.peak_complement, np.float64)
                    # and r̂_c = 0: the graph's β = k̂_h / r̂ is 0 there, numpy's the limit
                    # β_h / (p + (1-p) β_h): both lobes reflect nothing (r = 0)
                    q = np.where(np.asarray(d.mapping.core_reflectivity).max(-1) > 0, q, 0.0)
                    keep = np.broadcast_to((q if q.shape == a.shape else q[..., None]) > 1e-5, a.shape)
                if name == "specular_tint":  # r_c = 0: the graph's tint is 0, numpy's 1; r = 0
                    keep = np.broadcast_to(np.asarray(d.mapping.core_reflectivity).max(-1)[..., None] > 0,
                                           a.shape)
                scale = 1.0
                if relative:
                    r = np.asarray(d.mapping.reflectivity if kind == "CONDUCTOR"
                                   else d.mapping.reflectivity_max, np.float64)
                    if r.shape != a.shape:
                        r = r[..., None]
                    keep = np.broadcast_to(r < 1 - 2 ** -20, a.shape)
                    scale = np.maximum(np.abs(b), 1.0) / np.maximum(1.0 - r, 2 ** -20)
                err = np.where(keep, np.abs(a - b) / scale, 0.0)
                key = f"{name}{' (rel / cond)' if relative else ''}"
                WORST[key] = max(WORST.get(key, 0.0), float(err.max()))
                bad = np.unravel_index(np.argmax(err), err.shape)[0]
                assert err.max() <= tol, (name, dist, float(err.max()), a.flat[np.argmax(err)],
                                          b.flat[np.argmax(err)],
                                          {k: np.asarray(v)[bad].tolist() for k, v in x.items()})
            if kind == "LEGACY":  # the total weight is r everywhere
                total = np.asarray(got["colour_narrow"], np.float64) + got["colour_wide"]
                assert np.abs(total - np.asarray(got["reflectivity"], np.float64)).max() <= 2e-7


def test_graph_output_is_finite_on_garbage_texels():
    """Textures can hold anything: NaN, ±inf, negatives, huge values give finite outputs."""
    rng = np.random.default_rng(5)
    bad = np.array([np.nan, np.inf, -np.inf, -1.0, -1e30, 0.0, 1e30, 3.4e38, 1e-45, 0.5], F32)
    n = 4000
    x = {k: rng.choice(bad, (n, 3) if v else n) for k, v in node_math.INPUTS.items()}
    for kind in K.KINDS:
        for aniso, smooth in itertools.product((False, True), repeat=2):
            g, out = _graph(kind, aniso, smooth, "GGX")
            got = evaluate(out, x)
            for name, v in got.items():
                for a in (v if isinstance(v, tuple) else (v,)):
                    assert np.all(np.isfinite(a)), (kind, aniso, smooth, name)


def test_folding_and_sharing():
    g = Graph()
    x = g.input("x")
    a = g.add(g.mul(x, 2.0), 1.0)
    b = g.add(g.mul(x, 2.0), 1.0)
    assert a is b  # one node per distinct computation
    c = g.add(g.mul(3.0, 2.0), 1.0)
    assert c.is_const and float(c.value) == 7.0  # constants fold
    assert len(g.used(a)) == 3  # input, multiply, add
    # a mapping fed only constants needs no node at all, and folds to the evaluated values
    gc = Graph()
    vals = dict(core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5), roughness=0.2,
                anisotropy=0.0, rotation=0.0, haziness=0.5, haze_extent_x=5.0, haze_extent_y=5.0,
                smoothness=2.0)
    folded = node_math.mapping(gc, vals, kind="CONDUCTOR", anisotropic=False, smooth=False)
    assert gc.used(folded) == []
    g2, out = _graph("CONDUCTOR", False, False, "GGX")
    ev = evaluate(out, {k: np.asarray(v, F32) for k, v in vals.items()})
    for k in ("beta", "ior", "extinction", "roughness_wide"):
        assert np.array_equal(np.asarray(folded[k].value, F32), np.asarray(ev[k], F32)), k


def test_signature_ignores_constant_values():
    def build(h):
        g = Graph()
        src = {k: g.input(k, vector=v) for k, v in node_math.INPUTS.items()}
        src["haziness"] = h
        return g, node_math.mapping(g, src, kind="CONDUCTOR", anisotropic=False, smooth=False)
    g1, o1 = build(0.3)
    g2, o2 = build(0.7)
    assert signature(g1, o1) == signature(g2, o2)
    g3, o3 = _graph("CONDUCTOR", False, False, "GGX")
    assert signature(g3, o3) != signature(g1, o1)


def test_semantics_follow_blender():
    g = Graph()
    x, y = g.input("x"), g.input("y")
    out = dict(div=g.div(x, y), sqrt=g.sqrt(x), pow=g.math("POWER", x, 0.5),
               clamp=g.math("ADD", x, 0.0, clamp=True), mix=g.select(g.less(x, y), x, y),
               cmp=g.math("COMPARE", x, y, 0.0))
    v = evaluate(out, dict(x=np.array([1.0, -4.0, np.nan, 2.0], F32), y=np.array([0.0, 2.0, 1.0, 2.0], F32)))
    assert v["div"].tolist()[:2] == [0.0, -2.0]  # x / 0 = 0
    assert v["sqrt"].tolist()[1] == 0.0 and v["pow"].tolist()[1] == 0.0  # negative base
    assert v["clamp"].tolist() == [1.0, 0.0, 0.0, 1.0]  # saturate, NaN -> 0
    assert v["mix"].tolist()[:2] == [0.0, -4.0]  # the smaller of x, y
    assert v["cmp"].tolist()[3] == 1.0


def test_semantics_of_the_cheaper_node_kinds():
    """Clamp (the kernel's comparisons: x NaN gives lo, a NaN bound wins the max), SATURATE
    (NaN -> 0, ±inf kept and clamped), the vector Mix, vsqrt (< 0 gives 0); render-checked in
    tests/blender/test_graph_semantics.py."""
    g = Graph()
    x, y = g.input("x"), g.input("y")
    out = dict(clamp=g.clamp(x, 0.25, 0.75), low=g.clamp(0.5, x, 1e3), most=g.at_most(x, y),
               sat=g.vclamp01(g.combine(x, y, 0.5)), mix=g.vmix(g.combine(x, 1.0, 0.5), 1.0, 1e-6),
               root=g.vsqrt(g.combine(x, y, 4.0)))
    v = evaluate(out, dict(x=np.array([np.nan, np.inf, -np.inf, 0.5, 1.0], F32),
                           y=np.array([-1.0, 2.0, 0.1, 0.25, 9.0], F32)))
    assert v["clamp"].tolist() == [0.25, 0.75, 0.25, 0.5, 0.75]
    assert v["low"].tolist()[:3] == [1e3, 1e3, 0.5]  # NaN min: NaN, then min(NaN, 1e3) = 1e3
    assert v["most"].tolist()[3:] == [0.25, 1.0]
    assert v["sat"][:, 0].tolist() == [0.0, 1.0, 0.0, 0.5, 1.0]
    assert v["sat"][:, 1].tolist() == [0.0, 1.0, F32(0.1), 0.25, 1.0]
    assert v["mix"][4].tolist() == [F32(1e-6), F32(1e-6), F32(0.5) + F32(0.5) * F32(1e-6)]
    assert v["root"][3:].tolist() == [[np.sqrt(F32(0.5)), 0.5, 2.0], [1.0, 3.0, 2.0]]
    assert v["root"][0, 1] == 0.0  # √ of a negative


def test_folded_roughness_has_the_peak_of_the_mix():
    """The EEVEE fold: 1/α_f² = (1-β)/α_n² + β/α_w² (α = R²), i.e. the GGX peak D(0) ∝ 1/α²
    of the two-lobe mix, against that formula in float64."""
    rng = np.random.default_rng(3)
    n = 2000
    beta = rng.uniform(0.0, 1.0, n)
    r_n = rng.uniform(0.02, 0.9, n)
    r_w = np.minimum(r_n * rng.uniform(1.0, 8.0, n), 1.0)
    g = Graph()
    out = node_math.folded_roughness(g, g.input("b"), g.input("n"), g.input("w"))
    got = evaluate(out, dict(b=beta.astype(F32), n=r_n.astype(F32), w=r_w.astype(F32)))
    a_n, a_w = r_n.astype(F32).astype(np.float64) ** 2, r_w.astype(F32).astype(np.float64) ** 2
    b = beta.astype(F32).astype(np.float64)
    want = ((1.0 - b) / a_n ** 2 + b / a_w ** 2) ** -0.25  # R_f = α_f^½
    assert np.max(np.abs(got / want - 1.0)) < 2e-6


def test_node_counts_are_lean():
    """Shared sub-expressions and the Clamp/Mix forms keep the graph small (docs/node-groups.md
    lists the counts with the lobes)."""
    counts = {}
    for kind in K.KINDS:
        for aniso, smooth in itertools.product((False, True), repeat=2):
            g, out = _graph(kind, aniso, smooth, "GGX")
            counts[(kind, aniso, smooth)] = len([e for e in g.used(out) if e.op != "input"])
    assert counts[("CONDUCTOR", False, False)] <= 61  # the former group: 94 incl. 4 lobe nodes
    assert max(counts.values()) < 137 - 5 - 10


def teardown_module(module):
    print("\nnode math vs numpy mapping, worst errors:", {k: f"{v:.2e}" for k, v in WORST.items()})


def test_one_point_evaluation_equals_the_array_form():
    """evaluate() takes np.float32 scalars and its _FAST forms for one shading point (the
    panel, the notes) and arrays otherwise (texture conversion): both give the same float32
    bits, NaN where the other has NaN, on every layer configuration and on stiff inputs."""
    from hazy_gloss.core import layer_graph
    rng = np.random.default_rng(7)
    stiff = [0.0, 1.0, -1.0, 1e-30, 1e30, np.inf, -np.inf, np.nan, 0.5, 2.0, 1.5, 1e-8]
    for cfg in (layer_graph.Config("PRINCIPLED", "MULTI_GGX"),
                layer_graph.Config("PRINCIPLED", "GGX", smooth=True, body=True),
                layer_graph.Config("METALLIC", "MULTI_GGX", fresnel="PHYSICAL_CONDUCTOR"),
                layer_graph.Config("METALLIC", "GGX", fresnel="F82"),
                layer_graph.Config("GLOSSY", "GGX", smooth=True)):
        lay = layer_graph.build(cfg)
        outs = {str(k): v for k, v in {**lay.shown, **lay.outputs()}.items()
                if hasattr(v, "op")}
        n = 64
        arrays = {}
        for name, e in lay.graph.inputs.items():
            pick = rng.integers(0, len(stiff), (n, 3) if e.vector else n)
            v = np.where(rng.random(pick.shape) < 0.6, rng.uniform(-0.2, 1.5, pick.shape),
                         np.asarray(stiff)[pick])
            arrays[name] = v.astype(np.float32)
        whole = evaluate(outs, arrays, lay.graph.tables)
        for i in range(n):
            one = evaluate(outs, {k: v[i] for k, v in arrays.items()}, lay.graph.tables)
            for k in outs:
                a = np.asarray(one[k], np.float32)
                b = np.broadcast_to(np.asarray(whole[k], np.float32), (n,) + a.shape)[i]
                assert a.shape == b.shape, (cfg, k)
                same = np.isnan(a) == np.isnan(b)
                assert same.all() and np.array_equal(np.nan_to_num(a).view(np.uint32),
                                                     np.nan_to_num(b).view(np.uint32)), (cfg, k, i, a, b)


def test_lazy_point_evaluation_equals_the_full_one_on_finite_inputs():
    """evaluate(lazy=True) skips the side of a select it drops: the same values wherever the
    inputs are finite (the notes read it; NaN inputs are the full evaluation's to show)."""
    from hazy_gloss.core import layer_graph
    rng = np.random.default_rng(11)
    for cfg in (layer_graph.Config("PRINCIPLED", "MULTI_GGX"),
                layer_graph.Config("PRINCIPLED", "GGX", body=True),
                layer_graph.Config("METALLIC", "MULTI_GGX", fresnel="PHYSICAL_CONDUCTOR"),
                layer_graph.Config("GLOSSY", "GGX", smooth=True)):
        lay = layer_graph.build(cfg)
        outs = {str(k): v for k, v in {**lay.shown, **lay.outputs()}.items() if hasattr(v, "op")}
        for _ in range(24):
            ins = {}
            for name, e in lay.graph.inputs.items():
                v = rng.uniform(-0.2, 1.5, 3 if e.vector else None)
                if rng.random() < 0.3:  # switches: transmission, films, metallic 0 / 1
                    v = np.round(v)
                ins[name] = np.float32(v) if not e.vector else v.astype(np.float32)
            full = evaluate(outs, ins, lay.graph.tables)
            lazy = evaluate(outs, ins, lay.graph.tables, lazy=True)
            for k in outs:
                a, b = np.asarray(full[k], np.float32), np.asarray(lazy[k], np.float32)
                # (a signed zero may differ: 0·a + (-0) is +0, the side alone -0)
                assert np.array_equal(a, b, equal_nan=True), (cfg, k, a, b)
