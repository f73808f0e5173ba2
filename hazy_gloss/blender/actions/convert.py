# SPDX-License-Identifier: GPL-3.0-or-later
"""Texture batch conversion through bpy: perceptual maps in, physical maps out, strip by strip.

The numeric part (validation, Blender's conventions, haze mapping, PNG encodings) is bpy-free
in ``conversion/convert.py``, the strip readers and writers in ``conversion/imagestream.py``;
what needs Blender is in four modules:

- blender/model/convert_inputs.py: reading the perceptual maps in strips (files through Blender's own
  OpenImageIO, datablocks in place), every file checked before Blender reads it;
- blender/model/convert_outputs.py: writing float OpenEXR or 16-bit PNG strip by strip through
  OpenImageIO, **all or nothing** (the maps proved by decoding them once, renamed into place
  together, the folder restored on any failure, interruption or cancel);
- this module: the options checked, the run (:func:`convert_maps_steps`, a generator that
  yields after every strip: the modal operator steps it between events), each strip mapped
  from perceptual to physical values (:class:`_Run`);
- blender/model/convert_wiring.py: the written maps wired into a material's lean node tree
  (:func:`wire_material`).

The operator is ``convert_ops.HAZY_GLOSS_OT_convert_maps``.
"""
from __future__ import annotations

import os
import re
import stat
import time

import bpy
import numpy as np

from ... import constants as K
from ...conversion import convert as conversion
from ...conversion import imagestream as stream
from ...conversion.convert import ConversionError
from ...conversion.oiio import openimageio
from ..model.convert_inputs import UDIM_TOKEN, Source, os_reason, short_repr, tile_paths, udim_tiles
from ..model.convert_outputs import (EXTENSIONS, MapFile, Transaction, check_codec, final_path,
                                     out_path, undo_run)
from ..model.convert_wiring import wire_material

__all__ = ("check_prefix", "check_targets", "convert_maps", "convert_maps_steps")


# --------------------------------------------------------------------------------------------
# Conversion
# --------------------------------------------------------------------------------------------


def check_prefix(prefix):
    if prefix is None:
        return ""
    if not isinstance(prefix, str):
        raise ConversionError(f"prefix must be a string, got {type(prefix).__name__} {short_repr(prefix)}")
    if any(c in "/\\" or ord(c) < 32 or ord(c) == 127 for c in prefix) or \
            prefix.startswith(".") or ".." in prefix:
        raise ConversionError(f"prefix must be a plain file-name prefix (no path separator, control "
                              f"or NUL character, leading '.' or '..'), got {prefix!r}")
    return prefix


def _check_options(material, interpolation, progress, tile_texels, resample):
    """The options that are used after the maps are written: checked before anything is."""
    if material is not None:
        if not isinstance(material, bpy.types.Material):
            hint = (f" (use bpy.data.materials[{material!r}])" if isinstance(material, str) else "")
            raise ConversionError(f"material must be a bpy.types.Material or None, got "
                                  f"{type(material).__name__} {short_repr(material)}{hint}")
        if material.library is not None:
            raise ConversionError(f"material {material.name!r} is linked from a library and "
                                  "cannot be edited")
    items = [e.identifier for e in
             bpy.types.ShaderNodeTexImage.bl_rna.properties["interpolation"].enum_items]
    if interpolation not in items:
        raise ConversionError(f"interpolation must be one of {', '.join(items)}; got "
                              f"{short_repr(interpolation)}")
    if progress is not None and not callable(progress) and not isinstance(progress, conversion.Progress):
        raise ConversionError(f"progress must be None or a callable(done, total, message), got "
                              f"{type(progress).__name__}")
    if isinstance(tile_texels, bool) or not isinstance(tile_texels, (int, np.integer)) or \
            tile_texels < 1:
        raise ConversionError(f"tile_texels must be a positive integer, got {short_repr(tile_texels)}")
    if not isinstance(resample, (bool, np.bool_)):
        raise ConversionError(f"resample must be True or False, got {short_repr(resample)}")


def _materials_reading(targets, material=None):
    """Names of the file's materials (but ``material``) whose image nodes read one of the files
    ``targets`` (a UDIM image: any of its tiles)."""
    want = {os.path.normcase(os.path.realpath(t)) for t in targets}
    images = set()
    for img in bpy.data.images:
        path = img.filepath_raw or img.filepath
        if img.library is not None or not path or img.source not in ("FILE", "TILED"):
            continue
        path = os.path.normcase(os.path.realpath(bpy.path.abspath(path)))
        tiles = re.sub(r"<udim>", "\0", path, flags=re.IGNORECASE)  # (a UDIM image's token)
        pattern = re.escape(tiles).replace("\0", r"\d{4}") if "\0" in tiles else None
        if path in want or (pattern and any(re.fullmatch(pattern, t) for t in want)):
            images.add(img.name)
    if not images:
        return []
    return sorted(m.name for m in bpy.data.materials
                  if m != material and m.node_tree is not None and any(
                      n.bl_idname == "ShaderNodeTexImage" and n.image is not None
                      and n.image.name in images for n in m.node_tree.nodes))


def check_targets(targets, input_files, txn, material=None):
    """Before anything is written: no target is an input (same path or same file), a folder, a
    name too long for the file system, or a map a material of this file reads (other than
    ``material``, the one this conversion updates: the other would render the new maps while
    its panel shows the haze it was converted with)."""
    readers = _materials_reading(targets, material)
    if readers:
        shown = ", ".join(f"“{m}”" for m in readers[:3]) + (", ..." if len(readers) > 3 else "")
        one = len(readers) == 1
        raise ConversionError(f"{os.path.dirname(targets[0])}: the material{'' if one else 's'} "
                              f"{shown} of this file read{'s' if one else ''} the maps there "
                              f"(converted before), which this run would replace: convert into "
                              f"another folder, or delete {'it' if one else 'them'} first")
    input_ids = set()
    for p in input_files:
        try:
            st = os.stat(p)
            input_ids.add((st.st_dev, st.st_ino))
        except OSError:
            pass
    for t in targets:
        if len(os.fsencode(os.path.basename(txn.side(t, "tmp")))) > 255:
            raise ConversionError(f"output file name {os.path.basename(t)!r} is too long; use a "
                                  "shorter prefix")
        try:
            st = os.stat(t)
        except FileNotFoundError:
            st = None
        except OSError as exc:
            raise ConversionError(f"output {t}: {os_reason(exc)}") from None
        if os.path.realpath(t) in input_files or (st is not None and (st.st_dev, st.st_ino) in input_ids):
            raise ConversionError(f"output {t} would overwrite an input; choose another folder "
                                  "or prefix")
        if st is not None and stat.S_ISDIR(st.st_mode):
            raise ConversionError(f"output {t} is a folder; remove it or choose another folder "
                                  "or prefix")


def _all_map_names():
    return sorted({s.name for k in K.KINDS for s in conversion.output_specs(k, True)},
                  key=len, reverse=True)


def convert_maps(inputs, out_dir, **options):
    """Convert perceptual maps to physical maps, all or nothing; see hazy_gloss.api.convert_maps.
    Blocking: runs :func:`convert_maps_steps` to its end."""
    return conversion.drain(convert_maps_steps(inputs, out_dir, **options))


def convert_maps_steps(inputs, out_dir, *, kind="CONDUCTOR", smoothness=None, distribution="GGX",
                       file_format="OPEN_EXR", resample=False, prefix="", exr_codec="ZIP",
                       material=None, interpolation="Linear", progress=None,
                       tile_texels=K.STRIP_TEXELS, threads=None):
    """The conversion as a generator: it yields after every strip (the modal operator steps it
    between events) and returns the ConversionResult.  ``progress``: a callable(done, total,
    message) or a conversion.Progress (whose cancel() stops the run, undone, at the next strip)."""
    t0 = time.perf_counter()
    started = time.time()
    file_format = str(file_format).upper()
    specs, notes = conversion.resolve_inputs(inputs, kind=kind, distribution=distribution,
                                       smoothness=smoothness, file_format=file_format)
    kind, distribution = str(kind).upper(), str(distribution).upper()
    prefix = check_prefix(prefix)
    _check_options(material, interpolation, progress, tile_texels, resample)
    codec = check_codec(file_format, exr_codec)
    prog = progress if isinstance(progress, conversion.Progress) else conversion.Progress(progress)
    sources = {n: Source(n, s.role, s.source) for n, s in specs.items() if not s.is_constant}
    # a haze extent shared by both axes is read once
    shared_extent = (specs["haze_extent_x"].given_as == "haze_extent"
                     and not specs["haze_extent_x"].is_constant)
    if shared_extent:
        sources.pop("haze_extent_y", None)

    tiles = udim_tiles(sources)
    for src in sources.values():  # every input file, before anything is written
        src.check()
    out_dir = out_path(out_dir)
    input_files = {os.path.realpath(p) for s in sources.values() for p in s.files()}

    report = conversion.ConversionReport(kind=kind, distribution=distribution, file_format=file_format,
                                   tiles=list(tiles), warnings=list(notes))
    ext = EXTENSIONS[file_format]
    jobs = tiles or [None]
    txn = Transaction(out_dir, started)
    check_targets([final_path(out_dir, prefix, s.name, tile, ext)
                    for tile in jobs for s in conversion.output_specs(kind, True)], input_files, txn,
                   material)
    alpha_given = specs["roughness"].transform == "sqrt"
    run = _Run(specs, sources, shared_extent, resample, report, prog, alpha_given, tile_texels)
    try:
        txn.make_folder()
        stale = txn.clean_stale(_all_map_names())
        if stale:
            report.warnings.append(f"removed {len(stale)} temporary file(s) left in "
                                   f"{out_dir} by an interrupted earlier conversion")
        anisotropic = yield from run.anisotropy(jobs)
        out_specs = conversion.output_specs(kind, anisotropic)
        report.anisotropic = anisotropic
        paths = {s.name: final_path(out_dir, prefix, s.name, UDIM_TOKEN if tiles else None, ext)
                 for s in out_specs}
        for tile in jobs:
            if tile:
                prog.next_item(jobs.index(tile), len(jobs), tile, key="tile")
            finals = {s.name: final_path(out_dir, prefix, s.name, tile, ext) for s in out_specs}
            yield from run.tile(tile, finals, txn, out_specs, kind, distribution, smoothness,
                                anisotropic, file_format, codec, threads)
        retire = []
        if tiles:  # tiles of an earlier, larger set would join this one in a tiled image
            for s in out_specs:
                on_disk = tile_paths(final_path(out_dir, prefix, s.name, UDIM_TOKEN, ext))
                retire += [p for t, p in sorted(on_disk.items()) if t not in tiles]
            if retire:
                report.warnings.append("removed UDIM tiles of an earlier conversion that are not "
                                       "in this set: " + ", ".join(os.path.basename(p) for p in retire))
        prog.check()  # the last point where a cancel undoes the run
        txn.commit(retire)
    except BaseException as exc:
        undo_run(txn, exc)
        raise
    report.warnings = list(dict.fromkeys(report.warnings))
    report.seconds = time.perf_counter() - t0
    result = conversion.ConversionResult(paths, report, out_specs)
    if material is not None:
        wire_material(material, result, interpolation=interpolation)
    return result


class _Run:
    """The inputs of one conversion, opened tile by tile as strip readers."""

    def __init__(self, specs, sources, shared_extent, resample, report, prog, alpha_given,
                 tile_texels):
        self.specs, self.sources, self.shared = specs, sources, shared_extent
        self.resample, self.report, self.prog = resample, report, prog
        self.alpha_given, self.tile_texels = alpha_given, tile_texels
        self.constants = {n: s.source for n, s in specs.items() if s.is_constant}
        self.oiio = openimageio()

    def open(self, tile, names=None):
        """({name: _Decoded}, (w, h)) of this tile's inputs, sizes checked (or resampled)."""
        readers, sizes = {}, []
        try:
            for name, src in self.sources.items():
                if names is not None and name not in names:
                    continue
                r = src.strips(tile, self.report.warnings, self.oiio)
                readers[name] = r
                sizes.append((src.label + (f" tile {tile}" if tile else ""), (r.width, r.height), name))
            target = max((s for _, s, _ in sizes), key=lambda s: s[0] * s[1])
            if self.resample:
                for label, size, name in sizes:
                    if size != target:
                        if names is None:
                            self.report.warnings.append(
                                f"{label}: resampled from {size[0]}x{size[1]} to "
                                f"{target[0]}x{target[1]} (bilinear)")
                        readers[name] = _Resampled(readers[name], target)
            else:
                conversion.check_sizes([(label, size) for label, size, _ in sizes])
        except BaseException:
            for r in readers.values():
                r.close()
            raise
        return readers, target

    def _arrays(self, readers, y0, y1):
        arrays = dict(self.constants)
        for name, r in readers.items():
            arrays[name] = r.rows(y0, y1)
        if self.shared:
            arrays["haze_extent_y"] = arrays["haze_extent_x"]
        return arrays

    def anisotropy(self, jobs):
        """Whether the set needs the anisotropic maps, known before anything is written: from
        the constants, or by reading the anisotropy and haze extent maps first (all tiles:
        they must agree)."""
        c = self.constants
        names = [n for n in ("anisotropy", "haze_extent_x", "haze_extent_y") if n in self.sources]
        if "anisotropy" in c and float(c["anisotropy"]) > 0:
            return True
        if "haze_extent_x" in c and "haze_extent_y" in c:
            if float(c["haze_extent_x"]) != float(c["haze_extent_y"]):
                return True
            if "anisotropy" in c:
                return False
        if self.shared and names == ["haze_extent_x"] and "anisotropy" in c:
            return False
        for tile in jobs:
            readers, (w, h) = self.open(tile, names=names)
            try:
                rows = stream.strip_rows(w, self.tile_texels)
                for y0 in range(0, h, rows):
                    y1 = min(h, y0 + rows)
                    arrays = self._arrays(readers, y0, y1)
                    for n in conversion.PARAMETERS:  # inputs not read here: their defaults
                        arrays.setdefault(n, np.float32(conversion.DEFAULTS[n]))
                    clean = conversion.sanitise_inputs(arrays, {}, alpha_given=self.alpha_given)
                    self.prog.advance(0, "checking anisotropy" + (f" of tile {tile}" if tile else ""))
                    if conversion.is_anisotropic(clean):
                        return True
                    yield
            finally:
                for r in readers.values():
                    r.close()
        return False

    def tile(self, tile, finals, txn, out_specs, kind, distribution, smoothness, anisotropic,
             file_format, codec, threads):
        """One tile (or the single image): its maps written to temporaries and verified."""
        readers, (w, h) = self.open(tile)
        if self.report.size == (0, 0):
            self.report.size = (w, h)
        files = {}
        try:
            for s in out_specs:
                files[s.name] = MapFile(file_format, codec, txn.temp(finals[s.name]),
                                         finals[s.name], w, h)
            yield from self.strips(readers, files, out_specs, (w, h), kind, distribution,
                                   smoothness, anisotropic, file_format, threads)
            for s in out_specs:
                files[s.name].finish()
                self.prog.advance(0, f"wrote {s.name}")
        finally:
            for f in files.values():
                f.abort()
            for r in readers.values():
                r.close()
        self.report.texels += w * h

    def strips(self, readers, files, out_specs, size, kind, distribution, smoothness,
               anisotropic, file_format, threads):
        """Map and write every strip of one tile (the strips run on a thread pool)."""
        w, h = size
        rows = stream.strip_rows(w, self.tile_texels)
        self.prog.begin(h)
        counts = []

        def read(y0, y1):
            return self._arrays(readers, y0, y1)

        def compute(y0, y1, arrays):
            clamped = {}
            clean = conversion.sanitise_inputs(arrays, clamped, alpha_given=self.alpha_given)
            maps, limits = conversion.describe_maps(clean, kind=kind, distribution=distribution,
                                              smoothness=smoothness, anisotropic=anisotropic,
                                              shape=(y1 - y0, w))
            conversion.add_counts(clamped, limits)
            encoded = {}
            for s in out_specs:
                values = maps[s.name]
                if file_format == "PNG":
                    values = conversion.encode_png(s, values)
                encoded[s.name] = files[s.name].encode(y0, values)
            return clamped, encoded

        def write(y0, y1, result):
            clamped, encoded = result
            counts.append(clamped)
            for s in out_specs:
                files[s.name].append(encoded[s.name])

        done = 0
        for y1, _ in stream.run_strips(h, rows, read, compute, write, workers=threads):
            self.prog.advance(y1 - done, "mapping and writing")
            done = y1
            yield
        for c in counts:  # in strip order: the report does not depend on the thread schedule
            conversion.add_counts(self.report.clamped, c)


class _Resampled:
    """Rows of a smaller (or larger) input resampled bilinearly to ``size`` (texel centres
    aligned, edges clamped: conversion.resample_bilinear), reading the source rows a strip needs,
    in order, keeping only those still needed."""

    def __init__(self, reader, size):
        self.reader, self.label = reader, reader.label
        self.width, self.height = int(size[0]), int(size[1])
        self.ys = conversion.resample_axis(self.height, reader.height)
        self.xs = conversion.resample_axis(self.width, reader.width)
        self._y0, self._rows = 0, None

    def _source(self, a, b):
        if self._rows is None or a < self._y0:
            self._y0, self._rows = a, self.reader.rows(a, b)
        have = self._y0 + self._rows.shape[0]
        if b > have:
            new = self.reader.rows(have, b)
            self._rows = np.concatenate([self._rows[max(0, a - self._y0):], new])
            self._y0 = max(a, self._y0)
        return self._rows[a - self._y0:b - self._y0]

    def rows(self, y0, y1):
        i0, i1, fy = (v[y0:y1] for v in self.ys)
        a, b = int(i0.min()), int(i1.max()) + 1
        block = self._source(a, b)
        return conversion.resample_block(block, i0 - a, i1 - a, fy, self.xs)

    def close(self):
        self.reader.close()
