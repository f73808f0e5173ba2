# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md section 6b: error against cost of the layer's math, per choice.

Under Multiscatter GGX the layer solves (*) r [(1-β) S_n + β p S_w] = r_c S_0 for r by unrolled
Newton steps (core.node_multiscatter.STEPS; docs/mapping.md §11).  Each choice of step count
trades math nodes for how well the peak holds.  Measured on the textured plastic of section 6
(its roughness map makes the math per shading point; section 6's constant materials fold it
all away), one group per choice:

- **nodes**: the group's nodes (nested groups expanded) and the math nodes Cycles runs at every
  shading point for this material's links (layer_values.varying_math: the rest folds);
- **CPU**: hazy / peer and hazy / original, interleaved as in section 6;
- **peak error**: over the material's texels, the peak the sockets give (F0 of the IOR the
  group computes, β, the wide roughness; each lobe's factor from Cycles' tables,
  core.multiscatter) against the haze-free material's: max and 99th percentile of
  |hazy / haze-free - 1|.

Plus the same material with GGX lobes (the paper's single scattering: no correction, exact;
another look) for the cost of the correction itself.

    .venv/bin/python benchmarks/perf_layer_choices.py   # also run by benchmarks/report.py
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import numpy as np  # noqa: E402

import perf_layer as PL  # noqa: E402

BEGIN, END = "<!-- perf_layer_choices:begin -->", "<!-- perf_layer_choices:end -->"
LABEL = "textured plastic"
#: (row label, distribution, dielectric max-channel steps)
CHOICES = (("Multiscatter GGX, 0 steps (single-scatter r)", "MULTI_GGX", 0),
           ("Multiscatter GGX, 1 step", "MULTI_GGX", 1),
           ("Multiscatter GGX, 2 steps (the layer)", "MULTI_GGX", 2),
           ("Multiscatter GGX, 3 steps", "MULTI_GGX", 3),
           ("GGX (single scattering, exact)", "GGX", None))
TEXELS = 64  # the roughness map's texels checked per side (a 64 x 64 subsample)


def peak_error(node, rough_map, distribution):
    """Max and 99th percentile over ``rough_map``'s values of |hazy peak / haze-free - 1| for
    the layer node's constants (its other inputs), from the values its group gives."""
    from hazy_gloss.blender.model import layer_values
    from hazy_gloss.core import layer_graph, multiscatter as ms
    lay = layer_values.graph_of(node)
    slots = {s.role: s for s in layer_graph.slots_of(lay.cycles)}
    mix = next(t for t in layer_graph.walk(lay.cycles) if isinstance(t, layer_graph.Mix))
    r = np.asarray(rough_map, np.float32).ravel()
    out = {"ior": slots["A narrow"].writes["IOR"], "beta": mix.factor,
           "rw": slots["A wide"].writes["Roughness"]}
    got = {}
    for i in range(0, len(r), 512):  # (evaluate takes one texel's constants at a time)
        chunk = r[i:i + 512]
        vals = [layer_values.evaluate(node, out, overrides={"in:Roughness": float(x)})[0]
                for x in chunk]
        for k in out:
            got.setdefault(k, []).extend(float(v[k]) for v in vals)
    eta, beta, rw = (np.asarray(got[k], np.float64) for k in ("ior", "beta", "rw"))
    eta0 = np.full_like(eta, float(node.inputs["IOR"].default_value))
    a_n = np.maximum(r.astype(np.float64), 0.004) ** 2
    a_w = np.minimum(rw ** 2, 1.0)
    p = (a_n / a_w) ** 2

    def lobe(ior, alpha):
        """F(0) S of a Principled dielectric lobe (Specular IOR Level 0.5, white tint)."""
        f0 = ((ior - 1) / (ior + 1)) ** 2
        if distribution != "MULTI_GGX":
            return f0
        fss = ms.single_scatter_albedo("DIELECTRIC", ior=ior, specular_tint=np.ones(ior.shape + (3,)))
        return f0 * ms.energy_scale((alpha, alpha), fss)[..., 0]  # (white: channels equal)
    hazy = (1 - beta) * lobe(eta, a_n) + beta * p * lobe(eta, a_w)
    ref = lobe(eta0, a_n)
    rel = np.abs(hazy / ref - 1.0)
    return float(rel.max()), float(np.percentile(rel, 99))


def main():
    C.start_blender()
    import bpy
    from hazy_gloss import api
    from hazy_gloss.blender.model import layer, layer_group, layer_values
    from hazy_gloss.core import node_multiscatter
    import scenes

    C.clean_file()
    scenes.setup_render(samples=PL.SAMPLES, resolution=PL.RESOLUTION, bounces=2)
    tex = PL.textures()
    images = {k: PL.new_image(bpy, k, rgb, data) for k, (rgb, data) in tex.items()}
    rough = tex["roughness"][0][..., 0]
    step = max(1, rough.shape[0] // TEXELS)
    rough = rough[::step, ::step]
    mats, rows = {}, []
    saved = dict(node_multiscatter.STEPS["DIELECTRIC"])
    for label, dist, steps in CHOICES:
        if steps is not None:
            node_multiscatter.STEPS["DIELECTRIC"]["m"] = steps
        try:
            orig = PL.original(bpy, LABEL, images, f"{label} original")
            hazy = PL.original(bpy, LABEL, images, f"{label} hazy")
            peer = PL.peer(bpy, LABEL, images)
            for m in (orig, hazy, peer):
                b = next(n for n in m.node_tree.nodes if n.bl_idname == PL.PRINCIPLED)
                b.distribution = dist
            api.make_hazy(hazy, **PL.CLASSES[LABEL][2])
            node = layer.layer_node(hazy)
            fresh = bpy.data.node_groups.new(f"{label} group", "ShaderNodeTree")
            want = layer.wanted_group(node)
            layer_group.build(fresh, *want)  # built with this step count
            fresh[layer_group.K.GROUP_STAMP] = dict(node.node_tree[layer_group.K.GROUP_STAMP])
            node.node_tree = fresh
            layer_values._LAYERS.clear()
            err = peak_error(node, rough, dist)
            mats[label] = {"original": orig, "hazy": hazy, "peer": peer}
            rows.append({"choice": label, "nodes": PL.group_nodes(hazy),
                         "per_point": layer_values.varying_math(node),
                         "peak_max": err[0], "peak_p99": err[1]})
        finally:
            node_multiscatter.STEPS["DIELECTRIC"].update(saved)
            layer_values._LAYERS.clear()
    sphere = PL.frame_filling_scene(bpy, mats[CHOICES[0][0]]["original"])
    scene = bpy.context.scene

    def render(mat):
        sphere.data.materials.clear()
        sphere.data.materials.append(mat)
        scene.cycles.samples = PL.SAMPLES
        return scenes.render_exr()

    for row in rows:
        t0 = time.perf_counter()
        v = mats[row["choice"]]
        times = C.interleaved({k: (lambda m=v[k]: render(m)) for k in v}, PL.ROUNDS, warmup=1)
        row["hazy/peer"] = C.paired_ratio(times["cpu"], "hazy", "peer")
        row["hazy/original"] = C.paired_ratio(times["cpu"], "hazy", "original")
        print(f"[perf_layer_choices] {row['choice']}: {row['per_point']} per point, hazy/peer "
              f"{row['hazy/peer']['median']:.3f}, peak {row['peak_max']:.1e} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    res = {"rows": rows, "blender": bpy.app.version_string, "samples": PL.SAMPLES,
           "rounds": PL.ROUNDS, "machine": C.machine(),
           "date": C.utc_date()}
    C.publish("perf_layer_choices", res, markdown(res), BEGIN, END)


def markdown(res):
    L = ["### 6b. Error against cost of the layer's math\n"]
    L.append(f"Measured by `.venv/bin/python benchmarks/perf_layer_choices.py` on {res['date']} "
             f"(bpy {res['blender']}, {C.machine_line(res['machine'])}).\n")
    L.append("The textured plastic of section 6 (Base Color and Roughness maps: the roughness "
             "makes the mapping per shading point), one group per choice of the Multiscatter "
             "solve's Newton steps (docs/mapping.md §11), and the same material with GGX lobes "
             "(the paper's single scattering, exact without a correction; another look). "
             "**math per point**: the math nodes Cycles runs at every shading point for this "
             "material (the rest folds into constants); **peak error**: over the roughness "
             f"map's texels, the peak the group's values give against the haze-free material's "
             "(each lobe's energy factor from Cycles' tables), max and 99th percentile. The "
             "budget of an approximation under Multiscatter GGX is 1e-3.\n")
    header = ["choice", "group nodes", "math per point", "hazy / peer", "hazy / original",
              "peak error max", "peak error p99"]
    rows = [[r["choice"], str(r["nodes"]), str(r["per_point"]), C.fmt_ratio(r["hazy/peer"]),
             C.fmt_ratio(r["hazy/original"]), C.sci(r["peak_max"]), C.sci(r["peak_p99"])]
            for r in res["rows"]]
    L.append(C.md_table(header, rows) + "\n")
    ms = [r for r in res["rows"] if r["choice"].startswith("Multiscatter")]
    within = [r["choice"] for r in ms if r["peak_max"] <= 1e-3]
    L.append(f"Within the 1e-3 budget: {', '.join(within) or 'none'}. The per-point math is "
             "what a textured roughness pays for: the GGX row runs the mapping alone, the "
             "Multiscatter rows add the correction's Newton steps.")
    by_cost = sorted(ms, key=lambda r: r["per_point"])
    if len(by_cost) >= 2 and by_cost[-1]["per_point"] > by_cost[0]["per_point"]:
        lo, hi = by_cost[0], by_cost[-1]
        per_100 = 100 * (hi["hazy/peer"]["median"] - lo["hazy/peer"]["median"]) / (
            hi["per_point"] - lo["per_point"])
        apart = all(a["hazy/peer"]["q3"] < b["hazy/peer"]["q1"]
                    for a, b in zip(by_cost, by_cost[1:]))
        L[-1] += (f" From the fewest to the most math per point, every 100 math nodes a shading "
                  f"point runs add {per_100:.2f} to hazy / peer" +
                  (" (the Multiscatter rows' IQRs do not overlap)" if apart else
                   " (the IQRs of neighbouring Multiscatter rows overlap: the render's noise on "
                   "this machine)") + ".")
    L[-1] += "\n"
    return "\n".join(L)


if __name__ == "__main__":
    main()
