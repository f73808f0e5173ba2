# SPDX-License-Identifier: GPL-3.0-or-later
"""Scripting API: create, update and read hazy materials; convert texture maps.

    import hazy_gloss; hazy_gloss.register()
    from hazy_gloss import api
    mat = api.create_material("Brushed", kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3),
                              edge_tint=(1, 0.8, 0.5), roughness=0.1, haziness=0.8, haze_extent=5)
    api.update_material(mat, haziness=0.3)      # sets socket values; the peak does not change
    notes = api.make_hazy(bpy.data.materials["Car Paint"], haziness=0.4, coat_haziness=0.6)
    for line in notes:                          # a layer; what it cannot do, and the fix
        print(line)

Roughness is Blender's R = √α (α = R²).  Perceptual parameters are stamped on the material as
an ID property (``mat["hazy_gloss"]``), so a file saved with hazy materials keeps them and
renders identically where the add-on is not installed (only built-in nodes are used).
Everything here delegates to ``hazy_gloss.blender`` (bpy) and ``hazy_gloss.core`` (numpy).
"""
from . import constants as K
from .blender.model import layer as _layer, material as _material, material_read as _material_read
from .core.parameters import DEFAULTS, PARAMETERS, is_anisotropic, normalise as normalise_parameters
from .schema import HAZE_SOCKETS

STAMP = K.STAMP
NODE_PREFIX = K.NODE_PREFIX
KINDS = K.KINDS
GROUP_NODE = _material.GROUP_NODE
min_roughness = K.min_roughness
is_ours = _material.is_ours
is_hazy = _material_read.is_hazy
read_parameters = _material_read.read_parameters
map_parameters = _material.map_parameters
lobes_for = _material.lobes_for


def create_material(name, *, kind="CONDUCTOR", core_reflectivity=(0.5, 0.5, 0.5), edge_tint=0.0,
                    roughness=0.1, anisotropy=0.0, haziness=0.5, haze_extent=5.0, smoothness=None,
                    distribution="GGX", shader_mapping=False, **extra):
    """Create a hazy material.  ``roughness`` is Blender's R = √α_n; ``haze_extent`` a number or
    an (x, y) pair; ``smoothness`` None (Eq. 7) or the Bézier weight w.  Extra keywords:
    rotation, base_color, transmission (dielectric), tangent ("UV_MAP" or "RADIAL_X/Y/Z").
    Raises ValueError (one line naming the parameter) before creating anything."""
    return _material.create_material(
        name, kind=kind, core_reflectivity=core_reflectivity, edge_tint=edge_tint,
        roughness=roughness, anisotropy=anisotropy, haziness=haziness, haze_extent=haze_extent,
        smoothness=smoothness, distribution=distribution, shader_mapping=shader_mapping, **extra)


class Notes(list):
    """What a haze layer says of itself after a change (one plain line each: haze that cannot
    show and the setting that fixes it, a peak it cannot hold, a part it approximates); empty
    when there is nothing to say.  ``material``: the material."""

    def __init__(self, material, lines=()):
        super().__init__(lines)
        self.material = material


def make_hazy(mat, *, haziness=None, haze_extent=None, **haze):
    """Put a haze layer on ``mat``'s own Principled, Metallic or Glossy BSDF (the one closest to
    the Material Output, also inside Mix / Add Shader trees): every input and link of it and
    everything else in the tree stay; at haziness 0 the material renders exactly as before.
    On a material that has a layer already, the haze values given are set on it and the others
    kept (a new layer starts from haziness 0, haze_extent 5 for those not given).
    Haze keywords: those of ``hazy_gloss.schema.HAZE_PARAMETERS`` (docs/parameters.md's haze
    layer table: haziness, haze_extent (a number or an (x, y) pair), smoothness, ...);
    ``node`` (a node or its name) picks the BSDF.  Returns the layer's :class:`Notes` (``.material``: ``mat``); raises
    ValueError (one line, the reason) when it cannot, touching nothing."""
    from .blender.actions import make_hazy as _make
    _material_read.check_material(mat, "make_hazy")
    status, msg, notes = _make.make_hazy(mat, haziness=haziness, haze_extent=haze_extent, **haze)
    if status == "ERROR":
        raise ValueError(msg)
    return Notes(mat, notes)


def upgrade_layers(materials=None):
    """Move layer nodes whose group another Blender or Hazy Gloss made to this one's
    (``materials``: all of the file's by default, passing over linked ones with a
    UserWarning; a layer also moves on its first haze edit).  Returns the names of the
    materials upgraded; raises ValueError (one line) when there were old layers and none could
    be upgraded."""
    from .blender.model import layer
    from .blender.actions import make_hazy as _make
    mats = _make.materials_or_all(materials)
    for m in mats:
        _material_read.check_material(m, "upgrade_layers")
    old = [m for m in mats if layer.outdated_group(m)]
    status, msg, notes = _make.upgrade_layers(old, every=materials is None)
    if status == "ERROR":
        raise ValueError(notes[0] if notes else msg)
    if notes:
        import warnings
        warnings.warn("; ".join(notes), UserWarning, stacklevel=2)
    return [m.name for m in old if not layer.outdated_group(m)]


def add_haziness_map(mat, *, size=1024, param="haziness"):
    """Link a paintable float image (filled with the current value, packed into the file) into
    the layer node's Haziness (``param="coat_haziness"``: Coat Haziness) through an Image
    Texture, made the active paint slot; what is painted is packed again when the file is
    saved.  Returns the image; raises ValueError (one line); what stands in the way of painting
    (no UV map) comes as a UserWarning."""
    from .blender.model import layer
    from .blender.actions import make_hazy as _make
    _material_read.check_material(mat, "add_haziness_map")
    status, msg, notes = _make.add_haziness_map(mat, size=size, param=param)
    if status == "ERROR":
        raise ValueError(msg)
    if notes:
        import warnings
        warnings.warn(f"{mat.name}: {'; '.join(notes)}", UserWarning, stacklevel=2)
    sock = layer.layer_node(mat).inputs[HAZE_SOCKETS[param][0]]
    return sock.links[0].from_node.image


def create_look(look, name=None, **haze):
    """A new Principled material for one of the looks (``hazy_gloss.utils.looks.LOOKS``: CAR_PAINT,
    LACQUERED_WOOD, SATIN_VARNISH, BRUSHED_ALUMINIUM, WORN_PLASTIC) with its haze layer;
    ``haze`` overrides the look's haze parameters (haziness=0, coat_haziness=0: the original)."""
    from .blender.actions import looks as _looks
    return _looks.create_look(look, name, **haze)


def remove_haze(mat):
    """Take the haze layer off ``mat``: its BSDF gets the user's own values and links back and
    the layer's nodes go.  Returns whether there was a layer; what it could not give back as it
    was comes as a UserWarning."""
    from .blender.actions import make_hazy as _make
    _material_read.check_material(mat, "remove_haze")
    status, msg, notes = _make.remove_haze(mat)
    if status == "ERROR":
        raise ValueError(msg)
    if notes:
        import warnings
        warnings.warn(f"{mat.name}: {'; '.join(notes)}", UserWarning, stacklevel=2)
    return status == "FINISHED"


def add_eevee_output(mat, mode="auto"):
    """Give the layered ``mat`` an EEVEE-only output: one BSDF with each layer's narrow and wide
    lobes folded into one that keeps its peak (docs/mapping.md §12), for noise-free EEVEE
    previews; Cycles keeps rendering the full layer.  ``mode`` "auto" builds it only where EEVEE
    would otherwise pick lobes at random (a Principled core with a coat), "always" for any
    layer.  The request is kept: the output follows every later change of the layer.  Returns
    ``{"added": bool, "reason": str, "nodes": int}``; raises ValueError when ``mat`` has no layer."""
    from .blender.actions import eevee_output as _eevee
    _material_read.check_material(mat, "add_eevee_output")
    return _eevee.add_eevee_output(mat, mode=mode)


def remove_eevee_output(mat):
    """Take the EEVEE-only output off ``mat`` (EEVEE renders the full layer again).  Returns
    whether there was one."""
    from .blender.actions import eevee_output as _eevee
    _material_read.check_material(mat, "remove_eevee_output")
    return _eevee.remove_eevee_output(mat)


def sync_haze(mat):
    """Read a lean / in-shader material's node-editor edits back into its parameters, bring a
    haze layer's group (the parts its inputs reach) and export fallback up to date with its
    node (a handler does this for materials in use; call it for a material no object uses).
    A haze layer's render needs nothing: its node computes from its inputs.
    Returns whether anything changed; raises ValueError (one line) on linked data."""
    from .blender.actions import sync as _sync
    _material_read.check_material(mat, "sync_haze")
    if mat.library is not None or getattr(mat, "override_library", None) is not None:
        raise ValueError(_material_read.edit_problem(mat))  # (read-only here, as everywhere)
    return _sync.sync(mat, force=True)


def update_material(mat, **changes):
    """Change some parameters of a hazy material: socket values are set in place when the node
    structure stays the same, else the hazy nodes are rebuilt keeping the user's links.  On a
    material made hazy with :func:`make_hazy` (a haze layer) the changes are haze parameters
    (the core's own are its node's inputs) and it returns the layer's :class:`Notes`; on a
    whole hazy material (create_material) the HazeMapping of the new parameters.

    Values the user changed in the node editor on the add-on's nodes are read back first (the
    group's inputs of an in-shader material; a lean tree through the inverse haze mapping); what
    cannot be read back is replaced, with a UserWarning naming it."""
    return _update(mat, changes)[0]


def update_material_links(mat, **changes):
    """:func:`update_material`, also returning the group inputs whose links had to be dropped
    because the new configuration has no such input (e.g. Edge Tint of a dielectric)."""
    return _update(mat, changes)


def _update(mat, changes):
    from .blender.actions import edit as _edit
    out = _edit.update_material(mat, **changes)
    if out[0] is None and _layer.is_layered(mat):
        out = (Notes(mat, _layer.held_haze(mat, changes) + _layer.notes(mat)), out[1])
    replaced = _edit.REPLACED.get(mat.session_uid)
    if replaced:
        import warnings
        warnings.warn(f"{mat.name}: replaced node-editor edits the haze parameters cannot "
                      f"represent: {', '.join(replaced)}", UserWarning, stacklevel=3)
    return out


def convert_maps(inputs, out_dir, *, kind="CONDUCTOR", smoothness=None, distribution="GGX",
                 file_format="OPEN_EXR", **options):
    """Batch-convert perceptual maps into physical maps (paper §2.4); docs/textures.md.

    A PBR texture set: ``inputs`` with base_color, metallic, roughness, normal, coat,
    coat_roughness and alpha or opacity (the opacity: the perceptual form's alpha is the core
    roughness α) maps beside the haze maps (haziness, haze_extent[_x/_y],
    coat_haziness, coat_haze_extent) gives a Principled material (``material``: the user's own,
    whose empty inputs take the maps; else a new one, ``name``) with its haze layer baked into
    maps in ``out_dir`` (the raised IOR / base colour, wide roughness and β of each part, the
    coat's), metallic per texel; the result's ``.material`` is the material.

    ``inputs`` maps parameter names (core_reflectivity, edge_tint, roughness or alpha, anisotropy,
    rotation, haziness, haze_extent or haze_extent_x + haze_extent_y) to an image path (``<UDIM>``
    token for tile sets), a ``bpy.types.Image``, or a constant; missing ones take the defaults of
    create_material.  Writes float OpenEXR (or 16-bit PNG) physical maps into ``out_dir``
    atomically and returns ``{map name: path}`` with ``.report`` (texels, clamped texels per
    reason and parameter, seconds, warnings).  Options: resample=False, prefix="",
    exr_codec="ZIP", material=None (wire the maps into that material's lean tree),
    interpolation="Linear", progress=None (callable(done, total, message), or a
    hazy_gloss.conversion.convert.Progress: its cancel() stops the run, undone, at the next strip).
    Files are read and written in strips: memory does not grow with the image
    (docs/textures.md, "Production sizes").

    All or nothing: every target is checked before anything is written, the maps are written
    to temporary names, read back and compared, then renamed into place together; on any
    failure or KeyboardInterrupt the output folder is left as it was (docs/textures.md).
    Every error the caller can cause raises conversion.convert.ConversionError (a ValueError)
    with a one-line message naming the parameter or file (an unknown option:
    ConversionOptionError, also a TypeError)."""
    from .conversion.convert import ConversionOptionError, did_you_mean
    from .blender.actions import convert_pbr as _pbr
    if _pbr.is_pbr(inputs):
        unknown = [k for k in options if k not in _PBR_OPTIONS]
        if unknown or kind != "CONDUCTOR":
            k = unknown[0] if unknown else "kind"
            raise ConversionOptionError(f"convert_maps: {k!r} does not apply to a PBR set (its "
                                        f"Principled BSDF is metal or dielectric per texel); "
                                        f"options: {', '.join(_PBR_OPTIONS)}")
        return _pbr.convert_pbr(inputs, out_dir, smoothness=smoothness, file_format=file_format,
                                distribution=distribution, **options)
    unknown = [k for k in options if k not in _CONVERT_OPTIONS]
    if unknown:
        k = unknown[0]
        raise ConversionOptionError(f"convert_maps: unknown option {k!r}"
                                    f"{did_you_mean(k, _CONVERT_OPTIONS)}; options: "
                                    f"{', '.join(_CONVERT_OPTIONS)}")
    from .blender.actions import convert as _convert
    return _convert.convert_maps(inputs, out_dir, kind=kind, smoothness=smoothness,
                                 distribution=distribution, file_format=file_format, **options)


_PBR_OPTIONS = ("material", "name", "prefix", "exr_codec", "interpolation", "progress",
                "keep_body_colour")
_CONVERT_OPTIONS = ("resample", "prefix", "exr_codec", "material", "interpolation", "progress",
                    "tile_texels")


def last_error(mat):
    """The message of the last change of ``mat`` through ``mat.hazy_gloss_settings`` that was
    refused (None after a change that went through).  Blender prints and swallows exceptions
    raised in property setters, so a script setting ``mat.hazy_gloss_settings.roughness = 2``
    learns of the refusal here, or raises with :func:`strict_settings`."""
    _material_read.check_material(mat, "last_error")
    from .blender.actions import messages as _messages
    return _messages.error_for(mat)


def strict_settings():
    """A context manager: settings changed inside it that are refused raise ValueError (one
    line: the material and the reason) when the block ends::

        with api.strict_settings():
            mat.hazy_gloss_settings.roughness = 2   # ValueError: roughness must be in [0, 1] ...
    """
    from .blender.ui import properties as _props
    return _props.strict_settings()


__all__ = ("create_material", "create_look", "make_hazy", "Notes", "remove_haze", "sync_haze",
           "add_eevee_output", "remove_eevee_output", "update_material", "update_material_links",
           "read_parameters", "is_hazy", "map_parameters", "lobes_for", "normalise_parameters",
           "convert_maps", "last_error", "strict_settings", "PARAMETERS", "DEFAULTS", "KINDS",
           "is_anisotropic")


# --------------------------------------------------------------------------------------------
# Interchange: MaterialX, USD, glTF/USD fallbacks, other engines (docs/interchange.md)
# --------------------------------------------------------------------------------------------


def export_materialx(materials=None, path="", flavour="eq1", *, validate=True):
    """Write hazy materials (a bpy material, a list of materials or names; None: every hazy
    material of the file) to
    one MaterialX 1.39 document at ``path``.  ``flavour`` "eq1" (default): each material an
    exact Eq. 1 graph of the standard pbr library; "openpbr_1.2": open_pbr_surface 1.2 with
    specular_haze (approximate; the error is in the notes).  A material with a haze layer
    (:func:`make_hazy`) is written as its own network whatever the flavour: each BSDF of the
    layer an open_pbr_surface (or pbr BSDF) with its socket values, mixed by β as the tree mixes
    them, its textures and node math included (docs/interchange.md §5).  Needs no extra package; with the
    ``materialx`` package installed the file is validated (``report.validated``).
    Returns a report: ``.path``, ``.materials`` [(name, MaterialX name, notes)], ``.validated``
    (True/False, None without the package), ``.validation``, ``.notes``, ``.skipped``."""
    from .blender.actions import interchange as _ix
    return _ix.export_materialx(materials, path, flavour, validate=validate)


def import_materialx(path, *, progress=None):
    """Materials from a MaterialX document, or a USD file with MaterialX networks (needs
    usd-core): the surfaces material libraries ship (open_pbr_surface 1.1 and 1.2 with
    specular_haze, standard_surface, gltf_pbr, UsdPreviewSurface) as Principled BSDF materials
    with their textures (OpenPBR 1.2's haze as a haze layer, :func:`make_hazy`); the add-on's
    layered exports as the same layered material; Eq. 1 graphs (our own exports come back with
    their perceptual parameters, a foreign mix of two conductor_bsdf / dielectric_bsdf /
    generalized_schlick_bsdf lobes goes through core.inverse_haze_mapping) as hazy materials.
    A damaged input is read the way MaterialX 1.39.5 reads it and reported; a damaged material
    is reported and the rest of the file read.  ``progress``: callable(fraction, message).
    Returns the list of new materials with ``.report`` (one entry per material found:
    ``exact`` — False whenever a note says something was not reproduced, a missing texture
    included —, ``source``, ``notes``, ``parameters`` or ``surface``, ``material``).
    The new materials get a fake user: no object uses them yet, and a material library
    imported from a file must survive the next save (Blender drops datablocks without users);
    clear ``use_fake_user`` for the ones you assign or do not want."""
    from .blender.actions import interchange as _ix
    from .blender.actions import make_hazy as _make
    res = _ix.import_materialx(path, progress=progress, apply_haze=_make.apply_imported_haze)
    for mat in res:
        mat.use_fake_user = True
    return res


def export_usd(materials=None, path="", *, preview=True):
    """Write hazy materials to USD (UsdShade with MaterialX node ids, plus a UsdPreviewSurface
    of the core lobe) with usd-core; RuntimeError when ``pxr`` is missing.
    Returns (path, [(name, prim path, notes)], skipped)."""
    from .blender.actions import interchange as _ix
    return _ix.export_usd(materials, path, preview=preview)


def add_export_fallback(mat):
    """Make Blender's own glTF and USD exporters write this hazy material's core lobe (its
    look at haziness 0) without changing Cycles/EEVEE renders; idempotent.  Returns notes.
    A material with a haze layer gets the user's own BSDF at haziness 0 (its values and links,
    the metallic map included); the notes say when Blender's USD preview takes another node."""
    from .blender.model import fallback as _fallback
    _material_read.check_material(mat, "add_export_fallback")
    return _fallback.add_export_fallback(mat)


def remove_export_fallback(mat):
    """Undo :func:`add_export_fallback`; returns True when something was removed."""
    from .blender.model import fallback as _fallback
    _material_read.check_material(mat, "remove_export_fallback")
    return _fallback.remove_export_fallback(mat)


def engine_parameters(mat, engines=None, *, measure=True):
    """The closest Unity HDRP StackLit, Unreal Substrate, Filament and OpenPBR 1.2 parameters
    of a hazy material (a bpy material or a dict of perceptual parameters), each with its
    BRDF error against Eq. 1 (``fit.error``: max, mean, peak) when ``measure``.
    Returns {engine: EngineFit(parameters, notes, error, alternatives)}."""
    from .interchange import engines as _engines
    from .interchange.materialx import lobes_of
    if isinstance(mat, dict):
        p = normalise_parameters(mat)
    else:
        p = read_parameters(mat)
        if p is None:
            raise ValueError(f"{getattr(mat, 'name', mat)!r} is not a hazy material")
        if p.get("layered"):
            raise ValueError(_material_read.engine_problem(mat))
    return _engines.engine_parameters(lobes_of(p), engines or _engines.ENGINES, measure=measure)


__all__ += ("export_materialx", "import_materialx", "export_usd", "add_export_fallback",
            "remove_export_fallback", "engine_parameters")
