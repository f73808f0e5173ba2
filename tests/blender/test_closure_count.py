# SPDX-License-Identifier: GPL-3.0-or-later
"""The note on Cycles' closure limit: blender.model.layer_wiring.closure_count counts a
material's closures as Cycles does (checked against the number Cycles itself logs when it is over
64; a material under it is read with Principled BSDFs added), and a layer whose material goes
over says so (it used to say nothing while Cycles logged "Maximum number of closures exceeded:
72 > 64"), and one under it says nothing (it warned of 92 on hazy water that Cycles counts 56)."""
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


def liquid(api):
    """QA's case: water (transmission 1, IOR 1.33) with Volume Absorption, its haziness a
    texture: 2 copies (Metallic 0 folds the metal part away) + 32; the note said 92 > 64."""
    mat, bsdf = principled("Water", **{"Transmission Weight": 1.0, "IOR": 1.33})
    tree = mat.node_tree
    absorb = tree.nodes.new("ShaderNodeVolumeAbsorption")
    tree.links.new(absorb.outputs[0], _output(tree).inputs["Volume"])
    api.make_hazy(mat, haziness=0.5)
    noise = tree.nodes.new("ShaderNodeTexNoise")
    layer = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeGroup")
    tree.links.new(noise.outputs["Fac"], layer.inputs["Haziness"])
    return mat


def rust_on_plastic(api):
    """QA's case: a hazy rust Principled (Metallic 1) mixed by a noise with a plastic one: 36,
    the note said 72."""
    mat, plastic = principled("Rust on plastic")
    tree = mat.node_tree
    rust = tree.nodes.new("ShaderNodeBsdfPrincipled")
    rust.inputs["Metallic"].default_value = 1.0
    noise = tree.nodes.new("ShaderNodeTexNoise")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(noise.outputs["Fac"], mix.inputs["Fac"])
    tree.links.new(plastic.outputs[0], mix.inputs[1])
    tree.links.new(rust.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], _output(tree).inputs[0])
    api.make_hazy(mat, haziness=0.5, node=rust.name)
    return mat


def _cycles_count(api, wiring, mat):
    """The count Cycles logs for ``mat`` (5.x): one under the limit is read with Principled
    BSDFs mixed in by a texture until it is over (12 each), and those taken away again."""
    tree = mat.node_tree
    out = _output(tree)
    extra = max(0, (wiring.MAX_CLOSURES - wiring.closure_count(tree)) // 12 + 1)
    if extra:
        noise = tree.nodes.new("ShaderNodeTexNoise")
        acc = out.inputs["Surface"].links[0].from_socket
        for _ in range(extra):
            mix = tree.nodes.new("ShaderNodeMixShader")
            tree.links.new(noise.outputs["Fac"], mix.inputs["Fac"])
            tree.links.new(acc, mix.inputs[1])
            tree.links.new(tree.nodes.new("ShaderNodeBsdfPrincipled").outputs[0], mix.inputs[2])
            acc = mix.outputs[0]
        tree.links.new(acc, out.inputs["Surface"])
    with pytest.raises(scenes.ClosureLimitExceeded) as got:
        render(api_env(api), mat)
    return int(re.search(r"exceeded: (\d+) > 64", str(got.value)).group(1)) - 12 * extra


@pytest.mark.parametrize("build", [hazy_beside_a_principled, every_kind, hazy_in_a_fog,
                                   hazy_metal_in_a_fog, liquid, rust_on_plastic])
def test_closure_count_is_the_number_cycles_logs(env, build):
    """closure_count is the count Cycles logs (5.x, with Blender's debug flag), folded Mix
    Shaders of the layer's group included (Metallic 1 drops the dielectric part: the count was
    an upper bound, and the note warned of 92 where Cycles counts 56); a hazy material over
    the limit says so, one under it says nothing."""
    api, wiring = env
    mat = build(api)
    count = wiring.closure_count(mat.node_tree)
    if api.is_hazy(mat):
        said = [n for n in api.read_parameters(mat)["notes"] if "closures" in n]
        assert said == ([n for n in said if f"Cycles counts up to {count} closures" in n]
                        if count > wiring.MAX_CLOSURES else [])
        assert len(said) == (count > wiring.MAX_CLOSURES)
    if bpy.app.version < (5, 0, 0):
        pytest.skip("4.5's Cycles logs its count at a verbose level a module cannot set")
    assert _cycles_count(api, wiring, mat) == count


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
    return SimpleNamespace(exr=importlib.import_module(api.__name__.rsplit(".", 1)[0] + ".conversion.imagecheck"))
