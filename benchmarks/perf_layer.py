# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md section 6: what Make Hazy's layer costs in Cycles, on the defaults an
artist gets: the Principled BSDF's own distribution (Multiscatter GGX), image textures, the
material filling the frame.

For each material four renders, interleaved:

- ``original``: the artist's Principled BSDF, no haze;
- ``hazy``:     the same after ``api.make_hazy`` (one layer node);
- ``peer``:     what an artist builds without the add-on, the same closures and no mapping:
  OpenPBR 1.2's haze, a Mix Shader of the Principled and a copy of it whose roughness is
  lerp(R, 1, 0.3) (a Mix node, so a roughness map stays per pixel), factor 0.3; for a car
  paint with a hazy coat, the layer's own BSDF copies hand-wired with the values its group
  computes (constant inputs only: that is what its math costs once Cycles folds it);
- ``floor``:    the original plus one Glossy BSDF in a Mix Shader (the least a second lobe
  costs; not the same image).

CPU time of the rendering process per render, variants in alternating order, one warm-up round
dropped, median of the per-round ratios [interquartile range].

    .venv/bin/python benchmarks/perf_layer.py          # also run by benchmarks/report.py

Writes out/report/perf_layer.{json,md} and, run standalone, its section of docs/performance.md.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import numpy as np  # noqa: E402

SAMPLES = 128
ROUNDS = 7
RESOLUTION = (96, 96)
TEX = 256
#: hazy / peer targets
TARGETS = {"textured plastic": 1.10, "plastic": 1.05, "metallic map": 1.10,
           "car paint, hazy coat": 1.10}
if C.QUICK:
    SAMPLES, ROUNDS = 4, 1

PRINCIPLED = "ShaderNodeBsdfPrincipled"
BEGIN, END = "<!-- perf_layer:begin -->", "<!-- perf_layer:end -->"
PEER_MIX = 0.3

#: label -> (Principled inputs, textured inputs -> image, haze keywords); every other input and
#: the distribution are the Principled's defaults
CLASSES = {
    "textured plastic": ({"IOR": 1.5}, {"Base Color": "colour", "Roughness": "roughness"},
                         dict(haziness=0.3)),
    "plastic": ({"Base Color": (0.05, 0.12, 0.35, 1.0), "Roughness": 0.3}, {},
                dict(haziness=0.3)),
    "metallic map": ({"Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.3},
                     {"Metallic": "metallic"}, dict(haziness=0.3)),
    "car paint, hazy coat": ({"Metallic": 1.0, "Base Color": (0.6, 0.05, 0.05, 1.0),
                              "Roughness": 0.35, "Coat Weight": 1.0, "Coat Roughness": 0.03},
                             {}, dict(haziness=0.3, coat_haziness=0.4)),
}


def textures(n=TEX):
    """The artist's images: a colour pattern, a roughness map 0.1-0.5, a checker of metal and
    dielectric into Metallic."""
    u = (np.arange(n) + 0.5) / n
    U, V = np.meshgrid(u, u)
    tau = 2 * np.pi
    colour = np.stack([0.35 + 0.3 * np.sin(tau * 3 * U), 0.25 + 0.2 * np.sin(tau * (U + 2 * V)),
                       0.15 + 0.1 * np.cos(tau * 4 * V)], -1)
    rough = 0.3 + 0.2 * np.sin(tau * 5 * U) * np.cos(tau * 3 * V)
    checker = ((np.floor(U * 8) + np.floor(V * 8)) % 2).astype(float)
    grey = lambda a: np.repeat(a[..., None], 3, -1)  # noqa: E731
    return {"colour": (colour, False), "roughness": (grey(rough), True),
            "metallic": (grey(checker), True)}


def new_image(bpy, name, rgb, data=True):
    h, w = rgb.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True, is_data=data)
    img.pixels.foreach_set(np.concatenate([rgb, np.ones((h, w, 1))], -1).astype(np.float32).ravel())
    img.pack()
    return img


def original(bpy, label, images, name=None):
    inputs, tex, _ = CLASSES[label]
    mat = bpy.data.materials.new(name or label)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    b = next(n for n in tree.nodes if n.bl_idname == PRINCIPLED)
    for k, v in inputs.items():
        b.inputs[k].default_value = v
    for sock, img in tex.items():
        t = tree.nodes.new("ShaderNodeTexImage")
        t.image = images[img]
        tree.links.new(t.outputs["Color"], b.inputs[sock])
    return mat


def _output(tree):
    return next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")


def peer(bpy, label, images):
    """The Principled and a copy of it with roughness lerp(R, 1, 0.3), mixed 0.3."""
    mat = original(bpy, label, images, label + " peer")
    tree = mat.node_tree
    b = next(n for n in tree.nodes if n.bl_idname == PRINCIPLED)
    c = tree.nodes.new(PRINCIPLED)
    c.distribution, c.subsurface_method = b.distribution, b.subsurface_method
    for s in b.inputs:
        if hasattr(s, "default_value") and s.name in c.inputs:
            c.inputs[s.name].default_value = s.default_value
        for link in s.links:
            tree.links.new(link.from_socket, c.inputs[s.name])
    lerp = tree.nodes.new("ShaderNodeMix")
    lerp.data_type = "FLOAT"
    lerp.inputs["Factor"].default_value = PEER_MIX
    lerp.inputs["B"].default_value = 1.0
    r = b.inputs["Roughness"]
    if r.is_linked:
        tree.links.new(r.links[0].from_socket, lerp.inputs["A"])
    else:
        lerp.inputs["A"].default_value = r.default_value
    tree.links.new(lerp.outputs["Result"], c.inputs["Roughness"])
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = PEER_MIX
    tree.links.new(b.outputs[0], mix.inputs[1])
    tree.links.new(c.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], _output(tree).inputs["Surface"])
    return mat


def floor(bpy, label, images):
    """The original with one Glossy BSDF mixed in (factor 0.5: nothing folds)."""
    mat = original(bpy, label, images, label + " floor")
    tree = mat.node_tree
    out = _output(tree)
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Roughness"].default_value = 0.5
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    tree.links.new(out.inputs["Surface"].links[0].from_socket, mix.inputs[1])
    tree.links.new(glossy.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def hand_wired(bpy, hazy):
    """The layer node's Cycles closure tree typed in: a Principled BSDF per slot with the
    node's inputs and the values the group's math gives it, Mix Shaders with its factors."""
    import layer_probe
    from hazy_gloss.blender.model import layer, layer_values
    from hazy_gloss.core import layer_graph
    node = layer.layer_node(hazy)
    lay = layer_values.graph_of(node)
    core = layer.original_node(hazy)
    mat = bpy.data.materials.new(hazy.name + " hand-wired")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out = tree.nodes.new("ShaderNodeOutputMaterial")

    def build(t):
        if isinstance(t, layer_graph.Slot):
            b = tree.nodes.new(PRINCIPLED)
            b.distribution, b.subsurface_method = core.distribution, core.subsurface_method
            for s in node.inputs:
                if s.name in b.inputs and hasattr(s, "default_value"):
                    b.inputs[s.name].default_value = s.default_value
            for k, v in layer_probe.slot_values(layer_values, node, t.role).items():
                sock = b.inputs[k]
                if isinstance(v, tuple) and len(sock.default_value) == 4:
                    v = v[:3] + (1.0,)
                sock.default_value = v
            return b.outputs[0]
        f = layer_values.evaluate(node, {"f": t.factor})[0]["f"] if not t.add else None
        if f == 0.0:
            return build(t.a)
        if f == 1.0:
            return build(t.b)
        m = tree.nodes.new("ShaderNodeAddShader" if t.add else "ShaderNodeMixShader")
        off = 0 if t.add else 1
        if not t.add:
            m.inputs[0].default_value = f
        tree.links.new(build(t.a), m.inputs[off])
        tree.links.new(build(t.b), m.inputs[off + 1])
        return m.outputs[0]

    tree.links.new(build(lay.cycles), out.inputs["Surface"])
    return mat


def frame_filling_scene(bpy, material):
    """A smooth UV sphere under an orthographic camera whose frame lies inside the sphere's
    outline (every pixel is the material), an area light and the gradient sky."""
    import perf_scene as P
    import scenes
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    obj = P.uv_sphere()
    obj.data.materials.append(material)
    scenes._ortho_camera("HG Frame Camera", scenes.spherical_direction(70.0, -90.0), 1.3)
    P.gradient_world()
    light = bpy.data.lights.new("HG Frame Area", "AREA")
    light.size, light.energy = 1.0, 150.0
    lo = bpy.data.objects.new("HG Frame Area", light)
    bpy.context.scene.collection.objects.link(lo)
    d = scenes.spherical_direction(50.0, -130.0)
    lo.location = d * 5.0
    lo.rotation_euler = d.to_track_quat("Z", "Y").to_euler()
    return obj


def group_nodes(mat):
    """Nodes of the material's tree, nested groups expanded."""
    return C.count_nodes(mat.node_tree)


def main():
    C.start_blender()
    import bpy
    from hazy_gloss import api
    import scenes

    C.clean_file()
    scenes.setup_render(samples=SAMPLES, resolution=RESOLUTION, bounces=2)
    images = {k: new_image(bpy, k, rgb, data) for k, (rgb, data) in textures().items()}
    mats = {}
    for label, (_, tex, haze) in CLASSES.items():
        hazy = original(bpy, label, images, label + " hazy")
        api.make_hazy(hazy, **haze)
        v = {"original": original(bpy, label, images), "hazy": hazy,
             "floor": floor(bpy, label, images)}
        v["peer"] = hand_wired(bpy, hazy) if "coat_haziness" in haze else peer(bpy, label, images)
        mats[label] = v
    sphere = frame_filling_scene(bpy, mats["plastic"]["original"])
    scene = bpy.context.scene
    assert bpy.app.version >= (4, 5, 0)

    def render(mat):
        sphere.data.materials.clear()
        sphere.data.materials.append(mat)
        scene.cycles.samples = SAMPLES
        return scenes.render_exr()

    res = {"samples": SAMPLES, "rounds": ROUNDS, "resolution": RESOLUTION, "targets": TARGETS,
           "texels": TEX, "blender": bpy.app.version_string, "classes": {}}
    for label, v in mats.items():
        t0 = time.perf_counter()
        names = ["original", "hazy", "peer", "floor"]
        times = C.interleaved({k: (lambda m=v[k]: render(m)) for k in names}, ROUNDS, warmup=1)
        pairs = [("hazy", "peer"), ("hazy", "original"), ("peer", "original"),
                 ("floor", "original")]
        res["classes"][label] = {
            "peer": "hand-wired copies" if "coat_haziness" in CLASSES[label][2] else "OpenPBR mix",
            "nodes": {k: group_nodes(v[k]) for k in names},
            "ratios": {f"{a}/{b}": C.paired_ratio(times["cpu"], a, b) for a, b in pairs},
            "cpu_seconds": {k: float(np.median(times["cpu"][k])) for k in names}}
        r = res["classes"][label]["ratios"]
        print(f"[perf_layer] {label}: hazy/peer {r['hazy/peer']['median']:.3f}, hazy/original "
              f"{r['hazy/original']['median']:.3f} ({time.perf_counter() - t0:.0f} s)", flush=True)
    res["machine"] = C.machine()
    res["date"] = C.utc_date()
    C.publish("perf_layer", res, markdown(res), BEGIN, END)


def markdown(res):
    L = ["## 6. Make Hazy's layer in Cycles: the cost\n"]
    L.append(f"Measured by `.venv/bin/python benchmarks/perf_layer.py` on {res['date']} "
             f"(bpy {res['blender']}, {C.machine_line(res['machine'])}).\n")
    L.append("The defaults an artist gets: the Principled BSDF's own distribution (Multiscatter "
             "GGX), image textures, the material filling the frame (an orthographic "
             f"{res['resolution'][0]}x{res['resolution'][1]} frame inside a sphere's outline, an "
             f"area light and a sky, {res['samples']} spp, 2 bounces, {res['texels']}-texel "
             "images). **hazy**: after Make Hazy; **peer**: what an artist builds without us, "
             "the same closures and no mapping (OpenPBR 1.2's haze: a Mix Shader of the "
             "Principled and a copy with roughness lerp(R, 1, 0.3), factor 0.3, peak lost; for "
             "the car paint the layer's own copies hand-wired with the values its group "
             "computes); **floor**: the original plus one Glossy BSDF. CPU time of the "
             f"rendering process, interleaved, {res['rounds']} rounds after a warm-up, median "
             "of the per-round ratios [interquartile range].\n")
    header = ["material", "hazy / peer (target)", "hazy / original", "peer / original",
              "floor / original", "nodes (original, hazy, peer)", "CPU s (original, hazy)"]
    rows, missed = [], []
    for label, r in res["classes"].items():
        q, n, s = r["ratios"], r["nodes"], r["cpu_seconds"]
        t = res["targets"][label]
        if q["hazy/peer"]["median"] > t:
            missed.append(f"{label} ({q['hazy/peer']['median']:.2f} > {t:.2f})")
        rows.append([label, f"{C.fmt_ratio(q['hazy/peer'])} (<= {t:.2f})",
                     C.fmt_ratio(q["hazy/original"]), C.fmt_ratio(q["peer/original"]),
                     C.fmt_ratio(q["floor/original"]), f"{n['original']}, {n['hazy']}, {n['peer']}",
                     f"{s['original']:.2f}, {s['hazy']:.2f}"])
    L.append(C.md_table(header, rows) + "\n")
    L.append("Targets: " + ("**met** for every material." if not missed else
                            "**not met** for " + "; ".join(missed) + " (section 6b: what the "
                            "mapping's math costs per choice, and its error).") + "\n")
    return "\n".join(L)


if __name__ == "__main__":
    main()
