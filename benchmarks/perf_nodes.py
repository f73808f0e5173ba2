# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md section 3, "What a node costs": Cycles' SVM cost of each node kind the
generated node math can use (core.graph's choices: Clamp nodes, colour Mix with Clamp Result,
vector Mix, Separate / Combine Color, per-lane square roots).

A Metallic BSDF on the UV sphere of section 1 whose Roughness and IOR come from the Generated
coordinates; each variant adds a chain of CHAIN nodes of one kind whose result is folded to 0
(min(x, -1e30) then max(·, 0): NaN gives 0 too) and added to both inputs, so every variant
renders the same image and differs only by the chain.  Cost per node = (t_variant / t_base - 1)
/ CHAIN, CPU time, variants interleaved.  Writes out/report/perf_nodes.{json,md}.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

CHAIN = 20
SAMPLES = 64
ROUNDS = 8
if C.QUICK:
    SAMPLES, ROUNDS = 4, 1


def _ids(node, which):
    return {s.identifier: s for s in getattr(node, which)}


def _new(t, bl_idname, **props):
    n = t.nodes.new(bl_idname)
    for k, v in props.items():
        setattr(n, k, v)
    return n


def _set(sock, v):
    sock.default_value = v


def _chains():
    """name -> (label, step(tree, x, v, i) -> (x, v), SVM nodes per step)."""
    def math(op, clamp=False):
        def step(t, x, v, i):
            n = _new(t, "ShaderNodeMath", operation=op, use_clamp=clamp)
            t.links.new(x, n.inputs[0])
            _set(n.inputs[1], 0.9 + 0.001 * i)
            return n.outputs[0], v
        return step

    def vmath(op):
        def step(t, x, v, i):
            n = _new(t, "ShaderNodeVectorMath", operation=op)
            t.links.new(v, n.inputs[0])
            _set(n.inputs[1], (0.9 + 0.001 * i,) * 3)
            _set(n.inputs[2], (0.01,) * 3)
            return x, n.outputs[0]
        return step

    def clamp(t, x, v, i):
        n = _new(t, "ShaderNodeClamp", clamp_type="MINMAX")
        t.links.new(x, n.inputs[0])
        t.links.new(x, n.inputs[1])  # a linked bound: max(x, x)
        _set(n.inputs[2], 3.0e38)
        return n.outputs[0], v

    def mix_float(t, x, v, i):
        n = _new(t, "ShaderNodeMix", data_type="FLOAT", clamp_factor=False)
        s = _ids(n, "inputs")
        t.links.new(x, s["Factor_Float"])
        t.links.new(x, s["A_Float"])
        _set(s["B_Float"], 0.3 + 0.01 * i)
        return _ids(n, "outputs")["Result_Float"], v

    def mix_vector(uniform):
        def step(t, x, v, i):
            n = _new(t, "ShaderNodeMix", data_type="VECTOR", clamp_factor=False,
                     factor_mode="UNIFORM" if uniform else "NON_UNIFORM")
            s = _ids(n, "inputs")
            t.links.new(x if uniform else v, s["Factor_Float" if uniform else "Factor_Vector"])
            t.links.new(v, s["A_Vector"])
            _set(s["B_Vector"], (0.5,) * 3)
            return x, _ids(n, "outputs")["Result_Vector"]
        return step

    def mix_saturate(t, x, v, i):
        n = _new(t, "ShaderNodeMix", data_type="RGBA", blend_type="MIX", clamp_factor=False,
                 clamp_result=True)
        s = _ids(n, "inputs")  # as core.graph's SATURATE is emitted: v as B at factor 1
        _set(s["Factor_Float"], 1.0)
        _set(s["A_Color"], (0.0, 0.0, 0.0, 1.0))
        t.links.new(v, s["B_Color"])
        return x, _ids(n, "outputs")["Result_Color"]

    def split_join(sep, comb):
        def step(t, x, v, i):
            s = _new(t, sep)
            c = _new(t, comb)
            t.links.new(v, s.inputs[0])
            for k in range(3):
                t.links.new(s.outputs[k], c.inputs[2 - k])
            return x, c.outputs[0]
        return step

    def vpow_half(t, x, v, i):
        n = _new(t, "ShaderNodeVectorMath", operation="POWER")
        t.links.new(v, n.inputs[0])
        _set(n.inputs[1], (0.5,) * 3)
        return x, n.outputs[0]

    def lanes_sqrt(t, x, v, i):
        s = _new(t, "ShaderNodeSeparateColor")
        c = _new(t, "ShaderNodeCombineColor")
        t.links.new(v, s.inputs[0])
        for k in range(3):
            q = _new(t, "ShaderNodeMath", operation="SQRT")
            t.links.new(s.outputs[k], q.inputs[0])
            t.links.new(q.outputs[0], c.inputs[k])
        return x, c.outputs[0]

    return {
        "math_mul": ("Math Multiply", math("MULTIPLY")),
        "math_max": ("Math Maximum", math("MAXIMUM")),
        "math_div": ("Math Divide", math("DIVIDE")),
        "math_sqrt": ("Math Square Root", math("SQRT")),
        "math_max_clamp": ("Math Maximum with its Clamp option", math("MAXIMUM", clamp=True)),
        "clamp": ("Clamp (Min Max, a linked bound)", clamp),
        "mix_float": ("Mix, float", mix_float),
        "vmath_mul": ("Vector Math Multiply", vmath("MULTIPLY")),
        "vmath_madd": ("Vector Math Multiply Add", vmath("MULTIPLY_ADD")),
        "vmath_max": ("Vector Math Maximum", vmath("MAXIMUM")),
        "vmath_div": ("Vector Math Divide", vmath("DIVIDE")),
        "mix_vector_uniform": ("Mix, vector, uniform factor", mix_vector(True)),
        "mix_vector_lanes": ("Mix, vector, non-uniform factor", mix_vector(False)),
        "mix_saturate": ("Mix, colour, Clamp Result", mix_saturate),
        "xyz_pair": ("Separate XYZ + Combine XYZ", split_join("ShaderNodeSeparateXYZ",
                                                             "ShaderNodeCombineXYZ")),
        "color_pair": ("Separate Color + Combine Color", split_join("ShaderNodeSeparateColor",
                                                                   "ShaderNodeCombineColor")),
        "vpow_half": ("√ per lane: Vector Math Power 0.5", vpow_half),
        "lanes_sqrt": ("√ per lane: Separate Color, 3 Math Square Root, Combine Color",
                       lanes_sqrt),
    }


def _material(name, step=None):
    import perf_scene as P
    mat, t, out = P.empty_material(name)
    tc = _new(t, "ShaderNodeTexCoord")
    sep = _new(t, "ShaderNodeSeparateXYZ")
    t.links.new(tc.outputs["Generated"], sep.inputs[0])
    x0, v0 = sep.outputs[0], tc.outputs["Generated"]
    x, v = x0, v0
    for i in range(CHAIN if step else 0):
        x, v = step(t, x, v, i)
    # the sink: whatever the chain made -> 0 (min with -1e30, max with 0), added to the inputs
    a = _new(t, "ShaderNodeMath", operation="MINIMUM")
    t.links.new(x, a.inputs[0])
    _set(a.inputs[1], -1e30)
    b = _new(t, "ShaderNodeMath", operation="MAXIMUM")
    t.links.new(a.outputs[0], b.inputs[0])
    _set(b.inputs[1], 0.0)
    va = _new(t, "ShaderNodeVectorMath", operation="MINIMUM")
    t.links.new(v, va.inputs[0])
    _set(va.inputs[1], (-1e30,) * 3)
    vb = _new(t, "ShaderNodeVectorMath", operation="MAXIMUM")
    t.links.new(va.outputs[0], vb.inputs[0])
    _set(vb.inputs[1], (0.0,) * 3)
    rough = _new(t, "ShaderNodeMath", operation="MULTIPLY_ADD")
    t.links.new(x0, rough.inputs[0])
    _set(rough.inputs[1], 0.2)
    r2 = _new(t, "ShaderNodeMath", operation="ADD")
    t.links.new(b.outputs[0], r2.inputs[0])
    _set(r2.inputs[1], 0.1)
    t.links.new(r2.outputs[0], rough.inputs[2])
    ior = _new(t, "ShaderNodeVectorMath", operation="MULTIPLY_ADD")
    t.links.new(v0, ior.inputs[0])
    _set(ior.inputs[1], (0.1,) * 3)
    i2 = _new(t, "ShaderNodeVectorMath", operation="ADD")
    t.links.new(vb.outputs[0], i2.inputs[0])
    _set(i2.inputs[1], (1.5, 1.0, 0.5))
    t.links.new(i2.outputs[0], ior.inputs[2])
    m = _new(t, "ShaderNodeBsdfMetallic", distribution="GGX", fresnel_type="PHYSICAL_CONDUCTOR")
    t.links.new(rough.outputs[0], m.inputs["Roughness"])
    t.links.new(ior.outputs[0], m.inputs["IOR"])
    _set(m.inputs["Extinction"], (3.0, 2.5, 2.0))
    t.links.new(m.outputs[0], out.inputs["Surface"])
    return mat


def main():
    C.start_blender()
    import perf_scene as P
    import scenes

    C.clean_file()
    scenes.setup_render(samples=SAMPLES, resolution=P.RESOLUTION, bounces=2)
    chains = _chains()
    mats = {"base": _material("base")}
    for key, (_, step) in chains.items():
        mats[key] = _material(key, step)
    info = P.lit_sphere_scene(mats["base"])

    def render(mat):
        P.assign(info, mat)
        return scenes.render_exr()

    times = C.interleaved({k: (lambda m=m: render(m)) for k, m in mats.items()}, ROUNDS,
                          warmup=1)
    res = {"chain": CHAIN, "samples": SAMPLES, "rounds": ROUNDS, "kinds": {}}
    for key, (label, _) in chains.items():
        r = C.paired_ratio(times["cpu"], key, "base")
        res["kinds"][key] = {"label": label, "ratio": r,
                             "per_node_pct": {q: (r[q] - 1.0) / CHAIN * 100.0
                                              for q in ("median", "q1", "q3")}}
        print(f"[perf_nodes] {label}: {res['kinds'][key]['per_node_pct']['median']:.3f} %",
              flush=True)
    C.write_json("perf_nodes", res)
    (C.OUT / "perf_nodes.md").write_text(_markdown(res))


def _markdown(res):
    L = ["### What a node costs in Cycles (SVM)\n",
         f"Why the generated node math uses the nodes it does: a Metallic BSDF on section 1's "
         f"sphere, plus a chain of {res['chain']} nodes of one kind whose result is folded to 0 "
         "and added to the BSDF's inputs (every variant renders the same image). Cost of one "
         "node (or one step of the chain) = (CPU time with the chain / without - 1) / "
         f"{res['chain']}, in % of the scene's render; variants interleaved, "
         f"{res['rounds']} rounds, median [interquartile range]. Seen from here: Cycles "
         "expands a Math node's Clamp option into a second node; Separate / Combine XYZ compile "
         "to one node per lane, the Color ones to one; Vector Math Power is three powf "
         "calls.\n"]
    rows = [[k["label"], f"{k['per_node_pct']['median']:.3f} [{k['per_node_pct']['q1']:.3f}, "
             f"{k['per_node_pct']['q3']:.3f}]"] for k in res["kinds"].values()]
    L.append(C.md_table(["node kind (one chain step)", "% of the render per step"], rows) + "\n")
    L.append("So the node math (core.graph) clamps with Clamp nodes, saturates colours with one "
             "colour Mix, multiplies vectors with the vector Mix ((1 - a) 0 + a b for finite "
             "operands), splits and joins vectors with Separate / Combine Color and takes "
             "per-lane square roots as three Math Square Roots.\n")
    return "\n".join(L)


if __name__ == "__main__":
    main()
