"""Scene settings (one PropertyGroup: scene.surfmap) and the add-on preferences."""
import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from . import native


class SURFMAP_PG_settings(bpy.types.PropertyGroup):
    source_base_vertex: IntProperty(
        name="Source Base Vertex", default=-1, min=-1,
        description="Vertex where the source's loops meet (-1: chosen automatically)")
    target_base_vertex: IntProperty(
        name="Target Base Vertex", default=-1, min=-1,
        description="Vertex where the target's (active object's) loops meet "
                    "(-1: chosen automatically)")
    loop_bevel: FloatProperty(
        name="Loop Bevel", default=0.005, min=0.0, soft_max=0.05, precision=4,
        description="Thickness of the loop curves, as a fraction of the object's size "
                    "(bounding-box diagonal)")
    mark_seams: BoolProperty(
        name="Mark Seams", default=True,
        description="Mark the mesh edges along the loops as UV seams (the cut graph: "
                    "unwrapping then gives one island)")
    status: StringProperty(
        name="Status", default="",
        description="Result of the last run")


class SURFMAP_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    module_path: StringProperty(
        name="Module Folder", subtype='DIR_PATH', default="",
        description="Folder that contains the surfmap package (e.g. <repo>/build/python); "
                    "only needed when the add-on does not ship it")

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "module_path")
        mod = native.load(extra_dirs=(bpy.path.abspath(self.module_path),) if self.module_path else ())
        if mod is not None:
            layout.label(text=f"surfmap loaded from {native.origin()}", icon='CHECKMARK')
        else:
            layout.label(text="surfmap native module missing", icon='ERROR')
            for line in _wrap(native.error(), 90):
                layout.label(text=line)


def _wrap(text, width):
    words, lines, cur = text.split(), [], ""
    for w in words:
        if cur and len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = w
        else:
            cur = (cur + " " + w).strip()
    if cur:
        lines.append(cur)
    return lines


def extra_module_dirs(context):
    """The folder from the add-on preferences, if any."""
    addon = context.preferences.addons.get(__package__) if context else None
    if addon is not None and addon.preferences is not None and addon.preferences.module_path:
        return (bpy.path.abspath(addon.preferences.module_path),)
    return ()


classes = (SURFMAP_PG_settings, SURFMAP_AP_preferences)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.surfmap = PointerProperty(type=SURFMAP_PG_settings)


def unregister():
    del bpy.types.Scene.surfmap
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
