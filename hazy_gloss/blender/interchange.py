# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy materials in and out of Blender: MaterialX / USD export and import, and the export
fallback that makes Blender's own glTF and USD exporters write the core lobe.

The formats are bpy-free (hazy_gloss/interchange); this module reads Blender materials into
``materialx.Source`` objects, creates materials from what is imported (library surfaces through
blender/surface_build.py), and holds the operators (File > Export, the material context menu;
File > Import is blender/interchange_ops.py, over api.import_materialx).  A material with a haze layer (Make Hazy)
becomes a snapshot of its node tree (:func:`tree_snapshot`), which interchange/layered.py
writes node by node (docs/interchange.md §5).

**Export fallback** (:func:`add_export_fallback`).  Blender's glTF exporter takes the first
Principled BSDF linked to the *active* Material Output (a Mix of two Metallic BSDFs gives it
nothing, a Mix of two Principled its slot 2: the halo); its USD exporter takes the first
Principled / Diffuse BSDF of the tree's node list for the UsdPreviewSurface and the active
"All" output for its MaterialX network.  Cycles and EEVEE, however, render the output whose
target is their own (Cycles / EEVEE) before any "All" output (ntreeShaderOutputNode).  So the
fallback adds, with built-in nodes only:

- "HG Export fallback": a Principled BSDF with the core lobe's look (the material at haziness 0:
  engines.core_surface — metallic, base colour r_c, roughness, anisotropy, IOR, tint);
- "HG Export output": a Material Output (target All), made the active output, fed by it;
- "HG Render output Cycles" / "HG Render output EEVEE": Material Outputs with those targets,
  fed by whatever the renderers used before (the hazy mix) — unless the tree already has a
  dedicated output for that renderer, which keeps winning;
- and, for dielectrics, recreates the add-on's two Principled lobes after the fallback so the
  fallback is the first Principled in the node list (the USD preview's choice).

A haze layer's fallback is the user's own BSDF at haziness 0 (:func:`_layer_fallback`): a copy
of the core with the user's values and links of the inputs the layer owns.

Renders are unchanged (tests/blender/test_interchange.py compares Cycles and EEVEE pixels);
:func:`remove_export_fallback` restores the previous active output.  The nodes carry the add-on's
roles, so a rebuild of the material (blender/material.apply) removes them: call
:func:`add_export_fallback` again after creating or updating a material (it is idempotent and
refreshes the values).
"""
import os

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, StringProperty
from bpy_extras.io_utils import ExportHelper

from .. import constants as K
from ..convert import ConversionReport, ConversionResult, output_specs
from ..interchange import engines, layered, materialx, usd
from . import compat, layer_group, material, stamp, surface_build
from .context import target_material
from .messages import plain_message
from .reports import report

FALLBACK_STAMP = "hazy_gloss_export_fallback"
IMPORT_STAMP = "hazy_gloss_import"
_PRINCIPLED = "ShaderNodeBsdfPrincipled"
_OUTPUT = "ShaderNodeOutputMaterial"
_USD_FIRST = (_PRINCIPLED, "ShaderNodeBsdfDiffuse")  # what the USD exporter's preview looks for
_RENDER_TARGETS = ("CYCLES", "EEVEE")

# --------------------------------------------------------------------------------------------
# Blender materials -> materialx.Source
# --------------------------------------------------------------------------------------------


def _maps_stamp(mat):
    """The converted-maps stamp as (kind, distribution, anisotropic, {map: path}), or None when
    it does not read."""
    d = stamp.group(mat, K.MAPS_STAMP)
    maps = d.get("maps") if d is not None else None
    if not isinstance(maps, dict) or not all(isinstance(v, str) for v in maps.values()) or \
            d.get("kind") not in K.KINDS or d.get("distribution") not in K.DISTRIBUTIONS:
        return None
    return d["kind"], d["distribution"], bool(d.get("anisotropic")), maps


def _tangent_kind(tree):
    t = material.ours(tree).get("Tangent")
    if t is None or t.bl_idname != "ShaderNodeTangent" or t.direction_type == "UV_MAP":
        return "UV_MAP"
    return f"RADIAL_{t.axis}"


_NODE_PROPS = ("operation", "use_clamp", "data_type", "blend_type", "clamp_factor", "clamp_result",
               "factor_mode", "distribution", "fresnel_type", "subsurface_method", "interpolation",
               "extension", "projection", "target", "direction_type", "axis", "uv_map", "space",
               "mode", "clamp_type")


def _socket_value(sock):
    v = getattr(sock, "default_value", None)
    if v is None or isinstance(v, str):
        return None
    if hasattr(v, "__len__"):
        return tuple(float(x) for x in v)
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def _links_into(tree):
    """{(node name, input identifier): link} of a tree (``socket.links`` walks every link of
    the tree in Python: one table instead, for trees of hundreds of nodes)."""
    return {(lk.to_node.name, lk.to_socket.identifier): lk for lk in tree.links}


def _snap_socket(sock, is_input, into=None):
    link = None
    if is_input and sock.is_linked:
        lk = into.get((sock.node.name, sock.identifier)) if into is not None else sock.links[0]
        if lk is not None and getattr(lk, "is_valid", True) and not getattr(lk, "is_muted", False):
            link = (lk.from_node.name, lk.from_socket.identifier)
    return layered.Socket(sock.identifier, sock.name, sock.type, _socket_value(sock), link,
                          bool(getattr(sock, "enabled", True)),
                          bool(not is_input and sock.is_linked), sock.node.name)


def _image_info(img):
    if img is None:
        return None
    info = dict(name=img.name, source=img.source, packed=img.packed_file is not None,
                colorspace=img.colorspace_settings.name,
                is_data=bool(getattr(img.colorspace_settings, "is_data", False)), path=None)
    raw = img.filepath_raw or img.filepath
    if raw and img.source in ("FILE", "TILED", "SEQUENCE", "MOVIE"):
        path = os.path.normpath(bpy.path.abspath(raw, library=img.library))
        if img.source == "TILED" or os.path.isfile(path):
            info["path"] = path
    return info


def _bnode(n, core=None, prefix="", into=None):
    props = {k: getattr(n, k) for k in _NODE_PROPS if hasattr(n, k)}
    props = {k: (v if isinstance(v, (bool, int, float, str)) else str(v)) for k, v in props.items()}
    b = layered.BNode(prefix + n.name, n.bl_idname, [_snap_socket(x, True, into) for x in n.inputs],
                      [_snap_socket(x, False, into) for x in n.outputs], props, n.label,
                      material.role(n), core is not None and n == core, bool(n.mute))
    if n.bl_idname == "ShaderNodeTexImage":
        b.image = _image_info(n.image)
    if n.bl_idname == "ShaderNodeValToRGB":
        r = n.color_ramp
        b.ramp = dict(color_mode=r.color_mode, interpolation=r.interpolation,
                      elements=[(float(e.position), tuple(float(c) for c in e.color))
                                for e in r.elements])
    return b


def _valid(lk):
    return lk is not None and getattr(lk, "is_valid", True) and not getattr(lk, "is_muted", False)


def _as_type(value, stype):
    if value is None:
        return None
    if stype in ("RGBA", "VECTOR") and not hasattr(value, "__len__"):
        return (value,) * (4 if stype == "RGBA" else 3)
    if stype == "VALUE" and hasattr(value, "__len__"):
        return float(value[0])
    return value


def _inline_group(gnode, nodes, feed, prefix=""):
    """A group node's inside as nodes of the material's tree (named "<node>/<inner>", nested
    groups likewise): a link from its Group Input becomes what ``feed(input identifier)`` gives
    ((node, socket) link or None, value); returns {output identifier: (link, value)} for what
    its Group Output gets."""
    tree = gnode.node_tree
    into = _links_into(tree)
    p = prefix + gnode.name + "/"
    subs = {}

    def source(lk):
        src = lk.from_socket
        n = src.node
        if n.bl_idname == "NodeGroupInput":
            return feed(src.identifier)
        if n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None:
            return sub(n).get(src.identifier, (None, None))
        if n.bl_idname == "NodeReroute":
            up = into.get((n.name, n.inputs[0].identifier))
            return source(up) if _valid(up) else (None, None)
        return (p + n.name, src.identifier), None

    def sub(n):
        if n.name not in subs:
            def sub_feed(identifier, n=n):
                s_ = next((x for x in n.inputs if x.identifier == identifier), None)
                lk_ = into.get((n.name, identifier)) if s_ is not None else None
                if _valid(lk_):
                    return source(lk_)
                return None, (_socket_value(s_) if s_ is not None else None)
            subs[n.name] = {}
            subs[n.name] = _inline_group(n, nodes, sub_feed, p)
        return subs[n.name]

    for n in tree.nodes:
        if n.bl_idname in ("NodeFrame", "NodeGroupInput", "NodeGroupOutput", "NodeReroute"):
            continue
        if n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None:
            sub(n)
            continue
        b = _bnode(n, prefix=p, into=into)
        for sock, snap in zip(n.inputs, b.inputs):
            lk = into.get((n.name, sock.identifier))
            if not _valid(lk):
                continue
            link, value = source(lk)
            snap.link = link
            if link is None:
                snap.value = _as_type(value, snap.type)
        nodes[b.name] = b
    gout = next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"), None)
    redirect = {}
    for s_ in (gout.inputs if gout is not None else ()):
        lk = into.get((gout.name, s_.identifier)) if s_.name else None
        if _valid(lk):
            redirect[s_.identifier] = source(lk)
    return redirect


def _core_view(gnode, kind, settings):
    """The user's BSDF as the layer node holds it (its inputs are the BSDF's own): a node of
    the core's type for the snapshot (the USD preview and the fallback read it)."""
    b = layered.BNode(gnode.name + " (core)", layer_group.BSDF_NODES[kind],
                      [_snap_socket(x, True) for x in gnode.inputs], [], dict(settings),
                      gnode.label, None, True, False)
    b.base = {}
    return b


def tree_snapshot(mat):
    """The node tree of ``mat`` as interchange.layered.Tree (plain values, no bpy), with the
    haze layer's state.  The layer node's group is inlined: the exporters see the BSDF copies,
    mixes and math the group renders with."""
    tree = mat.node_tree
    from . import layer as _layer
    state = _layer.layer_state(mat) or {}
    legacy = bool(state.get("legacy"))
    core = _layer.find_core(tree, state.get("core")) if legacy else None
    gnode = _layer.layer_node(mat) if state and not legacy else None
    nodes, redirect = {}, {}
    into = _links_into(tree)
    for n in tree.nodes:
        if n.bl_idname in ("NodeFrame",):
            continue
        if gnode is not None and n == gnode:
            def feed(identifier, n=n):
                sock = next(x for x in n.inputs if x.identifier == identifier)
                lk = into.get((n.name, identifier))
                if _valid(lk):
                    return (lk.from_node.name, lk.from_socket.identifier), None
                return None, _socket_value(sock)
            redirect = {k: v[0] for k, v in _inline_group(n, nodes, feed).items()}
            continue
        b = _bnode(n, core, into=into)
        if b.core:
            b.base = {k: dict(v) for k, v in state.get("base", {}).items()}
        nodes[b.name] = b
    if gnode is not None:  # links from the layer node come from inside its group
        for b in nodes.values():
            for snap in b.inputs:
                if snap.link is not None and snap.link[0] == gnode.name and snap.link[1] in redirect:
                    snap.link = redirect[snap.link[1]]
    outs = [n for n in tree.nodes if n.bl_idname == _OUTPUT]
    used = _engine_output(outs, "CYCLES")
    lay = {}
    if state:
        h = _layer.haze_of(mat)
        lay = dict(haze={k: (list(v) if isinstance(v, tuple) else v) for k, v in h.items()})
        if legacy:
            lay.update(core=core.name if core is not None else None,
                       core_type=_layer.core_type(core) if core is not None else None,
                       baked=bool(state.get("baked")), live_math=bool(state.get("math")),
                       nodes=sorted(r for r in material.ours(tree) if r.startswith("layer ")))
        elif gnode is not None:
            st = stamp.group(gnode.node_tree, K.GROUP_STAMP) or {}
            kind = st.get("bsdf", "PRINCIPLED")
            settings = st.get("settings", {})
            view = _core_view(gnode, kind, settings)
            nodes[view.name] = view
            lay.update(core=gnode.name, core_type=kind, settings=settings, live_math=True,
                       group=gnode.node_tree.name, version=_layer.LAYER_VERSION,
                       nodes=sorted(n for n in nodes if n.startswith(gnode.name + "/")))
    return layered.Tree(mat.name, nodes, used.name if used is not None else None, lay)


def source_of(mat):
    """(materialx.Source or None, reason) for one Blender material."""
    p = material.read_parameters(mat)
    if p is not None and p.get("layered"):
        if mat.node_tree is None:
            return None, f"“{mat.name}” has no node tree"
        snap = tree_snapshot(mat)
        if snap.output is None:
            return None, f"“{mat.name}” has no Material Output"
        return materialx.Source(mat.name, layer=snap), ""
    if p is not None:
        src = materialx.Source(mat.name, parameters=p)
        if p["shader_mapping"] and mat.node_tree is not None:
            textured = material.UserLinks(mat.node_tree).textured_inputs
            if textured:
                src.notes.append(f"textures linked into {', '.join(textured)} are not exported "
                                 f"(the stamped constants are)")
        return src, ""
    if K.MAPS_STAMP in mat and mat.node_tree is not None:
        read = _maps_stamp(mat)
        if read is None:
            return None, (f"the converted-maps stamp of “{mat.name}” (mat[{K.MAPS_STAMP!r}]) is "
                          f"damaged: convert the maps again")
        kind, distribution, anisotropic, maps = read
        maps = {k: os.path.normpath(bpy.path.abspath(v)) for k, v in maps.items()}
        src = materialx.Source(mat.name, maps=maps, kind=kind, distribution=distribution,
                               anisotropic=anisotropic)
        tree = mat.node_tree
        narrow = material.ours(tree).get("Narrow lobe")
        if src.kind == "DIELECTRIC" and narrow is not None:
            bc = narrow.inputs.get("Base Color")
            tr = narrow.inputs.get("Transmission Weight")
            if bc is not None and not bc.is_linked:
                src.base_color = tuple(bc.default_value)[:3]
            if tr is not None and not tr.is_linked:
                src.transmission = float(tr.default_value)
        src.tangent = _tangent_kind(tree)
        for n in tree.nodes:
            if n.bl_idname == "ShaderNodeTexImage" and material.is_ours(n):
                src.filtertype = {"Closest": "closest", "Cubic": "cubic"}.get(n.interpolation, "linear")
                break
        return src, ""
    return None, f"“{mat.name}” is not a hazy material"


def _materials(materials):
    if materials is None:
        return [m for m in bpy.data.materials if material.is_hazy(m) or K.MAPS_STAMP in m]
    if isinstance(materials, (bpy.types.Material, str)):
        materials = [materials]
    out = []
    for m in materials:
        if isinstance(m, str):
            found = bpy.data.materials.get(m)
            if found is None:
                raise ValueError(f"no material named {m!r}")
            m = found
        out.append(m)
    return out


def sources(materials=None):
    """([Source], [skipped reasons]) for Blender materials (None: every hazy material)."""
    srcs, skipped = [], []
    for m in _materials(materials):
        s, why = source_of(m)
        (srcs.append(s) if s is not None else skipped.append(why))
    return srcs, skipped


def export_materialx(materials=None, path="", flavour="eq1", *, validate=True):
    """Write hazy materials to one MaterialX document; returns a materialx.ExportReport (its
    ``skipped`` lists materials that are not hazy)."""
    srcs, skipped = sources(materials)
    if not srcs:
        raise ValueError("no hazy material to export" + (f" ({'; '.join(skipped)})" if skipped else ""))
    if not os.fspath(path):
        raise ValueError("no file path given")
    rep = materialx.write(srcs, bpy.path.abspath(os.fspath(path)), flavour,
                          validate_with_package=validate)
    rep.skipped = skipped
    return rep


def export_usd(materials=None, path="", *, preview=True):
    """Write hazy materials as UsdShade MaterialX networks (+ UsdPreviewSurface of the core)
    with usd-core; raises RuntimeError when ``pxr`` is not installed."""
    srcs, skipped = sources(materials)
    if not srcs:
        raise ValueError("no hazy material to export" + (f" ({'; '.join(skipped)})" if skipped else ""))
    if not os.fspath(path):
        raise ValueError("no file path given")
    path, done = usd.write(srcs, bpy.path.abspath(os.fspath(path)), preview=preview)
    return path, done, skipped


# --------------------------------------------------------------------------------------------
# Import
# --------------------------------------------------------------------------------------------


class ImportResult(list):
    """The created materials, with ``.report``: one materialx.ImportedMaterial per material
    found in the file (``.material`` is the Blender material, or None when it could not be
    made)."""

    def __init__(self, mats, report):
        super().__init__(mats)
        self.report = report


def _map_material(im):
    info = im.map_info
    kind = str(info["kind"]).upper()
    aniso = bool(info.get("anisotropic"))
    specs = output_specs(kind, aniso)
    missing = [s.name for s in specs if s.name not in im.maps]
    if missing:
        raise ValueError(f"the document lacks the maps {', '.join(missing)}")
    rep = ConversionReport(kind=kind, distribution=str(info["distribution"]).upper(),
                           file_format="", anisotropic=aniso)
    result = ConversionResult({s.name: im.maps[s.name] for s in specs}, rep, specs)
    from .convert import wire_material
    mat = compat.new_material(im.name)
    tree = mat.node_tree
    for n in [n for n in tree.nodes if n.bl_idname != _OUTPUT]:
        tree.nodes.remove(n)
    wire_material(mat, result, base_color=tuple(info.get("base_color", (0, 0, 0))),
                  transmission=float(info.get("transmission", 0.0)),
                  tangent=info.get("tangent", "UV_MAP"))
    return mat


def import_materialx(path, progress=None, apply_haze=None):
    """Materials from a MaterialX document (.mtlx) or a USD file with MaterialX networks
    (.usd/.usda/.usdc, needs usd-core).  Returns an ImportResult (a list of the new
    materials, with ``.report``).  Library surfaces (OpenPBR, standard_surface, gltf_pbr,
    UsdPreviewSurface) become Principled BSDF materials (OpenPBR 1.2's haze a haze layer),
    the add-on's layered exports their layer again, Eq. 1 graphs hazy materials.  Each material
    carries ``mat["hazy_gloss_import"]``: exact, source and the notes of what was not exact.
    ``progress``: callable(fraction, message) — reading is the first half, making the
    materials the second.  ``apply_haze``: callable(material, bsdf node, make_hazy keywords)
    that puts an imported haze layer on (api.import_materialx passes api.make_hazy's)."""
    path = bpy.path.abspath(os.fspath(path))
    if not os.path.isfile(path):
        raise ValueError(f"no file {path!r}")

    def part(lo):
        return None if progress is None else (lambda f, msg: progress(lo + 0.5 * f, msg))

    if os.path.splitext(path)[1].lower() in (".usd", ".usda", ".usdc", ".usdz"):
        found = usd.read(path)
    else:
        found = materialx.read(path, progress=part(0.0))
    mats = []
    step = max(1, len(found) // 100)
    for i, im in enumerate(found):
        im.material = None
        try:
            if im.maps is not None:
                mat = _map_material(im)
            elif im.parameters is not None:
                mat = material.create_material(im.name, **im.parameters)
            elif im.surface is not None:
                mat = surface_build.build(im, apply_haze=apply_haze)
            else:
                continue
        except (ValueError, OSError) as exc:
            im.notes.append(f"not created: {plain_message(exc)}")
            continue
        finally:
            if progress is not None and (i % step == 0 or i == len(found) - 1):
                progress(0.5 + 0.5 * (i + 1) / len(found), "making materials")
        mat[IMPORT_STAMP] = {"file": path, "exact": int(bool(im.exact)), "source": im.source,
                             "notes": "\n".join(im.notes)}
        im.material = mat
        mats.append(mat)
    return ImportResult(mats, found)


# --------------------------------------------------------------------------------------------
# Export fallback for Blender's glTF and USD exporters
# --------------------------------------------------------------------------------------------


def _outputs(tree):
    return [n for n in tree.nodes if n.bl_idname == _OUTPUT]


def _engine_output(outputs, target, active=None):
    """The Material Output a renderer with ``target`` uses (Blender's ntreeShaderOutputNode:
    an exact target beats "All"; among equals the active one, else the first).  ``active``:
    the node to treat as the active output (default: the flagged one)."""
    def is_active(n):
        return n == active if active is not None else n.is_active_output

    best = None
    for n in outputs:
        if n.target == "ALL":
            if best is None or (best.target == "ALL" and is_active(n) and not is_active(best)):
                best = n
        elif n.target == target:
            if best is None or best.target == "ALL" or (is_active(n) and not is_active(best)):
                best = n
    return best


def _role_node(tree, role):
    return material.ours(tree).get(role)


def _new(tree, bl_idname, role, label, location):
    n = tree.nodes.new(bl_idname)
    n.name = f"{K.NODE_PREFIX} {role}"
    n[K.ROLE] = role
    n.label = label
    n.location = location
    return n


def _copy_output_links(tree, src, dst):
    for s in src.inputs:
        d = next((x for x in dst.inputs if x.identifier == s.identifier), None)
        if d is None:
            continue
        if hasattr(s, "default_value") and hasattr(d, "default_value"):
            try:
                d.default_value = s.default_value
            except (TypeError, AttributeError):
                pass
        for link in list(d.links):
            tree.links.remove(link)
        for link in s.links:
            tree.links.new(link.from_socket, d)


def _set(sock, value):
    if sock is None or sock.is_linked or value is None:
        return
    v = value
    if hasattr(sock.default_value, "__len__"):
        v = tuple(value) + (1.0,) * (len(sock.default_value) - len(tuple(value)))
    sock.default_value = v


def _set_fallback_values(node, c, kind):
    ins = node.inputs
    node.distribution = "GGX"
    _set(ins.get("Base Color"), c["base_color"] if kind == "DIELECTRIC" else c["f0"])
    _set(ins.get("Metallic"), c["metallic"])
    _set(ins.get("Roughness"), c["roughness"])
    _set(ins.get("IOR"), c["ior"])
    _set(ins.get("Specular IOR Level"), 0.5)
    _set(ins.get("Specular Tint"), c["specular_tint"])
    _set(ins.get("Transmission Weight"), c["transmission"] if kind == "DIELECTRIC" else 0.0)
    _set(ins.get("Anisotropic"), c["anisotropy"] if c["anisotropy"] is not None else 0.0)
    _set(ins.get("Anisotropic Rotation"), c["rotation"] if c["rotation"] is not None else 0.0)


def _link_like(tree, node, narrow, names):
    """Link ``node``'s inputs from what feeds the same-named inputs of the core lobe."""
    if narrow is None:
        return
    for name in names:
        src = narrow.inputs.get(name)
        dst = node.inputs.get(name)
        if src is None or dst is None:
            continue
        for link in list(dst.links):
            tree.links.remove(link)
        if src.is_linked:
            tree.links.new(src.links[0].from_socket, dst)


def _snapshot(tree, node):
    """Everything needed to recreate one node: settings, socket values, links, custom props."""
    skip = {"name", "label", "location", "width", "height", "parent", "select", "hide", "mute",
            "color", "use_custom_color", "show_options", "show_preview", "show_texture",
            "location_absolute", "warning_propagation", "width_hidden", "is_active_output"}
    props = {}
    for p in node.bl_rna.properties:
        if p.is_readonly or p.identifier in skip or p.identifier.startswith("bl_"):
            continue
        if p.type in ("BOOLEAN", "INT", "FLOAT", "STRING", "ENUM") and getattr(p, "array_length", 0) == 0:
            props[p.identifier] = getattr(node, p.identifier)
    values = []
    for s in node.inputs:
        v = getattr(s, "default_value", None)
        values.append((s.identifier, tuple(v) if hasattr(v, "__len__") else v, s.hide, s.hide_value))
    return dict(
        bl_idname=node.bl_idname, name=node.name, label=node.label, location=tuple(node.location),
        width=node.width, hide=node.hide, mute=node.mute, parent=node.parent,
        use_custom_color=node.use_custom_color, color=tuple(node.color), props=props,
        custom={k: node[k] for k in node.keys()}, values=values,
        links_in=[(l.from_node.name, l.from_socket.identifier, l.to_socket.identifier)
                  for l in tree.links if l.to_node == node],
        links_out=[(l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                   for l in tree.links if l.from_node == node])


def _restore_node(tree, s):
    n = tree.nodes.new(s["bl_idname"])
    n.name = s["name"]
    n.label = s["label"]
    n.location = s["location"]
    n.width = s["width"]
    n.hide = s["hide"]
    n.mute = s["mute"]
    if s["parent"] is not None:
        n.parent = s["parent"]
    n.use_custom_color = s["use_custom_color"]
    n.color = s["color"]
    for k, v in s["props"].items():
        try:
            setattr(n, k, v)
        except (AttributeError, TypeError, ValueError):
            pass
    for k, v in s["custom"].items():
        n[k] = v
    by_id = {x.identifier: x for x in n.inputs}
    for ident, v, hide, hide_value in s["values"]:
        sock = by_id.get(ident)
        if sock is None:
            continue
        if v is not None and hasattr(sock, "default_value"):
            sock.default_value = v
        sock.hide = hide
        sock.hide_value = hide_value
    return n


def _relink(tree, s):
    n = tree.nodes[s["name"]]
    for from_name, from_id, to_id in s["links_in"]:
        src = tree.nodes.get(from_name)
        a = next((x for x in src.outputs if x.identifier == from_id), None) if src else None
        b = next((x for x in n.inputs if x.identifier == to_id), None)
        if a is not None and b is not None:
            tree.links.new(a, b)
    for from_id, to_name, to_id in s["links_out"]:
        dst = tree.nodes.get(to_name)
        a = next((x for x in n.outputs if x.identifier == from_id), None)
        b = next((x for x in dst.inputs if x.identifier == to_id), None) if dst else None
        if a is not None and b is not None:
            tree.links.new(a, b)


def _make_first_bsdf(tree, fallback):
    """Make ``fallback`` the first Principled/Diffuse BSDF of the node list by recreating the
    add-on's BSDF nodes that precede it (remove all, then create the fallback, then them).
    The user's own nodes are never recreated (a script's reference to a removed node points at
    freed memory): when one comes first, a note says so.  Returns (fallback node, notes)."""
    nodes = list(tree.nodes)
    idx = nodes.index(fallback)
    before = [n for n in nodes[:idx] if n.bl_idname in _USD_FIRST]
    if not before:
        return fallback, []
    theirs = [n for n in before if not material.is_ours(n)]
    if theirs:
        return fallback, [f"the tree's own {theirs[0].bl_idname[10:]} “{theirs[0].name}” comes "
                          f"first in the node list: Blender's USD exporter will use it for the "
                          f"preview surface"]
    moved = [n for n in nodes if n.bl_idname in _USD_FIRST and n != fallback and material.is_ours(n)]
    snaps = [_snapshot(tree, n) for n in [fallback] + moved]
    for n in [fallback] + moved:
        tree.nodes.remove(n)
    for s in snaps:
        _restore_node(tree, s)
    for s in snaps:
        _relink(tree, s)
    return tree.nodes[snaps[0]["name"]], []


def has_export_fallback(mat):
    tree = getattr(mat, "node_tree", None)
    return tree is not None and _role_node(tree, K.FALLBACK_ROLE) is not None


def _check_fallback_material(mat):
    if mat is None or getattr(mat, "node_tree", None) is None:
        raise ValueError("no material with a node tree")
    if mat.library is not None:
        raise ValueError(f"material {mat.name!r} is linked from a library and cannot be edited")
    if K.RECOMPOSITE_STAMP in mat:
        raise ValueError(f"{mat.name!r} is in recomposite mode: leave it first")
    p = material.read_parameters(mat)
    if p is None:
        if K.MAPS_STAMP in mat:
            raise ValueError(f"{mat.name!r} is driven by converted maps: the export fallback "
                             f"needs a hazy material with constant parameters")
        raise ValueError(f"{mat.name!r} is not a hazy material")
    return p


def _render_outputs(mat, tree):
    """Step 1: the renderers keep what they used (a dedicated output per target).  Returns
    (the reference output, the user's outputs)."""
    mine = material.ours(tree)
    user_outs = [n for n in _outputs(tree) if not material.is_ours(n)]
    if not user_outs:
        raise ValueError(f"{mat.name!r} has no Material Output")
    if mine.get(K.FALLBACK_OUTPUT_ROLE) is None:
        previous = next((n for n in user_outs if n.is_active_output), user_outs[0])
        mat[FALLBACK_STAMP] = {"version": 1, "active": previous.name}
    ref = tree.nodes.get(_fallback_active(mat)) if FALLBACK_STAMP in mat else None
    if ref is None or material.is_ours(ref):
        ref = user_outs[0]
    loc = ref.location
    for i, target in enumerate(_RENDER_TARGETS):
        role = f"{K.RENDER_OUTPUT_ROLE} {target.capitalize()}"
        ours_t = mine.get(role)
        theirs = [n for n in user_outs if n.target == target]
        if target == "EEVEE" and mine.get(K.EEVEE_OUTPUT_ROLE) is not None:
            theirs.append(mine[K.EEVEE_OUTPUT_ROLE])  # the layer's EEVEE-only output
        if theirs:  # the tree has its own output for this renderer: it keeps winning
            if ours_t is not None:
                tree.nodes.remove(ours_t)
            continue
        used = _engine_output(user_outs, target, ref)
        if ours_t is None:
            ours_t = _new(tree, _OUTPUT, role, f"Render ({target.capitalize()})",
                          (loc.x, loc.y - 300.0 * (i + 1)))
            ours_t.target = target
        _copy_output_links(tree, used, ours_t)
    return ref, user_outs


def _fallback_node(tree, loc):
    mine = material.ours(tree)
    fb = mine.get(K.FALLBACK_ROLE)
    if fb is None or fb.bl_idname != _PRINCIPLED:
        if fb is not None:
            tree.nodes.remove(fb)
        fb = _new(tree, _PRINCIPLED, K.FALLBACK_ROLE, "Export fallback (core lobe)",
                  (loc.x - 300.0, loc.y - 900.0))
    return fb


def _export_output(tree, fb, ref, user_outs):
    """Step 2: the active "All" output the exporters read, fed by the fallback."""
    loc = ref.location
    x_out = material.ours(tree).get(K.FALLBACK_OUTPUT_ROLE)
    if x_out is None:
        x_out = _new(tree, _OUTPUT, K.FALLBACK_OUTPUT_ROLE, "Export (glTF / USD)",
                     (loc.x, loc.y - 900.0))
    x_out.target = "ALL"
    for link in list(x_out.inputs["Surface"].links):
        tree.links.remove(link)
    tree.links.new(fb.outputs[0], x_out.inputs["Surface"])
    used_all = _engine_output(user_outs, "ALL", ref)
    if used_all is not None:  # displacement / volume of the exported surface as before
        for ident in ("Volume", "Displacement"):
            s = used_all.inputs.get(ident)
            d = x_out.inputs.get(ident)
            if s is not None and d is not None:
                for link in list(d.links):
                    tree.links.remove(link)
                if s.is_linked:
                    tree.links.new(s.links[0].from_socket, d)
    x_out.is_active_output = True


def add_export_fallback(mat):
    """Give a hazy material a single-surface fallback that Blender's glTF and USD exporters
    pick up (the core lobe: the material at haziness 0), without changing what Cycles and
    EEVEE render.  Idempotent (a second call refreshes the values); undone by
    :func:`remove_export_fallback`.  Returns a list of notes.  Raises ValueError for a
    material that is not hazy (or is driven by converted maps: not supported yet).

    A material with a haze layer (Make Hazy) gets the user's own BSDF at haziness 0: a
    Principled copy of the core with the user's values and links of the inputs the layer owns
    (:func:`_layer_fallback`)."""
    p = _check_fallback_material(mat)
    if p.get("layered"):
        return _layer_fallback(mat)
    tree = mat.node_tree
    notes = []
    c = engines.core_surface(p, materialx.lobes_of)
    ref, user_outs = _render_outputs(mat, tree)
    loc = ref.location
    fb = _fallback_node(tree, loc)
    _set_fallback_values(fb, c, p["kind"])
    mine = material.ours(tree)
    narrow = mine.get("Narrow lobe")
    _link_like(tree, fb, narrow, ("Normal", "Tangent"))
    tangent = mine.get("Tangent")
    if narrow is None and tangent is not None and c["anisotropy"] is not None:  # in-shader group
        for link in list(fb.inputs["Tangent"].links):
            tree.links.remove(link)
        tree.links.new(tangent.outputs[0], fb.inputs["Tangent"])
    if p["shader_mapping"]:
        textured = material.UserLinks(tree).textured_inputs
        if textured:
            notes.append(f"textures linked into {', '.join(textured)} are not in the fallback "
                         f"(it uses the stamped constants)")
    fb, more = _make_first_bsdf(tree, fb)
    notes += more
    _export_output(tree, fb, ref, user_outs)
    if p["kind"] == "CONDUCTOR":
        notes.append("glTF and USD preview get the core lobe as a metal with F0 = r_c (the "
                     "edge tint survives only as the Principled Specular Tint)")
    return notes


# -- haze layers -----------------------------------------------------------------------------


def _put(tree, sock, value=None, source=None):
    """Set ``sock`` to ``value`` or link it from ``source`` (a socket), dropping other links."""
    if sock is None:
        return
    if source is not None:
        if not (sock.is_linked and sock.links[0].from_socket == source):
            for link in list(sock.links):
                tree.links.remove(link)
            tree.links.new(source, sock)
        return
    for link in list(sock.links):
        tree.links.remove(link)
    if value is not None and hasattr(sock, "default_value"):
        from .nodes.builder import socket_value
        v = socket_value(sock, value)
        cur = sock.default_value
        if (tuple(cur) if hasattr(cur, "__len__") else cur) != v:
            sock.default_value = v


def _user_input(tree, core, base, name):
    """(value, source socket or None) of the core's input ``name`` as the user set it: the
    stamped user value or link of an input the layer owns, else what the core holds now."""
    from . import layer as _layer
    sock = core.inputs.get(name)
    b = base.get(name)
    if b is not None:
        src = _layer._resolve(tree, b["link"]) if "link" in b else None
        val = b.get("value", _socket_value(sock) if sock is not None else None)
        return val, src
    if sock is None:
        return None, None
    src = sock.links[0].from_socket if sock.is_linked else None
    if src is not None and (material.is_ours(src.node) and
                            (material.role(src.node) or "").startswith("layer ")):
        src = None  # a layer node (cannot happen for inputs the layer does not own)
    return _socket_value(sock), src


def _layer_fallback(mat):
    """The export fallback of a layered material: the user's BSDF at haziness 0 (coat
    haziness 0 too).  For a Principled core, a copy of it with every value and link, the
    owned inputs (IOR, Base Color, Metallic, Coat IOR, ...) given the user's own values or
    links back; for a Metallic or Glossy core, a metallic Principled with its colour,
    roughness and anisotropy."""
    from . import layer as _layer
    tree = mat.node_tree
    state = _layer.layer_state(mat) or {}
    if state.get("legacy"):
        core = _layer.find_core(tree, state.get("core"))
        base = dict(state.get("base", {}))
    else:  # the layer node's inputs are the user's own values and links
        node = _layer.layer_node(mat)
        core = _CoreProxy(node, state) if node is not None else None
        base = {}
    if core is None:
        raise ValueError(f"the core node of {mat.name!r} is gone: Remove Haze and Make Hazy again")
    notes = []
    ref, user_outs = _render_outputs(mat, tree)
    fb = _fallback_node(tree, ref.location)
    fb.label = "Export fallback (your BSDF at haziness 0)"
    skip = {"Weight"}
    if core.bl_idname == _PRINCIPLED:
        for prop in ("distribution", "subsurface_method"):
            if getattr(fb, prop) != getattr(core, prop):
                setattr(fb, prop, getattr(core, prop))
        for sock in fb.inputs:
            if sock.name in skip or core.inputs.get(sock.name) is None:
                continue
            val, src = _user_input(tree, core, base, sock.name)
            _put(tree, sock, val, src)
    else:
        _metal_fallback(tree, fb, core, base, notes)
    first = next((n for n in tree.nodes if n.bl_idname in _USD_FIRST), None)
    if first is not None and first != fb:
        what = ("the layer's core: the narrow lobe, with the inputs the haze raises"
                if first == core else "your BSDF as it was before haze (kept beside the layer node)"
                if first.get(K.ORIGINAL_NODE_KEY) else "not the fallback")
        notes.append(f"Blender's USD exporter takes the first Principled / Diffuse BSDF of the "
                     f"node list for its UsdPreviewSurface: “{first.name}”, {what}. Its MaterialX "
                     f"network (the USD export option) and glTF get the fallback")
    _export_output(tree, fb, ref, user_outs)
    return notes


class _CoreProxy:
    """The layer node seen as the user's BSDF: its inputs, the BSDF's type and settings."""

    def __init__(self, node, state):
        st = stamp.group(node.node_tree, K.GROUP_STAMP) or {}
        self.node = node
        self.name = node.name
        self.inputs = node.inputs
        self.bl_idname = layer_group.BSDF_NODES[st.get("bsdf", "PRINCIPLED")]
        self.settings = dict(st.get("settings") or state.get("settings") or {})

    def __getattr__(self, name):
        if name in ("distribution", "subsurface_method", "fresnel_type"):
            return self.settings.get(name, {"distribution": "GGX", "subsurface_method": "RANDOM_WALK",
                                            "fresnel_type": "F82"}[name])
        raise AttributeError(name)

    def __eq__(self, other):
        return other is self or other == self.node

    __hash__ = object.__hash__


def _metal_fallback(tree, fb, core, base, notes):
    """A metallic Principled for a Metallic / Glossy core (F82: Base Color and Edge Tint are
    Principled's metal F82 model; Physical Conductor: r and the F82 tint of its Fresnel;
    Glossy: Color as F0, tint 1)."""
    from ..core import conventions, gulbrandsen_inverse
    from ..interchange.brdf import fresnel_conductor
    u = lambda name: _user_input(tree, core, base, name)  # noqa: E731
    dist = core.distribution if core.distribution in ("GGX", "MULTI_GGX") else "GGX"
    if core.distribution != dist:
        notes.append(f"the Principled fallback has no {core.distribution.title()}: GGX")
    fb.distribution = dist
    _put(tree, fb.inputs["Metallic"], 1.0)
    for name in ("Normal", "Tangent"):
        _put(tree, fb.inputs[name], None, u(name)[1])
    _put(tree, fb.inputs["Roughness"], *u("Roughness"))
    glossy = core.bl_idname != "ShaderNodeBsdfMetallic"
    if glossy:
        _put(tree, fb.inputs["Base Color"], *u("Color"))
        _put(tree, fb.inputs["Specular Tint"], (1.0, 1.0, 1.0, 1.0))
        (a, a_src), (rot, rot_src) = u("Anisotropy"), u("Rotation")
        if a_src is not None or rot_src is not None:
            notes.append("the Glossy BSDF's linked anisotropy is not in the fallback")
            a, rot = 0.0, 0.0
        r = float(u("Roughness")[0])
        ax, ay = layered.glossy_alpha(r, a)
        if ax != ay:
            rough, ratio, swap = conventions.lobe_from_alpha(ax, ay)
            a = float(conventions.metallic_anisotropy(ratio))
            rot = float(rot) + (0.25 if swap else 0.0)
        else:
            a = 0.0
        _put(tree, fb.inputs["Anisotropic"], a)
        _put(tree, fb.inputs["Anisotropic Rotation"], rot)
        notes.append("glTF and USD get the Glossy BSDF as a metal with F0 = Color (a Glossy lobe "
                     "has no Fresnel; the metal brightens towards grazing angles)")
        return
    _put(tree, fb.inputs["Anisotropic"], *u("Anisotropy"))
    _put(tree, fb.inputs["Anisotropic Rotation"], *u("Rotation"))
    if core.fresnel_type == "PHYSICAL_CONDUCTOR":
        (eta, e_src), (kap, k_src) = u("IOR"), u("Extinction")
        if e_src is not None or k_src is not None:
            notes.append("the Physical Conductor's linked IOR / Extinction are not in the fallback")
        eta = np.maximum(np.asarray(eta, float)[:3], 0.0)
        kap = np.maximum(np.asarray(kap, float)[:3], 0.0)
        r, _ = gulbrandsen_inverse(eta, kap)
        r = np.clip(np.nan_to_num(r), 0.0, 1.0)
        tint, _ = engines.f82_tint_fit(lambda c: fresnel_conductor(c, eta, kap), r)
        _put(tree, fb.inputs["Base Color"], tuple(r) + (1.0,))
        _put(tree, fb.inputs["Specular Tint"], tuple(tint) + (1.0,))
        notes.append("glTF and USD get the Physical Conductor as Principled's F82 metal (F0 = r, "
                     "the tint matching its Fresnel at 82°)")
    else:
        _put(tree, fb.inputs["Base Color"], *u("Base Color"))
        _put(tree, fb.inputs["Specular Tint"], *u("Edge Tint"))


def remove_export_fallback(mat):
    """Remove what :func:`add_export_fallback` added and make the previous output active
    again.  Returns True when something was removed."""
    tree = getattr(mat, "node_tree", None)
    if tree is None:
        return False
    mine = material.ours(tree)
    roles = [K.FALLBACK_ROLE, K.FALLBACK_OUTPUT_ROLE] + [
        f"{K.RENDER_OUTPUT_ROLE} {t.capitalize()}" for t in _RENDER_TARGETS]
    removed = False
    for r in roles:
        n = mine.get(r)
        if n is not None:
            tree.nodes.remove(n)
            removed = True
    if FALLBACK_STAMP in mat:
        name = _fallback_active(mat)
        del mat[FALLBACK_STAMP]
        prev = tree.nodes.get(name)
        if prev is None:
            prev = next(iter(_outputs(tree)), None)
        if prev is not None:
            prev.is_active_output = True
        removed = True
    return removed


def _fallback_active(mat):
    """The name of the output the fallback replaced ("" when its stamp does not say)."""
    name = (stamp.group(mat, FALLBACK_STAMP) or {}).get("active", "")
    return name if isinstance(name, str) else ""


def refresh_export_fallback(mat):
    """Refresh the fallback's values if the material has one (no-op otherwise)."""
    if has_export_fallback(mat) or FALLBACK_STAMP in mat:
        return add_export_fallback(mat)
    return []


def refresh_stamped_fallback(mat):
    """refresh_export_fallback where the material's stamp says it has one (a key lookup, no
    tree scan: called after every layer or EEVEE-output change).  Raises ValueError as
    add_export_fallback does."""
    if FALLBACK_STAMP in mat:
        refresh_export_fallback(mat)


# --------------------------------------------------------------------------------------------
# Operators (thin: the work is above)
# --------------------------------------------------------------------------------------------

_SELECTION = [("ALL", "All Hazy Materials", "Every hazy material in the file"),
              ("SELECTED", "Selected Objects", "Hazy materials of the selected objects"),
              ("ACTIVE", "Active Material", "The active object's active material")]
_FLAVOURS = [("eq1", "Eq. 1 (MaterialX 1.39 pbr)", "Exact: a mix of two lobes with one Fresnel, "
              "standard library nodes only"),
             ("openpbr_1.2", "OpenPBR 1.2 (unreleased)", "open_pbr_surface 1.2 with specular_haze: "
              "approximate (its error is reported); the 1.2 nodedef is embedded")]


def _selected_materials(context, selection):
    if selection == "ALL":
        return None
    if selection == "ACTIVE":
        m = target_material(context)
        return [m] if m is not None else []
    mats = []
    for obj in getattr(context, "selected_objects", []) or []:
        for slot in getattr(obj, "material_slots", []):
            if slot.material is not None and slot.material not in mats:
                mats.append(slot.material)
    return mats


class HAZY_GLOSS_OT_export_materialx(bpy.types.Operator, ExportHelper):
    """Write hazy materials to a MaterialX document: each one an exact Eq. 1 graph (a mix of two
    microfacet lobes sharing one Fresnel) from the standard library"""

    bl_idname = "hazy_gloss.export_materialx"
    bl_label = "Export Hazy Gloss MaterialX"
    bl_options = {"REGISTER"}

    filename_ext = ".mtlx"
    filter_glob: StringProperty(default="*.mtlx", options={"HIDDEN"})
    selection: EnumProperty(name="Materials", items=_SELECTION, default="ALL")
    flavour: EnumProperty(name="Flavour", items=_FLAVOURS, default="eq1")
    validate: BoolProperty(name="Validate", default=True,
                           description="Validate with the materialx package when it is installed")

    def execute(self, context):
        mats = _selected_materials(context, self.selection)
        try:
            rep = export_materialx(mats, self.filepath, self.flavour, validate=self.validate)
        except (ValueError, OSError) as exc:
            report(self, "ERROR", plain_message(exc))
            return {"CANCELLED"}
        report(self, "INFO", f"Wrote {len(rep.materials)} hazy material"
               f"{'s' if len(rep.materials) != 1 else ''} to {bpy.path.basename(rep.path)}")
        if rep.validated is None and self.validate:
            report(self, "WARNING", "Not validated: the materialx package is not installed "
                   "(pip install materialx); the file itself does not need it")
        elif rep.validated is False:
            report(self, "ERROR", f"MaterialX validation failed: {rep.validation}")
        notes = rep.notes + list(getattr(rep, "skipped", []))
        if notes:
            report(self, "WARNING", "; ".join(notes[:6]))
        return {"FINISHED"}


class HAZY_GLOSS_OT_export_usd(bpy.types.Operator, ExportHelper):
    """Write hazy materials to USD as MaterialX networks (UsdShade), with a UsdPreviewSurface of
    the core lobe (needs the pxr module: pip install usd-core)"""

    bl_idname = "hazy_gloss.export_usd"
    bl_label = "Export Hazy Gloss USD"
    bl_options = {"REGISTER"}

    filename_ext = ".usda"
    filter_glob: StringProperty(default="*.usd;*.usda;*.usdc", options={"HIDDEN"})
    selection: EnumProperty(name="Materials", items=_SELECTION, default="ALL")
    preview: BoolProperty(name="Preview Surface", default=True,
                          description="Add a UsdPreviewSurface of the core lobe")

    def execute(self, context):
        if not usd.available():
            report(self, "ERROR", usd.USD_MISSING)
            return {"CANCELLED"}
        mats = _selected_materials(context, self.selection)
        try:
            path, done, skipped = export_usd(mats, self.filepath, preview=self.preview)
        except (ValueError, OSError, RuntimeError) as exc:
            report(self, "ERROR", plain_message(exc))
            return {"CANCELLED"}
        report(self, "INFO", f"Wrote {len(done)} hazy material{'s' if len(done) != 1 else ''} "
               f"to {bpy.path.basename(path)}")
        if skipped:
            report(self, "WARNING", "; ".join(skipped[:6]))
        return {"FINISHED"}


class HAZY_GLOSS_OT_add_export_fallback(bpy.types.Operator):
    """Make Blender's glTF and USD exporters write the core lobe of this hazy material (its look
    at haziness 0) instead of nothing or the halo; renders are unchanged"""

    bl_idname = "hazy_gloss.add_export_fallback"
    bl_label = "Add Export Fallback (glTF / USD)"
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(name="Material", default="", options={"HIDDEN", "SKIP_SAVE"})
    all_materials: BoolProperty(name="All Hazy Materials", default=False, options={"SKIP_SAVE"},
                                description="Every hazy material of the file, not only this one")

    def execute(self, context):
        if self.all_materials:
            mats = [m for m in bpy.data.materials if material.is_hazy(m) and m.library is None
                    and K.RECOMPOSITE_STAMP not in m]
        else:
            mats = [target_material(context, self.material)]
        done, notes = [], []
        for mat in mats:
            try:
                notes += add_export_fallback(mat)
            except ValueError as exc:
                if not self.all_materials:
                    report(self, "ERROR", plain_message(exc))
                    return {"CANCELLED"}
                notes.append(plain_message(exc))
                continue
            done.append(mat.name)
        if not done:
            report(self, "ERROR", "No hazy material to give an export fallback")
            return {"CANCELLED"}
        report(self, "INFO", (f"“{done[0]}”" if len(done) == 1 else f"{len(done)} materials")
               + ": glTF and USD export now get the core lobe")
        if notes:
            report(self, "WARNING", "; ".join(sorted(set(notes))))
        return {"FINISHED"}


class HAZY_GLOSS_OT_remove_export_fallback(bpy.types.Operator):
    """Remove the export fallback nodes and make the previous output active again"""

    bl_idname = "hazy_gloss.remove_export_fallback"
    bl_label = "Remove Export Fallback"
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(name="Material", default="", options={"HIDDEN", "SKIP_SAVE"})

    def execute(self, context):
        mat = target_material(context, self.material)
        if mat is None or not remove_export_fallback(mat):
            report(self, "ERROR", "No export fallback to remove")
            return {"CANCELLED"}
        report(self, "INFO", f"“{mat.name}”: export fallback removed")
        return {"FINISHED"}


# --------------------------------------------------------------------------------------------
# Menu entries (appended by menus.add_entries through menus.ENTRIES)
# --------------------------------------------------------------------------------------------


def draw_export_menu(self, context):
    self.layout.operator("hazy_gloss.export_materialx", text="Hazy Gloss MaterialX (.mtlx)")
    self.layout.operator("hazy_gloss.export_usd", text="Hazy Gloss USD (.usda)")


def draw_import_menu(self, context):
    self.layout.operator("hazy_gloss.import_materialx", text="Hazy Gloss MaterialX (.mtlx, .usd)")


def draw_material_menu(self, context):
    layout = self.layout
    layout.separator()
    layout.operator("hazy_gloss.add_export_fallback")
    layout.operator("hazy_gloss.add_export_fallback",
                    text="Add Export Fallback to All Hazy Materials").all_materials = True
    layout.operator("hazy_gloss.remove_export_fallback")
    op = layout.operator("hazy_gloss.export_materialx", text="Export Hazy Material (MaterialX)")
    op.selection = "ACTIVE"


classes = (HAZY_GLOSS_OT_export_materialx, HAZY_GLOSS_OT_export_usd,
           HAZY_GLOSS_OT_add_export_fallback, HAZY_GLOSS_OT_remove_export_fallback)

register, unregister = bpy.utils.register_classes_factory(classes)
