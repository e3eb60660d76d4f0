"""Operators. SURFMAP_OT_show_cut_loops: the system of loops of the selected mesh(es)."""
import bpy

from . import blender_io, core, native
from .properties import extra_module_dirs


def surfmap_module(context):
    return native.load(extra_dirs=extra_module_dirs(context))


def native_and_object_mode(cls, context):
    """The poll precondition every Surface Map operator shares: the native module is there
    and Blender is in Object Mode (otherwise the reason goes to poll_message_set)."""
    if surfmap_module(context) is None:
        cls.poll_message_set("The surfmap native module is missing (see the Surface Map panel)")
        return False
    if context.mode != 'OBJECT':
        cls.poll_message_set("Switch to Object Mode")
        return False
    return True


def pick_objects(context):
    """(source, target) following Blender's selected-to-active habit: the active object is the
    target, the other selected mesh the source (None with a single mesh). Raises
    core.ObjectProblem with a message when the selection does not fit."""
    selected = list(context.selected_objects)
    active = context.active_object
    if active is not None and active.select_get() and active not in selected:
        selected.append(active)
    others = [o for o in selected if o.type != 'MESH']
    if others:
        o = others[0]
        raise core.ObjectProblem(f"'{o.name}' is a {o.type.lower()}, not a mesh: "
                                 f"select one or two mesh objects")
    if not selected:
        raise core.ObjectProblem("no mesh selected: select one or two mesh objects")
    if len(selected) > 2:
        raise core.ObjectProblem(f"{len(selected)} objects selected: select one mesh, or two "
                                 f"(the active one is the target, the other the source)")
    if len(selected) == 1:
        return None, selected[0]
    if active not in selected:
        raise core.ObjectProblem("two meshes selected but neither is active: the active object "
                                 "is the target (click it last)")
    source = selected[0] if selected[1] == active else selected[1]
    return source, active


class SURFMAP_OT_show_cut_loops(bpy.types.Operator):
    """Compute the system of cut loops (2g loops through one base vertex that cut the surface
    into a disk) of the selected mesh(es); draw them as curves and mark them as seams"""
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
        try:
            source, target = pick_objects(context)
            depsgraph = context.evaluated_depsgraph_get()
            objs = [o for o in (source, target) if o is not None]
            # 1. Read and validate everything before touching the scene, so that an error
            #    leaves it exactly as it was.
            data, intakes = {}, {}
            for o in objs:
                d = blender_io.read_object_mesh(o, depsgraph)
                if len(d["F"]) == 0:
                    raise core.ObjectProblem(f"object '{o.name}' has no faces")
                data[o.name] = d
                intakes[o.name] = core.intake_object(sm, o.name, d["V"], d["F"])
            core.check_genus(source.name if source else None,
                             intakes[source.name]["info"]["genus"] if source else None,
                             target.name, intakes[target.name]["info"]["genus"])
            results = {}
            for o in objs:
                it = intakes[o.name]
                base = settings.target_base_vertex if o == target else settings.source_base_vertex
                results[o.name] = core.loops_of_object(sm, o.name, it["V"], it["F"], base)
        except core.ObjectProblem as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        except sm.Error as e:
            self.report({'ERROR'}, f"surfmap: {e}")
            return {'CANCELLED'}

        # 2. Write: seams (on the original mesh only), loop curves, materials.
        notes = []
        for o in objs:
            r, d, it = results[o.name], data[o.name], intakes[o.name]
            bevel = settings.loop_bevel * core.bounding_diagonal(it["V"])
            blender_io.add_loop_curves(context.scene, o, r["curves"], bevel)
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
        parts = [f"'{o.name}': genus {results[o.name]['genus']}, base vertex "
                 f"{results[o.name]['base_vertex']}, word {results[o.name]['word_text']}"
                 for o in objs]
        msg = "; ".join(parts)
        settings.status = "; ".join([msg] + notes)
        for note in notes:
            self.report({'WARNING'} if "modifiers" in note else {'INFO'}, note)
        self.report({'INFO'}, msg)
        return {'FINISHED'}


classes = (SURFMAP_OT_show_cut_loops,)

register, unregister = bpy.utils.register_classes_factory(classes)
