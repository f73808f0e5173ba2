# SPDX-License-Identifier: GPL-3.0-or-later
"""Image files through OpenImageIO (bpy-free): the one check before Blender loads a file
(texture conversion, the recomposite compositor, the MaterialX import's textures, the read-back
of written maps), and the channels of an OpenEXR file (the recomposite passes).

Blender's loaders are not safe on damaged files: the first half of a small ZIP OpenEXR
segfaults bpy 5.0.1 on ``img.size`` after ``bpy.data.images.load`` (4.5, 5.2 and 5.3 load it as
0x0), a PNG cut off by a full disk loads as 0x0, a cut-off JPEG is filled with grey without an
error, and a tiny file whose header claims a huge image makes Blender allocate gigabytes.
:func:`check_image_file` opens the file with the OpenImageIO Blender ships (:mod:`.oiio`),
refuses a header that claims more pixels than the file can hold, then decodes every subimage
(level 0 of a tiled file: what Blender reads) in strips of rows (memory: one strip), so a file
that passes decodes without an error in the libraries Blender reads it with.

Every defect raises :class:`ImageFileError` (a ``ValueError``) with a one-line message that
names the file and what is wrong; I/O errors (missing file, no permission) stay ``OSError``.
The libraries' own messages on stderr (libpng, OpenEXR) are held while a file is read: dropped
when it is refused (its line carries the reason), passed on when it passes.
"""
from __future__ import annotations

import os
import stat
from contextlib import contextmanager
from typing import NamedTuple

import numpy as np

from .. import constants as K
from .oiio import MISSING, error_text, format_of, held_stderr, open_input, openimageio, read_rows

__all__ = ("ImageFileError", "ImageInfo", "FORMAT_NAMES", "check_image_file", "read_exr")

#: Format id (Blender's ``file_format`` names where it has one) -> the name users know; in the
#: order the "not an image file" message lists them.
FORMAT_NAMES = {
    "PNG": "PNG", "JPEG": "JPEG", "OPEN_EXR": "OpenEXR", "TIFF": "TIFF", "HDR": "Radiance HDR",
    "TARGA": "TGA", "BMP": "BMP", "WEBP": "WebP", "DPX": "DPX", "CINEON": "Cineon",
    "JPEG2000": "JPEG 2000", "IRIS": "Iris", "PSD": "PSD", "DDS": "DDS",
}
#: OpenImageIO's format names of the formats Blender reads -> the ids above.
_FORMATS = {"png": "PNG", "jpeg": "JPEG", "openexr": "OPEN_EXR", "tiff": "TIFF", "hdr": "HDR",
            "targa": "TARGA", "bmp": "BMP", "webp": "WEBP", "dpx": "DPX", "cineon": "CINEON",
            "jpeg2000": "JPEG2000", "sgi": "IRIS", "psd": "PSD", "dds": "DDS"}
#: The most a codec expands one stored byte to (deflate ~1032; OpenEXR's RLE 2 bytes -> 128), a
#: tighter bound than MAX_TEXELS_PER_BYTE on the pixels a header may claim (the decoders
#: allocate for them); other codecs (PIZ, DWA, HTJ2K, JPEG, ...) only have that one.
_EXPANSION = {("OPEN_EXR", "none"): 1, ("OPEN_EXR", "rle"): 64, ("OPEN_EXR", "zips"): 1100,
              ("OPEN_EXR", "zip"): 1100, ("PNG", ""): 1100, ("PNG", "zip"): 1100}
#: Subimages (EXR parts) a file may have: bounds the work on a crafted file.
_MAX_SUBIMAGES = 4096


class ImageFileError(ValueError):
    """A malformed, truncated or unsupported image file.  ``str()`` is one line naming the file
    and the defect, e.g. ``"<path> is a damaged PNG file (cut off or corrupt: …)"``."""


class ImageInfo(NamedTuple):
    """What :func:`check_image_file` found: ``format`` is a key of :data:`FORMAT_NAMES`;
    width and height of the first subimage (an OpenEXR file's first part's data window)."""
    format: object
    width: object
    height: object


def _rows(width):
    return max(1, (K.STRIP_TEXELS // max(width, 1)))


class _File:
    """One image file open in OpenImageIO: the format, the bound on its size, its pixels read
    in strips; every failure an ImageFileError naming the file."""

    def __init__(self, path):
        self.path = path
        st = os.stat(path)
        if stat.S_ISDIR(st.st_mode):
            raise ImageFileError(f"{path} is a folder, not an image file")
        if not stat.S_ISREG(st.st_mode):
            raise ImageFileError(f"{path} is not a regular file")
        if st.st_size == 0:
            raise ImageFileError(f"{path} is empty (0 bytes)")
        self.size = st.st_size
        self.oiio = openimageio()
        if self.oiio is None:
            raise ImageFileError(f"{MISSING}: cannot check {path} before Blender reads it")
        with open(path, "rb"):  # an unreadable file is an OSError, as for any file
            pass
        self.inp, why = open_input(self.oiio, path)
        if self.inp is None:
            meant = format_of(self.oiio, path, _FORMATS)  # by the magic number
            if meant is not None:
                self.format = _FORMATS[meant]
                raise self.damaged(why)
            raise ImageFileError(f"{path} is not an image file Blender reads "
                                 f"({', '.join(FORMAT_NAMES.values())}), or a damaged one "
                                 f"({why})")
        self.format = _FORMATS.get(self.inp.format_name())
        if self.format is None:
            name = self.inp.format_name()
            self.close()
            raise ImageFileError(f"{path} is not an image file Blender reads "
                                 f"({', '.join(FORMAT_NAMES.values())}); OpenImageIO reads it "
                                 f"as {name}")

    def damaged(self, why):
        return ImageFileError(f"{self.path} is a damaged {FORMAT_NAMES[self.format]} file "
                              f"(cut off or corrupt: {why or 'no reason given'})")

    def cannot_load(self, why):
        return ImageFileError(f"{self.path} is an {FORMAT_NAMES[self.format]} file Blender "
                              f"cannot load ({why})")

    def subimages(self, for_blender=True):
        """Every subimage's spec (level 0), checked against the file's size; ``for_blender``:
        and against what Blender's loader assumes."""
        specs, texels, stored = [], 0, 0
        while True:
            why = error_text(self.inp) if specs else None  # e.g. libjpeg's "premature end"
            if why:
                raise self.damaged(why)
            if not self.inp.seek_subimage(len(specs), 0):
                break
            if len(specs) >= _MAX_SUBIMAGES:
                raise self.damaged(f"more than {_MAX_SUBIMAGES} parts")
            spec = self.inp.spec()
            if spec.deep:
                raise self.cannot_load(f"part {len(specs)} holds deep data")
            window = (spec.x, spec.y, spec.width, spec.height)
            if for_blender and specs and window != (specs[0].x, specs[0].y, specs[0].width,
                                                    specs[0].height):
                # its multilayer reader sizes every part's buffer by the first part's window:
                # a file whose parts differ corrupts its memory (bpy 5.3, tested)
                raise self.cannot_load(f"part {len(specs)}'s data window {window[2]}x"
                                       f"{window[3]} at ({window[0]}, {window[1]}) is not part "
                                       f"0's {specs[0].width}x{specs[0].height} at "
                                       f"({specs[0].x}, {specs[0].y})")
            w, h = spec.width, spec.height
            if w < 1 or h < 1 or spec.nchannels < 1:
                raise self.damaged(f"part {len(specs)} has {w}x{h} pixels, {spec.nchannels} "
                                   "channels")
            texels += w * h
            codec = spec.get_string_attribute("compression", "").split(":")[0]
            ratio = _EXPANSION.get((self.format, codec))
            stored += w * h * sum(spec.channelformat(c).size() for c in range(spec.nchannels))
            if w * h > K.MAX_IMAGE_PIXELS or texels > K.MAX_TEXELS_PER_BYTE * self.size or \
                    ratio is not None and stored > ratio * self.size:
                raise self.damaged(f"its header claims {w}x{h} pixels, which {self.size} bytes "
                                   "cannot hold")
            specs.append(spec)
        if not specs:
            raise self.damaged(error_text(self.inp))
        # opened again: some readers (WebP) decode nothing after a seek past the last subimage
        self.inp.close()
        self.inp, why = open_input(self.oiio, self.path)
        if self.inp is None:
            raise self.damaged(why)
        return specs

    def read(self, spec, subimage, level, y0, y1, fmt, channels):
        """Rows y0..y1 (spec coordinates) of a subimage and level, channels ``channels`` (a
        range), or ImageFileError."""
        a = read_rows(self.inp, spec, subimage, level, y0, y1, channels, fmt)
        why = error_text(self.inp)
        if why or a is None or not hasattr(a, "shape"):
            raise self.damaged(why)
        return a

    def read_all(self, specs):
        """Decode level 0 of every subimage (what Blender reads), strip by strip."""
        for index, spec in enumerate(specs):
            rows = _rows(spec.width)
            for y in range(spec.y, spec.y + spec.height, rows):
                self.read(spec, index, 0, y, min(spec.y + spec.height, y + rows),
                          self.oiio.UNKNOWN, range(spec.nchannels))  # as stored

    def close(self):
        if self.inp is not None:
            self.inp.close()
            self.inp = None


@contextmanager
def _opened(path):
    path = os.fspath(path)
    with held_stderr() as keep:
        f = None
        try:
            f = _File(path)
            yield f
        except ImageFileError:
            keep[0] = False
            raise
        finally:
            if f is not None:
                f.close()


def check_image_file(path):
    """Check that ``path`` is a whole image Blender reads, before ``bpy.data.images.load``.

    - a regular, non-empty file (not a folder, a device or a pipe);
    - a format Blender reads (:data:`FORMAT_NAMES`), as OpenImageIO tells it by the contents:
      anything else is "not an image file Blender reads";
    - no header claiming more pixels than the file can hold
      (:data:`~hazy_gloss.constants.MAX_TEXELS_PER_BYTE` per byte, at most
      :data:`~hazy_gloss.constants.MAX_IMAGE_PIXELS`), no deep OpenEXR data (Blender does not
      load it), the same data window in every part of a multi-part OpenEXR (Blender's loader
      assumes it, and corrupts its memory on a file that differs);
    - every subimage (OpenEXR part; level 0 of a mip- or rip-mapped file, what Blender reads)
      decodes without an error (scanline and tiled OpenEXR in every codec, PNG, JPEG, TIFF,
      ...).

    Returns an :class:`ImageInfo`.  Raises :class:`ImageFileError` (a ``ValueError``; the
    message is one line naming the file and the defect) for a damaged or unreadable file, or
    where OpenImageIO is missing; ``OSError`` when the file cannot be opened.  The cost is one
    decode of the file; memory one strip of rows."""
    with _opened(path) as f:
        specs = f.subimages()
        f.read_all(specs)
        return ImageInfo(f.format, specs[0].width, specs[0].height)


def read_exr(path):
    """Every channel of an OpenEXR file as float32 arrays, checked as :func:`check_image_file`
    checks a file.

    Returns ``{channel name: (H, W) float32}`` with full names as Blender writes them, e.g.
    ``"HG Narrow Delta.Combined.R"``; the channels of every part (a multi-part file) in one
    dict.  Row 0 is the BOTTOM row (Blender's pixel order, like ``Image.pixels``).  Any codec
    (ZIP, PIZ, DWAA, DWAB, RLE, NONE, ...), scanline or tiled (level 0).

    Parts of different data windows are read (they are not handed to Blender).  Raises
    :class:`ImageFileError` (a ``ValueError``; one line naming the file and the defect) for a
    damaged file, another format, a channel in two parts, or more than
    :data:`~hazy_gloss.constants.MAX_EXR_DECODED_BYTES` of float32 values."""
    with _opened(path) as f:
        if f.format != "OPEN_EXR":
            raise ImageFileError(f"{f.path} is a {FORMAT_NAMES[f.format]} file, not OpenEXR")
        specs = f.subimages(for_blender=False)
        total = sum(4 * s.width * s.height * s.nchannels for s in specs)
        if total > K.MAX_EXR_DECODED_BYTES:
            raise ImageFileError(f"{f.path}: {total} bytes of float32 values exceeds the limit "
                                 f"of {K.MAX_EXR_DECODED_BYTES}")
        out = {}
        for index, spec in enumerate(specs):
            try:
                names = list(spec.channelnames)
            except UnicodeDecodeError:
                raise f.damaged(f"part {index} has a channel name that is not UTF-8") from None
            a = np.empty((spec.height, spec.width, spec.nchannels), np.float32)
            # 32-bit integer channels by value (OpenImageIO's float conversion normalises them)
            ints = [c for c in range(spec.nchannels)
                    if spec.channelformat(c).basetype == f.oiio.UINT32]
            rows = _rows(spec.width)
            for y in range(0, spec.height, rows):
                y1 = min(spec.height, y + rows)
                a[y:y1] = np.asarray(f.read(spec, index, 0, spec.y + y, spec.y + y1, f.oiio.FLOAT,
                                            range(spec.nchannels))).reshape(y1 - y, spec.width, -1)
                for c in ints:
                    a[y:y1, :, c] = np.asarray(f.read(spec, index, 0, spec.y + y, spec.y + y1,
                                                      f.oiio.UINT32, range(c, c + 1))
                                               ).reshape(y1 - y, -1)
            for c, name in enumerate(names):
                if name in out:
                    raise f.damaged(f"channel {name!r} appears in two parts")
                out[name] = np.ascontiguousarray(a[::-1, :, c])  # file: top row first
        return out
