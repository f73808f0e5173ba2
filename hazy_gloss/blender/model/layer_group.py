# SPDX-License-Identifier: GPL-3.0-or-later
"""The haze layer's node group: one per configuration (BSDF type, distribution, subsurface
method or Fresnel type, haze curve, the parts the material uses, Blender version), shared by
every material that has it.

Its interface is the wrapped BSDF's own inputs — names, types, limits, defaults and panels as
Blender declares them (core.tables.bsdf_interfaces, read through Make Group) — and a Haze panel
(schema.HAZE_SOCKETS): the same for every configuration of a BSDF, so a layer node moves
between them keeping its values, links and animation.  Its inside is core.layer_graph emitted
as built-in nodes, each part of the mapping in a labelled frame (node_layout), then the BSDF
slots (copies of the wrapped node type whose inputs are the group's own, except those the
mapping computes) and their Mix Shaders.  Two outputs: "BSDF" (the layer) and "EEVEE" (each
layer's lobes folded into one, for the EEVEE-only output).
"""
from __future__ import annotations

import hashlib
import re
import sys

import bpy

from ... import constants as K
from ... import node_layout
from ...core import (body_colour, graph, layer_graph, multiscatter, node_body_colour, node_fresnel,
                     node_math, node_multiscatter, node_thin_film, thin_film)
from ...core.multiscatter import cycles_version
from ...core import tables
from ...core.tables import bsdf_interfaces, cycles_albedo_tables
from ... import schema
from . import groups, stamp
from ..nodes import builder
from ..nodes import emit as emit_module
from ..nodes.builder import TreeBuilder, socket_value
from ..nodes.emit import emit
from .groups import rebuild_interface

__all__ = ("LAYER_GROUP_VERSION", "BSDF_NODES", "NODE_SETTINGS", "version_tag", "settings_of",
           "kind_of", "all_parts", "config_for", "PART_LETTERS", "group_name", "fits", "parts_of",
           "is_layer_group", "ensure_group", "SHIPPED_DIR", "SHIPPED", "COPY_SUFFIX", "share_tables",
           "same_table", "write_shipped", "bsdf_inputs", "haze_params", "LOBES_FRAME", "build",
           "forget_edits", "edited_parts")

#: Bumped when what a layer group holds changes: older groups are rebuilt in place on first
#: use (4: one flat group of the parts a material uses, each in a frame; 5: a Multiscatter
#: Newton step of 23 math nodes, not 26).
LAYER_GROUP_VERSION = 5

BSDF_NODES = {"PRINCIPLED": "ShaderNodeBsdfPrincipled", "METALLIC": "ShaderNodeBsdfMetallic",
              "GLOSSY": "ShaderNodeBsdfGlossy"}
#: Node settings a configuration fixes (the group node has no enum properties).
NODE_SETTINGS = {"PRINCIPLED": ("distribution", "subsurface_method"),
                 "METALLIC": ("distribution", "fresnel_type"), "GLOSSY": ("distribution",)}
_LABEL = {"PRINCIPLED": "Hazy Principled BSDF", "METALLIC": "Hazy Metallic BSDF",
          "GLOSSY": "Hazy Glossy BSDF"}
_SETTING_LABEL = {"RANDOM_WALK": "", "RANDOM_WALK_SKIN": "Skin", "BURLEY": "Christensen-Burley",
                  "F82": "F82", "PHYSICAL_CONDUCTOR": "Physical"}


def version_tag(version=None):
    v = cycles_version(version)
    return f"{v[0]}.{v[1]}"


def settings_of(node):
    """{setting: value} of a BSDF node (what a configuration fixes)."""
    kind = kind_of(node)
    settings = {p: getattr(node, p) for p in NODE_SETTINGS[kind]}
    unknown = [p for p, v in settings.items() if not v]  # (an enum a newer Blender saved)
    if unknown:
        prop = node.bl_rna.properties[unknown[0]].name
        raise ValueError(f"the {prop} of “{node.name}” is one this Blender does not know (the "
                         f"file was saved by a newer Blender): pick one in the node, then try "
                         f"again")
    return settings


def kind_of(node):
    for kind, idname in BSDF_NODES.items():
        if node.bl_idname == idname or (kind == "GLOSSY" and node.bl_idname == "ShaderNodeBsdfAnisotropic"):
            return kind
    return None


def all_parts(kind):
    """Every part a group of ``kind`` can hold (core.layer_graph.PARTS), sorted."""
    return tuple(sorted(layer_graph.PARTS[kind]))


def _parts(kind, parts, baked):
    """The parts of a configuration as stamped (sorted names; a converted group holds all)."""
    if baked or parts is None:
        return all_parts(kind)
    return tuple(sorted(parts))


def config_for(kind, settings, *, smooth=False, baked=False, body=False, parts=None):
    """The layer_graph.Config of a BSDF kind, its node settings and the parts it holds."""
    return layer_graph.Config(kind, settings.get("distribution", "GGX"),
                              fresnel=settings.get("fresnel_type", ""), smooth=bool(smooth),
                              version=cycles_version(None), baked=bool(baked), body=bool(body),
                              parts=frozenset(_parts(kind, parts, baked)))


#: A part's letter in a group's name (docs/node-groups.md lists them).
PART_LETTERS = {"dielectric": "D", "metal": "M", "coat": "C", "film": "F", "transmission": "T",
                "thin_wall": "W", "aniso": "A"}


def group_name(kind, settings, smooth=False, baked=False, body=False, parts=None):
    """E.g. "Hazy Principled BSDF (Multiscatter GGX, Skin, Smooth, DC, 5.3)": the parts by
    their letters (PART_LETTERS) where not all (< 64 bytes; the version inside the brackets:
    Blender reads a trailing ".3" as a copy's number)."""
    words = [K.label(K.DISTRIBUTION_TERMS, settings.get("distribution", ""))]
    for key in ("subsurface_method", "fresnel_type"):
        label = _SETTING_LABEL.get(settings.get(key), "")
        if label:
            words.append(label)
    if smooth:
        words.append("Smooth")
    if baked:
        words.append("Converted")
    if body:
        words.append("Body")
    held = _parts(kind, parts, baked)
    if held != all_parts(kind):
        words.append("".join(PART_LETTERS[p] for p in held) or "Iso")
    name = f"{_LABEL[kind]} ({', '.join(words + [version_tag()])})"
    for long, short in _SHORTER:  # Blender's ID names hold 63 bytes
        if len(name.encode()) <= 63:
            break
        name = name.replace(long, short)
    return name


_SHORTER = (("Christensen-Burley", "Burley"),
            (K.label(K.DISTRIBUTION_TERMS, "MULTI_GGX"), "MS GGX"),
            (K.label(K.DISTRIBUTION_TERMS, "ASHIKHMIN_SHIRLEY"), "AS"), (" BSDF (", " ("))


def _stamp_of(kind, settings, smooth, baked=False, body=False, parts=None):
    d = {"kind": "layer", "version": LAYER_GROUP_VERSION, "bsdf": kind, "settings": dict(settings),
         "smooth": int(bool(smooth)), "blender": version_tag(),
         "parts": list(_parts(kind, parts, baked))}
    if baked:
        d["baked"] = 1
    if body:
        d["body"] = 1
    return d


def fits(ng, kind, settings, smooth, baked=False, body=False, parts=None, linked_ok=False):
    """Whether ``ng`` is this Blender's and add-on's group of the configuration (a linked group
    is read-only here, so it does not fit a local layer unless ``linked_ok``)."""
    if ng is None or (ng.library is not None and not linked_ok):
        return False
    return (stamp.group(ng, K.GROUP_STAMP) or {}) == _stamp_of(kind, settings, smooth, baked, body,
                                                                parts)


def parts_of(ng):
    """The parts a layer group holds (its stamp; an earlier add-on's group: all of them)."""
    st = stamp.group(ng, K.GROUP_STAMP) or {}
    parts = st.get("parts")
    return tuple(parts) if parts is not None else all_parts(st.get("bsdf", "PRINCIPLED"))


def is_layer_group(ng):
    return ng is not None and (stamp.group(ng, K.GROUP_STAMP) or {}).get("kind") == "layer"


def ensure_group(kind, settings, smooth=False, baked=False, body=False, parts=None):
    """The group of this configuration: found by its stamp (a renamed group is taken), else
    appended from the groups the extension ships or the per-user cache, else built (and
    cached); an outdated group of the same name is rebuilt in place (its users keep their links
    and values)."""
    config = (kind, settings, smooth, baked, body, _parts(kind, parts, baked))
    name = group_name(*config)
    ng = bpy.data.node_groups.get(name)
    if fits(ng, *config) and not edited_parts(ng, cached=True):
        return ng
    # (a group the artist edited is theirs: a new layer gets one as built)
    found = next((g for g in bpy.data.node_groups if fits(g, *config)
                  and not edited_parts(g, cached=True)), None)
    if found is not None:
        return found
    # an outdated group of this name is rebuilt in place; an edited one stays the artist's
    stale = ng is not None and ng.library is None and is_layer_group(ng) and not fits(ng, *config)
    if not stale:
        cached = _from_cache(name, config)
        if cached is not None:
            return _unedited(cached)
    if not stale:
        ng = bpy.data.node_groups.new(name, "ShaderNodeTree")
    before = set(bpy.data.node_groups), set(bpy.data.images)
    try:
        build(ng, *config)
    except Exception as exc:  # (nothing half-built stays in the file)
        bpy.data.batch_remove([i for c, old in zip((bpy.data.node_groups, bpy.data.images), before)
                               for i in c if i not in old] + ([] if stale else [ng]))
        raise ValueError(f"building the layer group “{name}” failed: {exc}") from exc
    ng[K.GROUP_STAMP] = _stamp_of(*config)
    _keep_one_copy(ng, *before)
    _to_cache(ng)
    return _unedited(ng)


# --------------------------------------------------------------------------------------------
# The per-user cache: building a group takes seconds (every node edit in Blender updates the
# whole tree), appending it from a .blend tens of milliseconds
# --------------------------------------------------------------------------------------------

#: The modules whose code builds the groups: their files are hashed (a module object, not a path,
#: so a moved or renamed module cannot drop out of the hash unnoticed), and so are the data
#: tables they read (core/tables/*.json).
_SOURCES = (sys.modules[__name__], emit_module, builder, groups, layer_graph, node_math,
            node_fresnel, node_multiscatter, node_body_colour, body_colour, node_thin_film,
            thin_film, cycles_albedo_tables, graph, bsdf_interfaces, multiscatter, K, schema)
_digest = []

#: Where the built extension keeps the layer groups it ships, under the package (beside
#: assets/, not in it: the asset library holds assets only).
SHIPPED_DIR = ("layer_groups",)
#: The configurations shipped (built by each Blender scripts/build.py finds): each BSDF's
#: default settings and the other distribution an artist picks most, with the parts of the
#: commonest materials (a plastic, a metal, a metallic map, a car paint, a lacquer).
_PRINCIPLED_PARTS = (("dielectric",), ("metal",), ("dielectric", "metal"), ("coat", "metal"),
                     ("coat", "dielectric"))
SHIPPED = tuple(
    [("PRINCIPLED", {"distribution": d, "subsurface_method": "RANDOM_WALK"}, parts)
     for d in ("MULTI_GGX", "GGX") for parts in _PRINCIPLED_PARTS]
    + [("METALLIC", {"distribution": d, "fresnel_type": f}, ()) for d in ("MULTI_GGX", "GGX")
       for f in ("F82", "PHYSICAL_CONDUCTOR")]
    + [("GLOSSY", {"distribution": d}, ()) for d in ("MULTI_GGX", "GGX")])


def _code_digest():
    """A hash of the code that builds groups (a cached group from other code is not taken)."""
    if not _digest:
        h = hashlib.sha256()
        for path in [module.__file__ for module in _SOURCES] + tables.files():
            with open(path, "rb") as fh:
                h.update(fh.read())
        _digest.append(h.hexdigest()[:16])
    return _digest[0]


def _file_name(name):
    """The .blend of a group in the per-user cache and in the extension's shipped groups."""
    import re
    slug = re.sub(r"[^A-Za-z0-9.]+", "_", name).strip("_")
    return f"{_code_digest()}-{LAYER_GROUP_VERSION}-{slug}.blend"


def _shipped_path(name):
    """Where the built extension ships this group (scripts/build.py: write_shipped)."""
    import os
    package_dir = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return os.path.join(package_dir, *SHIPPED_DIR, _file_name(name))


def _cache_path(name):
    import os
    import re
    try:
        base = bpy.utils.extension_path_user(__package__.rpartition(".blender")[0],
                                             path="layer_groups", create=True)
    except (ValueError, TypeError, AttributeError, RuntimeError):
        # registered by a script (import hazy_gloss; register()): a per-user temporary folder
        import getpass
        import tempfile
        try:
            user = re.sub(r"[^A-Za-z0-9]+", "_", getpass.getuser())
        except (KeyError, OSError):
            user = "user"
        base = os.path.join(tempfile.gettempdir(), f"hazy_gloss_{user}", "layer_groups")
        try:
            os.makedirs(base, exist_ok=True)
        except OSError:
            return None
    return os.path.join(base, _file_name(name))


def _from_cache(name, config):
    """The group appended from the extension's shipped groups, else from the per-user cache;
    None when neither has it (or holds a group that does not fit)."""
    for path in (_shipped_path(name), _cache_path(name)):
        ng = _append(path, name, config)
        if ng is not None:
            return ng
    return None


def _drop_library(path):
    """The Library entry an append leaves behind (it holds nothing once the data is local)."""
    import os
    for lib in [lib for lib in bpy.data.libraries
                if os.path.normcase(os.path.abspath(bpy.path.abspath(lib.filepath)))
                == os.path.normcase(os.path.abspath(path))]:
        if not any(i.library == lib for c in (bpy.data.node_groups, bpy.data.images) for i in c):
            bpy.data.libraries.remove(lib)


def _append(path, name, config):
    import os
    if path is None or not os.path.isfile(path):
        return None
    before = set(bpy.data.node_groups), set(bpy.data.images)
    try:
        with bpy.data.libraries.load(path, link=False) as (src, dst):
            if name not in src.node_groups:
                return None
            dst.node_groups = [name]
    except (OSError, RuntimeError):
        return None
    finally:
        _drop_library(path)
    new = [g for g in bpy.data.node_groups if g not in before[0]]
    for i in new + [i for i in bpy.data.images if i not in before[1]]:
        i.use_fake_user = False  # (as built ones: dropped on save once nothing uses them)
    ng = next((g for g in new if fits(g, *config)), None)
    _keep_one_copy(ng, *before)
    return ng


def _keep_one_copy(ng, groups_before, images_before):
    """After ``ng`` was appended or built: the table images that came with it give way to the
    file's where those are the same (share_tables), and what nothing of ``ng`` uses is removed,
    in one pass over the file (everything new, when ``ng`` is None)."""
    groups_before, images_before = _alive(groups_before), _alive(images_before)
    new_groups = [g for g in bpy.data.node_groups if g not in groups_before]
    new_images = [i for i in bpy.data.images if i not in images_before]
    if ng is not None:
        share_tables(ng, images_before, new_images)
    used = set() if ng is None else {ng} | {n.image for n in ng.nodes
                                            if n.bl_idname in K.IMAGE_NODES and n.image}
    drop = [i for i in new_groups + new_images if i not in used]
    if drop:
        bpy.data.batch_remove(drop)


def _alive(ids):
    """``ids`` without those removed since."""
    out = set()
    for i in ids:
        try:
            i.name
        except ReferenceError:
            continue
        out.add(i)
    return out


#: What Blender adds to the name of a data-block appended beside one of the same name.
COPY_SUFFIX = re.compile(r"\.\d{3,}$")


def share_tables(ng, images_before, new_images):
    """Point ``ng``'s table lookups at the tables the file has already (the same name, the same
    values) instead of the copies an append brought ("<name>.001")."""
    names = {i.name: i for i in images_before if i.library is None}  # (never a linked one)
    copies = {}
    for i in new_images:
        base = COPY_SUFFIX.sub("", i.name)
        if base != i.name and base in names and same_table(i, names[base]):
            copies[i] = names[base]
    for node in ng.nodes:
        if node.bl_idname in K.IMAGE_NODES and node.image in copies:
            node.image = copies[node.image]


def same_table(new, old):
    """The same table: the same hash of its values, the same packed bytes."""
    digest = new.get("hazy_gloss_table")
    return digest is not None and old.get("hazy_gloss_table") == digest and \
        new.packed_file is not None and old.packed_file is not None and \
        old.packed_file.data == new.packed_file.data


def _to_cache(ng):
    import os
    path = _cache_path(ng.name)
    if path is None:
        return
    tmp = path + f".{os.getpid()}.tmp"
    try:
        bpy.data.libraries.write(tmp, {ng}, fake_user=True, compress=True)
        os.replace(tmp, path)
    except (OSError, RuntimeError):
        try:
            os.remove(tmp)
        except OSError:
            pass


def write_shipped(out_dir, configs=None):
    """Build the ``configs`` (default SHIPPED) with this Blender and write each into
    ``out_dir`` as the cache names it (scripts/build.py puts them in the extension, so the first
    Make Hazy on a machine appends instead of building).  Returns the files written."""
    import os
    os.makedirs(out_dir, exist_ok=True)
    written = []
    for kind, settings, parts in configs or SHIPPED:
        config = (kind, dict(settings), False, False, False, parts)
        name = group_name(*config)
        if bpy.data.node_groups.get((name, None)) is not None:
            raise RuntimeError(f"write_shipped runs in an empty file; {name!r} is in this one")
        ng = bpy.data.node_groups.new(name, "ShaderNodeTree")
        build(ng, *config)
        ng[K.GROUP_STAMP] = _stamp_of(*config)
        path = os.path.join(out_dir, _file_name(name))
        bpy.data.libraries.write(path, {ng}, fake_user=True, compress=True)
        written.append(path)
    return written


# --------------------------------------------------------------------------------------------
# Interface
# --------------------------------------------------------------------------------------------


def _declarations(kind):
    tables = bsdf_interfaces.TABLES
    tag = version_tag()
    if tag not in tables:  # a newer Blender: its sockets, with the newest known declarations
        tag = max(tables, key=lambda t: tuple(int(x) for x in t.split(".")))
    return tables[tag][kind]


def bsdf_inputs(node):
    """The enabled inputs of a BSDF node, in order (what the group's interface mirrors)."""
    return [s for s in node.inputs if s.enabled]


def _new_socket(iface, name, decl, parent):
    stype = decl.get("type", "NodeSocketFloat")
    s = iface.new_socket(name=name, in_out="INPUT", socket_type=stype, parent=parent)
    if decl.get("subtype") and hasattr(s, "subtype"):
        try:
            s.subtype = decl["subtype"]
        except (TypeError, ValueError):
            pass
    for attr, key in (("min_value", "min_value"), ("max_value", "max_value"),
                      ("default_value", "default")):
        if key in decl and hasattr(s, attr):
            try:
                setattr(s, attr, decl[key])
            except (TypeError, ValueError):
                pass
    s.hide_value = bool(decl.get("hide_value", False))
    return s


def _interface(ng, kind, template, smooth, baked=False):
    """The wrapped BSDF's inputs (``template``: a node of that kind and configuration) in its
    panels, then the Haze panel (or, converted, the Converted Maps); outputs BSDF and EEVEE."""
    iface = ng.interface
    iface.new_socket(name="BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
    eevee = iface.new_socket(name="EEVEE", in_out="OUTPUT", socket_type="NodeSocketShader")
    eevee.description = ("Each layer's narrow and wide lobes folded into one with the same peak: "
                         "for the EEVEE-only output (Hazy Gloss panel, EEVEE setting)")
    decl = _declarations(kind)
    panels = {}
    for sock in bsdf_inputs(template):
        d = dict(decl["sockets"].get(sock.name, {}))
        if not d:  # not declared in the table: the socket's own type
            d = {"type": {"VALUE": "NodeSocketFloat", "RGBA": "NodeSocketColor",
                          "VECTOR": "NodeSocketVector", "BOOLEAN": "NodeSocketBool",
                          "INT": "NodeSocketInt"}.get(sock.type, "NodeSocketFloat"),
                 "hide_value": sock.hide_value}
        title = d.get("panel", "")
        parent = None
        if title:
            parent = panels.get(title)
            if parent is None:
                parent = panels[title] = iface.new_panel(
                    title, default_closed=decl["panels"].get(title, True))
        _new_socket(iface, sock.name, d, parent)
    if baked:
        maps = iface.new_panel("Converted Maps", default_closed=False)
        for key, (name, colour) in layer_graph.BAKED.items():
            s = iface.new_socket(name=name, in_out="INPUT", parent=maps,
                                 socket_type="NodeSocketColor" if colour else "NodeSocketFloat")
            s.description = "Written by texture conversion (the haze mapping per texel)"
        return
    haze = iface.new_panel(K.HAZE_PANEL, default_closed=False)
    for param in haze_params(kind, smooth):
        name, default, lo, hi, desc = schema.HAZE_SOCKETS[param]
        s = iface.new_socket(name=name, in_out="INPUT", socket_type="NodeSocketFloat", parent=haze)
        if _SOCKET_PARAMETER[param].factor and hasattr(s, "subtype"):
            s.subtype = "FACTOR"
        s.default_value, s.min_value, s.max_value, s.description = default, lo, hi, desc


_SOCKET_PARAMETER = {k: p for p in schema.SCHEMA for k in schema.socket_keys(p)}


def haze_params(kind, smooth):
    """The haze sockets (schema.HAZE_SOCKETS keys) a group of ``kind`` has, in panel order."""
    return schema.layer_sockets(kind, smooth)


# --------------------------------------------------------------------------------------------
# Inside
# --------------------------------------------------------------------------------------------

#: Rows an unlinked vector input draws (its label and x, y, z).
_VECTOR_ROWS = 4
#: The title of the frame of the BSDF's copies (an ungrouped layer is told by it).
LOBES_FRAME = "Eq. 1: the BSDF's copies, mixed by β"


def build(ng, kind, settings, smooth, baked=False, body=False, parts=None):
    """(Re)build ``ng`` for this configuration.  An existing interface is kept when it is the
    same (the group nodes' links and values stay).  Every node computes in this one tree
    (Blender's MaterialX and USD exporters flatten groups anyway); each section of the math
    sits in a labelled frame of at most node_layout.FRAME_MAX nodes, with a Group Input of the
    sockets it reads, and the BSDF copies and their Mix Shaders in a last frame."""
    ng.nodes.clear()
    template = ng.nodes.new(BSDF_NODES[kind])
    for p, v in settings.items():
        setattr(template, p, v)
    rebuild_interface(ng, lambda tree: _interface(tree, kind, template, smooth, baked),
                      update_sockets=False)
    ng.nodes.remove(template)
    cfg = config_for(kind, settings, smooth=smooth, baked=baked, body=body, parts=parts)
    lay = layer_graph.build(cfg)

    def inputs(gin):
        """{graph input name: socket} of a Group Input."""
        out = {layer_graph.input_name(sock.name): sock for sock in gin.outputs if sock.name}
        if baked:
            out.update({layer_graph.baked_name(key): gin.outputs[name]
                        for key, (name, _) in layer_graph.BAKED.items()})
        else:
            out.update({layer_graph.haze_name(p): gin.outputs[schema.HAZE_SOCKETS[p][0]]
                        for p in haze_params(kind, smooth)})
        return out

    # -- the math: each section with a Group Input of its own, framed below ----------------
    wanted = {k: e for k, e in lay.outputs().items() if e is not None}
    titles = {}
    for e in lay.graph.used(wanted):
        if e.op != "input":
            titles.setdefault(lay.section_of(e), []).append(e)
    gins, routes = {}, {}
    for title in titles:
        gins[title] = gin = ng.nodes.new("NodeGroupInput")
        gin.label = "Inputs"
        routes[title] = inputs(gin)
    first = next(iter(titles))
    if body:  # the view cosine Keep Body Colour reads, on the BSDF's normal
        lw = ng.nodes.new("ShaderNodeLayerWeight")
        lw.label = "View cosine (Keep Body Colour)"
        lw.inputs["Blend"].default_value = 0.5
        title = next((t for t in titles if t.startswith("Keep Body Colour")), first)
        ng.links.new(gins[title].outputs["Normal"], lw.inputs["Normal"])
        for r in routes.values():
            r[node_body_colour.FACING] = lw.outputs["Facing"]
        titles.setdefault(title, [])
    made = {}
    tb = TreeBuilder(ng, prefix="")
    tb.set_locations = False  # (laid out once, below: each location set updates the tree)
    outs = emit(tb, lay.graph, wanted, routes[first], nodes_by_expr=made,
                route=lambda e: routes[lay.section_of(e)])
    section_of = {}
    for index in sorted(made):
        section_of.setdefault(made[index].name, lay.section_of(lay.graph.nodes[index]))
    members = {title: [] for title in titles}
    for n in tb.created:
        members[section_of[n.name]].append(n)
    if body:
        members[title].insert(0, lw)
    frames = []
    for title, nodes in members.items():
        boxes = [node_layout.Box(n, tb.grid.get(n.name, (0, 0))[0], n.width, _height(n))
                 for n in nodes]
        chunked = node_layout.chunks(title, boxes, node_layout.FRAME_MAX - 1)
        gin = gins[title]
        for sock in gin.outputs:  # each Group Input shows the sockets it feeds
            sock.hide = bool(sock.name) and not sock.is_linked
        chunked[0].boxes.insert(0, node_layout.Box(gin, -1, gin.width, _height(gin)))
        frames += chunked

    # -- the BSDF copies and their Mix Shaders --------------------------------------------
    gin = ng.nodes.new("NodeGroupInput")
    gin.label = "Inputs (passed to every BSDF)"
    lobes = []
    results = {}
    for tree_name, tree in (("BSDF", lay.cycles), ("EEVEE", lay.eevee)):
        results[tree_name] = _closures(ng, tree, kind, settings, outs, gin, lobes)
    gout = ng.nodes.new("NodeGroupOutput")
    for name, sock in results.items():
        ng.links.new(sock, gout.inputs[name])
    for sock in gin.outputs:
        sock.hide = bool(sock.name) and not sock.is_linked
    last = max(d for _, d in lobes) + 1
    frames.append(node_layout.Frame(LOBES_FRAME, (
        [node_layout.Box(gin, -1, gin.width, _height(gin))]
        + [node_layout.Box(n, d, n.width, _height(n)) for n, d in lobes]
        + [node_layout.Box(gout, last, gout.width, _height(gout))])))
    node_layout.layout(frames)
    for frame in frames:
        f = ng.nodes.new("NodeFrame")
        f.label = frame.title
        f.label_size = 16
        f.shrink = True
        for b in frame.boxes:
            b.key.parent = f
            _place(b.key, b.x, b.y)
    ng[K.GROUP_PRINT] = _fingerprint(ng)
    return lay


def _place(node, x, y):
    """The node's top-left corner at (x, y) in the group, whatever its frame (Blender 4.4 on
    keeps a framed node's location relative to its frame: location_absolute is the tree's)."""
    if hasattr(node, "location_absolute"):
        node.location_absolute = (x, y)
    else:
        node.location = (x, y)


def _height(node):
    """The node's height for the layout (node_layout.node_height): its visible sockets, an
    unlinked vector input as its label and three rows."""
    rows = sum(1 for s in node.outputs if s.enabled and not s.hide)
    for s in node.inputs:
        if not s.enabled or s.hide or (s.hide_value and not s.is_linked and s.type != "SHADER"):
            continue
        rows += _VECTOR_ROWS if s.type == "VECTOR" and not s.is_linked else 1
    return node_layout.node_height(node.bl_idname, rows)


def forget_edits():
    """Node groups changed: what edited_parts(cached=True) remembered is stale."""
    _edited_seen.clear()


_edited_seen = {}  # (group session_uid, sizes) -> edited_parts (forget_edits clears it)


def _unedited(ng):
    """``ng`` as this code just built or appended it: no edit to look for."""
    _edited_seen[(ng.session_uid, len(ng.nodes), len(ng.links))] = []
    return ng


def edited_parts(ng, cached=False):
    """[the layer group's name] when ``ng`` was edited since it was built (its fingerprint
    differs; none for another Blender's group: it hashes otherwise, and its note says
    Upgrade).  ``cached``: as last found until forget_edits or a node or link more or less
    (hashing the group takes milliseconds)."""
    if cached:  # (keyed also by node and link counts: a script's edit shows at once)
        key = (ng.session_uid, len(ng.nodes), len(ng.links))
        if key not in _edited_seen:
            _edited_seen[key] = edited_parts(ng)
        return _edited_seen[key]
    if (stamp.group(ng, K.GROUP_STAMP) or {}).get("blender") != version_tag():
        return []
    return [ng.name] if isinstance(ng.get(K.GROUP_PRINT), str) and \
        ng[K.GROUP_PRINT] != _fingerprint(ng) else []


def _fingerprint(ng):
    """What a group holds: its nodes (name, type, operation, unlinked input values) and how
    many links (so a group the artist edited is told from ours)."""
    h = hashlib.sha1(str(len(ng.links)).encode())
    for n in ng.nodes:
        if n.bl_idname == "NodeFrame":
            continue
        h.update(f"{n.name}|{n.bl_idname}|{getattr(n, 'operation', '')}".encode())
        for sock in n.inputs:
            if not sock.is_linked and hasattr(sock, "default_value"):
                v = sock.default_value
                h.update(repr(tuple(v) if hasattr(v, "__len__") else v).encode())
    return h.hexdigest()


def _closures(ng, tree, kind, settings, outs, gin, made):
    """Nodes of a layer_graph closure tree (``made`` collects (node, depth): BSDF copies at
    depth 0, each Mix Shader one column right of its inputs); returns the root's output."""

    def visit(node):
        if isinstance(node, layer_graph.Slot):
            bsdf = ng.nodes.new(BSDF_NODES[kind])
            for p, v in settings.items():
                setattr(bsdf, p, v)
            bsdf.name = bsdf.label = node.role
            bsdf.hide = False
            for sock in bsdf_inputs(bsdf):
                key = (node.role, sock.name)
                if sock.name in node.writes:
                    value = outs[key]
                    if hasattr(value, "node"):
                        ng.links.new(value, sock)
                    elif value is not None and hasattr(sock, "default_value"):
                        sock.default_value = socket_value(sock, value)
                elif sock.name in gin.outputs:
                    ng.links.new(gin.outputs[sock.name], sock)
            made.append((bsdf, 0))
            return bsdf.outputs[0], 0
        (a, da), (b, db) = visit(node.a), visit(node.b)
        mix = ng.nodes.new("ShaderNodeAddShader" if node.add else "ShaderNodeMixShader")
        mix.name = mix.label = node.role
        first = 0 if node.add else 1
        if not node.add:
            fac = outs[(node.role, "factor")]
            if hasattr(fac, "node"):
                ng.links.new(fac, mix.inputs[0])
            else:
                mix.inputs[0].default_value = float(fac)
        ng.links.new(a, mix.inputs[first])
        ng.links.new(b, mix.inputs[first + 1])
        d = max(da, db) + 1
        made.append((mix, d))
        return mix.outputs[0], d

    return visit(tree)[0]
