"""surfmap.show_cut_loops (bpy): the system of loops of the selected mesh(es), drawn as curves
and marked as seams. The maths is in cut_loops.py."""
from types import SimpleNamespace

import bpy
import numpy as np

from . import blender_io, cut_loops, native
from .ops_common import errors_reported, native_and_object_mode, pick_objects, surfmap_module
from .ops_map import draw_boundary_loops


class SURFMAP_OT_show_cut_loops(bpy.types.Operator):
    """Compute the system of cut loops (2g loops through one base vertex that cut the surface
    into a disk) of the selected mesh(es); draw them as curves and mark them as seams. An open
    mesh's boundary loops are drawn instead"""
    bl_idname = "surfmap.show_cut_loops"
    bl_label = "Show Cut Loops"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        if not native_and_object_mode(cls, context):
            return False
        if not any(o.type == 'MESH' for o in context.selected_objects):
            cls.poll_message_set("Select one or two mesh objects (active = target)")
            return False
        return True

    def execute(self, context):
        sm = surfmap_module(context)
        settings = context.scene.surfmap
        if not hasattr(sm, "system_of_loops"):
            self.report({'ERROR'}, f"the surfmap module at {native.origin()} is too old: it has "
                                   f"no system_of_loops (rebuild it)")
            return {'CANCELLED'}
        with errors_reported(self, sm) as r:
            source, target = pick_objects(context)
            depsgraph = context.evaluated_depsgraph_get()
            objs = [o for o in (source, target) if o is not None]
            # 1. Read and validate everything before touching the scene, so that an error
            #    leaves it exactly as it was.
            data, intakes = {}, {}
            for o in objs:
                d = blender_io.read_object_mesh(o, depsgraph)
                if len(d["F"]) == 0:
                    raise cut_loops.ObjectProblem(f"object '{o.name}' has no faces")
                data[o.name] = d
                intakes[o.name] = cut_loops.intake_object(sm, o.name, d["V"], d["F"], allow_boundary=True)
            # Open meshes (docs/open_surfaces.md): their boundary loops are drawn instead, as
            # Compute Map draws them; the cut loops are a closed surface's.
            closed = [o for o in objs if not intakes[o.name].get("boundary_loops")]
            if len(closed) == len(objs):
                cut_loops.check_genus(source.name if source else None,
                                      intakes[source.name]["info"]["genus"] if source else None,
                                      target.name, intakes[target.name]["info"]["genus"])
            else:
                for o in closed:
                    cut_loops.check_genus(None, None, o.name, intakes[o.name]["info"]["genus"])
            results = {}
            for o in closed:
                it = intakes[o.name]
                base = settings.target_base_vertex if o == target else settings.source_base_vertex
                results[o.name] = cut_loops.loops_of_object(sm, o.name, it["V"], it["F"], base)
        if r.failed:
            return {'CANCELLED'}

        # 2. Write: seams (on the original mesh only), loop curves, materials.
        notes, parts = [], []
        for o in objs:
            it = intakes[o.name]
            if o.name not in results:
                side = SimpleNamespace(V=np.asarray(it["V"], dtype=np.float64),
                                       boundary_loops=[np.asarray(l, dtype=np.int64) for l in it["boundary_loops"]])
                drawn = draw_boundary_loops(context, [(o, side)])
                b = len(side.boundary_loops)
                parts.append(f"'{o.name}': genus {it['info']['genus']} with {b} boundary loop{'s' if b != 1 else ''}, "
                             + (f"drawn as {b} curve{'s' if b != 1 else ''} (no cut loops: open surfaces map "
                                f"through their boundary)" if drawn else
                                "boundary not drawn (the object's mesh has modifiers applied)"))
                continue
            r, d = results[o.name], data[o.name]
            bevel = settings.loop_bevel * cut_loops.bounding_diagonal(it["V"])
            own = not d["evaluated"] and len(it["V"]) == len(o.data.vertices)
            blender_io.add_loop_curves(context.scene, o, r["curves"], bevel,
                                       r.get("curve_weights") if own else None)
            if d["evaluated"]:
                notes.append(f"'{o.name}': used the mesh with modifiers applied; seams not "
                             f"marked (its edges are not the object's own)")
            elif settings.mark_seams and len(it["V"]) == len(o.data.vertices):
                marked = blender_io.mark_seams(o.data, r["seam_edges"])
                if marked < len(r["seam_edges"]):
                    notes.append(f"'{o.name}': {len(r['seam_edges']) - marked} of "
                                 f"{len(r['seam_edges'])} loop edges cross polygons (they are "
                                 f"triangulation diagonals) and are not marked as seams")
            for note in it["info"].get("notes", []):
                notes.append(f"'{o.name}': {note}")
        parts += [f"'{o.name}': genus {results[o.name]['genus']}, base vertex "
                  f"{results[o.name]['base_vertex']}, word {results[o.name]['word_text']}"
                  for o in objs if o.name in results]
        msg = "; ".join(parts)
        settings.status = "; ".join([msg] + notes)
        for note in notes:
            self.report({'WARNING'} if "modifiers" in note else {'INFO'}, note)
        self.report({'INFO'}, msg)
        return {'FINISHED'}


classes = (SURFMAP_OT_show_cut_loops,)

_register, _unregister = bpy.utils.register_classes_factory(classes)


def register():
    _register()
    blender_io.register_handlers()   # the loop curves follow the morph's shape keys


def unregister():
    blender_io.unregister_handlers()
    _unregister()
