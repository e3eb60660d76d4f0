"""Surface Map: globally optimal maps between surfaces of equal topology, closed or open
(the method: docs/method.md). Blender side of the surfmap project.

Module layout (like the glTF add-on; the data flow file by file is in docs/addon.md):
  no bpy (plain pytest can import them):
    native.py       finds and loads the native surfmap module
    side.py         MeshSide: one object of a map as plain data; ObjectProblem
    cut_loops.py    the system of loops of one object
    map_job.py      MapOptions (the panel's choices in the core's spelling), MapJob (the solve
                    on a worker thread, the outputs in slices)
    geometry.py, distortion.py, colours.py, uv_transfer.py, texture_bake.py, landmarks.py,
    morph.py        the maths of the outputs
  bpy:
    properties.py   the scene's PropertyGroup (scene.surfmap) and the add-on preferences
    blender_io.py   reading meshes, writing attributes, UVs, shape keys, curves
    ops_common.py   what every operator shares (selection, poll)
    ops_cut_loops.py, ops_map.py, ops_stored_map.py, ops_view.py   the SURFMAP_OT_* operators
    panel.py        the sidebar panels and the pairings' UIList
    legend.py       the colour legend drawn in the 3D views (gpu/blf)
"""
bl_info = {
    "name": "Surface Map",
    "author": "surfmap project",
    "version": (0, 2, 0),
    "blender": (3, 4, 0),
    "location": "3D Viewport > Sidebar (N) > Surface Map",
    "description": "Optimal maps between closed or open meshes of equal topology",
    "category": "Mesh",
}

try:
    import bpy  # noqa: F401
except ImportError:   # imported outside Blender (pytest of the bpy-free modules)
    bpy = None

_BPY_MODULES = ("properties", "blender_io", "ops_common", "ops_cut_loops", "ops_map",
                "ops_stored_map", "ops_view", "verify_operator", "batch_operators", "bake_operator", "panel",
                "legend")
_PLAIN_MODULES = ("native", "side", "geometry", "distortion", "colours", "uv_transfer",
                  "texture_bake", "landmarks", "morph", "cut_loops", "map_job")

if bpy is not None:
    import importlib
    import sys
    if "properties" in locals():   # "Reload Scripts": reload in dependency order
        for _m in _PLAIN_MODULES + _BPY_MODULES:
            _full = f"{__name__}.{_m}"
            if _full in sys.modules:
                importlib.reload(sys.modules[_full])
    from . import (properties, ops_cut_loops, ops_map, ops_stored_map, ops_view,  # noqa: E402
                   verify_operator, batch_operators, bake_operator, panel, legend)

    _modules = (properties, ops_cut_loops, ops_map, ops_stored_map, ops_view, verify_operator,
                batch_operators, bake_operator, panel, legend)

    def register():
        for m in _modules:
            m.register()

    def unregister():
        for m in reversed(_modules):
            m.unregister()
