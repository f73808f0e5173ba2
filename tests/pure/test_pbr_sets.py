# SPDX-License-Identifier: GPL-3.0-or-later
"""Which file of a texture library's PBR set is which map (hazy_gloss.conversion.convert.detect_pbr_set)."""
import pytest

from hazy_gloss.conversion.convert import ConversionError, detect_pbr_set

LIBRARIES = {
    "ambientCG": (["Wood049_4K-PNG_Color.png", "Wood049_4K-PNG_NormalGL.png",
                   "Wood049_4K-PNG_NormalDX.png", "Wood049_4K-PNG_Roughness.png",
                   "Wood049_4K-PNG_Displacement.png", "Wood049_4K-PNG_Metalness.png",
                   "Wood049.usdc", "Wood049_4K-PNG.mtlx"],
                  dict(base_color="Wood049_4K-PNG_Color.png", normal="Wood049_4K-PNG_NormalGL.png",
                       roughness="Wood049_4K-PNG_Roughness.png",
                       metallic="Wood049_4K-PNG_Metalness.png")),
    "Poly Haven": (["rusty_metal_diff_2k.jpg", "rusty_metal_nor_gl_2k.exr",
                    "rusty_metal_rough_2k.jpg", "rusty_metal_metal_2k.jpg", "rusty_metal_arm_2k.jpg"],
                   dict(base_color="rusty_metal_diff_2k.jpg", normal="rusty_metal_nor_gl_2k.exr",
                        roughness="rusty_metal_rough_2k.jpg", metallic="rusty_metal_metal_2k.jpg")),
    "Quixel": (["T_Crate_Albedo.tga", "T_Crate_Normal.tga", "T_Crate_Roughness.tga",
                "T_Crate_Opacity.tga"],
               dict(base_color="T_Crate_Albedo.tga", normal="T_Crate_Normal.tga",
                    roughness="T_Crate_Roughness.tga", alpha="T_Crate_Opacity.tga")),
    "Substance": (["crate_BaseColor.png", "crate_Metallic.png", "crate_Roughness.png",
                   "crate_Normal.png", "crate_Haziness.png"],
                  dict(base_color="crate_BaseColor.png", metallic="crate_Metallic.png",
                       roughness="crate_Roughness.png", normal="crate_Normal.png",
                       haziness="crate_Haziness.png")),
}


@pytest.mark.parametrize("library", sorted(LIBRARIES))
def test_library_naming(library):
    files, want = LIBRARIES[library]
    assert detect_pbr_set(files) == want


def test_refusals():
    with pytest.raises(ConversionError, match="DirectX normal map"):
        detect_pbr_set(["a_Color.png", "a_NormalDX.png"])
    with pytest.raises(ConversionError, match="more than one file for roughness"):
        detect_pbr_set(["a_Roughness.png", "b_Roughness.png"])
    with pytest.raises(ConversionError, match="no map"):
        detect_pbr_set(["readme.txt", "a_Displacement.png"])
