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


def measure(r, Vs, Fs, Vt, Ft, identity):
    """The row's figures, counted here from the result's forward map."""
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
    ident = float(np.linalg.norm(pos - Vt[:len(Vs)], axis=1).mean() / diag) if identity else float("nan")
    return off / diag, inside / diag, flips_here, ident


def run(name, gb, Vs, Fs, Vt, Ft, identity):
    t0 = time.time()
    try:
        r = surfmap.surface_map(Vs, Fs, Vt, Ft)
    except Exception as e:   # a row says what failed; the table goes on
        print(f"| {name} | ({gb[0]}, {gb[1]}) | {len(Vs)} → {len(Vt)} | **failed**: {str(e)[:200]} |"
              f" | | | | | | {time.time() - t0:.0f} |", flush=True)
        return None
    dt = time.time() - t0
    off, inside, flips_here, ident = measure(r, Vs, Fs, Vt, Ft, identity)
    o = r["open"]
    path = o["domain"] + (f", {o.get('orientation', '')}" if o["domain"] == "double" else "")
    conv = r.get("converged", True)
    moved = o.get("untangled_vertices", 0)
    print(f"| {name} | ({gb[0]}, {gb[1]}) | {len(Vs)} → {len(Vt)} | {path} | {o['boundary_pairing']} | {conv} | "
          f"{r['flipped_triangles']} ({flips_here}) | {moved if moved else ''} | {off:.1e} / {inside:.1e} | "
          f"{'' if np.isnan(ident) else f'{100 * ident:.3f}%'} | {r['distortion']['mean']:.3f} / "
          f"{r['distortion']['max']:.1f} | {dt:.0f} |", flush=True)
    return r


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", default="")
    ap.add_argument("--real", default="")
    ap.add_argument("--quick", action="store_true", help="coarser shapes")
    ap.add_argument("--no-remeshed", action="store_true")
    ap.add_argument("--no-pairs", action="store_true")
    args = ap.parse_args()
    print("| shape | (g, b) | V | path | pairing | converged | flipped (here) | untangled | boundary off / interior to "
          "loops | identity | mean / max D' | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, (gb, make_a, make_b) in shapes(args.quick).items():
        if args.only and args.only not in name:
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
        for path in sorted(glob.glob(os.path.join(args.real, "open_*"))):
            if args.only and args.only not in path:
                continue
            V, polys = surfmap.read_polygon_soup(path)
            it = surfmap.intake(np.asarray(V, float), [list(p) for p in polys], allow_boundary=True)
            V, F, info = np.asarray(it["V"], float), np.asarray(it["F"]), it["info"]
            run(os.path.basename(path) + " → remeshed", (info["genus"], info["num_boundary_loops"]), V, F,
                *subdivide(V, F), True)


if __name__ == "__main__":
    main()
