"""Many objects at once (docs/many_shapes.md): the active object (the template) mapped onto each
other selected mesh, one after another; and "Compare Selected", the distance table of the
selected meshes (surfmap.compare, pairwise mode) in a text block, each object coloured by the
mean dilatation D' of the active one's map onto it.

In the UI both run modally (the native solves on a worker thread, progress per object, Esc
cancels the rest: what finished is kept); in `blender -b` and from scripts they run
synchronously. Only the native solve runs on the worker thread (see mapjob.MapJob.compute_outputs
for why).
"""
import threading
import time

import bpy
import numpy as np

from . import colours, ops_map
from .side import ObjectProblem
from .ops_common import errors_reported, native_and_object_mode, surfmap_module

COMPARE_TEXT = "surfmap comparison"
DILATATION_KEY = "surfmap_mean_dilatation_to_active"


def _selected_meshes(context):
    """(active, [other selected meshes]); raises ObjectProblem when that does not fit."""
    act = context.active_object
    if act is None or act.type != 'MESH' or not act.select_get():
        raise ObjectProblem("make the template (the reference) the active, selected mesh")
    others = [o for o in context.selected_objects if o != act]
    bad = [o for o in others if o.type != 'MESH']
    if bad:
        raise ObjectProblem(f"'{bad[0].name}' is a {bad[0].type.lower()}, not a mesh")
    if not others:
        raise ObjectProblem("select the other meshes too (the active one is the template)")
    return act, sorted(others, key=lambda o: o.name)


def _status(context, text):
    if context.workspace is not None:
        context.workspace.status_text_set(text)


class _Modal:
    """A list of steps, each a native call run on a worker thread (UI) or inline
    (background); subclasses define _begin(context, k) -> callable or None (skip) and
    _end(context, k, result_or_exception)."""
    _timer = None

    def execute(self, context):
        if not self._setup(context):
            return {'CANCELLED'}
        return self._run_all(context)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        if not self._setup(context):
            return {'CANCELLED'}
        return self._start(context)

    def _run_all(self, context):
        for k in range(self._count):
            call = self._begin(context, k)
            if call is None:
                continue
            try:
                result = call()
            except Exception as e:  # recorded per step; the others go on
                result = e
            self._end(context, k, result)
        return self._done(context, cancelled=False)

    def _start(self, context):
        self._k, self._thread, self._box = -1, None, {}
        self._cancel = False
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 100)
        self._next(context)
        return {'RUNNING_MODAL'}

    def _next(self, context):
        while True:
            self._k += 1
            if self._k >= self._count:
                self._thread = None
                return
            call = self._begin(context, self._k)
            if call is not None:
                break
        box = self._box = {}

        def work():
            try:
                box["result"] = call()
            except Exception as e:
                box["result"] = e
        self._t0 = time.time()
        self._thread = threading.Thread(target=work, name="surfmap batch", daemon=True)
        self._thread.start()

    def modal(self, context, event):
        if event.type == 'ESC' and event.value == 'PRESS':
            self._cancel = True
            self._stop_current()
        if event.type == 'TIMER':
            frac = (max(self._k, 0) + self._fraction()) / max(self._count, 1)
            context.window_manager.progress_update(int(100 * frac))
            _status(context, "Surface Map: cancelling..." if self._cancel else self._status_text())
        if self._thread is not None and not self._thread.is_alive():
            self._end(context, self._k, self._box.get("result"))
            if self._cancel:
                self._thread = None
            else:
                self._next(context)
        if self._thread is None:
            wm = context.window_manager
            wm.event_timer_remove(self._timer)
            wm.progress_end()
            _status(context, None)
            return self._done(context, cancelled=self._cancel)
        if event.type in {'MIDDLEMOUSE', 'WHEELUPMOUSE', 'WHEELDOWNMOUSE', 'TRACKPADPAN',
                          'TRACKPADZOOM', 'MOUSEMOVE', 'INBETWEEN_MOUSEMOVE'}:
            return {'PASS_THROUGH'}
        return {'RUNNING_MODAL'}


class SURFMAP_OT_map_onto_selected(_Modal, bpy.types.Operator):
    """Map the active object (the template) onto every other selected mesh, one after another,
    with the Compute Map options and outputs (Esc cancels the rest)"""
    bl_idname = "surfmap.map_onto_selected"
    bl_label = "Map Active onto Selected"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return native_and_object_mode(cls, context)

    def _setup(self, context):
        self._sm = surfmap_module(context)
        try:
            self._template, self._targets = _selected_meshes(context)
        except ObjectProblem as e:
            self.report({'ERROR'}, str(e))
            return False
        self._count = len(self._targets)
        self._jobs, self._lines, self._mapped = {}, [], 0
        return True

    def _override(self, context, target):
        return context.temp_override(selected_objects=[self._template, target],
                                     selected_editable_objects=[self._template, target],
                                     active_object=target, object=target)

    def _begin(self, context, k):
        target = self._targets[k]
        try:
            with self._override(context, target):
                job, notes = ops_map.prepare_job(bpy.context, self._sm)
        except (ObjectProblem, self._sm.Error) as e:
            self._record(target, f"skipped: {e}")
            return None
        self._jobs[k] = (job, notes)

        def solve():
            job.run(with_outputs=False)
            return job
        return solve

    def _record(self, target, text, ok=False):
        """One line per target; `ok` counts it as mapped."""
        self._mapped += bool(ok)
        self._lines.append(f"{target.name}: {text}")
        self.report({'INFO'} if ok else {'WARNING'}, f"'{self._template.name}' -> '{target.name}': {text}")

    def _end(self, context, k, result):
        target = self._targets[k]
        job, notes = self._jobs[k]
        if isinstance(result, Exception) or job.error is not None or job.cancel:
            kind, msg = job.error if job.error is not None else ("failed", str(result))
            self._record(target, "cancelled" if kind == "cancelled" else f"failed: {msg}")
            return
        job.compute_outputs()
        self._notes = notes
        with self._override(context, target):
            status = ops_map.SURFMAP_OT_compute_map._finish(self, bpy.context, job)
        if 'FINISHED' in status:
            res = job.result
            target[DILATATION_KEY] = float(res["distortion"]["mean"])
            self._record(target, f"done: mean D' {res['distortion']['mean']:.4g}, energy "
                                 f"{res['energy']['final']:.6g}, {job.elapsed:.1f}s", ok=True)
        else:
            self._record(target, "failed: outputs not written")

    def _stop_current(self):
        job = self._jobs.get(self._k, (None,))[0]
        if job is not None:
            job.cancel = True

    def _fraction(self):
        job = self._jobs.get(self._k, (None,))[0]
        return job.fraction if job is not None else 0.0

    def _status_text(self):
        job = self._jobs.get(self._k, (None,))[0]
        name = self._targets[self._k].name if 0 <= self._k < self._count else ""
        inner = job.status_text() if job is not None else ""
        return f"Surface Map: object {self._k + 1}/{self._count} '{name}' — {inner}"

    def _done(self, context, cancelled):
        done = self._mapped
        text = (f"'{self._template.name}' mapped onto {done} of {self._count} objects"
                + (" (cancelled: the rest were not mapped)" if cancelled else ""))
        context.scene.surfmap.map_status = "; ".join([text] + self._lines)
        self.report({'WARNING'} if cancelled or done < self._count else {'INFO'}, text)
        return {'FINISHED'} if done else {'CANCELLED'}


def _object_mesh(context, ob):
    """(V (n,3) local coordinates, F (m,3)) of the evaluated mesh, triangulated."""
    ev = ob.evaluated_get(context.evaluated_depsgraph_get())
    me = ev.to_mesh()
    try:
        me.calc_loop_triangles()
        V = np.empty(len(me.vertices) * 3)
        me.vertices.foreach_get("co", V)
        F = np.empty(len(me.loop_triangles) * 3, dtype=np.int64)
        me.loop_triangles.foreach_get("vertices", F)
    finally:
        ev.to_mesh_clear()
    return V.reshape(-1, 3), F.reshape(-1, 3)


class SURFMAP_OT_compare_selected(_Modal, bpy.types.Operator):
    """Distance table of the selected meshes (every pair mapped; λ and mean curvature compared,
    docs/many_shapes.md) in the text block 'surfmap comparison'; each object is coloured by the
    mean dilatation D' of the active object's map onto it"""
    bl_idname = "surfmap.compare_selected"
    bl_label = "Compare Selected"
    bl_options = {'REGISTER', 'UNDO'}

    beta: bpy.props.FloatProperty(name="Beta", default=1.0, min=0.0,
                                  description="Weight of the mean-curvature term")

    @classmethod
    def poll(cls, context):
        return native_and_object_mode(cls, context)

    def _setup(self, context):
        sm = self._sm = surfmap_module(context)
        import importlib
        self._C = importlib.import_module(sm.__name__ + ".compare")
        self._mapcall = importlib.import_module(sm.__name__ + ".mapcall")
        with errors_reported(self, sm) as r:
            act, others = _selected_meshes(context)
            self._objects = [act] + others
            self._meshes = []
            for ob in self._objects:
                V, F = _object_mesh(context, ob)
                d = sm.intake(V, F)
                self._meshes.append((np.asarray(d["V"]), np.asarray(d["F"], dtype=np.int64),
                                     int(d["info"]["genus"])))
        if r.failed:
            return False
        genera = {g for _, _, g in self._meshes}
        if len(genera) != 1:
            self.report({'ERROR'}, "the selected meshes differ in genus: " + ", ".join(
                f"'{o.name}' {g}" for o, (_, _, g) in zip(self._objects, self._meshes)))
            return False
        n = len(self._objects)
        self._pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
        self._count = len(self._pairs)
        self._E = np.full((n, n), np.nan)
        np.fill_diagonal(self._E, 0.0)
        self._dil = np.full(n, np.nan)
        self._dil[0] = 1.0
        self._errors = []
        return True

    def _begin(self, context, k):
        i, j = self._pairs[k]
        (Vi, Fi, _), (Vj, Fj, _) = self._meshes[i], self._meshes[j]
        C, mc = self._C, self._mapcall
        a, b = C.normalise(Vi, Fi), C.normalise(Vj, Fj)  # numpy here, on the main thread
        self._stop = False

        def solve():
            return mc.run_map(a, Fi, b, Fj, progress=lambda stage, f: not self._stop)
        return solve

    def _end(self, context, k, result):
        i, j = self._pairs[k]
        names = (self._objects[i].name, self._objects[j].name)
        if isinstance(result, Exception) or result is None:
            self._errors.append(f"{names[0]} -> {names[1]}: {result}")
            return
        (Vi, Fi, _), (Vj, Fj, _) = self._meshes[i], self._meshes[j]
        e = self._C.distance_of_map(Vi, Fi, Vj, Fj, result, self.beta)
        self._E[i, j] = self._E[j, i] = e
        if i == 0:
            self._dil[j] = float(result["distortion"]["mean"])

    def _stop_current(self):
        self._stop = True

    def _fraction(self):
        return 0.0

    def _status_text(self):
        i, j = self._pairs[self._k]
        return (f"Surface Map: comparing {self._k + 1}/{self._count} '{self._objects[i].name}' "
                f"-> '{self._objects[j].name}', {time.time() - self._t0:.1f}s — Esc to cancel")

    def _done(self, context, cancelled):
        names = [o.name for o in self._objects]
        width = max(8, *(len(n) for n in names))
        lines = [f"surfmap comparison: E(Si, Sj) = ∫ |λi − λj|² + β |Hi − Hj|² (β = {self.beta:g}), "
                 f"pairwise maps; reference (active) '{names[0]}'"
                 + (" — CANCELLED, missing entries are nan" if cancelled else ""), ""]
        lines.append(" " * width + " " + " ".join(f"{n[:10]:>10}" for n in names))
        for n, row in zip(names, self._E):
            lines.append(f"{n:<{width}} " + " ".join(f"{x:10.4g}" for x in row))
        lines += ["", f"mean D' of '{names[0]}' mapped onto each object:"]
        finite = self._dil[np.isfinite(self._dil)]
        hi = max(float(finite.max()), 1.0 + 1e-6)
        rgba = colours.colour_scale(np.nan_to_num(self._dil, nan=hi), 1.0, hi, colours.SEQUENTIAL)
        for ob, d, c in zip(self._objects, self._dil, rgba):
            lines.append(f"  {ob.name}: {d:.4g}")
            if np.isfinite(d):
                ob[DILATATION_KEY] = float(d)
                ob.color = (float(c[0]), float(c[1]), float(c[2]), 1.0)
        lines += [f"error: {e}" for e in self._errors]
        text = bpy.data.texts.get(COMPARE_TEXT) or bpy.data.texts.new(COMPARE_TEXT)
        text.clear()
        text.write("\n".join(lines) + "\n")
        for area in (context.screen.areas if context.screen else []):
            if area.type == 'VIEW_3D':
                area.spaces.active.shading.color_type = 'OBJECT'  # show the colours
        msg = (f"compared {len(names)} objects ({self._count - len(self._errors)} maps); table in "
               f"the text block '{COMPARE_TEXT}'")
        self.report({'WARNING'} if cancelled or self._errors else {'INFO'}, msg)
        return {'FINISHED'}


def draw_rows(layout):
    """The two panel rows of these operators."""
    col = layout.column(align=True)
    col.label(text="Active and other selected:")
    row = col.row(align=True)
    row.operator(SURFMAP_OT_map_onto_selected.bl_idname, text="Map Onto", icon='MOD_UVPROJECT')
    row.operator(SURFMAP_OT_compare_selected.bl_idname, text="Compare", icon='SORTSIZE')


classes = (SURFMAP_OT_map_onto_selected, SURFMAP_OT_compare_selected)

register, unregister = bpy.utils.register_classes_factory(classes)
