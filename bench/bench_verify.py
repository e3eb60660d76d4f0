"""The independent certificate (docs/verification.md) on the maps the benchmark pairs produce:
one table row per pair with the certificate's figures (not a test).

  SURFMAP_PYTHONPATH=build/python /usr/bin/python3 bench/bench_verify.py [--genus 0,1,2,3,4] [--vertices 10000]
      [--real]

Generated pairs as in bench/bench_map.cpp (genus 1: tori of revolution (1, .5) -> (1.5, .5);
genus 2: n_hole_torus -> vase; genus 3: -> polycube; genus >= 4: -> a jittered finer copy),
genus 0 a sphere onto a jittered, stretched sphere. --real adds the development pairs of
shared/meshes in both directions (SURFMAP_MESHES, default <repo>/../shared/meshes).
Columns: source/target vertices, map seconds, negative / degenerate image triangles,
smallest signed area / longest edge^2, vertex stars not winding once, unresolved image triangles
(corner normals more than 60 degrees apart), signed image area /
target area, largest |F(I(t)) - t| and |I(F(s)) - s| relative to the image triangle, verdict.
"""
import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.environ.get("SURFMAP_PYTHONPATH", os.path.join(os.path.dirname(__file__), "..", "build", "python")))
import surfmap as sm  # noqa: E402

REAL = [("g2_double-torus_gpjs.obj", "g2_eight_summer.off"), ("g1_bob_tri.obj", "g1_kitten_gpjs.obj"),
        ("g3_3holes.off", "g3_block.off"), ("g0_spot.obj", "g0_bunny_libigl.off")]


def generated(genus, v):
    S = sm.shapes
    if genus == 0:
        s = int(round(math.log(max(v, 42) / 10.0, 4)))
        a = S.sphere(s)
        V, F = S.sphere(s)
        V, F = S.jitter(V * np.array([1.8, 1.0, 0.7]), F, 0.2, 3)
        return a, (V, F)
    if genus == 1:
        res = max(8, round(math.sqrt(v / 2)))
        return S.torus_of_revolution(1.0, 0.5, 2 * res, res), S.torus_of_revolution(1.5, 0.5, 5 * res // 2, res, 1)
    r0 = 40
    v0 = len(S.n_hole_torus(genus, r0, True)[0])
    res = max(32, round(r0 * math.sqrt(v / v0)))
    a = S.n_hole_torus(genus, res, True)
    if genus == 2:
        return a, S.vase(res, True)
    if genus == 3:
        return a, S.polycube(3, res, True)
    V, F = S.n_hole_torus(genus, res + res // 8, True)
    return a, S.jitter(V, F, 0.1, 7)


def row(name, a, b):
    t = time.time()
    try:
        r = sm.surface_map(*a, *b)
    except sm.Error as e:
        print(f"{name:34s} map failed: {e}")
        return
    secs = time.time() - t
    c = sm.verify(*a, *b, r)
    print(f"{name:34s} {len(a[0]):6d} {len(b[0]):6d} {secs:7.1f} | {c['negative_triangles']:4d} "
          f"{c['degenerate_triangles']:4d} {c['min_relative_area']:8.2e} {c['winding_failures']:4d} {c['unresolved_triangles']:5d} "
          f"{c['area_ratio']:7.4f} {c['max_inverse_error']:7.3f} {c['max_forward_error']:7.3f} | "
          f"{'CERTIFIED' if c['certified'] else 'NOT: ' + '; '.join(c['failures'])}", flush=True)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--genus", default="0,1,2,3,4")
    p.add_argument("--vertices", type=int, default=10000)
    p.add_argument("--real", action="store_true")
    args = p.parse_args()
    print(f"{'pair':34s} {'Vs':>6s} {'Vt':>6s} {'map s':>7s} | {'neg':>4s} {'deg':>4s} {'minrelA':>8s} "
          f"{'wind':>4s} {'unres':>5s} {'A/At':>7s} {'F(I)':>7s} {'I(F)':>7s} | verdict")
    for g in (int(x) for x in args.genus.split(",")):
        a, b = generated(g, args.vertices)
        row(f"generated genus {g}", a, b)
    if args.real:
        root = os.environ.get("SURFMAP_MESHES", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "meshes"))
        for s, t in REAL:
            for x, y in ((s, t), (t, s)):
                a, b = (sm.load_mesh(os.path.join(root, n)) for n in (x, y))
                row(f"{x[:-4]} -> {y[:-4]}", (a["V"], a["F"]), (b["V"], b["F"]))


if __name__ == "__main__":
    main()
