"""The re-runs from the stored correspondence (bpy): surfmap.transfer_uvs, surfmap.create_morph
and surfmap.paint_distortion write one output again without a solve, from the map stored on
both objects by compute_map (checked against the meshes' fingerprints)."""
import bpy
import numpy as np

from . import blender_io, map_job
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


classes = (SURFMAP_OT_transfer_uvs, SURFMAP_OT_create_morph,
           SURFMAP_OT_paint_distortion)

register, unregister = bpy.utils.register_classes_factory(classes)
