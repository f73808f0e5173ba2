# SPDX-License-Identifier: GPL-3.0-or-later
"""Every constant the add-on shares between modules, bpy-free, in one place.

The numbers are Cycles' limits (docs/blender-versions.md; kernel/closure/bsdf_microfacet.h) and the
add-on's own choices; every path (lean material, in-shader nodes, baked maps, recomposite)
clamps with these same values.
"""

from dataclasses import dataclass

__all__ = ("Term", "KIND_TERMS", "DISTRIBUTION_TERMS", "TANGENT_TERMS", "KINDS", "DISTRIBUTIONS",
           "TANGENTS", "NODE_DISTRIBUTIONS", "label", "enum_items", "MAX_HAZINESS", "MIN_ROUGHNESS",
           "MIN_ROUGHNESS_AS", "ALPHA_MAX", "MAX_ASPECT", "MIN_SMOOTHNESS", "ONE_MINUS_ULP32",
           "FLOAT32_MAX", "min_roughness", "NODE_PREFIX", "STAMP", "TEXTURED", "PAINTED_MAP",
           "MAPS_STAMP", "RECOMPOSITE_STAMP", "GROUP_STAMP", "GROUP_PRINT", "ROLE", "HAZE_PANEL",
           "LAYER_NODE_KEY", "ORIGINAL_NODE_KEY", "MAX_IMAGE_PIXELS", "MAX_EXR_DECODED_BYTES",
           "MAX_TEXELS_PER_BYTE", "STRIP_TEXELS", "EXR_ZIP_LEVEL", "PNG_ZIP_LEVEL", "EXIT_OK",
           "EXIT_BAD_INPUT", "EXIT_NO_BPY", "EXIT_SETS_FAILED", "EXIT_INTERRUPTED",
           "LOSSLESS_EXR_CODECS", "CONVERT_RUN_ID_HEX", "MATERIALX_VERSION", "MATERIALX_COLORSPACE",
           "MATERIALX_DATA_COLORSPACE", "MATERIALX_SRGB_COLORSPACE", "MATERIALX_ATTR",
           "INTERCHANGE_VERSION", "MATERIALX_PROGRESS_BYTES", "INTERCHANGE_RTOL",
           "OPENPBR_12_NODEDEF", "OPENPBR_12_VERSION", "OPENPBR_RELEASED_VERSION", "F82_MU",
           "UNITY_HAZE_BEZIER_W", "UNITY_MAX_DIELECTRIC_F0", "FILAMENT_CLEARCOAT_F0",
           "FALLBACK_ROLE", "FALLBACK_OUTPUT_ROLE", "RENDER_OUTPUT_ROLE", "IMAGE_NODES",
           "TABLE_IMAGE_PREFIX", "CONVERTED_ROLE", "EEVEE_ROLE", "EEVEE_OUTPUT_ROLE")


@dataclass(frozen=True)
class Term:
    """One word of the vocabulary: ``id`` (the stamp's and Blender's enum value), ``label`` (UI,
    node group names, docs), ``description`` (tooltip); ``kinds``: for a distribution, the kinds
    whose node offers it."""
    id: str
    label: str
    description: str
    kinds: tuple = ()


#: Lobe kinds: Metallic BSDF lobes (conductor Fresnel), Principled BSDF lobes (dielectric
#: Fresnel over a base), Glossy BSDF lobes (no Fresnel, weights in the colours).
KIND_TERMS = (
    Term("CONDUCTOR", "Conductor", "Metal: Metallic BSDF lobes with the physical conductor "
         "Fresnel from core reflectivity and edge tint (Gulbrandsen 2014)"),
    Term("DIELECTRIC", "Dielectric", "Plastic, varnish, glass: Principled BSDF specular lobes "
         "over a base colour; keep haziness small (about 0-0.1)"),
    Term("LEGACY", "Legacy", "Glossy BSDF lobes without Fresnel (colours only)"),
)
#: Microfacet distributions, spelled as Blender's node enums, and which kinds' nodes offer them
#: (Metallic, Principled, Glossy BSDF).
DISTRIBUTION_TERMS = (
    Term("GGX", "GGX", "GGX microfacets (all kinds)", ("CONDUCTOR", "DIELECTRIC", "LEGACY")),
    Term("BECKMANN", "Beckmann", "Beckmann microfacets (conductor and legacy)",
         ("CONDUCTOR", "LEGACY")),
    Term("MULTI_GGX", "Multiscatter GGX", "GGX with multiple-scattering energy compensation "
         "(β and r corrected so the peak stays invariant)", ("CONDUCTOR", "DIELECTRIC", "LEGACY")),
    Term("ASHIKHMIN_SHIRLEY", "Ashikhmin-Shirley", "Ashikhmin-Shirley lobes (legacy only)",
         ("LEGACY",)),
)
#: The tangent of anisotropic lobes.
TANGENT_TERMS = (
    Term("UV_MAP", "UV Map", "Tangent from the object's UV map (the usual choice)"),
    Term("RADIAL_X", "Radial X", "Radial tangent around the object's X axis"),
    Term("RADIAL_Y", "Radial Y", "Radial tangent around the object's Y axis"),
    Term("RADIAL_Z", "Radial Z", "Radial tangent around the object's Z axis (Blender's default "
         "for an unconnected Tangent)"),
)

KINDS = tuple(t.id for t in KIND_TERMS)
DISTRIBUTIONS = tuple(t.id for t in DISTRIBUTION_TERMS)
TANGENTS = tuple(t.id for t in TANGENT_TERMS)
#: Which distributions each kind's node offers.
NODE_DISTRIBUTIONS = {k: tuple(t.id for t in DISTRIBUTION_TERMS if k in t.kinds) for k in KINDS}


def label(terms, term_id):
    """The label of ``term_id`` in ``terms`` (KIND_TERMS, ...); the id itself when unknown."""
    return next((t.label for t in terms if t.id == term_id), term_id)


def enum_items(terms):
    """(id, label, description, number) items of a Blender EnumProperty."""
    return tuple((t.id, t.label, t.description, i) for i, t in enumerate(terms))


#: Haziness β_h is kept in [0, MAX_HAZINESS]: β_h = 1 is the degenerate single-wide-lobe case
#: (the paper's β_h ∈ [0, 1)); every path clamps to this one value.
MAX_HAZINESS = 0.9999

#: Smallest roughness R the add-on gives a hazy lobe, just above the mirror cut-off (Cycles
#: turns a lobe into a perfect mirror when α_x α_y <= 2e-10, i.e. R < 0.00376).
MIN_ROUGHNESS = 0.004
#: Cycles clamps Ashikhmin-Shirley α to >= 1e-4 and drops a lobe whose α are all <= 1e-4.
MIN_ROUGHNESS_AS = 0.0101
#: Cycles clamps every α to <= 1 after anisotropy.
ALPHA_MAX = 1.0
#: Longest α_x/α_y the Metallic and Principled nodes can express (anisotropy 1).
MAX_ASPECT = 10.0
#: Smallest Bézier weight w (Eqs. 12-15) the add-on accepts.
MIN_SMOOTHNESS = 1e-4
#: Largest float32 below 1: r <= 1 - ε keeps η, κ finite in float32 shader math.
ONE_MINUS_ULP32 = 1.0 - 2.0 ** -23
#: float32's largest finite value (what a Blender float socket holds).
FLOAT32_MAX = 3.4028234663852886e38


def min_roughness(distribution):
    """Smallest roughness R a lobe of ``distribution`` gets."""
    return MIN_ROUGHNESS_AS if distribution == "ASHIKHMIN_SHIRLEY" else MIN_ROUGHNESS


#: Name prefix of every node the add-on builds in a material tree (the rest is the user's).
NODE_PREFIX = "HG"
#: ID-property stamps.
STAMP = "hazy_gloss"  # on a hazy material: its perceptual parameters
#: A haze parameter that a link feeds, as read back from the layer node (no one value).
TEXTURED = "texture"
#: On a haziness map Add Haziness Map made: the parameter it paints.
PAINTED_MAP = "hazy_gloss_painted_map"
MAPS_STAMP = "hazy_gloss_maps"  # on a material wired to converted maps
RECOMPOSITE_STAMP = "hazy_gloss_recomposite"  # on materials and the scene in recomposite mode
GROUP_STAMP = "hazy_gloss_group"  # on the generated shader node groups
GROUP_PRINT = "hazy_gloss_print"  # a layer group's fingerprint when built (an edit is told)
#: Node custom property naming a node's role in a hazy material (survives renaming).
ROLE = "hazy_gloss_role"

#: (The haze layer's own inputs, the group node's Haze panel: schema.HAZE_SOCKETS.)
#: The Haze panel's name on a layer group node.
HAZE_PANEL = "Haze"
#: Node custom property on a layer's group node and on the artist's BSDF it wraps (kept aside).
LAYER_NODE_KEY = "hazy_gloss_layer"
ORIGINAL_NODE_KEY = "hazy_gloss_original"

#: Limits of the add-on's image files (conversion/imagecheck.py): anything beyond them is a damaged
#: or hostile file, refused before memory is allocated for it.
MAX_IMAGE_PIXELS = 1 << 30  # width x height (e.g. 32768 x 32768; 16 GiB as RGBA float)
MAX_EXR_DECODED_BYTES = 1 << 31  # float32 values read_exr returns (a 4K 30-channel render: 1 GiB)
#: Texels per file byte beyond which a header's image size is not believed: a loose bound (a
#: constant 32768-wide HTJ2K image packs ~4000 texels into a byte, deflate at most ~1032 bytes)
#: that stops tiny files whose header would make Blender allocate gigabytes.
MAX_TEXELS_PER_BYTE = 1 << 16
#: Texture conversion in strips (conversion/imagestream.py): texels per strip (memory per map
#: in flight), and the zlib levels its writers ask OpenImageIO for (measured on a 1K β map: EXR
#: ZIP level 4 within 0.1 % of Blender's file, level 6 no smaller; 16-bit PNG level 3 5 %
#: smaller than Blender's, level 6 3 % smaller still for more time).
STRIP_TEXELS = 1 << 18
EXR_ZIP_LEVEL = 4
PNG_ZIP_LEVEL = 3

# -- texture conversion (conversion/, blender/actions/convert.py, python -m hazy_gloss) --------
#: Exit statuses of ``python -m hazy_gloss convert`` (docs/textures.md).
EXIT_OK = 0
EXIT_BAD_INPUT = 2  # bad input or usage: one line "hazy_gloss convert: error: ..." on stderr
EXIT_NO_BPY = 3  # the bpy module is not importable
EXIT_SETS_FAILED = 4  # --batch: some sets failed (each one line on stderr), the others converted
EXIT_INTERRUPTED = {2: 130, 15: 143}  # SIGINT, SIGTERM: 128 + signal number, run undone
#: OpenEXR codecs that store 32-bit floats exactly (measured in 4.5, 5.2 and 5.3): maps written
#: with them are read back and compared bit for bit; the others only for size and finiteness.
LOSSLESS_EXR_CODECS = ("NONE", "ZIP", "ZIPS", "PIZ", "RLE", "HTJ2K")
#: Files a conversion writes before it commits: ".<name>.<run>.tmp<ext>" (new maps) and
#: ".<name>.<run>.bak<ext>" (the maps they replace, until the whole set is in place), <run>
#: being CONVERT_RUN_ID_HEX lowercase hex digits.
CONVERT_RUN_ID_HEX = 12

# --------------------------------------------------------------------------------------------
# Interchange (hazy_gloss/interchange, docs/interchange.md)
# --------------------------------------------------------------------------------------------

#: MaterialX document version written (the released 1.39 standard libraries).
MATERIALX_VERSION = "1.39"
#: Working colour space of the documents (linear Rec.709, Blender's scene-linear default).
MATERIALX_COLORSPACE = "lin_rec709"
#: Colour space of data (Non-Color) textures: no colour transform.
MATERIALX_DATA_COLORSPACE = "raw"
#: Colour space of sRGB-encoded colour textures.
MATERIALX_SRGB_COLORSPACE = "srgb_texture"
#: Prefix of the custom attributes the add-on writes into MaterialX (and USD customData).
MATERIALX_ATTR = "hazygloss"
#: Version of the perceptual-parameter record stored with an exported material.
INTERCHANGE_VERSION = 1
#: import-materialx shows a progress bar for files of this size and more (--quiet: never).
MATERIALX_PROGRESS_BYTES = 1 << 20
#: Relative tolerance within which a graph's physical values count as "the same" as the
#: forward mapping of the stored perceptual parameters (17 significant digits are written).
INTERCHANGE_RTOL = 1e-6
#: Nodedef of the OpenPBR 1.2 surface subset embedded in the OpenPBR flavour (1.2 is on the
#: dev_1.2 branch, not in the released libraries).
OPENPBR_12_NODEDEF = "ND_open_pbr_surface_surfaceshader_v1_2_hazygloss"
OPENPBR_12_VERSION = "1.2"
OPENPBR_RELEASED_VERSION = "1.1.1"
#: OpenPBR's metal F82-tint reference angle μ̄ = cos θ̄ = 1/7 (Kutz et al. 2021).
F82_MU = 1.0 / 7.0
#: Unity HDRP StackLit hazy gloss: Bézier weight w and the default dielectric F0 cap.
UNITY_HAZE_BEZIER_W = 10.0
UNITY_MAX_DIELECTRIC_F0 = 0.25
#: Filament clear coat: fixed IOR 1.5, F0 = 0.04 (Schlick).
FILAMENT_CLEARCOAT_F0 = 0.04
#: Role names of the export fallback's nodes (blender/model/fallback.py add_export_fallback).
FALLBACK_ROLE = "Export fallback"
FALLBACK_OUTPUT_ROLE = "Export output"
RENDER_OUTPUT_ROLE = "Render output"
#: Nodes that read an image: a layer group reads its tables with Environment Textures.
IMAGE_NODES = ("ShaderNodeTexImage", "ShaderNodeTexEnvironment")
TABLE_IMAGE_PREFIX = ".Hazy Gloss table "  # + table name and values' hash: a group's lookup table
CONVERTED_ROLE = "layer converted "  # + BAKED key: an Image Texture of a baked layer's map
EEVEE_ROLE = "layer eevee "  # the role of every node blender/actions/eevee_output.py builds starts so
EEVEE_OUTPUT_ROLE = EEVEE_ROLE + "output"  # blender/actions/eevee_output.py's EEVEE-only Material Output
