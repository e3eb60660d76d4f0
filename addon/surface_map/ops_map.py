"""surfmap.compute_map (bpy): reads the pair into MeshSides, runs a MapJob (the native solve on
a worker thread, the outputs in timer slices, so Blender keeps drawing), writes the outputs and
the run's summary; surfmap.solve_candidate re-solves with a chosen handle pairing. Everything
that can fail is checked before the first write, so a refusal leaves the scene as it was. The
maths is in map_job.py and the modules it imports; the data flow is in docs/addon.md."""
import json
import math
import time

import bpy
import numpy as np

from . import blender_io, cut_loops, landmarks as landmark_pairs_mod, map_job, uv_transfer
from .map_job import MapJob, MapOptions
from .ops_common import errors_reported, native_and_object_mode, pick_objects, surfmap_module
from .side import MeshSide, ObjectProblem

GENERATED_UV = "surfmap box projection"
OUTPUT_FLAGS = (("write_uvs", "UV"), ("write_morph", "MORPH"), ("write_distortion", "DISTORTION"),
                ("write_refined", "REFINED"))


# --- reading -----------------------------------------------------------------------------------

def read_side(obj, depsgraph, sm=None, flipped=None, allow_boundary=False):
    """One object's mesh as a MeshSide. With sm: validated by the native intake (raises
    ObjectProblem naming the object), else re-oriented like a stored run (`flipped`).
    allow_boundary: accept an open mesh (side.boundary_loops; docs/open_surfaces.md)."""
    d = blender_io.read_map_mesh(obj, depsgraph)
    side = MeshSide.from_mesh_data(obj.name, blender_io.matrix_np(obj.matrix_world), d)
    if len(side.F) == 0:
        raise ObjectProblem(f"object '{obj.name}' has no faces")
    if sm is not None:
        it = cut_loops.intake_object(sm, obj.name, side.V, side.F, allow_boundary)
        if it["F"].shape != side.F.shape:
            raise ObjectProblem(f"object '{obj.name}': the intake changed the number of "
                                f"triangles ({len(side.F)} -> {len(it['F'])})")
        flipped = bool(it["flipped"])
        side.genus = int(it["info"]["genus"])
        side.notes = list(it["info"].get("notes", []))
        side.boundary_loops = [np.asarray(l, dtype=np.int64) for l in it.get("boundary_loops", [])]
    return side.orient(bool(flipped))


_side = read_side   # (the name the stored-map operators used)


def _landmarks(settings, source, target, src_side, tgt_side):
    """(pairs (k,2) or None, description) from the panel's landmark setting."""
    mode = settings.landmark_mode
    if mode == 'NONE':
        return None, ""
    if mode == 'GROUPS':
        prefix = landmark_pairs_mod.LANDMARK_PREFIX
        pick = lambda d: {k: v for k, v in d["vertex_groups"].items() if k.startswith(prefix)}
        pairs, names, problems = landmark_pairs_mod.landmark_pairs(pick(src_side), pick(tgt_side))
        if problems:
            raise ObjectProblem("landmarks: " + "; ".join(problems))
        if len(pairs) == 0:
            raise ObjectProblem(f"landmarks: no vertex groups named '{prefix}...' on both "
                                f"'{source.name}' and '{target.name}'")
        desc = f"{len(pairs)} landmark(s) from vertex groups " + ", ".join(names)
    else:
        lists = []
        for ob, side in ((source, src_side), (target, tgt_side)):
            if side.evaluated and not side.same_topology:
                raise ObjectProblem(f"landmarks: '{ob.name}' has modifiers that change its "
                                    f"vertices, so its selected vertices cannot be used; "
                                    f"use vertex groups named 'lm_...'")
            lists.append(blender_io.selected_vertex_order(ob.data))
        if len(lists[0]) != len(lists[1]) or not lists[0]:
            raise ObjectProblem(f"landmarks: {len(lists[0])} vertices selected on "
                                f"'{source.name}' but {len(lists[1])} on '{target.name}' "
                                f"(select the same number, in matching order)")
        pairs = np.stack([np.asarray(lists[0]), np.asarray(lists[1])], axis=1)
        desc = f"{len(pairs)} landmark(s) from the selected vertices"
    try:
        landmark_pairs_mod.check_landmarks(pairs, len(src_side.V), len(tgt_side.V))
    except ValueError as e:
        raise ObjectProblem(f"landmarks: {e}") from None
    return pairs, desc


def _modifier_note(side):
    if not side.evaluated:
        return None
    if side.same_topology:
        return (f"'{side['name']}': used the mesh with its modifiers applied (same vertices and "
                f"faces as its own mesh, so the outputs are written on it; shape keys act "
                f"before the modifiers)")
    return (f"'{side['name']}': used the mesh with its modifiers applied; they change its "
            f"topology, so the outputs go on a new object holding that mesh")


def prepare_job(context, sm):
    """Reads and checks everything; returns (MapJob, notes). Raises ObjectProblem."""
    settings = context.scene.surfmap
    source, target = pick_objects(context)
    if source is None:
        raise ObjectProblem(f"only '{target.name}' is selected: select two meshes (the "
                            f"source, then the target as the active object)")
    if source.data == target.data:
        raise ObjectProblem(f"'{source.name}' and '{target.name}' share the mesh "
                            f"'{target.data.name}': the map's layers would overwrite each "
                            f"other (Object > Relations > Make Single User first)")
    depsgraph = context.evaluated_depsgraph_get()
    # Open meshes (docs/open_surfaces.md) when this core maps them.
    open_ok = map_job.core_supports(sm, "boundary_pairing")
    src = _side(source, depsgraph, sm, allow_boundary=open_ok)
    tgt = _side(target, depsgraph, sm, allow_boundary=open_ok)
    if src.boundary_loops or tgt.boundary_loops:
        check_open_pair(source.name, src, target.name, tgt, settings.landmark_mode,
                        map_job.core_has_feature(sm, "open_landmarks"))
    elif src.genus != tgt.genus:
        raise ObjectProblem(f"source '{source.name}' has genus {src['genus']} but target "
                            f"'{target.name}' has genus {tgt['genus']}: a map needs equal "
                            f"genus")
    landmarks, lm_desc = _landmarks(settings, source, target, src, tgt)
    outputs = {flag for prop, flag in OUTPUT_FLAGS if getattr(settings, prop)}
    options = MapOptions.from_settings(settings, landmarks, outputs)
    if src.boundary_loops and not getattr(settings, "boundary_pairing_auto", False):
        # open pair with Auto unticked: the panel's boundary loop correspondence
        try:
            options.boundary_pairing = map_job.parse_boundary_pairing(
                getattr(settings, "boundary_pairing", ""))
        except ValueError as e:
            raise ObjectProblem(str(e)) from None
    word = options.unsupported(sm)
    if word is not None:
        raise ObjectProblem(f"this build of the surfmap module does not support {word} yet "
                            f"(rebuild it from a newer checkout)")
    if "UV" in outputs:
        ours = set(target.data.get(blender_io.LAYERS_KEY, [])) if not (
            tgt.evaluated and not tgt.same_topology) else set()
        wanted = [target_uv_name(n) for n in (src.uv_layers or [GENERATED_UV])]
        if settings.write_uvs_before and src.genus >= 1:
            wanted += [before_uv_name(n) for n in (src.uv_layers or [GENERATED_UV])]
        need = sum(1 for n in wanted if f"uv:{n}" not in ours)
        if need > 8 - len(tgt.uv_layers):
            raise ObjectProblem(f"'{target.name}' has {len(tgt['uv_layers'])} UV maps; the "
                                f"{need} transferred ones do not fit (Blender allows 8): "
                                f"remove some, or untick the UVs output")
    notes = [n for n in (_modifier_note(src), _modifier_note(tgt)) if n]
    if "UV" in outputs and not src.uv_layers:
        # nothing to carry over: give the source a cube projection (a new layer) and carry that
        src.uv_layers[GENERATED_UV] = uv_transfer.box_projection(
            src.V, src.loop_vertex, src.loop_start, src.loop_total)
        src.generated_uv = GENERATED_UV
        notes.append(f"'{source.name}' has no UV map: wrote a cube projection '{GENERATED_UV}' "
                     f"on it and transferred that")
    for side in (src, tgt):
        if side.has_ngons:
            notes.append(f"'{side['name']}': polygons with more than 3 sides were triangulated "
                         f"for the solve; the results are written on the original corners")
        notes += [f"'{side['name']}': {n}" for n in side.get("notes", [])]
    if lm_desc:
        notes.append(lm_desc)
    return MapJob(sm, src, tgt, options), notes


def describe_topology(side):
    """'genus 0 with 2 boundary loops' / 'genus 1 (closed)' of a read side."""
    b = len(side.boundary_loops)
    return f"genus {side.genus} " + (f"with {b} boundary loop{'s' if b != 1 else ''}" if b else "(closed)")


def check_open_pair(source_name, src, target_name, tgt, landmark_mode, open_landmarks=False):
    """An open pair: equal genus and number of boundary loops; landmarks only when the core
    holds them on open pairs (`open_landmarks`; its rules, e.g. boundary onto boundary, are
    checked there and come back as a one-line error). Raises ObjectProblem naming both."""
    if (src.genus, len(src.boundary_loops)) != (tgt.genus, len(tgt.boundary_loops)):
        raise ObjectProblem(f"source '{source_name}' has {describe_topology(src)} but target "
                            f"'{target_name}' has {describe_topology(tgt)}: a map needs equal "
                            f"genus and number of boundary loops")
    if landmark_mode != 'NONE' and not open_landmarks:
        raise ObjectProblem(f"landmarks are not supported for open surfaces by this build "
                            f"('{source_name}', '{target_name}'): set Landmarks to None")


def draw_boundary_loops(context, pairs):
    """Open meshes: each boundary loop as a cyclic curve on its object, like the cut loops
    (named '<object> boundary <k>', following the morph's shape keys). pairs: (object, side)."""
    lines = []
    bevel_scale = context.scene.surfmap.loop_bevel
    for ob, side in pairs:
        if not side.boundary_loops or len(side.V) != len(ob.data.vertices):
            continue
        V = np.asarray(side.V, dtype=np.float64)
        curves = [(f"boundary {k + 1}", V[loop]) for k, loop in enumerate(side.boundary_loops)]
        one = np.tile([1.0, 0.0, 0.0], (1, 1))
        weights = [(np.repeat(loop[:, None], 3, axis=1), np.repeat(one, len(loop), axis=0))
                   for loop in side.boundary_loops]
        colours = [cut_loops.pair_colour(2 * k) for k in range(len(curves))]
        bevel = bevel_scale * cut_loops.bounding_diagonal(V)
        blender_io.add_loop_curves(context.scene, ob, curves, bevel, weights, colours)
        lines.append(f"boundary loops of '{ob.name}' drawn as {len(curves)} curve(s)")
    return lines


# --- writing -----------------------------------------------------------------------------------

def _destination(context, obj, side):
    if side.evaluated and not side.same_topology:
        return blender_io.applied_copy(obj, context.evaluated_depsgraph_get(),
                                       f"{obj.name} (surfmap)")
    return obj


def _meta(side, partner, role, res, pairing=None):
    """The map's record on an object. pairing: the chosen pairing's number in the panel's list
    (panel_pairing), which differs from the core's when the run asked for it by its words."""
    m = {"partner": partner["dest_name"], "role": role, "fingerprint": side.fingerprint,
         "partner_fingerprint": partner["fingerprint"], "flipped": int(side.flipped),
         "partner_flipped": int(partner["flipped"]), "evaluated": int(side.evaluated)}
    if res is not None and "genus" in res:
        m.update(genus=int(res["genus"]), energy=float(res["energy"]["final"]),
                 homotopy=int(res["homotopy"]["chosen"] if pairing is None else pairing),
                 mean_dilatation=float(res["distortion"]["mean"]))
    return m


def target_uv_name(source_uv_name):
    """'surfmap <name>' (without doubling the prefix of a layer this add-on made)."""
    return source_uv_name if source_uv_name.startswith("surfmap ") else f"surfmap {source_uv_name}"


def before_uv_name(source_uv_name):
    """'surfmap before <name>': the UVs carried through the initial map."""
    n = source_uv_name[len("surfmap "):] if source_uv_name.startswith("surfmap ") else source_uv_name
    return f"surfmap before {n}"


def write_outputs(context, source, target, src, tgt, out, res, which, pairing=None):
    """Writes the outputs in `which` ({'CORRESPONDENCE','UV','MORPH','DISTORTION'}); returns
    report lines. source/target: the objects; src/tgt: their sides; out: compute_outputs';
    pairing: the chosen pairing's number in the panel's list (panel_pairing), or None for the
    core's."""
    lines = []
    # Checks that could refuse come first (nothing written yet).
    uv_names = ([target_uv_name(n) for n in out["uv"]]
                + [before_uv_name(n) for n in out.get("uv_before", {})]) if "UV" in which else []
    if uv_names:
        room = 8 - len(tgt.uv_layers)
        ours = set(target.data.get(blender_io.LAYERS_KEY, [])) if not (
            tgt.evaluated and not tgt.same_topology) else set()
        need = sum(1 for n in uv_names if f"uv:{n}" not in ours)
        if need > room:
            raise ObjectProblem(f"'{target.name}' has {len(tgt['uv_layers'])} UV maps; "
                                f"{need} more do not fit (Blender allows 8): remove some "
                                f"or untick UVs")
    s_obj = src.dest or _destination(context, source, src)
    t_obj = tgt.dest or _destination(context, target, tgt)
    src.dest, tgt.dest = s_obj, t_obj
    src.dest_name, tgt.dest_name = s_obj.name, t_obj.name
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
        blender_io.write_correspondence(s_obj.data, fw_f, fw_b, _meta(src, tgt, "source", res, pairing),
                                        i_fw if both else None)
        blender_io.write_correspondence(t_obj.data, iv_f, iv_b, _meta(tgt, src, "target", res, pairing),
                                        i_iv if both else None)
        lines.append(f"correspondence stored on '{s_obj.name}' and '{t_obj.name}' (attributes "
                     f"{blender_io.CORR_FACE}, {blender_io.CORR_BARY}"
                     + (f"; the initial map in {blender_io.CORR_FACE_INITIAL}, "
                        f"{blender_io.CORR_BARY_INITIAL}" if both else "") + ")")
    if "UV" in which and out["uv"]:
        written = []
        if src.generated_uv:
            name = src.generated_uv
            blender_io.write_uv_map(s_obj.data, name, src.uv_layers[name])
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
        M = map_job.morph.morph_matrix(tgt.matrix, src.matrix,
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
        for ob, key, raw in ((s_obj, "colours", "raw"), (t_obj, "target_colours", "target_raw")):
            me = ob.data
            names = [blender_io.write_colour(me, name, rgba, domain)
                     for name, (rgba, domain) in out[key].items()]
            for name, values in out.get(raw, {}).items():
                blender_io.write_raw_values(me, name, values, map_job.COLOUR_OUTPUTS[name][2])
            if names and me.color_attributes.get(names[0]) is not None:
                me.color_attributes.active_color = me.color_attributes[names[0]]
            if names:
                lines.append(f"colour attributes on '{ob.name}': " + ", ".join(names))
        settings = context.scene.surfmap
        settings.dilatation_range = out["ranges"]["dilatation"]
        settings.legends.clear()
        for name, (title, scale, _) in map_job.COLOUR_OUTPUTS.items():
            if name in out["ranges"] and name in out["colours"]:
                item = settings.legends.add()
                item.name, item.title, item.scale = name, title, scale
                item["lo"], item["hi"] = out["ranges"][name]   # (no recolouring on the way in)
        settings.legend_pair = f"{s_obj.name}\t{t_obj.name}"
    if src.boundary_loops or tgt.boundary_loops:
        lines += draw_boundary_loops(context, ((s_obj, src), (t_obj, tgt)))
    for o in (s_obj, t_obj):
        o.data.update()
    return lines


# --- compute_map -------------------------------------------------------------------------------

def _ratio_on_own_edges(quality):
    """The core's energy ratio was taken on the source's own-edge weights (Weights: Own Edges),
    not on the intrinsic energy the bound is about (quality.energy_ratio_basis)."""
    return "NOT comparable" in str(quality.get("energy_ratio_basis", ""))


def _summary(res, elapsed):
    e = res["energy"]
    s = (f"genus {res['genus']}, energy {e['initial']:.6g} -> {e['final']:.6g} in "
         f"{res['iterations']} iteration(s), mean D' {res['distortion']['mean']:.4g} (max "
         f"{res['distortion']['max']:.4g}), {res['flipped_triangles']} flipped, {elapsed:.1f}s")
    if isinstance(res.get("open"), dict):
        st = res.get("source_topology", {})
        s += (f", open surfaces ({st.get('description', '')}): {res['open'].get('domain', '')}"
              f", boundary loops {res['open'].get('boundary_pairing', [])}")
        if res['open'].get('orientation'):   # through the doubles: which orientation, pairing how
            s += f" ({res['open']['orientation']}, {res['open'].get('pairing_choice', '')})"
    how = res.get("initial_map", {}).get("construction")
    if how:
        s += f", initial map: {how}"
    if res.get("source_weights") and res.get("genus", 0) >= 2:
        s += f", source weights: {res['source_weights']}"
    if not res.get("converged", True):
        s += " (NOT converged)"
    quality = res.get("quality")
    if isinstance(quality, dict):
        ratio = quality.get("energy_ratio")
        if isinstance(ratio, (int, float)) and ratio == ratio:
            s += f", energy {ratio:.3g}x the conformal bound"
            if _ratio_on_own_edges(quality):
                s += " (own-edge weights' energy: not comparable with the bound)"
        if quality.get("warning"):
            s += f"; {quality['warning']}"
    return s


def summary_rows(res, times):
    """The run's summary as short (label, value) rows for the Result panel. times: wall
    seconds per stage (read, solve, outputs, write)."""
    e, d = res["energy"], res["distortion"]
    rows = [("Energy", f"{e['initial']:.4g} → {e['final']:.4g}"),
            ("Mean D'", f"{d['mean']:.4g}"), ("Max D'", f"{d['max']:.4g}"),
            ("Flipped", str(int(res.get("flipped_triangles", 0))))]
    quality = res.get("quality")
    if isinstance(quality, (int, float)):
        rows.append(("Quality", f"{quality:.4g}"))
    elif isinstance(quality, dict):   # genus >= 2: energy over the conformal bound 8 pi (g - 1)
        ratio = quality.get("energy_ratio")
        if isinstance(ratio, (int, float)) and ratio == ratio:
            rows.append(("E / bound", f"{ratio:.3g}" + (" (own)" if _ratio_on_own_edges(quality)
                                                          else "")))
        if quality.get("warning"):
            rows.append(("Warning", "twisted pairing?"))
    rows.append(("Iterations", f"{res.get('iterations', 0)}"
                 + ("" if res.get("converged", True) else " (not converged)")))
    total = sum(times.values())
    rows.append(("Time", f"{total:.1f} s"))
    for stage in ("read", "solve", "outputs", "write"):
        if stage in times:
            rows.append((f"  {stage}", f"{times[stage]:.1f} s"))
    return rows


def _candidate_energies(item, c):
    """A listed pairing's energies from the report's candidate `c`; its line for the summary."""
    e = float(c.get("energy", math.nan))
    if not math.isfinite(e):
        e = float(c.get("coarse_energy", math.nan))
    item.solved = bool(c.get("solved", True)) and math.isfinite(e)
    item.estimated = not item.solved and math.isfinite(e)
    item.energy = e if math.isfinite(e) else 0.0
    held = float(c.get("landmark_energy", math.nan))
    item.landmark_energy = held
    return (f"E = {e:.6g}" if item.solved else f"E ≈ {e:.6g} (estimated)" if item.estimated
            else "no energy") + (f", with landmarks {held:.6g}" if not math.isnan(held) else "")


def _asked_by_words(settings, res):
    """Whether the run asked for the panel's picked pairing by its words
    (map_job.listed_class_words), so that the core listed that pairing alone as its class 0."""
    cands = res["homotopy"]["candidates"]
    picked = map_job.listed_class_words(settings)
    return picked is not None and len(cands) == 1 and cands[0].get("words") == picked


def panel_pairing(settings, res):
    """The number the run's chosen pairing has in the panel's list after store_candidates: the
    picked one's for a run that asked for it by its words, else the core's."""
    return int(settings.homotopy) if _asked_by_words(settings, res) else int(res["homotopy"]["chosen"])


def store_candidates(settings, res):
    """The handle pairings of a run as the panel's list: the solved energy, or the core's
    estimate (marked estimated) for the pairings it only estimated. A run asked for a listed
    pairing by its words (map_job.listed_class_words) lists that pairing alone: the list stays,
    so that its numbers keep naming the same pairings, and the picked one gets this run's
    energies."""
    cands = res["homotopy"]["candidates"]
    if _asked_by_words(settings, res):
        k = int(settings.homotopy)
        item = next(it for it in settings.candidates if int(it.index) == k)
        settings.chosen_candidate = k
        settings.candidate_index = -1
        return [f"{k}: " + _candidate_energies(item, cands[0])]
    settings.candidates.clear()
    lines = []
    for i, c in enumerate(cands):
        item = settings.candidates.add()
        item.index, item.description = i, str(c.get("description", ""))
        item.words = json.dumps(c.get("words") or [])   # the pairing's name in the next run
        lines.append(f"{i}: " + _candidate_energies(item, c))
    settings.chosen_candidate = int(res["homotopy"]["chosen"])
    settings.candidate_index = -1
    return lines


def is_quit_shortcut(context, event):
    """Whether `event` presses the window's Quit shortcut (the user keymap's wm.quit_blender
    items; Ctrl+Q / Cmd+Q when there is no keymap): Compute Map's modal handler holds every
    other key, and quitting mid-solve must still work (docs/addon.md "The solve's thread")."""
    if getattr(event, "value", None) != 'PRESS':
        return False
    # (hyper: Blender 4.4's modifier; event and keymap item lack it on older versions, and
    # getattr's defaults then compare equal)
    mods = {m: bool(getattr(event, m, False)) for m in ("ctrl", "shift", "alt", "oskey", "hyper")}
    try:
        km = context.window_manager.keyconfigs.user.keymaps.get("Window")
        items = [k for k in km.keymap_items if k.idname == "wm.quit_blender" and k.active] \
            if km is not None else []
    except AttributeError:   # (no window manager or keyconfig: the stand-ins of the tests)
        items = []
    if not items:
        return event.type == 'Q' and (mods["ctrl"] or mods["oskey"]) \
            and not (mods["shift"] or mods["alt"] or mods["hyper"])
    for k in items:
        if k.type != event.type or k.value not in ('PRESS', 'ANY'):
            continue
        # The item's extra key held with it (key_modifier, 'NONE' for none): the event's.
        held = getattr(k, "key_modifier", 'NONE') or 'NONE'
        if held != 'NONE' and held != getattr(event, "type_prev", None):
            continue
        # (a modifier of -1 is "any" in Blender 4; KeyMapItem.any is "any" in 3.x)
        if getattr(k, "any", False) or all(int(getattr(k, m, 0)) == -1
                                          or bool(getattr(k, m, 0)) == mods[m] for m in mods):
            return True
    return False


class SURFMAP_OT_compute_map(bpy.types.Operator):
    """Compute the best map from the selected source onto the active target and write UVs,
    morph shape keys, distortion colours and the correspondence (Esc cancels)"""
    bl_idname = "surfmap.compute_map"
    bl_label = "Compute Map"
    bl_options = {'REGISTER', 'UNDO'}

    _job = None
    _timer = None
    TICK = 0.1        # seconds between the modal timer's ticks
    SLICE = 0.05      # seconds of output work per tick (keeps the UI drawing)
    UI_UPDATE = 1.0   # seconds between visible progress updates (see _show_progress)

    @classmethod
    def poll(cls, context):
        if map_job.ACTIVE.get("job") is not None:
            cls.poll_message_set("A map is being computed")
            return False
        return native_and_object_mode(cls, context)

    def _prepare(self, context):
        self._t_click = time.time()
        sm = surfmap_module(context)
        with errors_reported(self, sm) as r:
            job, notes = prepare_job(context, sm)
        if r.failed:
            return None
        self._notes = notes
        job.times["read"] = time.time() - self._t_click
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
        job.ticks = []
        map_job.ACTIVE["job"] = job
        wm = context.window_manager
        self._timer = wm.event_timer_add(self.TICK, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 100)
        job.start()
        return {'RUNNING_MODAL'}

    def _status(self, context, text):
        # The status bar only: a header text on the 3D view redraws the whole view on every
        # tick (seconds per frame on a software-rendered, busy machine).
        if context.workspace is not None:
            context.workspace.status_text_set(text)
        if text is None and context.area is not None:
            context.area.header_text_set(None)   # (clears one set by an older version)

    def _redraw(self, context, every=0.0):
        """The sidebar's progress bar reads the job: its regions are redrawn (at most every
        `every` seconds: with the sidebar over the view, that redraws the view too)."""
        now = time.time()
        if now - getattr(self, "_t_redraw", 0.0) < every:
            return
        self._t_redraw = now
        screen = getattr(context, "screen", None)
        for area in (screen.areas if screen is not None else ()):
            if area.type == 'VIEW_3D':
                for region in area.regions:
                    if region.type == 'UI':
                        region.tag_redraw()

    def _cleanup(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        self._status(context, None)
        if map_job.ACTIVE.get("job") is self._job:
            map_job.ACTIVE["job"] = None
        self._redraw(context)

    def _show_progress(self, context, job):
        """The progress cursor, the status bar and the sidebar's progress bar, all changed in
        the same tick and at most every UI_UPDATE seconds (Esc's "cancelling" at once): each
        visible change makes Blender composite the window again, ~0.5 s of the main thread
        with software OpenGL on a busy machine, and changes made in one tick share one
        composite (docs/addon.md, "UI ticks during the compute")."""
        now = time.time()
        if job.cancel:
            text = "Surface Map: cancelling..."
        elif now - getattr(self, "_t_shown", 0.0) < self.UI_UPDATE:
            return
        else:
            text = job.status_text()
        self._t_shown = now
        percent = int(100 * job.fraction)
        if percent != getattr(self, "_percent_shown", None):
            context.window_manager.progress_update(percent)
        if text != getattr(self, "_status_shown", None):
            self._status(context, text)
            self._status_shown = text
        if (percent, job.stage) != (getattr(self, "_percent_shown", None),
                                    getattr(self, "_stage_shown", None)):
            self._redraw(context)
        self._percent_shown, self._stage_shown = percent, job.stage

    def modal(self, context, event):
        job = self._job
        if event.type == 'ESC' and event.value == 'PRESS':
            job.cancel = True
        if event.type == 'TIMER':
            t_in = time.time()
            getattr(job, "ticks", []).append(t_in)
            if job.done() and not job.cancel and job.error is None:
                job.step_outputs(self.SLICE)    # no-op: the worker computed the outputs
            self._show_progress(context, job)
            job.tick_work = getattr(job, "tick_work", []) + [(t_in, time.time() - t_in)]
        if job.done() and (job.cancel or job.error is not None or job.outputs is not None
                           or job.result is None):
            self._cleanup(context)
            return self._finish(context, job)
        if event.type in {'MIDDLEMOUSE', 'WHEELUPMOUSE', 'WHEELDOWNMOUSE', 'TRACKPADPAN',
                          'TRACKPADZOOM', 'MOUSEMOVE', 'INBETWEEN_MOUSEMOVE'}:
            return {'PASS_THROUGH'}  # the view can be navigated, nothing edited
        if is_quit_shortcut(context, event):
            return {'PASS_THROUGH'}  # Ctrl+Q quits (map_job.stop_running_jobs stops the job)
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
        source = bpy.data.objects.get(src.name)
        target = bpy.data.objects.get(tgt.name)
        if source is None or target is None:
            self.report({'ERROR'}, "the source or target object was removed during the solve")
            return {'CANCELLED'}
        which = {"CORRESPONDENCE"} | set(job.options.outputs)
        t_write = time.time()
        try:
            lines = write_outputs(context, source, target, src, tgt, out, res, which,
                                  panel_pairing(context.scene.surfmap, res))
        except ObjectProblem as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        settings = context.scene.surfmap
        lines_c = store_candidates(settings, res)
        lines.append(f"handle correspondences (chosen {settings.chosen_candidate}): "
                     + "; ".join(lines_c))
        job.times["write"] = time.time() - t_write
        t_click = getattr(self, "_t_click", job.t0 or time.time())
        job.elapsed = time.time() - t_click      # the wall time the user waited
        summary = f"'{source.name}' -> '{target.name}': " + _summary(res, job.elapsed)
        lm = job.options.landmarks
        lm_line = landmark_pairs_mod.landmark_summary(res, 0 if lm is None else len(lm))
        settings.landmark_status = lm_line or ""
        if lm_line:
            summary += "; " + lm_line
        settings.map_status = "; ".join([summary] + self._notes)
        times = {k: v for k, v in job.times.items()}
        other = job.elapsed - sum(times.values())
        if other > 0.05:   # waiting for timer ticks between the stages
            times["other"] = other
        settings.summary_rows.clear()
        for label, value in summary_rows(res, times):
            row = settings.summary_rows.add()
            row.name, row.value = label, value
        ticks = getattr(job, "ticks", [])
        if len(ticks) > 1:
            gaps = np.diff(ticks)
            settings.max_tick_gap = float(gaps.max())
        for note in self._notes:
            self.report({'WARNING'} if "modifiers" in note else {'INFO'}, note)
        for line in out["report"] + lines:
            self.report({'INFO'}, line)
        self.report({'INFO'}, summary)
        return {'FINISHED'}


class SURFMAP_OT_solve_candidate(bpy.types.Operator):
    """Solve the map again with the handle pairing picked in the list"""
    bl_idname = "surfmap.solve_candidate"
    bl_label = "Solve With This Pairing"
    # No UNDO here: compute_map, which this starts, is the undo step (one Ctrl+Z removes it).
    bl_options = {'REGISTER'}

    index: bpy.props.IntProperty(name="Pairing", default=-1, min=-1,
                                 description="Which pairing (-1: the one picked in the list)")

    @classmethod
    def poll(cls, context):
        settings = context.scene.surfmap
        if not len(settings.candidates):
            cls.poll_message_set("Compute a map first")
            return False
        return SURFMAP_OT_compute_map.poll(context)

    def _pick(self, context):
        settings = context.scene.surfmap
        i = self.index if self.index >= 0 else settings.candidate_index
        if not 0 <= i < len(settings.candidates):
            self.report({'ERROR'}, "pick a pairing in the list first")
            return False
        settings.homotopy = settings.candidates[i].index
        return True

    def _compute(self, context, how):
        """Compute Map for the picked pairing. When it refuses (no mesh selected, two meshes of
        different genus, ...) bpy.ops raises its error as a RuntimeError: reported here as its
        one line (not a Python traceback), and the pairing setting goes back to what it was,
        since nothing was solved."""
        settings = context.scene.surfmap
        before = settings.homotopy
        if not self._pick(context):
            return {'CANCELLED'}
        try:
            return bpy.ops.surfmap.compute_map(how)
        except RuntimeError as e:
            settings.homotopy = before
            lines = [x.strip() for x in str(e).splitlines() if x.strip()]
            line = next((x for x in lines if x.startswith("Error:")), lines[0] if lines else "")
            line = line[len("Error:"):].strip() if line.startswith("Error:") else line
            self.report({'ERROR'}, line or "Compute Map failed")
            return {'CANCELLED'}

    def execute(self, context):
        return self._compute(context, 'EXEC_DEFAULT')

    def invoke(self, context, event):
        r = self._compute(context, 'INVOKE_DEFAULT')
        return {'FINISHED'} if 'RUNNING_MODAL' in r else r


classes = (SURFMAP_OT_compute_map, SURFMAP_OT_solve_candidate)

register, unregister = bpy.utils.register_classes_factory(classes)
