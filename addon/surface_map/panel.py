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
        draw_map(layout, settings)


def draw_map(layout, settings):
    """The map's options, its button, the candidates of the last run and the re-runs."""
    box = layout.box()
    box.label(text="Optimal Map", icon='MOD_UVPROJECT')
    col = box.column(align=True)
    col.prop(settings, "homotopy")
    for c in settings.candidates:
        mark = "* " if c.index == settings.chosen_candidate else "  "
        energy = f"E = {c.energy:.6g}" if c.solved else "not solved"
        if c.landmark_energy == c.landmark_energy:  # not nan: ranked with the landmarks held
            energy += f" (landmarks: {c.landmark_energy:.6g})"
        col.label(text=f"{mark}{c.index}: {energy}  {c.description}"[:90])
    col = box.column(align=True)
    col.prop(settings, "landmark_mode")
    if settings.landmark_status:
        for i, line in enumerate(_wrap(settings.landmark_status, 40)[:4]):
            col.label(text=line, icon='PINNED' if i == 0 else 'BLANK1')
    col.prop(settings, "method")
    col.prop(settings, "source_weights")
    col.prop(settings, "tolerance")
    col = box.column(align=True)
    col.label(text="Outputs:")
    row = col.row(align=True)
    row.prop(settings, "write_uvs")
    row.prop(settings, "write_morph")
    row.prop(settings, "write_distortion")
    col.prop(settings, "write_uvs_before")
    col.prop(settings, "write_refined")
    col.prop(settings, "morph_space")
    box.operator("surfmap.compute_map", icon='PLAY')
    col = box.column(align=True)
    col.label(text="From the stored map:")
    col.operator("surfmap.transfer_uvs", icon='UV')
    col.operator("surfmap.create_morph", icon='SHAPEKEY_DATA')
    col.operator("surfmap.paint_distortion", icon='COLOR')
    col.operator("surfmap.bake_textures", icon='TEXTURE')
    if settings.map_status:
        for line in _wrap(settings.map_status, 40)[:8]:
            box.label(text=line)


classes = (SURFMAP_PT_main,)

register, unregister = bpy.utils.register_classes_factory(classes)
