"""The cut loops of one object (no bpy). Plain numpy in, plain numpy out: triangulating
polygons with the corner mapping, running the native pipeline on one object's mesh, mapping
refined loop vertices back onto the original surface, choosing the original edges to mark as
seams, loop names and colours. Runs (and is tested) outside Blender too.
"""
import colorsys

import numpy as np


# --- polygons -------------------------------------------------------------------------------

def triangulate_polygons(polygons):
    """Fan-triangulates polygons (lists of vertex indices, >= 3 each).

    Returns (F, tri_polygon, tri_corners):
      F           (m, 3) int   triangle vertex indices;
      tri_polygon (m,)   int   polygon each triangle came from;
      tri_corners (m, 3) int   for each triangle corner, its corner index within the polygon
                               (0..len(polygon)-1), so per-corner data (UVs, colours) can be
                               carried back to the polygon's own corners.
    Blender's loop_triangles are preferred for concave polygons; this is the bpy-free fallback.
    """
    F, tri_polygon, tri_corners = [], [], []
    for p, poly in enumerate(polygons):
        poly = list(poly)
        if len(poly) < 3:
            raise ValueError(f"polygon {p} has {len(poly)} vertices (needs at least 3)")
        for k in range(1, len(poly) - 1):
            F.append((poly[0], poly[k], poly[k + 1]))
            tri_polygon.append(p)
            tri_corners.append((0, k, k + 1))
    return (np.asarray(F, dtype=np.int64).reshape(-1, 3),
            np.asarray(tri_polygon, dtype=np.int64),
            np.asarray(tri_corners, dtype=np.int64).reshape(-1, 3))


# --- loops back on the original surface ------------------------------------------------------

def points_on_surface(V, F, origin_face, origin_barycentric):
    """Positions of refined vertices on the ORIGINAL surface.

    V (n,3), F (m,3): the input mesh (as given to system_of_loops); origin_face (n',),
    origin_barycentric (n',3): per refined vertex, its input triangle and barycentric
    coordinates there. Returns (n',3) = sum_k b_k V[F[f, k]].
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    tri = F[np.asarray(origin_face, dtype=np.int64)]            # (n',3)
    b = np.asarray(origin_barycentric, dtype=np.float64)        # (n',3)
    return np.einsum("ik,ikj->ij", b, V[tri])


def _support(v, n, F, origin_face, origin_barycentric, eps):
    """Input vertices whose barycentric weight is non-zero for refined vertex v."""
    if v < n:
        return frozenset((int(v),))
    f = int(origin_face[v])
    return frozenset(int(F[f, k]) for k in range(3) if origin_barycentric[v, k] > eps)


def original_edges_along_loops(loops, n, F, origin_face, origin_barycentric, V=None, eps=1e-9):
    """Input edges that the (refined) loops run along, fully.

    A loop segment (u, w) lies along the input edge {p, q} when both ends lie on that edge
    (the union of their barycentric supports is {p, q}); a segment crossing the inside of an
    input face lies along no input edge (it cannot be a seam; the curve shows it). An input
    edge counts when the segments along it cover its whole length (refinement may split it).
    Returns a sorted list of (p, q) with p < q.
    """
    F = np.asarray(F, dtype=np.int64)
    ob = np.asarray(origin_barycentric, dtype=np.float64)
    covered = {}
    for loop in loops:
        loop = [int(v) for v in loop]
        for u, w in zip(loop[:-1], loop[1:]):
            s = _support(u, n, F, origin_face, ob, eps) | _support(w, n, F, origin_face, ob, eps)
            if len(s) != 2:
                continue
            e = tuple(sorted(s))
            covered.setdefault(e, []).append((u, w))
    if V is None:
        return sorted(covered)
    # Lengths along the edge, measured in the edge's own parameter t in [0, 1].
    P = points_on_surface(V, F, origin_face, ob)
    out = []
    for (p, q), segs in covered.items():
        d = P[q] - P[p]  # the first n refined vertices are the input vertices
        L2 = float(d @ d)
        if L2 == 0.0:
            continue
        total = 0.0
        for u, w in segs:
            total += abs(float((P[w] - P[u]) @ d)) / L2
        if total >= 1.0 - 1e-6:
            out.append((p, q))
    return sorted(out)


def loop_edges(loops):
    """Undirected edges (p < q) of closed vertex paths [x, ..., x] along mesh edges."""
    out = set()
    for loop in loops:
        loop = [int(v) for v in loop]
        for u, w in zip(loop[:-1], loop[1:]):
            if u != w:
                out.add((min(u, w), max(u, w)))
    return sorted(out)


def open_path(loop):
    """[x, v1, ..., x] -> [x, v1, ...] (the closing repeat dropped), for cyclic curves."""
    loop = [int(v) for v in loop]
    if len(loop) > 1 and loop[0] == loop[-1]:
        loop = loop[:-1]
    return loop


# --- names and colours -----------------------------------------------------------------------

def loop_name(k):
    """Loop k -> 'a1', 'b1', 'a2', ... (loop 2i is a_{i+1}, loop 2i+1 is b_{i+1})."""
    return ("a" if k % 2 == 0 else "b") + str(k // 2 + 1)


def pair_colour(k, genus=None):
    """Linear RGBA colour of loop k: a_i and b_i share a hue family (a deep and saturated,
    b a light pastel of a neighbouring hue), each handle i gets a hue far from the others (golden-ratio steps)."""
    i = k // 2
    hue = (0.02 + i * 0.618033988749895) % 1.0
    if k % 2 == 0:
        r, g, b = colorsys.hsv_to_rgb(hue, 1.0, 0.9)
    else:
        r, g, b = colorsys.hsv_to_rgb((hue + 0.09) % 1.0, 0.4, 1.0)
    # HSV values are display (sRGB) values; Blender colours are linear.
    lin = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in (r, g, b)]
    return (lin[0], lin[1], lin[2], 1.0)


def srgb_from_linear(rgba):
    """Linear colour -> display (sRGB) values, e.g. to compare hues as a person sees them."""
    out = [c * 12.92 if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055 for c in rgba[:3]]
    return tuple(out) + tuple(rgba[3:])


# One definition for the loops and the map outputs.
from .geometry import bounding_diagonal  # noqa: E402,F401
from .side import ObjectProblem  # noqa: E402,F401


# --- one object through the native pipeline ---------------------------------------------------

def intake_object(sm, name, V, F, allow_boundary=False):
    """Validates one triangulated mesh. Returns the intake dict; raises ObjectProblem.
    allow_boundary: accept open meshes (the dict then lists 'boundary_loops')."""
    kw = {"allow_boundary": True} if allow_boundary else {}
    try:
        res = sm.intake(np.ascontiguousarray(V, dtype=np.float64),
                        np.ascontiguousarray(F, dtype=np.int32), **kw)
    except sm.InputError as e:
        raise ObjectProblem(f"object '{name}': {e}") from None
    return res


def check_genus(source_name, source_genus, target_name, target_genus):
    """Raises ObjectProblem naming both genera when they differ, or when the genus is 0."""
    if source_name is not None and source_genus != target_genus:
        raise ObjectProblem(f"source '{source_name}' has genus {source_genus} but target "
                            f"'{target_name}' has genus {target_genus}: a map needs equal genus")
    if target_genus == 0:
        which = f"'{target_name}'" if source_name is None else \
            f"'{source_name}' and '{target_name}'"
        raise ObjectProblem(f"{which} has genus 0 (a topological sphere): there are no cut loops")


def loops_of_object(sm, name, V, F, base_vertex=-1):
    """System of loops of one validated mesh, plus everything the Blender side draws.

    V, F: the intake's (triangulated, outward) mesh in the object's local coordinates.
    Returns a dict:
      genus, base_vertex, word_text,
      curves:      list of (name, (k,3) points) per loop, on the original surface, the closing
                   repeat of the base vertex dropped (the curves are cyclic);
      curve_weights: per loop, (vertices (k,3), barycentrics (k,3)): each curve point as a
                   combination of three mesh vertices (so the curve can follow a morph);
      seam_edges:  list of (p, q) input vertex pairs to mark as seams: the unrefined loops
                   (their union is the cut graph: cutting along it leaves one disk, so Blender's
                   Unwrap gives one island) — refined loops detour through faces near shared
                   vertices, so they alone would leave gaps;
      edges_along: input edges that the refined loops run along fully (for reporting/tests).
    """
    n = len(V)
    if base_vertex >= n:
        raise ObjectProblem(f"object '{name}': base vertex {base_vertex} is out of range "
                            f"(the mesh has {n} vertices)")
    try:
        V = np.ascontiguousarray(V, dtype=np.float64)
        F = np.ascontiguousarray(F, dtype=np.int32)
        sol = sm.system_of_loops(V, F, base_vertex=int(base_vertex), refine=True)
        raw = sm.system_of_loops(V, F, base_vertex=int(sol["base_vertex"]), refine=False)
    except sm.InputError as e:
        raise ObjectProblem(f"object '{name}': {e}") from None
    except sm.Error as e:
        raise ObjectProblem(f"object '{name}': system of loops failed: {e}") from None
    P = points_on_surface(V, F, sol["origin_face"], sol["origin_barycentric"])
    tri = np.asarray(F, dtype=np.int64)[np.asarray(sol["origin_face"], dtype=np.int64)]
    bary = np.asarray(sol["origin_barycentric"], dtype=np.float64)
    curves, weights = [], []
    for k, loop in enumerate(sol["loops"]):
        path = open_path(loop)
        curves.append((loop_name(k), P[path]))
        weights.append((tri[path], bary[path]))
    return {
        "genus": int(sol["genus"]),
        "base_vertex": int(sol["base_vertex"]),
        "word_text": str(sol.get("word_text", "")),
        "curves": curves,
        "curve_weights": weights,
        "seam_edges": loop_edges(raw["loops"]),
        "edges_along": original_edges_along_loops(sol["loops"], n, F, sol["origin_face"],
                                                  sol["origin_barycentric"], V),
        "num_refined_vertices": int(len(sol["V"])),
    }
