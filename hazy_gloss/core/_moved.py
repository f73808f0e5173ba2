# SPDX-License-Identifier: GPL-3.0-or-later
"""Old import paths of modules that moved (issue 23: a moved public module warns once with its
new path, for one release): ``__getattr__ = moved(__name__, new)`` in the old module."""
from __future__ import annotations

import importlib
import warnings


def moved(old, new):
    """Warn (DeprecationWarning, at the import of ``old``) and return a module ``__getattr__``
    that reads every name from the module ``new``."""
    warnings.warn(f"{old} moved to {new}; the old path goes in the next release",
                  DeprecationWarning, stacklevel=3)
    target = importlib.import_module(new)
    return lambda name: getattr(target, name)
