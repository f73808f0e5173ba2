# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md section 8: how fast the layer node is to make and to edit.

Two materials of the issue: a Principled BSDF with image textures on Base Color, Roughness,
Metallic, Coat Weight and a Normal Map (8 nodes), and a Principled BSDF with every input linked
(one Value / RGB node per input).  Measured, in one process (bpy, the add-on registered):

- **Make Hazy** (``api.make_hazy(mat, haziness=0.5)`` on a fresh copy): with the layer's group
  already in the file (every Make Hazy after the first of its configuration; beside it
  Blender's own part, a group node added and the BSDF's links made again into it), appended
  from the per-user cache (the first in a file; beside it Blender's append of that group
  alone), and built (the first ever on this machine and code);
- **the first Make Hazy by the file's size**: in files of 0, 100 and 500 other materials, next
  to Blender's append alone of the layer's group and of a 10-node group (what any append costs
  in that file);
- **a slider change**: one haze socket of the layer node set (Haziness) and the depsgraph
  updated (``view_layer.update()``: what Blender does after a drag step; the add-on's handler
  runs in it), the first change after Make Hazy included; next to the same change of the plain
  material's Roughness (Blender's own cost);
- **500 materials**: a frame change (``scene.frame_set``, every material's Roughness keyed) and
  an edit of one material's own node (a Base Color set + depsgraph update), in a scene of 500
  objects with hazy materials against one with the same 500 materials plain, interleaved.

    .venv/bin/python benchmarks/perf_layer_edit.py     # also run by benchmarks/report.py

Writes out/report/perf_layer_edit.{json,md}; run alone, it replaces its section of
docs/performance.md (between the perf_layer_edit markers).
"""
from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

BEGIN, END = "<!-- perf_layer_edit:begin -->", "<!-- perf_layer_edit:end -->"
REPEATS = 15  # Make Hazy / slider changes per state
COLD = 3  # cold builds (seconds each)
MANY = 500
ROUNDS = 9
FILE_SIZES = (0, 100, 500)  # other materials in the file of a first Make Hazy
FLOOR_REPEATS = 9
SMALL_GROUP = 10  # Math nodes of the small group appended beside the layer's
#: Node kinds whose append is timed per node (append_parts), NODE_KIND_COUNT chained each.
NODE_KINDS = {"Math": "ShaderNodeMath", "Vector Math": "ShaderNodeVectorMath",
              "Mix (float)": "ShaderNodeMix", "Clamp": "ShaderNodeClamp"}
NODE_KIND_COUNT = 600
if C.QUICK:
    REPEATS, COLD, MANY, ROUNDS, FILE_SIZES, FLOOR_REPEATS = 3, 1, 20, 2, (0, 20), 2
#: targets (ms): the first Make Hazy of a configuration, a slider change
TARGET_FIRST_MS, TARGET_MAKE_MS, TARGET_SLIDER_MS = 20.0, 6.0, 2.0
PRINCIPLED = "ShaderNodeBsdfPrincipled"


def textured(bpy, name):
    """Image textures on Base Color, Roughness, Metallic, Coat Weight and a Normal Map."""
    import numpy as np
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    b = next(n for n in tree.nodes if n.bl_idname == PRINCIPLED)
    b.distribution = "MULTI_GGX"
    for i, sock in enumerate(("Base Color", "Roughness", "Metallic", "Coat Weight", "Normal")):
        img = bpy.data.images.get(f"perf edit {sock}")
        if img is None:
            img = bpy.data.images.new(f"perf edit {sock}", 64, 64, float_buffer=True,
                                      is_data=sock != "Base Color")
            img.pixels.foreach_set(np.random.default_rng(i).random(64 * 64 * 4).astype(np.float32))
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image = img
        tex.location = (-600, -300 * i)
        if sock == "Normal":
            nm = tree.nodes.new("ShaderNodeNormalMap")
            tree.links.new(tex.outputs["Color"], nm.inputs["Color"])
            tree.links.new(nm.outputs["Normal"], b.inputs["Normal"])
        else:
            tree.links.new(tex.outputs["Color"], b.inputs[sock])
    return mat


def textured_ggx(bpy, name):
    """The textured material with the single-scattering GGX distribution: its layer group has
    no Multiscatter GGX correction of the base (the coat's stays), about 2/3 of the nodes."""
    mat = textured(bpy, name)
    next(n for n in mat.node_tree.nodes if n.bl_idname == PRINCIPLED).distribution = "GGX"
    return mat


def all_linked(bpy, name):
    """Every input of the Principled BSDF fed by a Value or RGB node (its default value)."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    b = next(n for n in tree.nodes if n.bl_idname == PRINCIPLED)
    b.distribution = "MULTI_GGX"
    for i, sock in enumerate(s for s in b.inputs if s.enabled and hasattr(s, "default_value")):
        v = sock.default_value
        if sock.type == "RGBA":
            n = tree.nodes.new("ShaderNodeRGB")
            n.outputs[0].default_value = tuple(v)
        elif sock.type == "VECTOR":
            n = tree.nodes.new("ShaderNodeCombineXYZ")
            for j in range(3):
                n.inputs[j].default_value = v[j]
        else:
            n = tree.nodes.new("ShaderNodeValue")
            n.outputs[0].default_value = float(v)
        n.location = (-400, -60 * i)
        if sock.type in ("VECTOR",) and sock.name in ("Normal", "Coat Normal", "Tangent"):
            tree.nodes.remove(n)
            n = tree.nodes.new("ShaderNodeNewGeometry")
            tree.links.new(n.outputs["Normal" if "Normal" in sock.name else "Tangent"], sock)
            continue
        tree.links.new(n.outputs[0], sock)
    return mat


def _ms(xs):
    return {"median": 1e3 * statistics.median(xs), "max": 1e3 * max(xs), "min": 1e3 * min(xs),
            "n": len(xs)}


def _drop_layer_groups(bpy, layer_group):
    for ng in [g for g in bpy.data.node_groups if layer_group.is_layer_group(g)
               or g.name.startswith(".HG ")]:
        bpy.data.node_groups.remove(ng)
    for img in [i for i in bpy.data.images if i.name.startswith(".Hazy Gloss table")]:
        bpy.data.images.remove(img)


def _cache_in(layer_group, cache_dir):
    """Point the per-user group cache at ``cache_dir`` and look at no shipped groups (this
    measures the cache); the caller restores ``_cache_path`` and ``_shipped_path``."""
    layer_group._shipped_path = lambda name: None
    layer_group._cache_path = lambda name: os.path.join(
        cache_dir, "".join(c if c.isalnum() or c == "." else "_" for c in name) + ".blend")


def make_hazy_times(bpy, api, layer_group, make, cache_dir):
    """Make Hazy on fresh materials (not timed: making them), per state of the group."""
    out = {}
    orig_path = layer_group._cache_path, layer_group._shipped_path
    try:
        # built: no cache
        layer_group._cache_path = layer_group._shipped_path = lambda name: None
        xs = []
        for i in range(COLD):
            _drop_layer_groups(bpy, layer_group)
            m = make(bpy, f"cold {i}")
            t0 = time.perf_counter()
            api.make_hazy(m, haziness=0.5)
            xs.append(time.perf_counter() - t0)
        out["built"] = _ms(xs)
        # from the per-user cache (filled once, then every run appends)
        _cache_in(layer_group, cache_dir)
        _drop_layer_groups(bpy, layer_group)
        api.make_hazy(make(bpy, "fill cache"), haziness=0.5)
        xs = []
        for i in range(REPEATS):
            _drop_layer_groups(bpy, layer_group)
            m = make(bpy, f"cache {i}")
            t0 = time.perf_counter()
            api.make_hazy(m, haziness=0.5)
            xs.append(time.perf_counter() - t0)
        out["from the cache"] = _ms(xs)
        # Blender's part of it: the same group appended alone, as _from_cache does, with none of
        # the add-on's work around it (the floor of a first Make Hazy in a file)
        name = next(g.name for g in bpy.data.node_groups if layer_group.is_layer_group(g))
        path = layer_group._cache_path(name)
        xs = []
        for i in range(REPEATS):
            _drop_layer_groups(bpy, layer_group)
            t0 = time.perf_counter()
            with bpy.data.libraries.load(path, link=False) as (_src, dst):
                dst.node_groups = [name]
            xs.append(time.perf_counter() - t0)
        out["append alone"] = _ms(xs)
        xs = []
        for i in range(REPEATS):
            m = make(bpy, f"warm {i}")
            t0 = time.perf_counter()
            api.make_hazy(m, haziness=0.5)
            xs.append(time.perf_counter() - t0)
        out["group in the file"] = _ms(xs)
        ng = next(n.node_tree for n in m.node_tree.nodes
                  if n.bl_idname == "ShaderNodeGroup" and layer_group.is_layer_group(n.node_tree))
        out["node and links"] = node_and_links(bpy, ng, make)
    finally:
        layer_group._cache_path, layer_group._shipped_path = orig_path
    return out


def node_and_links(bpy, ng, make):
    """Blender's part of a later Make Hazy: a group node of the layer's group ``ng`` added to a
    fresh copy and the links into the BSDF made again into it, by socket name (what Make Hazy
    must do at least; every link Blender makes updates the whole tree), nothing of the
    add-on's.  The copies are removed (the add-on's handlers look at every material)."""
    xs = []
    for i in range(REPEATS):
        m = make(bpy, f"links {i}")
        tree = m.node_tree
        core = next(n for n in tree.nodes if n.bl_idname == PRINCIPLED)
        t0 = time.perf_counter()
        node = tree.nodes.new("ShaderNodeGroup")
        node.node_tree = ng
        for link in [lk for lk in tree.links if lk.to_node == core]:
            target = node.inputs.get(link.to_socket.name)
            if target is not None:
                tree.links.new(link.from_socket, target, verify_limits=False)
        for link in [lk for lk in tree.links if lk.from_node == core]:
            tree.links.new(node.outputs[0], link.to_socket)
        xs.append(time.perf_counter() - t0)
        bpy.data.materials.remove(m)
    return _ms(xs)


def _small_group_file(bpy, path):
    """A .blend holding one node group of SMALL_GROUP Math nodes: what any append costs."""
    ng = bpy.data.node_groups.new("perf small group", "ShaderNodeTree")
    ng.interface.new_socket("x", in_out="INPUT", socket_type="NodeSocketFloat")
    ng.interface.new_socket("y", in_out="OUTPUT", socket_type="NodeSocketFloat")
    sock = ng.nodes.new("NodeGroupInput").outputs[0]
    for _ in range(SMALL_GROUP):
        node = ng.nodes.new("ShaderNodeMath")
        ng.links.new(sock, node.inputs[0])
        sock = node.outputs[0]
    ng.links.new(sock, ng.nodes.new("NodeGroupOutput").inputs[0])
    bpy.data.libraries.write(path, {ng}, fake_user=True, compress=True)
    bpy.data.node_groups.remove(ng)
    return "perf small group"


def append_by_file_size(bpy, api, layer_group, cache_dir):
    """The first Make Hazy in files of 0 .. FILE_SIZES[-1] other materials (every input linked,
    34 nodes each), next to Blender's append alone of the layer's group (its 7 node groups and
    table images) and of a small group (one node group of SMALL_GROUP Math nodes)."""
    orig_path = layer_group._cache_path, layer_group._shipped_path
    small_path = os.path.join(cache_dir, "small_group.blend")
    small = _small_group_file(bpy, small_path)
    out = {}
    try:
        _cache_in(layer_group, cache_dir)
        for n in FILE_SIZES:
            C.clean_file()
            for i in range(n):
                all_linked(bpy, f"other {i}")
            api.make_hazy(all_linked(bpy, "fill cache"), haziness=0.5)
            name = next(g.name for g in bpy.data.node_groups if layer_group.is_layer_group(g))
            path = layer_group._cache_path(name)
            row = {"small": [], "layer group": [], "make hazy": []}
            for i in range(FLOOR_REPEATS):
                for what, lib, group in (("small", small_path, small), ("layer group", path, name)):
                    _drop_layer_groups(bpy, layer_group)
                    old = bpy.data.node_groups.get(small)
                    if old is not None:
                        bpy.data.node_groups.remove(old)
                    before = len(bpy.data.node_groups), len(bpy.data.images)
                    t0 = time.perf_counter()
                    with bpy.data.libraries.load(lib, link=False) as (_src, dst):
                        dst.node_groups = [group]
                    row[what].append(time.perf_counter() - t0)
                    if what == "layer group":
                        blocks = (len(bpy.data.node_groups) - before[0],
                                  len(bpy.data.images) - before[1])
                _drop_layer_groups(bpy, layer_group)
                m = all_linked(bpy, f"first {i}")
                t0 = time.perf_counter()
                api.make_hazy(m, haziness=0.5)
                row["make hazy"].append(time.perf_counter() - t0)
                bpy.data.materials.remove(m)
            out[n] = {k: _ms(v) for k, v in row.items()}
            out[n]["data-blocks"] = blocks  # (node groups, images) the layer's group brings
            print(f"[perf_layer_edit] a file of {n} materials: first Make Hazy "
                  f"{out[n]['make hazy']['median']:.0f} ms", flush=True)
    finally:
        layer_group._cache_path, layer_group._shipped_path = orig_path
    C.clean_file()
    return out


def _node_kind_file(bpy, path, idname, n):
    """A .blend holding one group of ``n`` chained nodes of one kind."""
    ng = bpy.data.node_groups.new(f"perf {idname}", "ShaderNodeTree")
    prev = None
    for _ in range(n):
        node = ng.nodes.new(idname)
        if prev is not None:
            ng.links.new(prev.outputs[0], node.inputs[0])
        prev = node
    name = ng.name
    bpy.data.libraries.write(path, {ng}, fake_user=True, compress=True)
    bpy.data.node_groups.remove(ng)
    return name


def append_parts(bpy, api, layer_group, cache_dir):
    """Where Blender's append of the layer's group spends its time, in an empty file: opening
    the group's file with nothing appended, the whole group, the same group from an
    uncompressed copy; and the append of NODE_KIND_COUNT chained nodes per node kind."""
    orig_path = layer_group._cache_path, layer_group._shipped_path
    out = {"files": {}, "kinds": {}}
    try:
        _cache_in(layer_group, cache_dir)
        C.clean_file()
        api.make_hazy(textured(bpy, "parts"), haziness=0.5)
        name = next(g.name for g in bpy.data.node_groups if layer_group.is_layer_group(g))
        path = layer_group._cache_path(name)
        plain = os.path.join(cache_dir, "uncompressed.blend")
        bpy.data.libraries.write(plain, {bpy.data.node_groups[name]}, fake_user=True,
                                 compress=False)
        C.clean_file()
        cases = {"open the group's file, append nothing": (path, None),
                 "append the group": (path, name),
                 "append the group from an uncompressed copy": (plain, name)}
        for kind, idname in NODE_KINDS.items():
            kpath = os.path.join(cache_dir, f"kind {idname}.blend")
            cases[kind] = (kpath, _node_kind_file(bpy, kpath, idname, NODE_KIND_COUNT))
        xs = {k: [] for k in cases}
        for _ in range(FLOOR_REPEATS):
            for what, (lib, group) in cases.items():  # (interleaved)
                t0 = time.perf_counter()
                with bpy.data.libraries.load(lib, link=False) as (_src, dst):
                    if group is not None:
                        dst.node_groups = [group]
                xs[what].append(time.perf_counter() - t0)
                _drop_layer_groups(bpy, layer_group)
                for g in [g for g in bpy.data.node_groups if g.name.startswith("perf ")]:
                    bpy.data.node_groups.remove(g)
        for what, (lib, _group) in cases.items():
            slot = "kinds" if what in NODE_KINDS else "files"
            out[slot][what] = dict(_ms(xs[what]), bytes=os.path.getsize(lib))
    finally:
        layer_group._cache_path, layer_group._shipped_path = orig_path
    C.clean_file()
    return out


def slider_times(bpy, api, layer, make):
    """Haziness set on the layer node + depsgraph update; the first change after Make Hazy
    separately; the plain material's Roughness likewise."""
    scene = bpy.context.scene
    obj = bpy.data.objects.get("perf edit object")
    if obj is None:
        mesh = bpy.data.meshes.new("perf edit mesh")
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
        obj = bpy.data.objects.new("perf edit object", mesh)
        scene.collection.objects.link(obj)
    first, later, plain = [], [], []
    for i in range(REPEATS):
        m = make(bpy, f"slider {i}")
        obj.data.materials.clear()
        obj.data.materials.append(m)
        bpy.context.view_layer.update()
        api.make_hazy(m, haziness=0.5)
        bpy.context.view_layer.update()
        sock = layer.layer_node(m).inputs["Haziness"]
        for k in range(4):
            t0 = time.perf_counter()
            sock.default_value = 0.3 + 0.1 * (k % 2) + 0.01 * i
            bpy.context.view_layer.update()
            (first if k == 0 else later).append(time.perf_counter() - t0)
        p = make(bpy, f"plain {i}")
        obj.data.materials[0] = p
        bpy.context.view_layer.update()
        b = next(n for n in p.node_tree.nodes if n.bl_idname == PRINCIPLED)
        for k in range(4):
            t0 = time.perf_counter()
            b.inputs["Roughness"].default_value = 0.3 + 0.1 * (k % 2)
            bpy.context.view_layer.update()
            plain.append(time.perf_counter() - t0)
    return {"first": _ms(first), "later": _ms(later), "plain": _ms(plain)}


def many_materials(bpy, api, layer):
    """Frame change and a node edit with MANY hazy vs MANY plain materials, interleaved."""
    scenes = {}
    for kind in ("plain", "hazy"):
        sc = bpy.data.scenes.new(f"perf {kind}")
        mesh = bpy.data.meshes.new(f"perf {kind} mesh")
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
        mats = []
        for i in range(MANY):
            m = bpy.data.materials.new(f"{kind} {i}")
            if bpy.app.version < (5, 0, 0):
                m.use_nodes = True
            b = next(n for n in m.node_tree.nodes if n.bl_idname == PRINCIPLED)
            b.inputs["Roughness"].default_value = 0.2
            if kind == "hazy":
                api.make_hazy(m, haziness=0.5)
                b = layer.layer_node(m)
            sock = b.inputs["Roughness"]
            for f, v in ((1, 0.2), (10, 0.4)):
                sock.default_value = v
                sock.keyframe_insert("default_value", frame=f)
            ob = bpy.data.objects.new(f"{kind} {i}", mesh.copy())
            ob.data.materials.append(m)
            sc.collection.objects.link(ob)
            mats.append((m, b))
        scenes[kind] = (sc, mats)
    window_scene = bpy.context.window.scene if bpy.context.window else None
    frame = [1]

    def frame_change(kind):
        sc, _ = scenes[kind]
        frame[0] = 1 + frame[0] % 9
        sc.frame_set(frame[0])

    def edit(kind):
        sc, mats = scenes[kind]
        _, node = mats[len(mats) // 2]
        node.inputs["Base Color"].default_value = (0.2 + 0.1 * (frame[0] % 2), 0.3, 0.4, 1.0)
        sc.view_layers[0].update()
        frame[0] += 1

    res = {}
    for what, fn in (("frame change", frame_change), ("edit of one node", edit)):
        t = C.interleaved({k: (lambda k=k: fn(k)) for k in ("plain", "hazy")}, ROUNDS * 3,
                          warmup=2)
        res[what] = {"ratio": C.paired_ratio(t["wall"], "hazy", "plain"),
                     "ms": {k: 1e3 * statistics.median(t["wall"][k]) for k in t["wall"]}}
    del window_scene
    return res


def main():
    hg = C.start_blender()
    import bpy
    from hazy_gloss import api
    from hazy_gloss.blender.model import layer, layer_group
    del hg
    C.clean_file()
    res = {"repeats": REPEATS, "many": MANY, "rounds": ROUNDS, "blender": bpy.app.version_string,
           "targets": {"first_ms": TARGET_FIRST_MS, "make_ms": TARGET_MAKE_MS,
                       "slider_ms": TARGET_SLIDER_MS}, "materials": {}}
    cache_dir = tempfile.mkdtemp(prefix="hg_group_cache_")
    for label, make in (("textured (8 nodes)", textured), ("every input linked", all_linked),
                        ("textured, GGX (a smaller group)", textured_ggx)):
        C.clean_file()  # (each row in a file of its own: an append's time grows with the file)
        t0 = time.perf_counter()
        row = {"make_hazy": make_hazy_times(bpy, api, layer_group, make, cache_dir),
               "slider": slider_times(bpy, api, layer, make)}
        probe = make(bpy, "probe")
        n0 = len(probe.node_tree.nodes)
        api.make_hazy(probe, haziness=0.5)
        row["top_level_nodes"] = [n0, len(probe.node_tree.nodes)]
        row["issue_material"] = make is not textured_ggx  # (the targets are the issue's two)
        group = layer.layer_node(probe).node_tree
        row["group_nodes"] = C.count_nodes(group)
        res["materials"][label] = row
        print(f"[perf_layer_edit] {label}: make hazy "
              f"{row['make_hazy']['group in the file']['median']:.1f} ms, slider first "
              f"{row['slider']['first']['median']:.2f} ms ({time.perf_counter() - t0:.0f} s)",
              flush=True)
    res["by_file_size"] = append_by_file_size(bpy, api, layer_group, cache_dir)
    res["small_group"] = SMALL_GROUP
    res["append_parts"] = append_parts(bpy, api, layer_group, cache_dir)
    res["append_parts_count"] = NODE_KIND_COUNT
    C.clean_file()
    res["many_materials"] = many_materials(bpy, api, layer)
    res["machine"] = C.machine()
    res["date"] = C.utc_date()
    C.publish("perf_layer_edit", res, markdown(res), BEGIN, END)


def markdown(res):
    t = res["targets"]
    L = ["## 8. Making and editing a layer: how fast\n"]
    L.append(f"Measured by `.venv/bin/python benchmarks/perf_layer_edit.py` on {res['date']} "
             f"(bpy {res['blender']}, {C.machine_line(res['machine'])}); wall time, milliseconds, "
             f"median [min, max] of {res['repeats']} (a built group: of 3).\n")
    L.append("**Make Hazy** (`api.make_hazy(mat, haziness=0.5)`) by where the layer's node group "
             "comes from: already in the file (every Make Hazy after the first of its "
             "configuration: one shared group per configuration), appended from the per-user "
             "cache (the first in a file), built (what a configuration costs the first time when "
             "neither the extension nor the per-user cache has it; the built extension ships "
             "each BSDF's default settings and GGX, these rows' configurations among them). "
             "**A slider change**: the layer node's Haziness set and the depsgraph "
             "updated (what a drag step does; the add-on's depsgraph handler runs in it), next to "
             "the same change of a plain Principled BSDF's Roughness: the difference is the "
             f"add-on's. Targets: the first Make Hazy of a configuration in a file <= "
             f"{t.get('first_ms', t['make_ms']):.0f} ms, every later one <= {t['make_ms']:.0f} "
             f"ms, a slider change <= {t['slider_ms']:.0f} ms (the first included).\n")
    rows = []

    def f(d):
        return f"{d['median']:.1f} [{d['min']:.1f}, {d['max']:.1f}]"

    def g(d):
        return f"{d['median']:.2f} [{d['min']:.2f}, {d['max']:.2f}]"

    for label, r in res["materials"].items():
        mh, sl = r["make_hazy"], r["slider"]
        rows.append([label, f"{r['top_level_nodes'][0]} -> {r['top_level_nodes'][1]}",
                     f"{r.get('group_nodes', '')}",
                     f(mh["group in the file"]), f(mh["node and links"]), f(mh["from the cache"]),
                     f(mh["append alone"]), f(mh["built"]),
                     g(sl["first"]), g(sl["later"]), g(sl["plain"])])
    L.append(C.md_table(["material", "top-level nodes", "nodes in the layer's group",
                         "Make Hazy: group in file", "of it, Blender's node and links",
                         "from the cache", "of it, Blender's append alone", "built",
                         "slider: first change", "later changes",
                         "plain material's change"], rows) + "\n")
    issue = [r for r in res["materials"].values() if r.get("issue_material", True)]
    links = max(r["make_hazy"]["node and links"]["median"] for r in issue)
    append = max(r["make_hazy"]["append alone"]["median"] for r in issue)
    first = max(r["slider"]["first"]["median"] for r in issue)
    first_t = t.get("first_ms", t["make_ms"])
    def verdicts(key, target):
        return "; ".join(
            f"{label} {r['make_hazy'][key]['median']:.1f} ms "
            f"(**{'met' if r['make_hazy'][key]['median'] <= target else 'not met'}**)"
            for label, r in res["materials"].items() if r.get("issue_material", True))

    L.append(f"Make Hazy with the group in the file, target <= {t['make_ms']:.0f} ms: "
             f"{verdicts('group in the file', t['make_ms'])}. Blender's own part takes up to "
             f"{links:.1f} ms of it (a group node of the layer's group added and each link into "
             "the BSDF made again into it; every link Blender makes updates the whole tree). "
             "The first of a configuration in a file "
             f"appends its group from the cache, target <= {first_t:.0f} ms: "
             f"{verdicts('from the cache', first_t)}. Blender's append of the group "
             "(`bpy.data.libraries.load`, nothing of the add-on's around it) takes up to "
             f"{append:.0f} ms of it: Blender's append, not the add-on's code, sets that floor "
             "(by the group's size and the file's: the next table). A slider change, the first "
             f"included: {first:.2f} ms at most "
             f"(**{'met' if first <= t['slider_ms'] else 'not met'}**): setting a socket of the "
             "node is all it does; the shader computes the rest. (Targets: the first two rows; "
             "with every input linked, Make Hazy moves 34 links onto the layer node.)\n")
    others = {k: r for k, r in res["materials"].items() if not r.get("issue_material", True)}
    for label, r in others.items():
        mine = next(iter(res["materials"].values()))
        L.append(f"*{label}*: its group has {r.get('group_nodes')} nodes against "
                 f"{mine.get('group_nodes')}; Blender appends it in "
                 f"{r['make_hazy']['append alone']['median']:.0f} ms against "
                 f"{mine['make_hazy']['append alone']['median']:.0f} ms: in a small file the "
                 "group's size sets the floor of the first Make Hazy.\n")
    fs = res.get("by_file_size")
    if fs:
        sizes = sorted(fs, key=int)
        L.append("**The first Make Hazy in a file, by the file's size** (the file holds that many "
                 "other materials, every input linked, 34 nodes each; the layer's group dropped "
                 "before each run; median [min, max] of "
                 f"{fs[sizes[0]]['make hazy']['n']}), next to Blender's append alone of the "
                 f"layer's group ({fs[sizes[0]]['data-blocks'][0]} node groups, "
                 f"{fs[sizes[0]]['data-blocks'][1]} table images) and of a group of "
                 f"{res['small_group']} Math nodes (one data-block):\n")
        rows = [[str(n), f(fs[n]["make hazy"]), f(fs[n]["layer group"]), f(fs[n]["small"])]
                for n in sizes]
        L.append(C.md_table(["other materials in the file", "first Make Hazy",
                             "Blender's append of the layer's group",
                             f"Blender's append of {res['small_group']} Math nodes"], rows) + "\n")
        big = sizes[-1]
        floor = fs[big]["small"]["median"]
        verdict = (f"The first Make Hazy of a configuration in a file of that size cannot meet "
                   f"{t['make_ms']:.0f} ms with any group Blender appends"
                   if floor > t["make_ms"] else
                   f"A small group still appends in {floor:.0f} ms there: the layer's group's "
                   "size sets the floor")
        L.append(f"Blender's append grows with the file it appends into: in a file of {big} "
                 f"materials even the {res['small_group']}-node group takes "
                 f"{fs[big]['small']['median']:.0f} ms (in an empty file "
                 f"{fs[sizes[0]]['small']['median']:.1f} ms), and the layer's group, which "
                 f"brings {sum(fs[big]['data-blocks'])} data-blocks, "
                 f"{fs[big]['layer group']['median']:.0f} ms. {verdict}; building the group "
                 "with Python instead costs the seconds of the *built* column. Every later "
                 "Make Hazy in that file reuses the group (the first table's *group in file*).\n")
    ap = res.get("append_parts")
    if ap:
        files, kinds = ap["files"], ap["kinds"]
        rows = [[what, f(d), f"{d['bytes'] / 1e3:,.0f}"] for what, d in files.items()]
        L.append("**What Blender's append of the layer's group is made of** (an empty file; "
                 f"median [min, max] of {next(iter(files.values()))['n']}, interleaved):\n")
        L.append(C.md_table(["what", "ms", "file kB"], rows) + "\n")
        per = {k: 1e3 * d["median"] / res["append_parts_count"] for k, d in kinds.items()}
        opened = files["open the group's file, append nothing"]["median"]
        whole = files["append the group"]["median"]
        plain = files["append the group from an uncompressed copy"]["median"]
        L.append(f"Opening the group's file alone takes {opened:.1f} ms of the {whole:.1f} "
                 "(Blender reads and decompresses the whole file before it appends anything); "
                 f"an uncompressed copy appends in {plain:.1f} ms from "
                 f"{files['append the group from an uncompressed copy']['bytes'] / 1e6:.1f} MB "
                 "instead of "
                 f"{files['append the group']['bytes'] / 1e6:.2f} MB, which is why the "
                 "extension ships compressed groups. The rest is per node: appending "
                 f"{res['append_parts_count']} chained nodes costs, per node, "
                 + ", ".join(f"{k} {v:.0f} µs" for k, v in per.items())
                 + " (a Mix node carries every socket variant of its data types).\n")
    mm = res["many_materials"]
    rows = [[what, f"{d['ms']['plain']:.2f}", f"{d['ms']['hazy']:.2f}", C.fmt_ratio(d["ratio"])]
            for what, d in mm.items()]
    L.append(f"**{res['many']} materials** (one object each, every material's Roughness keyed; "
             "interleaved plain / hazy, "
             f"{3 * res['rounds']} rounds, median ms and the ratio hazy / plain):\n")
    L.append(C.md_table(["what", f"{res['many']} plain", f"{res['many']} hazy",
                         "hazy / plain"], rows) + "\n")
    return "\n".join(L)


if __name__ == "__main__":
    main()
