"""SURFMAP_OT_verify_map: the independent certificate of the stored map of the selected pair
(surfmap.verify, docs/verification.md): every vertex located on a face of the other mesh, no
negatively oriented or degenerate image triangle, every vertex star winding once, degree 1 and
the inverse consistent with the forward map."""
import bpy

from .side import ObjectProblem
from .ops_stored_map import stored_pair
from .ops_common import native_and_object_mode, surfmap_module

# Stored barycentrics are float32 attributes: their sums are 1 only to ~1e-7.
STORED_BARYCENTRIC_TOLERANCE = 1e-5


class SURFMAP_OT_verify_map(bpy.types.Operator):
    """Certify the stored map of the selected pair as a bijection with a checker written apart
    from the solver (no folded or reversed image triangle, degree 1, inverse consistent)"""
    bl_idname = "surfmap.verify_map"
    bl_label = "Verify"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        return native_and_object_mode(cls, context)

    def execute(self, context):
        sm = surfmap_module(context)
        try:
            source, target, src, tgt, res = stored_pair(context)
            cert = sm.verify(src["V"], src["F"], tgt["V"], tgt["F"], res["forward"], res["inverse"],
                             barycentric_tolerance=STORED_BARYCENTRIC_TOLERANCE)
        except (ObjectProblem, sm.Error) as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        lines = cert["summary"].splitlines()
        verdict = next(i for i, line in enumerate(lines) if "CERTIFIED" in line)
        for line in lines[:verdict]:            # the figures of every check
            self.report({'INFO'}, line)
        for line in cert["undecided"]:          # failed only where the image is unresolved
            self.report({'WARNING'}, "undecided: " + line)
        head = f"'{source.name}' -> '{target.name}': {lines[verdict]}"
        if not cert["certified"]:
            self.report({'ERROR'}, head + " " + "; ".join(cert["failures"]))
            return {'CANCELLED'}
        self.report({'INFO'}, head)
        return {'FINISHED'}


classes = (SURFMAP_OT_verify_map,)

register, unregister = bpy.utils.register_classes_factory(classes)
