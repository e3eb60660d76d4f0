"""SURFMAP_OT_bake_textures: the source's textures baked into the target's own UV layout through
the stored correspondence (texture_bake.py; docs/baking.md)."""
import time

import bpy
import numpy as np

from . import texture_bake
from .ops_common import object_mode
from .ops_stored_map import stored_pair
from .side import ObjectProblem

BAKE_UV = "surfmap bake UV"          # the target's UV map when it has none of its own
OUR_PREFIX = "surfmap "              # layers the add-on wrote (e.g. transferred UVs): not "own"


def bake_image_name(target_name, what="texture"):
    return f"surfmap bake {target_name} {what}"


def bake_material_name(target_name):
    return f"surfmap bake {target_name}"


# --- reading the source's colours --------------------------------------------------------------

def _upstream_image_node(node, depth=0):
    """The Image Texture node feeding `node` (through at most a few nodes), or None."""
    if node is None or depth > 6:
        return None
    if node.type == 'TEX_IMAGE' and node.image is not None:
        return node
    for inp in node.inputs:
        for link in inp.links:
            got = _upstream_image_node(link.from_node, depth + 1)
            if got is not None:
                return got
    return None


def material_colour_source(mat):
    """(image node or None, constant RGBA) of a material: the Image Texture feeding the
    Principled BSDF's Base Color (else the first Image Texture node), else its base colour."""
    if mat is None:
        return None, (0.8, 0.8, 0.8, 1.0)
    if mat.use_nodes and mat.node_tree is not None:
        nodes = mat.node_tree.nodes
        for n in nodes:
            if n.type == 'BSDF_PRINCIPLED':
                base = n.inputs.get("Base Color")
                if base is not None and base.links:
                    img = _upstream_image_node(base.links[0].from_node)
                    if img is not None:
                        return img, tuple(base.default_value)
                if base is not None:
                    fallback = tuple(base.default_value)
                    break
        else:
            fallback = tuple(mat.diffuse_color)
        for n in nodes:
            if n.type == 'TEX_IMAGE' and n.image is not None:
                return n, fallback
        return None, fallback
    return None, tuple(mat.diffuse_color)


def image_pixels(image):
    """(h, w, 4) float32 pixels of a Blender image (row 0 at the bottom, like Image.pixels)."""
    w, h = image.size
    if w == 0 or h == 0:
        raise ObjectProblem(f"image '{image.name}' has no pixels (missing file?)")
    buf = np.empty(w * h * image.channels, dtype=np.float32)
    image.pixels.foreach_get(buf)
    px = buf.reshape(h, w, image.channels)
    if image.channels == 4:
        return px
    out = np.ones((h, w, 4), dtype=np.float32)
    out[..., :min(3, image.channels)] = px[..., :3]
    if image.channels == 1:
        out[..., 1] = out[..., 2] = px[..., 0]
    return out


def _image_uv_name(node, mesh):
    """The UV map an Image Texture node reads: a UV Map node on its Vector input, else the
    mesh's active render UV map."""
    vec = node.inputs.get("Vector")
    if vec is not None and vec.links:
        src = vec.links[0].from_node
        if src.type == 'UVMAP' and src.uv_map:
            return src.uv_map
    for layer in mesh.uv_layers:
        if layer.active_render:
            return layer.name
    return mesh.uv_layers[0].name if len(mesh.uv_layers) else None


def source_colour(source, src, use_colour_attribute=False):
    """texture_bake.SourceColour of the source object and a description of what it samples."""
    mesh = source.data
    if use_colour_attribute:
        attr = mesh.color_attributes.active_color if hasattr(mesh, "color_attributes") else None
        if attr is None:
            raise ObjectProblem(f"the source '{source.name}' has no colour attribute")
        n = len(attr.data)
        buf = np.empty(n * 4, dtype=np.float32)
        attr.data.foreach_get("color", buf)
        col = buf.reshape(n, 4).astype(np.float64)
        corner = col[src["tri_loops"]] if attr.domain == 'CORNER' else col[
            np.asarray(src["F"], dtype=np.int64)]
        return texture_bake.SourceColour(corner_colour=corner), f"colour attribute '{attr.name}'"
    tri_poly = np.asarray(src["tri_polygon"], dtype=np.int64)
    poly_mat = np.zeros(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("material_index", poly_mat)
    face_material = poly_mat[tri_poly] if len(poly_mat) else np.zeros(len(tri_poly), np.int64)
    specs, names = [], []
    slots = [s.material for s in source.material_slots] or [None]
    for mat in slots:
        node, constant = material_colour_source(mat)
        if node is None:
            specs.append({"colour": constant})
            names.append(f"{mat.name if mat else 'no material'}: constant colour")
            continue
        uv_name = _image_uv_name(node, mesh)
        if uv_name is None or uv_name not in src["uv_layers"]:
            raise ObjectProblem(f"the source '{source.name}' has no UV map for the image "
                                     f"'{node.image.name}'")
        specs.append({"image": image_pixels(node.image),
                      "corner_uv": np.asarray(src["uv_layers"][uv_name])[src["tri_loops"]],
                      "float": bool(node.image.is_float), "image_name": node.image.name})
        names.append(f"image '{node.image.name}' on UV map '{uv_name}'")
    face_material = np.clip(face_material, 0, len(specs) - 1)
    return (texture_bake.SourceColour(face_material=face_material, materials=specs),
            "; ".join(names))


# --- the target's own UV map ------------------------------------------------------------------

def own_uv_name(mesh):
    """The target's own UV map (not one the add-on transferred): the active render one if it
    is its own, else the first own one; None when it has none."""
    def usable(layer):   # (Blender 3.4 may list other attributes among the UV maps)
        return mesh.uv_layers.get(layer.name) is not None and len(layer.data) == len(mesh.loops)
    own = [l for l in mesh.uv_layers if usable(l) and (l.name == BAKE_UV or not
                                                        l.name.startswith(("surfmap ", "surfmap_")))]
    for layer in own:
        if layer.active_render:
            return layer.name
    return own[0].name if own else None


def smart_uv_project(context, obj, name=BAKE_UV):
    """Adds a UV map `name` to obj made by Smart UV Project (in Edit Mode, then back)."""
    layer = obj.data.uv_layers.new(name=name)
    if layer is None:
        raise ObjectProblem(f"'{obj.name}' cannot take another UV map (8 at most)")
    obj.data.uv_layers.active = layer
    made = layer.name    # (Edit Mode reallocates the layers: `layer` is stale after it)
    view_layer = context.view_layer
    was_active, was_selected = view_layer.objects.active, list(context.selected_objects)
    for o in was_selected:
        o.select_set(False)
    obj.select_set(True)
    view_layer.objects.active = obj
    try:
        bpy.ops.object.mode_set(mode='EDIT')
        bpy.ops.mesh.select_all(action='SELECT')
        bpy.ops.uv.smart_project(angle_limit=1.15192, island_margin=0.01)
    finally:
        bpy.ops.object.mode_set(mode='OBJECT')
        obj.select_set(False)
        for o in was_selected:
            o.select_set(True)
        view_layer.objects.active = was_active
    return made


# --- writing ------------------------------------------------------------------------------------

def write_image(name, pixels, is_float):
    """A new (or replaced) packed image holding pixels (h,w,4)."""
    h, w = pixels.shape[:2]
    old = bpy.data.images.get(name)
    if old is not None:
        bpy.data.images.remove(old)
    img = bpy.data.images.new(name, width=w, height=h, alpha=True, float_buffer=is_float)
    img.pixels.foreach_set(np.ascontiguousarray(pixels, dtype=np.float32).ravel())
    img.pack()
    return img


def bake_material(name, image, uv_name):
    """A material: Image Texture (image, on UV map uv_name) -> Principled Base Color."""
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    tex = nt.nodes.new("ShaderNodeTexImage")
    uvn = nt.nodes.new("ShaderNodeUVMap")
    tex.image = image
    uvn.uv_map = uv_name
    nt.links.new(uvn.outputs["UV"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    out.location, bsdf.location, tex.location, uvn.location = (300, 0), (0, 0), (-350, 0), (-600, 0)
    return mat


def assign_material(obj, mat):
    """mat on every polygon of obj (a slot is added unless it already has one with mat)."""
    mats = obj.data.materials
    idx = next((i for i, m in enumerate(mats) if m == mat), None)
    if idx is None:
        mats.append(mat)
        idx = len(mats) - 1
    obj.data.polygons.foreach_set("material_index", np.full(len(obj.data.polygons), idx,
                                                            dtype=np.int32))
    obj.data.update()


class SURFMAP_OT_bake_textures(bpy.types.Operator):
    """Bake the source's image textures (or its colour attribute) into new images in the
    target's own UV layout through the stored map, and give the target a material using them
    (Smart UV Project first when the target has no UV map of its own)"""
    bl_idname = "surfmap.bake_textures"
    bl_label = "Bake Textures"
    bl_options = {'REGISTER', 'UNDO'}

    resolution: bpy.props.IntProperty(name="Resolution", default=1024, min=16, max=8192,
                                      description="Width and height of the baked image")
    supersample: bpy.props.IntProperty(name="Supersample", default=2, min=1, max=8,
                                       description="S x S samples per texel, averaged")
    margin: bpy.props.IntProperty(name="Margin", default=8, min=0, max=64,
                                  description="Texels of bleed around the UV islands")
    colour_attribute: bpy.props.BoolProperty(
        name="Colour Attribute", default=False,
        description="Bake the source's active colour attribute instead of its textures")

    @classmethod
    def poll(cls, context):
        return object_mode(cls, context)

    def execute(self, context):
        t0 = time.time()
        try:
            source, target, src, tgt, res = stored_pair(context)
            if tgt.get("evaluated") and not tgt.get("same_topology", True):
                raise ObjectProblem(f"the map of '{target.name}' was computed on its mesh "
                                         f"with modifiers, which change its faces: apply them "
                                         f"and compute the map again to bake")
            colour, what = source_colour(source, src, self.colour_attribute)
            uv_name = own_uv_name(target.data)
            made_uv = uv_name is None
            if made_uv:
                uv_name = smart_uv_project(context, target)
            L = len(target.data.loops)
            loop_uv = np.empty(L * 2, dtype=np.float64)
            target.data.uv_layers[uv_name].data.foreach_get("uv", loop_uv)
            corner_uv = loop_uv.reshape(L, 2)[tgt["tri_loops"]]
            out = texture_bake.bake(
                src["V"], src["F"], tgt["F"], corner_uv,
                (res["forward"]["face"], res["forward"]["barycentric"]),
                (res["inverse"]["face"], res["inverse"]["barycentric"]),
                colour, self.resolution, self.resolution, self.supersample, self.margin,
                V_tgt=tgt["V"])
        except ObjectProblem as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        is_float = any(s.get("float") for s in getattr(colour, "materials", []))
        kind = "colour attribute" if self.colour_attribute else "texture"
        image = write_image(bake_image_name(target.name, kind), out["image"], is_float)
        mat = bake_material(bake_material_name(target.name), image, uv_name)
        assign_material(target, mat)
        msg = (f"baked {what} of '{source.name}' into '{image.name}' ({self.resolution}^2, "
               f"{self.supersample}x{self.supersample} samples per texel) on '{target.name}''s "
               f"UV map '{uv_name}'{' (made by Smart UV Project)' if made_uv else ''}: "
               f"{100 * out['fill_fraction']:.2f}% of the island texels filled, "
               f"{out['inserted']} source vertices as nodes, {out['unlocated']} sub-triangles "
               f"and {out['clamped']} samples located approximately, {time.time() - t0:.1f}s")
        context.scene.surfmap.map_status = msg
        self.report({'INFO'}, msg)
        return {'FINISHED'}


classes = (SURFMAP_OT_bake_textures,)

register, unregister = bpy.utils.register_classes_factory(classes)
