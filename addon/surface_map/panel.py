"""The 'Surface Map' sidebar panel of the 3D view (N-panel, category 'Surface Map')."""
import bpy

from . import native
from .properties import _wrap, extra_module_dirs


class SURFMAP_PT_main(bpy.types.Panel):
    bl_idname = "SURFMAP_PT_main"
    bl_label = "Surface Map"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Surface Map"

    def draw(self, context):
        layout = self.layout
        mod = native.load(extra_dirs=extra_module_dirs(context))
        box = layout.box()
        if mod is not None:
            box.label(text="Native module: loaded", icon='CHECKMARK')
        else:
            box.label(text="Native module: missing", icon='ERROR')
            for line in _wrap(native.error(), 40)[:8]:
                box.label(text=line)
        settings = context.scene.surfmap
        sel = [o for o in context.selected_objects if o.type == 'MESH']
        act = context.active_object
        col = layout.column(align=True)
        if len(sel) == 2 and act in sel:
            src = sel[0] if sel[1] == act else sel[1]
            col.label(text=f"Source: {src.name}", icon='MESH_DATA')
            col.label(text=f"Target: {act.name}", icon='MESH_DATA')
        elif len(sel) == 1:
            col.label(text=f"Object: {sel[0].name}", icon='MESH_DATA')
        else:
            col.label(text="Select 1 or 2 meshes (active = target)", icon='INFO')
        col = layout.column(align=True)
        col.prop(settings, "source_base_vertex")
        col.prop(settings, "target_base_vertex")
        col.prop(settings, "loop_bevel")
        col.prop(settings, "mark_seams")
        layout.operator("surfmap.show_cut_loops", icon='MOD_CURVE')
        if settings.status:
            for line in _wrap(settings.status, 40)[:6]:
                layout.label(text=line)


classes = (SURFMAP_PT_main,)


def register():
    for c in classes:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
