# SPDX-License-Identifier: GPL-3.0-or-later
"""Command line: ``python -m hazy_gloss convert ...`` (on the ``bpy`` module) or, inside Blender,
``blender -b --python-expr "import sys; from bl_ext.user_default.hazy_gloss.__main__ import main;
sys.exit(main(['convert', ...]))"``.  See docs/textures.md.

Exit status (constants.EXIT_*; tested in tests/blender/test_convert.py and tests/pure):

- 0: success;
- 2: bad input or usage, one line ``hazy_gloss convert: error: <reason>`` on stderr (missing,
  unreadable, truncated or non-image file, mismatched sizes, bad kind or constant, empty or
  unwritable --out, bad --prefix, unknown flag); nothing is written;
- 3: the bpy module is not importable (one line);
- 130 (SIGINT, Ctrl+C) or 143 (SIGTERM): interrupted, one line; the maps this run wrote are
  removed and the maps it was replacing restored, so the output folder is as it was (a signal
  after the last map is in place says so instead: the new set is complete);
- 1: an internal error (a bug: Python prints a traceback).
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys

from . import constants as K

#: (parameter name, flag) of the map/constant inputs.
INPUT_FLAGS = (
    ("core_reflectivity", "--core-reflectivity"),
    ("edge_tint", "--edge-tint"),
    ("roughness", "--roughness"),
    ("alpha", "--alpha"),
    ("anisotropy", "--anisotropy"),
    ("rotation", "--rotation"),
    ("haziness", "--haziness"),
    ("haze_extent", "--haze-extent"),
    ("haze_extent_x", "--haze-extent-x"),
    ("haze_extent_y", "--haze-extent-y"),
)
PROG = "hazy_gloss convert"


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage block
        self.exit(2, f"{PROG}: error: {message}\n")


def parse_value(text):
    """A constant ("0.5", "0.9,0.6,0.3") or a path (anything else, or an existing file)."""
    if os.path.exists(text):
        return text
    try:
        nums = [float(p) for p in text.split(",")]
    except ValueError:
        return text
    return nums[0] if len(nums) == 1 else tuple(nums)


def build_parser():
    parser = _Parser(prog="python -m hazy_gloss",
                     description="Hazy Gloss command line tools (run on the bpy module or "
                                 "inside Blender).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    conv = sub.add_parser(
        "convert", help="convert perceptual maps into physical maps",
        description="Convert perceptual hazy-gloss maps into physical maps (float OpenEXR by "
                    "default).  Each input is an image path (use <UDIM> for tile sets) or a "
                    "constant: a number, or r,g,b for colours.  Missing inputs take the "
                    "defaults of api.create_material.")
    for name, flag in INPUT_FLAGS:
        conv.add_argument(flag, dest=name, metavar="PATH|VALUE", default=None)
    conv.add_argument("--kind", default="CONDUCTOR", type=str.upper,
                      help="CONDUCTOR (default), DIELECTRIC or LEGACY")
    conv.add_argument("--distribution", default="GGX", type=str.upper,
                      help="GGX (default), BECKMANN, MULTI_GGX, ASHIKHMIN_SHIRLEY (legacy)")
    conv.add_argument("--smoothness", type=float, default=None,
                      help="Bézier weight w (Eqs. 12-15); default: Eq. 7")
    conv.add_argument("--format", dest="file_format", default="OPEN_EXR", type=str.upper,
                      help="OPEN_EXR (default, 32-bit float) or PNG (16-bit, encoded)")
    conv.add_argument("--exr-codec", default="ZIP", help="EXR codec (default ZIP, lossless)")
    conv.add_argument("--prefix", default="", help="prefix of the output file names")
    conv.add_argument("--resample", action="store_true",
                      help="resample inputs of other sizes to the largest (bilinear)")
    conv.add_argument("--out", required=True, help="output folder (created if needed)")
    conv.add_argument("--json", action="store_true", help="print the report as JSON")
    conv.add_argument("--quiet", action="store_true", help="print nothing on success")
    return parser


class Interrupted(KeyboardInterrupt):
    """Raised by the CLI's SIGINT / SIGTERM handler (the conversion undoes its files)."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


def _raise_interrupted(signum, frame):
    raise Interrupted(signum)


class _Signals:
    """The CLI's SIGINT / SIGTERM handling (signals ignored at start, e.g. under nohup, stay
    ignored).  First the signals are only recorded: an exception raised inside ``import bpy``
    leaves Blender half initialised (tracebacks from its registration, crashes at exit);
    :meth:`arm` then reports a recorded one and makes the next ones raise Interrupted, which the
    conversion undoes; :meth:`hold` records them again once the maps are in place (reported
    after the summary); :meth:`restore` puts the previous handlers back."""

    def __init__(self):
        self.saved, self.pending = {}, []
        for name in ("SIGINT", "SIGTERM"):
            sig = getattr(signal, name, None)
            if sig is None:
                continue
            try:
                old = signal.getsignal(sig)
                if old is signal.SIG_IGN:
                    continue
                signal.signal(sig, self._record)
            except (ValueError, OSError):  # not the main thread
                continue
            self.saved[sig] = old

    def _record(self, signum, frame):
        self.pending.append(signum)

    def arm(self):
        for sig in self.saved:
            signal.signal(sig, _raise_interrupted)
        if self.pending:
            raise Interrupted(self.pending[0])

    def hold(self):
        for sig in self.saved:
            signal.signal(sig, self._record)

    def ignore(self):
        for sig in self.saved:
            signal.signal(sig, signal.SIG_IGN)

    def restore(self):
        for sig, old in self.saved.items():
            signal.signal(sig, old if old is not None else signal.SIG_DFL)


def _error(message, code=K.EXIT_BAD_INPUT):
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return code


def _convert(args):
    signals = _Signals()
    try:
        try:
            code = _run_convert(args, signals)
            if code == K.EXIT_OK and signals.pending:  # arrived after the maps were in place
                exc = Interrupted(signals.pending[0])
                exc.committed = True
                raise exc
            return code
        finally:
            if __name__ == "__main__":  # a CLI process: its status is decided, it only exits
                signals.ignore()  # now (Python's shutdown would reset a handler to default)
            else:  # in-process (inside Blender): hand the signals back
                signals.restore()
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", signal.SIGINT)
        name = signal.Signals(signum).name
        if getattr(exc, "committed", False):
            print(f"{PROG}: interrupted ({name}) after every map was written and verified; the "
                  "new maps are in place", file=sys.stderr)
        else:
            print(f"{PROG}: interrupted ({name}); the maps of this run were removed and the "
                  "output folder is as it was", file=sys.stderr)
        return K.EXIT_INTERRUPTED.get(int(signum), 128 + int(signum))


def _run_convert(args, signals):
    if not args.out.strip():
        return _error(f"--out must name a folder, got {args.out!r}")
    inputs = {name: parse_value(getattr(args, name)) for name, _ in INPUT_FLAGS
              if getattr(args, name) is not None}
    try:
        import bpy  # noqa: F401  (the conversion reads and writes images through Blender)
    except ImportError as exc:
        return _error(f"bpy is not importable ({exc}); install the bpy module or run inside "
                      "Blender", K.EXIT_NO_BPY)
    from . import api
    from .blender import convert as _  # noqa: F401  (imported before the signals raise)
    from .convert import ConversionError
    signals.arm()
    try:
        result = api.convert_maps(inputs, args.out, kind=args.kind,
                                  smoothness=args.smoothness, distribution=args.distribution,
                                  file_format=args.file_format, resample=args.resample,
                                  prefix=args.prefix, exr_codec=args.exr_codec)
    except ConversionError as exc:
        return _error(exc)
    except OSError as exc:  # not expected (the conversion turns them into ConversionError)
        return _error(f"{exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}")
    except MemoryError:
        return _error("not enough memory for these images")
    signals.hold()  # the maps are in place: a signal now is reported after the summary
    rep = result.report
    if args.json:
        print(json.dumps({"maps": dict(result), "texels": rep.texels, "size": list(rep.size),
                          "tiles": rep.tiles, "seconds": rep.seconds, "clamped": rep.clamped,
                          "clamped_by_parameter": rep.clamped_by_parameter,
                          "warnings": rep.warnings}, indent=1))
    elif not args.quiet:
        print(rep.summary(len(result)))
        for w in rep.warnings:
            print(f"warning: {w}")
        for name, path in result.items():
            print(f"{name}: {path}")
    return K.EXIT_OK


def main(argv=None):
    args = build_parser().parse_args(argv)
    if args.command == "convert":
        return _convert(args)
    return 2  # pragma: no cover (argparse requires a command)


if __name__ == "__main__":
    sys.exit(main())
