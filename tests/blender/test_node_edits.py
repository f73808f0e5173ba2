# SPDX-License-Identifier: GPL-3.0-or-later
"""Node-editor edits of the add-on's nodes.

The user edits a hazy material in the node editor (a socket value, a label, a frame, a move,
F2 on the group) and then moves a slider in the panel.  What each group of tests compares:

- Adopted: a socket value typed into one of the add-on's nodes (a lean lobe's Roughness or
  IOR, the Lobe mix factor; an in-shader group's Haziness) survives the next panel change of
  another parameter: ``api.read_parameters`` shows it read back (the group inputs are the
  perceptual parameters; a lean tree goes through the inverse haze mapping), and the add-on's
  nodes hold exactly what a fresh material of the read-back parameters holds (float32).
- Replaced and said: an edit the parameters cannot represent (the two lobes given different
  IORs: Eq. 1 has one Fresnel term; a haziness of 1) is listed by ``panels.node_edit_notes``
  before the change, in ``messages.last_error`` (one line) after a panel change, and by a
  UserWarning of ``api.update_material`` naming the node and the input.
- Kept: name, label, frame, width, collapse, colour and the location of a single moved node
  survive a change that sets values and a change that rebuilds the tree (isotropic ->
  anisotropic, a kind change).
- Renamed group: renaming the group's node tree (F2 on a group node) or the node keeps the
  panel attached: sliders still set the group's inputs, no second group datablock appears,
  a texture linked into a group input stays linked.
- Handler: for a material an object uses, the depsgraph handler (blender.actions.sync) reads an edit
  back as soon as it is made, with no panel change.
"""
import importlib
import warnings
from types import SimpleNamespace

import bpy
import numpy as np
import pytest


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return SimpleNamespace(api=mod("api"), material=mod("blender.model.material"),
                           material_edits=mod("blender.model.material_edits"),
                           edit=mod("blender.actions.edit"), messages=mod("blender.actions.messages"),
                           panels=mod("blender.ui.panels"),
                           sync=mod("blender.actions.sync"), K=mod("constants"), hg=hg)


def lean(env, name="Lean", **kw):
    params = dict(kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3), roughness=0.2,
                  haziness=0.5, haze_extent=4.0)
    params.update(kw)
    if params["kind"] == "CONDUCTOR":
        params.setdefault("edge_tint", (0.8, 0.5, 0.3))
    return env.api.create_material(name, **params)


def in_shader(env, name="In-shader", **kw):
    return lean(env, name, shader_mapping=True, **kw)


def node(env, mat, role):
    return env.material.ours(mat.node_tree)[role]


def group(env, mat):
    return node(env, mat, env.material.GROUP_ROLE)


def value(sock):
    v = sock.default_value
    return np.array(v, dtype=np.float64) if hasattr(v, "__len__") else float(v)


def held(env, mat):
    """{(role, input or setting): value} the add-on's nodes hold (unlinked inputs)."""
    out = {}
    for r, n in env.material.ours(mat.node_tree).items():
        for s in n.inputs:
            if not s.is_linked and hasattr(s, "default_value"):
                out[(r, s.identifier)] = value(s)
        for attr in ("distribution", "fresnel_type", "direction_type", "axis"):
            if hasattr(n, attr):
                out[(r, "@" + attr)] = getattr(n, attr)
    return out


def assert_holds_its_parameters(env, mat):
    """The add-on's nodes hold what a fresh material of the read-back parameters holds."""
    p = env.api.read_parameters(mat)
    fresh = env.api.create_material("Fresh " + mat.name, **{k: v for k, v in p.items()})
    got, want = held(env, mat), held(env, fresh)
    assert set(got) == set(want), sorted(set(got) ^ set(want))
    for key, w in want.items():
        if isinstance(w, str):
            assert got[key] == w, key
        else:
            np.testing.assert_allclose(got[key], w, rtol=2e-6, atol=1e-6, err_msg=str(key))
    assert env.material_edits.node_edits(mat) == []
    bpy.data.materials.remove(fresh)


def panel_change(env, mat, **changes):
    """What a sidebar slider does (edit.edit_material); returns last_error's line."""
    m, msg = env.edit.edit_material(mat, **changes)
    assert msg is None and m is not None
    return env.messages.error_for(mat)


# --------------------------------------------------------------------------------------------
# a. Edits the parameters represent are read back
# --------------------------------------------------------------------------------------------


def test_lean_roughness_edit_is_read_back(env):
    mat = lean(env)
    narrow = node(env, mat, "Narrow lobe")
    narrow.inputs["Roughness"].default_value = 0.27
    assert panel_change(env, mat, haziness=0.3) is None
    p = env.api.read_parameters(mat)
    assert p["roughness"] == pytest.approx(0.27, abs=1e-6)
    assert p["haziness"] == pytest.approx(0.3)
    assert narrow.inputs["Roughness"].default_value == pytest.approx(0.27, abs=1e-6)
    assert_holds_its_parameters(env, mat)


def test_lean_mix_factor_edit_is_read_back_as_haziness(env):
    """β typed into the Lobe mix: the inverse mapping gives the haziness (and keeps the peak
    the nodes render); the next change of roughness starts from it."""
    mat = lean(env)
    mix = node(env, mat, "Lobe mix")
    mix.inputs["Fac"].default_value = 0.35
    before = env.api.read_parameters(mat)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing is replaced: no warning
        env.api.update_material(mat, roughness=0.2)  # the same value: only the edit changes
    p = env.api.read_parameters(mat)
    assert p["haziness"] != pytest.approx(before["haziness"], abs=1e-3)
    assert mix.inputs["Fac"].default_value == pytest.approx(0.35, abs=1e-6)
    assert_holds_its_parameters(env, mat)


def test_lean_shared_ior_edit_on_one_lobe_is_read_back_for_both(env):
    """A dielectric's IOR typed into the core lobe: the wide lobe shares it (one Fresnel term),
    so the change takes it for both and the core reflectivity follows."""
    mat = lean(env, kind="DIELECTRIC", core_reflectivity=0.04)
    node(env, mat, "Narrow lobe").inputs["IOR"].default_value = 1.7
    assert panel_change(env, mat, roughness=0.25) is None  # keeps β: r stays
    p = env.api.read_parameters(mat)  # the lobes share the global reflectivity r = F0(IOR)
    assert p["roughness"] == pytest.approx(0.25)
    np.testing.assert_allclose(env.api.map_parameters(p).reflectivity, (0.7 / 2.7) ** 2,
                               rtol=1e-5)
    assert node(env, mat, "Wide lobe").inputs["IOR"].default_value == pytest.approx(1.7, abs=1e-5)
    assert_holds_its_parameters(env, mat)


@pytest.mark.parametrize("anisotropy", [0.0, 0.5])
def test_in_shader_group_input_edit_is_read_back(env, anisotropy):
    mat = in_shader(env, anisotropy=anisotropy)
    g = group(env, mat)
    g.inputs["Haziness"].default_value = 0.7
    assert panel_change(env, mat, roughness=0.3) is None
    p = env.api.read_parameters(mat)
    assert p["haziness"] == pytest.approx(0.7, abs=1e-6) and p["roughness"] == pytest.approx(0.3)
    assert g.inputs["Haziness"].default_value == pytest.approx(0.7, abs=1e-6)
    assert g.inputs["Roughness"].default_value == pytest.approx(0.3, abs=1e-6)
    assert_holds_its_parameters(env, mat)


# --------------------------------------------------------------------------------------------
# b. Edits the parameters cannot represent are replaced, and said
# --------------------------------------------------------------------------------------------


def _different_iors(env, mat):
    """Two IORs: the lobes no longer share one Fresnel term (Eq. 1)."""
    for role, by in (("Narrow lobe", 0.1), ("Wide lobe", 0.6)):
        sock = node(env, mat, role).inputs["IOR"]
        sock.default_value = tuple(x + by for x in sock.default_value)


def _haziness_one(env, mat):
    group(env, mat).inputs["Haziness"].default_value = 1.0


@pytest.mark.parametrize("make, edit, named", [
    (lean, _different_iors, "Wide lobe: IOR"),
    (in_shader, _haziness_one, "Hazy Gloss: Haziness"),
])
def test_edit_that_cannot_be_read_back_is_said(env, make, edit, named):
    mat = make(env)
    edit(env, mat)
    p = env.api.read_parameters(mat)
    notes = env.panels.node_edit_notes(mat, p)
    replaced = [text for text, icon in notes if icon == "ERROR"]
    assert len(replaced) == 1 and "replaced" in replaced[0] and named in replaced[0], notes
    # the panel: one line in last_error, and the nodes are back to the parameters
    line = panel_change(env, mat, roughness=0.25)
    assert line is not None and "\n" not in line and named in line, line
    assert env.api.read_parameters(mat)["roughness"] == pytest.approx(0.25)
    assert_holds_its_parameters(env, mat)
    assert env.panels.node_edit_notes(mat, env.api.read_parameters(mat)) == []
    # the scripting API: a UserWarning naming the node and the input
    edit(env, mat)
    with pytest.warns(UserWarning, match=named) as caught:
        env.api.update_material(mat, roughness=0.3)
    assert caught[0].filename == __file__  # said where the script called it
    assert_holds_its_parameters(env, mat)
    # a change after that has nothing to replace: the panel's line goes
    assert panel_change(env, mat, haziness=0.4) is None


@pytest.mark.parametrize("make, edit, named, good, key", [
    (lean, _different_iors, "Wide lobe: IOR", ("Narrow lobe", "Roughness", 0.27), "roughness"),
    (in_shader, _haziness_one, "Hazy Gloss: Haziness", ("Hazy Gloss", "Roughness", 0.3),
     "roughness"),
])
def test_edit_that_reads_is_kept_beside_one_that_does_not(env, make, edit, named, good, key):
    mat = make(env)
    edit(env, mat)
    role, name, v = good
    node(env, mat, role).inputs[name].default_value = v
    notes = dict((icon, text) for text, icon in env.panels.node_edit_notes(
        mat, env.api.read_parameters(mat)))
    assert f"{role}: {name}" in notes["INFO"] and named in notes["ERROR"], notes
    assert f"{role}: {name}" not in notes["ERROR"]
    line = panel_change(env, mat, haze_extent=3.0)
    assert named in line and f"{role}: {name}" not in line, line
    p = env.api.read_parameters(mat)
    assert p[key] == pytest.approx(v, abs=1e-6) and p["haze_extent"][0] == pytest.approx(3.0)
    assert_holds_its_parameters(env, mat)


# --------------------------------------------------------------------------------------------
# c. What the user set on the add-on's nodes survives changes, rebuilds included
# --------------------------------------------------------------------------------------------


def _dress(tree, n):
    """Name, label, frame, width, collapse, colour and a move of one node (as in the node
    editor)."""
    frame = tree.nodes.new("NodeFrame")
    frame.name = frame.label = "My frame"
    n.name, n.label = "My core", "Core, polished"
    n.parent = frame
    n.width = 311.0
    n.hide = True  # collapsed
    n.use_custom_color, n.color = True, (0.8, 0.1, 0.2)
    n.location = (n.location.x + 137.0, n.location.y - 59.0)  # this node alone
    return dict(name=n.name, label=n.label, parent=frame.name, width=n.width, hide=True,
                use_custom_color=True, color=tuple(n.color), location=tuple(n.location))


def _look(n):
    return dict(name=n.name, label=n.label, parent=n.parent.name if n.parent else None,
                width=n.width, hide=n.hide, use_custom_color=n.use_custom_color,
                color=tuple(n.color), location=tuple(n.location))


def assert_looks(got, want):
    for k, w in want.items():
        if isinstance(w, tuple):
            np.testing.assert_allclose(got[k], w, rtol=0, atol=1e-4, err_msg=k)
        else:
            assert got[k] == w, (k, got[k], w)


@pytest.mark.parametrize("make, dressed", [(lean, "Narrow lobe"), (in_shader, "Hazy Gloss")])
@pytest.mark.parametrize("rebuild", [dict(anisotropy=0.5), dict(kind="DIELECTRIC",
                                                                core_reflectivity=0.05)])
def test_node_settings_survive_changes(env, make, dressed, rebuild):
    mat = make(env)
    other = next(r for r in env.material.ours(mat.node_tree) if r != dressed) \
        if make is lean else None
    others = {r: tuple(n.location) for r, n in env.material.ours(mat.node_tree).items()
              if r != dressed}
    want = _dress(mat.node_tree, node(env, mat, dressed))
    tree_nodes = len(mat.node_tree.nodes)
    assert panel_change(env, mat, haziness=0.3) is None  # sets values only
    assert len(mat.node_tree.nodes) == tree_nodes
    assert_looks(_look(node(env, mat, dressed)), want)
    panel_change(env, mat, **rebuild)  # a new structure: the add-on's nodes are built again
    assert env.material.ours(mat.node_tree)[dressed].name == "My core"
    assert_looks(_look(node(env, mat, dressed)), want)
    assert [n.name for n in mat.node_tree.nodes if n.bl_idname == "NodeFrame"] == ["My frame"]
    if other is not None:  # the others stay where they were (not moved with the one)
        assert tuple(node(env, mat, other).location) == pytest.approx(others[other])


# --------------------------------------------------------------------------------------------
# d. A renamed group stays attached
# --------------------------------------------------------------------------------------------


def test_renamed_group_stays_attached(env):
    mat = in_shader(env)
    tree = mat.node_tree
    g = group(env, mat)
    tex = tree.nodes.new("ShaderNodeTexImage")
    tree.links.new(tex.outputs["Color"], g.inputs["Core Reflectivity"])
    g.node_tree.name = "Polished chrome"  # F2 on a group node renames its node tree
    groups = len(bpy.data.node_groups)
    assert panel_change(env, mat, roughness=0.33) is None
    g = group(env, mat)
    assert g.node_tree.name == "Polished chrome" and len(bpy.data.node_groups) == groups
    assert g.inputs["Roughness"].default_value == pytest.approx(0.33, abs=1e-6)
    assert g.inputs["Core Reflectivity"].links[0].from_node == tex
    g.name = "Chrome"  # the node's own name (the sidebar; F2 in older keymaps)
    assert panel_change(env, mat, haziness=0.2) is None
    g = group(env, mat)
    assert g.name == "Chrome" and g.inputs["Haziness"].default_value == pytest.approx(0.2)
    assert len(bpy.data.node_groups) == groups
    # anisotropic and back: the renamed group is taken again, not a second copy of it
    panel_change(env, mat, anisotropy=0.4)
    panel_change(env, mat, anisotropy=0.0)
    g = group(env, mat)
    assert g.node_tree.name == "Polished chrome" and g.name == "Chrome"
    stamp = env.K.GROUP_STAMP
    iso = [ng for ng in bpy.data.node_groups
           if stamp in ng and not ng[stamp].get("anisotropic") and ng[stamp].get("kind") == "CONDUCTOR"]
    assert [ng.name for ng in iso] == ["Polished chrome"]
    assert g.inputs["Core Reflectivity"].links[0].from_node == tex
    assert g.inputs["Roughness"].default_value == pytest.approx(0.33, abs=1e-6)


def _interface_names(ng):
    return [(i.item_type, i.name) for i in ng.interface.items_tree]


@pytest.mark.parametrize("changed", [False, True], ids=["same sockets", "sockets changed"])
def test_outdated_group_is_rebuilt_in_place(env, changed):
    """A group saved by an older add-on (an older stamp version) is rebuilt on first use with
    its sockets kept: no duplicated interface, the user's links and typed values stay; when the
    interface itself differs, the group nodes' links and values are put back by name."""
    groups = importlib.import_module(env.hg.__name__ + ".blender.model.groups")
    mat = in_shader(env)
    tree = mat.node_tree
    g = group(env, mat)
    ng = g.node_tree
    want = _interface_names(ng)
    tex = tree.nodes.new("ShaderNodeTexImage")
    tree.links.new(tex.outputs["Color"], g.inputs["Core Reflectivity"])
    g.inputs["Haze Extent"].default_value = 7.5
    if changed:  # a socket of an older layout
        ng.interface.new_socket(name="Old Input", in_out="INPUT", socket_type="NodeSocketFloat")
    stamp = dict(ng[env.K.GROUP_STAMP])
    stamp["version"] = groups.GROUP_VERSION - 1
    ng[env.K.GROUP_STAMP] = stamp
    assert groups.ensure_group("CONDUCTOR") == ng
    assert _interface_names(ng) == want
    assert ng[env.K.GROUP_STAMP]["version"] == groups.GROUP_VERSION
    g = group(env, mat)
    assert g.inputs["Core Reflectivity"].links[0].from_node == tex
    assert g.inputs["Haze Extent"].default_value == pytest.approx(7.5)
    assert g.outputs["BSDF"].is_linked
    # the rebuilt group reads its inputs: a slider change still sets the group's value
    assert panel_change(env, mat, haziness=0.25) is None
    assert group(env, mat).inputs["Haziness"].default_value == pytest.approx(0.25)


# --------------------------------------------------------------------------------------------
# e. The depsgraph handler reads edits of a material in use back at once
# --------------------------------------------------------------------------------------------


def _in_use(mat):
    mesh = bpy.data.meshes.new("Plane")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new("Plane", mesh)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.update()


@pytest.mark.parametrize("make, role, name, edited, key", [
    (lean, "Narrow lobe", "Roughness", 0.31, "roughness"),
    (in_shader, "Hazy Gloss", "Haziness", 0.66, "haziness"),
])
def test_handler_reads_edits_back(env, make, role, name, edited, key):
    mat = make(env)
    _in_use(mat)
    node(env, mat, role).inputs[name].default_value = edited
    bpy.context.view_layer.update()  # the depsgraph handler (blender.actions.sync.on_depsgraph_update)
    assert env.api.read_parameters(mat)[key] == pytest.approx(edited, abs=1e-6)
    assert env.material_edits.node_edits(mat) == [] and env.panels.node_edit_notes(
        mat, env.api.read_parameters(mat)) == []
    assert_holds_its_parameters(env, mat)
    # a material no object uses: sync() (api.sync_haze) does what the handler does
    idle = make(env, "Idle")
    node(env, idle, role).inputs[name].default_value = edited
    assert env.sync.sync(idle) is True
    assert env.api.read_parameters(idle)[key] == pytest.approx(edited, abs=1e-6)
    assert env.sync.sync(idle) is False  # nothing new
