"""Landmarks (no bpy): pairs from vertex groups named 'lm_...', their checks, and the one-line
account of how a solve held them."""
import numpy as np


LANDMARK_PREFIX = "lm_"


def landmark_pairs(source_groups, target_groups, prefix=LANDMARK_PREFIX):
    """Landmark pairs from vertex groups of matching names (e.g. 'lm_nose' on both objects).

    source_groups / target_groups: {group name: (vertex indices, weights)} of the groups whose
    names start with `prefix`. Each group names one landmark: its vertex of largest weight.
    Returns (pairs (k,2) int, names, problems): problems lists groups present on one object only
    or empty; the caller decides whether they are errors."""
    names, pairs, problems = [], [], []
    for name in sorted(set(source_groups) | set(target_groups)):
        if not name.startswith(prefix):
            continue
        if name not in source_groups or name not in target_groups:
            side = "source" if name in source_groups else "target"
            problems.append(f"vertex group '{name}' is only on the {side}")
            continue
        picks = []
        for side, groups in (("source", source_groups), ("target", target_groups)):
            idx, w = groups[name]
            if len(idx) == 0:
                problems.append(f"vertex group '{name}' on the {side} has no vertices")
                break
            picks.append(int(np.asarray(idx)[int(np.argmax(w))]))
        if len(picks) == 2:
            names.append(name)
            pairs.append(picks)
    return np.asarray(pairs, dtype=np.int64).reshape(-1, 2), names, problems


def check_landmarks(pairs, n_source, n_target):
    """Raises ValueError for out-of-range or repeated landmark vertices."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    for side, col, n in (("source", 0, n_source), ("target", 1, n_target)):
        v = pairs[:, col]
        if len(v) and (v.min() < 0 or v.max() >= n):
            raise ValueError(f"landmark vertex out of range on the {side} "
                             f"(the mesh has {n} vertices)")
        u, c = np.unique(v, return_counts=True)
        if np.any(c > 1):
            raise ValueError(f"{side} vertex {int(u[c > 1][0])} is used by two landmarks")


def landmark_summary(res, count):
    """How the landmarks of a surface_map result were held, in one line (None without any).

    Genus 0: the Möbius map they fix (exact up to 3, least squares beyond). Genus >= 1, from
    res['landmark_method']: plain pins (the exact held optimum), the barrier continuation (the
    landmarks walked to their targets with the map bijective at every step; its steps), or
    carried neighbourhoods (rings of neighbours held rigidly with each landmark; tried when
    the continuation stalls)."""
    if not count:
        return None
    if res.get("genus", 0) == 0:
        err = float(res.get("landmark_error", 0.0))
        return (f"{count} landmark(s): the Möbius map they fix"
                + (" (exact)" if count <= 3 else f" (least squares, largest miss {err:.3g})"))
    method = res.get("landmark_method", "")
    steps, solves = int(res.get("landmark_steps", 0)), int(res.get("landmark_solves", 0))
    if method == "pinned":
        how = "plain pins (the exact held optimum; nothing folded)"
    elif method == "barrier continuation":
        how = (f"barrier continuation in {steps} step(s) (plain pins folded the map; bijective "
               f"at every step)")
    elif method == "carried neighbourhoods":
        rings = [int(r) for r in res.get("landmark_rings", [])]
        how = (f"carried neighbourhoods (rings {rings}, {int(res.get('landmark_held_vertices', 0))} "
               f"vertices held rigidly, {solves} solve(s)"
               + (f"; the barrier continuation stalled after {steps} step(s)" if steps else "") + ")")
    else:
        how = method or "held"
    return f"{count} landmark(s) held by {how}"
