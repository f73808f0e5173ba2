# SPDX-License-Identifier: GPL-3.0-or-later
"""Command line: ``python -m hazy_gloss convert ...`` (on the ``bpy`` module) or, inside Blender,
``blender -b --python-expr "import sys; from bl_ext.user_default.hazy_gloss.__main__ import main;
sys.exit(main(['convert', ...]))"``.  See docs/textures.md.

Interchange (docs/interchange.md): ``export-materialx BLEND OUT.mtlx [--flavour openpbr_1.2]
[--usd]`` (bpy), ``import-materialx FILE [--blend OUT.blend]`` (bpy only with --blend) and
``engines FILE`` (the closest parameters of other engines with their BRDF error).

Exit status (constants.EXIT_*; tested in tests/blender/test_convert.py and tests/pure):

- 0: success;
- 2: bad input or usage, one line ``hazy_gloss convert: error: <reason>`` on stderr (missing,
  unreadable, truncated or non-image file, mismatched sizes, bad kind or constant, empty or
  unwritable --out, bad --prefix, unknown flag); nothing is written;
- 3: the bpy module is not importable (one line);
- 4: ``--batch``: some sets failed (one line each on stderr), the others were converted;
- 130 (SIGINT, Ctrl+C) or 143 (SIGTERM): interrupted, one line; the maps this run wrote are
  removed and the maps it was replacing restored, so the output folder is as it was (a signal
  after the last map is in place says so instead: the new set is complete);
- 1: an internal error (a bug: Python prints a traceback).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import signal
import sys

from . import constants as K
from .schema import HAZE_MAP_INPUTS, LAYER_MAP_INPUTS

#: The core's maps of a perceptual conversion (the haze maps are the schema's HAZE_MAP_INPUTS).
_CORE_INPUTS = ("core_reflectivity", "edge_tint", "roughness", "alpha", "anisotropy", "rotation")
#: The maps of a PBR texture set (api.convert_maps' PBR form: a Principled material with a
#: baked layer); it also takes the haze layer's own haze maps (coat_haziness, ...).
_PBR_INPUTS = ("base_color", "metallic", "normal", "coat", "coat_roughness", "opacity")
#: (parameter name, flag) of the map/constant inputs.
INPUT_FLAGS = tuple((name, "--" + name.replace("_", "-"))
                    for name in _CORE_INPUTS + HAZE_MAP_INPUTS + _PBR_INPUTS)
PROG = "hazy_gloss convert"


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage block, named as the command typed
        self.exit(2, f"{self.prog.replace('python -m ', '')}: error: {as_flags(message)}\n")


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
    conv.add_argument("--blend", default=None,
                      help="PBR sets: save the material into this .blend (added to it if it "
                           "exists; Blender keeps the previous version as .blend1)")
    conv.add_argument("--name", default=None, help="PBR sets: the material's name")
    conv.add_argument("--batch", metavar="FOLDER", default=None,
                      help="a texture library: every subfolder of FOLDER is a PBR set and becomes "
                           "a material, its maps in --out/<subfolder>; each set all or nothing, "
                           "a summary at the end (haze inputs: constants for every set)")
    conv.add_argument("--json", action="store_true", help="print the report as JSON")
    conv.add_argument("--quiet", action="store_true",
                      help="print nothing on success (no progress bar)")
    conv.add_argument("--progress", action="store_true",
                      help="show the progress bar on stderr even when it is not a terminal")
    _add_interchange(sub)
    for command in sub.choices.values():  # (main names a command's own errors by it)
        command.set_defaults(command_parser=command)
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


#: Parameter names as the command line spells them (the API's messages name parameters).
_FLAG_NAMES = dict(INPUT_FLAGS, smoothness="--smoothness", file_format="--format",
                   exr_codec="--exr-codec", prefix="--prefix", kind="--kind",
                   distribution="--distribution")


def as_flags(message):
    """``message`` with the parameters it names spelt as flags: snake_case names anywhere (no
    prose has them), a plain word only as the subject it opens with."""
    text = str(message)
    names = sorted((n for n in _FLAG_NAMES if "_" in n), key=len, reverse=True)
    if names:
        text = re.sub(r"(?<![\w-])(" + "|".join(names) + r")(?!\w)",
                      lambda m: _FLAG_NAMES[m.group(1)], text)
    text = text.replace("None selects", "leaving it out selects")
    head = re.match(r"(\w+)(?=[: ])", text)
    if head and head.group(1) in _FLAG_NAMES:
        text = _FLAG_NAMES[head.group(1)] + text[head.end():]
    return text


def _error(message, code=K.EXIT_BAD_INPUT):
    print(f"{PROG}: error: {as_flags(message)}", file=sys.stderr)
    return code


def _convert(args):
    def interrupted(name, committed):
        if committed:
            return (f"{PROG}: interrupted ({name}) after every map was written and verified; "
                    "the new maps are in place")
        return (f"{PROG}: interrupted ({name}); the maps of this run were removed and the "
                "output folder is as it was")
    return _signalled(_run_convert, args, interrupted)


def _signalled(run, args, interrupted):
    """``run(args, signals)`` under the CLI's SIGINT / SIGTERM handling (:class:`_Signals`): an
    interruption is the one line ``interrupted(signal name, committed)`` and exit 130 / 143
    (``committed``: the signal came after the output was in place)."""
    signals = _Signals()
    try:
        try:
            code = run(args, signals)
            if code == K.EXIT_OK and signals.pending:  # arrived after the output was in place
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
        print(interrupted(name, getattr(exc, "committed", False)), file=sys.stderr)
        return K.EXIT_INTERRUPTED.get(int(signum), 128 + int(signum))


def _same_file(a, b):
    """Whether the paths ``a`` and ``b`` name one file (links and spellings included)."""
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.normcase(os.path.abspath(a)) == os.path.normcase(os.path.abspath(b))


def _blend_problem(path, inputs=()):
    """Why ``--blend path`` cannot be saved (one line), or None; checked before anything is
    read or written, so that a refused --blend leaves nothing behind."""
    name = os.path.basename(path)
    if not name.lower().endswith(".blend"):
        return f"--blend {path!r}: not a .blend file name"
    if any(_same_file(path, p) for p in inputs):
        return f"--blend {path!r} is the input file: give another .blend"
    if os.path.exists(path) and not os.path.isfile(path):
        return f"--blend {path}: not a file"
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        return f"--blend: no folder {folder!r} to save {name!r} in"
    if not os.access(folder, os.W_OK | os.X_OK):  # (Blender saves through a temporary there)
        return f"--blend: the folder {folder!r} is not writable"
    if os.path.exists(path) and not os.access(path, os.R_OK):
        return f"--blend {path!r} cannot be read"
    return None


def _run_convert(args, signals):
    if not args.out.strip():
        return _error(f"--out must name a folder, got {args.out!r}")
    inputs = {name: parse_value(getattr(args, name)) for name, _ in INPUT_FLAGS
              if getattr(args, name) is not None}
    pbr = any(k in inputs for k in _PBR_INPUTS + LAYER_MAP_INPUTS)
    if "opacity" in inputs:
        if "alpha" in inputs:
            return _error("--alpha is the core roughness α of perceptual maps; a PBR set's "
                          "opacity is --opacity: give one of them")
        inputs["alpha"] = inputs.pop("opacity")
    if (args.blend or args.name) and not pbr and not args.batch:
        return _error("--blend and --name are for PBR sets (--base-color, --metallic, ...)")
    problem = _blend_problem(args.blend) if args.blend else None
    if problem is not None:
        return _error(problem)
    try:
        from .blender.actions import cli  # imports bpy (the conversion's Blender half needs it)
    except ImportError as exc:
        return _error(f"bpy is not importable ({exc}); install the bpy module or run inside "
                      "Blender", K.EXIT_NO_BPY)
    from . import api
    from .blender.actions import convert as _  # noqa: F401  (imported before the signals raise)
    from .conversion.convert import ConversionError, Progress
    bar = ProgressBar(sys.stderr, enabled=not args.quiet and not args.json and (
        args.progress or _isatty(sys.stderr)))
    progress = Progress(bar.update)
    bar.progress = progress
    signals.arm()
    try:
        if args.batch:
            return _run_batch(args, inputs, progress, bar, cli, signals)
        if pbr:
            if args.blend and os.path.isfile(args.blend):
                rc = _open_blend("convert", args.blend)
                if rc is not None:
                    bar.close()
                    return rc
            result = api.convert_maps(inputs, args.out, smoothness=args.smoothness,
                                      distribution=args.distribution, prefix=args.prefix,
                                      exr_codec=args.exr_codec, name=args.name,
                                      progress=progress)
            if args.blend:
                rc = _save_blend("convert", args.blend, (result.material,))
                if rc is not None:
                    bar.close()
                    return rc
        else:
            result = api.convert_maps(inputs, args.out, kind=args.kind,
                                      smoothness=args.smoothness, distribution=args.distribution,
                                      file_format=args.file_format, resample=args.resample,
                                      prefix=args.prefix, exr_codec=args.exr_codec,
                                      progress=progress)
    except ConversionError as exc:
        bar.close()
        return _error(exc)
    except OSError as exc:  # not expected (the conversion turns them into ConversionError)
        return _error(f"{exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}")
    except MemoryError:
        return _error("not enough memory for these images")
    signals.hold()  # the maps are in place: a signal now is reported after the summary
    bar.close()
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


def _isatty(stream):
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


class ProgressBar:
    """The CLI's progress bar: one line on ``stream`` redrawn in place (at most 5 times a
    second), ended by :meth:`close`; nothing at all when not ``enabled``."""

    def __init__(self, stream, enabled=True, interval=0.2):
        import time
        self.stream, self.enabled, self.interval = stream, enabled, interval
        self.progress = None
        self._clock, self._last, self._shown = time.monotonic, None, False

    def update(self, done, total, message):
        if not self.enabled or self.progress is None:
            return
        now = self._clock()
        if self._last is not None and now - self._last < self.interval and done < total:
            return
        self._last = now
        from .conversion.convert import progress_bar
        self.stream.write("\r" + progress_bar(self.progress)[:119].ljust(119))
        self.stream.flush()
        self._shown = True

    def close(self):
        if self._shown:
            self.stream.write("\n")
            self.stream.flush()
            self._shown = False


def _run_batch(args, inputs, progress, bar, cli, signals):
    """--batch FOLDER: every subfolder a PBR set; a summary line at the end; exit 0 when every
    set converted, 4 when some failed (one line each on stderr)."""
    from .blender.actions.convert_pbr import convert_library_steps
    from .conversion.convert import ConversionError, drain
    haze = {k: v for k, v in inputs.items() if k in HAZE_MAP_INPUTS}
    paths = [k for k, v in haze.items() if isinstance(v, str)]
    others = [k for k in inputs if k not in haze]
    if paths or others:
        bar.close()
        return _error("--batch takes the haze as constants for every set (the maps come from "
                      f"each set's folder); got {', '.join(paths + others)}")
    if not os.path.isdir(args.batch):
        bar.close()
        return _error(f"--batch {args.batch}: not a folder")
    if args.blend and os.path.isfile(args.blend):
        rc = _open_blend("convert", args.blend)
        if rc is not None:
            bar.close()
            return rc
    try:
        report = drain(convert_library_steps(args.batch, args.out, haze=haze, progress=progress))
    except ConversionError as exc:
        bar.close()
        return _error(exc)
    if args.blend and report.done:
        rc = _save_blend("convert", args.blend, [r.material for _, r in report.done])
        if rc is not None:
            bar.close()
            return rc
    signals.hold()
    bar.close()
    for name, why in report.failed:
        print(f"{PROG}: error: {name}: {as_flags(why)}", file=sys.stderr)
    if args.json:
        print(json.dumps({"sets": {n: dict(r) for n, r in report.done},
                          "failed": dict(report.failed), "seconds": report.seconds}, indent=1))
    elif not args.quiet:
        for name, r in report.done:
            print(f"{name}: {r.report.summary(len(r))}")
        print(report.summary())
    return K.EXIT_SETS_FAILED if report.failed else K.EXIT_OK


#: The interchange subcommands: name, help, description, then each argument's
#: (names, keywords).
_INTERCHANGE_COMMANDS = (
    ("export-materialx", "write a .blend's hazy materials to MaterialX (or USD)",
     "Write the hazy materials of a .blend file to one MaterialX document (each an exact Eq. 1 "
     "graph of the standard pbr library), or with --usd to USD (UsdShade MaterialX networks, "
     "needs usd-core).  Runs on the bpy module.",
     ((("blend",), dict(help="the .blend file")),
      (("out",), dict(help="output .mtlx (or .usd/.usda/.usdc with --usd); an existing file "
                           "is replaced only when it is a document of that kind")),
      (("--flavour",), dict(default="eq1", choices=("eq1", "openpbr_1.2"),
                            help="eq1 (default, exact) or openpbr_1.2 (approximate, unreleased 1.2)")),
      (("--materials",), dict(default=None, help="comma-separated names (default: all hazy)")),
      (("--usd",), dict(action="store_true", help="write USD instead of .mtlx")),
      (("--json",), dict(action="store_true", help="print the report as JSON")))),
    ("import-materialx", "recognise hazy materials in a MaterialX or USD file",
     "Read the materials of a .mtlx (or USD, needs usd-core) file: library surfaces (OpenPBR, "
     "standard_surface, gltf_pbr, UsdPreviewSurface) as Principled BSDF materials, OpenPBR 1.2 "
     "haze as a haze layer, two-lobe mixes as hazy materials; prints what each becomes and what "
     "is not exact.  With --blend, creates them in a .blend (needs bpy).",
     ((("path",), {}),
      (("--blend",), dict(default=None, help="save the imported materials to this .blend (added "
                                             "to it if it exists; kept with a fake user)")),
      (("--json",), dict(action="store_true")),
      (("--quiet",), dict(action="store_true",
                          help="no progress bar (files of 1 MB and more show one on stderr)")))),
    ("engines", "closest Unity / Unreal / Filament / OpenPBR 1.2 parameters",
     "For each hazy material of a .mtlx/.usd file or a .blend, the closest parameters of Unity "
     "HDRP StackLit, Unreal Substrate, Filament and OpenPBR 1.2 with their BRDF error against "
     "Eq. 1 (max, mean, peak).",
     ((("path",), dict(help=".mtlx, .usd(a/c) or .blend")),
      (("--json",), dict(action="store_true")))),
)


def _add_interchange(sub):
    for name, help_, description, arguments in _INTERCHANGE_COMMANDS:
        command = sub.add_parser(name, help=help_, description=description)
        for names, keywords in arguments:
            command.add_argument(*names, **keywords)


def _fail(prog, msg, code=2):
    print(f"hazy_gloss {prog}: error: {msg}", file=sys.stderr)
    return code


def _need_bpy(prog):
    try:
        from .blender.actions import cli  # noqa: F401  (imports bpy)
    except ImportError as exc:
        return _fail(prog, f"bpy is not importable ({exc}); install the bpy module or run "
                           f"inside Blender", 3)
    return None


def _open_blend(prog, path):
    """Open ``path`` in bpy; a one-line error's exit code when Blender cannot read it."""
    from .blender.actions import cli
    try:
        cli.open_blend(path)
    except RuntimeError as exc:  # (not a .blend, truncated, from a newer Blender: Blender's words)
        return _fail(prog, f"Blender cannot open {path!r}: {_blender_words(exc, 'unreadable')}")
    return None


def _blender_words(exc, default):
    """The first line of a bpy operator's RuntimeError, without its "Error: "."""
    why = str(exc).replace("Error: ", "").strip().splitlines()
    return why[0] if why else default


def _save_blend(prog, path, keep):
    """Save the open file as ``path`` keeping ``keep``; a one-line error's exit code when
    Blender cannot."""
    from .blender.actions import cli
    try:
        cli.save_blend(path, keep=keep)
    except RuntimeError as exc:
        return _fail(prog, f"--blend: cannot save {path!r}: {_blender_words(exc, 'failed')}")
    return None


def _os_message(exc):
    """One line for an OSError, naming the user's file (not a temporary)."""
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.strerror}: {exc.filename}" if exc.filename else exc.strerror
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _export(args):
    out = os.path.abspath(args.out)
    state = {}

    def interrupted(name, committed):
        if committed or state.get("before", False) not in (False, _identity(out)):
            return (f"hazy_gloss export-materialx: interrupted ({name}) after {out} was "
                    f"written; it is complete")
        return (f"hazy_gloss export-materialx: interrupted ({name}); nothing was written "
                f"({out} and its tables are as they were)")
    return _signalled(lambda a, signals: _run_export(a, signals, out, state), args, interrupted)


def _identity(path):
    from .interchange.materialx import file_identity
    return file_identity(path)


def _run_export(args, signals, out, state):
    prog = "export-materialx"
    if not os.path.isfile(args.blend):
        return _fail(prog, f"no file {args.blend!r}")
    if _same_file(args.blend, out):
        return _fail(prog, f"the output {args.out!r} is the input .blend: give another file name")
    from .interchange.materialx import output_problem, validate
    problem = output_problem(out, "usd" if args.usd else "mtlx")  # (before Blender starts)
    if problem is not None:
        return _fail(prog, problem)
    state["before"] = _identity(out)
    rc = _need_bpy(prog)
    if rc is not None:
        return rc
    from . import api
    from .blender.actions import interchange as _  # noqa: F401  (imported before the signals raise)
    signals.arm()
    rc = _open_blend(prog, args.blend)
    if rc is not None:
        return rc
    names = [n.strip() for n in args.materials.split(",")] if args.materials else None
    try:
        if args.usd:
            path, done, skipped = api.export_usd(names, out)
            res = {"path": path, "materials": [{"name": n, "prim": p, "notes": no} for n, p, no in done],
                   "skipped": skipped}
        else:
            rep = api.export_materialx(names, out, flavour=args.flavour, validate=False)
            res = {"path": rep.path, "flavour": rep.flavour, "validated": None,
                   "validation": "",
                   "materials": [{"name": n, "materialx": m, "notes": no} for n, m, no in rep.materials],
                   "skipped": rep.skipped}
    except (ValueError, RuntimeError, OSError) as exc:
        return _fail(prog, _os_message(exc))
    signals.hold()  # the output is in place: a signal now is reported after the summary
    if not args.usd:
        res["validated"], res["validation"] = validate(res["path"])
    if args.json:
        print(json.dumps(res, indent=1))
    else:
        print(f"wrote {len(res['materials'])} materials to {res['path']}")
        if res.get("validated") is not None:
            print(f"MaterialX validate(): {'ok' if res['validated'] else res['validation']}")
        for m in res["materials"]:
            for note in m["notes"]:
                print(f"note: {m['name']}: {note}")
    return 0 if res.get("validated") is not False else 1


def _read_any(path, progress=None):
    from .interchange import materialx, usd
    if os.path.splitext(path)[1].lower() in (".usd", ".usda", ".usdc", ".usdz"):
        return usd.read(path)
    return materialx.read(path, progress=progress)


def _surface_json(im):
    if im.surface is None:
        return None
    from .interchange.materialx_import import resolve_haze
    resolve_haze(im.surface)  # the make_hazy keywords (solved per hazy material)
    return im.surface.to_dict()


def _import(args):
    prog = "import-materialx"
    if not os.path.isfile(args.path):
        return _fail(prog, f"no file {args.path!r}")
    from .utils.progress import TextProgress
    big = os.path.getsize(args.path) >= K.MATERIALX_PROGRESS_BYTES
    bar = TextProgress("import-materialx", quiet=args.quiet or not big)
    try:
        if args.blend:
            problem = _blend_problem(args.blend, (args.path,))  # (first: nothing is lost)
            if problem is not None:
                return _fail(prog, problem)
            rc = _need_bpy(prog)
            if rc is not None:
                return rc
            from . import api
            from .blender.actions import cli
            if os.path.isfile(args.blend):  # added to it, as convert --blend does
                rc = _open_blend(prog, args.blend)
                if rc is not None:
                    return rc
            else:
                cli.empty_file()
            try:
                res = api.import_materialx(os.path.abspath(args.path), progress=bar)
            except (ValueError, RuntimeError, OSError) as exc:
                return _fail(prog, _os_message(exc))
            found = res.report
            rc = _save_blend(prog, args.blend, res)  # (kept: no object uses them)
            if rc is not None:
                return rc
        else:
            try:
                found = _read_any(args.path, progress=bar)
            except (ValueError, RuntimeError, OSError) as exc:
                return _fail(prog, _os_message(exc))
    finally:
        bar.close()
    if args.json:
        out = [{"name": im.name, "exact": im.exact, "source": im.source, "parameters": im.parameters,
                "surface": _surface_json(im), "notes": im.notes, "maps": im.maps} for im in found]
        print(json.dumps(out, indent=1))
    else:
        for im in found:
            if im.surface is not None:
                what = f"{im.surface.bsdf.replace('ShaderNodeBsdf', '')} BSDF" + (
                    " with a haze layer" if im.surface.haze_target or im.surface.haze else "")
            else:
                what = "hazy material" if im.parameters or im.maps else "not imported"
            state = "exact" if im.exact else ("approximate" if im.ok else "-")
            print(f"{im.name}: {what}, {state} ({im.source or '-'})")
            for note in im.notes:
                print(f"  - {note}")
    return 0


def _engines(args):
    prog = "engines"
    from .interchange import engines
    from .interchange.materialx import lobes_of
    from .core.parameters import normalise
    if not os.path.isfile(args.path):
        return _fail(prog, f"no file {args.path!r}")
    params = {}
    if args.path.lower().endswith(".blend"):
        rc = _need_bpy(prog)
        if rc is not None:
            return rc
        rc = _open_blend(prog, args.path)
        if rc is not None:
            return rc
        from .blender.actions import cli
        params, skipped = cli.hazy_parameters()
        for name, why in skipped.items():  # (as api.engine_parameters refuses them)
            print(f"hazy_gloss {prog}: skipped: {why}", file=sys.stderr)
    else:
        try:
            found = _read_any(args.path)
        except (ValueError, RuntimeError, OSError) as exc:
            return _fail(prog, _os_message(exc))
        for im in found:
            if im.parameters is not None:
                params[im.name] = normalise(im.parameters)
    out = {}
    for name, p in params.items():
        fits = engines.engine_parameters(lobes_of(p))
        out[name] = fits
        if not args.json:
            print(f"== {name}")
            print(engines.table(fits))
    if args.json:
        def j(fit):
            return {"parameters": fit.parameters, "error": fit.error, "notes": fit.notes,
                    "alternatives": {k: j(a) for k, a in fit.alternatives.items()}}
        print(json.dumps({n: {e: j(f) for e, f in fits.items()} for n, fits in out.items()},
                         indent=1, default=float))
    return 0


def main(argv=None):
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # (named by the command they were given to, as argparse's other errors are)
        args.command_parser.error(f"unrecognized arguments: {' '.join(extra)}")
    if args.command == "convert":
        return _convert(args)
    if args.command == "export-materialx":
        return _export(args)
    if args.command == "import-materialx":
        return _import(args)
    if args.command == "engines":
        return _engines(args)
    return 2  # pragma: no cover (argparse requires a command)


if __name__ == "__main__":
    sys.exit(main())
