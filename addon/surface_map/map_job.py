"""One map computation as plain data (no bpy): the options as the core spells them, the native
solve and every output computed with numpy (on a worker thread in the UI, a closed pair's solve
on the core's own niced thread, which runs no Python; inline in background mode; in slices, so
progress and Esc are seen between them), ready for the bpy side
(ops_map.write_outputs) to write. Data flow: docs/addon.md.
"""
import atexit
from dataclasses import dataclass, field
import json
import os
import sys
import threading
import time
from typing import Optional, Set

import numpy as np

from . import colours, distortion, geometry, morph, uv_transfer
from .side import MeshSide  # noqa: F401  (the type of job.source / job.target)

STAGE_NAMES = {
    "target uniformization": "Uniformizing target",
    "source homotopy data and weights": "Source weights",
    "homotopy candidates": "Ranking handle pairings",
    "harmonic solve": "Harmonic solve",
    "quality": "Measuring distortion",
    "forward location": "Locating source on target",
    "inverse location": "Locating target on source",
    "landmarks": "Holding landmarks",
    "done": "Map made",
    "retry with the short generators": "Retry, short generators",   # (fits the sidebar)
    "retry at another base vertex": "Retry, another vertex",        # (fits the sidebar)
}


def _stage_name(stage):
    return STAGE_NAMES.get(stage, stage[:1].upper() + stage[1:])


# The prefixes of the stages that name a run and the stage inside it, '<run> (<stage>)': the
# core's runs after the main one and its retries, and an open pair's candidates (open_double).
CORE_RUNS = ("other runs", "retry ")
RUN_PREFIXES = CORE_RUNS + ("doubles:",)


def _stage_parts(stage):
    """[the innermost stage, then the runs around it from the inside out]: 'doubles: pairing
    [0], preserving (other runs (landmarks))' -> ['landmarks', 'other runs', 'doubles: pairing
    [0], preserving']; a stage that names no run -> [stage]."""
    runs = []
    while stage.startswith(RUN_PREFIXES) and stage.endswith(")") and " (" in stage:
        run, _, inner = stage.partition(" (")
        runs.append(run)
        stage = inner[:-1]
    return [stage] + runs[::-1]


# The solve's share of the progress bar; the outputs take the rest.
SOLVE_SHARE = 0.85

# Panel value -> the core's spelling, in one place.
METHODS = {"NEWTON": "newton", "RELAXATION": "relaxation"}
SOURCE_WEIGHTS = {"AUTO": "auto", "INTRINSIC": "intrinsic", "OWN": "own"}


def _module_attribute(sm, name):
    """The native module's attribute `name`, on the package or its _core; None when absent."""
    value = getattr(sm, name, None)
    return value if value is not None else getattr(getattr(sm, "_core", None), name, None)


def core_has_feature(sm, name):
    """Whether the native module names `name` in its FEATURES (what it does beyond its
    keywords, e.g. "open_landmarks"); False for builds without the attribute."""
    return name in (_module_attribute(sm, "FEATURES") or ())


def core_supports(sm, word):
    """Whether the native module takes the surface_map keyword `word`: from its explicit
    CAPABILITIES attribute when it has one (a set/list of names or a dict of flags, on the
    package or its _core), else from the function's docstring (older builds)."""
    caps = _module_attribute(sm, "CAPABILITIES")
    if caps is not None:
        try:
            if isinstance(caps, dict):
                if word in caps:
                    return bool(caps[word])
                return any(isinstance(v, (set, list, tuple, frozenset)) and word in v
                           for v in caps.values())
            return word in caps
        except TypeError:
            pass
    return word in (getattr(getattr(sm, "surface_map", None), "__doc__", None) or "")


def parse_boundary_pairing(text):
    """The panel's Boundary Loops text ('1 0', '1,0'; empty: None) as a list of loop indices;
    raises ValueError naming the text."""
    words = str(text or "").replace(",", " ").split()
    if not words:
        return None
    try:
        return [int(w) for w in words]
    except ValueError:
        raise ValueError(f"Boundary Loops '{text}': give loop indices such as '1 0'") from None


def listed_class_words(settings):
    """The words of the pairing `settings.homotopy` names in the last run's list (the panel's
    candidates, each with its words as JSON), or None: automatic, not listed, or genus 1 (a
    torus's pairings have no words)."""
    k = int(getattr(settings, "homotopy", -1))
    for item in getattr(settings, "candidates", ()):
        if int(item.index) == k and getattr(item, "words", ""):
            words = json.loads(item.words)
            return words or None
    return None


@dataclass
class MapOptions:
    """What the panel asks for, already in the core's spelling (see from_settings)."""
    homotopy: int = -1
    # Genus >= 2: the picked pairing by its words (the core's class_words), which name it in
    # the next run too; `homotopy` is an index into the last run's list, which the next run
    # (other options, landmarks) may order otherwise (docs/handle_classes.md "Classes named by words").
    class_words: Optional[list] = None
    landmarks: Optional[np.ndarray] = None   # (k,2) source vertex, target vertex
    method: str = "newton"
    tolerance: float = 0.0                   # 0: the core's default
    source_weights: str = "auto"
    outputs: Set[str] = field(default_factory=lambda: {"UV", "MORPH", "DISTORTION"})
    uv_before: bool = False
    morph_space: str = "IN_PLACE"
    colour_percentile: float = 99.0
    boundary_pairing: Optional[list] = None  # open meshes: target loop of each source loop

    @classmethod
    def from_settings(cls, settings, landmarks=None, outputs=None):
        """From the scene's PropertyGroup (any object with its attribute names)."""
        return cls(homotopy=int(settings.homotopy), class_words=listed_class_words(settings),
                   landmarks=landmarks,
                   method=METHODS.get(settings.method, str(settings.method).lower()),
                   tolerance=float(settings.tolerance),
                   source_weights=SOURCE_WEIGHTS.get(settings.source_weights,
                                                     str(settings.source_weights).lower()),
                   outputs=set(outputs) if outputs is not None else {"UV", "MORPH",
                                                                     "DISTORTION"},
                   uv_before=bool(settings.write_uvs_before),
                   morph_space=str(settings.morph_space),
                   colour_percentile=float(getattr(settings, "colour_percentile", 99.0)))

    def native_kwargs(self):
        """The surface_map keywords that differ from the core's defaults."""
        kw = {"homotopy": int(self.homotopy)}
        if self.class_words:
            kw = {"homotopy": -1, "class_words": [list(map(int, w)) for w in self.class_words]}
        if self.landmarks is not None and len(self.landmarks):
            kw["landmarks"] = np.ascontiguousarray(self.landmarks, dtype=np.int32)
        if self.method != "newton":
            kw["method"] = self.method
        if self.tolerance:
            kw["tolerance"] = float(self.tolerance)
        if self.source_weights != "auto":
            kw["source_weights"] = self.source_weights
        if self.boundary_pairing is not None:
            kw["boundary_pairing"] = list(self.boundary_pairing)
        return kw

    def unsupported(self, sm):
        """The first option this native module does not take, or None."""
        for word in self.native_kwargs():
            if word not in ("homotopy", "class_words") and not core_supports(sm, word):
                return word
        return None

    # Read access by key, for code written against the earlier dict form of the options.
    def __getitem__(self, key):
        return getattr(self, key)

    def get(self, key, default=None):
        return getattr(self, key, default)


class MapJob:
    def __init__(self, sm, source, target, options):
        """source, target: MeshSide; options: MapOptions."""
        self.sm = sm
        self.source, self.target = source, target
        self.options = options
        self.stage, self.fraction = "starting", 0.0
        self.energy = None
        self.cancel = False
        self.result = None       # the native dict
        self.outputs = None      # computed outputs (see OutputComputation)
        self.error = None        # (kind, message): 'cancelled' | 'input' | 'solve' | 'internal'
        self.thread = None
        self.t0 = None
        self.elapsed = 0.0
        self.times = {}          # wall seconds per stage: solve, outputs (+ write, by the op)
        self._slices = None
        self.niceness = 0        # how much lower the solve thread's priority was set
        self.solve_job = None    # the core's job (surfmap.MapJob) of a closed pair

    # -- the solve ----------------------------------------------------------------------------

    def _progress(self, stage, fraction, *extra):
        self.stage = str(stage)
        self.fraction = SOLVE_SHARE * float(fraction)
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
        kw = self.options.native_kwargs()
        if "class_words" in kw and not core_supports(self.sm, "class_words"):
            kw.pop("class_words")   # an older core: the pairing by its index in the last run's list
            kw["homotopy"] = int(self.options.homotopy)
        if core_supports(self.sm, "solve_progress"):
            kw["solve_progress"] = self._solve_progress
        # The "before" morph and UVs, also from the stored correspondence later: the core
        # locates the initial map only on request (an output, no figure depends on it).
        if core_supports(self.sm, "locate_initial_map"):
            kw["locate_initial_map"] = True
        return kw

    def run(self, with_outputs=True):
        """The native solve and, with `with_outputs`, the outputs; never raises (the error is
        kept in self.error)."""
        if self.t0 is None:
            self.t0 = time.time()
        self._guarded(self._solve)
        if with_outputs:
            self.compute_outputs()
        self.elapsed = time.time() - self.t0

    def compute_outputs(self):
        """All the numpy outputs of a finished solve at once."""
        while self.step_outputs(budget=None):
            pass

    def step_outputs(self, budget=0.05):
        """Runs output slices for about `budget` seconds (None: to the end) on the calling
        thread (the worker thread in the UI, see start). Returns True while slices remain."""
        if self.error is not None or self.result is None or self.outputs is not None:
            return False
        if self._slices is None:
            self._t_outputs = time.time()
            self._slices = OutputComputation(self.source, self.target, self.result,
                                             self.options)
        t = time.time()
        while True:
            more = self._guarded(self._slices.step)
            if self.error is not None:
                return False
            self.stage = self._slices.stage
            self.fraction = SOLVE_SHARE + (1 - SOLVE_SHARE) * self._slices.fraction
            if self.cancel:
                self.error = ("cancelled", "cancelled")
                return False
            if not more:
                self.outputs = self._slices.out
                self.stage, self.fraction = "writing outputs", 1.0
                self.times["outputs"] = time.time() - self._t_outputs
                return False
            if budget is not None and time.time() - t > budget:
                return True

    def _solve(self):
        t = time.time()
        kw = self.native_kwargs()   # prepare_job checked the core accepts them

        # The core's default target metric (the flip-based one, docs/uniformization.md "Which
        # target metric runs"): every output reads the map only at the per-vertex images
        # (forward: source vertices on the target's faces, inverse: target vertices on the
        # source's), which it delivers on the user's own faces for either metric
        # (docs/addon.md "Outputs on the flip-based metric").
        self.result = self.sm.surface_map(self.source.V, self.source.F, self.target.V,
                                          self.target.F, progress=self._progress, **kw)
        self.times["solve"] = time.time() - t
        if self.cancel:
            raise self.sm.Cancelled("cancelled")

    def _guarded(self, step):
        sm = self.sm
        try:
            return step()
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
        return None

    # While the worker runs Python (the output slices), every Python call of Blender's main
    # thread (timers, each line of a panel's draw) waits for the GIL up to the interpreter's
    # switch interval (5 ms by default): a sidebar redraw of a few hundred calls then takes
    # over a second. A short interval during the job keeps the UI's Python responsive.
    SWITCH_INTERVAL = 0.0005

    # The solve's thread (and the core's threads, which inherit it) runs this much nicer than
    # Blender's main thread, so drawing (software OpenGL's rasterizer threads too) gets the
    # CPU first when the machine is busy; the solve takes what remains (docs/addon.md, "UI
    # ticks during the compute"). Only a thread that never runs Python is niced: the core's
    # own (surfmap.start_surface_map), never a Python thread (docs/addon.md "The solve's thread").
    WORKER_NICENESS = 10

    # Seconds between two reads of the native job's progress (and of Esc) by the worker.
    POLL = 0.05

    def native_job_possible(self):
        """Whether the solve can run on the core's own thread (surfmap.start_surface_map): a
        closed pair and a core that offers it. Open pairs run their driver's Python, on the
        worker thread at Blender's priority (docs/addon.md "The solve's thread")."""
        return (not (self.source.boundary_loops or self.target.boundary_loops)
                and _module_attribute(self.sm, "start_surface_map") is not None)

    def _take_progress(self, p):
        self._progress(p["stage"], p["fraction"])
        if p.get("energy") is not None:
            self.energy = float(p["energy"])

    def _take_final_energy(self):
        """The status text's energy once the map is made: the result's final energy. The solve
        reports the energy of its Newton iterations, and the runs after the main one report
        none, so the text kept the first class's energy while the outputs were written, also
        when the map returned is another class's (40.44 shown for a map of 27.18, double torus
        -> genus-2 block, seen under Xvfb)."""
        energy = self.result.get("energy") if isinstance(self.result, dict) else None
        final = energy.get("final") if isinstance(energy, dict) else None
        if final is not None:
            self.energy = float(final)

    def _solve_in_native_job(self):
        """The solve on the core's thread, which lowers its own priority and never takes the
        GIL: this (worker, not niced) thread converts the arguments, polls the progress, passes
        Esc on and converts the result; a niced thread asking for the GIL would stall Blender's
        main thread until the scheduler ran it (seconds under load)."""
        t = time.time()
        kw = self.native_kwargs()   # prepare_job checked the core accepts them
        kw.pop("solve_progress", None)   # the job's progress() carries the solve's energy
        start = _module_attribute(self.sm, "start_surface_map")
        job = self.solve_job = start(self.source.V, self.source.F, self.target.V,
                                     self.target.F, niceness=self.WORKER_NICENESS, **kw)
        try:
            # time.sleep, not job.wait: a daemon thread that Python's exit finds inside a
            # native call that released the GIL is ended (pthread_exit) in that call's C++
            # frame, which aborts the process ("terminate called without an active
            # exception"); time.sleep's frame is C. stop_running_jobs joins the worker first.
            while not job.done():
                time.sleep(self.POLL)
                self._take_progress(job.progress())
                if not self.niceness:
                    self.niceness = job.niceness
                if self.cancel:
                    job.cancel()
            self.niceness = job.niceness
            self._take_progress(job.progress())
            self.result = job.result()
        finally:
            if not job.done():   # (an error of ours while polling: stop the solve)
                job.cancel()
        self.times["solve"] = time.time() - t
        if self.cancel:
            raise self.sm.Cancelled("cancelled")

    def _run_threaded(self):
        """The solve, then the outputs, on this worker thread at Blender's priority: the
        outputs run Python holding the GIL, and a niced thread preempted while holding it (or
        asking for it) would make the main thread wait (a priority inversion: pauses of 0.5 s
        at load 23, of 7.9 s in a loaded CI, in test_map's tick test). The closed solve itself
        runs on the core's niced thread (_solve_in_native_job)."""
        before = sys.getswitchinterval()
        sys.setswitchinterval(min(before, self.SWITCH_INTERVAL))
        RUNNING.add(self)
        try:
            if self.t0 is None:
                self.t0 = time.time()
            self._guarded(self._solve_in_native_job if self.native_job_possible()
                          else self._solve)
            self._take_final_energy()
            self.compute_outputs()
            self.elapsed = time.time() - self.t0
        finally:
            sys.setswitchinterval(before)
            RUNNING.discard(self)

    def start(self):
        """The native solve AND the numpy outputs on a worker thread, so Blender's main thread
        only ticks the timer and then writes (docs/addon.md). Safe: the worker touches no bpy
        data (MeshSide and the result are plain arrays), and Blender releases Python's GIL
        while it draws; numpy's large array operations release it too."""
        self.t0 = time.time()
        self.thread = threading.Thread(target=self._run_threaded, name="surfmap solve",
                                       daemon=True)
        # Registered here, on the main thread, not only by the worker once it runs: a quit
        # before the new thread was first scheduled (a loaded machine) would otherwise find it
        # unregistered, and Python's exit could end it inside a native call (stop_running_jobs).
        RUNNING.add(self)
        self.thread.start()

    def done(self):
        return self.thread is None or not self.thread.is_alive()

    def stage_text(self, short=False):
        """The stage as the status bar (and, `short`, the sidebar) shows it. Some stages name
        the run they belong to, '<run> (<stage>)', and nest: an open pair's driver names a
        closed solve inside a candidate '<candidate> (<closed stage>)' (open_double), and the
        core names the runs after the main one (the other direction, the through-shape step)
        'other runs (<stage>)' and its automatic retries 'retry after folds (<stage>)',
        'retry with the short generators (<stage>)' and 'retry at another base vertex
        (<stage>)'. The innermost stage comes first, then the runs from the inside out, joined
        by ' · ', and it comes alone when `short` (the sidebar's 229 px label clips long text in
        its middle)."""
        parts = _stage_parts(self.stage)
        return _stage_name(parts[0]) if short else " · ".join(_stage_name(p) for p in parts)

    def run_text(self):
        """The sidebar's line under the stage: the core's run the stage belongs to, the
        innermost of its runs after the main one and its retries ('Other runs', 'Retry after
        folds', 'Retry, short generators', 'Retry, another vertex'); "" in the main run. Without it the other runs'
        stages read as the main run's started over at the same percentage. (An open pair's
        candidate is named in the status bar only: wider than the sidebar.)"""
        runs = [p for p in _stage_parts(self.stage)[1:] if p.startswith(CORE_RUNS)]
        return _stage_name(runs[0]) if runs else ""

    def status_text(self):
        s = f"Surface Map: {self.stage_text()} ({100 * self.fraction:.0f}%)"
        if self.energy is not None:
            s += f", energy {self.energy:.6g}"
        if self.t0 is not None:   # whole seconds: the text (a status bar redraw) changes at
            s += f", {time.time() - self.t0:.0f}s"   # most once a second from the clock
        return s + " — Esc to cancel"


# --- outputs -----------------------------------------------------------------------------------

def corner_uvs(side, loop_uv):
    """(m,3,2) UV of every triangle corner, in the order of the side's triangles F."""
    return np.asarray(loop_uv, dtype=np.float64)[side["tri_loops"]]


def distortion_colours(values_per_polygon, lo, hi, loop_total):
    """CORNER-domain colours of a per-polygon value (each corner takes its polygon's)."""
    rgba = colours.colour_scale(values_per_polygon, lo, hi, colours.SEQUENTIAL)
    return np.repeat(rgba, np.asarray(loop_total, dtype=np.int64), axis=0)


# The colour outputs: attribute name -> (legend title, scale, domain of the raw values).
DILATATION_COLOURS = "surfmap dilatation"
DILATATION_INITIAL_COLOURS = "surfmap dilatation initial"
CONFORMAL_COLOURS = "surfmap conformal factor"
CURVATURE_COLOURS = "surfmap mean curvature difference"
COLOUR_OUTPUTS = {
    DILATATION_COLOURS: ("D' (dilatation)", "SEQUENTIAL", 'FACE'),
    DILATATION_INITIAL_COLOURS: ("D' initial map", "SEQUENTIAL", 'FACE'),
    CONFORMAL_COLOURS: ("log2 area ratio", "DIVERGING", 'POINT'),
    CURVATURE_COLOURS: ("mean curv. diff.", "DIVERGING", 'POINT'),
}


def colours_of(name, values, lo, hi, loop_total):
    """The colour attribute data of one output from its raw values: (rgba, domain)."""
    title, scale, domain = COLOUR_OUTPUTS[name]
    if domain == 'FACE':
        return distortion_colours(values, lo, hi, loop_total), 'CORNER'
    return colours.colour_scale(values, lo, hi, colours.STOPS[scale]), 'POINT'


class OutputComputation:
    """compute_outputs in slices: step() runs one slice and returns True while more remain;
    `stage` / `fraction` say where it is, `out` holds the result (see compute_outputs)."""

    def __init__(self, source, target, res, options, only=None):
        self.source, self.target, self.res, self.options = source, target, res, options
        self.outputs = set(options.get("outputs", {"UV", "MORPH", "DISTORTION"})) \
            if only is None else set(only)
        self.stage, self.fraction = "locating points", 0.0
        self.out = None
        self._plan = self._slices()
        self._total = 2 + len(source["uv_layers"]) * ("UV" in self.outputs) \
            + 3 * ("DISTORTION" in self.outputs)
        self._done = 0
        self.slice_times = []   # (stage before the slice, seconds): the UI pauses this long

    def step(self):
        t = time.time()
        stage = self.stage
        try:
            self.stage = next(self._plan)
        except StopIteration:
            self.fraction = 1.0
            return False
        finally:
            self.slice_times.append((stage, time.time() - t))
        self.fraction = min(self._done / max(self._total, 1), 1.0)
        return True

    def _slices(self):
        source, target, res, options = self.source, self.target, self.res, self.options
        outputs = self.outputs
        Vs, Fs, Vt, Ft = source["V"], source["F"], target["V"], target["F"]
        fw_f = np.asarray(res["forward"]["face"], dtype=np.int64)
        fw_b = np.asarray(res["forward"]["barycentric"], dtype=np.float64)
        iv_f = np.asarray(res["inverse"]["face"], dtype=np.int64)
        iv_b = np.asarray(res["inverse"]["barycentric"], dtype=np.float64)
        out = {"forward": (fw_f, fw_b), "inverse": (iv_f, iv_b), "colours": {},
               "target_colours": {}, "raw": {}, "target_raw": {}, "uv": {}, "uv_before": {},
               "report": [], "ranges": {}}
        for key in ("initial_forward", "initial_inverse"):
            init = res.get(key)
            out[key] = None if init is None else (np.asarray(init["face"], dtype=np.int64),
                                                  np.asarray(init["barycentric"],
                                                             dtype=np.float64))
        pos_s = geometry.points_at(Vt, Ft, fw_f, fw_b)   # source vertices on the target
        pos_t = geometry.points_at(Vs, Fs, iv_f, iv_b)   # target vertices on the source
        out["image_of_source"] = pos_s
        space = options.get("morph_space", "IN_PLACE")
        if "MORPH" in outputs:
            out["morph_source"] = geometry.apply_matrix(
                morph.morph_matrix(target["matrix"], source["matrix"], space), pos_s)
            out["morph_target"] = geometry.apply_matrix(
                morph.morph_matrix(source["matrix"], target["matrix"], space), pos_t)
            # The "before" morph: the initial map located on the target (genus >= 1).
            if out["initial_forward"] is not None:
                pos0 = geometry.points_at(Vt, Ft, *out["initial_forward"])
                out["morph_source_initial"] = geometry.apply_matrix(
                    morph.morph_matrix(target["matrix"], source["matrix"], space), pos0)
        self._done += 1
        yield "morph"
        if "UV" in outputs:
            yield from self._uv_slices(out, iv_f, iv_b)
        if "DISTORTION" in outputs:
            yield from self._distortion_slices(out, pos_s, pos_t)
        self._done += 1
        self.out = out

    def _uv_slices(self, out, iv_f, iv_b):
        source, target, options = self.source, self.target, self.options
        Vs, Fs = source["V"], source["F"]
        lv = target["loop_vertex"]
        total_straddling, names = 0, []
        for name, loop_uv in source["uv_layers"].items():
            tr = uv_transfer.UVTransfer(Fs, corner_uvs(source, loop_uv), Vs)
            yield f"UV map {name}"
            for _ in tr.iter_polygon_uvs(iv_f[lv], iv_b[lv], target["loop_start"],
                                         target["loop_total"]):
                yield f"UV map {name}"
            uv, straddling = tr.result
            if source.get("boundary_loops"):
                # An open pair: ears whose chord UVs turn over, righted in the UV chart.
                ears, righted, shaped = uv_transfer.right_ear_uvs(
                    tr, uv, target["V"], target["loop_start"], target["loop_total"], lv, iv_f[lv], iv_b[lv])
                if ears:
                    out["report"].append(f"UV map '{name}': {ears} ear triangle(s) (three boundary corners) "
                                         f"turned over: {righted} righted along the source's boundary, "
                                         f"{shaped} given their own shape")
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
                for _ in tr.iter_polygon_uvs(i0_f[lv], i0_b[lv], target["loop_start"],
                                             target["loop_total"]):
                    yield f"UV map {name} (before)"
                out["uv_before"][name] = tr.result[0]
            self._done += 1
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

    def _distortion_slices(self, out, pos_s, pos_t):
        source, target, res = self.source, self.target, self.res
        q = float(self.options.get("colour_percentile", 99.0)) / 100.0
        Vs, Fs, Vt, Ft = source["V"], source["F"], target["V"], target["F"]
        fw_f, fw_b = out["forward"]
        iv_f, iv_b = out["inverse"]
        tri_poly, npoly = source["tri_polygon"], source["num_polygons"]
        areas = geometry.face_areas(Vs, Fs)
        dist = res.get("distortion", {})
        if "dilatation_per_polygon" in res:
            Dp = np.asarray(res["dilatation_per_polygon"], dtype=np.float64)
            D = Dp[np.asarray(tri_poly, dtype=np.int64)]
        else:
            if "per_face" in dist:
                D = np.asarray(dist["per_face"], dtype=np.float64)
            else:  # from a stored correspondence: D' of the triangles of the image points
                nrm = geometry.face_normals(Vt, Ft)[fw_f[Fs[:, 0]]]
                D, _ = distortion.dilatation(Vs, Fs, pos_s, nrm)
            Dp = distortion.per_polygon(D, tri_poly, npoly, areas)
        Dp_init = res.get("initial_dilatation_per_polygon")
        D_init = res.get("initial_distortion", {}).get("per_face")
        if D_init is not None and len(D_init) != len(Fs):
            D_init = None  # not measured for this genus by this core
        if Dp_init is None and D_init is not None:
            Dp_init = distortion.per_polygon(np.asarray(D_init, dtype=np.float64), tri_poly,
                                             npoly, areas)
        # The target's D' through the inverse map (its triangles onto their preimages).
        nrm_s = geometry.face_normals(Vs, Fs)[iv_f[np.asarray(Ft)[:, 0]]]
        Dt, _ = distortion.dilatation(Vt, Ft, pos_t, nrm_s)
        Dpt = distortion.per_polygon(Dt, target["tri_polygon"], target["num_polygons"],
                                     geometry.face_areas(Vt, Ft))
        yield "distortion D'"
        # The range from the final map on both objects: the initial map's D' (often far
        # larger) would push the top up and leave the final map almost one colour (issue
        # 15); its colours use the same range, saturated (yellow) where above it.
        lo, hi = colours.robust_range(np.concatenate([Dp, Dpt]), hi_q=q, floor=1.0)
        out["dilatation"] = Dp
        out["dilatation_initial"] = Dp_init
        out["dilatation_target"] = Dpt
        out["raw"][DILATATION_COLOURS] = Dp
        out["target_raw"][DILATATION_COLOURS] = Dpt
        if Dp_init is not None:
            out["raw"][DILATATION_INITIAL_COLOURS] = Dp_init
        out["ranges"]["dilatation"] = (lo, hi)
        out["ranges"][DILATATION_COLOURS] = out["ranges"][DILATATION_INITIAL_COLOURS] = (lo, hi)
        fm = np.isfinite(D)
        mean = float(np.sum(areas[fm] * D[fm]) / max(float(areas[fm].sum()), 1e-300))
        worst = float(D[fm].max()) if fm.any() else float("inf")
        out["report"].append(f"dilatation D' colours: {lo:.3g} (dark violet) to {hi:.3g} "
                             f"(yellow), magenta = flipped; mean {mean:.4g}, max {worst:.4g}")
        self._done += 1
        lam = np.log2(distortion.conformal_factor(Vs, Fs, pos_s))
        yield "conformal factor"
        lam_t = -np.log2(distortion.conformal_factor(Vt, Ft, pos_t))  # source over target too
        l_lo, l_hi = colours.symmetric_range(np.concatenate([lam, lam_t]), q)
        out["raw"][CONFORMAL_COLOURS], out["target_raw"][CONFORMAL_COLOURS] = lam, lam_t
        out["ranges"]["conformal"] = out["ranges"][CONFORMAL_COLOURS] = (l_lo, l_hi)
        out["report"].append(f"conformal factor colours: log2 λ from {l_lo:.3g} (blue, area "
                             f"shrinks) to {l_hi:.3g} (red, area grows)")
        self._done += 1
        yield "conformal factor"
        dH = distortion.mean_curvature_difference(Vs, Fs, Vt, Ft, fw_f, fw_b)
        # on the target: (source at the preimage) − target, the same sign as on the source
        dH_t = -distortion.mean_curvature_difference(Vt, Ft, Vs, Fs, iv_f, iv_b)
        h_lo, h_hi = colours.symmetric_range(np.concatenate([dH, dH_t]), q)
        out["raw"][CURVATURE_COLOURS], out["target_raw"][CURVATURE_COLOURS] = dH, dH_t
        out["ranges"]["curvature"] = out["ranges"][CURVATURE_COLOURS] = (h_lo, h_hi)
        out["report"].append(f"mean-curvature difference colours (H·sqrt(A/4π), source − "
                             f"target): {h_lo:.3g} (blue) to {h_hi:.3g} (red)")
        self._done += 1
        yield "curvature difference"
        for raw_key, col_key, side in (("raw", "colours", source),
                                       ("target_raw", "target_colours", target)):
            for name, values in out[raw_key].items():
                lo_, hi_ = out["ranges"][name]
                out[col_key][name] = colours_of(name, values, lo_, hi_, side["loop_total"])


def compute_outputs(source, target, res, options, only=None):
    """Everything the bpy side writes, from the native result `res` (or from a stored
    correspondence: res then holds only 'forward' and 'inverse' {'face','barycentric'}).

    Returns dict with: forward/inverse (face, bary); morph_source (n_s,3) / morph_target (n_t,3)
    local coordinates for the shape keys (and morph_source_initial, the initial map's, when the
    result has a located initial map); uv {name: (L_t,2)} and uv_report, uv_before {name:
    (L_t,2)} through the initial map (options uv_before, when res has 'initial_inverse');
    colours / target_colours {name: (rgba, domain)} and raw / target_raw {name: values} on
    each object; dilatation per polygon (final, initial or None, target); ranges {name: (lo,
    hi)} and the report lines."""
    c = OutputComputation(source, target, res, options, only)
    while c.step():
        pass
    return c.out
ACTIVE = {"job": None}   # the job the UI is running (read by the panel progress bar)

# The jobs whose worker thread runs (MapJob._run_threaded): stopped when Python exits.
RUNNING = set()

# Seconds Python's exit waits for each worker to stop (normally the core's next progress point).
STOP_AT_EXIT = 120.0


def stop_running_jobs(timeout=STOP_AT_EXIT):
    """Cancels every running job and joins its worker thread (Blender quitting mid-solve,
    registered with atexit). Python's exit then finds no worker: a daemon thread still running
    when the interpreter finalizes is ended where it next takes the GIL, and where that is in a
    native call's C++ frame (the core job's wait or result, the open driver's progress
    callback) the process aborts instead of quitting (docs/addon.md "The solve's thread")."""
    jobs = [j for j in list(RUNNING) if j.thread is not None
            and j.thread is not threading.current_thread()]
    for job in jobs:
        job.cancel = True
        if job.solve_job is not None:
            job.solve_job.cancel()
    for job in jobs:
        if job.thread.is_alive():
            print("surfmap: stopping the map computation before quitting", flush=True)
            job.thread.join(timeout)


atexit.register(stop_running_jobs)
