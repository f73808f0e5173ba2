# SPDX-License-Identifier: GPL-3.0-or-later
"""Edit haziness after the render: the paper's §4.3 compositing route (Eq. 10-11).

With Schlick's Fresnel F = (1-Δ) r + Δ, Δ = (1 - cos θ_d)^5, reflected radiance is linear in
the physical parameters β and r (Eq. 11):

    L = (1-β) (r L0_n + L1_n) + β (r L0_w + L1_w)

where L0 renders the lobe with f (1-Δ) and L1 with f Δ.  Blender's Metallic BSDF in F82 mode
with Edge Tint 1 is pure Schlick, F = F0 + (1-F0) Δ, so F0 = 0 renders L1 and F0 = 1 renders
L0 + L1.  Besides the ordinary render V0 (the "original" view layer), four view layers
"HG Narrow Delta", "HG Narrow One", "HG Wide Delta", "HG Wide One" render V_k = H_k + X: H_k
the camera-visible hazy surfaces with one lobe and one Fresnel variant, X whatever else the
camera sees there (nothing when non-hazy objects are held out, as set up here).  With

    c1 = (1-β)(1-r),  c2 = (1-β) r,  c3 = β (1-r),  c4 = β r        (per channel, Σ c_k = 1)

Eq. 11 is Σ c_k H_k, and the recomposite is

    out = V0 + Σ_k (c_k(β', r') - c_k(β, r)) V_k

Σ_k of the weight differences is 0, so X cancels exactly, pixels that are not edited (or not
hazy: β = r = 0 there) are V0 bit for bit, and an edited hazy pixel becomes
V0 - Eq.11(β, r) + Eq.11(β', r').  The haze mapping (Eq. 7 with the rendered peak ratio p,
Eq. 4-5) turns an edited haziness β_h and core reflectivity r_c into β', r'.

Hazy materials switch per view layer through an Attribute node (type VIEW_LAYER) reading the
custom property ``hg_recomposite`` on the layer (0 or missing = normal), gated by the Light
Path node's Is Camera Ray: secondary bounces always see the normal material, so every layer
gets the same incident light.  Non-hazy objects are linked to a collection held out in the
four layers (Cycles holdout acts on camera rays only: they still cast shadows and appear in
reflections), so they are path traced once, in the original layer.  AOVs on the first layer
hold β, r, p, a hazy mask, β_h and r_c (coverage-weighted; divided by the mask).

This module has two halves:
- bpy-free (numpy): :func:`read_exr`, :func:`passes_from_exr`, :func:`recomposite`,
  :func:`recomposite_parameters` — usable in any pipeline;
- bpy glue (imports bpy lazily): :func:`setup_recomposite`, :func:`clear_recomposite`,
  :func:`ensure_compositor_group` (the compositor node group "Hazy Gloss Recomposite"),
  :func:`build_compositor`.
"""
from __future__ import annotations

import struct
import zlib

import numpy as np

from .core.mapping import haze_intensity

#: View layer custom property read by the hazy materials (Attribute node, type VIEW_LAYER).
PROPERTY = "hg_recomposite"
#: Modes: 0 normal; 1..4 = (lobe, Fresnel) variants for camera rays.
MODES = {"NARROW_DELTA": 1, "NARROW_ONE": 2, "WIDE_DELTA": 3, "WIDE_ONE": 4}
#: View layer per mode (order = c1..c4 in the module docstring).
LAYERS = ("HG Narrow Delta", "HG Narrow One", "HG Wide Delta", "HG Wide One")
#: Pass keys of :func:`recomposite` in the same order (plus "original", the ordinary render).
BUFFER_KEYS = ("narrow_delta", "narrow_one", "wide_delta", "wide_one")
#: Collection of the non-hazy objects, held out (camera rays only) in the four layers.
HOLDOUT_COLLECTION = "HG Recomposite Holdout"
#: AOVs written by hazy materials (name, type, key in the passes dict).
AOVS = (("hg_beta", "VALUE", "beta"), ("hg_reflectivity", "COLOR", "reflectivity"),
        ("hg_peak_ratio", "VALUE", "peak_ratio"), ("hg_mask", "VALUE", "mask"),
        ("hg_haziness", "VALUE", "haziness"),
        ("hg_core_reflectivity", "COLOR", "core_reflectivity"))
#: Haziness is limited to [0, MAX_HAZINESS] (β_h = 1 is the degenerate single-wide-lobe case).
MAX_HAZINESS = 0.9999

STAMP = "hazy_gloss_recomposite"  # on materials and on the scene
NODE_PREFIX = "HG"
RC_PREFIX = "HG RC"  # names of the nodes this module adds to material and compositor trees
GROUP_NAME = "Hazy Gloss Recomposite"
GROUP_VERSION = 2


# ============================================================================================
# bpy-free: OpenEXR reading
# ============================================================================================

_EXR_MAGIC = 20000630
_LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16}  # NONE, RLE, ZIPS, ZIP
_PIXEL_TYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}


def _exr_header(data, pos):
    attrs = {}
    while True:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode("latin-1")
        pos = end + 1
        if not name:
            return attrs, pos
        end = data.index(b"\0", pos)
        typ = data[pos:end].decode("latin-1")
        pos = end + 1
        (size,) = struct.unpack_from("<i", data, pos)
        pos += 4
        attrs[name] = (typ, data[pos:pos + size])
        pos += size


def _exr_channels(raw):
    out, p = [], 0
    while raw[p] != 0:
        end = raw.index(b"\0", p)
        name = raw[p:end].decode("utf-8")
        (ptype,) = struct.unpack_from("<i", raw, end + 1)
        xs, ys = struct.unpack_from("<ii", raw, end + 9)
        if (xs, ys) != (1, 1):
            raise ValueError(f"EXR channel {name!r} is subsampled; not supported")
        out.append((name, ptype))
        p = end + 17
    return out


def _predictor_deinterleave(raw):
    """Undo OpenEXR's ZIP/RLE preprocessing: byte delta predictor, then two-half interleave."""
    t = np.frombuffer(raw, dtype=np.uint8).astype(np.int64)
    t[1:] -= 128
    t = (np.cumsum(t) & 0xFF).astype(np.uint8)
    half = (t.size + 1) // 2
    out = np.empty(t.size, np.uint8)
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out.tobytes()


def _rle_decode(raw):
    out = bytearray()
    i, n = 0, len(raw)
    while i < n:
        count = struct.unpack_from("<b", raw, i)[0]
        i += 1
        if count < 0:
            out += raw[i:i - count]
            i -= count
        else:
            out += raw[i:i + 1] * (count + 1)
            i += 1
    return bytes(out)


def read_exr(path):
    """Every channel of a scanline OpenEXR file (single- or multi-part) as float32 arrays.

    Returns ``{channel name: (H, W) float32}`` with full names as Blender writes them, e.g.
    ``"HG Narrow Delta.Combined.R"`` or ``"HG Narrow Delta.hg_beta.X"``.  Row 0 is the BOTTOM
    row (Blender's pixel order, like ``Image.pixels``).  Compression NONE, RLE, ZIPS and ZIP
    (Blender's default) are supported; lossy codecs (PIZ, PXR24, B44, DWA) are not — and would
    break an exact recomposite anyway."""
    with open(path, "rb") as fh:
        data = fh.read()
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != _EXR_MAGIC:
        raise ValueError(f"{path}: not an OpenEXR file")
    if version & 0x200 or version & 0x800 and not version & 0x1000:
        raise ValueError(f"{path}: tiled or deep EXR files are not supported")
    multipart = bool(version & 0x1000)
    pos = 8
    headers = []
    while True:
        attrs, pos = _exr_header(data, pos)
        headers.append(attrs)
        if not multipart:
            break
        if data[pos] == 0:
            pos += 1
            break
    tables = []
    for attrs in headers:
        comp = attrs["compression"][1][0]
        if comp not in _LINES_PER_CHUNK:
            raise ValueError(f"{path}: EXR compression {comp} not supported (use ZIP or NONE)")
        if attrs.get("type", ("", b"scanlineimage"))[1].rstrip(b"\0") != b"scanlineimage":
            raise ValueError(f"{path}: only scanline EXR parts are supported")
        y0, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])[1::2]
        n = (y1 - y0 + _LINES_PER_CHUNK[comp]) // _LINES_PER_CHUNK[comp]
        tables.append(struct.unpack_from(f"<{n}Q", data, pos))
        pos += 8 * n

    out = {}
    for attrs, offsets in zip(headers, tables):
        channels = _exr_channels(attrs["channels"][1])
        comp = attrs["compression"][1][0]
        x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])
        w, h = x1 - x0 + 1, y1 - y0 + 1
        lines = _LINES_PER_CHUNK[comp]
        row_bytes = sum(_PIXEL_TYPES[t].itemsize for _, t in channels) * w
        res = {name: np.empty((h, w), np.float32) for name, _ in channels}
        for off in offsets:
            if multipart:
                off += 4  # part number
            y, size = struct.unpack_from("<ii", data, off)
            block = data[off + 8:off + 8 + size]
            n = min(lines, y1 - y + 1)
            if size < row_bytes * n:  # stored uncompressed when compression would not help
                if comp in (2, 3):
                    block = _predictor_deinterleave(zlib.decompress(block))
                elif comp == 1:
                    block = _predictor_deinterleave(_rle_decode(block))
            q = 0
            for row in range(n):
                for name, t in channels:
                    dt = _PIXEL_TYPES[t]
                    res[name][y - y0 + row] = np.frombuffer(block, dt, w, q)
                    q += dt.itemsize * w
        for name, arr in res.items():
            out[name] = arr[::-1].copy()  # file order is top row first
    return out


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
    ``core_reflectivity`` (H, W, 3).  Row 0 = bottom row."""
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
        return np.stack([ch[n] for n in names[:3]] + [a], axis=-1)

    passes = {key: rgba(f"{layer}.Combined") for key, layer in zip(BUFFER_KEYS, layers)}
    passes["original"] = rgba(f"{original}.Combined")
    first = layers[0]
    for aov, typ, key in AOVS:
        if typ == "VALUE":
            name = next((f"{first}.{aov}.{c}" for c in ("X", "V", "R", "Y")
                         if f"{first}.{aov}.{c}" in ch), None)
            if name is None:
                raise KeyError(f"{path}: missing AOV {aov} on layer {first!r}")
            passes[key] = ch[name]
        else:
            passes[key] = rgba(f"{first}.{aov}")[..., :3]
    return passes


# ============================================================================================
# bpy-free: the recomposite itself (Eq. 7, 4, 5 per pixel, then Eq. 11)
# ============================================================================================


def _as_map(value, shape, dtype):
    return np.broadcast_to(np.asarray(value, dtype=dtype), shape)


def recomposite_parameters(passes, haziness=None, core_reflectivity=None, *,
                           haziness_factor=1.0, core_reflectivity_factor=1.0):
    """Per-pixel (β, r, hazy) for edited perceptual parameters.

    haziness             new β_h: a number or an (H, W) map; None keeps the rendered one
    core_reflectivity    new r_c: a number (grey), an RGB triple or an (H, W, 3) map; None keeps
    *_factor             0..1 (number or (H, W) mask): blend from the rendered value to the new
                         one (a mask edits part of the image)
    Returns (β', r', β, r, hazy): the edited and the rendered β (H, W) and r (H, W, 3), all 0
    outside hazy surfaces, and the hazy mask (H, W) bool.  Where both factors are 0 the edited
    values are the rendered ones exactly."""
    mask = np.asarray(passes["mask"], dtype=np.float32)
    shape = mask.shape
    hazy = mask > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(hazy, 1.0 / mask, 0.0).astype(np.float32)
    beta0 = np.asarray(passes["beta"], np.float32) * inv
    r0 = np.asarray(passes["reflectivity"], np.float32)[..., :3] * inv[..., None]
    p = np.clip(np.asarray(passes["peak_ratio"], np.float32) * inv, 0.0, 1.0)
    bh0 = np.asarray(passes["haziness"], np.float32) * inv
    rc0 = np.asarray(passes["core_reflectivity"], np.float32)[..., :3] * inv[..., None]

    fh = _as_map(0.0 if haziness is None else haziness_factor, shape, np.float32)
    fr = _as_map(0.0 if core_reflectivity is None else core_reflectivity_factor, shape, np.float32)
    bh_new = _as_map(0.0 if haziness is None else haziness, shape, np.float32)
    rc_new = np.asarray(0.0 if core_reflectivity is None else core_reflectivity, np.float32)
    if rc_new.ndim == 0 or rc_new.shape[-1] != 3:
        rc_new = rc_new[..., None]
    rc_new = np.broadcast_to(rc_new, shape + (3,))

    bh = np.clip(bh0 + fh * (bh_new - bh0), 0.0, MAX_HAZINESS)
    rc = np.clip(rc0 + fr[..., None] * (rc_new - rc0), 0.0, 1.0)
    q = (1.0 - p).astype(np.float32)
    rc_max = rc.max(axis=-1)
    kh, beta1 = haze_intensity(rc_max, p, q, bh)  # Eq. 7 and Eq. 4
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.where(rc_max > 0, 1.0 + q * kh / rc_max, 1.0)
    r1 = np.minimum(rc * gain[..., None], 1.0)  # Eq. 5 with the core's chroma

    edited = hazy & ((fh > 0) | (fr > 0))
    beta0 = np.where(hazy, beta0, 0.0).astype(np.float32)
    r0 = np.where(hazy[..., None], r0, 0.0).astype(np.float32)
    beta = np.where(edited, beta1, beta0).astype(np.float32)
    r = np.where(edited[..., None], r1, r0).astype(np.float32)
    return beta, r, beta0, r0, hazy


def _halo_terms(v, beta, r):
    """D(β, r) = Σ c_k V_k - V1 = r (V2-V1) + β ((V3-V1) + r (V4-V3) - r (V2-V1)), RGB."""
    v1, v2, v3, v4 = (x[..., :3] for x in v)
    b = beta[..., None]
    d12 = v2 - v1
    return r * d12 + b * ((r * (v4 - v3) + (v3 - v1)) - r * d12)


def combine(passes, beta, r, beta0, r0):
    """out = V0 + Σ_k (c_k(β, r) - c_k(β0, r0)) V_k (module docstring); (H, W, 4) RGBA with the
    original's alpha."""
    v = [np.asarray(passes[k], np.float32) for k in BUFFER_KEYS]
    v0 = np.asarray(passes["original"], np.float32)
    delta = (_halo_terms(v, np.asarray(beta, np.float32), np.asarray(r, np.float32))
             - _halo_terms(v, np.asarray(beta0, np.float32), np.asarray(r0, np.float32)))
    out = v0.copy()
    out[..., :3] = v0[..., :3] + delta
    return out


def recomposite(passes, haziness=None, core_reflectivity=None, *, haziness_factor=1.0,
                core_reflectivity_factor=1.0):
    """Rebuild the image for a new haziness and/or core reflectivity (bpy-free).

    ``passes``: a dict as returned by :func:`passes_from_exr`.  ``haziness`` /
    ``core_reflectivity`` None keep the rendered values; numbers or maps replace them, blended
    by ``*_factor`` (numbers or masks).  Returns (H, W, 4) float32 RGBA, scene-linear, row 0 =
    bottom.  Same computation as the compositor group "Hazy Gloss Recomposite"."""
    beta, r, beta0, r0, _ = recomposite_parameters(
        passes, haziness, core_reflectivity, haziness_factor=haziness_factor,
        core_reflectivity_factor=core_reflectivity_factor)
    return combine(passes, beta, r, beta0, r0)


# ============================================================================================
# bpy glue: materials
# ============================================================================================


class Unsupported(ValueError):
    """A hazy material that cannot render in recomposite mode (it is then left as it is and
    treated as non-hazy: it appears unchanged in the composite)."""


def _pkg():
    from . import api
    from .node_groups import builder, groups, mapping_graph
    from .utils import conventions
    return api, builder, groups, mapping_graph, conventions


def _surface_link(tree, out):
    sock = out.inputs["Surface"]
    if not sock.is_linked:
        return None
    return sock.links[0].from_socket


def _schlick_distribution(dist):
    if dist == "ASHIKHMIN_SHIRLEY":
        raise Unsupported("Ashikhmin-Shirley lobes have no Metallic (Schlick) counterpart")
    # Multiscatter GGX scales each lobe by a factor that depends non-linearly on F0
    # (Cycles' microfacet_ggx_preserve_energy): Eq. 11 would not hold.  Single-scatter GGX.
    return "GGX" if dist == "MULTI_GGX" else dist


def _constant_values(p, api, groups, conventions):
    """Lobe parameters and AOV values as Python constants (lean materials)."""
    m = api.map_parameters(p)
    dist = _schlick_distribution(p["distribution"])
    rough = max(p["roughness"], groups.min_roughness(dist))
    f = lambda x: float(np.asarray(x))  # noqa: E731
    wx, wy = (f(a) for a in m.alpha_wide)
    r_w, ratio, swap = conventions.lobe_from_alpha(wx, wy)
    aniso = p["anisotropy"] > 0.0 or p["haze_extent"][0] != p["haze_extent"][1]
    narrow = dict(roughness=rough, anisotropy=None, rotation=None)
    wide = dict(roughness=f(r_w), anisotropy=None, rotation=None)
    if aniso:
        narrow.update(anisotropy=p["anisotropy"], rotation=p["rotation"])
        wide.update(anisotropy=f(conventions.metallic_anisotropy(ratio)),
                    rotation=p["rotation"] + 0.25 * bool(swap))
    return dict(distribution=dist, narrow=narrow, wide=wide, anisotropic=aniso,
                beta=f(m.beta), reflectivity=tuple(float(x) for x in m.reflectivity),
                peak_ratio=f(m.peak_ratio), haziness=f(m.haziness),
                core_reflectivity=tuple(float(x) for x in m.core_reflectivity))


_GROUP_INPUTS = {"core_reflectivity": "Core Reflectivity", "edge_tint": "Edge Tint",
                 "roughness": "Roughness", "haziness": "Haziness", "anisotropy": "Anisotropy",
                 "rotation": "Rotation", "smoothness": "Smoothness"}


def _socket_values(tree, p, tb, groups, mapping_graph):
    """Lobe parameters as sockets, from the inputs of an in-shader group node (textures kept)."""
    node = tree.nodes.get(f"{NODE_PREFIX} Hazy Gloss")
    if node is None or node.bl_idname != "ShaderNodeGroup":
        return None
    aniso = "Anisotropy" in node.inputs
    smooth = "Smoothness" in node.inputs

    def src(name):
        sock = node.inputs.get(name)
        if sock is None:
            return None
        if sock.is_linked:
            return sock.links[0].from_socket
        v = sock.default_value
        return tuple(v)[:3] if hasattr(v, "__len__") else float(v)

    s = {key: src(name) for key, name in _GROUP_INPUTS.items()}
    s["haze_extent_x"] = src("Haze Extent X" if aniso else "Haze Extent")
    s["haze_extent_y"] = src("Haze Extent Y") if aniso else None
    dist = _schlick_distribution(p["distribution"])
    # kind DIELECTRIC: the anisotropy outputs use the Metallic convention (our lobes are Metallic)
    m = mapping_graph.build_mapping(tb, s, kind="DIELECTRIC", anisotropic=aniso, smooth=smooth,
                                    min_roughness=groups.min_roughness(dist),
                                    distribution=p["distribution"])
    narrow = dict(roughness=m["roughness"], anisotropy=None, rotation=None)
    wide = dict(roughness=m["roughness_wide"], anisotropy=None, rotation=None)
    if aniso:
        narrow.update(anisotropy=s["anisotropy"], rotation=s["rotation"])
        wide.update(anisotropy=m["anisotropy_wide"], rotation=m["rotation_wide"])
    tangent = node.inputs["Tangent"].links[0].from_socket if aniso and node.inputs["Tangent"].is_linked else None
    normal = node.inputs["Normal"].links[0].from_socket if node.inputs["Normal"].is_linked else None
    base = src("Base Color") if "Base Color" in node.inputs else None
    return dict(distribution=dist, narrow=narrow, wide=wide, anisotropic=aniso,
                beta=m["beta"], reflectivity=m["reflectivity"], peak_ratio=m["peak_ratio"],
                haziness=tb.clamp(s["haziness"], 0.0, mapping_graph.MAX_HAZINESS),
                core_reflectivity=s["core_reflectivity"], tangent=tangent, normal=normal,
                base_color=base)


def _build_schlick(tree, p, v, tb):
    """The recomposite-mode hazy material: Eq. 1 with two Metallic F82 lobes (Schlick, F0 = r),
    switched per view layer for camera rays, and the AOVs."""
    att = tb.node("ShaderNodeAttribute", name="RC Mode", label=f"View layer [{PROPERTY}]", depth=0,
                  attribute_type="VIEW_LAYER", attribute_name=PROPERTY)
    lp = tb.node("ShaderNodeLightPath", name="RC Light Path", depth=0)
    mode = tb.mul(att.outputs["Fac"], lp.outputs["Is Camera Ray"], label="mode (camera rays)")
    normal = tb.less(mode, 0.5, label="normal")
    wide = tb.math("GREATER_THAN", mode, 2.5, label="wide lobe only")
    one = tb.add(tb.math("COMPARE", mode, 2.0, 0.5), tb.math("COMPARE", mode, 4.0, 0.5),
                 label="F = 1")
    fac = tb.madd(normal, v["beta"], wide, label="mix factor")
    f0 = tb.vmath("MULTIPLY_ADD", v["reflectivity"], normal, one, label="F0")

    def lobe(which, params, depth):
        n = tb.node("ShaderNodeBsdfMetallic", name=f"RC {which} lobe",
                    label=f"Schlick {which.lower()} lobe", depth=depth)
        n.distribution = v["distribution"]
        n.fresnel_type = "F82"  # F = F0 + (1 - F0)(1 - cos θd)^5 - b ..., b = 0 at Edge Tint 1
        tb.link(f0, n.inputs["Base Color"])
        tb.feed(n.inputs["Edge Tint"], (1.0, 1.0, 1.0))
        tb.feed(n.inputs["Roughness"], params["roughness"])
        if params["anisotropy"] is not None:
            tb.feed(n.inputs["Anisotropy"], params["anisotropy"])
            tb.feed(n.inputs["Rotation"], params["rotation"])
            if v.get("tangent") is not None:
                tb.link(v["tangent"], n.inputs["Tangent"])
        if v.get("normal") is not None:
            tb.link(v["normal"], n.inputs["Normal"])
        return n

    depth = 2 + max(tb._depth.values(), default=0)
    n_lobe = lobe("Narrow", v["narrow"], depth)
    w_lobe = lobe("Wide", v["wide"], depth)
    mix = tb.node("ShaderNodeMixShader", name="RC Lobe mix", label="Eq. 1 (Schlick)", depth=depth + 1)
    tb.link(fac, mix.inputs[0])
    tb.link(n_lobe.outputs[0], mix.inputs[1])
    tb.link(w_lobe.outputs[0], mix.inputs[2])
    bsdf = mix.outputs[0]
    base = v.get("base_color")
    if base is not None and (hasattr(base, "node") or max(base) > 0.0):
        diff = tb.node("ShaderNodeBsdfDiffuse", name="RC Base", label="Base (diffuse)", depth=depth)
        tb.feed(diff.inputs["Color"], base)
        if v.get("normal") is not None:
            tb.link(v["normal"], diff.inputs["Normal"])
        add = tb.node("ShaderNodeAddShader", name="RC Base add", depth=depth + 2)
        tb.link(diff.outputs[0], add.inputs[0])
        tb.link(bsdf, add.inputs[1])
        bsdf = add.outputs[0]

    values = {"beta": v["beta"], "reflectivity": v["reflectivity"], "peak_ratio": v["peak_ratio"],
              "mask": 1.0, "haziness": v["haziness"], "core_reflectivity": v["core_reflectivity"]}
    for aov, typ, key in AOVS:
        n = tb.node("ShaderNodeOutputAOV", name=f"RC AOV {aov}", depth=depth + 3)
        n.aov_name = aov
        tb.feed(n.inputs["Value" if typ == "VALUE" else "Color"], values[key])
    return bsdf


def convert_material(mat):
    """Switch one hazy material to recomposite mode (idempotent).  Raises Unsupported."""
    api, builder, groups, mapping_graph, conventions = _pkg()
    p = api.read_parameters(mat)
    if p is None:
        raise Unsupported(f"{mat.name!r} is not a hazy material")
    if mat.library is not None:
        raise Unsupported(f"{mat.name!r} is linked from a library")
    restore_material(mat)
    tree = mat.node_tree
    out = api._output_node(tree)
    original = _surface_link(tree, out)
    tb = builder.TreeBuilder(tree, prefix=NODE_PREFIX, x0=600.0, y0=-900.0)
    notes = []
    if p["kind"] == "DIELECTRIC" and p["transmission"] > 0.0:
        notes.append("transmission is not handled in recomposite mode (rendered opaque)")
    if p["distribution"] == "MULTI_GGX":
        notes.append("multiscatter GGX rendered as single-scatter GGX (Eq. 11 needs linearity in F0)")
    try:
        v = _socket_values(tree, p, tb, groups, mapping_graph) if p["shader_mapping"] else None
        if v is None:
            v = _constant_values(p, api, groups, conventions)
            v["base_color"] = p["base_color"] if p["kind"] == "DIELECTRIC" else None
            if v["anisotropic"]:  # the lean tree's explicit tangent (api._tangent)
                t = tree.nodes.get(f"{NODE_PREFIX} Tangent")
                if t is None:
                    t = api._tangent(tb, p, 0).node
                v["tangent"] = t.outputs[0]
        bsdf = _build_schlick(tree, p, v, tb)
    except Exception:
        for n in tb.created:
            tree.nodes.remove(n)
        raise
    # every node we add carries the RC prefix: restore_material removes exactly those, and
    # api.apply (prefix "HG ") removes them too when the material is edited
    for n in tb.created:
        if not n.name.startswith(RC_PREFIX + " "):
            n.name = f"{RC_PREFIX} {n.name}"
    tree.links.new(bsdf, out.inputs["Surface"])
    mat[STAMP] = {"version": GROUP_VERSION,
                  "surface_node": original.node.name if original is not None else "",
                  "surface_socket": original.identifier if original is not None else ""}
    return notes


def restore_material(mat):
    """Leave recomposite mode: remove the RC nodes and relink the original surface."""
    tree = mat.node_tree
    if tree is None:
        return False
    ours = [n for n in tree.nodes if n.name.startswith(RC_PREFIX + " ")]
    stamp = mat.get(STAMP)
    if stamp is None and not ours:
        return False
    for n in ours:
        tree.nodes.remove(n)
    if stamp is not None:
        node = tree.nodes.get(stamp.get("surface_node", ""))
        if node is not None:
            sock = next((s for s in node.outputs if s.identifier == stamp.get("surface_socket")), None)
            outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
            out = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
            if sock is not None and out is not None:
                tree.links.new(sock, out.inputs["Surface"])
        del mat[STAMP]
    return True


def is_recomposite_material(mat):
    return mat is not None and STAMP in mat


# ============================================================================================
# bpy glue: view layers and output
# ============================================================================================

_LAYER_ATTRS = ("samples", "use_solid", "use_sky", "use_ao", "use_strand", "use_volumes",
                "use_motion_blur", "pass_alpha_threshold", "material_override", "world_override")


def _copy_layer_collections(src, dst):
    for attr in ("exclude", "holdout", "indirect_only"):
        if hasattr(src, attr):
            setattr(dst, attr, getattr(src, attr))
    by_name = {c.name: c for c in dst.children}
    for child in src.children:
        if child.name in by_name:
            _copy_layer_collections(child, by_name[child.name])


def _layer_collection(layer, name):
    stack = [layer.layer_collection]
    while stack:
        lc = stack.pop()
        if lc.name == name:
            return lc
        stack.extend(lc.children)
    return None


def _new_layer(scene, template, name, mode, aovs):
    layer = scene.view_layers.get(name) or scene.view_layers.new(name)
    for attr in _LAYER_ATTRS:
        if hasattr(template, attr):
            try:
                setattr(layer, attr, getattr(template, attr))
            except (AttributeError, TypeError):
                pass
    _copy_layer_collections(template.layer_collection, layer.layer_collection)
    layer.use = True
    layer.use_pass_combined = True
    layer.use_freestyle = False
    if hasattr(layer, "cycles") and hasattr(layer.cycles, "use_denoising"):
        layer.cycles.use_denoising = False  # the buffers must stay linear in the radiance
    layer[PROPERTY] = float(mode)
    existing = {a.name for a in layer.aovs}
    if aovs:
        for aov, typ, _ in AOVS:
            if aov not in existing:
                a = layer.aovs.add()
                a.name = aov
                a.type = typ
    return layer


def _set_multilayer_exr(scene, codec="ZIP"):
    s = scene.render.image_settings
    if hasattr(s, "media_type"):  # 5.0
        s.media_type = "MULTI_LAYER_IMAGE"
    s.file_format = "OPEN_EXR_MULTILAYER"
    s.color_depth = "32"
    s.exr_codec = codec


_GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"}


def _scan(scene):
    """(hazy materials, names of objects that show a hazy material — directly, through geometry
    nodes, or through what they instance) from the evaluated depsgraph of the context's view
    layer when ``scene`` is the context scene, else from the objects' own materials."""
    import bpy
    from . import api
    depsgraph = bpy.context.evaluated_depsgraph_get() if bpy.context.scene == scene else None
    mats, objects = set(), set()

    def materials(ob):
        out = [slot.material for slot in getattr(ob, "material_slots", ())]
        out += list(getattr(getattr(ob, "data", None), "materials", ()) or ())
        return [m.original for m in out if m is not None]

    if depsgraph is not None:
        for inst in depsgraph.object_instances:
            hazy = [m for m in materials(inst.object) if api.is_hazy(m)]
            if hazy:
                mats.update(hazy)
                objects.add(inst.object.original.name)
                if inst.is_instance and inst.parent is not None:
                    objects.add(inst.parent.original.name)
    for ob in scene.objects:  # unevaluated fallback (and objects hidden from the depsgraph)
        hazy = [m for m in materials(ob) if api.is_hazy(m)]
        if hazy:
            mats.update(hazy)
            objects.add(ob.name)
    return sorted(mats, key=lambda m: m.name), objects


def hazy_materials(scene):
    """Hazy materials shown by the objects of ``scene``."""
    return _scan(scene)[0]


def _holdout_collection(scene, hazy_objects):
    """A collection of the scene's non-hazy objects (linked, not moved), created anew."""
    import bpy
    coll = bpy.data.collections.get(HOLDOUT_COLLECTION)
    if coll is None:
        coll = bpy.data.collections.new(HOLDOUT_COLLECTION)
    for ob in list(coll.objects):
        coll.objects.unlink(ob)
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    for ob in scene.objects:
        if ob.type in _GEOMETRY_TYPES and ob.name not in hazy_objects \
                and ob.instance_type in ("NONE", "VERTS", "FACES") and not ob.particle_systems \
                and ob.name not in coll.objects:
            if ob.instance_type != "NONE" and ob.children:
                continue  # instances children: they may be hazy
            coll.objects.link(ob)
    return coll


def setup_recomposite(scene, *, template=None, compositor=True, holdout=True, exr_codec="ZIP"):
    """Set ``scene`` up so one render yields everything the recomposite needs.

    - every hazy material of the scene switches to recomposite mode (Schlick lobes, AOVs);
    - ``template`` (default: the first enabled view layer) stays the ordinary render, V0;
    - four view layers ``LAYERS`` are created from it, the first one with the AOVs;
    - ``holdout``: non-hazy objects are linked to the collection ``HOLDOUT_COLLECTION``, held
      out in the four layers (camera rays only), so only hazy surfaces cost render time there.
      Anything left visible (e.g. non-hazy slots of a hazy object) cancels exactly anyway;
    - output: multilayer OpenEXR, 32-bit float, lossless ``exr_codec``;
    - ``compositor``: the scene compositor gets the "Hazy Gloss Recomposite" group fed by Render
      Layers nodes (edit its inputs after the render; the output is the recomposite).
    Returns a report dict: converted, skipped ({name: reason}), notes, layers, template, held_out."""
    if scene.render.engine != "CYCLES":
        raise ValueError("the recomposite passes need Cycles (the per-layer switch relies on "
                         "Cycles' view-layer attributes and holdout semantics)")
    state = scene.get(STAMP)
    state = state.to_dict() if state is not None else {}
    if template is None:
        name = state.get("template")
        template = scene.view_layers.get(name) if name else None
    if template is None:
        template = next((vl for vl in scene.view_layers if vl.use and vl.name not in LAYERS), None) \
            or next(vl for vl in scene.view_layers if vl.name not in LAYERS)
    if template.name in LAYERS:
        raise ValueError(f"the original layer cannot be one of {LAYERS}")
    s = scene.render.image_settings
    if not state:
        state = {"file_format": s.file_format, "color_depth": s.color_depth,
                 "exr_codec": s.exr_codec, "use_single_layer": bool(scene.render.use_single_layer),
                 "media_type": getattr(s, "media_type", ""), "template_use": bool(template.use)}
    state["template"] = template.name

    mats, hazy_objects = _scan(scene)
    report = {"converted": [], "skipped": {}, "notes": {}, "layers": list(LAYERS),
              "template": template.name, "held_out": []}
    for mat in mats:
        try:
            notes = convert_material(mat)
        except Unsupported as exc:
            report["skipped"][mat.name] = str(exc)
            continue
        report["converted"].append(mat.name)
        if notes:
            report["notes"][mat.name] = notes

    coll = _holdout_collection(scene, hazy_objects) if holdout else None
    for vl in scene.view_layers:  # the holdout acts in our four layers only
        lc = _layer_collection(vl, HOLDOUT_COLLECTION)
        if lc is not None:
            lc.holdout = False
    for i, (layer_name, mode) in enumerate(zip(LAYERS, (1, 2, 3, 4))):
        layer = _new_layer(scene, template, layer_name, mode, aovs=(i == 0))
        lc = _layer_collection(layer, HOLDOUT_COLLECTION)
        if lc is not None:
            lc.exclude = False
            lc.holdout = coll is not None
    if coll is not None:
        report["held_out"] = sorted(ob.name for ob in coll.objects)
    template.use = True
    scene.render.use_single_layer = False
    _set_multilayer_exr(scene, exr_codec)
    scene[STAMP] = state
    if compositor:
        build_compositor(scene)
    return report


def clear_recomposite(scene):
    """Undo :func:`setup_recomposite`: materials, view layers, holdout collection, output
    settings, compositor nodes."""
    import bpy
    for mat in bpy.data.materials:
        restore_material(mat)
    state = scene.get(STAMP)
    state = state.to_dict() if state is not None else {}
    for name in LAYERS:
        layer = scene.view_layers.get(name)
        if layer is not None and len(scene.view_layers) > 1:
            scene.view_layers.remove(layer)
    coll = bpy.data.collections.get(HOLDOUT_COLLECTION)
    if coll is not None:
        bpy.data.collections.remove(coll)
    template = scene.view_layers.get(state.get("template", ""))
    if template is not None:
        template.use = state.get("template_use", True)
    s = scene.render.image_settings
    if state:
        if state.get("media_type") and hasattr(s, "media_type"):
            s.media_type = state["media_type"]
        for attr in ("file_format", "color_depth", "exr_codec"):
            try:
                setattr(s, attr, state[attr])
            except (KeyError, TypeError, AttributeError):
                pass
        scene.render.use_single_layer = state.get("use_single_layer", False)
        del scene[STAMP]
    from .blender import compat
    tree = compat.compositor_tree(scene, create=False)
    if tree is not None:
        for n in [n for n in tree.nodes if n.name.startswith(RC_PREFIX + " ")]:
            tree.nodes.remove(n)


# ============================================================================================
# bpy glue: compositor (the version differences are in blender/compat.py)
# ============================================================================================


def _compositor_builder(tree):
    """A TreeBuilder whose scalar math and colour split use the compositor's nodes."""
    from .node_groups.builder import TreeBuilder

    from .blender import compat
    math_id = compat.compositor_math_node()

    class CompositorBuilder(TreeBuilder):
        MATH_NODE = math_id

        def separate(self, colour):
            n = self.node("CompositorNodeSeparateColor", depth=1 + self.depth_of(colour))
            self.feed(n.inputs[0], colour)
            return tuple(n.outputs[:4])

        def combine(self, r, g, b, a):
            d = 1 + max(self.depth_of(x) for x in (r, g, b, a))
            n = self.node("CompositorNodeCombineColor", depth=d)
            for sock, x in zip(n.inputs[:4], (r, g, b, a)):
                self.feed(sock, x)
            return n.outputs[0]

    return CompositorBuilder(tree, prefix=NODE_PREFIX)


_GROUP_SOCKETS = (
    # name, type, default, description
    ("Original", "NodeSocketColor", None, "The ordinary render (the original view layer)"),
    ("Narrow Delta", "NodeSocketColor", None, "Layer 'HG Narrow Delta': narrow lobe, F = Δ (L1_n)"),
    ("Narrow One", "NodeSocketColor", None, "Layer 'HG Narrow One': narrow lobe, F = 1 (L0_n + L1_n)"),
    ("Wide Delta", "NodeSocketColor", None, "Layer 'HG Wide Delta': wide lobe, F = Δ (L1_w)"),
    ("Wide One", "NodeSocketColor", None, "Layer 'HG Wide One': wide lobe, F = 1 (L0_w + L1_w)"),
    ("Beta", "NodeSocketFloat", 0.0, "AOV hg_beta: rendered β"),
    ("Reflectivity", "NodeSocketColor", None, "AOV hg_reflectivity: rendered r"),
    ("Peak Ratio", "NodeSocketFloat", 1.0, "AOV hg_peak_ratio: p"),
    ("Mask", "NodeSocketFloat", 0.0, "AOV hg_mask: hazy coverage"),
    ("Haziness", "NodeSocketFloat", 0.0, "AOV hg_haziness: rendered β_h"),
    ("Core Reflectivity", "NodeSocketColor", None, "AOV hg_core_reflectivity: rendered r_c"),
    ("New Haziness", "NodeSocketFloat", 0.5, "β_h to use (a value or a map)"),
    ("Haziness Factor", "NodeSocketFloat", 0.0, "0 keeps the rendered β_h, 1 uses New Haziness "
     "(a mask edits part of the image)"),
    ("New Core Reflectivity", "NodeSocketColor", (0.5, 0.5, 0.5, 1.0), "r_c to use"),
    ("Core Reflectivity Factor", "NodeSocketFloat", 0.0, "0 keeps the rendered r_c, 1 uses New "
     "Core Reflectivity"),
)


def _build_group(ng):
    for n in list(ng.nodes):
        ng.nodes.remove(n)
    ng.interface.clear()
    for name, typ, default, desc in _GROUP_SOCKETS:
        s = ng.interface.new_socket(name=name, in_out="INPUT", socket_type=typ)
        s.description = desc
        if default is not None:
            s.default_value = default
        if name.endswith("Factor"):
            s.min_value, s.max_value = 0.0, 1.0
    ng.interface.new_socket(name="Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    gin = ng.nodes.new("NodeGroupInput")
    gin.location = (-400, 0)
    gout = ng.nodes.new("NodeGroupOutput")
    tb = _compositor_builder(ng)
    i = gin.outputs

    # -- normalise the coverage-weighted AOVs ------------------------------------------------
    mask = i["Mask"]
    hazy = tb.math("GREATER_THAN", mask, 0.0, label="hazy")
    inv = tb.div(1.0, mask, label="1 / mask")  # safe divide: 0 outside hazy surfaces
    beta0 = tb.mul(i["Beta"], inv, label="β (rendered)")
    p = tb.clamp(tb.mul(i["Peak Ratio"], inv), 0.0, 1.0, label="p")
    q = tb.sub(1.0, p, label="q = 1 - p")
    bh0 = tb.mul(i["Haziness"], inv)
    r0 = [tb.mul(c, inv) for c in tb.separate(i["Reflectivity"])[:3]]
    rc0 = [tb.mul(c, inv) for c in tb.separate(i["Core Reflectivity"])[:3]]
    rc_new = tb.separate(i["New Core Reflectivity"])[:3]

    # -- edited perceptual parameters ---------------------------------------------------------
    fh, fr = i["Haziness Factor"], i["Core Reflectivity Factor"]
    bh = tb.clamp(tb.madd(tb.sub(i["New Haziness"], bh0), fh, bh0), 0.0, MAX_HAZINESS, label="β_h")
    rc = [tb.clamp(tb.madd(tb.sub(n, o), fr, o), 0.0, 1.0) for n, o in zip(rc_new, rc0)]
    rc_max = tb.maximum(tb.maximum(rc[0], rc[1]), rc[2], label="r̂_c")
    omr = tb.sub(1.0, rc_max)

    # -- Eq. 7 (k̂_h), Eq. 4 (β, stable form), Eq. 5 with the core's chroma (r) ------------------
    upper = tb.less(p, rc_max, label="r̂_c > p")
    kh = tb.mul(bh, tb.select(upper, tb.div(omr, q), tb.div(rc_max, p)), label="k̂_h (Eq. 7)")
    sigma = tb.select(upper, tb.div(tb.mul(rc_max, q), omr), p)
    beta1 = tb.clamp(tb.div(bh, tb.madd(q, bh, sigma)), 0.0, 1.0, label="β (Eq. 4)")
    gain = tb.add(1.0, tb.div(tb.mul(q, kh), rc_max), label="r̂ / r̂_c")
    r1 = [tb.minimum(tb.mul(c, gain), 1.0) for c in rc]

    # -- keep the rendered β, r where nothing is edited; zero outside hazy surfaces ------------
    edited = tb.mul(tb.math("GREATER_THAN", tb.add(fh, fr), 0.0), hazy, label="edited")
    keep = tb.sub(hazy, edited)  # hazy and not edited
    beta0 = tb.mul(hazy, beta0, label="β (rendered)")
    r0 = [tb.mul(hazy, c) for c in r0]
    beta = tb.madd(edited, beta1, tb.mul(keep, beta0), label="β'")
    r = [tb.madd(edited, a, tb.mul(keep, b)) for a, b in zip(r1, r0)]

    # -- out = V0 + D(β', r') - D(β, r), D = Σ c_k V_k - V1 (Eq. 11) -----------------------------
    v0 = tb.separate(i["Original"])
    v1 = tb.separate(i["Narrow Delta"])[:3]
    v2 = tb.separate(i["Narrow One"])[:3]
    v3 = tb.separate(i["Wide Delta"])[:3]
    v4 = tb.separate(i["Wide One"])[:3]
    rgb = []
    for c in range(3):
        d12 = tb.sub(v2[c], v1[c])
        d13 = tb.sub(v3[c], v1[c])
        d34 = tb.sub(v4[c], v3[c])

        def halo(b, rr):  # D = r d12 + β (d13 + r d34 - r d12)
            return tb.madd(rr, d12, tb.mul(b, tb.sub(tb.madd(rr, d34, d13), tb.mul(rr, d12))))

        rgb.append(tb.add(v0[c], tb.sub(halo(beta, r[c]), halo(beta0, r0[c])), label="Eq. 11"))
    image = tb.combine(*rgb, v0[3])
    gout.location = (180.0 * (max(tb._depth.values()) + 2), 0)
    ng.links.new(image, gout.inputs["Image"])
    return ng


def ensure_compositor_group():
    """The compositor node group "Hazy Gloss Recomposite" (built from code, rebuilt if stale)."""
    import bpy
    ng = bpy.data.node_groups.get(GROUP_NAME)
    if ng is not None and ng.bl_idname == "CompositorNodeTree" \
            and ng.get(STAMP, {}).get("version") == GROUP_VERSION:
        return ng
    if ng is None or ng.bl_idname != "CompositorNodeTree":
        ng = bpy.data.node_groups.new(GROUP_NAME, "CompositorNodeTree")
    _build_group(ng)
    ng[STAMP] = {"version": GROUP_VERSION}
    ng.use_fake_user = True
    return ng


def build_compositor(scene, source=None, *, original=None, haziness=None, core_reflectivity=None):
    """Wire the scene compositor: passes -> "Hazy Gloss Recomposite" -> output.

    ``source`` None: Render Layers nodes of the original layer and the four layers (live after
    a render); a path: a multilayer EXR written by a recomposite render, loaded in Image nodes
    (re-compositing a saved render costs no rendering: a compositor with no Render Layers node
    does not render).  ``original``: the original layer's name (default: from the setup, or the
    one layer of the file that is not ours).
    ``haziness`` / ``core_reflectivity``: new values (factors set to 1); None keeps.
    Returns the group node."""
    import bpy
    from .blender import compat
    tree = compat.compositor_tree(scene)
    for n in [n for n in tree.nodes if n.name.startswith(RC_PREFIX + " ")]:
        tree.nodes.remove(n)
    out_socket = compat.compositor_output(tree, f"{RC_PREFIX} Output")
    group = tree.nodes.new("CompositorNodeGroup")
    group.node_tree = ensure_compositor_group()
    group.name = f"{RC_PREFIX} Recomposite"
    group.label = GROUP_NAME
    group.location = (500, 0)
    group.width = 260

    image = None
    if source is not None:
        image = bpy.data.images.load(bpy.path.abspath(str(source)), check_existing=True)
        image.reload()
        if original is None:
            others = [n for n in exr_layers(read_exr(bpy.path.abspath(str(source))))
                      if n not in LAYERS and n != "Composite"]
            if len(others) != 1:
                raise ValueError(f"cannot tell the original layer among {others}; pass original=")
            original = others[0]
    elif original is None:
        state = scene.get(STAMP)
        original = state.get("template") if state is not None else None
        if original is None or scene.view_layers.get(original) is None:
            raise ValueError("run setup_recomposite first (or pass original=<view layer>)")
    names = (original,) + LAYERS
    for k, (layer_name, sock_name) in enumerate(zip(names, [s[0] for s in _GROUP_SOCKETS[:5]])):
        if image is None:
            n = tree.nodes.new("CompositorNodeRLayers")
            n.scene = scene
            n.layer = layer_name
        else:
            n = tree.nodes.new("CompositorNodeImage")
            n.image = image
            n.layer = layer_name
        n.name = f"{RC_PREFIX} {layer_name}"
        n.label = layer_name
        n.location = (0, 600 - 320 * k)
        tree.links.new(n.outputs["Image" if "Image" in n.outputs else "Combined"],
                       group.inputs[sock_name])
        if k == 1:
            for aov, _, key in AOVS:
                target = {"beta": "Beta", "reflectivity": "Reflectivity", "peak_ratio": "Peak Ratio",
                          "mask": "Mask", "haziness": "Haziness",
                          "core_reflectivity": "Core Reflectivity"}[key]
                tree.links.new(n.outputs[aov], group.inputs[target])
    if haziness is not None:
        group.inputs["New Haziness"].default_value = float(haziness)
        group.inputs["Haziness Factor"].default_value = 1.0
    if core_reflectivity is not None:
        rc = np.broadcast_to(np.asarray(core_reflectivity, dtype=float), (3,))
        group.inputs["New Core Reflectivity"].default_value = (*map(float, rc), 1.0)
        group.inputs["Core Reflectivity Factor"].default_value = 1.0
    tree.links.new(group.outputs["Image"], out_socket)
    scene.render.use_compositing = True
    return group
