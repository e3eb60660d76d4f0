"""One map computation as plain data (no bpy): the inputs read from the scene, the native solve
(run on a worker thread by the modal operator, or inline in background mode), and every output
computed with numpy (mapping.py), ready for the bpy side to write.

A side (source or target) is a dict as produced by blender_io.read_map_mesh, plus:
  name, F (the intake's triangles: Blender's loop triangles, oriented outward), flipped,
  tri_loops (m,3) re-ordered like F, matrix (4x4 world matrix), uv_layers {name: (L,2)}.
"""
import threading
import time

import numpy as np

from . import mapping

STAGE_NAMES = {
    "target uniformization": "uniformizing the target",
    "source homotopy data and weights": "homotopy data and weights",
    "homotopy candidates": "ranking handle correspondences",
    "harmonic solve": "harmonic map solve",
    "quality": "distortion",
    "forward location": "locating the source on the target",
    "inverse location": "locating the target on the source",
}


class MapJob:
    def __init__(self, sm, source, target, options):
        """options: homotopy (int), landmarks ((k,2) or None), method, tolerance,
        source_weights ('auto' | 'intrinsic' | 'own'), outputs (set of 'UV', 'MORPH',
        'DISTORTION'), uv_before (bool: also the UVs through the initial map), morph_space
        ('IN_PLACE' | 'WORLD')."""
        self.sm = sm
        self.source, self.target = source, target
        self.options = options
        self.stage, self.fraction = "starting", 0.0
        self.energy = None
        self.cancel = False
        self.result = None       # the native dict
        self.outputs = None      # computed outputs (see compute_outputs)
        self.error = None        # (kind, message): 'cancelled' | 'input' | 'solve' | 'internal'
        self.thread = None
        self.t0 = None
        self.elapsed = 0.0

    # -- the solve ----------------------------------------------------------------------------

    def _progress(self, stage, fraction, *extra):
        self.stage = str(stage)
        self.fraction = float(fraction)
        for x in extra:  # newer cores may pass the current energy
            if isinstance(x, (int, float)):
                self.energy = float(x)
                break
        return not self.cancel

    def _solve_progress(self, iteration, energy, gradient):
        """Per iteration of the harmonic solve: the status text shows the energy."""
        self.energy = float(energy)
        return not self.cancel

    def native_kwargs(self):
        o = self.options
        kw = {"homotopy": int(o.get("homotopy", -1))}
        lm = o.get("landmarks")
        if lm is not None and len(lm):
            kw["landmarks"] = np.ascontiguousarray(lm, dtype=np.int32)
        if o.get("method") and o["method"] != "newton":
            kw["method"] = o["method"]
        if o.get("tolerance"):
            kw["tolerance"] = float(o["tolerance"])
        if o.get("source_weights", "auto") != "auto":
            kw["source_weights"] = o["source_weights"]
        if "solve_progress" in getattr(self.sm, "CAPABILITIES", frozenset()):
            kw["solve_progress"] = self._solve_progress
        return kw

    def run(self, with_outputs=True):
        """The native solve and, with `with_outputs`, the outputs; never raises (the error is
        kept in self.error)."""
        self.t0 = time.time()
        self._guarded(self._solve)
        if with_outputs:
            self.compute_outputs()
        self.elapsed = time.time() - self.t0

    def compute_outputs(self):
        """The numpy outputs of a finished solve. The modal operator calls this on Blender's
        main thread: Blender releases the GIL inside bpy.ops calls, so Python running on the
        worker thread meanwhile is not safe (a numpy call there crashed under a screenshot
        operator); the worker runs only the native solve, which holds no Python state."""
        if self.error is None and self.result is not None and self.outputs is None:
            self._guarded(self._outputs)

    def _solve(self):
        kw = self.native_kwargs()   # prepare_job checked the core accepts them
        self.result = self.sm.surface_map(
            self.source["V"], self.source["F"], self.target["V"], self.target["F"],
            progress=self._progress, **kw)
        if self.cancel:
            raise self.sm.Cancelled("cancelled")

    def _outputs(self):
        self.stage, self.fraction = "writing outputs", 1.0
        self.outputs = compute_outputs(self.source, self.target, self.result, self.options)
        if self.cancel:
            self.outputs = None
            raise self.sm.Cancelled("cancelled")

    def _guarded(self, step):
        sm = self.sm
        try:
            step()
        except sm.Cancelled:
            self.error = ("cancelled", "cancelled")
        except sm.InputError as e:
            self.error = ("input", str(e))
        except sm.SolveError as e:
            self.error = ("solve", f"the map solve failed: {e}")
        except sm.Error as e:
            self.error = ("solve", f"surfmap: {e}")
        except Exception as e:  # a bug on our side: report it rather than crash Blender
            import traceback
            traceback.print_exc()
            self.error = ("internal", f"{type(e).__name__}: {e}")

    def start(self):
        """The native solve on a worker thread (outputs: compute_outputs on the main thread)."""
        self.thread = threading.Thread(target=self.run, kwargs={"with_outputs": False},
                                       name="surfmap solve", daemon=True)
        self.thread.start()

    def done(self):
        return self.thread is None or not self.thread.is_alive()

    def status_text(self):
        stage = STAGE_NAMES.get(self.stage, self.stage)
        s = f"Surface Map: {stage} ({100 * self.fraction:.0f}%)"
        if self.energy is not None:
            s += f", energy {self.energy:.6g}"
        if self.t0 is not None:
            s += f", {time.time() - self.t0:.1f}s"
        return s + " — Esc to cancel"


# --- outputs -----------------------------------------------------------------------------------

def morph_matrix(from_matrix, to_matrix, space):
    """4x4 taking the other object's local coordinates into this object's local coordinates.
    'WORLD': onto the other object where it stands; 'IN_PLACE': the other object's shape
    (rotation and scale included) placed at this object's origin, so the morph stays in place."""
    A = np.asarray(from_matrix, dtype=np.float64)   # the other object's world matrix
    B = np.asarray(to_matrix, dtype=np.float64)     # this object's world matrix
    shift = np.eye(4)
    if space == "IN_PLACE":
        shift[:3, 3] = B[:3, 3] - A[:3, 3]
    return np.linalg.inv(B) @ shift @ A


def corner_uvs(side, loop_uv):
    """(m,3,2) UV of every triangle corner, in the order of the side's triangles F."""
    return np.asarray(loop_uv, dtype=np.float64)[side["tri_loops"]]


def distortion_colours(values_per_polygon, lo, hi, loop_total):
    """CORNER-domain colours of a per-polygon value (each corner takes its polygon's)."""
    rgba = mapping.colour_scale(values_per_polygon, lo, hi, mapping.SEQUENTIAL)
    return np.repeat(rgba, np.asarray(loop_total, dtype=np.int64), axis=0)


def compute_outputs(source, target, res, options, only=None):
    """Everything the bpy side writes, from the native result `res` (or from a stored
    correspondence: res then holds only 'forward' and 'inverse' {'face','barycentric'}).

    Returns dict with: forward/inverse (face, bary); morph_source (n_s,3) / morph_target (n_t,3)
    local coordinates for the shape keys (and morph_source_initial, the initial map's, when the
    result has a located initial map); uv {name: (L_t,2)} and uv_report, uv_before {name:
    (L_t,2)} through the initial map (options uv_before, when res has 'initial_inverse'); colours
    {name: (rgba, domain)}; dilatation per polygon (final, initial or None); ranges and the
    report lines."""
    outputs = set(options.get("outputs", {"UV", "MORPH", "DISTORTION"})) if only is None else only
    Vs, Fs, Vt, Ft = source["V"], source["F"], target["V"], target["F"]
    fw_f = np.asarray(res["forward"]["face"], dtype=np.int64)
    fw_b = np.asarray(res["forward"]["barycentric"], dtype=np.float64)
    iv_f = np.asarray(res["inverse"]["face"], dtype=np.int64)
    iv_b = np.asarray(res["inverse"]["barycentric"], dtype=np.float64)
    out = {"forward": (fw_f, fw_b), "inverse": (iv_f, iv_b), "colours": {}, "uv": {},
           "uv_before": {}, "report": [], "ranges": {}}
    for key in ("initial_forward", "initial_inverse"):
        init = res.get(key)
        out[key] = None if init is None else (np.asarray(init["face"], dtype=np.int64),
                                              np.asarray(init["barycentric"], dtype=np.float64))
    pos_s = mapping.points_at(Vt, Ft, fw_f, fw_b)   # source vertices on the target (target local)
    pos_t = mapping.points_at(Vs, Fs, iv_f, iv_b)   # target vertices on the source (source local)
    out["image_of_source"] = pos_s
    space = options.get("morph_space", "IN_PLACE")
    if "MORPH" in outputs:
        out["morph_source"] = mapping.apply_matrix(
            morph_matrix(target["matrix"], source["matrix"], space), pos_s)
        out["morph_target"] = mapping.apply_matrix(
            morph_matrix(source["matrix"], target["matrix"], space), pos_t)
        # The "before" morph: the initial map located on the target (genus >= 1).
        if out["initial_forward"] is not None:
            pos0 = mapping.points_at(Vt, Ft, *out["initial_forward"])
            out["morph_source_initial"] = mapping.apply_matrix(
                morph_matrix(target["matrix"], source["matrix"], space), pos0)
    if "UV" in outputs:
        lv = target["loop_vertex"]
        total_straddling, names = 0, []
        for name, loop_uv in source["uv_layers"].items():
            tr = mapping.UVTransfer(Fs, corner_uvs(source, loop_uv), Vs)
            uv, straddling = tr.polygon_uvs(iv_f[lv], iv_b[lv], target["loop_start"],
                                            target["loop_total"])
            out["uv"][name] = uv
            total_straddling += int(straddling.sum())
            names.append(name)
            if tr.unresolved:
                out["report"].append(f"UV map '{name}': {tr.unresolved} corners kept their own "
                                     f"island's UV (no short path across the seam)")
            if options.get("uv_before") and out["initial_inverse"] is not None:
                # The same transfer through the initial map (the "before" figure); where the
                # initial map folds, a target vertex takes one of the covering source faces.
                i0_f, i0_b = out["initial_inverse"]
                out["uv_before"][name], _ = tr.polygon_uvs(i0_f[lv], i0_b[lv],
                                                           target["loop_start"],
                                                           target["loop_total"])
        if names:
            out["report"].append(f"UVs: {len(names)} map(s) transferred ({', '.join(names)}); "
                                 f"{total_straddling} target faces across source seams were "
                                 f"unfolded into one chart")
            if out["uv_before"]:
                out["report"].append(f"UVs through the initial map ('before'): "
                                     f"{len(out['uv_before'])} map(s)")
            elif options.get("uv_before"):
                out["report"].append("UVs through the initial map: none (no initial map "
                                     "located for this pair, e.g. genus 0, or not stored)")
        else:
            out["report"].append(f"UVs: the source '{source['name']}' has no UV map to transfer")
    if "DISTORTION" in outputs:
        tri_poly, npoly = source["tri_polygon"], source["num_polygons"]
        areas = mapping.face_areas(Vs, Fs)
        dist = res.get("distortion", {})
        if "dilatation_per_polygon" in res:
            Dp = np.asarray(res["dilatation_per_polygon"], dtype=np.float64)
            D = Dp[np.asarray(tri_poly, dtype=np.int64)]
        else:
            if "per_face" in dist:
                D = np.asarray(dist["per_face"], dtype=np.float64)
            else:  # from a stored correspondence: D' of the triangles of the image points
                nrm = mapping.face_normals(Vt, Ft)[fw_f[Fs[:, 0]]]
                D, _ = mapping.dilatation(Vs, Fs, pos_s, nrm)
            Dp = mapping.per_polygon(D, tri_poly, npoly, areas)
        Dp_init = res.get("initial_dilatation_per_polygon")
        D_init = res.get("initial_distortion", {}).get("per_face")
        if D_init is not None and len(D_init) != len(Fs):
            D_init = None  # not measured for this genus by this core
        if Dp_init is None and D_init is not None:
            Dp_init = mapping.per_polygon(np.asarray(D_init, dtype=np.float64), tri_poly, npoly,
                                          areas)
        both = Dp if Dp_init is None else np.concatenate([Dp, Dp_init])
        lo, hi = mapping.robust_range(both, hi_q=0.99, floor=1.0)
        out["dilatation"] = Dp
        out["dilatation_initial"] = Dp_init
        out["colours"]["surfmap dilatation"] = (
            distortion_colours(Dp, lo, hi, source["loop_total"]), 'CORNER')
        if Dp_init is not None:
            out["colours"]["surfmap dilatation initial"] = (
                distortion_colours(Dp_init, lo, hi, source["loop_total"]), 'CORNER')
        out["ranges"]["dilatation"] = (lo, hi)
        fm = np.isfinite(D)
        mean = float(np.sum(areas[fm] * D[fm]) / max(float(areas[fm].sum()), 1e-300))
        worst = float(D[fm].max()) if fm.any() else float("inf")
        msg = (f"dilatation D' colours: {lo:.3g} (dark violet) to {hi:.3g} (yellow), magenta = "
               f"flipped; mean {mean:.4g}, max {worst:.4g}")
        out["report"].append(msg)
        lam = np.log2(mapping.conformal_factor(Vs, Fs, pos_s))
        l_lo, l_hi = mapping.symmetric_range(lam)
        out["colours"]["surfmap conformal factor"] = (
            mapping.colour_scale(lam, l_lo, l_hi, mapping.DIVERGING), 'POINT')
        out["ranges"]["conformal"] = (l_lo, l_hi)
        out["report"].append(f"conformal factor colours: log2 λ from {l_lo:.3g} (blue, area "
                             f"shrinks) to {l_hi:.3g} (red, area grows)")
        dH = mapping.mean_curvature_difference(Vs, Fs, Vt, Ft, fw_f, fw_b)
        h_lo, h_hi = mapping.symmetric_range(dH)
        out["colours"]["surfmap mean curvature difference"] = (
            mapping.colour_scale(dH, h_lo, h_hi, mapping.DIVERGING), 'POINT')
        out["ranges"]["curvature"] = (h_lo, h_hi)
        out["report"].append(f"mean-curvature difference colours (H·sqrt(A/4π), source − "
                             f"target): {h_lo:.3g} (blue) to {h_hi:.3g} (red)")
    return out
