# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy materials as UsdShade with MaterialX node ids, through usd-core's ``pxr`` (bpy-free;
only this module needs ``pxr``, imported when a function runs).

:func:`write` puts each material's exact Eq. 1 network (the same Document the MaterialX writer
serialises, interchange/materialx.py) under a ``Material`` prim the way UsdMtlx lays it out
(Blender's own USD exporter does the same):

    Material  (apiSchemas MaterialXConfigAPI, config:mtlx:version "1.39")
      outputs:mtlx:surface -> Shader <name>_surface (info:id ND_surface).outputs:surface
      NodeGraph NG: one Shader per node (info:id = its nodedef, e.g. ND_conductor_bsdf),
                    BSDF ports typed token with renderType "BSDF", output "out"
      outputs:surface -> Shader preview_core (UsdPreviewSurface): the core lobe, i.e. the
                    material at haziness 0 (engines.core_surface) — the renderer-agnostic
                    fallback (metallic, diffuseColor, roughness, ior)
      customData["hazygloss"]: the perceptual parameters (JSON, as in the .mtlx), and
      userProperties:hazy_gloss:* (flat values: Blender's USD importer turns them into custom
      properties)

:func:`read` turns every Material with an ``outputs:mtlx:surface`` network back into a
Document and recognises it like a .mtlx file.  Files written by Blender's own USD exporter
(``userProperties:blender:data_name``) are read with its known deviation corrected: it writes
a Metallic BSDF's roughness R where MaterialX expects α, so a literal conductor roughness is
squared (and said so).
"""
from __future__ import annotations

import json
import os
import re

from .. import constants as K
from . import engines, layered
from .document import NODEDEFS, Document, Input, Node, valid_name
from .materialx import build_document, lobes_of, output_problem, recognise

__all__ = ("available", "write", "author", "is_layered", "read", "read_document", "USD_MISSING")

USD_MISSING = ("USD export and import need the pxr module (pip install usd-core); Blender's "
               "own File > Export > Universal Scene Description works without it")

_ATTR = K.MATERIALX_ATTR


def available():
    try:
        import pxr  # noqa: F401
        from pxr import Usd  # noqa: F401
    except ImportError:
        return False
    return True


def pxr_message(exc):
    """The first meaningful line of a pxr error (its text is lines of "Error in '<C++ function>'
    at line N in file <source> : '<message>'"): the message alone."""
    for line in str(exc).splitlines():
        line = line.strip()
        m = re.match(r"Error in '.*?' at line \d+ in file .*? : '(.*)'$", line)
        if m or line:
            return (m.group(1) if m else line)[:300]
    return type(exc).__name__


def _sdf_type(t):
    from pxr import Sdf
    T = Sdf.ValueTypeNames
    return {"float": T.Float, "color3": T.Color3f, "color4": T.Color4f, "vector2": T.Float2,
            "vector3": T.Vector3f, "vector4": T.Float4, "integer": T.Int, "boolean": T.Bool,
            "string": T.String, "filename": T.Asset}.get(t, T.Token)


def _gf(value, t):
    from pxr import Gf, Sdf
    if t == "color3":
        return Gf.Vec3f(*value)
    if t == "color4":
        return Gf.Vec4f(*value)
    if t == "vector2":
        return Gf.Vec2f(*value)
    if t == "vector3":
        return Gf.Vec3f(*value)
    if t == "vector4":
        return Gf.Vec4f(*value)
    if t == "filename":
        return Sdf.AssetPath(str(value))
    if t == "integer":
        return int(value)
    if t == "boolean":
        return bool(value)
    if t == "float":
        return float(value)
    return value


def _nodedef(node):
    for name, (cat, typ, _) in NODEDEFS.items():
        if cat == node.category and typ == node.type:
            return name
    raise ValueError(f"no nodedef for {node.category} ({node.type})")


def _shader_input(shader, inp):
    from pxr import Sdf
    is_port = inp.type in ("BSDF", "EDF", "VDF", "surfaceshader")
    i = shader.CreateInput(inp.name, Sdf.ValueTypeNames.Token if is_port else _sdf_type(inp.type))
    if is_port:
        i.SetRenderType(inp.type)
    if inp.value is not None and not inp.connected:
        i.Set(_gf(inp.value, inp.type))
    if inp.colorspace:
        i.GetAttr().SetColorSpace(inp.colorspace)
    return i


def _output(shader, node, name="out"):
    from pxr import Sdf
    if node.type in ("BSDF", "EDF", "VDF", "surfaceshader"):
        o = shader.CreateOutput(name, Sdf.ValueTypeNames.Token)
        o.SetRenderType(node.type)
        return o
    return shader.CreateOutput(name, _sdf_type(node.type))


def _material(stage, path, doc, mat_node, src, preview):
    from pxr import Sdf, UsdShade
    T = Sdf.ValueTypeNames
    mat = UsdShade.Material.Define(stage, path)
    prim = mat.GetPrim()
    prim.AddAppliedSchema("MaterialXConfigAPI")
    prim.CreateAttribute("config:mtlx:version", T.String).Set(K.MATERIALX_VERSION)
    record = {}
    for k, v in mat_node.attrs.items():
        if k.startswith(_ATTR + "_"):
            key = k[len(_ATTR) + 1:]
            record[key] = json.loads(v) if key in ("parameters", "maps", "openpbr_error") else v
    prim.SetCustomDataByKey(_ATTR, json.dumps(record, sort_keys=True))
    if mat_node.inputs["surfaceshader"].nodegraph:  # a haze layer: the whole network in NG
        _layer_network(stage, path, mat, doc.graphs[mat_node.inputs["surfaceshader"].nodegraph])
        _layer_extras(stage, path, mat, src, preview)
        return mat
    shader_node = doc.nodes[mat_node.inputs["surfaceshader"].nodename]
    graph = doc.graphs[shader_node.inputs["bsdf"].nodegraph]
    ng = UsdShade.NodeGraph.Define(stage, f"{path}/NG")
    shaders = {}
    for n in graph.nodes.values():
        s = UsdShade.Shader.Define(stage, f"{path}/NG/{n.name}")
        s.CreateIdAttr(_nodedef(n))
        shaders[n.name] = (s, _output(s, n), n)
    for name, (s, _, n) in shaders.items():
        for inp in n.inputs.values():
            i = _shader_input(s, inp)
            if inp.nodename:
                i.ConnectToSource(shaders[inp.nodename][1])
    out = graph.outputs["out"]
    ng_out = ng.CreateOutput("out", T.Token)
    ng_out.SetRenderType("BSDF")
    ng_out.ConnectToSource(shaders[out.nodename][1])
    surf = UsdShade.Shader.Define(stage, f"{path}/{shader_node.name}")
    surf.CreateIdAttr("ND_surface")
    b = surf.CreateInput("bsdf", T.Token)
    b.SetRenderType("BSDF")
    b.ConnectToSource(ng_out)
    surf.CreateInput("opacity", T.Float).Set(1.0)
    s_out = surf.CreateOutput("surface", T.Token)
    mat.CreateSurfaceOutput("mtlx").ConnectToSource(s_out)
    if src.parameters is not None:
        p = src.parameters
        for k in ("kind", "distribution", "tangent"):
            prim.CreateAttribute(f"userProperties:hazy_gloss:{k}", T.String, custom=True).Set(str(p[k]))
        for k in ("roughness", "anisotropy", "rotation", "haziness", "transmission"):
            prim.CreateAttribute(f"userProperties:hazy_gloss:{k}", T.Double, custom=True).Set(float(p[k]))
        for k in ("core_reflectivity", "edge_tint", "base_color"):
            prim.CreateAttribute(f"userProperties:hazy_gloss:{k}", T.Double3, custom=True).Set(tuple(p[k]))
        prim.CreateAttribute("userProperties:hazy_gloss:haze_extent", T.Double2, custom=True).Set(tuple(p["haze_extent"]))
        if preview:
            c = engines.core_surface(p, lobes_of)
            pv = UsdShade.Shader.Define(stage, f"{path}/preview_core")
            pv.CreateIdAttr("UsdPreviewSurface")
            pv.CreateInput("metallic", T.Float).Set(float(c["metallic"]))
            col = c["base_color"] if c["metallic"] == 0.0 else c["f0"]
            pv.CreateInput("diffuseColor", T.Color3f).Set(tuple(float(x) for x in col))
            pv.CreateInput("roughness", T.Float).Set(float(c["roughness"]))  # α = roughness²
            pv.CreateInput("ior", T.Float).Set(float(c["ior"]))
            if c["metallic"] == 0.0 and c["transmission"] > 0:
                pv.CreateInput("opacity", T.Float).Set(1.0 - float(c["transmission"]))
            mat.CreateSurfaceOutput().ConnectToSource(pv.CreateOutput("surface", T.Token))
    return mat


def _layer_network(stage, path, mat, graph):
    """A layered material's NodeGraph (interchange/layered.py): one Shader per node, info:id its
    nodedef, every output "out" (the nodedefs' name), the Material's mtlx:surface from NG.out."""
    from pxr import Sdf, UsdShade
    ng = UsdShade.NodeGraph.Define(stage, f"{path}/NG")
    shaders = {}
    for n in graph.nodes.values():
        sh = UsdShade.Shader.Define(stage, f"{path}/NG/{n.name}")
        sh.CreateIdAttr(n.nodedef or _nodedef(n))
        shaders[n.name] = (sh, _output(sh, n), n)
    for sh, _, n in shaders.values():
        for inp in n.inputs.values():
            i = _shader_input(sh, inp)
            if inp.nodename:
                i.ConnectToSource(shaders[inp.nodename][1])
    out = graph.outputs["out"]
    ng_out = ng.CreateOutput("out", Sdf.ValueTypeNames.Token)
    ng_out.SetRenderType("surfaceshader")
    ng_out.ConnectToSource(shaders[out.nodename][1])
    mat.CreateSurfaceOutput("mtlx").ConnectToSource(ng_out)
    for k, v in graph.attrs.items():
        ng.GetPrim().SetCustomDataByKey(k, str(v))


def _layer_extras(stage, path, mat, src, preview):
    """userProperties and the UsdPreviewSurface of a layered material: the user's BSDF at
    haziness 0 (its own values; textures are not in the preview)."""
    from pxr import Sdf, UsdShade
    T = Sdf.ValueTypeNames
    prim = mat.GetPrim()
    lay = src.layer.layer or {}
    prim.CreateAttribute("userProperties:hazy_gloss:layered", T.Bool, custom=True).Set(True)
    prim.CreateAttribute("userProperties:hazy_gloss:core_type", T.String, custom=True).Set(
        str(lay.get("core_type")))
    haze = lay.get("haze", {})
    for k in ("haziness", "coat_haziness"):
        v = haze.get(k)
        if isinstance(v, (int, float)):
            prim.CreateAttribute(f"userProperties:hazy_gloss:{k}", T.Double, custom=True).Set(float(v))
    if not preview:
        return
    c = layered.preview_values(src.layer)
    if c is None:
        return
    pv = UsdShade.Shader.Define(stage, f"{path}/preview_core")
    pv.CreateIdAttr("UsdPreviewSurface")
    for k in ("metallic", "roughness", "ior", "clearcoat", "clearcoatRoughness", "opacity"):
        pv.CreateInput(k, T.Float).Set(float(c[k]))
    pv.CreateInput("diffuseColor", T.Color3f).Set(tuple(float(x) for x in c["diffuseColor"]))
    if any(c["emissiveColor"]):
        pv.CreateInput("emissiveColor", T.Color3f).Set(tuple(float(x) for x in c["emissiveColor"]))
    mat.CreateSurfaceOutput().ConnectToSource(pv.CreateOutput("surface", T.Token))


def write(sources, path, *, preview=True, bind=None):
    """Write ``sources`` (materialx.Source) as UsdShade MaterialX networks to ``path`` (.usda,
    .usdc or .usd).  ``preview``: add the UsdPreviewSurface of the core lobe on
    outputs:surface.  ``bind``: optional {mesh name: material name} to write a unit quad per
    entry bound to the material (handy for viewers).  Returns (path, [(name, prim path, notes)])."""
    if not available():
        raise RuntimeError(USD_MISSING)
    from pxr import Tf
    path = os.path.abspath(os.fspath(path))
    problem = output_problem(path, "usd")
    if problem is not None:
        raise ValueError(problem)
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    doc, done = build_document(sources, "eq1", directory=os.path.dirname(path))
    try:
        return _write_stage(path, sources, doc, done, preview, bind)
    except Tf.ErrorException as exc:  # (pxr's text is many lines of C++ locations)
        raise RuntimeError(f"{path}: USD could not write it ({pxr_message(exc)})") from None


def author(stage, material_path, src, directory):
    """``src``'s network on a Material another writer made (Blender's USD exporter, through the
    add-on's USDHook): the network :func:`write` writes, on ``outputs:mtlx:surface``, with the
    perceptual parameters; the prims no output reaches any more (the MaterialX network
    Blender translated from the layer's group: its node math, not the haze) removed; the
    UsdPreviewSurface it wrote stays.  Texture paths relative to ``directory``.  Returns the
    notes of what the network does not hold."""
    doc, done = build_document([src], "eq1", directory=directory)
    _, mxname, notes = done[0]
    _material(stage, material_path, doc, doc.nodes[mxname], src, False)
    _drop_unreached(stage, stage.GetPrimAtPath(material_path))
    return notes


def _drop_unreached(stage, prim):
    """Remove the children of ``prim`` that no connection from its outputs reaches."""
    reached, todo = set(), [prim]
    while todo:
        for attr in todo.pop().GetAttributes():
            for target in attr.GetConnections():
                p = target.GetPrimPath()
                if p not in reached and p.HasPrefix(prim.GetPath()):
                    reached.add(p)
                    todo.append(stage.GetPrimAtPath(p))
    for child in list(prim.GetChildren()):
        if not any(p.HasPrefix(child.GetPath()) for p in reached):
            stage.RemovePrim(child.GetPath())


def is_layered(usd_material):
    """True for a Material holding a haze layer's network (written by :func:`write` or
    :func:`author`)."""
    prim = usd_material.GetPrim()
    attr = prim.GetAttribute("userProperties:hazy_gloss:layered")
    out = usd_material.GetSurfaceOutput("mtlx")
    return bool(attr and attr.Get()) and bool(out) and out.HasConnectedSource()


def _write_stage(path, sources, doc, done, preview, bind):
    from pxr import Usd, UsdGeom, UsdShade
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    root = UsdGeom.Xform.Define(stage, "/root")
    stage.SetDefaultPrim(root.GetPrim())
    UsdGeom.Scope.Define(stage, "/root/_materials")
    out = []
    prims = {}
    for src, (name, mxname, notes) in zip(sources, done):
        prim_path = f"/root/_materials/{mxname}"
        _material(stage, prim_path, doc, doc.nodes[mxname], src, preview)
        prims[name] = prim_path
        out.append((name, prim_path, notes))
    for i, (mesh_name, mat_name) in enumerate((bind or {}).items()):
        m = UsdGeom.Mesh.Define(stage, f"/root/{valid_name(mesh_name)}")
        x = 2.0 * i
        m.CreatePointsAttr([(x - .5, -.5, 0), (x + .5, -.5, 0), (x + .5, .5, 0), (x - .5, .5, 0)])
        m.CreateFaceVertexCountsAttr([4])
        m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
        UsdShade.MaterialBindingAPI.Apply(m.GetPrim()).Bind(
            UsdShade.Material(stage.GetPrimAtPath(prims[mat_name])))
    stage.GetRootLayer().Save()
    return path, out


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------


def _value(v, t):
    if v is None:
        return None
    if t in ("color3", "color4", "vector2", "vector3", "vector4"):
        return tuple(float(x) for x in v)
    if t == "filename":
        return v.path if hasattr(v, "path") else str(v)
    if t == "float":
        return float(v)
    return v


_BY_ID = {name: (cat, typ, spec) for name, (cat, typ, spec) in NODEDEFS.items()}
_EXTRA_IDS = {"ND_artistic_ior": ("artistic_ior", "multioutput"),
              # UsdShade's own preview network (the USD files most pipelines write)
              "UsdPreviewSurface": ("UsdPreviewSurface", "surfaceshader"),
              "UsdUVTexture": ("UsdUVTexture", "multioutput"),
              "UsdPrimvarReader_float2": ("UsdPrimvarReader", "vector2"),
              "UsdTransform2d": ("UsdTransform2d", "vector2")}


def _category(shader_id):
    if shader_id in _BY_ID:
        return _BY_ID[shader_id][0], _BY_ID[shader_id][1]
    if shader_id in _EXTRA_IDS:
        return _EXTRA_IDS[shader_id]
    return (shader_id[3:] if shader_id.startswith("ND_") else shader_id), "unknown"


def read_document(stage_or_path, *, only=None):
    """(Document, {material name: prim path}) of every UsdShade Material with a MaterialX
    surface network (outputs:mtlx:surface); ``only``: the prim path of the one to read."""
    if not available():
        raise RuntimeError(USD_MISSING)
    from pxr import Tf, Usd, UsdShade
    stage = stage_or_path
    if not hasattr(stage, "Traverse"):
        try:
            stage = Usd.Stage.Open(os.fspath(stage_or_path))
        except Tf.ErrorException as exc:  # (pxr's text is many lines of C++ locations)
            raise ValueError(f"{os.fspath(stage_or_path)}: not a readable USD file "
                             f"({pxr_message(exc)})") from None
        if stage is None:
            raise ValueError(f"{os.fspath(stage_or_path)}: not a readable USD file")
    doc = Document(source=str(stage.GetRootLayer().realPath))
    paths = {}
    prims = stage.Traverse() if only is None else [stage.GetPrimAtPath(str(only))]
    for prim in prims:
        if not prim or not prim.IsA(UsdShade.Material):
            continue
        mat = UsdShade.Material(prim)
        out = mat.GetSurfaceOutput("mtlx")
        if not out or not out.HasConnectedSource():  # no MaterialX network: its preview surface
            out = mat.GetSurfaceOutput()
            if not out or not out.HasConnectedSource():
                continue
        blender = prim.HasAttribute("userProperties:blender:data_name")
        squared = []

        def node_of(shader):
            key = str(shader.GetPath())
            if key in doc.nodes:
                return doc.nodes[key]
            cat, typ = _category(shader.GetIdAttr().Get() or "")
            n = Node(key, cat, typ)
            doc.nodes[key] = n
            spec = _BY_ID.get(shader.GetIdAttr().Get(), (None, None, {}))[2]
            for i in shader.GetInputs():
                name = i.GetBaseName()
                t = spec.get(name, (None,))[0] or _mx_type(i.GetTypeName())
                src = i.GetConnectedSources()[0]
                if src:
                    s = _follow(src[0])
                    if s is not None:
                        up = node_of(s[0])
                        n.inputs[name] = Input(name, t, nodename=up.name,
                                               output=s[1] if up.type == "multioutput" else None)
                        continue
                n.inputs[name] = Input(name, t, _value(i.Get(), t))
            if blender and cat == "conductor_bsdf":
                r = n.inputs.get("roughness")
                if r is not None and r.value is not None and not r.connected:
                    squared.append(key)
                    r.value = tuple(x * x for x in r.value)
            return n

        src = _follow(out.GetConnectedSources()[0][0])
        if src is None:
            continue
        surf = node_of(src[0])
        ng = prim.GetChild("NG")  # a layer network's shaders no connection reaches (its core)
        for child in (ng.GetChildren() if ng else ()):
            if child.IsA(UsdShade.Shader):
                node_of(UsdShade.Shader(child))
        name = prim.GetName()
        m = Node(f"{prim.GetPath()}#material", "surfacematerial", "material")
        m.inputs["surfaceshader"] = Input("surfaceshader", "surfaceshader", nodename=surf.name)
        raw = prim.GetCustomDataByKey(_ATTR)
        if raw:
            try:
                for k, v in json.loads(raw).items():
                    m.attrs[f"{_ATTR}_{k}"] = json.dumps(v) if isinstance(v, (dict, list)) else v
            except (ValueError, AttributeError):
                pass
        m.attrs.setdefault(f"{_ATTR}_name", name)
        if squared:
            m.attrs["blender_roughness"] = True
        doc.nodes[m.name] = m
        paths[m.attrs[f"{_ATTR}_name"]] = str(prim.GetPath())
    return doc, paths


def _mx_type(type_name):
    t = str(type_name)
    return {"float": "float", "color3f": "color3", "float2": "vector2", "vector3f": "vector3",
            "float3": "vector3", "int": "integer", "bool": "boolean", "string": "string",
            "asset": "filename", "token": "token", "normal3f": "vector3", "float4": "vector4",
            "color4f": "color4", "texCoord2f": "vector2"}.get(t, t)


def _follow(source_info):
    """(Shader, output name) behind a connection, through NodeGraph outputs."""
    from pxr import UsdShade
    for _ in range(32):
        prim = source_info.source.GetPrim()
        if prim.IsA(UsdShade.Shader):
            return UsdShade.Shader(prim), source_info.sourceName
        if prim.IsA(UsdShade.NodeGraph) or prim.IsA(UsdShade.Material):
            o = UsdShade.ConnectableAPI(prim).GetOutput(source_info.sourceName)
            srcs = o.GetConnectedSources()[0] if o else []
            if not srcs:
                return None
            source_info = srcs[0]
            continue
        return None
    return None


def read(path, *, use_stored=True):
    """ImportedMaterial for every MaterialX-network material of a USD file (see module doc)."""
    doc, _ = read_document(path)
    out = recognise(doc, use_stored=use_stored)
    for im, m in zip(out, doc.materials()):
        if m.attrs.get("blender_roughness"):
            im.notes.append("written by Blender's USD exporter, which puts the Metallic BSDF's "
                            "roughness R where MaterialX expects α: read as α = R² (its "
                            "anisotropy is not exported)")
    return out
