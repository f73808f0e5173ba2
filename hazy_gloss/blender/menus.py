# SPDX-License-Identifier: GPL-3.0-or-later
import bpy

classes = ()

register, unregister = bpy.utils.register_classes_factory(classes)
