"""The re-runs from the stored correspondence (bpy): surfmap.transfer_uvs, surfmap.create_morph
and surfmap.paint_distortion write one output again without a solve, from the map stored on
both objects by compute_map (checked against the meshes' fingerprints);
surfmap.cut_along_seams makes a copy of the target cut along the images of the source's UV
seams (uv_transfer.SeamCut) carrying the source's UV map without any face across a seam."""
import bpy
import numpy as np

from . import blender_io, map_job, uv_transfer
from .ops_common import object_mode, pick_objects
from .ops_map import read_side, write_outputs
from .side import ObjectProblem


def stored_pair(context):
    """(source, target, src side, tgt side, forward, inverse) from the stored correspondence
    of the selected pair (or of the one selected object and its stored partner). Raises
    ObjectProblem when it is missing or stale."""
    source, target = pick_objects(context)
    if source is None:
        meta = target.data.get(blender_io.CORR_KEY)
        if meta is None:
            raise ObjectProblem(f"'{target.name}' has no stored map: run Compute Map on a "
                                f"pair first")
        partner = bpy.data.objects.get(meta.get("partner", ""))
        if partner is None or partner.type != 'MESH':
            raise ObjectProblem(f"'{target.name}' was mapped with '{meta.get('partner')}', "
                                f"which is no longer in the file")
        source, target = (target, partner) if meta.get("role") == "source" else (partner, target)
    stored = {}
    for ob, role, other in ((source, "source", target), (target, "target", source)):
        got = blender_io.read_correspondence(ob.data)
        if got is None:
            raise ObjectProblem(f"no stored map on '{ob.name}' (or its vertex count "
                                f"changed): run Compute Map first")
        face, bary, meta = got
        if meta.get("role") != role or meta.get("partner") != other.name:
            raise ObjectProblem(
                                f"the map stored on '{ob.name}' is as {meta.get('role')} of "
                                f"'{meta.get('partner')}', not as {role} of '{other.name}': select the pair it "
                                f"was computed for (active = target) or run Compute Map")
        stored[role] = (face, bary, meta)
    depsgraph = context.evaluated_depsgraph_get()
    src = read_side(source, depsgraph, flipped=bool(stored["source"][2].get("flipped", 0)))
    tgt = read_side(target, depsgraph, flipped=bool(stored["target"][2].get("flipped", 0)))
    for ob, side, role in ((source, src, "source"), (target, tgt, "target")):
        meta = stored[role][2]
        if side.fingerprint != meta.get("fingerprint"):
            raise ObjectProblem(f"the stored map is stale: '{ob.name}' was edited since it "
                                f"was computed (vertices or faces changed): run Compute "
                                f"Map again")
        side.dest, side.dest_name = ob, ob.name
    for role, side, other in (("source", src, tgt), ("target", tgt, src)):
        f = stored[role][0]
        if len(f) and (f.min() < 0 or f.max() >= len(other.F)):
            raise ObjectProblem(f"the stored map on '{side['name']}' refers to faces that "
                                f"'{other['name']}' does not have: run Compute Map again")
    res = {"forward": {"face": stored["source"][0], "barycentric": stored["source"][1]},
           "inverse": {"face": stored["target"][0], "barycentric": stored["target"][1]}}
    i_fw = blender_io.read_initial_correspondence(source.data)
    i_iv = blender_io.read_initial_correspondence(target.data)
    if i_fw is not None and i_iv is not None:
        ok = (i_fw[0].min(initial=0) >= 0 and i_fw[0].max(initial=0) < len(tgt.F)
              and i_iv[0].min(initial=0) >= 0 and i_iv[0].max(initial=0) < len(src.F))
        if ok:  # (otherwise the "before" outputs are left out, the map itself is fine)
            res["initial_forward"] = {"face": i_fw[0], "barycentric": i_fw[1]}
            res["initial_inverse"] = {"face": i_iv[0], "barycentric": i_iv[1]}
    return source, target, src, tgt, res


class _StoredMapOperator:
    bl_options = {'REGISTER', 'UNDO'}
    output = ""

    @classmethod
    def poll(cls, context):
        return object_mode(cls, context)

    def execute(self, context):
        settings = context.scene.surfmap
        try:
            source, target, src, tgt, res = stored_pair(context)
            dist = {}
            if self.output == "DISTORTION":
                # D' as the solve measured it (kept on the source), so a re-paint shows the
                # same values; recomputed from the image triangles when it is not there.
                for key, name in (("dilatation_per_polygon", blender_io.DILATATION),
                                  ("initial_dilatation_per_polygon",
                                   blender_io.DILATATION_INITIAL)):
                    d = blender_io.read_face_float(source.data, name)
                    if d is not None:
                        dist[key] = np.where(d < 0, np.inf, d)
            opts = map_job.MapOptions.from_settings(settings)
            out = map_job.compute_outputs(src, tgt, dict(res, **dist), opts, only={self.output})
            if self.output == "UV" and not out["uv"]:
                raise ObjectProblem(f"the source '{source.name}' has no UV map to transfer")
            which = {self.output}
            if self.output == "MORPH" and settings.write_refined:
                which.add("REFINED")
            lines = write_outputs(context, source, target, src, tgt, out, None, which)
        except ObjectProblem as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        for line in out["report"] + lines:
            self.report({'INFO'}, line)
        return {'FINISHED'}


class SURFMAP_OT_transfer_uvs(_StoredMapOperator, bpy.types.Operator):
    """Carry every UV map of the source onto the target through the stored map (respecting
    seams)"""
    bl_idname = "surfmap.transfer_uvs"
    bl_label = "Transfer UVs"
    output = "UV"


class SURFMAP_OT_create_morph(_StoredMapOperator, bpy.types.Operator):
    """Shape keys from the stored map: the source shaped as the target, the target as the
    source"""
    bl_idname = "surfmap.create_morph"
    bl_label = "Create Morph"
    output = "MORPH"


class SURFMAP_OT_paint_distortion(_StoredMapOperator, bpy.types.Operator):
    """Colour attributes of the stored map's dilatation, conformal factor and mean-curvature
    difference on the source"""
    bl_idname = "surfmap.paint_distortion"
    bl_label = "Paint Distortion"
    output = "DISTORTION"


def cut_along_seams(src, tgt, res, uv_name):
    """uv_transfer.SeamCut of the target's polygons along the seams of the source's UV map
    `uv_name`, from the stored map res (forward: per source vertex, inverse: per target
    vertex)."""
    tr = uv_transfer.UVTransfer(src.F, src.corner_uvs(src.uv_layers[uv_name]), src.V)
    inv, fw = res["inverse"], res["forward"]
    return uv_transfer.SeamCut(tr, tgt.V, tgt.loop_start, tgt.loop_total, tgt.loop_vertex,
                               inv["face"], inv["barycentric"], fw["face"], fw["barycentric"],
                               tgt.F, tgt.tri_polygon).run()


def cut_object(context, target, cut, name, uv_name):
    """A new object (the target's transform, materials and collections) with the cut mesh and
    the UV map `uv_name`; returns it."""
    me = bpy.data.meshes.new(name)
    starts, totals = cut.loop_start.tolist(), cut.loop_total.tolist()
    lv = cut.loop_vertex.tolist()
    me.from_pydata(cut.V.tolist(), [], [lv[s:s + n] for s, n in zip(starts, totals)])
    layer = me.uv_layers.new(name=uv_name)
    layer.data.foreach_set("uv", np.asarray(cut.loop_uv, dtype=np.float32).ravel())
    me.polygons.foreach_set("use_smooth", [True] * len(me.polygons))
    for mat in target.data.materials:
        me.materials.append(mat)
    me.update()
    ob = bpy.data.objects.new(name, me)
    ob.matrix_world = target.matrix_world.copy()
    for coll in target.users_collection or (context.scene.collection,):
        coll.objects.link(ob)
    return ob


class SURFMAP_OT_cut_along_seams(bpy.types.Operator):
    """A copy of the target cut along the images of the source's UV seams, with the source's
    UV map on it: every face lies in one UV island, so textures show no saw-tooth at seams
    (new topology; the target itself is unchanged)"""
    bl_idname = "surfmap.cut_along_seams"
    bl_label = "Cut Target Along Seams"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return object_mode(cls, context)

    def execute(self, context):
        try:
            source, target, src, tgt, res = stored_pair(context)
            if not src.uv_layers:
                raise ObjectProblem(f"the source '{source.name}' has no UV map to cut along")
            active = source.data.uv_layers.active
            uv_name = active.name if active is not None and active.name in src.uv_layers \
                else next(iter(src.uv_layers))
            cut = cut_along_seams(src, tgt, res, uv_name)
        except ObjectProblem as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        ob = cut_object(context, target, cut, f"{target.name} cut along seams", uv_name)
        self.report({'INFO'}, f"'{ob.name}': {cut.cut} of {len(tgt.loop_start)} faces of "
                              f"'{target.name}' cut along the seams of '{source.name}' / "
                              f"'{uv_name}' ({cut.crossings} vertices on edges, "
                              f"{cut.junctions} at seam junctions)"
                    + (f"; {cut.unresolved} faces could not be cut and keep one "
                       f"continued chart (" + ", ".join(f"{n}: {w}" for w, n in
                                                       sorted(cut.reasons.items())) + ")"
                       if cut.unresolved else ""))
        return {'FINISHED'}


classes = (SURFMAP_OT_transfer_uvs, SURFMAP_OT_create_morph,
           SURFMAP_OT_paint_distortion, SURFMAP_OT_cut_along_seams)

register, unregister = bpy.utils.register_classes_factory(classes)
