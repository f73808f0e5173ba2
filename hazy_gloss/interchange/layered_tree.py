# SPDX-License-Identifier: GPL-3.0-or-later
"""What interchange/layered.py writes from: the bpy-free snapshot of a Blender node tree (:class:`Tree`,
:class:`BNode`, :class:`Socket`, made by blender/actions/interchange.py) and the Blender -> MaterialX
name tables (colour spaces, image address and filter modes, socket types).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .. import constants as K

__all__ = ("LUMA", "COLORSPACES", "ADDRESS", "FILTER", "MX_TYPE", "PRINCIPLED", "METALLIC",
           "GLOSSY", "Socket", "BNode", "Tree")

#: Blender's colour -> float conversion (Cycles linear_rgb_to_gray with the default OCIO
#: config's Rec.709 luma coefficients).
LUMA = (0.2126, 0.7152, 0.0722)
#: Blender image colour spaces -> MaterialX colour spaces.
COLORSPACES = {"sRGB": K.MATERIALX_SRGB_COLORSPACE, "Non-Color": K.MATERIALX_DATA_COLORSPACE,
               "Raw": K.MATERIALX_DATA_COLORSPACE, "Linear Rec.709": "lin_rec709",
               "Linear": "lin_rec709", "Linear CIE-XYZ E": None, "ACEScg": "acescg",
               "ACES2065-1": "lin_ap0", "Linear Rec.2020": "lin_rec2020",
               "Rec.2020": "lin_rec2020", "Linear DCI-P3 D65": "lin_displayp3",
               "Display P3": "srgb_displayp3", "Linear FilmLight E-Gamut": None}
ADDRESS = {"REPEAT": "periodic", "EXTEND": "clamp", "CLIP": "constant", "MIRROR": "mirror"}
FILTER = {"Linear": "linear", "Closest": "closest", "Cubic": "cubic", "Smart": "cubic"}
MX_TYPE = {"VALUE": "float", "RGBA": "color3", "VECTOR": "vector3", "INT": "float",
            "BOOLEAN": "float"}
PRINCIPLED = "ShaderNodeBsdfPrincipled"
METALLIC = "ShaderNodeBsdfMetallic"
GLOSSY = ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic")


# --------------------------------------------------------------------------------------------
# The snapshot of a Blender tree (made by blender/actions/interchange.py)
# --------------------------------------------------------------------------------------------


@dataclass
class Socket:
    identifier: str
    name: str
    type: str  #: Blender's socket type: VALUE, RGBA, VECTOR, SHADER, INT, ...
    value: object = None  #: the unlinked value (float or tuple), None when it has none
    link: tuple = None  #: (from node name, from socket identifier) of a valid, unmuted link
    enabled: bool = True
    linked: bool = False  #: an output with links
    node: str = ""  #: the node it belongs to (for the notes)


@dataclass
class BNode:
    name: str
    type: str  #: bl_idname
    inputs: list = field(default_factory=list)
    outputs: list = field(default_factory=list)
    props: dict = field(default_factory=dict)  #: operation, data_type, distribution, ...
    label: str = ""
    role: str = None  #: the add-on's role (hazy_gloss_role), None for the user's nodes
    core: bool = False  #: the layer's core (the user's BSDF)
    mute: bool = False
    image: dict = None  #: Image or Environment Texture: name, path (absolute), colorspace, source, packed
    ramp: dict = None  #: Color Ramp: color_mode, interpolation, elements [(pos, rgba)]
    base: dict = None  #: the core: the user's own value / link of each owned input

    def input(self, key):
        """The enabled input with this identifier, else the first enabled one with this name."""
        for s in self.inputs:
            if s.identifier == key and s.enabled:
                return s
        return next((s for s in self.inputs if s.name == key and s.enabled),
                    next((s for s in self.inputs if s.name == key or s.identifier == key), None))

    def output(self, identifier):
        return next((s for s in self.outputs if s.identifier == identifier), None)


@dataclass
class Tree:
    """A material's node tree: nodes by name, the Material Output the renderers use, and the
    haze layer's state (``layer``: haze, core, core_type, parts, coat, baked, maps)."""

    name: str
    nodes: dict = field(default_factory=dict)
    output: str = None
    layer: dict = field(default_factory=dict)

    def core(self):
        return next((n for n in self.nodes.values() if n.core), None)
