# SPDX-License-Identifier: GPL-3.0-or-later
"""Edit haziness after the render: the paper's §4.3 compositing route (Eq. 10-11), bpy-free.

With Schlick's Fresnel F = (1-Δ) r + Δ, Δ = (1 - cos θ_d)^5, reflected radiance is linear in
the physical parameters β and r (Eq. 11):

    L = (1-β) (r L0_n + L1_n) + β (r L0_w + L1_w)

where L0 renders the lobe with f (1-Δ) and L1 with f Δ.  Besides the ordinary render V0, four
view layers render V_k = H_k + X (H_k the camera-visible hazy surfaces with one lobe and one
Fresnel variant, X whatever else the camera sees there).  With

    c1 = (1-β)(1-r),  c2 = (1-β) r,  c3 = β (1-r),  c4 = β r        (per channel, Σ c_k = 1)

Eq. 11 is Σ c_k H_k and the recomposite is  out = V0 + Σ_k (c_k(β', r') - c_k(β, r)) V_k :
X cancels exactly, unedited pixels are V0 bit for bit, and an edited hazy pixel becomes
V0 - Eq.11(β, r) + Eq.11(β', r').  The haze mapping (Eq. 7 with the rendered peak ratio p and
its complement, Eq. 4-5) turns an edited haziness β_h and core reflectivity r_c into β', r'.
docs/compositing.md explains the render set-up (hazy_gloss.blender.model.recomposite).

- :func:`passes_from_exr`, :func:`recomposite`: numpy;
- :func:`compositor_graph`: the same computation as node math (core.graph), from which the
  compositor group "Hazy Gloss Recomposite" is generated.
"""
from __future__ import annotations

import numpy as np

from . import constants as K
from .core import node_math
from .core.graph import Graph, evaluate
from .conversion.imagecheck import ImageFileError, read_exr

__all__ = ("PROPERTY", "LAYERS", "BUFFER_KEYS", "HOLDOUT_COLLECTION", "AOVS", "MAX_HAZINESS",
           "GROUP_NAME", "GROUP_VERSION", "exr_layers", "passes_from_exr", "GRAPH_INPUTS",
           "compositor_graph", "recomposite")

#: View layer custom property read by the hazy materials (Attribute node, type VIEW_LAYER).
PROPERTY = "hg_recomposite"
#: View layer per mode (order = c1..c4 above).
LAYERS = ("HG Narrow Delta", "HG Narrow One", "HG Wide Delta", "HG Wide One")
#: Pass keys of :func:`recomposite` in the same order (plus "original", the ordinary render).
BUFFER_KEYS = ("narrow_delta", "narrow_one", "wide_delta", "wide_one")
#: Collection of the non-hazy objects, held out (camera rays only) in the four layers.
HOLDOUT_COLLECTION = "HG Recomposite Holdout"
#: AOVs written by hazy materials (name, type, key in the passes dict).
AOVS = (("hg_beta", "VALUE", "beta"), ("hg_reflectivity", "COLOR", "reflectivity"),
        ("hg_peak_ratio", "VALUE", "peak_ratio"),
        ("hg_peak_complement", "VALUE", "peak_complement"), ("hg_mask", "VALUE", "mask"),
        ("hg_haziness", "VALUE", "haziness"),
        ("hg_core_reflectivity", "COLOR", "core_reflectivity"))
#: Haziness is limited to [0, MAX_HAZINESS] (β_h = 1 is the degenerate single-wide-lobe case).
MAX_HAZINESS = K.MAX_HAZINESS

GROUP_NAME = "Hazy Gloss Recomposite"
GROUP_VERSION = 3


def exr_layers(channels):
    """Names of the layers in a multilayer EXR channel dict (those with a Combined pass).
    A render with compositing also writes "Composite" (the compositor's result)."""
    return sorted({name[:-len(".Combined.R")] for name in channels if name.endswith(".Combined.R")})


def passes_from_exr(path, original=None, layers=LAYERS):
    """The recomposite passes of a multilayer EXR written after :func:`setup_recomposite`.

    ``original``: the view layer holding the ordinary render; None finds it (the one layer
    that is not one of ``layers``).  Returns a dict for :func:`recomposite`: ``original``,
    ``narrow_delta``, ``narrow_one``, ``wide_delta``, ``wide_one`` as (H, W, 4) RGBA and the
    AOVs ``beta``, ``peak_ratio``, ``mask``, ``haziness`` (H, W) and ``reflectivity``,
    ``core_reflectivity`` (H, W, 3).  Row 0 = bottom row.

    The file is read through OpenImageIO (:func:`conversion.imagecheck.read_exr`): every codec
    Blender writes (ZIP, PIZ, DWAA, DWAB, RLE, NONE, ...), scanline or tiled.  Raises
    :class:`~conversion.imagecheck.ImageFileError` (a ValueError) for a damaged or unsupported
    file or passes of different sizes, KeyError for a well-formed file without the passes; both
    one line naming the file."""
    ch = read_exr(path)
    if original is None:
        others = [name for name in exr_layers(ch) if name not in layers and name != "Composite"]
        if len(others) != 1:
            raise KeyError(f"{path}: cannot tell the original layer among {others or 'none'}; "
                           "pass original=<view layer name>")
        original = others[0]

    def rgba(prefix):
        names = [f"{prefix}.{c}" for c in "RGBA"]
        missing = [n for n in names[:3] if n not in ch]
        if missing:
            raise KeyError(f"{path}: missing channels {missing} (was the scene set up with "
                           "hazy_gloss.setup_recomposite and saved as multilayer EXR?)")
        a = ch.get(names[3])
        if a is None:
            a = np.ones_like(ch[names[0]])
        return np.stack(list(same_size({n: ch[n] for n in names[:3]} | {names[3]: a}).values()),
                        axis=-1)

    def same_size(passes):
        sizes = {k: v.shape[:2] for k, v in passes.items()}
        if len(set(sizes.values())) > 1:
            raise ImageFileError(f"{path}: the recomposite passes have different sizes "
                           f"({', '.join(f'{k} {w}x{h}' for k, (h, w) in sizes.items())})")
        return passes

    passes = {key: rgba(f"{layer}.Combined") for key, layer in zip(BUFFER_KEYS, layers)}
    passes["original"] = rgba(f"{original}.Combined")
    first = layers[0]
    for aov, typ, key in AOVS:
        if typ == "VALUE":
            name = next((f"{first}.{aov}.{c}" for c in ("X", "V", "R", "Y")
                         if f"{first}.{aov}.{c}" in ch), None)
            if name is None and key == "peak_complement":
                continue  # renders before the AOV existed: 1 - p (recomposite_parameters)
            if name is None:
                raise KeyError(f"{path}: missing AOV {aov} on layer {first!r}")
            passes[key] = ch[name]
        else:
            passes[key] = rgba(f"{first}.{aov}")[..., :3]
    return same_size(passes)


# ============================================================================================
# The recomposite itself (Eq. 7, 4, 5 per pixel, then Eq. 11), written once as node math
# ============================================================================================

def _socket(key):
    """A graph input's compositor group socket: its key in title case."""
    return key.replace("_", " ").title()


def _layer_description(layer):
    lobe, fresnel = layer.removeprefix("HG ").lower().split()  # "narrow", "delta"
    n = lobe[0]
    term = f"F = Δ (L1_{n})" if fresnel == "delta" else f"F = 1 (L0_{n} + L1_{n})"
    return f"Layer '{layer}': {lobe} lobe, {term}"


#: What each AOV holds, for its socket's description.
_AOV_MEANING = {"beta": "rendered β", "reflectivity": "rendered r", "peak_ratio": "p",
                "peak_complement": "1 - p", "mask": "hazy coverage", "haziness": "rendered β_h",
                "core_reflectivity": "rendered r_c"}
#: The edit inputs: key, vector, description.
_EDITS = (
    ("new_haziness", False, "β_h to use (a value or a map)"),
    ("haziness_factor", False,
     "0 keeps the rendered β_h, 1 uses New Haziness (a mask edits part of the image)"),
    ("new_core_reflectivity", True, "r_c to use"),
    ("core_reflectivity_factor", False, "0 keeps the rendered r_c, 1 uses New Core Reflectivity"),
)

#: Inputs of :func:`compositor_graph`: name -> (vector, compositor group socket, description),
#: in socket order: the renders (LAYERS), the AOVs (AOVS), then the edits.
GRAPH_INPUTS = {
    "original": (True, "Original", "The ordinary render (the original view layer)"),
    "original_alpha": (False, None, None),
    **{key: (True, _socket(key), _layer_description(layer))
       for key, layer in zip(BUFFER_KEYS, LAYERS)},
    **{key: (typ == "COLOR", _socket(key), f"AOV {aov}: {_AOV_MEANING[key]}")
       for aov, typ, key in AOVS},
    **{key: (vector, _socket(key), desc) for key, vector, desc in _EDITS},
}


def compositor_graph(g, i):
    """The recomposite as node math on the passes ``i`` (name -> Expr, see GRAPH_INPUTS).
    Returns Exprs: image (RGB), beta, reflectivity (edited), beta0, r0 (rendered), hazy."""
    # -- normalise the coverage-weighted AOVs (safe divide: 0 outside hazy surfaces) ----------
    mask = i["mask"]
    hazy = g.math("GREATER_THAN", mask, 0.0, label="hazy")
    inv = g.div(1.0, mask, label="1 / mask")
    beta0 = g.mul(i["beta"], inv, label="β (rendered)")
    p = g.clamp(g.mul(i["peak_ratio"], inv), 0.0, 1.0, label="p")
    q = g.clamp(g.mul(i["peak_complement"], inv), 0.0, 1.0, label="q = 1 - p")
    bh0 = g.mul(i["haziness"], inv)
    r0 = g.vmath("SCALE", i["reflectivity"], inv)
    rc0 = g.vmath("SCALE", i["core_reflectivity"], inv)
    # -- edited perceptual parameters ---------------------------------------------------------
    fh, fr = i["haziness_factor"], i["core_reflectivity_factor"]
    bh = g.clamp(g.madd(g.sub(i["new_haziness"], bh0), fh, bh0), 0.0, K.MAX_HAZINESS, label="β_h")
    rc = g.vmath("MULTIPLY_ADD", g.vmath("SUBTRACT", i["new_core_reflectivity"], rc0), fr, rc0)
    rc = g.vclamp01(rc, label="r_c")
    rc_max = g.channel_max(rc)
    # -- Eq. 7 (k̂_h), Eq. 4 (β), Eq. 5 with the core's chroma (r): the material's own forms -----
    _, beta1, omr_hat, r_hat = node_math.haze_terms(g, rc_max, p, q, bh)
    r1 = node_math.reflectivity(g, rc, rc_max, r_hat, omr_hat)[0]
    # -- keep the rendered β, r where nothing is edited; zero outside hazy surfaces ------------
    edited = g.mul(g.math("GREATER_THAN", g.add(fh, fr), 0.0), hazy, label="edited")
    keep = g.sub(hazy, edited)
    beta0 = g.mul(hazy, beta0)
    r0 = g.vmath("SCALE", r0, hazy)
    beta = g.madd(edited, beta1, g.mul(keep, beta0), label="β'")
    r = g.vmath("MULTIPLY_ADD", r1, edited, g.vmath("SCALE", r0, keep), label="r'")
    # -- out = V0 + D(β', r') - D(β, r), D = Σ c_k V_k - V1 (Eq. 11) -----------------------------
    d12 = g.vmath("SUBTRACT", i["narrow_one"], i["narrow_delta"])
    d13 = g.vmath("SUBTRACT", i["wide_delta"], i["narrow_delta"])
    d34 = g.vmath("SUBTRACT", i["wide_one"], i["wide_delta"])

    def halo(b, rr):  # D = r d12 + β (d13 + r d34 - r d12)
        rd12 = g.vmath("MULTIPLY", rr, d12)
        inner = g.vmath("SUBTRACT", g.vmath("MULTIPLY_ADD", rr, d34, d13), rd12)
        return g.vmath("MULTIPLY_ADD", inner, b, rd12)

    image = g.vmath("ADD", i["original"], g.vmath("SUBTRACT", halo(beta, r), halo(beta0, r0)),
                    label="Eq. 11")
    return dict(image=image, beta=beta, reflectivity=r, beta0=beta0, r0=r0, hazy=hazy)


def _as_map(value, shape):
    return np.broadcast_to(np.asarray(value, dtype=np.float32), shape)


def _graph_inputs(passes, haziness, core_reflectivity, haziness_factor, core_reflectivity_factor):
    mask = np.asarray(passes["mask"], dtype=np.float32)
    shape = mask.shape
    rc_new = np.asarray(0.0 if core_reflectivity is None else core_reflectivity, np.float32)
    if rc_new.ndim == 0 or rc_new.shape[-1] != 3:
        rc_new = rc_new[..., None]
    vals = {"mask": mask,
            "new_haziness": _as_map(0.0 if haziness is None else haziness, shape),
            "haziness_factor": _as_map(0.0 if haziness is None else haziness_factor, shape),
            "new_core_reflectivity": np.broadcast_to(rc_new, shape + (3,)),
            "core_reflectivity_factor": _as_map(
                0.0 if core_reflectivity is None else core_reflectivity_factor, shape)}
    for key in ("beta", "peak_ratio", "haziness"):
        vals[key] = np.asarray(passes[key], np.float32)
    q = passes.get("peak_complement")  # renders before that AOV: 1 - p by subtraction
    vals["peak_complement"] = (np.asarray(q, np.float32) if q is not None
                               else (mask - vals["peak_ratio"]).astype(np.float32))
    for key in ("reflectivity", "core_reflectivity"):
        vals[key] = np.asarray(passes[key], np.float32)[..., :3]
    for key in BUFFER_KEYS + ("original",):
        vals[key] = np.asarray(passes[key], np.float32)[..., :3]
    vals["original_alpha"] = np.asarray(passes["original"], np.float32)[..., 3]
    return vals


def _run(passes, *args):
    g = Graph()
    i = {k: g.input(k, vector=v[0]) for k, v in GRAPH_INPUTS.items()}
    return evaluate(compositor_graph(g, i), _graph_inputs(passes, *args))


def recomposite(passes, haziness=None, core_reflectivity=None, *, haziness_factor=1.0,
                core_reflectivity_factor=1.0):
    """Rebuild the image for a new haziness and/or core reflectivity (bpy-free).

    ``passes``: a dict as returned by :func:`passes_from_exr`.  ``haziness`` /
    ``core_reflectivity`` None keep the rendered values; numbers or maps replace them, blended
    by ``*_factor`` (numbers or masks).  Returns (H, W, 4) float32 RGBA, scene-linear, row 0 =
    bottom: the numpy evaluation of the graph the compositor group "Hazy Gloss Recomposite" is
    built from."""
    o = _run(passes, haziness, core_reflectivity, haziness_factor, core_reflectivity_factor)
    return np.concatenate([o["image"], np.asarray(passes["original"], np.float32)[..., 3:4]],
                          axis=-1)
