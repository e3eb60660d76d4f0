#!/usr/bin/env python3
"""The energy of one handle class on a refined source (issue 14; docs/handle_classes.md
"Quality signal"):

  SURFMAP_PYTHONPATH=build/python nice python3 bench/refined_source.py SRC DST
      (--words-from REPORT.json | --class-words JSON | --identity) [--levels 2] [--target-levels 0]
      [--json OUT.json]

Is a ratio above 2x the class or the discretisation of the energy? The source is refined by 1-to-4
midpoint subdivision (bench_open_surfaces.subdivide: the new vertices on the flat faces, so the
surface and its conformal structure are unchanged, only the triangulation the map is represented
on), once per level, and the same class is solved on each level: level 0 in the class named by
its words (`--words-from` a `surfmap map` report's homotopy.chosen_words, or `--class-words`, in
the cuts of that run, so give the same two meshes). The refined mesh has other cuts, so the words
are carried to them (`words_on_refined`): the refined mesh mapped onto SRC by its own vertices
(`homotopy_images`; they lie on SRC's surface) gives its generators in SRC's letters, and the
class's words are substituted for those letters. That needs SRC's cuts as a source and as a
target to agree, checked first (SRC onto itself by its own vertices gives the identity words).
`--identity` (SRC and DST the same mesh) starts from the identity class: a self-map, the
discretisation baseline. `--target-levels K` subdivides the target K times too, the class composed
after the target's own identity carry (its surface unchanged; its discrete conformal structure
moves toward the surface's).

Per level: vertices, quality.energy_ratio (E / 8 pi (g - 1)), distortion.mean / max, flips,
converged, seconds, and `drift`: the mean and largest distance of the input vertices' images from
level 0's, over the target's bounding-box diagonal (small when the class is the same: the maps
converge; a different class moves the images across the surface). With three levels or more,
the observed order p of E_k - E_(k+1) = c h^p and the extrapolated E (Richardson) from the last
three levels. A table to read, not a test.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bench_open_surfaces  # noqa: E402  (its subdivide; it imports surfmap from SURFMAP_PYTHONPATH)

surfmap = bench_open_surfaces.surfmap


def load(path):
    m = surfmap.load_mesh(path)
    return np.asarray(m["V"], float), np.asarray(m["F"], np.int64)


def free_reduce(word):
    out = []
    for x in word:
        if out and out[-1] == -x:
            out.pop()
        else:
            out.append(x)
    return out


def substitute(outer, inner):
    """The class outer o inner: each word of `inner` with every letter k replaced by outer's word
    k (a letter -k by that word inverted), freely reduced."""
    def image(x):
        w = outer[abs(x) - 1]
        return list(w) if x > 0 else [-y for y in reversed(w)]
    return [free_reduce([y for x in w for y in image(x)]) for w in inner]


def identity_words(a, b, images):
    """The words of the identity from mesh a onto mesh b (the same surface; `images`: a's
    vertices on b), carried by homotopy_images: a's canonical generators in b's letters."""
    return surfmap.surface_map(a[0], a[1], b[0], b[1], homotopy_images=images)["homotopy"]["chosen_words"]


def words_on_refined(words, base, before, before_words, refined):
    """A class from `base` (its `words`) written in the cuts of `refined`, the subdivision of
    `before` (itself `base` or a subdivision of it, the class's words there `before_words`):
    refined's generators carried by the identity onto base (its vertices lie on base's surface),
    then the class. When that carry fails (the thin CAD plates' long fans, two levels down),
    through `before` instead, whose cuts as a source and as a target must agree (checked)."""
    try:
        return substitute(words, identity_words(refined, base, refined[0]))
    except surfmap.Error:
        if before is base or identity_words(before, before, before[0]) != [[k + 1] for k in range(len(words))]:
            raise
        return substitute(before_words, identity_words(refined, before, refined[0]))


def richardson(energies):
    """Observed order and extrapolated limit from the last three levels (h halves per level)."""
    if len(energies) < 3:
        return None, None
    e0, e1, e2 = energies[-3:]
    d0, d1 = e0 - e1, e1 - e2
    if not (d0 > 0 and d1 > 0):
        return None, None
    p = math.log2(d0 / d1)
    if not p > 0:
        return p, None
    return p, e2 - d1 / (2 ** p - 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source")
    ap.add_argument("target")
    how = ap.add_mutually_exclusive_group(required=True)
    how.add_argument("--words-from", metavar="REPORT", help="a surfmap map report of SRC -> DST: its chosen class")
    how.add_argument("--class-words", metavar="JSON", help="the class's words, as --class-words of surfmap map")
    how.add_argument("--identity", action="store_true", help="the identity class (SRC and DST one mesh)")
    ap.add_argument("--levels", type=int, default=2, help="subdivisions of the source (default 2)")
    ap.add_argument("--target-levels", type=int, default=0, help="subdivisions of the target (default 0)")
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--json", metavar="OUT", help="write the rows as JSON")
    a = ap.parse_args()
    if a.levels < 0 or a.target_levels < 0:
        ap.error("--levels and --target-levels must be 0 or more")
    try:
        S0, T0 = load(a.source), load(a.target)
    except surfmap.Error as e:
        ap.error(str(e).splitlines()[0])
    if a.identity:
        if S0[0].shape != T0[0].shape or np.abs(S0[0] - T0[0]).max() > 0 or (S0[1] != T0[1]).any():
            ap.error("--identity: SRC and DST must be the same mesh")
        words = [[k + 1] for k in range(2 * surfmap.inspect(*S0)["genus"])]
    else:
        try:
            words = (json.load(open(a.words_from))["homotopy"]["chosen_words"] if a.words_from
                     else json.loads(a.class_words))
        except (OSError, KeyError, TypeError, ValueError) as e:
            ap.error(f"{'--words-from' if a.words_from else '--class-words'}: no class words ({e})")
    checks = []
    # The words are in SRC's letters as a source and DST's as a target; the identities below are
    # in SRC's letters as a target and DST's as a source: the same when the surface's cuts as a
    # source and as a target agree (checked: the identity onto itself gives the identity words).
    for name, mesh in (("source", S0), ("target", T0)):
        w = identity_words(mesh, mesh, mesh[0])
        if w != [[k + 1] for k in range(len(w))]:
            sys.exit(f"the {name}'s cuts as a source and as a target differ ({w}): the class cannot be carried so")
        checks.append(f"{name} onto itself: identity words")
    T = T0
    for _ in range(a.target_levels):
        T = bench_open_surfaces.subdivide(*T)
    if a.target_levels:
        # DST's generators (as a source) in the refined target's letters: the class composed after it.
        words = substitute(identity_words(T0, T, T0[0]), words)
    diag = float(np.linalg.norm(T[0].max(axis=0) - T[0].min(axis=0)))
    rows, images0, S, given = [], None, S0, words
    for level in range(a.levels + 1):
        t0 = time.time()
        try:
            if level:
                before, S = S, bench_open_surfaces.subdivide(*S)
                given = words_on_refined(words, S0, before, given, S)
            m = surfmap.surface_map(S[0], S[1], T[0], T[1], threads=a.threads, class_words=given)
        except surfmap.Error as e:
            rows.append({"level": level, "vertices": len(S[0]), "error": str(e).splitlines()[0],
                         "seconds": time.time() - t0})
            print(f"level {level}: {rows[-1]['error']}", file=sys.stderr, flush=True)
            break
        wall = time.time() - t0
        pos = np.asarray(m["forward"]["position"])
        if images0 is None:
            images0 = pos.copy()
        d = np.linalg.norm(pos[:len(images0)] - images0, axis=1) / diag
        rows.append({"level": level, "vertices": len(S[0]), "energy_ratio": m["quality"]["energy_ratio"],
                     "mean": m["distortion"]["mean"], "max": m["distortion"]["max"],
                     "flipped": m["flipped_triangles"], "converged": m["converged"], "seconds": wall,
                     "drift_mean": float(d.mean()), "drift_max": float(d.max()), "words": given})
        print(f"{time.strftime('%H:%M:%S')} level {level}: {len(S[0])} vertices, ratio "
              f"{rows[-1]['energy_ratio']:.5f}, drift max {d.max():.2e}, {wall:.0f} s", file=sys.stderr, flush=True)
    energies = [r["energy_ratio"] for r in rows if "energy_ratio" in r]
    p, limit = richardson(energies)
    print(f"{os.path.basename(a.source)} -> {os.path.basename(a.target)}"
          f"{f' (target subdivided {a.target_levels}x)' if a.target_levels else ''}; {'; '.join(checks)}")
    print("| level | vertices | ratio | mean D' | max D' | flips | converged | drift mean / max | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "error" in r:
            print(f"| {r['level']} | {r['vertices']} | failed: {r['error']} | | | | | | {r['seconds']:.0f} |")
            continue
        print(f"| {r['level']} | {r['vertices']} | {r['energy_ratio']:.4f} | {r['mean']:.3f} | {r['max']:.3g} | "
              f"{r['flipped']} | {'yes' if r['converged'] else 'no'} | {r['drift_mean']:.2e} / "
              f"{r['drift_max']:.2e} | {r['seconds']:.0f} |")
    if p is not None:
        print(f"observed order p = {p:.2f}" + (f"; extrapolated ratio {limit:.4f}" if limit is not None else ""))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"source": a.source, "target": a.target, "target_levels": a.target_levels, "rows": rows,
                       "order": p, "extrapolated_ratio": limit}, f, indent=1)


if __name__ == "__main__":
    main()
