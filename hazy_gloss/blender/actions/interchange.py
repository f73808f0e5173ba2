# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy materials in and out of Blender: MaterialX / USD export and import.

The formats are bpy-free (hazy_gloss/interchange); this module reads Blender materials into
``materialx.Source`` objects and creates materials from what is imported (library surfaces
through blender/model/surface_build.py); the operators (File > Import / Export, the material context
menu) are blender/ui/interchange_ops.py.  A material with a haze layer (Make Hazy) becomes a snapshot of its node tree (:func:`tree_snapshot`), which
interchange/layered.py writes node by node (docs/interchange.md §5).  The export fallback for
Blender's own glTF and USD exporters is blender/model/fallback.py.
"""
import hashlib
import os
import re
import shutil

import bpy
import numpy as np

from ... import constants as K
from ...conversion.convert import ConversionReport, ConversionResult, output_specs
from ...interchange import layered_tree, materialx, usd
from .. import compat
from ..model import fallback, layer, layer_group, material, material_read, stamp, surface_build
from ..model.convert_outputs import MapFile
from ..model.convert_wiring import wire_material
from .messages import plain_message
from ..nodes.builder import default_value_of

__all__ = ("IMPORT_STAMP", "tree_snapshot", "source_of", "sources", "tables_folder", "write_tables",
           "export_materialx", "export_usd", "ImportResult", "import_materialx")

IMPORT_STAMP = "hazy_gloss_import"
_OUTPUT = "ShaderNodeOutputMaterial"

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
    return layered_tree.Socket(sock.identifier, sock.name, sock.type, default_value_of(sock), link,
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
    b = layered_tree.BNode(prefix + n.name, n.bl_idname, [_snap_socket(x, True, into) for x in n.inputs],
                      [_snap_socket(x, False, into) for x in n.outputs], props, n.label,
                      material.role(n), core is not None and n == core, bool(n.mute))
    if n.bl_idname in K.IMAGE_NODES:
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
                return None, (default_value_of(s_) if s_ is not None else None)
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
    b = layered_tree.BNode(gnode.name + " (core)", layer_group.BSDF_NODES[kind],
                      [_snap_socket(x, True) for x in gnode.inputs], [], dict(settings),
                      gnode.label, None, True, False)
    b.base = {}
    return b


def tree_snapshot(mat):
    """The node tree of ``mat`` as interchange.layered_tree.Tree (plain values, no bpy), with the
    haze layer's state.  The layer node's group is inlined: the exporters see the BSDF copies,
    mixes and math the group renders with."""
    tree = mat.node_tree
    state = layer.layer_state(mat) or {}
    gnode = layer.layer_node(mat) if state else None
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
                return None, default_value_of(sock)
            redirect = {k: v[0] for k, v in _inline_group(n, nodes, feed).items()}
            continue
        b = _bnode(n, None, into=into)
        nodes[b.name] = b
    if gnode is not None:  # links from the layer node come from inside its group
        for b in nodes.values():
            for snap in b.inputs:
                if snap.link is not None and snap.link[0] == gnode.name and snap.link[1] in redirect:
                    snap.link = redirect[snap.link[1]]
    outs = [n for n in tree.nodes if n.bl_idname == _OUTPUT]
    used = fallback.engine_output(outs, "CYCLES")
    lay = {}
    if state:
        h = layer.haze_of(mat)
        lay = dict(haze={k: (list(v) if isinstance(v, tuple) else v) for k, v in h.items()})
        if gnode is not None:
            st = stamp.group(gnode.node_tree, K.GROUP_STAMP) or {}
            kind = st.get("bsdf", "PRINCIPLED")
            settings = st.get("settings", {})
            view = _core_view(gnode, kind, settings)
            nodes[view.name] = view
            lay.update(core=gnode.name, core_type=kind, settings=settings, live_math=True,
                       group=gnode.node_tree.name, version=layer.LAYER_VERSION,
                       nodes=sorted(n for n in nodes if n.startswith(gnode.name + "/")))
    return layered_tree.Tree(mat.name, nodes, used.name if used is not None else None, lay)


def source_of(mat):
    """(materialx.Source or None, reason) for one Blender material; its notes name what is
    animated (MaterialX and USD get the current frame's values)."""
    src, why = _source_of(mat)
    moving = _animated_inputs(mat) if src is not None else []
    if moving:
        src.notes.append(f"{', '.join(moving)} {'is' if len(moving) == 1 else 'are'} animated "
                         f"(keys or drivers): written with frame "
                         f"{bpy.context.scene.frame_current}'s value"
                         f"{'' if len(moving) == 1 else 's'} (the file holds no animation)")
    return src, why


def _animated_inputs(mat):
    """“Node” Input for each input of ``mat``'s tree driven by keys or drivers."""
    tree = mat.node_tree
    out = []
    for path in sorted(compat.animated_paths(tree) if tree is not None else ()):
        try:
            sock = tree.path_resolve(path.rsplit(".", 1)[0])
        except ValueError:
            continue
        if isinstance(sock, bpy.types.NodeSocket):
            out.append(f"“{sock.node.name}” {sock.name}")
    return out


def _source_of(mat):
    p = material_read.read_parameters(mat)
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
        return [m for m in bpy.data.materials if material_read.is_hazy(m) or K.MAPS_STAMP in m]
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


def tables_folder(path):
    """The folder :func:`write_tables` writes the tables of the document ``path`` into."""
    return os.path.splitext(path)[0] + "_tables"


def write_tables(srcs, path):
    """The images the documents read that have no file on disk, written as float OpenEXR files
    in "<document>_tables/" beside the document ``path``, and the snapshots' images pointed at
    them: the layers' lookup tables (Multiscatter, glass, thin film: written as constants, the
    document gave a thin film's specular_color 4.25 where Cycles renders 3.1-3.25) and packed
    or generated images of the artist's (a painted haziness map: written at the socket's value,
    it rendered 23 % off).  A file's name ends with the hash of its values, so one already
    there of that name holds them and is kept.  Returns the files."""
    folder = tables_folder(path)
    files = {}  # image name -> file
    images = [b.image for src in srcs if src.layer is not None for b in src.layer.nodes.values()
              if getattr(b, "image", None)]
    for img in images:
        name = str(img.get("name", ""))
        if img.get("path"):
            continue
        image = bpy.data.images.get((name, None)) or bpy.data.images.get(name)
        if name not in files and image is not None and image.size[0] * image.size[1] > 0:
            if name.startswith(K.TABLE_IMAGE_PREFIX):  # (its name ends with its hash)
                stem, px = name[len(K.TABLE_IMAGE_PREFIX):].replace(" ", "_"), None
            else:
                px = _pixels(image)
                digest = hashlib.sha1(px.tobytes()).hexdigest()[:12]
                stem = _SAFE_NAME.sub("_", name).strip("_") + "_" + digest
            file = os.path.join(folder, stem + ".exr")
            if not os.path.isfile(file):
                os.makedirs(folder, exist_ok=True)
                _write_table(image, file, px)
            files[name] = file
        if name in files:
            img["path"] = files[name]
    return sorted(set(files.values()))


#: What a file name keeps of an image's name.
_SAFE_NAME = re.compile(r"[^\w.-]+")


def _pixels(image):
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    return px


def _write_table(image, file, px=None):
    """``image`` (its pixels ``px`` when read already) as the float OpenEXR ``file``, in the
    values it holds (its colour space stays the snapshot's): written to a temporary, read back
    (convert_outputs.MapFile) and only then moved into place."""
    w, h = image.size
    px = _pixels(image) if px is None else px
    tmp = file + ".partial"
    out = MapFile("OPEN_EXR", "ZIP", tmp, file, w, h)
    try:
        out.append(out.encode(0, px.reshape(h, w, 4)[::-1, :, :3]))  # (a file's top row first)
        out.finish()
        os.replace(tmp, file)
    finally:
        out.abort()
        if os.path.exists(tmp):
            os.remove(tmp)


class _Undone:
    """What an export adds beside its document (the tables, missing folders) taken away again
    when the export does not finish (an error, Ctrl+C): nothing partial is left.  Once the
    document is in place (renamed over the old one) it stays with its tables: complete."""

    def __init__(self, path):
        self.path, self.before = path, materialx.file_identity(path)
        self.tables = tables_folder(path)
        self.had = set(os.listdir(self.tables)) if os.path.isdir(self.tables) else None
        self.made, folder = [], os.path.dirname(path)
        while folder and not os.path.lexists(folder):  # (the writers create them)
            self.made.append(folder)
            folder = os.path.dirname(folder)

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if kind is None or materialx.file_identity(self.path) != self.before:
            return False
        if self.had is None:
            shutil.rmtree(self.tables, ignore_errors=True)
        elif os.path.isdir(self.tables):
            for name in set(os.listdir(self.tables)) - self.had:
                try:
                    os.remove(os.path.join(self.tables, name))
                except OSError:
                    pass
        for folder in self.made:  # deepest first; only while empty
            try:
                os.rmdir(folder)
            except OSError:
                break
        return False


def _output(path, kind):
    """``path`` made absolute; ValueError (one line) when it must not be written."""
    if not os.fspath(path):
        raise ValueError("no file path given")
    path = os.path.abspath(bpy.path.abspath(os.fspath(path)))
    problem = materialx.output_problem(path, kind)
    if problem is not None:
        raise ValueError(problem)
    return path


def export_materialx(materials=None, path="", flavour="eq1", *, validate=True):
    """Write hazy materials to one MaterialX document; returns a materialx.ExportReport (its
    ``skipped`` lists materials that are not hazy; ``tables`` the lookup tables written beside
    it, :func:`write_tables`).  ValueError when ``path`` is a folder or an existing file that
    is not a MaterialX document (materialx.output_problem); a failed or interrupted export
    leaves nothing behind."""
    srcs, skipped = sources(materials)
    if not srcs:
        raise ValueError("no hazy material to export" + (f" ({'; '.join(skipped)})" if skipped else ""))
    path = _output(path, "mtlx")
    with _Undone(path):
        tables = write_tables(srcs, path)
        rep = materialx.write(srcs, path, flavour, validate_with_package=False)
    if validate:  # (after the write: the document is complete whatever happens here)
        rep.validated, rep.validation = materialx.validate(path)
    rep.tables = tables
    rep.skipped = skipped
    return rep


def export_usd(materials=None, path="", *, preview=True):
    """Write hazy materials as UsdShade MaterialX networks (+ UsdPreviewSurface of the core)
    with usd-core; raises RuntimeError when ``pxr`` is not installed, ValueError when ``path``
    is not a .usd/.usda/.usdc name or an existing file that is not a USD layer; a failed or
    interrupted export leaves nothing behind."""
    srcs, skipped = sources(materials)
    if not srcs:
        raise ValueError("no hazy material to export" + (f" ({'; '.join(skipped)})" if skipped else ""))
    path = _output(path, "usd")
    if not usd.available():
        raise RuntimeError(usd.USD_MISSING)
    with _Undone(path):
        write_tables(srcs, path)
        path, done = usd.write(srcs, path, preview=preview)
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
        said = len(im.notes)
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
            im.exact = False
            continue
        finally:
            if progress is not None and (i % step == 0 or i == len(found) - 1):
                progress(0.5 + 0.5 * (i + 1) / len(found), "making materials")
        if len(im.notes) > said:  # (a missing texture, an input this Blender lacks: not reproduced)
            im.exact = False
        mat[IMPORT_STAMP] = {"file": path, "exact": int(bool(im.exact)), "source": im.source,
                             "notes": "\n".join(im.notes)}
        im.material = mat
        mats.append(mat)
    return ImportResult(mats, found)
