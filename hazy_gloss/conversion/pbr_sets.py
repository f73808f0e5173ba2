# SPDX-License-Identifier: GPL-3.0-or-later
"""PBR texture sets for the converter (convert.py): which file of a folder is which
map (base colour, metallic, roughness, ... by the name parts texture libraries use), and UDIM
tile sets folded into one name.
"""
from __future__ import annotations

import os
import re

from .status import ConversionError

__all__ = ("PBR_NAME_PARTS", "udim_sets", "detect_pbr_set")


# --------------------------------------------------------------------------------------------
# PBR texture sets: which file is which map
# --------------------------------------------------------------------------------------------

#: Name parts texture libraries use for each map of a PBR set (lower case, matched as whole
#: words between separators: "crate_BaseColor_2k.png", "Wood049_4K-PNG_Roughness.png").
PBR_NAME_PARTS = {
    "base_color": ("basecolor", "base_color", "albedo", "diffuse", "diff", "color", "col"),
    "metallic": ("metallic", "metalness", "metal"),
    "roughness": ("roughness", "rough"),
    "normal": ("normal", "normalgl", "nor_gl", "norm", "nrm", "nor"),
    "coat": ("coat", "clearcoat"),
    "alpha": ("opacity", "alpha", "mask"),
    "haziness": ("haziness", "haze"),
}
_PBR_IMAGE_EXT = (".png", ".jpg", ".jpeg", ".exr", ".tif", ".tiff", ".tga", ".bmp", ".webp", ".hdr")


_UDIM_FILE = None


def udim_sets(filenames):
    """File names with the tiles of a UDIM set (``name.1001.png``, ``name_1002.png``: a 4-digit
    tile 1001-2000 before the extension) folded into one ``name.<UDIM>.png``; others as they
    are."""
    global _UDIM_FILE
    if _UDIM_FILE is None:
        _UDIM_FILE = re.compile(r"\A(?P<head>.*[._])(?P<tile>\d{4})(?P<ext>\.[^.]+)\Z")
    out = []
    for fn in filenames:
        m = _UDIM_FILE.match(os.path.basename(fn))
        if m and 1001 <= int(m["tile"]) <= 2000:
            fn = os.path.join(os.path.dirname(fn), f"{m['head']}<UDIM>{m['ext']}")
        if fn not in out:
            out.append(fn)
    return out


def detect_pbr_set(filenames):
    """{map name: file name} for the files of one PBR set, by the name parts texture libraries
    use (PBR_NAME_PARTS; UDIM tiles are one ``<UDIM>`` name, :func:`udim_sets`); a DirectX normal map ("NormalDX") is skipped for the OpenGL one, and
    refused when it is the only normal map (Blender's Normal Map node reads OpenGL normals).
    Raises ConversionError when two files claim one map or none is found."""
    found, clash, directx = {}, {}, []
    named = {}
    for fn in sorted(udim_sets(filenames)):
        stem, ext = os.path.splitext(os.path.basename(fn))
        if ext.lower() in _PBR_IMAGE_EXT:
            named[fn] = [w for w in re.split(r"[^a-z0-9]+", re.sub(
                r"([a-z])([A-Z])", r"\1_\2", stem).lower()) if w]
    # the set's name is the words every file starts with; the resolution ("2k") the words
    # every file ends with, unless they name a map
    lists = list(named.values())
    pre = 0
    while len(lists) > 1 and all(len(w) > pre for w in lists) and \
            len({w[pre] for w in lists}) == 1:
        pre += 1
    post = 0
    map_words = {p for parts in PBR_NAME_PARTS.values() for p in parts}
    while len(lists) > 1 and all(len(w) > pre + post for w in lists) and \
            len({w[-1 - post] for w in lists}) == 1 and lists[0][-1 - post] not in map_words:
        post += 1
    def which(words):
        joined = {a + b for a, b in zip(words, words[1:])} | {a + "_" + b for a, b in zip(words, words[1:])}
        return next((name for name, parts in PBR_NAME_PARTS.items()
                     if any(p in words or p in joined for p in parts)), None)

    for fn, all_words in named.items():
        words = all_words[pre:len(all_words) - post] or all_words
        if "dx" in all_words and ({"normal", "nor", "nrm"} & set(all_words)):
            directx.append(fn)  # green down: Blender's Normal Map node reads OpenGL normals
            continue
        name = which(words)
        if name is None:
            continue
        if name in found and found[name] != fn:
            clash.setdefault(name, [found[name]]).append(fn)
        found.setdefault(name, fn)
    if clash:
        raise ConversionError("more than one file for " + "; ".join(
            f"{k}: {', '.join(v)}" for k, v in clash.items()) + " (pass the maps by name)")
    if directx and "normal" not in found:
        raise ConversionError(f"{directx[0]}: a DirectX normal map (green down); Blender's "
                              f"Normal Map node reads OpenGL normals: use the set's OpenGL "
                              f"normal map")
    if not found:
        raise ConversionError("no map of a PBR set found (names with basecolor, metallic, "
                              "roughness, normal, ...)")
    return found
