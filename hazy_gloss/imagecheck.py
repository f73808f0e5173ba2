# SPDX-License-Identifier: GPL-3.0-or-later
"""Check an image file's structure before Blender loads it (bpy-free).

Blender's loaders are not safe on damaged files: the first half of a small ZIP OpenEXR
segfaults bpy 5.0.1 on ``img.size`` after ``bpy.data.images.load`` (4.5, 5.2 and 5.3 load it as
0x0), and a PNG cut off by a full disk loads as 0x0.  :func:`check_image_file` reads only the
file's structure (headers, the EXR offset table and chunk headers, the PNG chunk list), never
the pixels, so it is cheap enough to run on every input of a conversion.

Every defect raises :class:`ImageFileError` (a ``ValueError``) with a one-line message that
names the file and what is wrong; I/O errors (missing file, no permission) stay ``OSError``.
"""
from __future__ import annotations

import mmap
import os
import struct
import zlib
from typing import NamedTuple

from . import constants as K
from .exr import ExrError, exr_header_check

__all__ = ("ImageFileError", "ImageInfo", "check_image_file", "check_png",
           "MAX_IMAGE_PIXELS")

#: Largest width x height accepted (hazy_gloss.constants): anything larger is a damaged or
#: hostile header, not a texture.
MAX_IMAGE_PIXELS = K.MAX_IMAGE_PIXELS

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_EXR_MAGIC = b"\x76\x2f\x31\x01"
#: PNG colour type -> allowed bit depths (PNG spec, IHDR).
_PNG_DEPTHS = {0: (1, 2, 4, 8, 16), 2: (8, 16), 3: (1, 2, 4, 8), 4: (8, 16), 6: (8, 16)}


class ImageFileError(ValueError):
    """A malformed or unsupported image file.  ``str()`` is one line: ``"<path>: <defect>"``."""


class ImageInfo(NamedTuple):
    """What :func:`check_image_file` found: ``format`` is ``"OPEN_EXR"``, ``"PNG"`` or None (a
    format this module does not check); width/height of the first part (EXR data window), or
    None when not checked."""
    format: object
    width: object
    height: object


def _open_map(path):
    """(file object, read-only mmap) of a non-empty file; raises ImageFileError when empty."""
    fh = open(path, "rb")
    try:
        size = os.fstat(fh.fileno()).st_size
        if size == 0:
            raise ImageFileError(f"{path}: the file is empty")
        return fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
    except BaseException:
        fh.close()
        raise


def check_png(path):
    """Validate a PNG's structure: the signature, IHDR (first, 13 bytes, valid dimensions, bit
    depth / colour type / methods), every chunk complete within the file with a valid type, the
    CRC of every critical chunk (IHDR, PLTE, IDAT, IEND; libpng rejects those, and only warns
    on ancillary ones), PLTE present for palette images, at least one IDAT, the IDATs
    consecutive, and IEND present.  Returns ``(width, height)``; raises ImageFileError.

    The zlib stream inside the IDATs is not decompressed (a cut-off file has no IEND, which
    is what this catches)."""
    fh, buf = _open_map(path)
    try:
        return _check_png(buf, path)
    finally:
        buf.close()
        fh.close()


def _check_png(buf, path):
    n = len(buf)

    def bad(what):
        return ImageFileError(f"{path}: malformed PNG: {what}")

    if n < 8 or buf[:8] != _PNG_SIGNATURE:
        raise bad("bad signature (not a PNG file)")
    pos, index = 8, 0
    seen_idat = idat_done = plte = False
    size, palette = None, False
    while True:
        if pos + 8 > n:
            raise bad(f"truncated: chunk header at byte {pos} is cut off (file has {n} bytes, "
                      "no IEND)")
        length, ctype = struct.unpack_from(">I4s", buf, pos)
        if not all(65 <= c <= 90 or 97 <= c <= 122 for c in ctype):
            raise bad(f"chunk {index} at byte {pos} has an invalid type {ctype!r}")
        name = ctype.decode("ascii")
        if length > 0x7FFFFFFF:
            raise bad(f"chunk {name} at byte {pos} has length {length} > 2^31 - 1")
        end = pos + 12 + length
        if end > n:
            raise bad(f"truncated: chunk {name} at byte {pos} needs {end} bytes, file has {n}")
        critical = 65 <= ctype[0] <= 90
        if critical:
            (crc,) = struct.unpack_from(">I", buf, pos + 8 + length)
            if zlib.crc32(buf[pos + 4:pos + 8 + length]) != crc:
                raise bad(f"CRC mismatch in chunk {name} at byte {pos}")
        if index == 0:
            if name != "IHDR" or length != 13:
                raise bad("the first chunk is not a 13-byte IHDR")
            w, h, depth, colour, comp, filt, interlace = struct.unpack_from(">IIBBBBB", buf,
                                                                             pos + 8)
            if not (1 <= w <= 0x7FFFFFFF and 1 <= h <= 0x7FFFFFFF):
                raise bad(f"invalid size {w} x {h}")
            if w * h > MAX_IMAGE_PIXELS:
                raise bad(f"{w} x {h} pixels exceeds the limit of {MAX_IMAGE_PIXELS}")
            if depth not in _PNG_DEPTHS.get(colour, ()):
                raise bad(f"invalid colour type {colour} / bit depth {depth}")
            if comp != 0 or filt != 0 or interlace not in (0, 1):
                raise bad(f"invalid compression/filter/interlace method ({comp}, {filt}, "
                          f"{interlace})")
            size, palette = (w, h), colour == 3
        elif name == "IHDR":
            raise bad(f"a second IHDR at byte {pos}")
        elif name == "PLTE":
            if seen_idat:
                raise bad("PLTE after IDAT")
            plte = True
        elif name == "IDAT":
            if idat_done:
                raise bad(f"IDAT chunks are not consecutive (byte {pos})")
            if palette and not plte:
                raise bad("palette image without PLTE before IDAT")
            seen_idat = True
        elif name == "IEND":
            if not seen_idat:
                raise bad("no IDAT chunk before IEND")
            if length != 0:
                raise bad(f"IEND has length {length} (must be 0)")
            return size
        elif seen_idat:
            idat_done = True
        pos = end
        index += 1


def check_image_file(path):
    """Check that ``path`` is a structurally complete image before ``bpy.data.images.load``.

    - OpenEXR (by magic number): :func:`hazy_gloss.exr.exr_header_check` — every header
      attribute, channel list, data window, compression, the offset table and every chunk's
      header and extent within the file (scanline, tiled and multi-part files; deep files are
      refused);
    - PNG (by signature): :func:`check_png`;
    - a file named ``*.exr`` / ``*.png`` whose contents are not that format is refused;
    - any other format is not checked (``ImageInfo(None, None, None)``), except that an empty
      file is refused.

    Returns an :class:`ImageInfo`.  Raises :class:`ImageFileError` (a ``ValueError``; the
    message is one line naming the file and the defect) for a damaged file, ``OSError`` when
    the file cannot be opened.  Pixels are not decoded: the cost is a few reads per chunk."""
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    with open(path, "rb") as fh:
        head = fh.read(8)
    if not head:
        raise ImageFileError(f"{path}: the file is empty")
    if head[:4] == _EXR_MAGIC:
        try:
            parts = exr_header_check(path)
        except ExrError as exc:
            raise ImageFileError(str(exc)) from exc
        return ImageInfo("OPEN_EXR", parts[0].width, parts[0].height)
    if head == _PNG_SIGNATURE:
        w, h = check_png(path)
        return ImageInfo("PNG", w, h)
    if ext == ".exr":
        raise ImageFileError(f"{path}: not an OpenEXR file (bad magic number)")
    if ext == ".png":
        raise ImageFileError(f"{path}: not a PNG file (bad signature)")
    return ImageInfo(None, None, None)
