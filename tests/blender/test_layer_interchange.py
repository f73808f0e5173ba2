# SPDX-License-Identifier: GPL-3.0-or-later
"""Haze layers (Make Hazy) in MaterialX, USD and Blender's own glTF / USD exporters.

Every exported graph is checked against what the Blender tree holds, read back through the
real ``materialx``, ``pxr`` (usd-core) and ``pygltflib`` packages: the OpenPBR surfaces'
α and IOR against Cycles' Principled conventions (formulas written here from Cycles'
closure.h and MaterialX's open_pbr_surface.mtlx, not taken from the code under test), the
mixes' factors and wiring against the Mix Shaders, the per-pixel node math against Cycles'
own render of the same sockets (AOVs), images against the Blender images' files and colour
spaces."""
import importlib
import math
import os
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest
import pygltflib
import MaterialX as mx
from MaterialX import PyMaterialXGenGlsl as mx_glsl, PyMaterialXGenOsl as mx_osl
from MaterialX import PyMaterialXGenShader as mx_gen
from pxr import Usd, UsdShade

import scenes
import test_layer as TL
from measurements import record

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "pure"))
import mx_eval  # noqa: E402


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    from types import SimpleNamespace
    return SimpleNamespace(api=mod("api"), ix=mod("blender.actions.interchange"), layer=mod("blender.model.layer"),
                           fallback=mod("blender.model.fallback"), doc=mod("interchange.document"), graph=mod("core.graph"),
                           exr=mod("conversion.imagecheck"), hg=hg)


def _stdlib():
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    return lib


_LIB = None


def _load(path):
    global _LIB
    if _LIB is None:
        _LIB = _stdlib()
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    doc.importLibrary(_LIB)
    return doc


def _generates(doc):
    for gen in (mx_glsl.GlslShaderGenerator.create(), mx_osl.OslShaderGenerator.create()):
        ctx = mx_gen.GenContext(gen)
        ctx.registerSourceCodeSearchPath(mx.getDefaultDataSearchPath())
        for m in doc.getMaterialNodes():
            if not m.hasSourceUri():
                assert gen.generate(m.getName(), m, ctx) is not None


def _save_images(mat, tmp_path, fmt="OPEN_EXR"):
    """Images made in memory get a file (MaterialX references files)."""
    for n in mat.node_tree.nodes:
        if n.bl_idname == "ShaderNodeTexImage" and n.image is not None and not n.image.filepath:
            ext = ".exr" if fmt == "OPEN_EXR" else ".png"
            n.image.filepath_raw = str(tmp_path / f"{n.image.name}{ext}")
            n.image.file_format = fmt
            n.image.save()


def _hazy(env, mat, **haze):
    env.api.make_hazy(mat, **(haze or dict(haziness=0.5)))
    return mat


# --------------------------------------------------------------------------------------------
# Independent conventions: Cycles' Principled (svm/closure.h) and MaterialX's OpenPBR 1.1.1
# --------------------------------------------------------------------------------------------


def cycles_alpha(r, a):
    r = min(max(r, 0.0), 1.0)
    a = min(max(a, 0.0), 1.0)
    s = math.sqrt(1.0 - 0.9 * a)
    return min(r * r / s, 1.0), min(r * r * s, 1.0)


def openpbr_alpha(v):
    """α of an open_pbr_surface (libraries/bxdf/open_pbr_surface.mtlx): coat roughening, then
    open_pbr_anisotropy; MaterialX clamps α to 1 in the BSDFs."""
    r, a = v["specular_roughness"], v["specular_roughness_anisotropy"]
    c, w = v["coat_roughness"], v["coat_weight"]
    r_eff = (1.0 - w) * r + w * min(1.0, 2.0 * c ** 4 + r ** 4) ** 0.25
    ax = r_eff * r_eff * math.sqrt(2.0 / (1.0 + (1.0 - a) ** 2))
    return min(ax, 1.0), min((1.0 - a) * ax, 1.0)


def openpbr_eta(v):
    """The base specular's IOR of an open_pbr_surface under its coat."""
    e, c, w = v["specular_ior"], v["coat_ior"], v["coat_weight"]
    ratio = e / c
    return (1.0 - w) * e + w * (ratio if ratio > 1.0 else 1.0 / ratio)


def glossy_alpha(r, a):
    r2 = min(max(r, 0.0), 1.0) ** 2
    a = min(max(a, -0.99), 0.99)
    if abs(a) <= 1e-4:
        return r2, r2
    if a < 0:
        return min(r2 / (1 + a), 1.0), min(r2 * (1 + a), 1.0)
    return min(r2 * (1 - a), 1.0), min(r2 / (1 - a), 1.0)


def _values(node):
    """{input: value} of a MaterialX node, nodedef defaults filled in."""
    out = {}
    nd = node.getNodeDef()
    for i in nd.getActiveInputs():
        mine = node.getInput(i.getName())
        src = mine if mine is not None and mine.getValueString() and not mine.getConnectedNode() else i
        v = src.getValue() if src.getValueString() else None
        out[i.getName()] = tuple(v) if hasattr(v, "__len__") and not isinstance(v, str) else v
    return out


def _bval(sock):
    v = sock.default_value
    return tuple(v)[:3] if hasattr(v, "__len__") else float(v)


def _close(a, b, rel=2e-6, abs_=1e-7):
    return np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=rel, atol=abs_)


class Seen:
    """A socket of a node inside the layer node's group as the renderer sees it: a link from
    the Group Input is the layer node's own input of that name (its link or value)."""

    def __init__(self, sock, outer):
        self.sock, self.outer = sock, outer
        self.name = sock.name
        src = sock.links[0].from_node if sock.is_linked else None
        self.through = outer.inputs.get(sock.name if src is None else sock.links[0].from_socket.name) \
            if src is not None and src.bl_idname == "NodeGroupInput" else None

    @property
    def is_linked(self):
        return self.through.is_linked if self.through is not None else self.sock.is_linked

    @property
    def default_value(self):
        return (self.through if self.through is not None else self.sock).default_value

    @property
    def links(self):
        return self.sock.links


class Inputs:
    def __init__(self, node, outer):
        self.node, self.outer = node, outer

    def __getitem__(self, key):
        s = self.node.inputs[key]
        return Seen(s, self.outer) if self.outer is not None else s


class Walk:
    """Walks the Blender tree from the Material Output Cycles uses (into the layer node's
    group, as the exporters inline it), and the MaterialX graph in step, checking every BSDF
    and mix against the Blender node it was written from."""

    def __init__(self, env, mat, ng):
        self.env, self.mat, self.ng = env, mat, ng
        self.vname = env.doc.valid_name
        self.seen = {"principled": 0, "metallic": 0, "glossy": 0, "mix": 0, "add": 0}
        self.outer = None

    def name(self, b):
        return self.vname((self.outer.name + "/" if self.outer is not None else "") + b.name)

    @staticmethod
    def unwrap(mx_node):
        """A BSDF lifted into a surfaceshader ("<mix>_a_surface"): the BSDF."""
        if mx_node.getCategory() == "surface" and mx_node.getInput("bsdf") is not None:
            up = mx_node.getInput("bsdf").getConnectedNode()
            if up is not None:
                return up
        return mx_node

    def check(self, sock, mx_node):
        link = next((lk for lk in sock.links if not lk.is_muted), None)
        assert link is not None
        b = link.from_node
        t = b.bl_idname
        if t == "ShaderNodeGroup":  # the layer node: its group's inside
            gout = next(n for n in b.node_tree.nodes if n.bl_idname == "NodeGroupOutput")
            self.outer = b
            return self.check(gout.inputs[link.from_socket.name], mx_node)
        mx_node = self.unwrap(mx_node)
        if t == "ShaderNodeBsdfPrincipled":
            self.principled(b, mx_node)
        elif t == "ShaderNodeBsdfMetallic":
            self.metallic(b, mx_node)
        elif t in ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic"):
            self.glossy(b, mx_node)
        elif t == "ShaderNodeMixShader":
            assert mx_node.getCategory() == "mix" and mx_node.getName() == self.name(b)
            fac = b.inputs[0]
            if not fac.is_linked:
                got = float(mx_node.getInput("mix").getValue())
                assert got == pytest.approx(min(max(fac.default_value, 0.0), 1.0), rel=1e-7, abs=1e-9)
            self.seen["mix"] += 1
            self.check(b.inputs[2], mx_node.getInput("fg").getConnectedNode())
            self.check(b.inputs[1], mx_node.getInput("bg").getConnectedNode())
        elif t == "ShaderNodeAddShader":
            assert mx_node.getCategory() == "add"
            self.seen["add"] += 1
            self.check(b.inputs[0], mx_node.getInput("in1").getConnectedNode())
            self.check(b.inputs[1], mx_node.getInput("in2").getConnectedNode())
        elif t == "ShaderNodeEmission":
            assert mx_node.getCategory() in ("uniform_edf", "surface")
        else:
            raise AssertionError(f"unexpected {t}")

    def principled(self, b, n):
        assert n.getCategory() == "open_pbr_surface" and n.getName() == self.name(b)
        self.seen["principled"] += 1
        v = _values(n)
        ins = Inputs(b, self.outer)
        lin = lambda name: ins[name].is_linked  # noqa: E731
        if not lin("Base Color"):
            assert _close(v["base_color"], _bval(ins["Base Color"]))
        if not lin("Metallic"):
            assert v["base_metalness"] == pytest.approx(min(max(ins["Metallic"].default_value, 0), 1))
        if not (lin("Roughness") or lin("Anisotropic") or lin("Coat Roughness") or lin("Coat Weight")):
            want = cycles_alpha(ins["Roughness"].default_value, ins["Anisotropic"].default_value)
            assert _close(openpbr_alpha(v), want, rel=1e-6), (b.name, openpbr_alpha(v), want)
        if not (lin("IOR") or lin("Coat IOR") or lin("Coat Weight")):
            assert openpbr_eta(v) == pytest.approx(ins["IOR"].default_value, rel=1e-6), b.name
        if not lin("Specular IOR Level"):
            level = ins["Specular IOR Level"].default_value
            m = v["base_metalness"] if v["base_metalness"] is not None else 0.0
            want = 1.0 if (not lin("Metallic") and m >= 1.0) else 2.0 * level
            assert v["specular_weight"] == pytest.approx(want, rel=1e-7)
        for bl, key in (("Coat Weight", "coat_weight"), ("Coat IOR", "coat_ior"),
                        ("Coat Roughness", "coat_roughness"), ("Transmission Weight", "transmission_weight"),
                        ("Sheen Weight", "fuzz_weight"), ("Emission Strength", "emission_luminance")):
            if not lin(bl):
                assert v[key] == pytest.approx(ins[bl].default_value, rel=1e-7, abs=1e-9), (b.name, key)
        if not lin("Specular Tint"):
            t = np.asarray(_bval(ins["Specular Tint"]))
            if v["base_metalness"] == 1.0:
                t = np.minimum(t, 1.0)
            assert _close(v["specular_color"], t)
        assert v["coat_darkening"] == 0.0  # Cycles darkens the base by the coat's albedo only

    def metallic(self, b, n):
        self.seen["metallic"] += 1
        v = _values(n)
        ins = Inputs(b, self.outer)
        if ins["Roughness"].is_linked or ins["Anisotropy"].is_linked:
            return  # the layer's math feeds the wide lobe (checked per pixel below)
        want = cycles_alpha(ins["Roughness"].default_value, ins["Anisotropy"].default_value)
        assert _close(v["roughness"], want, rel=1e-6)
        fresnel = ("IOR", "Extinction") if b.fresnel_type == "PHYSICAL_CONDUCTOR" else \
            ("Base Color", "Edge Tint")
        if any(ins[k].is_linked for k in fresnel):
            return  # raised by the layer's math
        if b.fresnel_type == "PHYSICAL_CONDUCTOR":
            assert n.getCategory() == "conductor_bsdf"
            assert _close(v["ior"], _bval(ins["IOR"])) and _close(v["extinction"], _bval(ins["Extinction"]))
        else:
            assert n.getCategory() == "generalized_schlick_bsdf"
            assert _close(v["color0"], np.clip(_bval(ins["Base Color"]), 0, 1))
            assert _close(v["color82"], np.clip(_bval(ins["Edge Tint"]), 0, 1))
            assert v["color90"] == (1.0, 1.0, 1.0) and v["exponent"] == 5.0

    def glossy(self, b, n):
        self.seen["glossy"] += 1
        assert n.getCategory() == "generalized_schlick_bsdf"
        v = _values(n)
        ins = Inputs(b, self.outer)
        if ins["Roughness"].is_linked or ins["Anisotropy"].is_linked or ins["Color"].is_linked:
            return
        assert _close(v["roughness"], glossy_alpha(ins["Roughness"].default_value,
                                                   ins["Anisotropy"].default_value), rel=1e-6)
        assert _close(v["color0"], _bval(ins["Color"])) and _close(v["color90"], _bval(ins["Color"]))
        assert v["color82"] == (1.0, 1.0, 1.0)


def _renderer_output(mat):
    outs = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    return next((n for n in outs if n.target == "CYCLES"), None) or \
        next((n for n in outs if n.is_active_output), outs[0])


# --------------------------------------------------------------------------------------------
# MaterialX: the tree, BSDF by BSDF
# --------------------------------------------------------------------------------------------

HAZE = {"car paint (metal + coat)": dict(haziness=0.5, coat_haziness=0.6),
        "tinted anisotropic plastic": dict(haziness=0.6, haze_extent=(8.0, 3.0))}


@pytest.mark.parametrize("name", list(TL.MATERIALS))
def test_layer_exports_the_tree_it_holds(env, name, tmp_path):
    mat = TL.MATERIALS[name]()
    _save_images(mat, tmp_path)
    _hazy(env, mat, **HAZE.get(name, dict(haziness=0.5)))
    rep = env.api.export_materialx(mat, str(tmp_path / "layer.mtlx"))
    assert rep.validated is True, rep.validation
    assert not rep.skipped
    doc = _load(rep.path)
    ok, msg = doc.validate()
    assert ok, msg
    _generates(doc)
    (m,) = [m for m in doc.getMaterialNodes() if not m.hasSourceUri()]
    assert m.getAttribute("hazygloss_flavour") == "layer"
    ng = doc.getNodeGraph(m.getInput("surfaceshader").getNodeGraphString())
    top = ng.getOutput("out").getConnectedNode()
    w = Walk(env, mat, ng)
    w.check(_renderer_output(mat).inputs["Surface"], top)
    assert w.outer == env.layer.layer_node(mat)  # the walk went through the layer node
    assert w.seen["principled"] + w.seen["metallic"] + w.seen["glossy"] >= 2
    assert w.seen["mix"] + w.seen["add"] >= 1
    if name == "rusty metal (noise into Metallic)":  # a procedural texture: said, not hidden
        assert any("Noise Texture" in n and "not exported" in n for n in rep.notes), rep.notes


def test_operator_and_cli_write_layered_materials(env, tmp_path, capsys):
    mat = _hazy(env, TL.car_paint(), haziness=0.4, coat_haziness=0.3)
    bpy.ops.mesh.primitive_cube_add()
    bpy.context.object.data.materials.append(mat)
    path = str(tmp_path / "op.mtlx")
    assert bpy.ops.hazy_gloss.export_materialx(filepath=path) == {"FINISHED"}
    doc = _load(path)
    assert doc.validate()[0] and [m.getName() for m in doc.getMaterialNodes()] == ["Car_Paint"]
    blend = str(tmp_path / "s.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    cli = importlib.import_module(env.hg.__name__ + ".__main__")
    out = str(tmp_path / "cli.mtlx")
    assert cli.main(["export-materialx", blend, out]) == 0
    assert "MaterialX validate(): ok" in capsys.readouterr().out
    assert _load(out).getNode("Car_Paint").getCategory() == "surfacematerial"
    res = env.api.import_materialx(out)  # the same layered material again
    (im,) = res.report
    assert im.source == "hazy_gloss layer" and env.api.is_hazy(im.material)
    haze = env.api.read_parameters(im.material)
    assert haze["haziness"] == pytest.approx(0.4) and haze["coat_haziness"] == pytest.approx(0.3)
    # engines: a layer is skipped in one line, as api.engine_parameters refuses it (it printed
    # fits that ignored the coat; a painted Haziness raised)
    capsys.readouterr()
    env.api.add_haziness_map(bpy.data.materials["Car Paint"], size=16)  # (the CLI opened the file)
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    assert cli.main(["engines", blend]) == 0
    err = capsys.readouterr().err
    assert "engines: skipped: “Car Paint” is a haze layer on its own BSDF" in err, err


def test_cli_bad_files_get_one_line(env, tmp_path, capsys):
    """Not a .blend, a truncated one, malformed MaterialX, a --blend in no folder: one line and
    exit 2 (they raised tracebacks, exit 1; the import was done, then lost on save)."""
    cli = importlib.import_module(env.hg.__name__ + ".__main__")
    bad = tmp_path / "bad.blend"
    bad.write_text("garbage")
    scene = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(scene))
    short = tmp_path / "short.blend"
    short.write_bytes(scene.read_bytes()[:5000])
    mtlx = tmp_path / "bad.mtlx"
    mtlx.write_text("<materialx")
    for argv in (["export-materialx", str(bad), str(tmp_path / "o.mtlx")],
                 ["export-materialx", str(short), str(tmp_path / "o.mtlx")],
                 ["engines", str(bad)], ["engines", str(mtlx)],
                 ["import-materialx", str(mtlx), "--blend", str(tmp_path / "no" / "x.blend")]):
        capsys.readouterr()
        assert cli.main(argv) == 2, argv
        err = [line for line in capsys.readouterr().err.splitlines() if "hazy_gloss" in line]
        assert len(err) == 1 and "error:" in err[0], (argv, err)


# --------------------------------------------------------------------------------------------
# Textures: the user's images, the baked maps
# --------------------------------------------------------------------------------------------


def _image(name, pixels, path, non_color=True, fmt="OPEN_EXR"):
    img = TL.image(name, pixels, non_color=non_color)
    img.filepath_raw = str(path)
    img.file_format = fmt
    img.save()
    return img


def _upstream(node, cat):
    """The first upstream node of category ``cat`` (depth-first through every input)."""
    stack, seen = [node], set()
    while stack:
        n = stack.pop()
        if n.getName() in seen:
            continue
        seen.add(n.getName())
        if n.getCategory() == cat:
            return n
        stack.extend(i.getConnectedNode() for i in n.getInputs() if i.getConnectedNode() is not None)
    return None


def _upstream_files(node):
    files, stack, seen = set(), [node], set()
    while stack:
        n = stack.pop()
        if n is None or n.getName() in seen:
            continue
        seen.add(n.getName())
        if n.getCategory() == "image":
            files.add(n.getInputValue("file"))
        stack.extend(i.getConnectedNode() for i in n.getInputs())
    return files


def test_images_keep_their_files_and_colour_spaces(env, tmp_path):
    mat, b = TL.principled("Textured", **{"Roughness": 0.3})
    tree = mat.node_tree
    rng = np.random.default_rng(3)
    col = _image("albedo", np.concatenate([rng.uniform(0, 1, (4, 4, 3)), np.ones((4, 4, 1))], -1),
                 tmp_path / "albedo.png", non_color=False, fmt="PNG")
    met = _image("metal", TL.grey(TL.METALLIC_MAP), tmp_path / "metal.exr")
    nrm = _image("normal", TL.grey(np.full((4, 4), 0.5)), tmp_path / "normal.png", fmt="PNG")
    texs = {}
    for key, img in (("Base Color", col), ("Metallic", met)):
        t = texs[key] = tree.nodes.new("ShaderNodeTexImage")
        t.image = img
        tree.links.new(t.outputs["Color"], b.inputs[key])
    t = tree.nodes.new("ShaderNodeTexImage")
    t.image = nrm
    nm = tree.nodes.new("ShaderNodeNormalMap")
    tree.links.new(t.outputs["Color"], nm.inputs["Color"])
    tree.links.new(nm.outputs[0], b.inputs["Normal"])
    _hazy(env, mat, haziness=0.5)
    rep = env.api.export_materialx(mat, str(tmp_path / "tex.mtlx"))
    assert rep.validated, rep.validation
    doc = _load(rep.path)
    _generates(doc)
    ng = doc.getNodeGraphs()[0]
    images = {os.path.normpath(os.path.join(str(tmp_path), n.getInputValue("file"))): n
              for n in ng.getNodes() if n.getCategory() == "image"}
    want = {os.path.normpath(bpy.path.abspath(i.filepath)): i for i in (col, met, nrm)}
    assert set(images) - set(want) == set(rep.tables)  # (the layer's lookup tables, beside)
    for path, n in images.items():
        if path in rep.tables:
            assert n.getInput("file").getColorSpace() == "raw"
            continue
        cs = n.getInput("file").getColorSpace()
        assert cs == ("srgb_texture" if want[path].colorspace_settings.name == "sRGB" else "raw"), (path, cs)
    # the metallic map is the factor of the layer's mix of its parts
    mix = ng.getNode(env.doc.valid_name("Principled BSDF/Mix parts or coat"))
    src = _upstream(mix.getInput("mix").getConnectedNode(), "image")
    assert src is not None and src.getInputValue("file") == "metal.exr"
    surfaces = [n for n in ng.getNodes() if n.getCategory() == "open_pbr_surface"]
    assert surfaces
    for n in surfaces:  # (through the selects of the metallic split: both maps are upstream)
        assert "albedo.png" in _upstream_files(n.getInput("base_color").getConnectedNode())
        assert n.getInput("geometry_normal").getConnectedNode().getCategory() == "normalmap"


@pytest.mark.parametrize("distribution", ["GGX", "MULTI_GGX"])
def test_live_node_math_is_cycles_math_per_pixel(env, tmp_path, distribution):
    """Textured roughness: the layer computes the wide roughness, the raised IOR and β per
    pixel in Math nodes.  Cycles renders those sockets (AOVs); the exported MaterialX math,
    evaluated at the same texels, gives the same values."""
    mat, b = TL.principled("Live", distribution=distribution,
                           **{"Base Color": (0.2, 0.3, 0.5, 1.0), "Roughness": 0.3, "IOR": 1.45})
    tree = mat.node_tree
    r = np.linspace(0.0, 1.0, 64).reshape(8, 8)
    img = _image("rough", TL.grey(r), tmp_path / "rough.exr")
    tex = TL.window_image(tree, img)
    tree.links.new(tex.outputs["Color"], b.inputs["Roughness"])
    _hazy(env, mat, haziness=0.6)
    rep = env.api.export_materialx(mat, str(tmp_path / "live.mtlx"))
    assert rep.validated, rep.validation
    assert any("per pixel" in n for n in rep.notes)
    node = env.layer.layer_node(mat)
    ng = node.node_tree.copy()  # (a copy: the probe outputs stay out of the shared group)
    inner = {n.name: n for n in ng.nodes}
    wide, narrow, mix = inner["A wide"], inner["A narrow"], inner["Mix A"]
    gout = next(n for n in ng.nodes if n.bl_idname == "NodeGroupOutput")
    probes = {"texel": tex.outputs["Color"]}
    for k, s in (("wide", wide.inputs["Roughness"]), ("ior", narrow.inputs["IOR"]),
                 ("beta", mix.inputs[0])):
        ng.interface.new_socket(name=f"probe {k}", in_out="OUTPUT", socket_type="NodeSocketFloat")
        ng.links.new(s.links[0].from_socket, gout.inputs[f"probe {k}"])
    node.node_tree = ng
    for k in ("wide", "ior", "beta"):
        probes[k] = node.outputs[f"probe {k}"]
    scenes.setup_render("CYCLES", samples=1, resolution=(16, 16), bounces=0)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scenes.flat_plane_scene(mat)
    got = {k: v.reshape(-1) for k, v in scenes.render_aovs(env.exr.read_exr, tree, probes).items()}
    doc = _load(rep.path)
    ng = doc.getNodeGraphs()[0]
    img_node = next(n for n in ng.getNodes() if n.getCategory() == "image")
    texel = got["texel"].astype(np.float32)
    ev = mx_eval.Evaluator(ng, texel.size, {img_node.getName(): np.repeat(texel[:, None], 3, 1)})
    vn = env.doc.valid_name
    mxv = {"wide": ev.value(vn("Principled BSDF/A wide"), "specular_roughness"),
           "ior": ev.value(vn("Principled BSDF/A narrow"), "specular_ior"),
           "beta": ev.value(vn("Principled BSDF/Mix A"), "mix")}
    worst = {}
    for k, v in mxv.items():
        want = got[k] if k == "ior" else np.clip(got[k], 0.0, 1.0)  # the sockets' saturation
        err = np.abs(v.astype(np.float64) - want) / np.maximum(np.abs(want), 1e-3)
        worst[k] = float(err.max())
    f0 = lambda e: ((e - 1.0) / (e + 1.0)) ** 2  # noqa: E731
    worst["F0"] = float(np.max(np.abs(f0(mxv["ior"].astype(np.float64)) / f0(got["ior"]) - 1.0)))
    record("layer_mtlx_node_math", {distribution: dict(worst, materialx_nodes=len(ng.getNodes()))})
    # float32 rounding of a chain of hundreds of operations (Multiscatter GGX: ~2000 nodes)
    # in Cycles and in the evaluator, in another order
    assert worst["wide"] <= 1e-6 and worst["beta"] <= 2e-6, worst
    assert worst["ior"] <= 1e-5 and worst["F0"] <= 1e-5, worst


class _TableLookups(mx_eval.Evaluator):
    """mx_eval with ``image`` nodes read from their files (OpenEXR, beside the document) as
    MaterialX's linear filter and address modes (periodic or clamp) read them: texel centres at
    (i + 0.5)/W, (0, 0) the image's lower left."""

    def __init__(self, graph, folder, read_exr):
        super().__init__(graph, 1)
        self.folder, self.read_exr = folder, read_exr

    def _eval(self, node):
        if node.getCategory() != "image":
            return super()._eval(node)
        ch = self.read_exr(os.path.join(self.folder, node.getInputValue("file")))
        rgb = np.stack([ch[k] for k in ("R", "G", "B")], -1).astype(np.float64)  # row 0: bottom
        h, w = rgb.shape[:2]
        uv = np.asarray(self.input(node, "texcoord"), np.float64).reshape(-1, 2)
        x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
        if self.input(node, "uaddressmode") == "periodic":  # (the layer's: Environment Textures)
            assert self.input(node, "vaddressmode") == "periodic"
            x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
            x1, y1 = (x0 + 1) % w, (y0 + 1) % h
            fx, fy = (x - x0)[:, None], (y - y0)[:, None]
            x0, y0 = x0 % w, y0 % h
            out = (rgb[y0, x0] * (1 - fx) + rgb[y0, x1] * fx) * (1 - fy) + \
                (rgb[y1, x0] * (1 - fx) + rgb[y1, x1] * fx) * fy
            return out.astype(np.float32)
        x, y = np.clip(x, 0.0, w - 1.0), np.clip(y, 0.0, h - 1.0)
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
        fx, fy = (x - x0)[:, None], (y - y0)[:, None]
        out = (rgb[y0, x0] * (1 - fx) + rgb[y0, x1] * fx) * (1 - fy) + \
            (rgb[y1, x0] * (1 - fx) + rgb[y1, x1] * fx) * fy
        return out.astype(np.float32)


@pytest.mark.parametrize("distribution", ["GGX", "MULTI_GGX"])
def test_lookup_tables_are_written_beside_the_document(env, tmp_path, distribution):
    """A thin film (and Multiscatter GGX) make the layer read lookup tables, packed images:
    they are written as OpenEXR files beside the document, which reads them through the
    exported math.  Evaluated with those files, the narrow lobe's specular_color is the
    Specular Tint Cycles renders (it was written as a constant 4.25 where Cycles renders
    3.12-3.25, with two notes per table image)."""
    mat, b = TL.principled("Film", distribution=distribution, **{
        "Base Color": (0.2, 0.3, 0.5, 1.0), "Roughness": 0.3, "Thin Film Thickness": 400.0,
        "Thin Film IOR": 1.8})
    _hazy(env, mat, haziness=0.3)
    rep = env.api.export_materialx(mat, str(tmp_path / "film.mtlx"))
    assert rep.validated, rep.validation
    group = env.layer.layer_node(mat).node_tree
    tables = {n.image.name for g in [group] + [n.node_tree for n in group.nodes
                                               if getattr(n, "node_tree", None)]
              for n in g.nodes if n.bl_idname == "ShaderNodeTexEnvironment"}
    assert len(rep.tables) == len(tables)  # (4.5's GGX film needs none)
    assert all(p.startswith(str(tmp_path / "film_tables")) for p in rep.tables)
    assert not any("without a file on disk" in n or "is not exported" in n for n in rep.notes)
    again = env.api.export_materialx(mat, str(tmp_path / "film.mtlx"))  # (the files are kept)
    assert again.tables == rep.tables
    tree, node = mat.node_tree, env.layer.layer_node(mat)
    ng = node.node_tree.copy()  # (a copy: the probe outputs stay out of the shared group)
    tint = next(n for n in ng.nodes if n.name == "A narrow").inputs["Specular Tint"]
    sep = ng.nodes.new("ShaderNodeSeparateColor")
    ng.links.new(tint.links[0].from_socket, sep.inputs[0])
    gout = next(n for n in ng.nodes if n.bl_idname == "NodeGroupOutput")
    for k, lane in zip("rgb", ("Red", "Green", "Blue")):
        ng.interface.new_socket(name=f"probe {k}", in_out="OUTPUT", socket_type="NodeSocketFloat")
        ng.links.new(sep.outputs[lane], gout.inputs[f"probe {k}"])
    node.node_tree = ng
    scenes.setup_render("CYCLES", samples=1, resolution=(4, 4), bounces=0)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scenes.flat_plane_scene(mat)
    got = scenes.render_aovs(env.exr.read_exr, tree,
                             {f"tint {k}": node.outputs[f"probe {k}"] for k in "rgb"})
    want = np.array([np.median(got[f"tint {k}"]) for k in "rgb"])
    assert np.ptp(want) > 0.05, want  # (the film's colour, not the grey constant)
    doc = _load(rep.path)
    ev = _TableLookups(doc.getNodeGraphs()[0], str(tmp_path), env.exr.read_exr)
    mxv = ev.value(env.doc.valid_name("Principled BSDF/A narrow"), "specular_color")
    err = float(np.max(np.abs(np.asarray(mxv, np.float64).reshape(3) / want - 1.0)))
    record("layer_mtlx_tables", {distribution: {"max_rel_specular_color": err}})
    assert err <= 1e-4, (mxv, want)


def test_baked_layer_exports_its_maps(env, tmp_path):
    """A PBR set converted with haze maps (api.convert_maps): the layer reads its β, wide
    roughness and raised IOR from baked maps; the document reads the same files."""
    rng = np.random.default_rng(7)
    h, w = 4, 4
    maps = {}
    for key, arr in (("base_color", np.concatenate([rng.uniform(0.1, 0.9, (h, w, 3)), np.ones((h, w, 1))], -1)),
                     ("roughness", TL.grey(rng.uniform(0.2, 0.6, (h, w)))),
                     ("metallic", TL.grey((rng.uniform(0, 1, (h, w)) > 0.5).astype(float))),
                     ("haziness", TL.grey(rng.uniform(0.2, 0.8, (h, w))))):
        maps[key] = str(tmp_path / f"{key}.exr")
        _image(key, arr, maps[key], non_color=key != "base_color")
    res = env.api.convert_maps(maps, str(tmp_path / "out"), name="Baked")
    mat = res.material
    assert env.layer.is_baked(mat)
    rep = env.api.export_materialx(mat, str(tmp_path / "baked.mtlx"))
    assert rep.validated, rep.validation
    doc = _load(rep.path)
    _generates(doc)
    ng = doc.getNodeGraphs()[0]
    files = {os.path.normpath(os.path.join(str(tmp_path), n.getInputValue("file")))
             for n in ng.getNodes() if n.getCategory() == "image"}
    node = env.layer.layer_node(mat)
    lg = importlib.import_module(env.hg.__name__ + ".core.layer_graph")
    baked = {key: node.inputs[name].links[0].from_node.image.name
             for key, (name, _) in lg.BAKED.items()}
    want = {os.path.normpath(bpy.path.abspath(bpy.data.images[name].filepath)) for name in baked.values()}
    assert want and want <= files, (want - files)
    # the wide lobe's roughness and the raised IOR read those maps in the document
    tree = mat.node_tree
    vname = env.doc.valid_name
    for slot, bl, key, bkey in (("A wide", "Roughness", "specular_roughness", "roughness_wide"),
                                ("A narrow", "IOR", "specular_ior", "ior_d")):
        mxn = ng.getNode(vname(f"{node.name}/{slot}"))
        f = os.path.normpath(bpy.path.abspath(bpy.data.images[baked[bkey]].filepath))
        up = mxn.getInput(key).getConnectedNode()
        files_up = set()
        stack = [up]
        while stack:
            x = stack.pop()
            if x is None:
                continue
            if x.getCategory() == "image":
                files_up.add(os.path.normpath(os.path.join(str(tmp_path), x.getInputValue("file"))))
            stack.extend(i.getConnectedNode() for i in x.getInputs())
        assert f in files_up, (slot, f, files_up)
    # its export fallback is the user's BSDF at haziness 0: the PBR maps, not the baked ones
    env.api.add_export_fallback(mat)
    fb = env.ix.material.ours(tree)["Export fallback"]
    baked_names = set(baked.values())
    for key in ("Base Color", "Roughness", "Metallic", "IOR"):
        s = fb.inputs[key]
        if s.is_linked:
            src = s.links[0].from_node
            assert not (src.bl_idname == "ShaderNodeTexImage" and src.image.name in baked_names), key
    assert fb.inputs["Roughness"].links[0].from_node.image.filepath.endswith("roughness.exr")


# --------------------------------------------------------------------------------------------
# USD
# --------------------------------------------------------------------------------------------


def test_usd_holds_the_same_network(env, tmp_path):
    mats = [_hazy(env, TL.car_paint(), haziness=0.5, coat_haziness=0.4),
            _hazy(env, TL.metallic_node("F82")), _hazy(env, TL.glossy_node())]
    mat_tex = TL.metallic_map()
    _save_images(mat_tex, tmp_path)
    mats.append(_hazy(env, mat_tex))
    path, done, skipped = env.api.export_usd(mats, str(tmp_path / "layers.usda"))
    assert not skipped and len(done) == len(mats)
    rep = env.api.export_materialx(mats, str(tmp_path / "layers.mtlx"))
    # no film, no note on one (a select between a film of 0 and 0 was written as a node, QA)
    assert not any("thin film" in n for _, _, ns in rep.materials for n in ns)
    doc = _load(rep.path)
    stage = Usd.Stage.Open(path)
    for mat, (name, prim_path, _) in zip(mats, done):
        prim = stage.GetPrimAtPath(prim_path)
        m = UsdShade.Material(prim)
        src = m.ComputeSurfaceSource("mtlx")[0]
        ng = doc.getNodeGraph(f"NG_{env.doc.valid_name(name)}")
        top = ng.getOutput("out").getConnectedNode()
        assert src.GetPrim().GetName() == top.getName()
        for n in ng.getNodes():
            sh = UsdShade.Shader(stage.GetPrimAtPath(f"{prim_path}/NG/{n.getName()}"))
            assert sh, n.getName()
            nd = sh.GetIdAttr().Get()
            assert _LIB.getNodeDef(nd) is not None and _LIB.getNodeDef(nd).getNodeString() == n.getCategory()
            for i in n.getInputs():
                ui = sh.GetInput(i.getName())
                up = i.getConnectedNode()
                if up is not None:
                    (s,) = ui.GetConnectedSources()[0]
                    assert s.source.GetPrim().GetName() == up.getName()
                elif i.getType() in ("float", "color3", "vector2", "vector3"):
                    assert _close(ui.Get(), i.getValue(), rel=1e-6, abs_=1e-7), (n.getName(), i.getName())
                elif i.getType() == "filename":
                    assert ui.Get().path == i.getValueString()
                    assert ui.GetAttr().GetColorSpace() == i.getColorSpace()
        # the preview is the user's BSDF at haziness 0
        pv = m.ComputeSurfaceSource()[0]
        assert pv.GetIdAttr().Get() == "UsdPreviewSurface"
        core = env.layer.layer_node(mat)  # its inputs are the user's own values
        if "IOR" in core.inputs and "Base Color" in core.inputs and "Coat Weight" in core.inputs:
            assert _close(pv.GetInput("diffuseColor").Get(), _bval(core.inputs["Base Color"]), rel=1e-6)
            assert pv.GetInput("ior").Get() == pytest.approx(core.inputs["IOR"].default_value, rel=1e-6)
        assert pv.GetInput("roughness").Get() == pytest.approx(core.inputs["Roughness"].default_value, rel=1e-6)
    res = env.api.import_materialx(path)  # USD too: every layer comes back as a layer
    assert len(res) == len(res.report) and all(im.source == "hazy_gloss layer" for im in res.report)
    assert all(env.api.is_hazy(m) for m in res)


# --------------------------------------------------------------------------------------------
# The export fallback: Blender's glTF and USD exporters get the user's BSDF at haziness 0
# --------------------------------------------------------------------------------------------

FALLBACK_MATERIALS = ("car paint (metal + coat)", "metallic map", "tinted anisotropic plastic",
                      "plastic in a Mix Shader", "Metallic BSDF (F82)", "Glossy BSDF", "glass (transmission)")


def _user_look(mat):
    """What glTF gets from the user's BSDF before Make Hazy (metallic, base colour, roughness)."""
    b = next(n for n in mat.node_tree.nodes if n.bl_idname.startswith("ShaderNodeBsdf"))
    if b.bl_idname == "ShaderNodeBsdfPrincipled":
        return (None if b.inputs["Metallic"].is_linked else b.inputs["Metallic"].default_value,
                _bval(b.inputs["Base Color"]), b.inputs["Roughness"].default_value, b.inputs["IOR"].default_value)
    col = b.inputs["Base Color" if b.bl_idname == "ShaderNodeBsdfMetallic" else "Color"]
    return 1.0, _bval(col), b.inputs["Roughness"].default_value, None


def _scene(env, names, tmp_path, fallback=True):
    mats = {}
    for i, name in enumerate(names):
        mat = TL.MATERIALS[name]()
        _save_images(mat, tmp_path, "PNG")
        look = _user_look(mat)
        _hazy(env, mat, **HAZE.get(name, dict(haziness=0.5)))
        bpy.ops.mesh.primitive_plane_add(size=1.0, location=(1.2 * (i - len(names) / 2) + 0.0137, 0.0213, 0.0))
        bpy.context.object.data.materials.append(mat)
        mats[mat.name] = (mat, look)
    return mats


def test_layer_fallback_gives_the_exporters_the_users_bsdf(env, tmp_path):
    """glTF (the active output) and the USD MaterialX network (the active "All" output) get the
    user's BSDF at haziness 0: its own colour, metallic (the map itself), roughness, IOR — not the
    layer's raised IOR / Base Color.  USD's UsdPreviewSurface takes the first Principled of the
    node list, the user's own core: said in a note (the user's node is never recreated)."""
    mats = _scene(env, FALLBACK_MATERIALS, tmp_path)
    preview_is_fallback = {}
    for mat, _ in mats.values():
        notes = env.api.add_export_fallback(mat)
        kept = env.layer.original_node(mat)
        said = any("UsdPreviewSurface" in n and "before haze" in n for n in notes)
        # the user's Principled, kept beside the layer node, precedes the fallback in the node
        # list; a Metallic / Glossy BSDF is no Principled
        assert said == (kept.bl_idname == "ShaderNodeBsdfPrincipled"), (mat.name, notes)
        preview_is_fallback[mat.name] = not said
    glb, usda = str(tmp_path / "s.glb"), str(tmp_path / "s.usda")
    bpy.ops.export_scene.gltf(filepath=glb, export_format="GLB")
    # USD as a machine without the add-on writes it (with it, the hook writes the exact network)
    hook = importlib.import_module(f"{env.hg.__name__}.blender.ui.interchange_ops").HAZY_GLOSS_usd_hook
    bpy.utils.unregister_class(hook)
    try:
        bpy.ops.wm.usd_export(filepath=usda, generate_preview_surface=True,
                              generate_materialx_network=True)
    finally:
        bpy.utils.register_class(hook)
    gl = {m.name: m for m in pygltflib.GLTF2().load(glb).materials}
    stage = Usd.Stage.Open(usda)
    us, pv = {}, {}
    for prim in stage.Traverse():
        if prim.IsA(UsdShade.Material):
            m = UsdShade.Material(prim)
            s = m.ComputeSurfaceSource("mtlx")[0]
            assert s.GetIdAttr().Get() == "ND_open_pbr_surface_surfaceshader", prim.GetName()
            us[prim.GetName()] = {i.GetBaseName(): i for i in s.GetInputs()}
            pv[prim.GetName()] = {i.GetBaseName(): i for i in m.ComputeSurfaceSource()[0].GetInputs()}
    for name, (mat, (metallic, colour, rough, ior)) in mats.items():
        pbr = gl[name].pbrMetallicRoughness
        assert pbr.roughnessFactor == pytest.approx(rough, abs=1e-6), name
        assert np.allclose(pbr.baseColorFactor[:3], colour, atol=1e-6), name
        op = us[env.doc.valid_name(name)]
        assert op["specular_roughness"].Get() == pytest.approx(rough, abs=1e-6), name
        assert np.allclose(op["base_color"].Get(), colour, atol=1e-6), name
        if metallic is None:  # the metallic map: a texture in both
            assert pbr.metallicRoughnessTexture is not None
            assert op["base_metalness"].HasConnectedSource()
        else:
            assert pbr.metallicFactor == pytest.approx(metallic, abs=1e-6), name
            assert op["base_metalness"].Get() == pytest.approx(metallic, abs=1e-6), name
        if ior is not None and metallic == 0.0:  # the user's IOR, not the layer's raised one
            assert op["specular_ior"].Get() == pytest.approx(ior, rel=1e-6), name
            ext = (gl[name].extensions or {}).get("KHR_materials_ior")
            assert ext is None or ext["ior"] == pytest.approx(ior, rel=1e-6)
        p = pv[env.doc.valid_name(name)]
        assert p["roughness"].Get() == pytest.approx(rough, abs=1e-6)
        if preview_is_fallback[name]:
            assert np.allclose(p["diffuseColor"].Get(), colour, atol=1e-6), name
            assert p["metallic"].Get() == pytest.approx(1.0), name
    assert "KHR_materials_clearcoat" in (gl["Car Paint"].extensions or {})
    assert "KHR_materials_anisotropy" in (gl["Brushed Plastic"].extensions or {})


def _tree_signature(mat):
    t = mat.node_tree
    return (sorted((n.name, n.bl_idname) for n in t.nodes),
            sorted((lk.from_node.name, lk.from_socket.identifier, lk.to_node.name,
                    lk.to_socket.identifier) for lk in t.links))


def test_layer_fallback_is_idempotent_and_removable(env, tmp_path):
    mats = _scene(env, FALLBACK_MATERIALS, tmp_path)
    for mat, _ in mats.values():
        before = _tree_signature(mat)
        active = [n.name for n in mat.node_tree.nodes
                  if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output]
        env.api.add_export_fallback(mat)
        once = _tree_signature(mat)
        env.api.add_export_fallback(mat)
        assert _tree_signature(mat) == once
        assert env.api.remove_export_fallback(mat)
        assert _tree_signature(mat) == before
        assert [n.name for n in mat.node_tree.nodes
                if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output] == active


def _render_scene(engine):
    if engine == "CYCLES":
        scenes.setup_render("CYCLES", samples=4, resolution=(112, 24), bounces=2)
    else:
        scenes.eevee_setup(samples=1, resolution=(112, 24))
    scenes.uniform_world(0.3)
    return scenes.render_exr()


def _camera_and_sun():
    cam = bpy.data.cameras.new("cam")
    cam.type, cam.ortho_scale = "ORTHO", 9.0
    obj = bpy.data.objects.new("cam", cam)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = (0.0, 0.0, 5.0)
    bpy.context.scene.camera = obj
    sun = bpy.data.lights.new("sun", "SUN")
    sun.angle, sun.energy = 0.05, 3.0
    so = bpy.data.objects.new("sun", sun)
    bpy.context.scene.collection.objects.link(so)
    so.rotation_euler = (math.radians(20.0), math.radians(10.0), 0.0)


@pytest.mark.parametrize("engine", ["CYCLES", "EEVEE"])
def test_layer_fallback_does_not_change_renders(env, tmp_path, engine):
    mats = _scene(env, FALLBACK_MATERIALS, tmp_path)
    _camera_and_sun()
    before = _render_scene(engine)
    for mat, _ in mats.values():
        env.api.add_export_fallback(mat)
    after = _render_scene(engine)
    assert float(before[..., :3].max()) > 0.01
    assert np.array_equal(before, after), float(np.abs(before - after).max())


def _feeds(sock):
    return sock.links[0].from_node if sock.is_linked else None


def _check_outputs(env, mat):
    """Render outputs get the layer's last mix (the core without a layer), the export output the
    fallback, the user's output the same as the renderers."""
    tree = mat.node_tree
    mine = env.ix.material.ours(tree)
    final_sock = env.layer.layer_node(mat).outputs["BSDF"]
    user_out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"
                    and not env.ix.material.is_ours(n))
    for t in ("Cycles", "Eevee"):
        assert _feeds(mine[f"Render output {t}"].inputs["Surface"]) == final_sock.node, (t, mat.name)
    assert _feeds(mine["Export output"].inputs["Surface"]) == mine["Export fallback"]
    assert mine["Export output"].is_active_output
    return user_out


def test_haze_updates_keep_the_fallback_outputs(env, tmp_path):
    """update_material after add_export_fallback: values in place, the layer rebuilt (haze on /
    off, a coat haze added), Remove Haze — the renderers keep the hazy BSDF, the exporters the
    user's BSDF, and renders match the material without the fallback."""
    mat, b = TL.principled("Paint", **{"Base Color": (0.5, 0.1, 0.1, 1.0), "Roughness": 0.3,
                                       "Coat Weight": 1.0, "Coat Roughness": 0.05})
    bpy.ops.mesh.primitive_plane_add(size=1.0)
    bpy.context.object.data.materials.append(mat)
    _camera_and_sun()
    user_ior = b.inputs["IOR"].default_value
    _hazy(env, mat, haziness=0.4)
    env.api.add_export_fallback(mat)
    steps = [dict(haziness=0.7), dict(haziness=0.0), dict(haziness=0.6), dict(coat_haziness=0.5),
             dict(haze_extent=(8.0, 2.0))]
    for change in steps:
        env.api.update_material(mat, **change)
        _check_outputs(env, mat)
        fb = env.ix.material.ours(mat.node_tree)["Export fallback"]
        assert fb.inputs["IOR"].default_value == pytest.approx(user_ior)  # the user's, not raised
        assert fb.inputs["Coat IOR"].default_value == pytest.approx(1.5)
        with_fb = _render_scene("CYCLES")
        sig = _tree_signature(mat)
        env.api.remove_export_fallback(mat)
        without = _render_scene("CYCLES")
        assert np.array_equal(with_fb, without), (change, float(np.abs(with_fb - without).max()))
        env.api.add_export_fallback(mat)
        assert _tree_signature(mat) == sig
    env.api.remove_haze(mat)  # takes the fallback with it: the tree is the user's again
    assert not env.fallback.has_export_fallback(mat)
    outs = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    assert len(outs) == 1 and outs[0].is_active_output and _feeds(outs[0].inputs["Surface"]) == b
    assert not env.ix.material.ours(mat.node_tree)
    env.api.make_hazy(mat, haziness=0.3)  # and Make Hazy finds the user's BSDF again
    assert env.layer.original_node(mat) == b


def test_fallback_follows_edits_of_the_core(env, tmp_path):
    mat, b = TL.principled("Edited", **{"Base Color": (0.2, 0.4, 0.1, 1.0), "Roughness": 0.3})
    _hazy(env, mat, haziness=0.5)
    env.api.add_export_fallback(mat)
    node = env.layer.layer_node(mat)
    node.inputs["Roughness"].default_value = 0.45  # user edits of the layer node
    node.inputs["IOR"].default_value = 1.7
    env.api.sync_haze(mat)
    fb = env.ix.material.ours(mat.node_tree)["Export fallback"]
    assert fb.inputs["Roughness"].default_value == pytest.approx(0.45)
    assert fb.inputs["IOR"].default_value == pytest.approx(1.7)


def test_a_painted_haziness_map_is_written_beside_the_document(env, tmp_path):
    """A packed haziness map (Add Haziness Map, painted) has no file on disk: the export
    writes its values beside the document and reads them from there (it wrote the socket's
    value instead, with a note, and the re-import rendered 23 % off, QA)."""
    mat = _hazy(env, TL.car_paint(), haziness=0.4)
    img = env.api.add_haziness_map(mat, size=16)
    px = np.zeros((16, 16, 4), np.float32)
    px[..., 0] = np.linspace(0.0, 0.8, 16)[None, :]  # (a painted gradient, left to right)
    px[..., 3] = 1.0
    img.pixels.foreach_set(px.ravel())
    rep = env.api.export_materialx(mat, str(tmp_path / "painted.mtlx"))
    assert rep.validated, rep.validation
    notes = [n for _, _, ns in rep.materials for n in ns]
    assert not any("without a file on disk" in n for n in notes), notes
    written = [p for p in rep.tables if os.path.basename(p).startswith(img.name.replace(" ", "_"))]
    assert len(written) == 1 and written[0].startswith(str(tmp_path / "painted_tables"))
    red = env.exr.read_exr(written[0])["R"]  # (rows bottom first, as Image.pixels)
    assert red.shape == (16, 16) and np.allclose(red, px[..., 0], atol=1e-7)
    doc = _load(rep.path)
    files = {i.getValueString() for n in doc.traverseTree() if n.isA(mx.Node) and n.getCategory() == "image"
             for i in n.getInputs() if i.getName() == "file"}
    assert os.path.relpath(written[0], tmp_path) in files
    img.pixels.foreach_set(np.ones(16 * 16 * 4, np.float32))  # (painted again: a new file)
    again = env.api.export_materialx(mat, str(tmp_path / "painted.mtlx"))
    assert set(again.tables) - set(rep.tables)
