"""Results one click away (bpy): surfmap.show_output switches the 3D views to the distortion
colours of both objects, the transferred texture or the morph, and back; recolour() applies a
legend's range (or a new percentile) to the stored raw values without a solve. The legend itself
is drawn by legend.py."""
import bpy
from bpy.props import EnumProperty, StringProperty
import numpy as np

from . import blender_io, colours, map_job
from .ops_common import object_mode

TEXTURE_MATERIAL = "surfmap texture"
CHECKER_IMAGE = "surfmap checker"
SAVED_KEY = "surfmap_saved_view"


def pair_objects(context):
    """(source, target) of the last coloured run, or the selected pair, as far as they exist."""
    names = context.scene.surfmap.legend_pair.split("\t")
    obs = [bpy.data.objects.get(n) for n in names if n]
    obs = [o for o in obs if o is not None and o.type == 'MESH']
    if len(obs) == 2:
        return obs
    return [o for o in context.selected_objects if o.type == 'MESH'][:2]


def recolour(context, from_percentile=False):
    """Colours of every legend's output written again from the raw values on both objects:
    with from_percentile, the range is first chosen from the data (the percentile field)."""
    settings = context.scene.surfmap
    obs = pair_objects(context)
    q = settings.colour_percentile / 100.0
    for item in settings.legends:
        raws = [(ob, blender_io.read_raw_values(ob.data, item.name)) for ob in obs]
        raws = [(ob, r) for ob, r in raws if r is not None]
        if not raws:
            continue
        if from_percentile:
            allv = np.concatenate([r[0] for _, r in raws])
            if item.scale == "DIVERGING":
                lo, hi = colours.symmetric_range(allv, q)
            else:
                lo, hi = colours.robust_range(allv, hi_q=q, floor=1.0)
            item["lo"], item["hi"] = lo, hi     # (without re-entering this update)
        for ob, (values, domain) in raws:
            loop_total = np.empty(len(ob.data.polygons), dtype=np.int64)
            ob.data.polygons.foreach_get("loop_total", loop_total)
            rgba, cdomain = map_job.colours_of(item.name, values, item.lo, item.hi, loop_total)
            blender_io.write_colour(ob.data, item.name, rgba, cdomain)
            ob.data.update()
    _redraw_views(context)


def _views(context):
    screen = getattr(context, "screen", None)
    for area in (screen.areas if screen is not None else ()):
        if area.type == 'VIEW_3D':
            yield area, area.spaces.active


def _redraw_views(context):
    for area, _ in _views(context):
        area.tag_redraw()


def _save_view(context):
    settings = context.scene.surfmap
    if settings.shown_saved:
        return
    for _, space in _views(context):
        sh = space.shading
        settings.shown_saved = f"{sh.type}\t{sh.color_type}"
        return
    settings.shown_saved = "SOLID\tMATERIAL"


def _set_shading(context, color_type):
    """Solid shading coloured by `color_type`; 'ATTRIBUTE' (Blender 4.x) is 'VERTEX' in 3.x."""
    for _, space in _views(context):
        space.shading.type = 'SOLID'
        items = space.shading.bl_rna.properties["color_type"].enum_items.keys()
        if color_type == 'ATTRIBUTE' and color_type not in items:
            color_type = 'VERTEX'
        space.shading.color_type = color_type


def _texture_material(source):
    """A material showing the source's first image texture (or a checker) through the active
    UV map of whichever object uses it."""
    image = None
    for slot in source.material_slots:
        mat = slot.material
        if mat is not None and mat.use_nodes and mat.name != TEXTURE_MATERIAL:
            for node in mat.node_tree.nodes:
                if node.type == 'TEX_IMAGE' and node.image is not None:
                    image = node.image
                    break
        if image is not None:
            break
    if image is None:
        image = bpy.data.images.get(CHECKER_IMAGE)
        if image is None:
            image = bpy.data.images.new(CHECKER_IMAGE, 1024, 1024)
            image.generated_type = 'COLOR_GRID'
    mat = bpy.data.materials.get(TEXTURE_MATERIAL)
    if mat is None:
        mat = bpy.data.materials.new(TEXTURE_MATERIAL)
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    tex = nodes.get("surfmap image") or nodes.new('ShaderNodeTexImage')
    tex.name = "surfmap image"
    tex.image = image
    nodes.active = tex
    bsdf = nodes.get("Principled BSDF")
    if bsdf is not None and not bsdf.inputs["Base Color"].is_linked:
        mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def _use_material(ob, mat):
    """Shows `mat` on every slot of the object through object-level links (the mesh's own
    materials are kept; Back returns the slots to them)."""
    if not ob.material_slots:
        ob.data.materials.append(None)
        ob[SAVED_KEY + "_added_slot"] = 1
    for slot in ob.material_slots:
        slot.link = 'OBJECT'
        slot.material = mat


def _restore_materials(ob):
    for slot in ob.material_slots:
        if slot.link == 'OBJECT' and slot.material is not None and \
                slot.material.name == TEXTURE_MATERIAL:
            slot.material = None
            slot.link = 'DATA'
    if ob.get(SAVED_KEY + "_added_slot"):
        if len(ob.data.materials) and ob.data.materials[-1] is None:
            ob.data.materials.pop()
        del ob[SAVED_KEY + "_added_slot"]


def morph_keys(source, target):
    """The morph's shape keys: (source key, target key), each None when missing."""
    def key(ob, other):
        sk = ob.data.shape_keys
        return None if sk is None else sk.key_blocks.get(f"surfmap to {other.name}")
    return key(source, target), key(target, source)


class SURFMAP_OT_show_output(bpy.types.Operator):
    """Show one result of the map on both objects in the 3D views (or go back)"""
    bl_idname = "surfmap.show_output"
    bl_label = "Show"
    bl_options = {'REGISTER', 'UNDO'}

    what: EnumProperty(
        name="Show", default='COLOURS',
        items=(('COLOURS', "Colours", "The distortion colours on both objects, with a legend"),
               ('TEXTURE', "Texture", "The source's texture on the target through the map"),
               ('MORPH', "Morph", "The morph: slide the shape keys in the panel"),
               ('BACK', "Back", "The view as it was before")))
    attribute: StringProperty(name="Colours", default=map_job.DILATATION_COLOURS,
                              description="The colour attribute to show")

    @classmethod
    def description(cls, context, props):
        return {'COLOURS': "Colour both objects by this distortion measure, with a legend",
                'TEXTURE': "Show the source's texture on the target through the map",
                'MORPH': "Show the morph sliders (each object into the other)",
                'BACK': "Put the view back as it was"}.get(props.what, cls.__doc__)

    @classmethod
    def poll(cls, context):
        return object_mode(cls, context)

    def execute(self, context):
        settings = context.scene.surfmap
        obs = pair_objects(context)
        if self.what != 'BACK' and len(obs) != 2:
            self.report({'ERROR'}, "no mapped pair: run Compute Map first (or select the pair)")
            return {'CANCELLED'}
        if self.what == 'BACK':
            return self._back(context, obs)
        source, target = obs
        if self.what == 'COLOURS':
            missing = [o.name for o in obs if o.data.color_attributes.get(self.attribute) is None]
            if missing:
                self.report({'ERROR'}, f"no colours '{self.attribute}' on {', '.join(missing)}: "
                                       f"run Compute Map with Colours ticked")
                return {'CANCELLED'}
            _save_view(context)
            for ob in obs:
                _restore_materials(ob)
                ca = ob.data.color_attributes
                ca.active_color = ca[self.attribute]
                if hasattr(ca, "render_color_index"):
                    ca.render_color_index = ca.active_color_index
            _set_shading(context, 'ATTRIBUTE')
            settings.shown = self.attribute
        elif self.what == 'TEXTURE':
            uv = next((u for u in target.data.uv_layers if u.name.startswith("surfmap ")
                       and not u.name.startswith("surfmap before ")), None)
            if uv is None:
                self.report({'ERROR'}, f"'{target.name}' has no transferred UV map: run Compute "
                                       f"Map with UVs ticked")
                return {'CANCELLED'}
            _save_view(context)
            mat = _texture_material(source)
            target.data.uv_layers.active = uv
            uv.active_render = True
            for ob in obs:
                _use_material(ob, mat)
            _set_shading(context, 'TEXTURE')
            settings.shown = 'TEXTURE'
        else:
            ks, kt = morph_keys(source, target)
            if ks is None and kt is None:
                self.report({'ERROR'}, "no morph shape keys: run Compute Map with Morph ticked")
                return {'CANCELLED'}
            for ob in obs:
                _restore_materials(ob)
            if ks is not None and ks.value == 0.0:
                ks.value = 0.5
            settings.shown = 'MORPH'
        _redraw_views(context)
        return {'FINISHED'}

    def _back(self, context, obs):
        settings = context.scene.surfmap
        for ob in obs:
            _restore_materials(ob)
        if len(obs) == 2:
            for k in morph_keys(*obs):
                if k is not None:
                    k.value = 0.0
        saved = settings.shown_saved.split("\t")
        if len(saved) == 2:
            for _, space in _views(context):
                space.shading.type, space.shading.color_type = saved
        settings.shown, settings.shown_saved = "", ""
        _redraw_views(context)
        return {'FINISHED'}


class SURFMAP_OT_colours_from_data(bpy.types.Operator):
    """Choose the colours' range from the values again (the percentile)"""
    bl_idname = "surfmap.colours_from_data"
    bl_label = "Range From Data"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        if not len(context.scene.surfmap.legends):
            self.report({'ERROR'}, "no colours yet: run Compute Map with Colours ticked")
            return {'CANCELLED'}
        recolour(context, from_percentile=True)
        return {'FINISHED'}


classes = (SURFMAP_OT_show_output, SURFMAP_OT_colours_from_data)

register, unregister = bpy.utils.register_classes_factory(classes)
