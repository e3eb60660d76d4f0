"""Operators of the map (DESIGN.md §5): surfmap.compute_map (modal with a worker thread in the
UI, synchronous in background mode) and the re-runs from the stored correspondence,
surfmap.transfer_uvs, surfmap.create_morph and surfmap.paint_distortion.

Reading the scene and writing it are the only bpy work here; the maths is in mapping.py and
mapjob.py. Everything that can fail is checked before the first write, so a refusal leaves the
scene as it was."""
import math

import bpy
import numpy as np

from . import blender_io, core, mapjob, mapping
from .operators import native_and_object_mode, pick_objects, surfmap_module

GENERATED_UV = "surfmap box projection"
OUTPUT_FLAGS = (("write_uvs", "UV"), ("write_morph", "MORPH"), ("write_distortion", "DISTORTION"),
                ("write_refined", "REFINED"))


# --- reading -----------------------------------------------------------------------------------

def _side(obj, depsgraph, sm=None, flipped=None):
    """One object's mesh as mapjob expects it. With sm: validated by the native intake (raises
    core.ObjectProblem naming the object), else re-oriented like a stored run (`flipped`)."""
    d = blender_io.read_map_mesh(obj, depsgraph)
    d["name"] = obj.name
    d["matrix"] = blender_io.matrix_np(obj.matrix_world)
    if len(d["F"]) == 0:
        raise core.ObjectProblem(f"object '{obj.name}' has no faces")
    if sm is not None:
        it = core.intake_object(sm, obj.name, d["V"], d["F"])
        if it["F"].shape != d["F"].shape:
            raise core.ObjectProblem(f"object '{obj.name}': the intake changed the number of "
                                     f"triangles ({len(d['F'])} -> {len(it['F'])})")
        flipped = bool(it["flipped"])
        d["genus"] = int(it["info"]["genus"])
        d["notes"] = list(it["info"].get("notes", []))
    d["flipped"] = bool(flipped)
    F = np.ascontiguousarray(d["F"], dtype=np.int32)
    tl = np.asarray(d["tri_loops"], dtype=np.int64)
    if d["flipped"]:
        F = np.ascontiguousarray(F[:, [0, 2, 1]])
        tl = tl[:, [0, 2, 1]]
    d["F"], d["tri_loops"] = F, tl
    d["fingerprint"] = mapping.fingerprint(d["V"], F)
    d["has_ngons"] = bool(np.any(np.asarray(d["loop_total"]) > 3))
    return d


def _landmarks(settings, source, target, src_side, tgt_side):
    """(pairs (k,2) or None, description) from the panel's landmark setting."""
    mode = settings.landmark_mode
    if mode == 'NONE':
        return None, ""
    if mode == 'GROUPS':
        prefix = mapping.LANDMARK_PREFIX
        pick = lambda d: {k: v for k, v in d["vertex_groups"].items() if k.startswith(prefix)}
        pairs, names, problems = mapping.landmark_pairs(pick(src_side), pick(tgt_side))
        if problems:
            raise core.ObjectProblem("landmarks: " + "; ".join(problems))
        if len(pairs) == 0:
            raise core.ObjectProblem(f"landmarks: no vertex groups named '{prefix}...' on both "
                                     f"'{source.name}' and '{target.name}'")
        desc = f"{len(pairs)} landmark(s) from vertex groups " + ", ".join(names)
    else:
        lists = []
        for ob, side in ((source, src_side), (target, tgt_side)):
            if side["evaluated"] and not side["same_topology"]:
                raise core.ObjectProblem(f"landmarks: '{ob.name}' has modifiers that change its "
                                         f"vertices, so its selected vertices cannot be used; "
                                         f"use vertex groups named 'lm_...'")
            lists.append(blender_io.selected_vertex_order(ob.data))
        if len(lists[0]) != len(lists[1]) or not lists[0]:
            raise core.ObjectProblem(f"landmarks: {len(lists[0])} vertices selected on "
                                     f"'{source.name}' but {len(lists[1])} on '{target.name}' "
                                     f"(select the same number, in matching order)")
        pairs = np.stack([np.asarray(lists[0]), np.asarray(lists[1])], axis=1)
        desc = f"{len(pairs)} landmark(s) from the selected vertices"
    try:
        mapping.check_landmarks(pairs, len(src_side["V"]), len(tgt_side["V"]))
    except ValueError as e:
        raise core.ObjectProblem(f"landmarks: {e}") from None
    return pairs, desc


def _modifier_note(side):
    if not side["evaluated"]:
        return None
    if side["same_topology"]:
        return (f"'{side['name']}': used the mesh with its modifiers applied (same vertices and "
                f"faces as its own mesh, so the outputs are written on it; shape keys act "
                f"before the modifiers)")
    return (f"'{side['name']}': used the mesh with its modifiers applied; they change its "
            f"topology, so the outputs go on a new object holding that mesh")


def prepare_job(context, sm):
    """Reads and checks everything; returns (MapJob, notes). Raises core.ObjectProblem."""
    settings = context.scene.surfmap
    source, target = pick_objects(context)
    if source is None:
        raise core.ObjectProblem(f"only '{target.name}' is selected: select two meshes (the "
                                 f"source, then the target as the active object)")
    if source.data == target.data:
        raise core.ObjectProblem(f"'{source.name}' and '{target.name}' share the mesh "
                                 f"'{target.data.name}': the map's layers would overwrite each "
                                 f"other (Object > Relations > Make Single User first)")
    depsgraph = context.evaluated_depsgraph_get()
    src = _side(source, depsgraph, sm)
    tgt = _side(target, depsgraph, sm)
    if src["genus"] != tgt["genus"]:
        raise core.ObjectProblem(f"source '{source.name}' has genus {src['genus']} but target "
                                 f"'{target.name}' has genus {tgt['genus']}: a map needs equal "
                                 f"genus")
    landmarks, lm_desc = _landmarks(settings, source, target, src, tgt)
    capabilities = getattr(sm, "CAPABILITIES", frozenset())
    for word, wanted in (("landmarks", landmarks is not None),
                         ("method", settings.method != 'NEWTON'),
                         ("tolerance", settings.tolerance > 0),
                         ("source_weights", settings.source_weights != 'AUTO')):
        if wanted and word not in capabilities:
            raise core.ObjectProblem(f"this build of the surfmap module does not support "
                                     f"{word} yet (rebuild it from a newer checkout)")
    outputs = {flag for prop, flag in OUTPUT_FLAGS if getattr(settings, prop)}
    options = {"homotopy": settings.homotopy, "landmarks": landmarks,
               "method": settings.method.lower(), "tolerance": settings.tolerance,
               "source_weights": settings.source_weights.lower(),
               "outputs": outputs, "uv_before": bool(settings.write_uvs_before),
               "morph_space": settings.morph_space}
    if "UV" in outputs:
        ours = set(target.data.get(blender_io.LAYERS_KEY, [])) if not (
            tgt["evaluated"] and not tgt["same_topology"]) else set()
        wanted = [target_uv_name(n) for n in (src["uv_layers"] or [GENERATED_UV])]
        if settings.write_uvs_before and src["genus"] >= 1:
            wanted += [before_uv_name(n) for n in (src["uv_layers"] or [GENERATED_UV])]
        need = sum(1 for n in wanted if f"uv:{n}" not in ours)
        if need > 8 - len(tgt["uv_layers"]):
            raise core.ObjectProblem(f"'{target.name}' has {len(tgt['uv_layers'])} UV maps; the "
                                     f"{need} transferred ones do not fit (Blender allows 8): "
                                     f"remove some, or untick the UVs output")
    notes = [n for n in (_modifier_note(src), _modifier_note(tgt)) if n]
    if "UV" in outputs and not src["uv_layers"]:
        # nothing to carry over: give the source a cube projection (a new layer) and carry that
        src["uv_layers"][GENERATED_UV] = mapping.box_projection(
            src["V"], src["loop_vertex"], src["loop_start"], src["loop_total"])
        src["generated_uv"] = GENERATED_UV
        notes.append(f"'{source.name}' has no UV map: wrote a cube projection '{GENERATED_UV}' "
                     f"on it and transferred that")
    for side in (src, tgt):
        if side["has_ngons"]:
            notes.append(f"'{side['name']}': polygons with more than 3 sides were triangulated "
                         f"for the solve; the results are written on the original corners")
        notes += [f"'{side['name']}': {n}" for n in side.get("notes", [])]
    if lm_desc:
        notes.append(lm_desc)
    return mapjob.MapJob(sm, src, tgt, options), notes


# --- writing -----------------------------------------------------------------------------------

def _destination(context, obj, side):
    if side["evaluated"] and not side["same_topology"]:
        return blender_io.applied_copy(obj, context.evaluated_depsgraph_get(),
                                       f"{obj.name} (surfmap)")
    return obj


def _meta(side, partner, role, res):
    m = {"partner": partner["dest_name"], "role": role, "fingerprint": side["fingerprint"],
         "partner_fingerprint": partner["fingerprint"], "flipped": int(side["flipped"]),
         "partner_flipped": int(partner["flipped"]), "evaluated": int(side["evaluated"])}
    if res is not None and "genus" in res:
        m.update(genus=int(res["genus"]), energy=float(res["energy"]["final"]),
                 homotopy=int(res["homotopy"]["chosen"]),
                 mean_dilatation=float(res["distortion"]["mean"]))
    return m


def target_uv_name(source_uv_name):
    """'surfmap <name>' (without doubling the prefix of a layer this add-on made)."""
    return source_uv_name if source_uv_name.startswith("surfmap ") else f"surfmap {source_uv_name}"


def before_uv_name(source_uv_name):
    """'surfmap before <name>': the UVs carried through the initial map."""
    n = source_uv_name[len("surfmap "):] if source_uv_name.startswith("surfmap ") else source_uv_name
    return f"surfmap before {n}"


def write_outputs(context, source, target, src, tgt, out, res, which):
    """Writes the outputs in `which` ({'CORRESPONDENCE','UV','MORPH','DISTORTION'}); returns
    report lines. source/target: the objects; src/tgt: their sides; out: compute_outputs'."""
    lines = []
    # Checks that could refuse come first (nothing written yet).
    uv_names = ([target_uv_name(n) for n in out["uv"]]
                + [before_uv_name(n) for n in out.get("uv_before", {})]) if "UV" in which else []
    if uv_names:
        room = 8 - len(tgt["uv_layers"])
        ours = set(target.data.get(blender_io.LAYERS_KEY, [])) if not (
            tgt["evaluated"] and not tgt["same_topology"]) else set()
        need = sum(1 for n in uv_names if f"uv:{n}" not in ours)
        if need > room:
            raise core.ObjectProblem(f"'{target.name}' has {len(tgt['uv_layers'])} UV maps; "
                                     f"{need} more do not fit (Blender allows 8): remove some "
                                     f"or untick UVs")
    s_obj = src.get("dest") or _destination(context, source, src)
    t_obj = tgt.get("dest") or _destination(context, target, tgt)
    src["dest"], tgt["dest"] = s_obj, t_obj
    src["dest_name"], tgt["dest_name"] = s_obj.name, t_obj.name
    if s_obj is not source:
        lines.append(f"outputs of '{source.name}' are on the new object '{s_obj.name}'")
    if t_obj is not target:
        lines.append(f"outputs of '{target.name}' are on the new object '{t_obj.name}'")
    if "CORRESPONDENCE" in which:
        fw_f, fw_b = out["forward"]
        iv_f, iv_b = out["inverse"]
        # The initial map is kept only when both directions were located (the "before"
        # morph and UVs are then regenerated from the stored map).
        i_fw, i_iv = out.get("initial_forward"), out.get("initial_inverse")
        both = i_fw is not None and i_iv is not None
        blender_io.write_correspondence(s_obj.data, fw_f, fw_b, _meta(src, tgt, "source", res),
                                        i_fw if both else None)
        blender_io.write_correspondence(t_obj.data, iv_f, iv_b, _meta(tgt, src, "target", res),
                                        i_iv if both else None)
        lines.append(f"correspondence stored on '{s_obj.name}' and '{t_obj.name}' (attributes "
                     f"{blender_io.CORR_FACE}, {blender_io.CORR_BARY}"
                     + (f"; the initial map in {blender_io.CORR_FACE_INITIAL}, "
                        f"{blender_io.CORR_BARY_INITIAL}" if both else "") + ")")
    if "UV" in which and out["uv"]:
        written = []
        if src.get("generated_uv"):
            name = src["generated_uv"]
            blender_io.write_uv_map(s_obj.data, name, src["uv_layers"][name])
            lines.append(f"UV map '{name}' (cube projection) on '{s_obj.name}'")
        for name, uv in out["uv"].items():
            got = blender_io.write_uv_map(t_obj.data, target_uv_name(name), uv)
            if got is not None:
                written.append(got)
        for name, uv in out.get("uv_before", {}).items():
            got = blender_io.write_uv_map(t_obj.data, before_uv_name(name), uv)
            if got is not None:
                written.append(got)
        if written:
            lines.append(f"UV maps on '{t_obj.name}': " + ", ".join(written))
    if "MORPH" in which and "morph_source" in out:
        k1 = blender_io.write_shape_key(s_obj, f"surfmap to {t_obj.name}", out["morph_source"])
        k2 = blender_io.write_shape_key(t_obj, f"surfmap to {s_obj.name}", out["morph_target"])
        lines.append(f"morph shape keys: '{k1}' on '{s_obj.name}', '{k2}' on '{t_obj.name}' "
                     f"(slide 0 -> 1)")
        if "morph_source_initial" in out:
            k0 = blender_io.write_shape_key(s_obj, f"surfmap before to {t_obj.name}",
                                            out["morph_source_initial"])
            how = (res or {}).get("initial_map", {}).get("construction", "")
            lines.append(f"'before' shape key '{k0}' on '{s_obj.name}': the initial map"
                         + (f" ({how})" if how else ""))
    if "REFINED" in which:
        M = mapjob.morph_matrix(tgt["matrix"], src["matrix"],
                                context.scene.surfmap.morph_space)
        ob, r = blender_io.refined_morph_object(
            s_obj, src, tgt, out["image_of_source"], out["forward"][0], M,
            f"surfmap to {t_obj.name}")
        lines.append(f"refined morph object '{ob.name}': {len(src['V'])} -> {len(r['V'])} "
                     f"vertices in {r['rounds']} round(s) of splitting the edges whose image "
                     f"is long or bends (shape key '{ob.data.shape_keys.key_blocks[1].name}')")
    if "DISTORTION" in which and out["colours"]:
        me = s_obj.data
        blender_io.write_face_float(me, blender_io.DILATATION,
                                    np.where(np.isfinite(out["dilatation"]), out["dilatation"], -1))
        if out.get("dilatation_initial") is not None:
            d0 = out["dilatation_initial"]
            blender_io.write_face_float(me, blender_io.DILATATION_INITIAL,
                                        np.where(np.isfinite(d0), d0, -1))
        names = [blender_io.write_colour(me, name, rgba, domain)
                 for name, (rgba, domain) in out["colours"].items()]
        if me.color_attributes.get(names[0]) is not None:
            me.color_attributes.active_color = me.color_attributes[names[0]]
        lines.append(f"colour attributes on '{s_obj.name}': " + ", ".join(names))
        context.scene.surfmap.dilatation_range = out["ranges"]["dilatation"]
    for o in (s_obj, t_obj):
        o.data.update()
    return lines


# --- compute_map -------------------------------------------------------------------------------

def _summary(res, elapsed):
    e = res["energy"]
    s = (f"genus {res['genus']}, energy {e['initial']:.6g} -> {e['final']:.6g} in "
         f"{res['iterations']} iteration(s), mean D' {res['distortion']['mean']:.4g} (max "
         f"{res['distortion']['max']:.4g}), {res['flipped_triangles']} flipped, {elapsed:.1f}s")
    how = res.get("initial_map", {}).get("construction")
    if how:
        s += f", initial map: {how}"
    if res.get("source_weights") and res.get("genus", 0) >= 2:
        s += f", source weights: {res['source_weights']}"
    if not res.get("converged", True):
        s += " (NOT converged)"
    return s


class SURFMAP_OT_compute_map(bpy.types.Operator):
    """Compute the globally optimal map from the selected source onto the active target and
    write UVs, morph shape keys, distortion colours and the correspondence (Esc cancels)"""
    bl_idname = "surfmap.compute_map"
    bl_label = "Compute Map"
    bl_options = {'REGISTER', 'UNDO'}

    _job = None
    _timer = None

    @classmethod
    def poll(cls, context):
        return native_and_object_mode(cls, context)

    def _prepare(self, context):
        sm = surfmap_module(context)
        try:
            job, notes = prepare_job(context, sm)
        except core.ObjectProblem as e:
            self.report({'ERROR'}, str(e))
            return None
        except sm.Error as e:
            self.report({'ERROR'}, f"surfmap: {e}")
            return None
        self._notes = notes
        return job

    def execute(self, context):
        job = self._prepare(context)
        if job is None:
            return {'CANCELLED'}
        job.run()
        return self._finish(context, job)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        job = self._prepare(context)
        if job is None:
            return {'CANCELLED'}
        self._job = job
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 100)
        job.start()
        return {'RUNNING_MODAL'}

    def _status(self, context, text):
        if context.workspace is not None:
            context.workspace.status_text_set(text)
        if context.area is not None:
            context.area.header_text_set(text)

    def _cleanup(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        self._status(context, None)

    def modal(self, context, event):
        job = self._job
        if event.type == 'ESC' and event.value == 'PRESS':
            job.cancel = True
        if event.type == 'TIMER':
            context.window_manager.progress_update(int(100 * job.fraction))
            self._status(context, job.status_text() if not job.cancel else
                         "Surface Map: cancelling...")
        if job.done():
            if not job.cancel:
                job.compute_outputs()
            self._cleanup(context)
            return self._finish(context, job)
        if event.type in {'MIDDLEMOUSE', 'WHEELUPMOUSE', 'WHEELDOWNMOUSE', 'TRACKPADPAN',
                          'TRACKPADZOOM', 'MOUSEMOVE', 'INBETWEEN_MOUSEMOVE'}:
            return {'PASS_THROUGH'}  # the view can be navigated, nothing edited
        return {'RUNNING_MODAL'}

    def _finish(self, context, job):
        if job.cancel or job.error is not None:
            kind, msg = job.error if job.error is not None else ("cancelled", "cancelled")
            if kind == "cancelled":
                self.report({'WARNING'}, "Surface Map cancelled; the scene is unchanged")
            else:
                self.report({'ERROR'}, msg)
            return {'CANCELLED'}
        src, tgt, res, out = job.source, job.target, job.result, job.outputs
        source = bpy.data.objects.get(src["name"])
        target = bpy.data.objects.get(tgt["name"])
        if source is None or target is None:
            self.report({'ERROR'}, "the source or target object was removed during the solve")
            return {'CANCELLED'}
        which = {"CORRESPONDENCE"} | set(job.options["outputs"])
        try:
            lines = write_outputs(context, source, target, src, tgt, out, res, which)
        except core.ObjectProblem as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        settings = context.scene.surfmap
        settings.candidates.clear()
        lines_c = []
        for i, c in enumerate(res["homotopy"]["candidates"]):
            item = settings.candidates.add()
            e = float(c["energy"])
            item.index, item.description = i, c["description"]
            item.solved = bool(c.get("solved", True)) and math.isfinite(e)
            item.energy = e if item.solved else 0.0
            held = float(c.get("landmark_energy", math.nan))
            item.landmark_energy = held
            lines_c.append(f"{i}: " + (f"E = {e:.6g}" if item.solved else "not solved")
                           + (f", with landmarks {held:.6g}" if not math.isnan(held) else ""))
        settings.chosen_candidate = int(res["homotopy"]["chosen"])
        lines.append(f"handle correspondences (chosen {settings.chosen_candidate}): "
                     + "; ".join(lines_c))
        summary = f"'{source.name}' -> '{target.name}': " + _summary(res, job.elapsed)
        lm = job.options.get("landmarks")
        lm_line = mapping.landmark_summary(res, 0 if lm is None else len(lm))
        settings.landmark_status = lm_line or ""
        if lm_line:
            summary += "; " + lm_line
        settings.map_status = "; ".join([summary] + self._notes)
        for note in self._notes:
            self.report({'WARNING'} if "modifiers" in note else {'INFO'}, note)
        for line in out["report"] + lines:
            self.report({'INFO'}, line)
        self.report({'INFO'}, summary)
        return {'FINISHED'}


# --- re-runs from the stored correspondence ---------------------------------------------------

def stored_pair(context):
    """(source, target, src side, tgt side, forward, inverse) from the stored correspondence
    of the selected pair (or of the one selected object and its stored partner). Raises
    core.ObjectProblem when it is missing or stale."""
    source, target = pick_objects(context)
    if source is None:
        meta = target.data.get(blender_io.CORR_KEY)
        if meta is None:
            raise core.ObjectProblem(f"'{target.name}' has no stored map: run Compute Map on a "
                                     f"pair first")
        partner = bpy.data.objects.get(meta.get("partner", ""))
        if partner is None or partner.type != 'MESH':
            raise core.ObjectProblem(f"'{target.name}' was mapped with '{meta.get('partner')}', "
                                     f"which is no longer in the file")
        source, target = (target, partner) if meta.get("role") == "source" else (partner, target)
    stored = {}
    for ob, role, other in ((source, "source", target), (target, "target", source)):
        got = blender_io.read_correspondence(ob.data)
        if got is None:
            raise core.ObjectProblem(f"no stored map on '{ob.name}' (or its vertex count "
                                     f"changed): run Compute Map first")
        face, bary, meta = got
        if meta.get("role") != role or meta.get("partner") != other.name:
            raise core.ObjectProblem(
                f"the map stored on '{ob.name}' is as {meta.get('role')} of "
                f"'{meta.get('partner')}', not as {role} of '{other.name}': select the pair it "
                f"was computed for (active = target) or run Compute Map")
        stored[role] = (face, bary, meta)
    depsgraph = context.evaluated_depsgraph_get()
    src = _side(source, depsgraph, flipped=bool(stored["source"][2].get("flipped", 0)))
    tgt = _side(target, depsgraph, flipped=bool(stored["target"][2].get("flipped", 0)))
    for ob, side, role in ((source, src, "source"), (target, tgt, "target")):
        meta = stored[role][2]
        if side["fingerprint"] != meta.get("fingerprint"):
            raise core.ObjectProblem(f"the stored map is stale: '{ob.name}' was edited since it "
                                     f"was computed (vertices or faces changed): run Compute "
                                     f"Map again")
        side["dest"], side["dest_name"] = ob, ob.name
    for role, side, other in (("source", src, tgt), ("target", tgt, src)):
        f = stored[role][0]
        if len(f) and (f.min() < 0 or f.max() >= len(other["F"])):
            raise core.ObjectProblem(f"the stored map on '{side['name']}' refers to faces that "
                                     f"'{other['name']}' does not have: run Compute Map again")
    res = {"forward": {"face": stored["source"][0], "barycentric": stored["source"][1]},
           "inverse": {"face": stored["target"][0], "barycentric": stored["target"][1]}}
    i_fw = blender_io.read_initial_correspondence(source.data)
    i_iv = blender_io.read_initial_correspondence(target.data)
    if i_fw is not None and i_iv is not None:
        ok = (i_fw[0].min(initial=0) >= 0 and i_fw[0].max(initial=0) < len(tgt["F"])
              and i_iv[0].min(initial=0) >= 0 and i_iv[0].max(initial=0) < len(src["F"]))
        if ok:  # (otherwise the "before" outputs are left out, the map itself is fine)
            res["initial_forward"] = {"face": i_fw[0], "barycentric": i_fw[1]}
            res["initial_inverse"] = {"face": i_iv[0], "barycentric": i_iv[1]}
    return source, target, src, tgt, res


class _StoredMapOperator:
    bl_options = {'REGISTER', 'UNDO'}
    output = ""

    @classmethod
    def poll(cls, context):
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode")
            return False
        return True

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
            opts = {"morph_space": settings.morph_space,
                    "uv_before": bool(settings.write_uvs_before)}
            out = mapjob.compute_outputs(src, tgt, dict(res, **dist), opts, only={self.output})
            if self.output == "UV" and not out["uv"]:
                raise core.ObjectProblem(f"the source '{source.name}' has no UV map to transfer")
            which = {self.output}
            if self.output == "MORPH" and settings.write_refined:
                which.add("REFINED")
            lines = write_outputs(context, source, target, src, tgt, out, None, which)
        except core.ObjectProblem as e:
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


classes = (SURFMAP_OT_compute_map, SURFMAP_OT_transfer_uvs, SURFMAP_OT_create_morph,
           SURFMAP_OT_paint_distortion)

register, unregister = bpy.utils.register_classes_factory(classes)
