# SPDX-License-Identifier: GPL-3.0-or-later
"""Check an image file's structure before Blender loads it (bpy-free): the one checker of the
add-on (texture conversion, the recomposite compositor, the MaterialX import's textures, the
read-back of written maps).

Blender's loaders are not safe on damaged files: the first half of a small ZIP OpenEXR
segfaults bpy 5.0.1 on ``img.size`` after ``bpy.data.images.load`` (4.5, 5.2 and 5.3 load it as
0x0), a PNG cut off by a full disk loads as 0x0, a cut-off JPEG is filled with grey without an
error, and a tiny file whose header claims a huge image makes Blender allocate gigabytes.
:func:`check_image_file` reads only the file's structure (headers, the EXR offset table and
chunk headers, the PNG chunk list, the JPEG segments), never decodes pixels, so it is cheap
enough to run on every input of a conversion.

Every defect raises :class:`ImageFileError` (a ``ValueError``) with a one-line message that
names the file and what is wrong; I/O errors (missing file, no permission) stay ``OSError``.
"""
from __future__ import annotations

import os
import stat
from typing import NamedTuple

from . import constants as K
from .exr import ExrError, exr_header_check
from .filebytes import FileBytes, FileShrankError

__all__ = ("ImageFileError", "ImageInfo", "FORMAT_NAMES", "check_image_file")

#: Format id (Blender's ``file_format`` names where it has one) -> the name users know; in the
#: order the "not an image file" message lists them.
FORMAT_NAMES = {
    "PNG": "PNG", "JPEG": "JPEG", "OPEN_EXR": "OpenEXR", "TIFF": "TIFF", "HDR": "Radiance HDR",
    "TARGA": "TGA", "BMP": "BMP", "WEBP": "WebP", "DPX": "DPX", "CINEON": "Cineon",
    "JPEG2000": "JPEG 2000", "IRIS": "Iris", "PSD": "PSD", "DDS": "DDS",
}
#: Leading bytes of the formats Blender reads (TGA has none: recognised by its extension and
#: header fields; WebP by its RIFF header).
_MAGIC = (
    (b"\x76\x2f\x31\x01", "OPEN_EXR"), (b"\x89PNG\r\n\x1a\n", "PNG"), (b"\xff\xd8\xff", "JPEG"),
    (b"II*\x00", "TIFF"), (b"MM\x00*", "TIFF"), (b"II+\x00", "TIFF"), (b"MM\x00+", "TIFF"),
    (b"#?", "HDR"), (b"BM", "BMP"), (b"SDPX", "DPX"), (b"XPDS", "DPX"),
    (b"\x80\x2a\x5f\xd7", "CINEON"), (b"\xd7\x5f\x2a\x80", "CINEON"),
    (b"\x00\x00\x00\x0cjP  \r\n\x87\n", "JPEG2000"), (b"\xff\x4f\xff\x51", "JPEG2000"),
    (b"\x01\xda", "IRIS"), (b"8BPS", "PSD"), (b"DDS ", "DDS"),
)
_TGA_EXTENSIONS = (".tga", ".tpic")
#: PNG colour type -> (channels, allowed bit depths) (PNG spec, IHDR).
_PNG_TYPES = {0: (1, (1, 2, 4, 8, 16)), 2: (3, (8, 16)), 3: (1, (1, 2, 4, 8)), 4: (2, (8, 16)),
              6: (4, (8, 16))}
#: Bytes of slack in the PNG capacity bound (zlib header, tiny images).
_PNG_SLACK = 4096
#: JPEG start-of-frame markers (SOF0-SOF15 but DHT C4, JPG C8, DAC CC): height, width follow.
_JPEG_FRAMES = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


class ImageFileError(ValueError):
    """A malformed, truncated or unsupported image file.  ``str()`` is one line naming the file
    and the defect, e.g. ``"<path> is a truncated PNG (no IEND chunk: …)"``."""


class ImageInfo(NamedTuple):
    """What :func:`check_image_file` found: ``format`` is a key of :data:`FORMAT_NAMES`;
    width/height of the image (the first part's data window for OpenEXR), or None for a
    format whose structure is not checked (only its leading bytes are)."""
    format: object
    width: object
    height: object


def _sniff(head, path):
    """The format id of a file starting with ``head`` (its first 16 bytes), or None."""
    fmt = next((f for magic, f in _MAGIC if head.startswith(magic)), None)
    if fmt is None and head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        fmt = "WEBP"
    if fmt is None and os.path.splitext(path)[1].lower() in _TGA_EXTENSIONS and \
            len(head) >= 3 and head[1] in (0, 1) and head[2] in (1, 2, 3, 9, 10, 11):
        fmt = "TARGA"
    return fmt


def _check_png(buf, path):
    """The chunks from the signature to IEND: every chunk complete within the file with a valid
    type; the CRC of every critical chunk (IHDR, PLTE, IDAT, IEND: libpng refuses those, and
    only warns on ancillary ones, so a third-party file with a bad ancillary CRC passes); IHDR
    first (13 bytes, valid size, bit depth / colour type / methods), PLTE before the IDATs of
    a palette image, the IDATs consecutive and able to hold the size IHDR claims (deflate packs
    at most ~1032 bytes into one), IEND present.  Returns (width, height).

    The zlib stream inside the IDATs is not decompressed (a cut-off file has no IEND, which is
    what this catches).  ``buf``: a :class:`~hazy_gloss.filebytes.FileBytes`."""
    n = len(buf)

    def corrupt(what):
        return ImageFileError(f"{path} is a corrupt PNG ({what})")

    pos, index, idat = 8, 0, 0
    limit = K.MAX_IMAGE_CHUNKS
    idat_done = plte = False
    size = palette = raw = None
    while True:
        if pos + 12 > n:
            raise ImageFileError(f"{path} is a truncated PNG (no IEND chunk: the file ends at "
                                 f"byte {n})")
        if index >= limit:
            raise corrupt(f"more than {limit} chunks")
        length, ctype = buf.unpack_from(">I4s", pos)
        if not all(65 <= c <= 90 or 97 <= c <= 122 for c in ctype):
            raise corrupt(f"chunk {index} at byte {pos} has an invalid type {ctype!r}")
        name = ctype.decode("ascii")
        if length > 0x7FFFFFFF:
            raise corrupt(f"chunk {name} at byte {pos} has length {length} > 2^31 - 1")
        end = pos + 12 + length
        if end > n:
            raise ImageFileError(f"{path} is a truncated PNG (chunk {name} at byte {pos} needs "
                                 f"{end} bytes, the file has {n})")
        if 65 <= ctype[0] <= 90:  # critical
            (crc,) = buf.unpack_from(">I", pos + 8 + length)
            if buf.crc32(pos + 4, pos + 8 + length) != crc:
                raise corrupt(f"CRC mismatch in chunk {name} at byte {pos}")
        if index == 0:
            if name != "IHDR" or length != 13:
                raise corrupt("the first chunk is not a 13-byte IHDR")
            w, h, depth, colour, comp, filt, interlace = buf.unpack_from(">IIBBBBB", pos + 8)
            if not (1 <= w <= 0x7FFFFFFF and 1 <= h <= 0x7FFFFFFF):
                raise corrupt(f"invalid size {w}x{h}")
            channels, depths = _PNG_TYPES.get(colour, (0, ()))
            if depth not in depths:
                raise corrupt(f"invalid colour type {colour} / bit depth {depth}")
            if comp != 0 or filt != 0 or interlace not in (0, 1):
                raise corrupt(f"invalid compression/filter/interlace method ({comp}, {filt}, "
                              f"{interlace})")
            size, palette = (w, h), colour == 3
            raw = h * (1 + -(-w * channels * depth // 8))  # filtered bytes (not interlaced)
        elif name == "IHDR":
            raise corrupt(f"a second IHDR at byte {pos}")
        elif name == "PLTE":
            if idat:
                raise corrupt("PLTE after IDAT")
            plte = True
        elif name == "IDAT":
            if idat_done:
                raise corrupt(f"IDAT chunks are not consecutive (byte {pos})")
            if palette and not plte:
                raise corrupt("palette image without PLTE before IDAT")
            idat += length
        elif name == "IEND":
            if not idat:
                raise corrupt("no image data before IEND")
            if length != 0:
                raise corrupt(f"IEND has length {length} (must be 0)")
            if raw > K.MAX_DEFLATE_RATIO * idat + _PNG_SLACK:
                raise ImageFileError(f"{path} is a truncated or corrupt PNG ({idat} bytes of "
                                     f"image data cannot hold {size[0]}x{size[1]})")
            if size[0] * size[1] > K.MAX_IMAGE_PIXELS:
                raise corrupt(f"{size[0]}x{size[1]} pixels exceeds the limit of "
                              f"{K.MAX_IMAGE_PIXELS}")
            return size
        elif idat:
            idat_done = True
        pos = end
        index += 1


def _check_jpeg(buf, path):
    """The marker segments up to the first scan (a frame header with the size among them), then
    an end-of-image marker after it (0xFF in the entropy-coded data is always escaped, so the
    first FF D9 after the scan header is the end of the image).  Returns (width, height);
    ``buf``: a :class:`~hazy_gloss.filebytes.FileBytes`."""
    n, pos, size, steps = len(buf), 2, None, 0
    while True:
        steps += 1
        if steps > K.MAX_IMAGE_CHUNKS:
            raise ImageFileError(f"{path} is a corrupt JPEG (more than {K.MAX_IMAGE_CHUNKS} "
                                 "markers before its image data)")
        if pos + 2 > n:
            raise ImageFileError(f"{path} is a truncated JPEG (the file ends at byte {n}, "
                                 "before its image data)")
        if buf[pos] != 0xFF:
            raise ImageFileError(f"{path} is a corrupt JPEG (no marker at byte {pos})")
        m = buf[pos + 1]
        if m == 0xFF:  # fill byte
            pos += 1
            continue
        if m == 0x01 or 0xD0 <= m <= 0xD8:  # standalone markers
            pos += 2
            continue
        if m == 0xD9:
            raise ImageFileError(f"{path} is a corrupt JPEG (it ends before its image data)")
        if pos + 4 > n:
            raise ImageFileError(f"{path} is a truncated JPEG (a marker segment at byte {pos} "
                                 "is cut off)")
        (length,) = buf.unpack_from(">H", pos + 2)
        if length < 2:
            raise ImageFileError(f"{path} is a corrupt JPEG (segment at byte {pos} has length "
                                 f"{length})")
        if pos + 2 + length > n:
            raise ImageFileError(f"{path} is a truncated JPEG (segment at byte {pos} needs "
                                 f"{pos + 2 + length} bytes, the file has {n})")
        if m in _JPEG_FRAMES and length >= 7:
            h, w = buf.unpack_from(">HH", pos + 5)
            if w == 0 or h == 0 or w * h > K.MAX_IMAGE_PIXELS:
                raise ImageFileError(f"{path} is a corrupt JPEG (frame header: {w}x{h} pixels)")
            size = (w, h)
        pos += 2 + length
        if m == 0xDA:  # start of scan: entropy-coded data follows
            break
    if size is None:
        raise ImageFileError(f"{path} is a corrupt JPEG (no frame header before its image data)")
    if buf.find(b"\xff\xd9", pos) < 0:
        raise ImageFileError(f"{path} is a truncated JPEG (no end-of-image marker after its "
                             "image data)")
    return size


def _check_exr(path):
    try:
        parts = exr_header_check(path)
    except ExrError as exc:
        detail = exc.detail or str(exc)
        if exc.kind == "unsupported":
            raise ImageFileError(f"{path} is an OpenEXR file Blender cannot load "
                                 f"({detail})") from None
        raise ImageFileError(f"{path} is a {exc.kind} OpenEXR file ({detail})") from None
    return parts[0].width, parts[0].height


def check_image_file(path):
    """Check that ``path`` is a structurally complete image Blender reads, before
    ``bpy.data.images.load``.

    - a regular, non-empty file (not a folder, a device or a pipe);
    - the format by its contents, as Blender tells it (:data:`FORMAT_NAMES`; TGA by its
      extension too): anything else is "not an image file Blender reads";
    - OpenEXR: :func:`hazy_gloss.exr.exr_header_check` — every header attribute, channel list,
      data window (refused when the file is too small to hold it), compression, the offset table
      and every chunk's header and extent within the file (scanline, tiled and multi-part files,
      every codec; deep files are refused: Blender does not load them);
    - PNG: the chunks to IEND, critical CRCs, IHDR, and image data able to hold the size;
    - JPEG: the segments to the first scan (a frame header with a size) and an end-of-image
      marker after it;
    - other formats: only their leading bytes (``ImageInfo(format, None, None)``).

    Returns an :class:`ImageInfo`.  Raises :class:`ImageFileError` (a ``ValueError``; the
    message is one line naming the file and the defect) for a damaged or unreadable file,
    ``OSError`` when the file cannot be opened.  Pixels are not decoded: the cost is a few
    reads per chunk (plus the CRC of the PNG image data)."""
    path = os.fspath(path)
    st = os.stat(path)
    if stat.S_ISDIR(st.st_mode):
        raise ImageFileError(f"{path} is a folder, not an image file")
    if not stat.S_ISREG(st.st_mode):
        raise ImageFileError(f"{path} is not a regular file")
    if st.st_size == 0:
        raise ImageFileError(f"{path} is empty (0 bytes)")
    with open(path, "rb") as fh:
        head = fh.read(16)
        fmt = _sniff(head, path)
        if fmt is None:
            prefix = next((f for magic, f in _MAGIC if magic.startswith(head)), None)
            if prefix is not None:
                raise ImageFileError(f"{path} is a truncated {FORMAT_NAMES[prefix]} file (only "
                                     f"{len(head)} bytes)")
            raise ImageFileError(f"{path} is not an image file Blender reads "
                                 f"({', '.join(FORMAT_NAMES.values())}); it starts with "
                                 f"{head[:8]!r}")
        if fmt == "OPEN_EXR":
            return ImageInfo(fmt, *_check_exr(path))
        if fmt not in ("PNG", "JPEG"):
            return ImageInfo(fmt, None, None)
        # read, not memory-mapped: a mapped file cut short meanwhile kills Blender (SIGBUS)
        try:
            size = (_check_png if fmt == "PNG" else _check_jpeg)(FileBytes(fh), path)
        except FileShrankError as exc:
            raise ImageFileError(f"{path} is a truncated {FORMAT_NAMES[fmt]} ({exc})") from None
        return ImageInfo(fmt, *size)
