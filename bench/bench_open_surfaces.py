"""Open surfaces, a held-out-like set (issue 16; docs/open_surfaces.md "Held-out-like set").

Generated open meshes of genus 0-2 with 1-4 boundary loops (cut spheres, tori and double tori,
garment-like shapes), each pair of the same (g, b) two different shapes mapped in both directions
with the automatic boundary pairing, and each shape mapped onto its remeshed copy (1-to-4 midpoint
subdivision: the same surface, the input's vertices first, so the identity is known). Optionally
real meshes (--real DIR: every open_*.obj / .stl there) onto their remeshed copies.

Per row: (g, b), the path (disk, annulus, double), the pairing and orientation chosen, converged,
flipped faces (the pipeline's count / counted here: the chord triangle of each face's images
against the target's normals at its corners' faces, ears left out), boundary: the largest
distance of a boundary vertex's image to its paired target loop and the smallest of an interior
vertex's image to any target loop (over the diagonal), identity: the mean distance of each input
vertex's image to itself over the diagonal (remeshed copies only), untangled: how many vertices
the untangling of folded faces moved (open.untangled_vertices), mean / max D' (ears left out),
seconds.

  SURFMAP_PYTHONPATH=build/python nice python3 bench/bench_open_surfaces.py [--only SUBSTRING]
      [--real DIR] [--quick]

A table to read, not a test: the checks the tests make on smaller shapes are in
native/tests/python/test_open_double.py and test_open_surfaces.py.
"""
import argparse
import glob
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.environ.get("SURFMAP_PYTHONPATH", os.path.join(os.path.dirname(__file__), "..", "build",
                                                                     "python")))
import surfmap  # noqa: E402
from surfmap import open_double  # noqa: E402


def compact(V, F):
    used = np.unique(F)
    remap = -np.ones(len(V), int)
    remap[used] = np.arange(len(used))
    return V[used], remap[F]


def punch(V, F, centres, radii):
    """Removes the faces whose centroid lies within radii[k] of centres[k] (points near the
    surface): one hole per centre."""
    c = V[F].mean(axis=1)
    keep = np.ones(len(F), bool)
    for p, r in zip(centres, radii):
        keep &= np.linalg.norm(c - np.asarray(p, float), axis=1) >= r
    return compact(V, F[keep])


def on_surface(V, direction, origin=(0, 0, 0)):
    """The vertex farthest along `direction` from `origin`: a point on the surface to punch."""
    d = np.asarray(direction, float)
    return V[np.argmax((V - np.asarray(origin, float)) @ (d / np.linalg.norm(d)))]


def bend(V, k, axis=0):
    diag = np.linalg.norm(V.max(axis=0) - V.min(axis=0))
    W = V / diag
    W[:, axis] += k * W[:, (axis + 1) % 3] ** 2
    return W * diag


def subdivide(V, F):
    edges, W, G = {}, list(V), []

    def mid(a, b):
        e = (min(a, b), max(a, b))
        if e not in edges:
            edges[e] = len(W)
            W.append(0.5 * (V[a] + V[b]))
        return edges[e]
    for a, b, c in F:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        G += [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
    return np.array(W), np.array(G)


def sphere(level, stretch=(1, 1, 1)):
    V, F = surfmap.shapes.sphere(level)
    return np.asarray(V, float) * np.asarray(stretch, float), np.asarray(F)


def holed_sphere(level, dirs, sizes, stretch=(1, 1, 1)):
    V, F = sphere(level, stretch)
    return punch(V, F, [on_surface(V, d) for d in dirs], sizes)


def grid_disk(n, height):
    t = np.linspace(-1, 1, n + 1)
    X, Y = np.meshgrid(t, t, indexing="ij")
    V = np.stack([X.ravel(), Y.ravel(), height * (X.ravel() ** 2 - 0.5 * Y.ravel() ** 2 + 0.3 * X.ravel() * Y.ravel())], 1)
    F = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = i * (n + 1) + j, (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1, i * (n + 1) + j + 1
            F += [[a, b, c], [a, c, d]] if (i + j) % 2 else [[a, b, d], [b, c, d]]
    return V, np.array(F)


def tube(around, rows, radius_of_t, length):
    V = np.array([[radius_of_t(i / rows) * np.cos(2 * np.pi * (j + 0.5 * (i % 2)) / around),
                   radius_of_t(i / rows) * np.sin(2 * np.pi * (j + 0.5 * (i % 2)) / around), length * i / rows]
                  for i in range(rows + 1) for j in range(around)])
    F = []
    for i in range(rows):
        for j in range(around):
            a, b = i * around + j, i * around + (j + 1) % around
            F += [[a, b, b + around], [a, b + around, a + around]] if i % 2 == 0 else \
                 [[a, b, a + around], [b, b + around, a + around]]
    return V, np.array(F)


def torus(R, r, n, m, holes):
    """holes: (angle around the axis, angle around the tube, radius)."""
    V, F = surfmap.shapes.torus_of_revolution(R, r, n, m)
    V, F = np.asarray(V, float), np.asarray(F)
    pts = [((R + r * np.cos(b)) * np.cos(a), (R + r * np.cos(b)) * np.sin(a), r * np.sin(b)) for a, b, _ in holes]
    return punch(V, F, pts, [h[2] for h in holes])


def double_torus(resolution, holes, stretch=(1, 1, 1)):
    """holes: (direction from the centre, radius): the surface point farthest that way."""
    V, F = surfmap.shapes.n_hole_torus(2, resolution)
    V, F = np.asarray(V, float) * np.asarray(stretch, float), np.asarray(F)
    return punch(V, F, [on_surface(V, d) for d, _ in holes], [h[1] for h in holes])


def shapes(quick):
    """name -> ((g, b), A, B): two different shapes of the same topology."""
    lv = 3 if quick else 4
    shirt_dirs = [(0, 0, 1), (0, 0, -1), (1, 0, 0.15), (-1, 0, 0.15)]      # neck, waist, sleeves
    return {
        "disk": ((0, 1), (lambda: (lambda m: (np.asarray(m[0], float), np.asarray(m[1])))(
            surfmap.shapes.spherical_cap(10 if quick else 14, 0.3))), lambda: grid_disk(16 if quick else 24, 0.3)),
        "annulus": ((0, 2), lambda: tube(32, 10, lambda t: 1 + 0.3 * t, 1.5),
                    lambda: holed_sphere(lv, [(0, 0, 1), (0.3, 0.2, -1)], [0.5, 0.7])),
        "pants": ((0, 3), lambda: holed_sphere(lv, [(1, 0, 0.3), (-0.5, 0.866, -0.2), (-0.4, -0.8, 0.5)],
                                                [0.55, 0.6, 0.7]),
                  lambda: holed_sphere(lv, [(0, 0, 1), (0.8, 0, -1), (-0.8, 0, -1)], [0.9, 0.5, 0.55],
                                       stretch=(1.2, 0.8, 1.6))),
        "shirt": ((0, 4), lambda: holed_sphere(lv, shirt_dirs, [0.45, 0.9, 0.35, 0.4], stretch=(1.3, 0.6, 1.6)),
                  lambda: holed_sphere(lv, [(1, 0, 0.3), (-0.5, 0.866, -0.2), (-0.4, -0.8, 0.5), (0.3, -0.2, -1)],
                                       [0.6, 0.55, 0.5, 0.45])),
        "torus_1": ((1, 1), lambda: torus(1.0, 0.45, 32, 16, [(0, np.pi / 2, 0.3)]),
                    lambda: (lambda m: (bend(m[0], 0.3), m[1]))(torus(1.2, 0.35, 36, 14, [(2.0, 0.0, 0.25)]))),
        "torus_2": ((1, 2), lambda: torus(1.0, 0.45, 32, 16, [(0, np.pi / 2, 0.3), (np.pi, 0, 0.25)]),
                    lambda: torus(1.2, 0.4, 36, 16, [(1.0, -np.pi / 2, 0.3), (2.5, np.pi, 0.2)])),
        "torus_4": ((1, 4), lambda: torus(1.0, 0.45, 40, 20, [(0, np.pi / 2, 0.3), (np.pi, 0, 0.25),
                                                              (np.pi / 2, np.pi, 0.2), (-np.pi / 2, 0, 0.22)]),
                    lambda: (lambda m: (bend(m[0], 0.3), m[1]))(
                        torus(1.1, 0.4, 44, 18, [(0.3, np.pi / 2, 0.3), (np.pi, 0.3, 0.3), (np.pi / 2, np.pi, 0.2),
                                                 (-np.pi / 2, 0, 0.25)]))),
        "double_torus_1": ((2, 1), lambda: double_torus(24 if quick else 32, [((0, 1, 0), 0.25)]),
                           lambda: double_torus(28 if quick else 36, [((0.3, -1, 0.2), 0.25)], stretch=(1.2, 1, 0.8))),
        "double_torus_2": ((2, 2), lambda: double_torus(24 if quick else 32, [((0, 1, 0), 0.25), ((0, -1, 0), 0.2)]),
                           lambda: double_torus(28 if quick else 36, [((0.3, -1, 0.2), 0.25), ((-0.2, 1, 0), 0.3)],
                                                stretch=(1.2, 1, 0.8))),
    }


def on_polyline(P, V, loop):
    A, B = V[loop], V[np.roll(loop, -1)]
    d = B - A
    out = np.full(len(P), np.inf)
    for s in range(0, len(P), 256):
        Q = P[s:s + 256]
        t = np.clip(np.einsum("pij,ij->pi", Q[:, None] - A[None], d) / np.einsum("ij,ij->i", d, d), 0, 1)
        out[s:s + 256] = np.linalg.norm(A[None] + t[..., None] * d[None] - Q[:, None], axis=2).min(axis=1)
    return out


def decimate(V, F, ratio=0.5, max_turn_deg=60.0, min_angle_deg=0.0, max_tilt_deg=30.0):
    """Another triangulation of nearly the same surface: half-edge collapses (an interior vertex
    merged into a neighbour, which stays where it is), shortest edge first, until `ratio` of the
    vertices remain. The kept vertices are input vertices (returned as `kept`, so the identity is
    known for them); boundary vertices are never removed (the loops stay as they are); a collapse
    is refused when the two vertices share other neighbours than the edge's two opposite corners
    (the link condition: the topology is kept) or when a face of the star would turn by more than
    `max_turn_deg` or lose its area, or (min_angle_deg > 0) would get an angle below min_angle_deg
    (without it the artery's copy has angles from 1.1 to 177.7 degrees), or would tilt by more than
    `max_tilt_deg` against the input surface (the sum of the input's vertex normals at its corners).
    Why the tilt: the turn is checked per collapse and adds up over many, so with the turn alone
    (max_tilt_deg=180, the copy before session 17) the artery's copy folded into pleats, 33 faces
    turned over against the artery and 4.2% more area (6.4% on the branch of loop 1), another
    surface than the artery, which no map of the two can take to the identity."""
    import heapq
    V, F = np.asarray(V, float), [list(f) for f in np.asarray(F)]
    alive = [True] * len(F)
    vf = [set() for _ in range(len(V))]
    for i, f in enumerate(F):
        for v in f:
            vf[v].add(i)
    on_b = np.zeros(len(V), bool)
    for loop in open_double.boundary_loops(V, np.asarray(F)):
        on_b[loop] = True

    def neighbours(u):
        return {w for i in vf[u] for w in F[i] if w != u}

    def normal(f):
        return np.cross(V[f[1]] - V[f[0]], V[f[2]] - V[f[0]])
    vertex_normal = np.zeros_like(V)
    for f in F:
        vertex_normal[f] += normal(f)
    vertex_normal /= np.maximum(np.linalg.norm(vertex_normal, axis=1), 1e-300)[:, None]
    cos_tilt = np.cos(np.radians(max_tilt_deg))

    def tilted(g):
        n, m = normal(g), vertex_normal[g].sum(axis=0)
        return n @ m <= cos_tilt * np.linalg.norm(n) * np.linalg.norm(m)

    heap = []

    def smallest_angle(f):
        P = V[f]
        u = np.roll(P, -1, axis=0) - P
        w = np.roll(P, 1, axis=0) - P
        c = np.einsum("ij,ij->i", u, w) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1) + 1e-300)
        return float(np.degrees(np.arccos(np.clip(c, -1, 1))).min())

    def push(u):
        if not on_b[u]:
            for w in neighbours(u):
                heapq.heappush(heap, (float(np.linalg.norm(V[u] - V[w])), u, w))
    for u in range(len(V)):
        push(u)
    removed, goal, gone = 0, int((1 - ratio) * len(V)), np.zeros(len(V), bool)
    cos_max = np.cos(np.radians(max_turn_deg))
    while heap and removed < goal:
        _, u, v = heapq.heappop(heap)
        if gone[u] or gone[v]:
            continue
        nu = neighbours(u)
        if v not in nu:
            continue
        shared = [i for i in vf[u] if v in F[i]]
        if len(shared) != 2 or len(nu & neighbours(v)) != 2:
            continue
        ok = True
        for i in vf[u]:
            if i in shared:
                continue
            g = [v if w == u else w for w in F[i]]
            n0, n1 = normal(F[i]), normal(g)
            a0, a1 = np.linalg.norm(n0), np.linalg.norm(n1)
            if a1 <= 1e-3 * a0 or n0 @ n1 <= cos_max * a0 * a1 or (min_angle_deg > 0 and
                                                                     smallest_angle(g) < min_angle_deg) or \
                    (max_tilt_deg < 180 and tilted(g)):
                ok = False
                break
        if not ok:
            continue
        for i in shared:
            alive[i] = False
            for w in F[i]:
                vf[w].discard(i)
        for i in vf[u]:
            F[i] = [v if w == u else w for w in F[i]]
            vf[v].add(i)
        vf[u] = set()
        gone[u] = True
        removed += 1
        push(v)
        for w in neighbours(v):
            push(w)
    kept = np.flatnonzero(~gone)
    remap = -np.ones(len(V), int)
    remap[kept] = np.arange(len(kept))
    G = remap[np.array([f for f, a in zip(F, alive) if a])]
    return V[kept], G, kept


def point_triangle_distance(P, A, B, C):
    """Distance of each point P[i] to the triangle (A[i], B[i], C[i]) (Ericson's closest point)."""
    ab, ac, ap = B - A, C - A, P - A
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp, cp = P - B, P - C
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    denom = va + vb + vc
    denom[denom == 0] = 1e-300
    v, w = vb / denom, vc / denom
    Q = A + v[:, None] * ab + w[:, None] * ac                                  # inside the face
    with np.errstate(divide="ignore", invalid="ignore"):
        cases = [
            ((d1 <= 0) & (d2 <= 0), A),
            ((d3 >= 0) & (d4 <= d3), B),
            ((d6 >= 0) & (d5 <= d6), C),
            ((vc <= 0) & (d1 >= 0) & (d3 <= 0), A + (d1 / (d1 - d3))[:, None] * ab),
            ((vb <= 0) & (d2 >= 0) & (d6 <= 0), A + (d2 / (d2 - d6))[:, None] * ac),
            ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
             B + ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None] * (C - B)),
        ]
    done = np.zeros(len(P), bool)
    for mask, X in cases:
        m = mask & ~done
        Q[m] = X[m]
        done |= m
    return np.linalg.norm(P - Q, axis=1)


def distance_to_surface(P, V, F, k=24):
    """The distance of each point to the mesh (V, F): the nearest of the k faces whose centroids
    are nearest (exact for the meshes here, whose faces are small against their curvature)."""
    from scipy.spatial import cKDTree
    c = V[F].mean(axis=1)
    _, idx = cKDTree(c).query(P, k=min(k, len(F)))
    best = np.full(len(P), np.inf)
    for j in range(idx.shape[1]):
        f = F[idx[:, j]]
        best = np.minimum(best, point_triangle_distance(P, V[f[:, 0]], V[f[:, 1]], V[f[:, 2]]))
    return best


def measure(r, Vs, Fs, Vt, Ft, identity):
    """The row's figures, counted here from the result's forward map. identity: None, or per
    source vertex the point of the target that is the same point of the surface (a copy's)."""
    fw = r["forward"]
    pos, face = np.asarray(fw["position"]), np.asarray(fw["face"])
    diag = np.linalg.norm(Vt.max(axis=0) - Vt.min(axis=0))
    s_loops, t_loops = open_double.boundary_loops(Vs, Fs), open_double.boundary_loops(Vt, Ft)
    pairing = r["open"]["boundary_pairing"]
    on_b = np.zeros(len(Vs), bool)
    off = 0.0
    for i, loop in enumerate(s_loops):
        on_b[loop] = True
        off = max(off, on_polyline(pos[loop], Vt, t_loops[pairing[i]]).max())
    inner = np.flatnonzero(~on_b)
    inside = min(on_polyline(pos[inner], Vt, l).min() for l in t_loops) if len(inner) else np.inf
    nt = np.cross(Vt[Ft[:, 1]] - Vt[Ft[:, 0]], Vt[Ft[:, 2]] - Vt[Ft[:, 0]])
    q = pos[Fs]
    img = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    sign = -1 if r["open"].get("orientation") == "reversing" else 1
    turned = sign * np.einsum("ij,ij->i", img, nt[face[Fs]].sum(axis=1)) <= 0
    flips_here = int(np.sum(turned & ~np.all(on_b[Fs], axis=1)))
    ident = floor = float("nan")
    if identity is not None:
        identity = np.asarray(identity, float)
        ident = float(np.linalg.norm(pos - identity, axis=1).mean() / diag)
        floor = float(distance_to_surface(identity, Vt, Ft).mean() / diag)
    return off / diag, inside / diag, flips_here, ident, floor


def run(name, gb, Vs, Fs, Vt, Ft, identity, **kw):
    """One row. identity: None, True (the target's first vertices are the source's: a subdivision)
    or per source vertex the same point on the target."""
    if identity is True:
        identity = Vt[:len(Vs)]
    elif identity is False:
        identity = None
    t0 = time.time()
    try:
        r = surfmap.surface_map(Vs, Fs, Vt, Ft, **kw)
    except Exception as e:   # a row says what failed; the table goes on
        print(f"| {name} | ({gb[0]}, {gb[1]}) | {len(Vs)} → {len(Vt)} | **failed**: {str(e)[:200]} |"
              f" | | | | | | {time.time() - t0:.0f} |", flush=True)
        return None
    dt = time.time() - t0
    off, inside, flips_here, ident, floor = measure(r, Vs, Fs, Vt, Ft, identity)
    o = r["open"]
    path = o["domain"] + (f", {o.get('orientation', '')}" if o["domain"] == "double" else "")
    if kw.get("boundary_pairing") is not None:
        path += ", given"
    conv = r.get("converged", True)
    moved = o.get("untangled_vertices", 0)
    inv = o.get("inverse_flipped_triangles", o.get("inverse_flipped", ""))
    ident_text = "" if np.isnan(ident) else f"{100 * ident:.3f}% ({100 * floor:.3f}%)"
    print(f"| {name} | ({gb[0]}, {gb[1]}) | {len(Vs)} → {len(Vt)} | {path} | {o['boundary_pairing']} | {conv} | "
          f"{r['flipped_triangles']} ({flips_here}) / {inv} | {moved if moved else ''} | {off:.1e} / {inside:.1e} | "
          f"{ident_text} | {r['distortion']['mean']:.3f} / "
          f"{r['distortion']['max']:.1f} | {dt:.0f} |", flush=True)
    return r


def read_open(path):
    V, polys = surfmap.read_polygon_soup(path)
    it = surfmap.intake(np.asarray(V, float), [list(p) for p in polys], allow_boundary=True)
    return np.asarray(it["V"], float), np.asarray(it["F"]), it["info"]


def real_copies(path, args):
    """A real open mesh onto three copies of itself and back: its 1-to-4 midpoint subdivision (the
    same surface), a decimated copy (another triangulation, half the vertices, decimate()) and a
    bent copy (x += 0.3 y^2 in coordinates over the diagonal; the same triangulation)."""
    V, F, info = read_open(path)
    gb = (info["genus"], info["num_boundary_loops"])
    name = os.path.basename(path).split("_")[3] if os.path.basename(path).count("_") >= 3 else os.path.basename(path)
    kw = {} if gb[1] <= args.auto_up_to else {"boundary_pairing": list(range(gb[1]))}
    Vs_, Fs_ = subdivide(V, F)
    Vd, Fd, kept = decimate(V, F, min_angle_deg=args.decimate_min_angle, max_tilt_deg=args.decimate_max_tilt)
    Vb = bend(V, 0.3)
    copies = {"subdivided": (Vs_, Fs_, True, Vs_), "decimated": (Vd, Fd, V, V[kept]), "bent 0.3": (Vb, F, Vb, V)}
    for label, (Vt, Ft, fwd_identity, back_identity) in copies.items():
        if args.copies and label.split()[0] not in args.copies:
            continue
        run(f"{name} → {label}", gb, V, F, Vt, Ft, fwd_identity, **kw)
        run(f"{label} → {name}", gb, Vt, Ft, V, F, back_identity, **kw)


def punched_real(path, holes):
    """A closed real mesh opened by holes: (direction from the centroid to the surface point
    punched, radius over the diagonal) each."""
    V, polys = surfmap.read_polygon_soup(path)
    it = surfmap.intake(np.asarray(V, float), [list(p) for p in polys])
    V, F = np.asarray(it["V"], float), np.asarray(it["F"])
    diag = np.linalg.norm(V.max(axis=0) - V.min(axis=0))
    centre = V.mean(axis=0)
    V, F = punch(V, F, [on_surface(V, d, centre) for d, _ in holes], [h[1] * diag for h in holes])
    return V, F


#: Real pairs of the same (g, b): each real open mesh against a closed real mesh opened by holes
#: (an open shell of another shape), and two closed genus-2 meshes opened by one hole each.
REAL_PAIRS = [
    ("open_g0_b1_face_gpjs.obj", ("g0_bunny_libigl.off", [((0, -1, 0), 0.25)])),
    ("open_g1_b1_punctured-torus_bff.obj", ("g1_bob_tri.obj", [((0, 1, 0), 0.12)])),
    ("open_g0_b3_artery_gmsh.stl", ("g0_spot.obj", [((0, 1, 0), 0.08), ((1, 0, 0), 0.08), ((-1, 0, 0), 0.08)])),
    ("open_g0_b4_poncho_diffavatar.obj", ("g0_spot.obj", [((0, 1, 0), 0.08), ((1, 0, 0), 0.08), ((-1, 0, 0), 0.08),
                                                          ((0, -1, 0), 0.08)])),
    (("g2_double-torus_gpjs.obj", [((0, 0, 1), 0.1)]), ("g2_eight_summer.off", [((0, 0, 1), 0.1)])),
]


def real_pairs(directory, args):
    def load(item):
        if isinstance(item, str):
            V, F, _ = read_open(os.path.join(directory, item))
            return item.split("_")[3], V, F
        name, holes = item
        V, F = punched_real(os.path.join(directory, name), holes)
        return os.path.splitext(name)[0].split("_")[1] + f" ({len(holes)} hole{'s' if len(holes) > 1 else ''})", V, F
    for a, b in REAL_PAIRS:
        if args.only and not any(args.only in (x if isinstance(x, str) else x[0]) for x in (a, b)):
            continue
        (na, Va, Fa), (nb, Vb, Fb) = load(a), load(b)
        ia = surfmap.intake(Va, Fa, allow_boundary=True)["info"]
        ib = surfmap.intake(Vb, Fb, allow_boundary=True)["info"]
        ga, gb = (ia["genus"], ia["num_boundary_loops"]), (ib["genus"], ib["num_boundary_loops"])
        if ga != gb:
            print(f"| {na} / {nb} | {ga} / {gb}: not the same topology | | | | | | | | | | |", flush=True)
            continue
        run(f"{na} → {nb}", ga, Va, Fa, Vb, Fb, None)
        run(f"{nb} → {na}", ga, Vb, Fb, Va, Fa, None)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", default="")
    ap.add_argument("--real", default="")
    ap.add_argument("--quick", action="store_true", help="coarser shapes")
    ap.add_argument("--no-remeshed", action="store_true")
    ap.add_argument("--no-pairs", action="store_true")
    ap.add_argument("--no-generated", action="store_true", help="only the real meshes (--real)")
    ap.add_argument("--no-copies", action="store_true", help="--real: no copies of the real meshes")
    ap.add_argument("--no-real-pairs", action="store_true", help="--real: no pairs of different real meshes")
    ap.add_argument("--copies", default="", help="--real: only these copies (subdivided,decimated,bent)")
    ap.add_argument("--decimate-min-angle", type=float, default=0.0,
                    help="--real decimated copies: refuse collapses that make an angle below this (degrees)")
    ap.add_argument("--decimate-max-tilt", type=float, default=30.0,
                    help="--real decimated copies: refuse collapses that tilt a face by more than this against the "
                         "input surface (degrees; 180: the copy before session 17, which folded the artery)")
    ap.add_argument("--auto-up-to", type=int, default=3,
                    help="--real copies: the automatic pairing up to this many loops, else loop i -> loop i given")
    args = ap.parse_args()
    print("| shape | (g, b) | V | path | pairing | converged | flipped (here) | untangled | boundary off / interior to "
          "loops | identity | mean / max D' | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, (gb, make_a, make_b) in shapes(args.quick).items():
        if args.no_generated or (args.only and args.only not in name):
            continue
        A, B = make_a(), make_b()
        for label, (V, F) in (("A", A), ("B", B)):
            info = surfmap.intake(V, F, allow_boundary=True)["info"]
            got = (info["genus"], info["num_boundary_loops"])
            if got != gb:
                print(f"| {name} {label} | generated {got}, wanted {gb} | | | | | | | | | | |", flush=True)
                break
        else:
            if not args.no_pairs:
                run(f"{name} A → B", gb, *A, *B, False)
                run(f"{name} B → A", gb, *B, *A, False)
            if not args.no_remeshed:
                run(f"{name} A → remeshed A", gb, *A, *subdivide(*A), True)
    if args.real:
        if not args.no_copies:
            for path in sorted(glob.glob(os.path.join(args.real, "open_*"))):
                if args.only and args.only not in path:
                    continue
                real_copies(path, args)
        if not args.no_real_pairs:
            real_pairs(args.real, args)

if __name__ == "__main__":
    main()
