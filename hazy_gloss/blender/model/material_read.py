# SPDX-License-Identifier: GPL-3.0-or-later
"""Reading and checking a hazy material: whether it is one (:func:`is_hazy`), the perceptual
parameters stamped on it (:func:`read_parameters`; :func:`read_parameters_lenient` for the
panel), and why it cannot be edited (:func:`edit_problem`, :func:`maps_problem`,
:func:`baked_problem`).  Building and
updating its tree is blender.model.material."""
import bpy

from ... import constants as K
from ...core.parameters import DEFAULTS, normalise
from . import layer, stamp
from .material import GROUP_ROLE
from ..nodes.ownership import ours


def check_material(mat, caller):
    """TypeError (one line) unless ``mat`` is a bpy.types.Material."""
    if isinstance(mat, bpy.types.Material):
        return
    hint = ""
    if isinstance(mat, str):
        hint = f" (look it up first: {caller}(bpy.data.materials[{mat!r}], ...))"
    elif isinstance(mat, bpy.types.Object):
        hint = " (an object: pass obj.active_material)"
    raise TypeError(f"{caller} expects a bpy.types.Material, got {type(mat).__name__}{hint}")


def read_parameters(mat):
    """The perceptual parameters stamped on a hazy material, or None.  Raises ValueError (one
    line naming the material, the parameter and what is valid; blender.model.stamp.StampError) when
    the stored values do not read.  A layered material (Make Hazy on the user's BSDF) gives its
    haze parameters and the core's own (blender.model.layer.read), with ``layered`` True."""
    check_material(mat, "read_parameters")
    if K.STAMP not in mat:
        return None
    if layer.is_layered(mat):
        return layer.read(mat)
    values, problems = stamp.read_material(mat)
    if problems:
        raise stamp.StampError(stamp.material_problem(mat, problems))
    return normalise(values, explicit=())


def read_parameters_lenient(mat):
    """(parameters, problem): what the panel shows — the stamped parameters, the defaults for
    whatever does not read — and the one-line reason why not, or None.  Never raises."""
    try:
        return read_parameters(mat), None
    except (ValueError, TypeError) as exc:
        problem = str(exc)
    p = tree_defaults(mat)
    try:
        if layer.is_layered(mat):
            p.update(layer.haze_of(mat))
        else:
            values, _ = stamp.read_material(mat)
            p.update(values or {})
        return normalise(p, explicit=()), problem
    except (ValueError, TypeError):
        return normalise({}), problem


def tree_defaults(mat):
    """DEFAULTS, with what the tree tells for values a damaged stamp lost: in-shader mapping
    when the add-on's group node is there."""
    d = dict(DEFAULTS)
    tree = getattr(mat, "node_tree", None)
    if tree is not None:
        d["shader_mapping"] = GROUP_ROLE in ours(tree)
    return d


def is_hazy(mat):
    return mat is not None and K.STAMP in mat


def edit_problem(mat):
    """Why ``mat`` cannot be edited, in plain words, or None."""
    if mat is None:
        return "No material"
    lib = mat.library
    if lib is not None:
        return (f"“{mat.name}” is linked from the library file “{bpy.path.basename(lib.filepath)}” "
                f"and is read-only here. Edit it in that file, or make it local "
                f"(Object > Relations > Make Local) to change it in this one")
    if getattr(mat, "override_library", None) is not None:
        return (f"“{mat.name}” is a library override; its node tree cannot be rebuilt. "
                f"Make it local to edit it")
    if not is_hazy(mat):
        return f"“{mat.name}” is not a hazy material: use Make Hazy first"
    return None


def maps_problem(mat):
    """Why a material driven by converted maps cannot be edited from the panel, or None."""
    if mat is not None and K.MAPS_STAMP in mat:
        return (f"“{mat.name}” is driven by converted texture maps: convert the maps again "
                f"(Convert Maps) to change it")
    return None


def shown(value):
    """A haze value in a message: a number, or "a map" where a texture gives it."""
    return "a map" if value == K.TEXTURED else f"{value:g}"


def engine_problem(mat):
    """Why engine parameters (api.engine_parameters, the CLI's engines) skip a haze layer: its
    lobes are the artist's BSDF's, the fits are for the mapping's own lobes."""
    return (f"“{mat.name}” is a haze layer on its own BSDF: engine parameters are for materials "
            f"made with New Hazy Material (api.create_material)")


def baked_problem(mat):
    """Why a haze edit cannot change a layer whose haze was converted into maps (the layer's
    twin of :func:`maps_problem`)."""
    h = layer.haze_of(mat)
    at = ", ".join(f"{k} {shown(v)}" for k, v in h.items()
                   if k in ("haziness", "coat_haziness") and v)
    return (f"the haze of “{mat.name}” was converted into its maps{f' ({at})' if at else ''}: "
            f"convert the maps again to change it (or Remove Haze, then Make Hazy for haze set "
            f"here)")


__all__ = ("read_parameters", "read_parameters_lenient", "check_material", "is_hazy",
           "edit_problem", "maps_problem", "baked_problem", "shown")
