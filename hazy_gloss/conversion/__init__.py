# SPDX-License-Identifier: GPL-3.0-or-later
"""Texture conversion, bpy-free: from image files to the haze mapping's maps.

In the order the data flows:

- :mod:`.pbr_sets` finds a PBR texture set (and its UDIM tiles) in a folder;
- :mod:`.imagecheck` checks a file before anything loads it (format, size, damage), through
  :mod:`.oiio`, Blender's OpenImageIO (or the PyPI wheel);
- :mod:`.imagestream` reads the maps in strips, writes each output strip by strip and
  proves it by one decode;
- :mod:`.pixels` converts colour spaces and resamples;
- :mod:`.convert` validates the options and runs the mapping (core.lobes.describe) on each
  strip; its errors and progress are :mod:`.status`.

The Blender half, in its layers: ``blender/ui/convert_ops.py`` (the operators),
``blender/actions/convert.py`` and ``convert_pbr.py`` (the work),
``blender/model/convert_inputs.py``, ``convert_outputs.py`` and ``convert_wiring.py`` (reading a
material's maps; committing the outputs all or nothing; wiring them into the material).
"""
__all__ = ()
