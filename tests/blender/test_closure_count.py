# SPDX-License-Identifier: GPL-3.0-or-later
"""The note on Cycles' closure limit: blender.model.layer_wiring.closure_count counts a
material's closures as Cycles does (checked against the number Cycles itself logs when it is over
64), and a layer whose material goes over says so (it used to say nothing while Cycles logged
"Maximum number of closures exceeded: 72 > 64")."""
import importlib
import re

import bpy
import pytest

import scenes
from test_layer import principled, render


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return mod("api"), mod("blender.model.layer_wiring")


def _mix(tree, a, b, fac=0.5):
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = fac
    tree.links.new(a, mix.inputs[1])
    tree.links.new(b, mix.inputs[2])
    return mix.outputs[0]


def _output(tree):
    return next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")


def hazy_beside_a_principled(api):
    """QA's case: a hazy Principled with a metallic map and coat haze, mixed with another."""
    mat, bsdf = principled("Dirty paint", **{"Coat Weight": 1.0, "Roughness": 0.3})
    tree = mat.node_tree
    checker = tree.nodes.new("ShaderNodeTexChecker")
    tree.links.new(checker.outputs["Fac"], bsdf.inputs["Metallic"])
    dirt = tree.nodes.new("ShaderNodeBsdfPrincipled")
    tree.links.new(_mix(tree, bsdf.outputs[0], dirt.outputs[0], 0.3), _output(tree).inputs[0])
    api.make_hazy(mat, haziness=0.5, haze_extent=3.0, coat_haziness=0.5)
    return mat


def every_kind(api):
    """Five Principled, a Glass, a Subsurface, a Multiscatter Glossy and a Diffuse: 68."""
    mat, bsdf = principled("Every kind")
    tree = mat.node_tree
    acc = bsdf.outputs[0]
    for idname in ["ShaderNodeBsdfPrincipled"] * 4 + ["ShaderNodeBsdfGlass",
                                                      "ShaderNodeSubsurfaceScattering",
                                                      "ShaderNodeBsdfGlossy", "ShaderNodeBsdfDiffuse"]:
        n = tree.nodes.new(idname)
        if idname == "ShaderNodeBsdfGlossy":
            n.distribution = "MULTI_GGX"
        acc = _mix(tree, acc, n.outputs[0])
    muted = tree.nodes.new("ShaderNodeBsdfPrincipled")
    muted.mute = True  # (not counted: a muted node passes nothing)
    acc = _mix(tree, acc, muted.outputs[0])
    tree.links.new(acc, _output(tree).inputs[0])
    return mat


def hazy_in_a_fog(api, metal_map=True):
    """A hazy coated metal with a Volume Scatter in the Volume socket (32 for a volume
    closure); without the metallic map, Metallic 1 folds a lobe away in Cycles."""
    mat, bsdf = principled("Foggy", **{"Metallic": 1.0, "Coat Weight": 1.0})
    if metal_map:
        checker = mat.node_tree.nodes.new("ShaderNodeTexChecker")
        mat.node_tree.links.new(checker.outputs["Fac"], bsdf.inputs["Metallic"])
    fog = mat.node_tree.nodes.new("ShaderNodeVolumeScatter")
    mat.node_tree.links.new(fog.outputs[0], _output(mat.node_tree).inputs["Volume"])
    api.make_hazy(mat, haziness=0.4, coat_haziness=0.2)
    return mat


def hazy_metal_in_a_fog(api):
    return hazy_in_a_fog(api, metal_map=False)


@pytest.mark.parametrize("build, exact", [(hazy_beside_a_principled, True), (every_kind, True),
                                          (hazy_in_a_fog, True), (hazy_metal_in_a_fog, False)])
def test_closure_count_is_the_number_cycles_logs(env, build, exact):
    """Over the limit, Cycles logs its own count (5.x, with Blender's debug flag): the same as
    closure_count's, or fewer where Cycles folds a Mix Shader whose factor is a constant 0 or 1
    (``exact`` False: Metallic 1 drops the dielectric lobe); a hazy material over it says so."""
    api, wiring = env
    mat = build(api)
    count = wiring.closure_count(mat.node_tree)
    assert count > wiring.MAX_CLOSURES
    if api.is_hazy(mat):
        assert any(f"Cycles counts up to {count} closures" in n
                   for n in api.read_parameters(mat)["notes"])
    if bpy.app.version < (5, 0, 0):
        pytest.skip("4.5's Cycles logs its count at a verbose level a module cannot set")
    with pytest.raises(scenes.ClosureLimitExceeded) as got:
        render(api_env(api), mat)
    logged = int(re.search(r"exceeded: (\d+) > 64", str(got.value)).group(1))
    assert logged == count if exact else wiring.MAX_CLOSURES < logged < count


def test_a_layer_alone_is_within_the_limit_and_says_nothing(env):
    api, wiring = env
    mat, bsdf = principled("Car paint", **{"Metallic": 1.0, "Coat Weight": 1.0})
    api.make_hazy(mat, haziness=0.4, coat_haziness=0.2)
    assert wiring.closure_count(mat.node_tree) <= wiring.MAX_CLOSURES
    assert not any("closures" in n for n in api.read_parameters(mat)["notes"])
    render(api_env(api), mat)  # (raises on Cycles' closure warning)


def api_env(api):
    """What test_layer.render reads from its env: the exr reader."""
    from types import SimpleNamespace
    return SimpleNamespace(exr=importlib.import_module(api.__name__.rsplit(".", 1)[0] + ".exr"))
