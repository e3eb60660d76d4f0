"""The one place where the many-shape tools (surfmap.compare, surfmap.batch, the add-on's
batch operators) call the native map and read its result.

Everything else goes through `run_map` (keyword options -> result dict) and `map_report`
(result dict -> JSON-able summary), so a change of the native options or of the result's
layout is adapted here only.
"""
import numpy as np

from . import _core

# Options the many-shape tools pass through to surfmap.surface_map (all optional); the
# names are the keyword arguments of the native call.
MAP_OPTION_NAMES = (
    "homotopy", "method", "tolerance", "max_iterations", "homotopy_candidates",
    "homotopy_full_solves", "initial_map", "source_weights", "homotopy_search",
    "homotopy_search_evaluations", "two_way", "flat_overlay", "cheap_direction_check",
    "compare_directions", "greedy_pants", "homotopy_extra_cuts", "own_weights_floor",
    "local_fold_repair", "fold_untangle", "target_loops", "two_way_ratio", "face_charts",
    "agreement_ratio",
)


def run_map(Vs, Fs, Vt, Ft, options=None, progress=None):
    """The optimal map source -> target (the native surface_map, GIL released during the
    solve). options: dict with keys from MAP_OPTION_NAMES; unknown keys raise InputError.
    Returns the native result dict."""
    options = dict(options or {})
    unknown = sorted(set(options) - set(MAP_OPTION_NAMES))
    if unknown:
        raise _core.InputError(f"unknown map option(s): {', '.join(unknown)}")
    return _core.surface_map(Vs, Fs, Vt, Ft, progress=progress, **options)


def forward_points(result):
    """(face (n,), barycentric (n,3), position (n,3)) of every source vertex on the target."""
    f = result["forward"]
    return np.asarray(f["face"]), np.asarray(f["barycentric"]), np.asarray(f["position"])


def inverse_points(result):
    """(face (m,), barycentric (m,3), position (m,3)) of every target vertex on the source."""
    f = result["inverse"]
    return np.asarray(f["face"]), np.asarray(f["barycentric"]), np.asarray(f["position"])


def _finite_or_none(x):
    """A float for JSON: None where not finite (genus < 2 has no ratio)."""
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if np.isfinite(x) else None


def map_report(result):
    """A small JSON-able summary of a map result (no per-vertex arrays)."""
    h = result["homotopy"]
    quality = result.get("quality") if isinstance(result.get("quality"), dict) else {}
    chosen = h["chosen"]
    cands = h["candidates"]
    return {
        "genus": int(result["genus"]),
        "converged": bool(result["converged"]),
        "iterations": int(result["iterations"]),
        "energy": {"initial": float(result["energy"]["initial"]),
                   "final": float(result["energy"]["final"])},
        "distortion": {"mean": float(result["distortion"]["mean"]),
                       "max": float(result["distortion"]["max"]),
                       "measure": result["distortion"].get("measure", "")},
        # The quality signal as `surfmap map --report` gives it (genus >= 2; None below).
        "quality": {"energy_ratio": _finite_or_none(quality.get("energy_ratio")),
                    "energy_ratio_basis": quality.get("energy_ratio_basis", ""),
                    "warning": quality.get("warning", "")},
        "source_weights": result.get("source_weights", ""),
        "flipped_triangles": int(result["flipped_triangles"]),
        "homotopy": {"chosen": int(chosen),
                     "description": cands[chosen]["description"] if 0 <= chosen < len(cands) else "",
                     "candidates": len(cands)},
        "time_s": float(result["time_s"]["total"]),
    }
