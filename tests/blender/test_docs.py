# SPDX-License-Identifier: GPL-3.0-or-later
"""Docs that run: every Python code block of README.md and docs/*.md, executed in bpy with the
add-on loaded as an extension, in a fresh file whose names the block uses created by a fixture
(the materials, images and files it names).  ``hazy_gloss`` and the installed extension's
``bl_ext.user_default.hazy_gloss`` both import the loaded package, as in Blender's console."""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import os
import re
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
FENCE = re.compile(r"^```(\w*)\s*$")


def python_blocks():
    """[(file, first line, code)] of every ```python block."""
    out = []
    for path in DOCS:
        lang, start, lines = None, 0, []
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            m = FENCE.match(line)
            if m and lang is None:
                lang, start, lines = m.group(1) or "text", i + 1, []
            elif line.startswith("```") and lang is not None:
                if lang == "python":
                    out.append((path.name, start, "\n".join(lines)))
                lang = None
            elif lang is not None:
                lines.append(line)
    return out


class _Alias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """``hazy_gloss[.x]`` and ``bl_ext.user_default.hazy_gloss[.x]`` -> the loaded extension."""

    def __init__(self, real):
        self.real = real
        self.names = ("hazy_gloss", "bl_ext.user_default.hazy_gloss")
        self.specs = {}

    def _target(self, fullname):
        for n in self.names:
            if fullname == n or fullname.startswith(n + "."):
                return self.real + fullname[len(n):]
        return None

    def find_spec(self, fullname, path=None, target=None):
        t = self._target(fullname)
        if t is None and fullname in ("bl_ext.user_default",):
            return importlib.util.spec_from_loader(fullname, self, is_package=True)
        if t is None:
            return None
        return importlib.util.spec_from_loader(fullname, self, is_package=True)

    def create_module(self, spec):
        t = self._target(spec.name)
        if t is None:  # the namespace package in between
            mod = type(sys)(spec.name)
            mod.__path__ = []
            return mod
        mod = importlib.import_module(t)
        # importlib sets the alias's spec on the real module: keep what it had, to put back
        self.specs.setdefault(t, (mod, mod.__spec__, getattr(mod, "__path__", None)))
        return mod

    def restore(self):
        """Give the real modules their own ``__spec__`` / ``__path__`` back (Python 3.12+
        warns when ``__package__ != __spec__.parent``, which the add-on's tests make errors)."""
        for mod, spec, path in self.specs.values():
            mod.__spec__ = spec
            if path is None:
                if hasattr(mod, "__path__"):
                    del mod.__path__
            else:
                mod.__path__ = path
        self.specs.clear()

    def exec_module(self, module):
        pass


@pytest.fixture
def alias(hg):
    finder = _Alias(hg.__name__)
    saved = {k: v for k, v in sys.modules.items()
             if k == "hazy_gloss" or k.startswith("hazy_gloss.") or k.startswith("bl_ext.user_default")}
    for k in saved:
        del sys.modules[k]
    sys.meta_path.insert(0, finder)
    ns = type(sys)("bl_ext.user_default")  # (Blender's bl_ext is not a regular package here)
    ns.__path__ = []
    sys.modules["bl_ext.user_default"] = ns
    yield hg
    sys.meta_path.remove(finder)
    finder.restore()
    wrong = [k for k, m in sys.modules.items() if (k == hg.__name__ or k.startswith(hg.__name__ + "."))
             and getattr(m, "__spec__", None) is not None and m.__spec__.name != k]
    assert not wrong, f"modules left with an alias's spec: {wrong}"
    for k in [k for k in sys.modules if k == "hazy_gloss" or k.startswith("hazy_gloss.")
              or k.startswith("bl_ext.user_default")]:
        del sys.modules[k]
    sys.modules.update(saved)


# --------------------------------------------------------------------------------------------
# What the blocks name
# --------------------------------------------------------------------------------------------


def _principled(name, **inputs):
    mat = scenes.new_material(name)
    b = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    for k, v in inputs.items():
        b.inputs[k].default_value = v
    return mat


def _save_png(path, rgb, data=False):
    h, w = rgb.shape[:2]
    img = bpy.data.images.new(os.path.basename(path), w, h, alpha=True, is_data=data)
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = rgb if rgb.ndim == 3 else rgb[..., None]
    img.pixels.foreach_set(px.ravel())
    img.filepath_raw = str(path)
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)


def _save_exr(path, grey):
    h, w = grey.shape
    img = bpy.data.images.new(os.path.basename(path), w, h, alpha=False, float_buffer=True,
                              is_data=True)
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = grey[..., None]
    img.pixels.foreach_set(px.ravel())
    img.filepath_raw = str(path)
    img.file_format = "OPEN_EXR"
    img.save()
    bpy.data.images.remove(img)


def _pbr_set(folder, stem):
    u = np.linspace(0.0, 1.0, 16, dtype=np.float32)
    U, V = np.meshgrid(u, u)
    _save_png(folder / f"{stem}_BaseColor.png", np.stack([0.4 + 0.3 * U, 0.3 + 0.2 * V, 0.2 + 0 * U], -1))
    _save_png(folder / f"{stem}_Metallic.png", (U > 0.5).astype(np.float32), data=True)
    _save_png(folder / f"{stem}_Roughness.png", 0.2 + 0.3 * V, data=True)
    _save_png(folder / f"{stem}_Normal.png", np.stack([0.5 + 0 * U, 0.5 + 0 * U, 1.0 + 0 * U], -1), data=True)
    _save_png(folder / f"{stem}_Haziness.png", 0.1 + 0.4 * U, data=True)


def _passes_exr(path, api):
    """A tiny recomposite render: the multilayer EXR composite.passes_from_exr reads."""
    comp = importlib.import_module(api.__name__.rpartition(".")[0] + ".blender.model.recomposite")
    scene = scenes.setup_render(samples=1, resolution=(8, 8), bounces=1, seed=1)
    mat = api.create_material("Docs Recomposite", kind="CONDUCTOR",
                              core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5),
                              roughness=0.15, haziness=0.2, haze_extent=6.0)
    scenes.analytic_sphere("Docs Sphere", (0.0, 0.0, 0.5), mat)
    cam = bpy.data.objects.new("Docs Cam", bpy.data.cameras.new("Docs Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -4.0, 0.5)
    cam.rotation_euler = (np.radians(90.0), 0.0, 0.0)
    scene.camera = cam
    scenes._sun(scenes.spherical_direction(40.0, -120.0), 3.0)
    comp.setup_recomposite(scene)
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)


def setup(doc, tmp, api):
    """Fresh file (saved in ``tmp``, so "//" paths resolve there) with what ``doc``'s blocks
    name.  Returns extra names for the block's namespace."""
    # README's snippet is pasted into a new file: File > New > General, the factory startup (a
    # cube with its "Material"); the other docs' blocks get an empty file and what they name.
    readme = doc == "README.md"
    bpy.ops.wm.read_homefile(use_empty=not readme, use_factory_startup=readme)
    extra = {}
    if readme:
        pass  # the snippet makes what it uses
    elif doc == "getting-started.md":
        mesh = bpy.data.meshes.new("Docs Mesh")
        obj = bpy.data.objects.new("Docs Object", mesh)
        bpy.context.scene.collection.objects.link(obj)
        bpy.context.view_layer.objects.active = obj
    elif doc == "user-guide.md":
        api.create_material("Brushed Copper", kind="CONDUCTOR", core_reflectivity=(0.95, 0.64, 0.54),
                            edge_tint=(1.0, 0.8, 0.6), roughness=0.2, haziness=0.5, haze_extent=5.0)
        _principled("Old Plastic", **{"Base Color": (0.6, 0.1, 0.1, 1.0), "Roughness": 0.3})
        mat = scenes.new_material("Two Glossies")
        t = mat.node_tree
        for n in [n for n in t.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"]:
            t.nodes.remove(n)
        a, b = t.nodes.new("ShaderNodeBsdfGlossy"), t.nodes.new("ShaderNodeBsdfGlossy")
        a.inputs["Roughness"].default_value, b.inputs["Roughness"].default_value = 0.1, 0.5
        mix = t.nodes.new("ShaderNodeMixShader")
        mix.inputs[0].default_value = 0.3
        t.links.new(a.outputs[0], mix.inputs[1])
        t.links.new(b.outputs[0], mix.inputs[2])
        out = next(n for n in t.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
        t.links.new(mix.outputs[0], out.inputs["Surface"])
    elif doc == "textures.md":
        _pbr_set(tmp, "crate")
        _principled("Mine")
        _principled("Gold")
        (tmp / "tex").mkdir(exist_ok=True)
        u = np.linspace(0.0, 1.0, 16, dtype=np.float32)
        U, V = np.meshgrid(u, u)
        _save_png(tmp / "tex" / "gold_rc.png", np.stack([0.9 + 0 * U, 0.6 + 0.1 * V, 0.3 + 0 * U], -1))
        _save_exr(tmp / "tex" / "rough.exr", 0.2 + 0.2 * U)
        haze = bpy.data.images.new("haze", 16, 16, float_buffer=True, is_data=True)
        px = np.ones((16, 16, 4), np.float32)
        px[..., :3] = (0.2 + 0.5 * V)[..., None]
        haze.pixels.foreach_set(px.ravel())
    elif doc == "compositing.md":
        _passes_exr(tmp / "render.exr", api)
        extra["mask"] = np.linspace(0.0, 1.0, 64, dtype=np.float32).reshape(8, 8)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp / "docs.blend"))
    return extra


BLOCKS = python_blocks()


def test_every_python_block_is_collected():
    assert len(BLOCKS) >= 8, [b[:2] for b in BLOCKS]


@pytest.mark.parametrize("doc,line,code", BLOCKS, ids=[f"{d}:{n}" for d, n, _ in BLOCKS])
def test_python_block_runs(alias, doc, line, code, tmp_path, monkeypatch):
    api = importlib.import_module(alias.__name__ + ".api")
    monkeypatch.chdir(tmp_path)
    extra = setup(doc, tmp_path, api)
    ns = {"__name__": "__docs__", **extra}
    try:
        exec(compile(code, f"{doc}:{line}", "exec"), ns)
    except Exception as exc:  # noqa: BLE001 (the report names the block)
        raise AssertionError(f"{doc} line {line}: {type(exc).__name__}: {exc}") from exc
