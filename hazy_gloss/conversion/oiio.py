# SPDX-License-Identifier: GPL-3.0-or-later
"""The OpenImageIO module the add-on reads, checks and writes image files with (bpy-free).

Inside Blender ``import OpenImageIO`` finds the module Blender ships.  The ``bpy`` module from
PyPI ships the same module inside its package (``bpy/<version>/python/lib/python3.X/
site-packages/OpenImageIO``) without putting it on ``sys.path``: :func:`openimageio` loads it
from there by its file, without importing bpy and leaving ``sys.path`` alone, and prefers it to
any other copy (it is built against the libraries bpy loads).  Elsewhere any ``OpenImageIO`` on
``sys.path`` (the PyPI ``openimageio`` wheel).  ``HAZY_GLOSS_NO_OIIO=1`` hides it (tests of the
message a Blender without the module gives).

:func:`open_input` opens a file for reading with OpenImageIO's classic OpenEXR reader: the one
on OpenEXRCore (OpenImageIO's default) reads an uncompressed OpenEXR file whose last chunk is cut
off without an error, the classic one (the OpenEXR library Blender itself reads with) refuses it.
The classic reader reads a tiled file by tiles only: :func:`read_rows` reads rows of either.
The libraries under it (libpng, OpenEXR) also print their errors on stderr: :func:`held_stderr`
holds them while a file is read, for the caller to drop when its own one line says it.
"""
from __future__ import annotations

import glob
import importlib.util
import os
import sys
import tempfile
from contextlib import contextmanager

import numpy as np

__all__ = ("openimageio", "MISSING", "open_input", "error_text", "read_rows", "format_of",
           "held_stderr")

#: What to say where the module is missing.
MISSING = ("Blender's OpenImageIO Python module is not available (blender.org builds and the "
           "bpy module ship it; a distribution's Blender needs its OpenImageIO Python package)")

_FOUND = []


def openimageio():
    """The OpenImageIO module, or None (found once)."""
    if not _FOUND:
        mod = None
        if not os.environ.get("HAZY_GLOSS_NO_OIIO"):
            mod = sys.modules.get("OpenImageIO") or _bundled()
            if mod is None:
                try:
                    import OpenImageIO as mod  # noqa: N813
                except ImportError:
                    mod = None
        _FOUND.append(mod)
    return _FOUND[0]


def _bundled():
    """The copy inside the bpy package, loaded by its file (bpy is looked up, not imported)."""
    try:
        spec = importlib.util.find_spec("bpy")
    except (ImportError, ValueError):
        return None
    roots = list(spec.submodule_search_locations or ()) if spec is not None else []
    for root in roots:
        found = sorted(glob.glob(os.path.join(root, "*", "python", "lib*", "python3*",
                                              "site-packages", "OpenImageIO", "__init__.py"))
                       + glob.glob(os.path.join(root, "*", "python", "lib", "site-packages",
                                                "OpenImageIO", "__init__.py")))
        for init in found:
            folder = os.path.dirname(init)
            try:
                mspec = importlib.util.spec_from_file_location(
                    "OpenImageIO", init, submodule_search_locations=[folder])
                mod = importlib.util.module_from_spec(mspec)
                sys.modules["OpenImageIO"] = mod
                mspec.loader.exec_module(mod)
                return mod
            except Exception:  # a build for another Python: look further
                sys.modules.pop("OpenImageIO", None)
    return None


def error_text(source):
    """``source.geterror()`` (an ImageInput, ImageOutput or the module) as one line; the
    message may quote undecodable bytes of a damaged file."""
    try:
        text = source.geterror()
    except UnicodeDecodeError:
        return "an error message that is not UTF-8 text"
    return "; ".join(p.strip() for p in str(text).splitlines() if p.strip())


def open_input(oiio, path):
    """``oiio.ImageInput.open(path)`` with the classic OpenEXR reader: (input, None), or
    (None, the reason in one line)."""
    before = oiio.get_int_attribute("openexr:core", 0)  # process-wide: set back at once
    if before:
        oiio.attribute("openexr:core", 0)  # consulted when the reader is created
    try:
        inp = oiio.ImageInput.open(path)
    finally:
        if before:
            oiio.attribute("openexr:core", before)
    if inp is None:
        return None, error_text(oiio) or "no reason given"
    return inp, None


def format_of(oiio, path, names):
    """The first of OpenImageIO's format ``names`` whose reader takes ``path`` by its contents
    (the magic number), or None: what a file that does not open was meant to be."""
    for name in names:
        try:
            inp = oiio.ImageInput.create(name)
            if inp is not None and inp.valid_file(path):
                return name
        except Exception:  # a format this build does not read
            pass
        error_text(oiio)  # none left pending
    return None


def read_rows(inp, spec, subimage, level, y0, y1, channels, fmt):
    """Rows ``y0 .. y1`` (data-window coordinates) of channels ``channels`` (a range) of a
    subimage and level whose spec is ``spec``, as ``read_scanlines`` returns them: a scanline
    file row by row, a tiled one by the rows of tiles that cover them (memory: those tiles)."""
    if spec.tile_width <= 0:
        return inp.read_scanlines(subimage, level, y0, y1, 0, channels.start, channels.stop, fmt)
    th = spec.tile_height
    top = spec.y + (y0 - spec.y) // th * th
    bottom = min(spec.y + spec.height, spec.y + -(-(y1 - spec.y) // th) * th)
    a = inp.read_tiles(subimage, level, spec.x, spec.x + spec.width, top, bottom, spec.z,
                       spec.z + max(spec.depth, 1), channels.start, channels.stop, fmt)
    if a is None or not hasattr(a, "shape"):
        return a
    return np.asarray(a).reshape(bottom - top, spec.width, -1)[y0 - top:y1 - top]


@contextmanager
def held_stderr():
    """stderr (the file descriptor: the C libraries write there) into a temporary file while
    the block runs, written out after it; yields a list whose one item the block sets to
    False to drop what was written (an error that its own message reports)."""
    keep = [True]
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no real descriptor: nothing held
        yield keep
        return
    tmp = tempfile.TemporaryFile()
    os.dup2(tmp.fileno(), 2)
    try:
        yield keep
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        if keep[0]:
            tmp.seek(0)
            text = tmp.read()
            if text:
                os.write(2, text)
        tmp.close()
