# SPDX-License-Identifier: GPL-3.0-or-later
"""Build a look (utils.looks): a Principled material as an artist would make it, with its haze
layer (blender.model.layer).  Only built-in nodes."""
from ...utils.looks import LOOKS
from .. import compat
from . import make_hazy

__all__ = ("TEXTURES", "create_look")


def _principled(mat):
    return next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")


def _wood(tree, bsdf):
    coord = tree.nodes.new("ShaderNodeTexCoord")
    wave = tree.nodes.new("ShaderNodeTexWave")
    wave.wave_type, wave.bands_direction = "RINGS", "Y"
    for k, v in {"Scale": 1.6, "Distortion": 6.0, "Detail": 3.0, "Detail Scale": 1.5}.items():
        wave.inputs[k].default_value = v
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.16, 0.06, 0.02, 1.0)
    ramp.color_ramp.elements[1].color = (0.42, 0.2, 0.08, 1.0)
    tree.links.new(coord.outputs["Object"], wave.inputs["Vector"])
    tree.links.new(wave.outputs["Fac"], ramp.inputs["Fac"])
    tree.links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    coord.location, wave.location, ramp.location = (-900, 200), (-700, 200), (-450, 200)


def _roughness_texture(tree, bsdf, texture, texture_values, output, range_values):
    """A ``texture`` node (with ``texture_values``) through a Map Range (``range_values``) to
    the BSDF's Roughness."""
    tex = tree.nodes.new(texture)
    for name, value in texture_values.items():
        tex.inputs[name].default_value = value
    rng = tree.nodes.new("ShaderNodeMapRange")
    for name, value in range_values.items():
        rng.inputs[name].default_value = value
    tree.links.new(tex.outputs[output], rng.inputs["Value"])
    tree.links.new(rng.outputs["Result"], bsdf.inputs["Roughness"])
    tex.location, rng.location = (-700, -200), (-450, -200)


def _flakes(tree, bsdf):
    """Metal flakes: a fine Voronoi varying the base's roughness."""
    _roughness_texture(tree, bsdf, "ShaderNodeTexVoronoi", {"Scale": 400.0}, "Distance",
                       {"To Min": 0.26, "To Max": 0.4})


def _worn_roughness(tree, bsdf):
    _roughness_texture(tree, bsdf, "ShaderNodeTexNoise", {"Scale": 4.0, "Detail": 6.0}, "Fac",
                       {"From Min": 0.35, "From Max": 0.65, "To Min": 0.18, "To Max": 0.5})


def _radial_tangent(tree, bsdf):
    """Brushed around the object's Z axis (works without a UV map)."""
    t = tree.nodes.new("ShaderNodeTangent")
    t.direction_type, t.axis = "RADIAL", "Z"
    tree.links.new(t.outputs["Tangent"], bsdf.inputs["Tangent"])
    t.location = (-450, -500)


#: Procedural set-ups a look can name (utils.looks.Look.textures).
TEXTURES = {"wood": _wood, "flakes": _flakes, "worn_roughness": _worn_roughness,
            "radial_tangent": _radial_tangent}


def create_look(look_id, name=None, **haze):
    """A new material for ``look_id`` (utils.looks.LOOKS) with its haze layer; ``haze``
    overrides the look's haze (e.g. haziness=0 for the haze-free original)."""
    try:
        look = LOOKS[look_id]
    except KeyError:
        raise ValueError(f"unknown look {look_id!r}; known: {', '.join(LOOKS)}") from None
    mat = compat.new_material(name or look.name)
    bsdf = _principled(mat)
    bsdf.distribution = "MULTI_GGX"  # Blender's default, kept (the mapping corrects for it)
    for key, value in look.principled.items():
        bsdf.inputs[key].default_value = value
    for texture in look.textures:
        TEXTURES[texture](mat.node_tree, bsdf)
    status, msg, _ = make_hazy.make_hazy(mat, **dict(look.haze, **haze))
    if status == "ERROR":
        raise ValueError(msg)
    return mat
