# SPDX-License-Identifier: GPL-3.0-or-later
"""The texture converter's pixel helpers (convert.py): the sRGB transfer functions
(float and 8-bit) and the bilinear resampling of a map to another size, in numpy.
"""
from __future__ import annotations

import numpy as np

__all__ = ("srgb_to_linear", "srgb_bytes_to_linear", "linear_to_srgb", "resample_axis",
           "resample_block", "resample_bilinear")


# --------------------------------------------------------------------------------------------
# Colour
# --------------------------------------------------------------------------------------------


def srgb_to_linear(x):
    """IEC 61966-2-1 sRGB decoding (piecewise, 0.04045 / 12.92 / 2.4), computed in float64,
    returned as float32.  Blender's OCIO "sRGB" colour space uses this curve (measured: a 16-bit
    PNG tagged sRGB decodes to it)."""
    x = np.asarray(x, dtype=np.float64)
    out = np.where(x <= 0.04045, x / 12.92, ((np.maximum(x, 0.04045) + 0.055) / 1.055) ** 2.4)
    return out.astype(np.float32)


def srgb_bytes_to_linear(x):
    """:func:`srgb_to_linear` of the float values Blender gives for an 8-bit image (k/255 as
    float32), through a 256-entry table: identical results, float32 memory only (the general
    function's float64 temporaries would take ~8x the image for a 4K map)."""
    x = np.asarray(x, dtype=np.float32)
    k = np.arange(256, dtype=np.float32) * np.float32(1 / 255)  # Blender's byte -> float
    lut = srgb_to_linear(k)
    idx = np.rint(x * np.float32(255))
    np.clip(idx, 0, 255, out=idx)
    idx = idx.astype(np.uint8)
    if not np.array_equal(np.take(k, idx), x):
        return srgb_to_linear(x)  # not 8-bit values: the general (exact) path
    return np.take(lut, idx)


def linear_to_srgb(x):
    """Inverse of :func:`srgb_to_linear` (recovers the file values of a float image Blender
    decoded from sRGB)."""
    x = np.asarray(x, dtype=np.float64)
    out = np.where(x <= 0.0031308, x * 12.92,
                   1.055 * np.maximum(x, 0.0031308) ** (1.0 / 2.4) - 0.055)
    return out.astype(np.float32)


def resample_axis(n_out, n_in):
    """(i0, i1, f) of bilinear resampling along one axis: output texel k reads input texels i0
    and i1 with weight f of i1 (texel centres aligned, edges clamped)."""
    x = (np.arange(n_out, dtype=np.float64) + 0.5) * (n_in / n_out) - 0.5
    x = np.clip(x, 0.0, n_in - 1)
    i0 = np.floor(x).astype(np.intp)
    i1 = np.minimum(i0 + 1, n_in - 1)
    return i0, i1, (x - i0).astype(np.float32)


def resample_block(arr, y0, y1, fy, xs):
    """Rows of a bilinear resampling: ``arr`` the input rows, ``y0``/``y1``/``fy`` the rows
    (indices into ``arr``) and weights of each output row, ``xs`` = resample_axis along x."""
    x0, x1, fx = xs
    if arr.ndim == 3:
        fx = fx[:, None]
    top = arr[y0][:, x0] * (1 - fx) + arr[y0][:, x1] * fx
    bot = arr[y1][:, x0] * (1 - fx) + arr[y1][:, x1] * fx
    fy = fy[:, None, None] if arr.ndim == 3 else fy[:, None]
    return (top * (1 - fy) + bot * fy).astype(np.float32)


def resample_bilinear(arr, size):
    """Resample an (H, W[, C]) array to ``size`` = (width, height), texel centres aligned
    (the convention of image editors), edges clamped.  float32 in and out."""
    w, h = int(size[0]), int(size[1])
    arr = np.asarray(arr, dtype=np.float32)
    h0, w0 = arr.shape[:2]
    if (h0, w0) == (h, w):
        return arr
    y0, y1, fy = resample_axis(h, h0)
    return resample_block(arr, y0, y1, fy, resample_axis(w, w0))


# --------------------------------------------------------------------------------------------
