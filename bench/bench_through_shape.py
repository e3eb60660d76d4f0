#!/usr/bin/env python3
"""Is a better handle class reachable? A class for A -> C composed through an intermediate shape B
(docs/history/handle_classes.md "Is a better class reachable"):

  python3 bench/bench_through_shape.py A B C [--build build]

Maps A -> B and B -> C with the defaults, then solves A -> C alone in the class of A's loops carried
to C through B: each A vertex's image on B (the A -> B map) is put in C's per-axis bounding box and
snapped to the nearest C vertex (the box overlay of B onto C, meant for B and C posed alike, e.g. a
generated n-hole torus and a CAD plate), solved with `homotopy_images` (that class alone). Prints the
ratio (energy / 8 pi (g - 1)), mean D' (max), flipped triangles and seconds of each run, beside the
A -> C default run when --direct is given. An upper bound of the best class's energy for A -> C.
"""
import argparse
import pathlib
import sys
import time

REPO = pathlib.Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("a"), ap.add_argument("b"), ap.add_argument("c")
    ap.add_argument("--build", default=str(REPO / "build"))
    ap.add_argument("--direct", action="store_true", help="also map A -> C with the defaults")
    args = ap.parse_args()
    sys.path.insert(0, str(pathlib.Path(args.build) / "python"))
    import numpy as np
    import surfmap

    def load(p):
        m = surfmap.load_mesh(p)
        return np.asarray(m["V"], float), np.asarray(m["F"], np.int64)

    A, B, C = load(args.a), load(args.b), load(args.c)
    rows = []

    def run(name, s, t, **kw):
        t0 = time.time()
        try:
            r = surfmap.surface_map(s[0], s[1], t[0], t[1], **kw)
        except Exception as e:  # a failed run is a row of the table
            rows.append((name, f"failed: {e}", "", "", f"{time.time() - t0:.0f}"))
            return None
        rows.append((name, f"{r['quality']['energy_ratio']:.4f}",
                     f"{r['distortion']['mean']:.3g} ({r['distortion']['max']:.3g})",
                     str(r["flipped_triangles"]), f"{time.time() - t0:.0f}"))
        return r

    ab = run("A -> B", A, B)
    run("B -> C", B, C)
    if args.direct:
        run("A -> C (defaults)", A, C)
    if ab is not None:
        lo_b, hi_b = B[0].min(0), B[0].max(0)
        lo_c, hi_c = C[0].min(0), C[0].max(0)
        on_b = np.asarray(ab["forward"]["position"])
        unit_b = (on_b - lo_b) / (hi_b - lo_b)
        unit_c = (C[0] - lo_c) / (hi_c - lo_c)
        from scipy.spatial import cKDTree
        nearest = cKDTree(unit_c).query(unit_b)[1]  # nearest C vertex in the unit box
        run("A -> C through B (that class alone)", A, C, homotopy_images=C[0][nearest])
    print("| run | ratio | mean D' (max) | flipped | s |")
    print("|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
