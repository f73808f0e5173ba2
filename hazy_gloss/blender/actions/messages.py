# SPDX-License-Identifier: GPL-3.0-or-later
"""What the add-on tells the user about a material: exceptions in plain words
(:func:`plain_message`) and the last refused change per material (:data:`last_error`, shown by
the panel and api.last_error).  Written by the property setters (blender/actions/edit.py) and the
depsgraph handler (blender/actions/sync.py); imports no other module of blender/, so anything may write
here."""
from ...core.parameters import HAZE_PARAMETERS, PARAMETERS

__all__ = ("last_error", "error_for", "set_error", "clear_error", "plain_message")

#: material session_uid -> plain-language message of the last refused change (the panel shows
#: it).  session_uid, not the name: a file loaded later may reuse the name.
last_error = {}


def error_for(mat):
    """The message of the last refused change of ``mat`` (or None)."""
    return last_error.get(mat.session_uid) if mat is not None else None


def set_error(mat, message):
    last_error[mat.session_uid] = message


def clear_error(mat):
    last_error.pop(mat.session_uid, None)


_PLAIN = (
    ("haziness >= 1", "Haziness must stay below 1 (1 would break energy conservation)"),
    ("offer", None),  # distribution / kind mismatch: the core's message is already plain
)


#: Parameter names a message may start with: kept as the user typed them (not capitalised).
_KEYWORDS = frozenset(HAZE_PARAMETERS) | frozenset(PARAMETERS)


def plain_message(exc):
    text = str(exc)
    for key, plain in _PLAIN:
        if key in text and plain:
            return plain
    first = text.split(" ", 1)[0].rstrip(":,")
    if first in _KEYWORDS:
        return text  # it starts with a keyword (haze_extent, smoothness): as the user typed it
    return text[:1].upper() + text[1:]
