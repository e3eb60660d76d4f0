"""Surface Map: globally optimal maps between closed surfaces of equal genus
(Li et al., TVCG 2008). Blender side of the surfmap project.

Module layout (like the glTF add-on): core.py, mapping.py, mapjob.py and native.py never import
bpy; blender_io.py, operators.py, map_ops.py, panel.py and properties.py are the Blender side.
"""
bl_info = {
    "name": "Surface Map",
    "author": "surfmap project",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D Viewport > Sidebar (N) > Surface Map",
    "description": "Cut loops and globally optimal maps between closed surfaces of equal genus",
    "category": "Mesh",
}

if "bpy" in locals():
    import importlib
    for _m in ("native", "core", "mapping", "mapjob", "blender_io", "properties", "operators",
               "map_ops", "panel", "texture_bake", "bake_operator"):
        if _m in locals():
            importlib.reload(locals()[_m])

import bpy  # noqa: E402

from . import (native, core, mapping, mapjob, blender_io, properties, operators,  # noqa: E402,F401
               map_ops, panel)
from . import texture_bake, bake_operator  # noqa: E402,F401

_modules = (properties, operators, map_ops, panel, bake_operator)


def register():
    for m in _modules:
        m.register()


def unregister():
    for m in reversed(_modules):
        m.unregister()
