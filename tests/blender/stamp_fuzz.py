# SPDX-License-Identifier: GPL-3.0-or-later
"""Stamp fuzz: corrupt the parameters the add-on keeps on materials and drive every reader.

The stamp ``mat["hazy_gloss"]`` (and the haze layer's ``mat["hazy_gloss"]["layer"]``) is an
ID property anyone can edit (Python console, the custom-properties panel, another add-on, a
damaged file).  For each material type — lean and in-shader (api.create_material), a haze layer
(api.make_hazy on a Principled BSDF with a metallic split and a coat) and a baked layer
(api.convert_maps of a PBR set) — every key path of its stamp gets every mutation of
:data:`MUTATIONS` (wrong types, NaN/inf, wrong lengths, strings, nested groups, deletion), and
the whole stamp is replaced by non-groups.  Each case drives the readers (read_parameters, the
settings' getters, both panels' draw through the layout stand-in of test_ui, interchange,
engine parameters), the writers (update_material, a settings setter, sync_haze) and the
operators (apply_preset, plot_to_image, import_two_lobe_mix, make_hazy, the recomposite set-up and
clear, remove_haze last); then all cases are saved in one file, reloaded and driven again.

Outcomes per (attack, driver):
- ``ok``: returned normally;
- ``refused``: ValueError / TypeError or an operator's ERROR report, one line (``refused,
  unclear`` when the message is Python's own, e.g. "'int' object is not iterable", naming
  nothing);
- ``uncaught <Type>``: any other exception, an operator whose report is a traceback, an
  exception inside a property getter or setter (Blender prints and swallows those: caught via
  sys.excepthook), a panel that raised;
- ``noop``: an operator that had nothing to do and said so (Make Hazy on a hazy material);
- ``hang``: over the per-driver work bound (tests/pure/work_bound.py: the add-on's Python
  calls, counted: the same on every machine);
- ``multi-line``: a refusal message of more than one line;
- ``silent panel``: a stamp that read_parameters refuses, drawn without the message or without
  a way out (the presets menu or Remove Haze);
- ``lost``: a driver removed one of the user's nodes, or a reader removed the stamp.

Works against any checkout (``python tests/blender/stamp_fuzz.py <repo root> [seconds]`` loads
that root's hazy_gloss with register(); docs/verification.md has the numbers before and after).
"""
from __future__ import annotations

import collections
import copy
import importlib
import math
import os
import importlib.util
import re
import sys
import tempfile
import time
from types import SimpleNamespace

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

import scenes  # noqa: E402
from test_ui import StandIn, fake_context  # noqa: E402  (the layout stand-in)


def load_work_bound():
    """tests/pure/work_bound.py, by its path (tests/pure on sys.path would shadow test modules
    of the same names here)."""
    if "work_bound" not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            "work_bound", os.path.join(os.path.dirname(HERE), "pure", "work_bound.py"))
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        sys.modules["work_bound"] = mod
    return sys.modules["work_bound"]


work_bound = load_work_bound()

STAMP = "hazy_gloss"
DELETE = object()
NAN, INF = float("nan"), float("inf")

#: (attack group, mutation name, value); DELETE removes the key.
MUTATIONS = [
    ("missing key", "deleted", DELETE),
    ("wrong type", "int 7", 7),
    ("wrong type", "bool", True),
    ("wrong type", "string", "abc"),
    ("wrong type", "numeric string", "0.9,0.6,0.3"),
    ("wrong type", "empty string", ""),
    ("NaN / inf / out of range", "NaN", NAN),
    ("NaN / inf / out of range", "+inf", INF),
    ("NaN / inf / out of range", "-inf", -INF),
    ("NaN / inf / out of range", "-1", -1.0),
    ("NaN / inf / out of range", "1e300", 1e300),
    ("NaN / inf / out of range", "2**31-1", 2 ** 31 - 1),
    ("NaN / inf / out of range", "NaN triple", [NAN, NAN, NAN]),
    ("wrong length", "[]", []),
    ("wrong length", "[1.0]", [1.0]),
    ("wrong length", "5 floats", [1.0] * 5),
    ("wrong length", "int pair", [1, 2]),
    ("nested junk", "group", {"x": 1}),
    ("nested junk", "deep group", {"a": {"b": [1.0, 2.0], "c": {"d": "e"}}, "f": "g"}),
    ("nested junk", "list of groups", [{"a": 1}, {"b": 2}]),
]
#: (attack group, name, whole stamp)
WHOLE = [
    ("stamp not a group", "int", 5),
    ("stamp not a group", "float NaN", NAN),
    ("stamp not a group", "string", "junk"),
    ("stamp not a group", "float list", [1.0, 2.0, 3.0]),
    ("stamp not a group", "list of groups", [{"kind": "CONDUCTOR"}]),
    ("stamp not a group", "empty group", {}),
    ("stamp not a group", "unknown keys only", {"colour": 1, "hazyness": 0.5}),
]
LAYER_WHOLE = [
    ("layer stamp not a group", "int", 5),
    ("layer stamp not a group", "string", "junk"),
    ("layer stamp not a group", "float list", [1.0, 2.0]),
    ("layer stamp not a group", "empty group", {}),
]

DRIVERS = ("read_parameters", "getters", "draw material panel", "draw node panel",
           "engine_parameters", "export_materialx", "add_export_fallback",
           "setup/clear_recomposite", "update_material", "setter", "sync_haze",
           "apply_preset", "plot_to_image", "import_two_lobe_mix", "make_hazy", "remove_haze")
#: Drivers after a save and reload.
RELOAD_DRIVERS = ("read_parameters", "getters", "draw material panel", "draw node panel",
                  "update_material", "apply_preset", "remove_haze")
#: Drivers that may legitimately remove the stamp or change the tree.
DESTRUCTIVE = {"remove_haze", "apply_preset", "update_material", "setter", "sync_haze",
               "make_hazy", "import_two_lobe_mix", "setup/clear_recomposite", "add_export_fallback"}
_SETTINGS = ("kind", "distribution", "core_reflectivity", "edge_tint", "roughness", "anisotropy",
             "rotation", "tangent", "haziness", "haze_extent_x", "haze_extent_y",
             "haze_extent_linked", "use_smoothness", "smoothness", "shader_mapping", "base_color",
             "transmission", "coat_haziness", "coat_haze_extent", "keep_body_colour")


#: Messages that are Python's, not the add-on's (they name no parameter).
_UNCLEAR = re.compile(r"is not iterable|could not convert|has no attribute|update sequence|"
                      r"index out of range|argument must be|0-dimensional|unsupported operand|"
                      r"not subscriptable|object is not|division by zero|unhashable|"
                      r"^'[^']*'$")


def plain(v):
    if hasattr(v, "to_dict"):
        return {k: plain(x) for k, x in v.to_dict().items()}
    if hasattr(v, "to_list"):
        return [plain(x) for x in v.to_list()]
    if isinstance(v, dict):
        return {k: plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


def key_paths(d, prefix=()):
    """Every key path of a nested dict (lists of strings, e.g. a socket reference, included as
    their items)."""
    out = []
    for k, v in d.items():
        path = prefix + (k,)
        out.append(path)
        if isinstance(v, dict):
            out += key_paths(v, path)
    return out


def mutate(d, path, value):
    d = copy.deepcopy(d)
    node = d
    for k in path[:-1]:
        node = node[k]
    if value is DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = copy.deepcopy(value)
    return d


# --------------------------------------------------------------------------------------------
# The materials
# --------------------------------------------------------------------------------------------


def _write_map(path, values):
    h, w = values.shape[:2]
    img = bpy.data.images.new(os.path.basename(path), w, h, alpha=False, float_buffer=True,
                              is_data=True)
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = values if values.ndim == 3 else values[..., None]
    img.pixels.foreach_set(px.ravel())
    img.filepath_raw = path
    img.file_format = "OPEN_EXR"
    img.save()
    bpy.data.images.remove(img)
    return path


def _principled(name):
    mat = scenes.new_material(name)
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    return mat, bsdf


def base_materials(api, folder):
    """{type: material} of the four material types, each with one user node (a texture)."""
    out = {}
    lean = api.create_material("Fuzz lean", kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3),
                               edge_tint=(1.0, 0.8, 0.6), roughness=0.2, haziness=0.5,
                               haze_extent=5.0)
    out["lean"] = lean
    shader = api.create_material("Fuzz in-shader", shader_mapping=True, anisotropy=0.4,
                                 haze_extent=(6.0, 3.0), smoothness=2.0, haziness=0.4)
    tree = shader.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    group = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeGroup")
    tree.links.new(noise.outputs["Fac"], group.inputs["Haziness"])
    out["in-shader"] = shader
    mat, bsdf = _principled("Fuzz layered")
    bsdf.inputs["Metallic"].default_value = 0.5
    bsdf.inputs["Coat Weight"].default_value = 1.0
    bsdf.inputs["Base Color"].default_value = (0.6, 0.3, 0.2, 1.0)
    api.make_hazy(mat, haziness=0.4, coat_haziness=0.3)
    out["layered"] = mat
    rng = np.random.default_rng(3)
    maps = dict(base_color=_write_map(os.path.join(folder, "set_basecolor.exr"),
                                      rng.uniform(0.1, 0.9, (4, 4, 3))),
                metallic=_write_map(os.path.join(folder, "set_metallic.exr"),
                                    (rng.uniform(0, 1, (4, 4)) > 0.5).astype(float)),
                roughness=_write_map(os.path.join(folder, "set_roughness.exr"),
                                     rng.uniform(0.2, 0.5, (4, 4))),
                haziness=_write_map(os.path.join(folder, "set_haziness.exr"),
                                    rng.uniform(0.1, 0.7, (4, 4))))
    res = api.convert_maps(maps, os.path.join(folder, "out"), name="Fuzz baked")
    out["baked"] = res.material
    for m in out.values():
        m.use_fake_user = True
    return out


def cases(bases):
    """[(material type, attack group, description, stamp or DELETE)] for every key path and
    mutation, and the whole-stamp replacements."""
    out = []
    for typ, mat in bases.items():
        d = plain(mat[STAMP])
        for path in key_paths(d):
            where = "[" + "][".join(repr(k) for k in path) + "]"
            for group, name, value in MUTATIONS:
                stamp = mutate(d, path, value)
                g = ("layer: " if path[0] == "layer" and len(path) > 1 else "") + group
                out.append((typ, g, f"{where} = {name}", stamp))
        for group, name, value in WHOLE:
            out.append((typ, group, f"stamp = {name}", value))
        if "layer" in d:
            for group, name, value in LAYER_WHOLE:
                out.append((typ, group, f"['layer'] = {name}", dict(d, layer=value)))
    return out


# --------------------------------------------------------------------------------------------
# Drivers
# --------------------------------------------------------------------------------------------


class Fuzz:
    def __init__(self, pkg, folder, *, work_limit=None):
        mod = lambda n: importlib.import_module(f"{pkg}.{n}")  # noqa: E731
        self.api = mod("api")
        self.panels = mod("blender.ui.panels")
        self.errors = mod("blender.actions.messages")  # the refused changes the panel shows
        self.reports = mod("blender.ui.reports")
        self.folder = folder
        self.work_limit = work_limit  # operations one driver may take (None: count only)
        # the add-on's own Python calls (loops uncounted: their callback would double the run)
        self.work = work_bound.Counter(only=[os.path.dirname(self.api.__file__) + os.sep],
                                       loops=False)
        self.counts = collections.Counter()  # (material type, attack, driver, outcome)
        self.examples = {}  # (driver, outcome) -> (case, message)
        self.messages = collections.Counter()  # every message that was not "ok"
        self.cases = self.planned = 0
        self.seconds = 0.0
        self.most = (0, None)  # the most operations one driver took, and where
        rna = bpy.ops.hazy_gloss.apply_preset.get_rna_type()
        self.preset = list(rna.properties["preset"].enum_items.keys())[-1]
        scene = bpy.context.scene
        scene.render.engine = "CYCLES"
        self.obj = bpy.data.objects.new("Fuzz object", bpy.data.meshes.new("Fuzz mesh"))
        scene.collection.objects.link(self.obj)
        self.obj.data.materials.append(None)
        self._hook = []

    # -- one driver ----------------------------------------------------------------------
    def _excepthook(self, typ, value, tb):
        self._hook.append(f"{typ.__name__}: {value}")

    def drive(self, typ, attack, case, driver, mat):
        base = driver[len("reloaded "):] if driver.startswith("reloaded ") else driver
        fn = getattr(self, "d_" + base.replace(" ", "_").replace("/", "_"))
        user_nodes = _user_nodes(mat)
        had_stamp = STAMP in mat
        self._hook = []
        old_hook, sys.excepthook = sys.excepthook, self._excepthook
        try:
            outcome, msg = self.work.run(fn, mat, limit=self.work_limit)
        except work_bound.WorkLimit:
            outcome, msg = "hang", ""
        except (ValueError, TypeError) as exc:
            msg = str(exc)
            outcome = "refused" if "\n" not in msg.strip() else "multi-line"
        except RuntimeError as exc:  # bpy.ops: the operator's ERROR report, or a traceback
            msg = str(exc)
            if "Traceback" in msg:
                last = [ln for ln in msg.splitlines() if ln and not ln.startswith((" ", "Location"))][-1]
                outcome = "uncaught " + last.split(":")[0].replace("Error: Python", "?")
            else:
                outcome = "refused" if "\n" not in msg.strip() else "multi-line"
        except Exception as exc:  # noqa: BLE001 (counted)
            outcome, msg = f"uncaught {type(exc).__name__}", str(exc)
        finally:
            sys.excepthook = old_hook
        if self.work.count > self.most[0]:
            self.most = (self.work.count, (typ, case, driver))
        if self._hook and not outcome.startswith("uncaught"):
            outcome, msg = "uncaught " + self._hook[0].split(":")[0], self._hook[0]
        if outcome == "refused" and _UNCLEAR.search(msg):
            outcome = "refused, unclear"
        if outcome in ("ok", "refused", "refused, unclear"):
            try:
                lost = not user_nodes <= _user_nodes(mat) or (
                    base not in DESTRUCTIVE and had_stamp and STAMP not in mat)
            except ReferenceError:
                lost = True
            if lost:
                outcome = "lost"
        self.counts[(typ, attack, driver, outcome)] += 1
        if outcome != "ok" and msg:
            self.messages[msg.strip()] += 1
        self.examples.setdefault((driver, outcome), (f"{typ} {case}", msg[:300]))
        return outcome, msg

    # -- readers -------------------------------------------------------------------------
    def d_read_parameters(self, mat):
        self.api.read_parameters(mat)
        return "ok", ""

    def d_getters(self, mat):
        s = mat.hazy_gloss_settings
        for name in _SETTINGS:
            v = getattr(s, name)
            if isinstance(v, float) and not math.isfinite(v):
                return "uncaught non-finite getter", f"{name} = {v}"
        return "ok", ""

    def _draw(self, mat, node_editor):
        log = []
        layout = StandIn(log)
        if node_editor:
            space = SimpleNamespace(type="NODE_EDITOR", tree_type="ShaderNodeTree",
                                    shader_type="OBJECT", id=mat, edit_tree=mat.node_tree)
            ctx = fake_context(None, self.obj, space)
            self.obj.active_material = mat
            self.panels.HAZY_GLOSS_PT_shader_editor.draw(SimpleNamespace(layout=layout), ctx)
        else:
            ctx = fake_context(mat, self.obj)
            self.panels.HAZY_GLOSS_PT_material.draw(SimpleNamespace(layout=layout), ctx)
        try:
            self.api.read_parameters(mat)
            return "ok", ""
        except Exception as exc:  # noqa: BLE001 (the panel must say it)
            problem = str(exc)
        texts = [g.get("text", "") for n, g in log if n == "label"]
        said = any(problem[:40].lower() in t.lower() for t in texts)
        way_out = any((n == "menu" and g.get("menu") == "HAZY_GLOSS_MT_presets") or
                      (n == "operator" and g.get("operator") == "hazy_gloss.remove_haze")
                      for n, g in log)
        if not (said and way_out):
            return "silent panel", problem
        return "ok", ""

    def d_draw_material_panel(self, mat):
        return self._draw(mat, False)

    def d_draw_node_panel(self, mat):
        return self._draw(mat, True)

    def d_engine_parameters(self, mat):
        self.api.engine_parameters(mat, measure=False)
        return "ok", ""

    def d_export_materialx(self, mat):
        rep = self.api.export_materialx([mat], os.path.join(self.folder, "fuzz.mtlx"), validate=False)
        if rep.skipped:
            s = rep.skipped[0]
            msg = s[1] if isinstance(s, tuple) else str(s)
            return ("refused" if "\n" not in msg.strip() else "multi-line"), msg
        return "ok", ""

    def d_add_export_fallback(self, mat):
        self.api.add_export_fallback(mat)
        self.api.remove_export_fallback(mat)
        return "ok", ""

    def d_setup_clear_recomposite(self, mat):
        self.obj.active_material = mat
        with bpy.context.temp_override(scene=bpy.context.scene):
            try:
                res = bpy.ops.hazy_gloss.setup_recomposite()
            finally:
                bpy.ops.hazy_gloss.clear_recomposite()
        return ("ok" if res == {"FINISHED"} else "refused"), ""

    # -- writers and operators -----------------------------------------------------------
    def d_update_material(self, mat):
        self.api.update_material(mat, haziness=0.3)
        return "ok", ""

    def d_setter(self, mat):
        mat.hazy_gloss_settings.haziness = 0.25
        err = self.errors.error_for(mat)
        if err:
            return ("refused" if "\n" not in err.strip() else "multi-line"), err
        return "ok", ""

    def d_sync_haze(self, mat):
        self.api.sync_haze(mat)
        return "ok", ""

    def _op(self, name, mat, **kw):
        del self.reports.last_reports[:]
        res = getattr(bpy.ops.hazy_gloss, name)(material=mat.name, **kw)
        reports = list(self.reports.last_reports)
        if "FINISHED" in res:
            return "ok", ""
        msg = reports[-1][1] if reports else ""
        return ("noop" if reports and reports[-1][0] == "INFO" else "refused"), msg

    def d_apply_preset(self, mat):
        return self._op("apply_preset", mat, preset=self.preset)

    def d_plot_to_image(self, mat):
        out = self._op("plot_to_image", mat, size=64)
        for img in [i for i in bpy.data.images if i.name.startswith(".Hazy Gloss")]:
            bpy.data.images.remove(img)
        return out

    def d_import_two_lobe_mix(self, mat):
        return self._op("import_two_lobe_mix", mat)

    def d_make_hazy(self, mat):
        return self._op("make_hazy", mat)

    def d_remove_haze(self, mat):
        return self._op("remove_haze", mat)

    # -- the run -------------------------------------------------------------------------
    def run(self, budget=None, stride=1):
        """Every case (every ``stride``-th), driven, saved, reloaded and driven again; the
        Counter of outcomes.  ``budget``: CPU seconds for a quick look by hand (main), never
        in the tests."""
        with self.work:
            return self._run(budget, stride)

    def _run(self, budget, stride):
        # budget in this process's CPU seconds: on a 2-core machine running four suites at once
        # wall time stretched 4x and cut the run short (460 of 702 cases)
        t_start = time.perf_counter()
        cpu_start = time.process_time()
        bases = base_materials(self.api, self.folder)
        all_cases = cases(bases)[::stride]
        self.planned = 2 * len(all_cases)  # each case driven, then saved, reloaded and driven
        kept = []
        for i, (typ, attack, case, stamp) in enumerate(all_cases):
            if budget is not None and time.process_time() - cpu_start > budget * 0.75:
                break
            mat = bases[typ].copy()
            mat.name = f"Fuzz {i:05d}"
            mat.use_fake_user = True
            for driver in DRIVERS:
                try:
                    _set_stamp(mat, stamp)
                except ReferenceError:
                    break
                self.drive(typ, attack, case, driver, mat)
            self.cases += 1
            kept.append((i, typ, attack, case, stamp))
        # save all cases in one file (a fresh copy each, stamp as mutated), reload, drive again
        names = {}
        for i, typ, attack, case, stamp in kept:
            if budget is not None and time.process_time() - cpu_start > budget * 0.85:
                break
            old = bpy.data.materials.get(f"Fuzz {i:05d}")
            if old is not None:
                bpy.data.materials.remove(old)
            mat = bases[typ].copy()
            mat.name = f"Fuzz {i:05d}"
            mat.use_fake_user = True
            _set_stamp(mat, stamp)
            names[mat.name] = (typ, attack, case, stamp)
        path = os.path.join(self.folder, "fuzz.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path)
        bpy.ops.wm.open_mainfile(filepath=path)
        self.obj = bpy.data.objects["Fuzz object"]
        for name, (typ, attack, case, stamp) in names.items():
            if budget is not None and time.process_time() - cpu_start > budget:
                break
            for driver in RELOAD_DRIVERS:
                mat = bpy.data.materials.get(name)
                if mat is None:
                    break
                if driver != RELOAD_DRIVERS[0]:
                    _set_stamp(mat, stamp)
                self.drive(typ, attack + " (reloaded)", case, "reloaded " + driver, mat)
            self.cases += 1
        self.seconds = time.perf_counter() - t_start
        return self.counts


def _set_stamp(mat, stamp):
    if stamp is DELETE:
        if STAMP in mat:
            del mat[STAMP]
    else:
        mat[STAMP] = copy.deepcopy(stamp)


def _user_nodes(mat):
    """Names of the user's nodes (a BSDF kept beside a haze layer node carries the suffix
    " (before haze)" until Remove Haze gives its name back: the same node)."""
    tree = mat.node_tree
    if tree is None:
        return set()
    return {n.name.removesuffix(" (before haze)") for n in tree.nodes
            if "hazy_gloss_role" not in n and not n.name.startswith("HG ")
            and n.bl_idname != "ShaderNodeOutputMaterial"}


def summary(counts, by=("attack",)):
    """{row key: Counter(outcome)} grouped by attack (or driver)."""
    rows = collections.defaultdict(collections.Counter)
    for (typ, attack, driver, outcome), n in counts.items():
        key = tuple({"type": typ, "attack": attack.replace(" (reloaded)", ""), "driver": driver}[b]
                    for b in by)
        rows[key][outcome] += n
    return rows


def table(counts, by=("attack",)):
    lines = []
    for key, c in sorted(summary(counts, by).items()):
        total = sum(c.values())
        parts = ", ".join(f"{o} {n}" for o, n in c.most_common())
        lines.append(f"{' / '.join(key)}: {total} -> {parts}")
    return "\n".join(lines)


def main(root, budget=None, stride=1):
    sys.path.insert(0, root)
    hg = importlib.import_module("hazy_gloss")
    hg.register()
    with tempfile.TemporaryDirectory() as folder:
        f = Fuzz("hazy_gloss", folder)
        counts = f.run(budget=budget, stride=stride)
        print("=" * 30 + " stamp fuzz")
        print(f"{f.cases} cases, {sum(counts.values())} driver calls, {f.seconds:.0f} s; "
              f"most work {f.most[0]} {f.work.unit} {f.most[1]}")
        print(table(counts))
        print()
        print(table(counts, by=("driver",)))
        print()
        if os.environ.get("STAMP_FUZZ_MESSAGES"):
            with open(os.environ["STAMP_FUZZ_MESSAGES"], "w") as fh:
                for msg, n in f.messages.most_common():
                    fh.write(f"{n}\t{msg}\n")
        for (driver, outcome), (case, msg) in sorted(f.examples.items()):
            if outcome != "ok":
                print(f"{driver} / {outcome}: {case}: {msg[:160]!r}")


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]) if len(sys.argv) > 2 else None,
         int(sys.argv[3]) if len(sys.argv) > 3 else 1)
