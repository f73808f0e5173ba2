# SPDX-License-Identifier: GPL-3.0-or-later
"""The layer node computes what the render depends on: keyframes and drivers on any
input render right on every frame, with the add-on and in a fresh process without it; links into
the haze inputs work; a paintable haziness map; earlier layers render as saved and move on an edit; no
material exceeds Cycles' closure limit; every entry point answers."""
import importlib
import json
import os
import re
import subprocess
import sys
import warnings
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

import scenes
import test_ui
from measurements import record
from test_layer import car_paint, metallic_map, principled, rel_diff, render


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return SimpleNamespace(api=mod("api"), layer=mod("blender.model.layer"), exr=mod("conversion.imagecheck"),
                           reports=mod("blender.ui.reports"), material=mod("blender.model.material"),
                           E=mod("blender.actions.eevee_output"), hg=hg)


DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data")

# keys: (input, [(frame, value), ...]); the same keys on every material of the test
KEYS = {
    "Roughness": [(1, 0.15), (10, 0.35)],
    "Base Color": [(1, (0.6, 0.05, 0.05, 1.0)), (10, (0.1, 0.3, 0.7, 1.0))],
    "Metallic": [(1, 1.0), (10, 0.4)],
    "Haziness": [(1, 0.2), (10, 0.8)],
    "Coat Haziness": [(1, 0.0), (10, 0.6)],
}
FRAMES = (1, 5, 10)


def _animate(node):
    for name, keys in KEYS.items():
        sock = node.inputs[name]
        for frame, value in keys:
            sock.default_value = value
            sock.keyframe_insert("default_value", frame=frame)
    # a driver too: the halo's extent follows the frame (a simple expression: no Python needed)
    fc = node.inputs["Haze Extent X"].driver_add("default_value")
    fc.driver.type = "SCRIPTED"
    fc.driver.expression = "3 + frame / 2"
    node.inputs["Haze Extent Y"].default_value = 4.0


FARM = r'''
import json, os, sys
import bpy
import numpy as np
blend, out, frames = sys.argv[1], sys.argv[2], [int(f) for f in sys.argv[3].split(",")]
bpy.ops.wm.open_mainfile(filepath=blend)
info = {"modules": sorted(n for n in sys.modules if "hazy_gloss" in n)}
scene = bpy.context.scene
for f in frames:
    scene.frame_set(f)
    scene.render.filepath = os.path.join(out, f"farm_{f}.exr")
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(scene.render.filepath)
    buf = np.empty(img.size[0] * img.size[1] * img.channels, dtype=np.float32)
    img.pixels.foreach_get(buf)
    np.save(os.path.join(out, f"farm_{f}.npy"), buf.reshape(img.size[1], img.size[0], img.channels))
print("INFO " + json.dumps(info))
sys.stdout.flush()
os._exit(0)
'''


def _farm(tmp_path, blend, frames):
    script = tmp_path / "farm.py"
    script.write_text(FARM)
    env_vars = dict(os.environ)
    env_vars["BLENDER_USER_RESOURCES"] = str(tmp_path / "no_addons")  # nothing installed
    env_vars.pop("PYTHONPATH", None)
    proc = subprocess.run([sys.executable, str(script), blend, str(tmp_path), ",".join(map(str, frames))],
                          cwd=str(tmp_path), env=env_vars, capture_output=True, text=True, timeout=600)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("INFO ")), None)
    assert proc.returncode == 0 and line, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert json.loads(line[5:])["modules"] == []
    return {f: np.load(tmp_path / f"farm_{f}.npy") for f in frames}


def test_keyframes_and_drivers_on_any_input_render_right(env, tmp_path):
    """Roughness, Base Color, Metallic, Haziness and Coat Haziness keyframed and the haze extent
    driven on the layer node of a coated car paint: every frame renders what Make Hazy on a
    material holding that frame's values renders (≤ 1e-5 of the peak), and a farm without the
    add-on renders the saved file pixel for pixel as this session does."""
    mat = car_paint()
    assert bpy.ops.hazy_gloss.make_hazy(material=mat.name) == {"FINISHED"}
    node = env.layer.layer_node(mat)
    _animate(node)
    scenes.setup_render("CYCLES", samples=1, resolution=(8, 8), bounces=0)
    scenes.flat_plane_scene(mat, light_dir=(30.0, 0.0), view_dir=(10.0, 180.0))
    scene = bpy.context.scene
    ours, want, values = {}, {}, {}
    for f in FRAMES:
        scene.frame_set(f)
        vals = {s.name: (tuple(s.default_value) if hasattr(s.default_value, "__len__")
                         else s.default_value) for s in node.inputs
                if hasattr(s, "default_value")}
        values[f] = vals
        ours[f] = scenes.render_exr()[..., :3]
    blend = str(tmp_path / "animated.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    farm = _farm(tmp_path, blend, FRAMES)
    # the static material of each frame: a fresh Principled with that frame's values, Make Hazy
    for f in FRAMES:
        v = values[f]
        static, bsdf = principled(f"Static {f}")
        for s in bsdf.inputs:
            if s.enabled and s.name in v and hasattr(s, "default_value") and not s.is_linked:
                s.default_value = v[s.name]
        env.api.make_hazy(static, haziness=v["Haziness"], haze_extent=(v["Haze Extent X"], 4.0),
                          coat_haziness=v["Coat Haziness"], coat_haze_extent=v["Coat Haze Extent"])
        scene.frame_set(f)
        want[f] = render(env, static, (30.0, 0.0), (10.0, 180.0))["combined"]
    errs = {f: rel_diff(ours[f], want[f]) for f in FRAMES}
    farm_diff = {f: float(np.abs(farm[f][..., :3] - ours[f]).max()) for f in FRAMES}
    record("layer_animation", {"frame vs static material": errs, "farm vs add-on": farm_diff,
                               "haze extent x by frame": {f: values[f]["Haze Extent X"] for f in FRAMES}})
    assert values[10]["Haze Extent X"] == pytest.approx(8.0)  # the driver ran
    assert rel_diff(ours[1], ours[10]) > 0.05  # the animation shows
    assert max(errs.values()) <= 1e-5, errs
    assert max(farm_diff.values()) == 0.0, farm_diff


def test_links_into_the_haze_inputs(env):
    """A procedural mask into Haziness: per pixel, the render is the layer at that pixel's
    haziness (pixel columns of a ramp against constant materials)."""
    mat, b = principled("Masked", **{"Metallic": 1.0, "Base Color": (0.9, 0.6, 0.3, 1.0),
                                     "Roughness": 0.3})
    env.api.make_hazy(mat, haziness=0.0)
    node = env.layer.layer_node(mat)
    tree = mat.node_tree
    coord = tree.nodes.new("ShaderNodeTexCoord")
    sep = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(coord.outputs["Window"], sep.inputs[0])
    tree.links.new(sep.outputs["X"], node.inputs["Haziness"])  # haziness = the window's x
    got = render(env, mat, (20.0, 0.0), (0.0, 0.0), res=(8, 2))["combined"]
    const, _ = principled("Const", **{"Metallic": 1.0, "Base Color": (0.9, 0.6, 0.3, 1.0),
                                      "Roughness": 0.3})
    env.api.make_hazy(const)
    worst = 0.0
    for col in (1, 4, 6):
        env.api.update_material(const, haziness=(col + 0.5) / 8.0)
        want = render(env, const, (20.0, 0.0), (0.0, 0.0), res=(8, 2))["combined"]
        worst = max(worst, rel_diff(got[:, col], want[:, col]))
    assert worst <= 1e-4, worst  # (the window coordinate of a pixel centre in float32)
    assert rel_diff(got[:, 1], got[:, 6]) > 0.01


def test_add_haziness_map(env):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.3)
    n0 = len(mat.node_tree.nodes)
    env.reports.last_reports.clear()
    assert bpy.ops.hazy_gloss.add_haziness_map(material=mat.name, size=64) == {"FINISHED"}
    node = env.layer.layer_node(mat)
    sock = node.inputs["Haziness"]
    tex = sock.links[0].from_node
    assert tex.bl_idname == "ShaderNodeTexImage" and mat.node_tree.nodes.active == tex
    img = tex.image
    assert img.size[:] == (64, 64) and img.packed_file is not None
    assert img.colorspace_settings.is_data
    px = np.empty(64 * 64 * 4, np.float32)
    img.pixels.foreach_get(px)
    assert np.allclose(px.reshape(-1, 4)[:, 0], 0.3, atol=1e-6)  # filled with the value it had
    assert len(mat.node_tree.nodes) == n0 + 1
    # twice: refused (one line), the link stays
    with pytest.raises(RuntimeError, match="linked to .* already"):
        bpy.ops.hazy_gloss.add_haziness_map(material=mat.name)
    assert sock.links[0].from_node == tex
    # Make Hazy again (the panel's button, a pipeline re-run) reports the map (it raised on
    # formatting "texture" as a number)
    env.reports.last_reports.clear()
    assert bpy.ops.hazy_gloss.make_hazy(material=mat.name) == {"FINISHED"}
    assert any("(haziness a map)" in r for r in map(str, env.reports.last_reports))
    # and it renders the value it holds: the same as the constant
    a = render(env, mat, (25.0, 0.0), (0.0, 0.0))["combined"]
    mat.node_tree.links.remove(sock.links[0])
    b = render(env, mat, (25.0, 0.0), (0.0, 0.0))["combined"]
    assert rel_diff(a, b) <= 1e-6
    # Remove Haze keeps the painted map (the artist's paint); haze put back takes it again
    # instead of a new image and node each time (QA: 4 -> 9 nodes, 6 -> 11 images)
    env.api.remove_haze(mat)
    env.api.make_hazy(mat, haziness=0.3)
    n1, images = len(mat.node_tree.nodes), len(bpy.data.images)
    assert env.api.add_haziness_map(mat) == img
    assert env.layer.layer_node(mat).inputs["Haziness"].links[0].from_node == tex
    assert (len(mat.node_tree.nodes), len(bpy.data.images)) == (n1, images)


def test_a_map_on_an_animated_haziness_says_it_replaces_the_keys(env):
    """Add Haziness Map on a keyed Haziness: the map holds this frame's value and the keys no
    longer do anything: it says so (it said nothing, QA)."""
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.3)
    sock = env.layer.layer_node(mat).inputs["Haziness"]
    for frame, value in ((1, 0.2), (10, 0.9)):
        sock.default_value = value
        sock.keyframe_insert("default_value", frame=frame)
    with pytest.warns(UserWarning, match="Haziness was animated: the map .* decides it now"):
        env.api.add_haziness_map(mat, size=16)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (Coat Haziness is not animated: nothing to say)
        env.api.add_haziness_map(mat, size=16, param="coat_haziness")


def test_texture_paint_lists_the_haziness_map_only(env):
    """Texture Paint's slots: the haziness map, made the active one, and not the layer's lookup
    tables (a thin film's part reads one; Blender lists every Image Texture inside a
    material's node groups, so the tables were read with those, an artist could paint over
    them)."""
    mat, _ = principled("Painted", distribution="MULTI_GGX", **{"Thin Film Thickness": 300.0})
    mesh = bpy.data.meshes.new("Painted")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new()
    mesh.materials.append(mat)
    ob = bpy.data.objects.new("Painted", mesh)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    env.api.make_hazy(mat, haziness=0.3)
    tables = {n.image.name for g in bpy.data.node_groups for n in g.nodes
              if getattr(n, "image", None) is not None}
    assert len(tables) >= 1, tables  # (the layer does read a table here)
    env.api.add_haziness_map(mat, size=16)
    bpy.ops.object.mode_set(mode="TEXTURE_PAINT")
    try:
        slots = [i.name for i in mat.texture_paint_images]
        assert slots == [f"{mat.name} Haziness"] and mat.paint_active_slot == 0, slots
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")


def test_a_painted_haziness_map_is_saved_with_the_paint(env, tmp_path):
    """Painting changes the image in memory; Blender writes a packed image's old bytes unless it
    is packed again: the add-on packs its painted maps before each save."""
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.3)
    img = env.api.add_haziness_map(mat, size=16)
    name = img.name
    painted = np.random.default_rng(7).random(16 * 16 * 4).astype(np.float32)
    img.pixels.foreach_set(painted)  # (what a brush stroke does: the image is dirty)
    assert img.is_dirty
    path = str(tmp_path / "painted.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    back = np.empty(16 * 16 * 4, np.float32)
    bpy.data.images[name].pixels.foreach_get(back)
    rgb = (slice(None), slice(0, 3))  # (an RGB image: alpha reads 1)
    assert np.array_equal(back.reshape(-1, 4)[rgb], painted.reshape(-1, 4)[rgb])


def test_remove_haze_keeps_a_painted_map_and_says_so(env):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.3)
    img = env.api.add_haziness_map(mat, size=16)
    with pytest.warns(UserWarning, match=f"the haziness map “{img.name}” stays in the tree"):
        env.api.remove_haze(mat)
    assert any(getattr(n, "image", None) == img for n in mat.node_tree.nodes)


def test_a_map_on_objects_without_uvs_warns(env):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.3)
    mesh = bpy.data.meshes.new("no uv")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    mesh.materials.append(mat)
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("no uv", mesh))
    with pytest.warns(UserWarning, match="no UV map"):
        env.api.add_haziness_map(mat, size=16)


# --------------------------------------------------------------------------------------------
# Closures: none over Cycles' limit (the harness fails any render that logs it)
# --------------------------------------------------------------------------------------------


def test_metallic_checker_under_a_hazy_coat_stays_within_the_closure_limit(env):
    """The issue's worst case: a checker into Metallic, Coat 1, haziness and coat haziness 0.3
    (8 Principled copies before): the layer renders within 64 closures (5 Principled at most),
    and checker texels (0 or 1) are exactly the pure materials' layers."""
    mat, b = principled("Checker Metal", **{"Base Color": (0.8, 0.5, 0.3, 1.0), "Roughness": 0.3,
                                            "Coat Weight": 1.0, "Coat Roughness": 0.05})
    checker = mat.node_tree.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 2.0
    mat.node_tree.links.new(checker.outputs["Fac"], b.inputs["Metallic"])
    env.api.make_hazy(mat, haziness=0.3, coat_haziness=0.3)
    got = render(env, mat, (30.0, 0.0), (0.0, 0.0))["combined"]  # raises on the closure warning
    assert got.max() > 0.0
    inner = env.layer.layer_node(mat).node_tree
    assert sum(n.bl_idname == "ShaderNodeBsdfPrincipled" for n in inner.nodes) <= 6  # 5 + EEVEE


# --------------------------------------------------------------------------------------------
# Files from before: layers of an earlier add-on open, render as saved and move on an edit
# --------------------------------------------------------------------------------------------


def test_a_4_5_layers_keys_and_drivers_stay_on_their_inputs_in_every_blender(env, tmp_path):
    """A layer node keyed and driven in 4.5, beside a Principled BSDF of its name: 5.2 opens the
    file moving the layer node's curves at inputs 5-30 up one (its versioning for the
    Principled's Thin Wall input takes every node of a Principled's name; Coat Weight's keys
    drove Coat Roughness, Haziness's Haze Extent X).  The add-on puts them back on load; keys
    on two inputs Blender put on one position are told apart by their values."""
    path = tmp_path / "animated.blend"
    path.write_bytes(open(os.path.join(DATA, "animated_layer_4_5.blend"), "rb").read())
    bpy.ops.wm.open_mainfile(filepath=str(path))
    mat = bpy.data.materials["Animated layer"]
    tree = mat.node_tree
    want = sorted((name, index) for _, index, name in json.loads(mat["expected_curves"]))
    anim = tree.animation_data
    curves = list(anim.drivers) + [fc for layer in anim.action.layers for strip in layer.strips
                                   for bag in strip.channelbags for fc in bag.fcurves] \
        if bpy.app.version >= (4, 4) else []
    got = sorted((tree.path_resolve(fc.data_path.rsplit(".", 1)[0]).name, fc.array_index)
                 for fc in curves)
    assert got == want
    assert env.api.last_error(mat) is None



def test_a_file_with_an_earlier_layer_renders_as_saved_and_moves_on_an_edit(env, tmp_path):
    """tests/data/earlier_layers_4_5.blend: layers made by the add-on before its groups held
    only the parts a material uses (one ~1,200-node group in section groups).  Opened here,
    nothing moves (the notes say Upgrade) and each renders what the file renders without the
    add-on; the first haze edit moves it to today's group of its parts, whose render is a
    fresh Make Hazy's of the same values."""
    path = tmp_path / "earlier.blend"
    path.write_bytes(open(os.path.join(DATA, "earlier_layers_4_5.blend"), "rb").read())
    bpy.ops.wm.open_mainfile(filepath=str(path))
    lg = importlib.import_module(f"{env.hg.__name__}.blender.model.layer_group")
    names = ("Earlier plastic", "Earlier car paint")
    old = {n: env.layer.layer_node(bpy.data.materials[n]).node_tree for n in names}
    assert all((g.get("hazy_gloss_group") or {}).get("version") == 3 for g in old.values())
    for n in names:  # here, and the file as saved where the add-on is not installed
        mat = bpy.data.materials[n]
        scenes.setup_render("CYCLES", samples=1, resolution=(8, 8), bounces=0)
        for o in list(bpy.data.objects):
            bpy.data.objects.remove(o)
        scenes.flat_plane_scene(mat, light_dir=(30.0, 0.0), view_dir=(10.0, 180.0))
        here = scenes.render_exr()[..., :3]
        assert env.layer.layer_node(mat).node_tree == old[n]  # (rendering moved nothing)
        assert any("Upgrade Haze Layers" in t for t in env.api.read_parameters(mat)["notes"])
        blend = str(tmp_path / f"{n}.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
        farm = _farm(tmp_path, blend, (1,))[1][..., :3]
        assert here.max() > 0.01 and np.array_equal(farm, here), n
    for n in names:
        mat = bpy.data.materials[n]
        h = env.api.read_parameters(mat)["haziness"]
        env.api.update_material(mat, haziness=h)  # the first haze edit: the same value
        g = env.layer.layer_node(mat).node_tree
        assert g != old[n] and g["hazy_gloss_group"]["version"] == lg.LAYER_GROUP_VERSION, n
        assert not any("Upgrade" in t for t in env.api.read_parameters(mat)["notes"]), n
        fresh = mat.copy()
        env.api.remove_haze(fresh)
        p = env.api.read_parameters(mat)
        env.api.make_hazy(fresh, haziness=p["haziness"], coat_haziness=p["coat_haziness"],
                          haze_extent=p["haze_extent"])
        assert np.array_equal(render(env, mat, (30.0, 0.0), (10.0, 180.0))["combined"],
                              render(env, fresh, (30.0, 0.0), (10.0, 180.0))["combined"]), n


# --------------------------------------------------------------------------------------------
# Every entry point answers
# --------------------------------------------------------------------------------------------


def test_make_hazy_on_a_hazy_material_updates_it(env):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.3)
    env.api.make_hazy(mat, haziness=0.6, coat_haziness=0.2)  # a pipeline re-run
    p = env.api.read_parameters(mat)
    assert p["haziness"] == pytest.approx(0.6) and p["coat_haziness"] == pytest.approx(0.2)
    env.reports.last_reports.clear()
    assert bpy.ops.hazy_gloss.make_hazy(material=mat.name, haziness=0.1) == {"FINISHED"}
    assert "Updated" in env.reports.last_reports[0][1]


def test_make_hazy_again_changes_only_what_it_is_given(env):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.4, haze_extent=8.0, coat_haziness=0.3, coat_haze_extent=7.0)
    env.api.make_hazy(mat, coat_haziness=0.6)
    p = env.api.read_parameters(mat)
    assert p["haziness"] == pytest.approx(0.4) and tuple(p["haze_extent"]) == (8.0, 8.0)
    assert p["coat_haziness"] == pytest.approx(0.6) and p["coat_haze_extent"] == 7.0
    assert bpy.ops.hazy_gloss.make_hazy(material=mat.name) == {"FINISHED"}  # nothing given
    assert env.api.read_parameters(mat)["haziness"] == pytest.approx(0.4)
    fresh, _ = principled("Fresh")
    env.api.make_hazy(fresh, coat_haziness=0.2)  # a new layer: the defaults for the rest
    p = env.api.read_parameters(fresh)
    assert p["haziness"] == 0.0 and tuple(p["haze_extent"]) == (5.0, 5.0)


def test_a_node_that_is_not_a_node_is_refused_in_one_line(env):
    mat = car_paint()
    for _ in ("plain", "hazy"):
        with pytest.raises(ValueError, match=r"^node must be a node or its name, got 123$"):
            env.api.make_hazy(mat, haziness=0.2, node=123)
        env.api.make_hazy(mat, haziness=0.2)


def test_a_group_that_cannot_be_built_leaves_nothing_behind(env, monkeypatch):
    lg = importlib.import_module(f"{env.hg.__name__}.blender.model.layer_group")
    monkeypatch.setattr(lg, "_from_cache", lambda name, config: None)

    def half_built(ng, *config):
        ng.nodes.new("ShaderNodeMath")
        bpy.data.node_groups.new("Half built", "ShaderNodeTree")
        raise RuntimeError("the builder broke")
    monkeypatch.setattr(lg, "build", half_built)
    mat = car_paint()
    with pytest.raises(ValueError, match=r"^Building the layer group .* failed: the builder broke$"):
        env.api.make_hazy(mat, haziness=0.3)
    assert not bpy.data.node_groups and env.layer.layer_node(mat) is None


def test_a_setting_saved_by_a_newer_blender_is_refused_in_one_line(env):
    """tests/data/principled_5_3.blend: a default Principled BSDF saved by 5.3 (read_homefile
    use_empty, one material with a fake user); 4.5 reads its Subsurface Method as no item."""
    bpy.ops.wm.open_mainfile(filepath=os.path.join(DATA, "principled_5_3.blend"))
    mat = bpy.data.materials["Principled 5.3"]
    if mat.node_tree.nodes["Principled BSDF"].subsurface_method:
        env.api.make_hazy(mat, haziness=0.3)  # (5.2, 5.3: the enum is known)
        assert env.layer.layer_node(mat) is not None
        return
    with pytest.raises(ValueError, match=r"^The Subsurface Method of “Principled BSDF” is one "
                                         r"this Blender does not know"):
        env.api.make_hazy(mat, haziness=0.3)
    assert not bpy.data.node_groups and env.layer.layer_node(mat) is None


def test_a_layer_on_another_blenders_group_moves_to_this_ones(env):
    """A file saved by another Blender keeps that Blender's group (its Multiscatter correction
    reads that Blender's tables): the layer says so (and not "edited by hand": that group's
    nodes hash otherwise here), and Upgrade Haze Layers or a haze edit moves it to this
    Blender's group with its values and links."""
    lg = importlib.import_module(f"{env.hg.__name__}.blender.model.layer_group")
    mats = [car_paint(), car_paint()]
    for m in mats:
        env.api.make_hazy(m, haziness=0.4, coat_haziness=0.2)
    ng = env.layer.layer_node(mats[0]).node_tree
    _as_made_by(ng, lg, "4.2")
    # another Blender's nodes hash otherwise (its own sockets and defaults): not "edited by hand"
    free = next(s for n in ng.nodes if n.bl_idname == "ShaderNodeMath" for s in n.inputs
                if not s.is_linked and s.enabled)
    free.default_value += 0.25
    tex = mats[0].node_tree.nodes.new("ShaderNodeValue")
    mats[0].node_tree.links.new(tex.outputs[0], env.layer.layer_node(mats[0]).inputs["Roughness"])
    for m in mats:
        notes = env.api.read_parameters(m)["notes"]
        assert any("made by Blender 4.2: Upgrade Haze Layers" in n for n in notes), m.name
        assert not any("edited by hand" in n for n in notes), notes
    env.api.update_material(mats[0], haziness=0.5)
    assert env.api.upgrade_layers() == [mats[1].name]
    for m, h in zip(mats, (0.5, 0.4)):
        node = env.layer.layer_node(m)
        assert node.node_tree != ng and lg.fits(node.node_tree, *env.layer.wanted_group(node))
        p = env.api.read_parameters(m)
        assert (p["haziness"], p["coat_haziness"]) == (pytest.approx(h), pytest.approx(0.2))
        assert not any("made by" in n for n in p["notes"])
    assert env.layer.layer_node(mats[0]).inputs["Roughness"].links[0].from_node == tex
    assert ng.users == 0  # (dropped on save)


def _driven(tree):
    """{(node, input name, path tail): curve kind} for every input curve of ``tree``."""
    out = {}
    anim = tree.animation_data
    curves = [(fc, "driver") for fc in anim.drivers] + [
        (fc, "key") for layer in anim.action.layers for strip in layer.strips
        for bag in strip.channelbags for fc in bag.fcurves] if bpy.app.version >= (4, 4) else []
    for fc, kind in curves:
        sock = tree.path_resolve(fc.data_path.rsplit(".", 1)[0])
        out[(sock.node.name, sock.name)] = kind
    return out


@pytest.mark.parametrize("change", ["smoothness", "keep_body_colour", "another_blender",
                                    "another_blenders_bsdf"])
def test_a_group_change_keeps_keys_drivers_and_links_on_their_inputs(env, change):
    """Smoothness, Keep Body Colour or another Blender's group give the layer node a group with
    other sockets: keys, drivers, links (a muted one stays muted) and the values under links
    stay on the inputs of the same name (Blender keeps them by position and identifier: keys
    on Coat Haziness moved to Reflectivity Cap, a link into Coat Haze Extent to Coat Haziness).
    *another_blenders_bsdf*: a group whose BSDF has an input fewer (5.2's Principled against
    5.3's): setting the group moves the curves by identifier, and moving them again by the
    old positions put Coat Weight's keys on Coat Roughness, Haziness's driver on Haze Extent X."""
    mat = car_paint()
    tree = mat.node_tree
    rough = tree.nodes.new("ShaderNodeValue")
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tree.links.new(rough.outputs[0], bsdf.inputs["Roughness"]).is_muted = True
    env.api.make_hazy(mat, haziness=0.4, coat_haziness=0.2)
    node = env.layer.layer_node(mat)
    lg = importlib.import_module(f"{env.hg.__name__}.blender.model.layer_group")
    if change == "another_blenders_bsdf":  # (an input before Coat Weight gone, as in 5.2's)
        older = node.node_tree.copy()
        older.interface.remove(next(i for i in older.interface.items_tree
                                    if getattr(i, "name", "") == "Specular Tint"))
        _as_made_by(older, lg, "5.1")
        node.node_tree = older
        for frame, value in ((1, 0.2), (10, 0.9)):
            node.inputs["Coat Weight"].default_value = value
            node.inputs["Coat Weight"].keyframe_insert("default_value", frame=frame)
    assert node.inputs["Roughness"].links[0].is_muted  # (a muted link renders nothing)
    for frame, value in ((1, 0.1), (10, 0.6)):
        node.inputs["Coat Haziness"].default_value = value
        node.inputs["Coat Haziness"].keyframe_insert("default_value", frame=frame)
    fc = node.inputs["Haziness"].driver_add("default_value")
    fc.driver.expression = "0.3"
    ext = tree.nodes.new("ShaderNodeValue")
    node.inputs["Coat Haze Extent"].default_value = 7.0
    tree.links.new(ext.outputs[0], node.inputs["Coat Haze Extent"])
    before = _driven(tree)
    old = node.node_tree
    if change == "another_blender":
        _as_made_by(old, lg, "4.2")
    if change.startswith("another_blender"):
        env.api.upgrade_layers()
    else:
        env.api.update_material(mat, **{change: 2.0 if change == "smoothness" else True})
    assert node.node_tree != old
    keyed = {(node.name, "Coat Haziness"): "key", (node.name, "Haziness"): "driver"}
    if change == "another_blenders_bsdf":
        keyed[(node.name, "Coat Weight")] = "key"
    assert _driven(tree) == before == keyed
    assert [l.from_node for l in node.inputs["Coat Haze Extent"].links] == [ext]
    assert node.inputs["Coat Haze Extent"].default_value == pytest.approx(7.0)
    assert not node.inputs["Coat Haziness"].is_linked
    assert [(l.from_node, l.is_muted) for l in node.inputs["Roughness"].links] == [(rough, True)]
    name = node.name
    env.api.remove_haze(mat)
    assert tree.nodes[name].bl_idname == "ShaderNodeBsdfPrincipled"
    # (the haze inputs' curves go with the layer node, the BSDF's back onto it)
    assert _driven(tree) == ({(name, "Coat Weight"): "key"} if change == "another_blenders_bsdf"
                             else {})


def test_setting_an_animated_or_linked_haze_value_says_what_decides_it(env):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.4)
    node = env.layer.layer_node(mat)
    node.inputs["Haziness"].keyframe_insert("default_value", frame=1)
    tex = mat.node_tree.nodes.new("ShaderNodeValue")
    mat.node_tree.links.new(tex.outputs[0], node.inputs["Coat Haziness"])
    for notes in (env.api.make_hazy(mat, haziness=0.9, coat_haziness=0.5),
                  env.api.update_material(mat, haziness=0.8, coat_haziness=0.1)):
        said = sorted(n for n in notes if n.startswith(("Haziness", "Coat Haziness")))
        assert len(said) == 2, notes
        assert "linked" in said[0] and "animated" in said[1]  # (Coat Haziness, Haziness)
    assert not any(n.startswith("Haze Extent") for n in env.api.update_material(mat, haze_extent=3))


def _node_curves(mat):
    """{data path: values at frames 1 and 10} of the curves animating ``mat``'s node tree."""
    anim = mat.node_tree.animation_data
    curves = [fc for layer in anim.action.layers for strip in layer.strips
              for fc in strip.channelbag(anim.action_slot).fcurves]
    return {fc.data_path: (fc.evaluate(1), fc.evaluate(10)) for fc in curves}


@pytest.mark.parametrize("shared_by", ["copy of the material", "another slot"])
def test_a_shared_action_stays_with_the_material_that_did_not_change(env, shared_by):
    mat, bsdf = principled("Paint")
    for name, keys in (("Coat Roughness", [(1, 0.1), (10, 0.5)]),
                       ("Emission Strength", [(1, 0.0), (10, 2.0)])):
        for frame, value in keys:
            bsdf.inputs[name].default_value = value
            bsdf.inputs[name].keyframe_insert("default_value", frame=frame)
    twin = mat.copy()
    if shared_by == "another slot":  # one action, a slot per material (4.4+ slotted actions)
        twin.node_tree.animation_data.action_slot = mat.node_tree.animation_data.action.slots.new(
            "NODETREE", "twin")
        for name, (a, b) in _node_curves(mat).items():
            fc = twin.node_tree.animation_data.action.layers[0].strips[0].channelbag(
                twin.node_tree.animation_data.action_slot, ensure=True).fcurves.new(name)
            fc.keyframe_points.insert(1, a)
            fc.keyframe_points.insert(10, b)
    before = _node_curves(twin)
    shared = twin.node_tree.animation_data.action == mat.node_tree.animation_data.action
    assert shared and len(before) == 2
    env.api.make_hazy(mat, haziness=0.3)
    assert _node_curves(twin) == before
    node = env.layer.layer_node(mat)
    assert {p.split(".inputs")[0] for p in _node_curves(mat)} == {f'nodes["{node.name}"]'}
    for name in ("Coat Roughness", "Emission Strength"):
        assert node.inputs[name].path_from_id() + ".default_value" in _node_curves(mat)
    copy = mat.copy()  # a copy of the hazy one, then its haze taken off: the original keeps it
    env.api.remove_haze(copy)
    assert {p.split(".inputs")[0] for p in _node_curves(mat)} == {f'nodes["{node.name}"]'}
    assert len(_node_curves(mat)) == 2 and _node_curves(twin) == before
    assert _node_curves(copy) == before


def test_remove_haze_after_the_kept_bsdf_was_deleted_gives_a_new_one(env):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.5)
    tree = mat.node_tree
    node = env.layer.layer_node(mat)
    node.inputs["Roughness"].default_value = 0.27
    tex = tree.nodes.new("ShaderNodeValue")
    tree.links.new(tex.outputs[0], node.inputs["Coat Weight"])
    tree.nodes.remove(env.layer.original_node(mat))
    with pytest.warns(UserWarning, match="was deleted: a new one"):
        assert env.api.remove_haze(mat) is True
    bsdf = tree.nodes["Principled BSDF"]
    assert bsdf.bl_idname == "ShaderNodeBsdfPrincipled" and not env.layer.is_layered(mat)
    assert bsdf.inputs["Roughness"].default_value == pytest.approx(0.27)
    assert bsdf.inputs["Coat Weight"].links[0].from_node == tex
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    assert out.inputs["Surface"].links[0].from_node == bsdf
    assert not any(n.bl_idname == "ShaderNodeGroup" for n in tree.nodes)
    env.api.make_hazy(mat, haziness=0.3)  # and it can be made hazy again
    env.layer.layer_node(mat).id_data.nodes.remove(env.layer.layer_node(mat))
    with pytest.warns(UserWarning, match="the BSDF is back, unconnected"):
        env.api.remove_haze(mat)


def test_remove_haze_refuses_to_overwrite_a_kept_bsdf_back_in_use(env):
    """The artist un-mutes the kept BSDF, edits it and renders it: Remove Haze would give it the
    layer node's values and links (it overwrote the edit, up to 40 % of the render); it refuses
    in one line and changes nothing, and goes ahead once that BSDF is muted again."""
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.5)
    tree = mat.node_tree
    kept = env.layer.original_node(mat)
    kept.mute = False
    kept.inputs["Roughness"].default_value = 0.7
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    tree.links.new(kept.outputs[0], out.inputs["Surface"])
    with pytest.raises(ValueError, match="in use again .* Remove Haze would overwrite it"):
        env.api.remove_haze(mat)
    assert env.layer.is_layered(mat) and kept.inputs["Roughness"].default_value == pytest.approx(0.7)
    assert out.inputs["Surface"].links[0].from_node == kept
    kept.mute = True
    tree.links.remove(out.inputs["Surface"].links[0])
    assert env.api.remove_haze(mat) is True and not env.layer.is_layered(mat)


def test_eevee_output_refuses_linked_data(env, tmp_path):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.3)
    mat.use_fake_user = True
    lib = str(tmp_path / "lib.blend")
    bpy.ops.wm.save_as_mainfile(filepath=lib)
    bpy.ops.wm.read_homefile(use_empty=True)
    with bpy.data.libraries.load(lib, link=True) as (src, dst):
        dst.materials = ["Car Paint"]
    linked = bpy.data.materials["Car Paint"]
    assert linked.library is not None
    for fn in (env.api.add_eevee_output, env.api.remove_eevee_output, env.api.sync_haze):
        with pytest.raises(ValueError, match="linked from the library"):
            fn(linked)  # (sync_haze returned False, as if there were nothing to do; QA)


def _as_made_by(ng, lg, version):
    """Stamp and name ``ng`` as Blender ``version``'s group of its configuration."""
    stamp = ng[lg.K.GROUP_STAMP].to_dict()
    stamp["blender"] = version
    ng[lg.K.GROUP_STAMP] = stamp
    ng.name = ng.name.rsplit(" ", 1)[0] + f" {version}"  # (as that Blender named it)


def test_upgrade_passes_over_linked_layers_and_a_current_linked_one_is_up_to_date(env, tmp_path):
    """A library's layer on this Blender's group is up to date (Upgrade raised on every file
    that linked one); a linked old layer is read-only here: Upgrade of the whole file passes
    over it with a note naming the library, and refuses it when named."""
    lg = importlib.import_module(f"{env.hg.__name__}.blender.model.layer_group")
    now, old = car_paint(), principled("Old", distribution="MULTI_GGX")[0]
    for m in (now, old):
        env.api.make_hazy(m, haziness=0.3)
        m.use_fake_user = True
    assert env.layer.layer_node(now).node_tree != env.layer.layer_node(old).node_tree
    _as_made_by(env.layer.layer_node(old).node_tree, lg, "4.2")
    lib, names = str(tmp_path / "lib.blend"), [now.name, old.name]
    bpy.ops.wm.save_as_mainfile(filepath=lib)
    bpy.ops.wm.read_homefile(use_empty=True)
    with bpy.data.libraries.load(lib, link=True) as (src, dst):
        dst.materials = names
    linked_now, linked_old = dst.materials
    local = principled("Local", distribution="MULTI_GGX")[0]
    env.api.make_hazy(local, haziness=0.3)
    _as_made_by(env.layer.layer_node(local).node_tree, lg, "4.2")
    assert env.layer.outdated_group(linked_now) is None
    assert not any("made by" in n for n in env.api.read_parameters(linked_now)["notes"])
    assert env.layer.outdated_group(linked_old) == "Blender 4.2"
    with pytest.warns(UserWarning, match=r"1 linked material .* left as .* upgrade it in lib.blend"):
        assert env.api.upgrade_layers() == [local.name]
    assert env.layer.outdated_group(local) is None
    with pytest.raises(ValueError, match="linked from the library"):
        env.api.upgrade_layers([linked_old])
    assert env.api.upgrade_layers([linked_now]) == []


def test_a_bypassed_layer_says_so(env):
    mat = metallic_map()
    env.api.make_hazy(mat, haziness=0.5)
    assert env.api.read_parameters(mat)["notes"] == []
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    kept = env.layer.original_node(mat)
    tree.links.new(kept.outputs[0], out.inputs["Surface"])  # the artist wires the old BSDF
    notes = " ".join(env.api.read_parameters(mat)["notes"])
    assert "before haze" in notes and "no haze renders" in notes
    tree.links.remove(out.inputs["Surface"].links[0])
    notes = " ".join(env.api.read_parameters(mat)["notes"])
    assert "not connected to the Material Output" in notes


def test_a_muted_copied_or_regrouped_layer_node_says_so(env):
    """The notes name what keeps the layer node from rendering as the panel shows it: muted (a
    muted group node has no shader to pass on: black), a copy (Shift+D) rendering instead or
    too, another group given to it; Remove Haze leaves the artist's copy and regrouped node, and
    says so (they were called "not connected" and "deleted")."""
    mat = metallic_map()
    env.api.make_hazy(mat, haziness=0.5)
    tree, node = mat.node_tree, env.layer.layer_node(mat)
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    node.mute = True
    assert any("“Principled BSDF” is muted" in n for n in env.api.read_parameters(mat)["notes"])
    node.mute = False
    copy = tree.nodes.new("ShaderNodeGroup")  # what Shift+D makes
    copy.node_tree, copy.name = node.node_tree, "Principled BSDF.001"
    tree.links.new(copy.outputs[0], out.inputs["Surface"])
    notes = " ".join(env.api.read_parameters(mat)["notes"])
    assert "“Principled BSDF.001”, a copy of the layer node “Principled BSDF”, renders instead" in notes
    assert "not connected" not in notes
    with pytest.warns(UserWarning, match="“Principled BSDF.001”, a copy of the layer node, stays"):
        env.api.remove_haze(mat)
    assert copy.name in tree.nodes and copy.outputs[0].is_linked

    mat = metallic_map()
    env.api.make_hazy(mat, haziness=0.5)
    tree, node = mat.node_tree, env.layer.layer_node(mat)
    mine = bpy.data.node_groups.new("Artist's group", "ShaderNodeTree")
    node.node_tree = mine
    with pytest.raises(ValueError, match="“Principled BSDF” uses “Artist's group”, not a Hazy "
                                         "Gloss layer group"):
        env.api.read_parameters(mat)
    with pytest.warns(UserWarning, match="“Principled BSDF” uses another group now: it stays"):
        env.api.remove_haze(mat)
    assert node.node_tree == mine and not env.api.is_hazy(mat)


def test_a_hazy_coat_says_what_it_dims(env):
    """A hazy coat keeps its peak by reflecting more, so the base and its emission under it dim
    (QA: emission at 0.49 of before at Coat Haziness 0.6, and nothing said): the notes give the
    coat's F(0) before and after; a rougher coat needs less of a raise."""
    def passes(coat_roughness, coat_haziness):
        mat, _ = principled("Glowing lacquer", **{"Coat Weight": 1.0, "Coat Roughness": coat_roughness,
                                                  "Emission Strength": 2.0})
        env.api.make_hazy(mat, coat_haziness=coat_haziness)
        notes = [n for n in env.api.read_parameters(mat)["notes"] if "Coat Haziness raises" in n]
        if not notes:
            return None
        m = re.search(r"from 0\.040 to (\S+) .*lets (\d+)% of the light", notes[0])
        assert m, notes
        f0 = float(m.group(1))
        assert int(m.group(2)) == round(100 * (1 - f0) / (1 - 0.04)), notes  # (1.5: F0 0.04)
        return f0
    assert passes(0.03, 0.0) is None
    smooth, rough = passes(0.03, 0.6), passes(0.3, 0.6)
    assert 0.5 < smooth < 0.7 and 0.04 < rough < smooth, (smooth, rough)


def _node_editor(tree):
    """A context override with a Node Editor showing ``tree`` (Ctrl+G / Ctrl+Alt+G run there)."""
    win = bpy.context.window_manager.windows[0]
    area = max(win.screen.areas, key=lambda a: a.width * a.height)
    area.type = "NODE_EDITOR"
    space = area.spaces.active
    space.tree_type = "ShaderNodeTree"
    space.shader_type = "OBJECT"
    space.pin = True
    space.node_tree = tree
    region = next(r for r in area.regions if r.type == "WINDOW")
    return dict(window=win, screen=win.screen, area=area, region=region, space_data=space)


@pytest.mark.parametrize("how", ["group_make", "group_ungroup"])
def test_a_grouped_or_ungrouped_layer_node_still_renders_and_remove_haze_says_so(env, how):
    """Ctrl+G (the layer node into a group of the artist's) or Ctrl+Alt+G (its parts into the
    tree): the haze still renders, so Remove Haze refuses in one line naming where the layer is
    and keeps the record (it said "deleted", dropped the record and left the haze rendering)."""
    mat, _ = principled("Grouped", **{"Roughness": 0.2})
    env.api.make_hazy(mat, haziness=0.8)
    tree, node = mat.node_tree, env.layer.layer_node(mat)
    for n in tree.nodes:
        n.select = n == node
    tree.nodes.active = node
    with bpy.context.temp_override(**_node_editor(tree)):
        getattr(bpy.ops.node, how)()
    assert env.layer.layer_node(mat) is None
    where = "inside the group node" if how == "group_make" else "was ungrouped: its nodes (the frame “Eq. 1"
    with pytest.raises(ValueError, match=re.escape(where)) as got:
        env.api.read_parameters(mat)
    # every entry point gives that way out only ("Remove Haze, then Make Hazy again" would be
    # refused; Make Hazy said the node "is gone", Add Haziness Map "Make Hazy first"; QA)
    assert "Make Hazy again" not in str(got.value)
    for call in (lambda: env.api.make_hazy(mat, haziness=0.5), lambda: env.api.add_haziness_map(mat)):
        with pytest.raises(ValueError, match=re.escape(where)) as got:
            call()
        assert "Make Hazy" not in str(got.value) and "is gone" not in str(got.value)
    panels = importlib.import_module(f"{env.hg.__name__}.blender.ui.panels")
    log = test_ui.draw_panel(panels.HAZY_GLOSS_PT_material, test_ui.fake_context(mat))
    assert any(where in text for text in test_ui.labels(log))
    assert "hazy_gloss.remove_haze" not in test_ui.ops_drawn(log)  # (it would refuse)
    before = len(tree.nodes)
    with pytest.raises(ValueError, match="Cannot remove the haze of “Grouped”: its layer node " +
                       re.escape("“Principled BSDF” is inside" if how == "group_make" else "was ungrouped")):
        env.api.remove_haze(mat)
    assert env.api.is_hazy(mat) and len(tree.nodes) == before


def test_an_edited_layer_group_says_so_and_remove_haze_keeps_it(env):
    """A layer group edited by hand (Make Single User, then a node added inside, or a part's
    math changed) renders what the panel does not show: the notes say so, in the panel too once
    the edit's depsgraph update came; Remove Haze keeps the edited group (a fake user)."""
    mat, other = metallic_map(), metallic_map()
    for m in (mat, other):
        env.api.make_hazy(m, haziness=0.6)
    mesh = bpy.data.meshes.new("Shown")
    mesh.materials.append(mat)
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("Shown", mesh))
    node = env.layer.layer_node(mat)
    mine = node.node_tree.copy()
    node.node_tree = mine
    bpy.context.view_layer.update()
    assert not any("edited by hand" in n for n in env.layer.summary(mat)["notes"])
    assert not any("edited by hand" in n for n in env.api.read_parameters(mat)["notes"])
    mul = mine.nodes.new("ShaderNodeMath")  # the artist's edit: a node inside
    bpy.context.view_layer.update()  # (the panel's note waits for this)
    assert any(f"its layer group was edited by hand (“{mine.name}”)" in n
               for n in env.api.read_parameters(mat)["notes"])
    assert any("edited by hand" in n for n in env.layer.summary(mat)["notes"])
    mine.nodes.remove(mul)
    shared = env.layer.layer_node(other).node_tree
    math = next(n for n in shared.nodes if n.bl_idname == "ShaderNodeMath"
                and any(not s.is_linked for s in n.inputs))
    free = next(s for s in math.inputs if not s.is_linked)
    assert not any("edited by hand" in n for n in env.layer.summary(mat)["notes"])
    free.default_value += 0.25  # an edit of a math node in the group the other material uses
    assert any(f"(“{shared.name}”)" in n for n in env.api.read_parameters(other)["notes"])
    assert not any("edited by hand" in n for n in env.api.read_parameters(mat)["notes"])
    bpy.context.view_layer.update()  # (a group's depsgraph update clears the panel's cache)
    assert not any("edited by hand" in n for n in env.layer.summary(mat)["notes"])
    own = next(s for n in mine.nodes if n.bl_idname == "ShaderNodeMath" for s in n.inputs
               if not s.is_linked and s.enabled)
    own.default_value += 0.25  # an edit of its own group's math
    with pytest.warns(UserWarning, match=f"the layer group “{re.escape(mine.name)}”, edited by "
                                         f"hand, stays in the file"):
        env.api.remove_haze(mat)
    assert mine.use_fake_user and mine.users == 1


def test_remove_haze_keeps_the_layer_nodes_name_label_frame_and_place(env):
    """What the artist changed on the layer node since Make Hazy (renamed, relabelled, framed,
    moved) the BSDF comes back with; what they did not change comes back as it was."""
    mat, plain = metallic_map(), metallic_map()
    for m in (mat, plain):
        env.api.make_hazy(m, haziness=0.4)
    tree, node = mat.node_tree, env.layer.layer_node(mat)
    frame = tree.nodes.new("NodeFrame")
    node.parent, node.name, node.label = frame, "Car body", "Body"
    node.location = (33.0, 44.0)
    env.api.remove_haze(mat)
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    assert (bsdf.name, bsdf.label, bsdf.parent) == ("Car body", "Body", frame)
    assert tuple(bsdf.location) == pytest.approx((33.0, 44.0))
    was = tuple(env.layer.original_node(plain).location)
    env.api.remove_haze(plain)
    bsdf = next(n for n in plain.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    assert (bsdf.name, bsdf.label, bsdf.parent) == ("Principled BSDF", "", None)
    assert tuple(bsdf.location) == pytest.approx((was[0], was[1] - 60.0))


def test_a_mirror_core_says_the_same_true_thing_everywhere(env):
    """Roughness below the mapping's smallest (0.004): Make Hazy, update_material and
    read_parameters give the same note (only Make Hazy gave one, and it said no halo could
    show, which renders); the halo is the one of roughness 0.004, the core stays a mirror."""
    lv = importlib.import_module(f"{env.hg.__name__}.blender.model.layer_values")
    mat, _ = principled("Mirror", Roughness=0.0)
    notes = env.api.make_hazy(mat, haziness=0.7)
    said = [n for n in notes if n.startswith("Roughness 0 is below 0.004")]
    assert len(said) == 1, notes
    assert said == [n for n in env.api.read_parameters(mat)["notes"] if n.startswith("Roughness")]
    assert said == [n for n in env.api.update_material(mat, haziness=0.5)
                    if n.startswith("Roughness")]
    node = env.layer.layer_node(mat)
    wide_at_0 = lv.values(node)[0]["roughness wide"]
    node.inputs["Roughness"].default_value = 0.004
    assert not any(n.startswith("Roughness") for n in env.api.read_parameters(mat)["notes"])
    assert lv.values(node)[0]["roughness wide"] == pytest.approx(wide_at_0, rel=1e-6)
    assert wide_at_0 > 0.004  # (a halo wider than the clamped core: it renders)
    node.inputs["Roughness"].default_value = 0.0
    assert not any(n.startswith("Roughness") for n in env.api.update_material(mat, haziness=0.0))


@pytest.mark.skipif(bpy.app.version >= (5, 0, 0), reason="5.x always renders a material's nodes")
def test_a_material_not_using_its_nodes_is_refused_in_one_line(env):
    """4.5: Use Nodes off, or no node tree: Make Hazy said "Made hazy" and nothing rendered it;
    Import Two-Lobe Mix raised AttributeError (QA)."""
    bare = bpy.data.materials.new("Bare")
    off, _ = principled("Off")
    off.use_nodes = False
    for mat, why in ((bare, "has no node tree"), (off, "does not use its nodes")):
        for op in (bpy.ops.hazy_gloss.make_hazy, bpy.ops.hazy_gloss.import_two_lobe_mix):
            with pytest.raises(RuntimeError, match=why):
                op(material=mat.name)
    assert not off.use_nodes and not env.api.is_hazy(off)


def test_the_layer_goes_on_the_bsdf_cycles_renders(env):
    """A material with an output for EEVEE and one for Cycles (Blender renders, per engine, the
    output of its target over All): Make Hazy hazes the BSDF Cycles renders (finals) and says
    EEVEE renders another; it hazed the active output's BSDF, which Cycles did not render, and
    said nothing (QA)."""
    mat, eevee_bsdf = principled("Two outputs")
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    out.target = "EEVEE"
    final = tree.nodes.new("ShaderNodeBsdfPrincipled")
    final.name = "Final BSDF"
    cycles_out = tree.nodes.new("ShaderNodeOutputMaterial")
    cycles_out.target = "CYCLES"
    tree.links.new(final.outputs[0], cycles_out.inputs["Surface"])
    out.is_active_output = True
    notes = env.api.make_hazy(mat, haziness=0.6)
    node = env.layer.layer_node(mat)
    assert node.name == "Final BSDF" and cycles_out.inputs["Surface"].links[0].from_node == node
    said = "EEVEE renders the Material Output “Material Output”, which does not reach the layer node"
    assert any(said in n for n in notes)
    assert any(said in n for n in env.api.read_parameters(mat)["notes"])


def test_messages_name_keywords_as_typed(env):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.3)
    with pytest.raises(ValueError) as e:
        env.api.update_material(mat, haze_extent=-1.0)
    assert str(e.value).startswith("haze_extent"), str(e.value)
    with pytest.raises(ValueError, match="smoothness"):
        env.api.update_material(mat, smoothness=float("inf"))
    with pytest.raises(ValueError, match="smoothness"):
        env.api.make_hazy(car_paint(), smoothness=float("inf"))


def test_entry_points_refuse_what_the_api_refuses_in_one_line(env):
    """An operator called from a script refuses an out-of-range value with the API's line (a
    hard property limit clamped it, saying nothing); sizes and material lists that do not read
    are named."""
    mat = car_paint()
    for key, value in (("haziness", 5.0), ("haziness", -1.0), ("haze_extent", -3.0)):
        with pytest.raises(ValueError) as api_says:
            env.api.make_hazy(car_paint(), **{key: value})
        with pytest.raises(RuntimeError) as op_says:
            bpy.ops.hazy_gloss.make_hazy(material=mat.name, **{key: value})
        assert str(api_says.value) in str(op_says.value)
        assert not env.api.is_hazy(mat)
    env.api.make_hazy(mat, haziness=0.3)
    for size in (float("nan"), float("inf"), None, "32", 16.7, 8, True):
        with pytest.raises(ValueError, match=r"^size must be a whole number of pixels, 16 to "
                                             r"16384, got "):
            env.api.add_haziness_map(mat, size=size)
    with pytest.raises(RuntimeError, match="size must be a whole number"):
        bpy.ops.hazy_gloss.add_haziness_map(material=mat.name, size=-5)
    assert not mat.node_tree.nodes.get("Image Texture")
    with pytest.raises(TypeError, match="upgrade_layers expects a list of materials, or None"):
        env.api.upgrade_layers(5)
    assert env.api.upgrade_layers(mat) == []


def test_a_haze_input_out_of_its_range_says_what_it_renders_as(env):
    """Keys, drivers and scripts can put any number in a haze input: the note names it and
    what it renders as — the group's clamp, checked against the static material with that
    value (equal to the last bit); NaN renders as the lower end, and says so."""
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.3, coat_haziness=0.3)
    node = env.layer.layer_node(mat)
    render(env, mat)  # (the scene holds the material: frame_set runs its drivers)
    for name, driven, clamped in (("Haziness", 2.0, 0.9999), ("Coat Haziness", -1.0, 0.0),
                                  ("Haze Extent X", -5.0, 0.0)):
        fc = node.inputs[name].driver_add("default_value")
        fc.driver.expression = repr(driven)
        bpy.context.scene.frame_set(1)
        assert node.inputs[name].default_value == driven
        notes = env.api.read_parameters(mat)["notes"]
        assert f"{name} is {driven:g} (from its keys or driver), outside" in " ".join(notes)
        assert f"it renders as {clamped:g}" in " ".join(notes)
        got = render(env, mat)["combined"]
        node.inputs[name].driver_remove("default_value")
        node.inputs[name].default_value = clamped
        assert np.array_equal(render(env, mat)["combined"], got), name
        assert not any(f"{name} is" in n for n in env.api.read_parameters(mat)["notes"])
        node.inputs[name].default_value = {"Haze Extent X": 5.0}.get(name, 0.3)
    # NaN (bpy takes it) renders as the lower end (it rendered as no value does: a wide
    # roughness of 0 and β 1 in Cycles, where Minimum passes NaN on in 5.x)
    for name, lo in (("Haze Extent Y", 0.0), ("Haziness", 0.0), ("Coat Haze Extent", 0.0),
                     ("Coat Haziness", 0.0), ("Reflectivity Cap", 0.0)):
        was = node.inputs[name].default_value
        node.inputs[name].default_value = lo
        want = render(env, mat)["combined"]
        node.inputs[name].default_value = float("nan")
        assert any(n.startswith(f"{name} is NaN: it renders as {lo:g}")
                   for n in env.api.read_parameters(mat)["notes"]), name
        assert np.array_equal(render(env, mat)["combined"], want), name
        node.inputs[name].default_value = was


def test_group_cache_key_covers_the_tables(env, monkeypatch, tmp_path):
    """The per-user cache of built layer groups is keyed by a hash of the code that builds them
    and of the data tables it reads (core/tables/*.json): a regenerated table (say, a new
    Blender's socket declarations) must not hand out a group built from the old one."""
    lg = importlib.import_module(f"{env.hg.__name__}.blender.model.layer_group")
    tables = importlib.import_module(f"{env.hg.__name__}.core.tables")
    files = tables.files()
    assert {p.name for p in files} >= {"bsdf_interfaces.json", "cycles_albedo_tables.json"}
    monkeypatch.setattr(lg, "_digest", [])
    before = lg._code_digest()
    for i, path in enumerate(files):
        edited = tmp_path / path.name
        edited.write_bytes(path.read_bytes().replace(b'"data"', b'"data" ', 1))
        monkeypatch.setattr(tables, "files", lambda i=i, e=edited: files[:i] + [e] + files[i + 1:])
        monkeypatch.setattr(lg, "_digest", [])
        assert lg._code_digest() != before, path.name
    monkeypatch.setattr(tables, "files", lambda: files)
    monkeypatch.setattr(lg, "_digest", [])
    assert lg._code_digest() == before


def _no_build(*_args, **_kw):
    raise AssertionError("built a layer group that should have been appended")


def test_configurations_share_their_tables(env, monkeypatch, tmp_path):
    """Every layer group shares the table images: built, or appended from the per-user cache
    into a file that has some of them, a file holds one copy of each (an append brings its own
    copies: they give way to the file's and are dropped)."""
    import re
    lg = importlib.import_module(f"{env.hg.__name__}.blender.model.layer_group")
    monkeypatch.setattr(lg, "_shipped_path", lambda name: None)
    monkeypatch.setattr(lg, "_cache_path", lambda name: str(tmp_path / lg._file_name(name)))
    configs = (("MULTI_GGX", "RANDOM_WALK"), ("MULTI_GGX", "BURLEY"), ("GGX", "RANDOM_WALK"))
    for how in ("built", "appended from the cache"):
        bpy.data.batch_remove(list(bpy.data.materials) + list(bpy.data.node_groups)
                              + list(bpy.data.images))
        if how != "built":  # (the second round must not build: it appends what the first cached)
            monkeypatch.setattr(lg, "build", _no_build)
        groups = []
        for dist, sss in configs:  # (a thin film: its part reads a table)
            mat, core = principled(f"{dist} {sss}", **{"Thin Film Thickness": 300.0})
            core.distribution, core.subsurface_method = dist, sss
            env.api.make_hazy(mat, haziness=0.5)
            groups.append(env.layer.layer_node(mat).node_tree)
        assert len(set(groups)) == 3 and all(lg.is_layer_group(g) for g in groups), how
        if how == "built":
            assert len(list(tmp_path.glob("*.blend"))) == 3
        copies = [i.name for c in (bpy.data.node_groups, bpy.data.images) for i in c
                  if re.search(r"\.\d{3}$", i.name)]
        assert not copies, (how, copies)
        tables = {i.name for i in bpy.data.images if i.name.startswith(".Hazy Gloss table")}
        used = [{n.image.name for n in g.nodes if n.bl_idname == "ShaderNodeTexEnvironment"}
                for g in groups]
        assert tables and tables == set().union(*used) and used[0] == used[1], (how, tables)
        assert all(g.users > 0 for g in bpy.data.node_groups), how  # nothing left over
        assert not bpy.data.libraries, how  # (an append's Library entry included)


def test_an_appended_hazy_material_brings_no_copies(env, tmp_path):
    """Appending hazy materials from another file into one that has their configuration: the
    copies of the groups and tables Blender brings ("<name>.001") give way to the file's (the
    name keeps its Blender version: no trailing ".3" for Blender to take as a copy's number);
    a copy the artist made of a layer group (Make Single User) stays theirs."""
    import re
    for name in ("Paint A", "Paint B"):
        mat = car_paint()
        mat.name = name
        env.api.make_hazy(mat, haziness=0.4)
        mat.use_fake_user = True
    lib = str(tmp_path / "lib.blend")
    bpy.ops.wm.save_as_mainfile(filepath=lib)
    bpy.ops.wm.read_homefile(use_empty=True)
    mine = car_paint()
    env.api.make_hazy(mine, haziness=0.2)
    group = env.layer.layer_node(mine).node_tree
    assert not re.search(r"\.\d+$", group.name), group.name
    counts = len(bpy.data.node_groups), len(bpy.data.images)
    with bpy.data.libraries.load(lib, link=False) as (src, dst):
        dst.materials = ["Paint A", "Paint B"]
    assert len(bpy.data.node_groups) > counts[0]  # (Blender's copies, before the update)
    bpy.context.view_layer.update()
    assert (len(bpy.data.node_groups), len(bpy.data.images)) == counts
    for name in ("Paint A", "Paint B"):
        assert env.layer.layer_node(bpy.data.materials[name]).node_tree == group
    single = group.copy()  # the artist's own copy, to edit
    env.layer.layer_node(mine).node_tree = single
    bpy.context.view_layer.update()
    assert env.layer.layer_node(mine).node_tree == single and single.name in bpy.data.node_groups


def test_an_edited_group_or_linked_data_is_not_shared(env, monkeypatch, tmp_path):
    """A layer group the artist edited is not handed to another material (it gets its own,
    as built or appended), and a group built in a file that links hazy materials from a
    library uses none of the library's data (the file and the per-user cache stay free of
    links)."""
    lg = importlib.import_module(f"{env.hg.__name__}.blender.model.layer_group")
    monkeypatch.setattr(lg, "_shipped_path", lambda name: None)
    monkeypatch.setattr(lg, "_cache_path", lambda name: str(tmp_path / lg._file_name(name)))

    def hazy(name):
        mat, _ = principled(name, distribution="MULTI_GGX")
        env.api.make_hazy(mat, haziness=0.5)
        return env.layer.layer_node(mat).node_tree

    # -- an edited group (of a material in the scene: the edit's update reaches the add-on) ----
    first = hazy("A")
    mesh = bpy.data.meshes.new("A")
    mesh.materials.append(bpy.data.materials["A"])
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("A", mesh))
    bpy.context.view_layer.update()
    math = next(n for n in first.nodes if n.bl_idname == "ShaderNodeMath"
                and not n.inputs[1].is_linked)
    math.inputs[1].default_value += 1.0  # the artist's edit
    bpy.context.view_layer.update()  # (as the node editor's edit is followed by one)
    assert lg.edited_parts(first) == [first.name]
    for how in ("built", "appended from the cache"):
        if how != "built":
            bpy.data.batch_remove([m for m in bpy.data.materials if m.name.startswith("B")])
            bpy.data.batch_remove([g for g in bpy.data.node_groups if g.users == 0])
            monkeypatch.setattr(lg, "build", _no_build)
        second = hazy(f"B {how}")
        assert second != first and second.name == first.name + ".001", (how, second.name)
        assert not lg.edited_parts(second), how
    monkeypatch.undo()

    # -- a library's layer groups -------------------------------------------------------------
    bpy.data.batch_remove(list(bpy.data.materials) + list(bpy.data.node_groups)
                          + list(bpy.data.images))
    monkeypatch.setattr(lg, "_shipped_path", lambda name: None)
    monkeypatch.setattr(lg, "_cache_path", lambda name: None)
    lib_mat = principled("Library hazy", distribution="MULTI_GGX")[0]
    env.api.make_hazy(lib_mat, haziness=0.5)
    lib_path = str(tmp_path / "library.blend")
    bpy.data.libraries.write(lib_path, {lib_mat}, fake_user=True)
    bpy.data.batch_remove(list(bpy.data.materials) + list(bpy.data.node_groups)
                          + list(bpy.data.images))
    with bpy.data.libraries.load(lib_path, link=True) as (_src, dst):
        dst.materials = ["Library hazy"]
    linked = [g for g in bpy.data.node_groups if g.library]
    assert any(lg.is_layer_group(g) for g in linked)  # the library's layer group is here
    local = hazy("Local")  # the same configuration, built in this file
    assert local.library is None
    uses = [n.image for n in local.nodes if n.bl_idname in ("ShaderNodeTexEnvironment",
                                                            "ShaderNodeTexImage") and n.image]
    assert not [i.name for i in uses if i.library is not None]
