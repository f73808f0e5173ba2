# SPDX-License-Identifier: GPL-3.0-or-later
"""The EEVEE-only simplification of a haze layer (blender.actions.eevee_output).

What is checked: the EEVEE output leaves the user's nodes and Cycles' image alone and goes away
cleanly; its one BSDF's lobes have the peak-preserving roughness 1/α_f² = (1-β)/α_n² + β/α_w²
(computed here from the layer's node values); Cycles renders that folded lobe with the layer's
peak; and EEVEE renders it without the closure-selection noise the full layer has when its
core has a coat (measured: 1 TAA sample against 16)."""
import importlib
import math
from types import SimpleNamespace

import numpy as np
import pytest

import layer_probe
import scenes
from measurements import record
from test_layer import car_paint, glossy_node, in_a_mix, metallic_map, metallic_node, principled


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return SimpleNamespace(api=mod("api"), layer=mod("blender.model.layer"), E=mod("blender.actions.eevee_output"),
                           layer_values=mod("blender.model.layer_values"),
                           ownership=mod("blender.nodes.ownership"))


def dielectric():
    return principled("Dielectric", **{"Base Color": (0.05, 0.12, 0.35, 1.0), "Roughness": 0.2})[0]


def metal():
    return principled("Metal", **{"Metallic": 1.0, "Base Color": (0.9, 0.6, 0.3, 1.0),
                                  "Roughness": 0.25})[0]


def coated_metallic_map():
    return metallic_map("Coated Metallic Map", **{"Coat Weight": 1.0, "Coat Roughness": 0.1})


MATERIALS = {  # name -> (builder, haze, EEVEE picks closures at random without the output)
    "dielectric": (dielectric, dict(haziness=0.6), False),
    "metal": (metal, dict(haziness=0.6), False),
    "metallic map": (metallic_map, dict(haziness=0.6), False),
    "car paint, hazy base and coat": (car_paint, dict(haziness=0.5, coat_haziness=0.6), True),
    "car paint, hazy coat only": (car_paint, dict(coat_haziness=0.6), True),
    "car paint, hazy base only": (car_paint, dict(haziness=0.5), True),
    "metallic map under a hazy coat": (coated_metallic_map, dict(haziness=0.6, coat_haziness=0.5),
                                       True),
    "plastic in a Mix Shader": (in_a_mix, dict(haziness=0.5), False),
    "Glossy BSDF": (glossy_node, dict(haziness=0.5), False),
    "Metallic BSDF (physical)": (lambda: metallic_node("PHYSICAL_CONDUCTOR"), dict(haziness=0.5),
                                 False),
}


def snapshot(mat, ours):
    """Every node that is not the EEVEE output's (name, type, settings, unlinked values) and
    every link between two such nodes."""
    keep = lambda n: not (ours(n) or "").startswith("layer eevee ")  # noqa: E731
    nodes = []
    for n in sorted(mat.node_tree.nodes, key=lambda n: n.name):
        if not keep(n):
            continue
        vals = []
        for s in n.inputs:
            if not s.is_linked and hasattr(s, "default_value"):
                v = s.default_value
                vals.append((s.identifier, tuple(v) if hasattr(v, "__len__") else v))
        props = tuple(getattr(n, p, None) for p in ("distribution", "fresnel_type", "target",
                                                    "is_active_output"))
        nodes.append((n.name, n.bl_idname, tuple(vals), props))
    links = sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name,
                    l.to_socket.identifier) for l in mat.node_tree.links
                   if keep(l.from_node) and keep(l.to_node))
    return nodes, links


def render(mat, engine="CYCLES", samples=1, light=(30.0, 0.0), view=(0.0, 0.0), res=(8, 8)):
    return scenes.render_plane(mat, engine=engine, samples=samples, resolution=res,
                               light_dir=light, view_dir=view)


@pytest.mark.parametrize("name", list(MATERIALS))
def test_eevee_output_keeps_the_user_tree_and_cycles(env, name):
    build, haze, noisy = MATERIALS[name]
    mat = build()
    env.api.make_hazy(mat, **haze)
    assert env.E.needs_eevee_output(mat)[0] == noisy
    before = snapshot(mat, env.ownership.role)
    cycles = render(mat)
    auto = env.E.add_eevee_output(mat)
    assert auto["added"] == noisy, auto
    info = env.E.add_eevee_output(mat, mode="always")  # replaces the "auto" one
    assert info["added"], info
    ours = env.E.eevee_nodes(mat.node_tree)
    outs = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    assert [n.target for n in outs if n in ours.values()] == ["EEVEE"]
    assert not any(n.bl_idname.startswith("ShaderNodeBsdf") for n in ours.values())
    # EEVEE's output comes from the layer node's EEVEE socket (its group's one folded BSDF),
    # through copies of the user's shader nodes in between
    node = env.layer.layer_node(mat)
    out = ours["layer eevee output"]
    src = out.inputs["Surface"].links[0].from_socket
    while src.node != node:
        assert src.node in ours.values()
        src = next(s for s in src.node.inputs if s.is_linked and s.type == "SHADER"
                   and _reaches(s, node)).links[0].from_socket
    assert src.name == "EEVEE"
    assert len(ours) == info["nodes"]
    assert snapshot(mat, env.ownership.role) == before  # nothing of the user's or the layer's
    assert np.array_equal(render(mat), cycles)  # Cycles renders the user's output as before
    assert env.E.sync_eevee_output(mat)
    assert len(env.E.eevee_nodes(mat.node_tree)) == info["nodes"]
    assert env.E.remove_eevee_output(mat)
    assert not env.E.eevee_nodes(mat.node_tree) and not env.E.has_eevee_output(mat)
    assert snapshot(mat, env.ownership.role) == before
    assert not env.E.remove_eevee_output(mat)


def _reaches(sock, node):
    stack = [sock]
    while stack:
        s = stack.pop()
        for lk in s.links:
            if lk.from_node == node:
                return True
            stack.extend(i for i in lk.from_node.inputs if i.type == "SHADER")
    return False


def test_folded_roughness_keeps_the_peak(env):
    """The EEVEE BSDF's Roughness and Coat Roughness are the single lobes whose GGX peak
    F(0)/(π α²) equals the layer's (1 - β) F(0)/(π α_n²) + β F(0)/(π α_w²), from the values
    the layer's group gives its slots (its graph evaluated for the node's values)."""
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.5, coat_haziness=0.6)
    node = env.layer.layer_node(mat)
    folded = layer_probe.slot_values(env.layer_values, node, "EEVEE folded")
    wide = layer_probe.slot_values(env.layer_values, node, "A wide")  # metal under the narrow coat
    under_wide_coat = layer_probe.slot_values(env.layer_values, node, "B narrow")  # (m = 1: B is A under the wide coat)
    vals, _ = env.layer_values.values(node)

    def peak_alpha(beta, r_n, r_w):
        a_n, a_w = r_n ** 2, r_w ** 2
        return 1.0 / math.sqrt((1.0 - beta) / a_n ** 2 + beta / a_w ** 2)

    want = peak_alpha(vals["beta metal"], node.inputs["Roughness"].default_value, wide["Roughness"])
    assert folded["Roughness"] ** 2 == pytest.approx(want, rel=1e-5)
    want_c = peak_alpha(vals["beta coat"], node.inputs["Coat Roughness"].default_value,
                        under_wide_coat["Coat Roughness"])
    assert folded["Coat Roughness"] ** 2 == pytest.approx(want_c, rel=1e-5)
    assert folded["Coat IOR"] == pytest.approx(wide["Coat IOR"])
    assert folded["Base Color"] == pytest.approx(wide["Base Color"])  # the raised metal colour


@pytest.mark.parametrize("name", ["dielectric", "metal"])
def test_cycles_peak_of_the_folded_lobe(env, name):
    """Rendered in Cycles (light, view and normal aligned: every pixel is the peak), the EEVEE
    output's folded BSDF gives the layer's peak (a GGX lobe without Cycles' energy
    compensation: exact up to float32)."""
    mat = MATERIALS[name][0]()
    env.api.make_hazy(mat, **MATERIALS[name][1])
    env.E.add_eevee_output(mat, mode="always")
    peak = dict(light=(0.0, 0.0), view=(0.0, 0.0))
    layered = render(mat, **peak)
    # let Cycles render the EEVEE output's BSDF: the layer node's EEVEE socket on the user's
    # output (swapping the outputs' targets would make the EEVEE output give way to the user's)
    user = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"
                and n.target == "ALL")
    mat.node_tree.links.new(env.layer.layer_node(mat).outputs["EEVEE"], user.inputs["Surface"])
    folded = render(mat, **peak)
    err = float(np.abs(folded - layered).max() / np.abs(layered).max())
    record("eevee_layer", {f"{name}: Cycles peak, folded / layered - 1": err})
    assert layered.max() > 0.1
    assert err <= 1e-5, err


def test_eevee_folded_tree_has_no_closure_noise(env):
    """The car paint with a hazy base and coat in EEVEE (flat plane, sun): the full layer's
    pixels scatter (EEVEE keeps one of the narrow and wide lobes that share a reflection bin per
    pixel), the EEVEE output's do not.  Noise = RMS over pixels of (1 TAA sample - 16 samples)
    relative to the mean."""
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.5, coat_haziness=0.6)
    res = (24, 24)

    def noise():
        one = render(mat, "EEVEE", 1, res=res)
        many = render(mat, "EEVEE", 16, res=res)
        return float(np.sqrt(np.mean((one - many) ** 2)) / many.mean()), many

    full, full16 = noise()
    env.E.add_eevee_output(mat)
    folded, folded16 = noise()
    env.E.remove_eevee_output(mat)
    original = car_paint()
    orig16 = render(original, "EEVEE", 16, res=res)
    record("eevee_layer", {"car paint EEVEE noise (1 vs 16 TAA samples)":
                           dict(full_layer=full, eevee_output=folded),
                           "car paint EEVEE mean, 16 samples": dict(
                               full_layer=float(full16.mean()), eevee_output=float(folded16.mean()),
                               original=float(orig16.mean()))})
    assert full > 0.05, full  # the layer's closure noise is there (else this test means nothing)
    assert folded < 0.01, folded


def test_auto_refuses_and_layer_rebuilds_remove_it(env):
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.5, coat_haziness=0.6)
    tree = mat.node_tree
    # a user EEVEE output is the user's choice: nothing is added
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.target = "EEVEE"
    info = env.E.add_eevee_output(mat)
    assert not info["added"] and "EEVEE output of its own: EEVEE renders what that output is given" in info["reason"]
    tree.nodes.remove(out)
    assert env.E.add_eevee_output(mat)["added"]
    # the layer rebuilds (its structure changes): every "layer ..." node goes, ours too; the
    # request is stamped, so the update brings the output back (base haze under the coat is
    # still noisy), and sync finds it up to date
    env.api.update_material(mat, coat_haziness=0.0)
    assert env.E.requested_mode(mat) == "auto"
    assert env.E.has_eevee_output(mat)
    env.E.remove_nodes(mat)  # as an edit of the path to the output would need
    assert not env.E.has_eevee_output(mat)
    assert env.E.sync_eevee_output(mat)
    assert env.E.has_eevee_output(mat)
    # a request for a material that does not need it: kept, nothing built until it does
    plain = dielectric()
    env.api.make_hazy(plain, haziness=0.5)
    assert not env.E.add_eevee_output(plain)["added"]
    assert not env.E.sync_eevee_output(plain) and env.E.requested_mode(plain) == "auto"
    env.E.remove_eevee_output(plain)
    assert env.E.requested_mode(plain) is None
    env.api.remove_haze(mat)
    assert not env.E.eevee_nodes(tree) and env.E.requested_mode(mat) is None
    with pytest.raises(ValueError, match="no haze layer"):
        env.E.add_eevee_output(mat)
    with pytest.raises(ValueError, match="mode must be"):
        env.E.add_eevee_output(car_paint(), mode="sometimes")


def test_the_output_follows_the_layer_and_the_panel(env, hg):
    """Asked for once (api or the panel's EEVEE setting), the EEVEE output follows every later
    change by itself (its BSDF is computed in the layer node's group): more haze folds into a
    wider lobe, an edit of the node's Roughness too, with no Python run; "Full Layer" removes
    it."""
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.5, coat_haziness=0.6)
    assert env.api.add_eevee_output(mat)["added"]
    node = env.layer.layer_node(mat)
    r0 = layer_probe.slot_values(env.layer_values, node, "EEVEE folded")["Roughness"]
    env.api.update_material(mat, haziness=0.8)
    assert env.E.has_eevee_output(mat)
    r1 = layer_probe.slot_values(env.layer_values, node, "EEVEE folded")["Roughness"]
    assert r1 > r0 * 1.01  # more haze: a wider folded lobe
    node.inputs["Roughness"].default_value = 0.5  # the user edits the node
    assert layer_probe.slot_values(env.layer_values, node, "EEVEE folded")["Roughness"] > r1 * 1.2
    settings = mat.hazy_gloss_settings
    assert settings.eevee_output == "AUTO"
    settings.eevee_output = "FULL"
    assert not env.E.has_eevee_output(mat) and env.E.requested_mode(mat) is None
    settings.eevee_output = "ALWAYS"
    assert env.E.has_eevee_output(mat) and env.E.requested_mode(mat) == "always"
    assert env.api.remove_eevee_output(mat) and settings.eevee_output == "FULL"
    mat["hazy_gloss"]["eevee"] = [1.0]  # a damaged request
    assert env.E.requested_mode(mat) is None and settings.eevee_output == "FULL"
    plain = dielectric()
    with pytest.raises(ValueError, match="no haze layer"):
        env.api.add_eevee_output(plain)
    with pytest.raises(TypeError, match="look it up"):
        env.api.add_eevee_output(plain.name)


def test_the_output_follows_the_artists_switch_of_outputs(env):
    """The artist makes another Material Output of theirs active: both engines render it (the
    EEVEE output gives way; it kept EEVEE on the layer while Cycles showed the new output,
    QA), and comes back when they switch back."""
    mat = car_paint()
    env.api.make_hazy(mat, haziness=0.5, coat_haziness=0.6)
    assert env.api.add_eevee_output(mat)["added"]
    tree = mat.node_tree
    mine = env.ownership.engine_output(tree, "CYCLES")
    green = tree.nodes.new("ShaderNodeEmission")
    other = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(green.outputs[0], other.inputs["Surface"])
    other.is_active_output = True
    assert env.api.sync_haze(mat)
    assert not env.E.has_eevee_output(mat) and env.E.requested_mode(mat) == "auto"
    assert env.ownership.engine_output(tree, "EEVEE") == other
    assert env.ownership.engine_output(tree, "CYCLES") == other
    mine.is_active_output = True
    assert env.api.sync_haze(mat)
    assert env.E.has_eevee_output(mat)
    assert env.ownership.engine_output(tree, "EEVEE").inputs["Surface"].links[0].from_socket == \
        env.layer.layer_node(mat).outputs["EEVEE"]


def test_with_an_export_fallback(env, hg):
    """An export fallback and the EEVEE output together: the fallback's EEVEE render output
    gives way to the EEVEE-only output (else EEVEE would pick between two EEVEE outputs) and
    comes back when it goes; both follow a haze change; the user's output is untouched."""
    mat = env.api.create_look("CAR_PAINT")
    role = env.ownership.role
    targets = lambda: sorted((role(n) or "user", n.target) for n in mat.node_tree.nodes  # noqa: E731
                             if n.bl_idname == "ShaderNodeOutputMaterial")
    env.api.add_export_fallback(mat)
    assert ("Render output Eevee", "EEVEE") in targets()
    assert env.api.add_eevee_output(mat)["added"]
    assert [t for t in targets() if t[1] == "EEVEE"] == [("layer eevee output", "EEVEE")]
    env.api.update_material(mat, haziness=0.2)  # values in place: a reused Color Ramp is checked
    assert env.E.has_eevee_output(mat)
    assert [t for t in targets() if t[1] == "EEVEE"] == [("layer eevee output", "EEVEE")]
    assert env.api.remove_eevee_output(mat)
    assert [t for t in targets() if t[1] == "EEVEE"] == [("Render output Eevee", "EEVEE")]
    env.api.remove_export_fallback(mat)
    assert targets() == [("user", "ALL")]
