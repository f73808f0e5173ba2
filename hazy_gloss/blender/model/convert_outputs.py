# SPDX-License-Identifier: GPL-3.0-or-later
"""The outputs of a texture conversion: physical maps written, verified, committed all or nothing.

Float OpenEXR (default, lossless ZIP) or 16-bit PNG is written strip by strip by OpenImageIO;
every map goes to a temporary name in the output folder and is proved by decoding it once
(:class:`MapFile`); :class:`Transaction` checks the folder, renames every map into place
(backing up the ones it replaces) and, on any failure, interruption or cancel, removes the
run's files and restores the maps it replaced (:func:`undo_run`).
"""
from __future__ import annotations

import os
import re
import shutil
import uuid

import bpy

from ... import constants as K
from ...conversion import imagestream as stream
from ...conversion.convert import ConversionError
from ...conversion.oiio import MISSING, openimageio
from .convert_inputs import DeferredSignals, absolute_path, os_reason, short_repr

__all__ = ("EXTENSIONS", "exr_codecs", "check_codec", "MapFile", "Transaction", "out_path",
           "undo_run", "final_path")

EXTENSIONS = {"OPEN_EXR": ".exr", "PNG": ".png"}

# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------

_CODECS = []


def exr_codecs():
    """The EXR codecs Blender offers for 32-bit float (measured once: the enum items a 32-bit
    EXR format accepts; B44 is for half floats)."""
    if _CODECS:
        return _CODECS[0]
    scene = bpy.data.scenes.new(".hazy_gloss_codecs")
    try:
        s = scene.render.image_settings
        if hasattr(s, "media_type"):  # 5.0
            s.media_type = "IMAGE"
        s.file_format, s.color_mode, s.color_depth = "OPEN_EXR", "RGB", "32"
        codecs = []
        for item in s.bl_rna.properties["exr_codec"].enum_items:
            try:
                s.exr_codec = item.identifier
                codecs.append(item.identifier)
            except TypeError:
                pass
    finally:
        bpy.data.scenes.remove(scene)
    _CODECS.append(tuple(codecs))
    return _CODECS[0]


def check_codec(file_format, exr_codec):
    _require_oiio()
    if file_format != "OPEN_EXR":
        return "ZIP"
    codecs = exr_codecs()
    codec = exr_codec.upper() if isinstance(exr_codec, str) else exr_codec
    if codec not in codecs:
        lossless = [c for c in codecs if c in K.LOSSLESS_EXR_CODECS]
        raise ConversionError(f"exr_codec must be one of {', '.join(codecs)} (lossless: "
                              f"{', '.join(lossless)}); got {short_repr(exr_codec)}")
    return codec


def _require_oiio():
    oiio = openimageio()
    if oiio is None:
        raise ConversionError(f"{MISSING}: the maps cannot be written")
    return oiio


class MapFile:
    """One output map written to its temporary in strips (hazy_gloss.conversion.imagestream, through
    OpenImageIO) and proved complete at the end: the file decodes to what was written (lossy
    codecs: to finite values).  I/O errors become one-line ConversionErrors naming ``final``."""

    def __init__(self, file_format, codec, tmp, final, width, height):
        self.tmp, self.final = tmp, final
        try:
            self.writer = stream.OiioStripWriter(_require_oiio(), tmp, width, height,
                                                 file_format, codec)
        except OSError as exc:
            raise ConversionError(f"could not write {final}: {os_reason(exc)}") from None
        except stream.StripError as exc:
            raise ConversionError(f"could not write {final}: {exc}") from None

    def encode(self, y0, values):
        return self.writer.encode(y0, values)

    def append(self, encoded):
        try:
            self.writer.append(encoded)
        except OSError as exc:
            raise ConversionError(f"could not write {self.final}: {os_reason(exc)}") from None

    def close_file(self):
        """The one call that completes a file (a seam for the tests' full-disk simulation)."""
        self.writer.close()

    def finish(self):
        try:
            self.close_file()
        except OSError as exc:
            raise ConversionError(f"could not write {self.final}: {os_reason(exc)}") from None
        try:
            self.writer.verify()
        except (stream.StripError, ConversionError) as exc:
            raise ConversionError(f"could not write {self.final} (disk full?): {exc}") from None
        except OSError as exc:
            raise ConversionError(f"could not write {self.final}: it does not read back "
                                  f"({os_reason(exc)})") from None

    def abort(self):
        try:
            self.writer.abort()
        except OSError:
            pass


# --------------------------------------------------------------------------------------------
# All or nothing: temporaries, backups, commit, undo
# --------------------------------------------------------------------------------------------


def _remove(path):
    try:
        os.remove(path)
    except FileNotFoundError:
        pass
    except OSError:
        return False
    return True


class Transaction:
    """The files of one conversion, all or nothing.

    Maps are written to temporaries ``.<name>.<run>.tmp<ext>`` in the output folder (same file
    system: renames are atomic) and verified; :meth:`commit` then backs up every map it replaces
    (a hard link ``.<name>.<run>.bak<ext>``, a copy where links are not supported), renames the
    temporaries into place and deletes the backups only once every map is in place.  On any
    failure or interruption :meth:`rollback` restores the replaced maps from their backups,
    deletes the maps new in this run and every temporary, and removes the folders the run
    created.  Temporaries and backups left by a killed earlier run are deleted by
    :meth:`clean_stale` (only names of this pattern, older than this run)."""

    def __init__(self, out_dir, started):
        self.out_dir = out_dir
        self.started = started
        self.run = uuid.uuid4().hex[:K.CONVERT_RUN_ID_HEX]
        self.created = []  # folders made by this run, parents first
        self.temps = {}  # final path -> temporary path
        self.backups = {}  # final path -> backup of the file it replaces
        self.renamed = []  # finals renamed into place by this run
        self.retired = {}  # stale file moved aside at commit -> its backup
        self.committed = False
        self.problems = []

    def side(self, final, tag):
        folder, base = os.path.split(final)
        stem, ext = os.path.splitext(base)
        return os.path.join(folder, f".{stem}.{self.run}.{tag}{ext}")

    def temp(self, final):
        """The temporary for ``final``, recorded before it exists (a failure while it is being
        written still removes it)."""
        return self.temps.setdefault(final, self.side(final, "tmp"))

    def make_folder(self):
        """Create the output folder and its missing parents (recorded for the rollback), then
        check that files can be created in it."""
        missing, p = [], self.out_dir
        while not os.path.isdir(p):
            if os.path.lexists(p):
                raise ConversionError(f"output folder {self.out_dir}: {p} is not a folder")
            missing.append(p)
            parent = os.path.dirname(p)
            if parent == p:
                break
            p = parent
        for d in reversed(missing):
            try:
                os.mkdir(d)
            except FileExistsError:
                if not os.path.isdir(d):
                    raise ConversionError(f"output folder {self.out_dir}: {d} is not a folder") from None
                continue
            except OSError as exc:
                raise ConversionError(f"cannot create the output folder {self.out_dir}: "
                                      f"{os_reason(exc)}") from None
            self.created.append(d)
        probe = self.side(os.path.join(self.out_dir, "hazy_gloss_probe.png"), "tmp")
        try:
            fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except OSError as exc:
            raise ConversionError(f"the output folder {self.out_dir} is not writable: "
                                  f"{os_reason(exc)}") from None
        os.close(fd)
        _remove(probe)

    def clean_stale(self, names):
        """Delete temporaries and backups of earlier runs: ``.<prefix><map>[.<tile>].<hex>.(tmp|
        bak).<ext>`` for a map name in ``names``, last modified before this run started."""
        rx = re.compile(r"\.(?P<stem>.+)\.(?P<run>[0-9a-f]{%d})\.(?:tmp|bak)(?:%s)\Z" % (
            K.CONVERT_RUN_ID_HEX, "|".join(re.escape(e) for e in EXTENSIONS.values())))
        removed = []
        try:
            entries = list(os.scandir(self.out_dir))
        except OSError:
            return removed
        for entry in entries:
            m = rx.match(entry.name)
            if m is None or m["run"] == self.run:
                continue
            stem = re.sub(r"\.\d{4}\Z", "", m["stem"])
            if stem != "hazy_gloss_probe" and not any(stem.endswith(n) for n in names):
                continue
            try:
                if not entry.is_file(follow_symlinks=False) or \
                        entry.stat(follow_symlinks=False).st_mtime >= self.started:
                    continue
            except OSError:
                continue
            if _remove(entry.path):
                removed.append(entry.name)
        return removed

    def commit(self, retire=()):
        """Move ``retire`` (stale files of an earlier set) aside, rename every temporary into
        place, then delete the backups.  Interruptions are handled between renames (undone)."""
        with DeferredSignals() as sig:
            try:
                for path in retire:
                    bak = self.side(path, "bak")
                    os.replace(path, bak)
                    self.retired[path] = bak
                    sig.poll()
                for final, tmp in self.temps.items():
                    if os.path.lexists(final):
                        bak = self.side(final, "bak")
                        try:
                            os.link(final, bak, follow_symlinks=False)
                        except OSError:  # no hard links here: a copy
                            shutil.copy2(final, bak, follow_symlinks=False)
                        self.backups[final] = bak
                    os.replace(tmp, final)
                    self.renamed.append(final)
                    sig.poll()
                sig.poll()  # the last point where the whole set can still be undone
            except BaseException:
                self.undo_run()
                raise
            self.committed = True
            for bak in [*self.backups.values(), *self.retired.values()]:
                _remove(bak)

    def rollback(self):
        """Undo everything this run did to the folder; returns what could not be undone."""
        with DeferredSignals():
            self.undo_run()
        return self.problems

    def undo_run(self):
        for final in reversed(self.renamed):
            bak = self.backups.pop(final, None)
            try:
                if bak is not None:
                    os.replace(bak, final)
                else:
                    os.remove(final)
            except OSError as exc:
                self.problems.append(f"could not restore {final} ({os_reason(exc)})"
                                     + (f"; its previous version is {bak}" if bak else ""))
        self.renamed.clear()
        for path, bak in list(self.retired.items()):
            try:
                os.replace(bak, path)
                del self.retired[path]
            except OSError as exc:
                self.problems.append(f"could not restore {path} ({os_reason(exc)}); it is {bak}")
        for tmp in self.temps.values():
            _remove(tmp)
        self.temps.clear()
        for bak in self.backups.values():  # backups of finals that were not replaced yet
            _remove(bak)
        self.backups.clear()
        for d in reversed(self.created):
            try:
                os.rmdir(d)
            except OSError:
                break
        self.created.clear()


def out_path(out_dir):
    """Absolute output folder ('//' is relative to the saved .blend); not created here."""
    if out_dir is None:
        raise ConversionError("out_dir: no output folder given")
    if not isinstance(out_dir, (str, bytes, os.PathLike)):
        raise ConversionError(f"out_dir must be a folder path, got {type(out_dir).__name__} "
                              f"{short_repr(out_dir)}")
    text = os.fspath(out_dir)
    text = os.fsdecode(text) if isinstance(text, bytes) else text
    if not text.strip():
        raise ConversionError(f"out_dir must name a folder, got {text!r}")
    path = absolute_path(text, what="out_dir")
    p = path
    while not os.path.isdir(p):  # the first existing ancestor must be a folder
        if os.path.lexists(p):
            raise ConversionError(f"output folder is a file: {p}" if p == path else
                                  f"output folder {path}: {p} is a file, not a folder")
        parent = os.path.dirname(p)
        if parent == p:
            break
        p = parent
    return path


def undo_run(txn, exc):
    """After a failure or an interruption: undo the run's files; OSErrors and failed undos become
    the one-line ConversionError (raised from here), anything else is re-raised by the caller."""
    if txn.committed:  # a signal held during the last clean-up: the set is complete
        exc.committed = True
        return
    problems = txn.rollback()
    extra = ("; " + "; ".join(problems)) if problems else ""
    if isinstance(exc, OSError):
        where = getattr(exc, "filename2", None) or exc.filename
        where = f"{where}: " if where else ""
        raise ConversionError(f"could not write the maps ({where}{os_reason(exc)}); "
                              + (extra[2:] if extra else "the output folder is unchanged")) from None
    if isinstance(exc, ConversionError) and extra:
        raise ConversionError(f"{exc}{extra}") from None
    if extra and hasattr(exc, "add_note"):
        exc.add_note(extra[2:])


def final_path(out_dir, prefix, name, tile, ext):
    return os.path.join(out_dir, f"{prefix}{name}{'.' + str(tile) if tile else ''}{ext}")
