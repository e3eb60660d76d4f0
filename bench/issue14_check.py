#!/usr/bin/env python3
"""Issue 14's check on every equal-genus pair of the development meshes of genus 2-4, both
directions (docs/handle_classes.md "The issue-14 check, every pair"):

  python3 bench/issue14_check.py --meshes DIR [--build build] [--out DIR] [--jobs 2] [--genus 2 3]
                                 [--map-arg=--one-canonical-basis ...]

Each ordered pair is mapped with the defaults (`nice surfmap map A B --out o.obj --report
r.json --quiet`, the command a user runs); the table gives per direction the report's
quality.energy_ratio (the chosen class's intrinsic energy / 8 pi (g - 1)), distortion.mean
(area-weighted D') and max, flipped triangles, whether it converged, the wall time, and per pair
whether the two separate runs chose inverse classes (bench_directions on the two reports: the
exact relation the two-way run computes). Criteria (issue 14): converged, 0 flipped, ratio <= 2,
mean D' <= 5, classes inverse. Genus 4 has one mesh in the set; the other two are generated here
(`surfmap generate cad-plate --genus 4`, `surfmap generate n-hole-torus --genus 4`).
Reports are kept in --out and reused on a second run (delete them to map again).
"""
import argparse
import concurrent.futures
import json
import math
import os
import pathlib
import subprocess
import time

REPO = pathlib.Path(__file__).resolve().parents[1]

PAIRS = [
    ("g2_double-torus_gpjs.obj", "g2_eight_summer.off"),
    ("g2_double-torus_gpjs.obj", "g2_modular_universal_joint.off"),
    ("g2_eight_summer.off", "g2_modular_universal_joint.off"),
    ("g3_block.off", "g3_3holes.off"),
    ("g2_double-torus_gpjs.obj", "g2_teapot_vhacd.obj"),
    ("g2_eight_summer.off", "g2_teapot_vhacd.obj"),
    ("g2_modular_universal_joint.off", "g2_teapot_vhacd.obj"),
    ("g4_fertility_libigl.off", "g4_cadplate.obj"),
    ("g4_fertility_libigl.off", "g4_nholetorus.obj"),
]
GENERATED = {"g4_cadplate.obj": ["cad-plate", "--genus", "4"],
             "g4_nholetorus.obj": ["n-hole-torus", "--genus", "4"]}


def genus_of(name):
    """The genus a mesh's name starts with ("g3_block.off": 3)."""
    return int(name.split("_")[0][1:])


def short(name):
    return name.split(".")[0]


def run_map(exe, meshes, out, a, b, timeout, extra=()):
    stem = f"{short(a)}__{short(b)}"
    rep = out / f"{stem}.json"
    if rep.exists():
        return stem, json.loads(rep.read_text())
    t0 = time.time()
    p = subprocess.run(["nice", str(exe), "map", str(meshes[a]), str(meshes[b]), "--out",
                        str(out / f"{stem}.obj"), "--report", str(rep), "--quiet", *extra],
                       capture_output=True, text=True, timeout=timeout)
    wall = time.time() - t0
    if p.returncode != 0:
        return stem, {"error": (p.stderr.strip().splitlines() or ["?"])[-1], "wall_s": wall}
    r = json.loads(rep.read_text())
    r["wall_s"] = wall
    rep.write_text(json.dumps(r))
    (out / f"{stem}.obj").unlink(missing_ok=True)
    return stem, r


def fmt(x, digits=4):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if abs(x) >= 1e4:
        return f"{x:.3g}"
    return f"{x:.{digits}g}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default=os.environ.get("SURFMAP_MESHES"), required=False,
                    help="directory of the development meshes (default $SURFMAP_MESHES)")
    ap.add_argument("--build", default=str(REPO / "build"))
    ap.add_argument("--out", default="issue14_out")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=3000)
    ap.add_argument("--genus", type=int, nargs="+", metavar="G",
                    help="only the pairs of these genera (default: every pair, genus 2-4)")
    ap.add_argument("--map-arg", action="append", default=[], metavar="ARG",
                    help="one more argument of every `surfmap map` run (repeat for more; write "
                         "--map-arg=--flag for a flag), e.g. --map-arg=--one-canonical-basis")
    a = ap.parse_args()
    if not a.meshes:
        ap.error("--meshes DIR (or $SURFMAP_MESHES) is required")
    pairs = [(x, y) for x, y in PAIRS if a.genus is None or genus_of(x) in a.genus]
    if not pairs:
        ap.error(f"--genus {' '.join(map(str, a.genus))}: no pair of these genera (the pairs have genus "
                 f"{', '.join(sorted({str(genus_of(x)) for x, _ in PAIRS}))})")
    build = pathlib.Path(a.build)
    exe, directions = build / "bin" / "surfmap", build / "bin" / "bench_directions"
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    meshes = {}
    for x, y in pairs:
        for name in (x, y):
            if name in GENERATED:
                path = out / name
                if not path.exists():
                    subprocess.run([str(exe), "generate", *GENERATED[name], "-o", str(path)], check=True,
                                   capture_output=True)
                meshes[name] = path
            else:
                meshes[name] = pathlib.Path(a.meshes) / name
    jobs = [job for x, y in pairs for job in ((x, y), (y, x))]   # quick pairs first
    results = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        futures = [pool.submit(run_map, exe, meshes, out, x, y, a.timeout, a.map_arg) for x, y in jobs]
        for f in concurrent.futures.as_completed(futures):
            stem, r = f.result()
            results[stem] = r
    print("| pair (source -> target) | ratio | mean D' | max D' | flips | converged | directions inverse "
          "| s | criteria |")
    print("|---|---|---|---|---|---|---|---|---|")
    for x, y in pairs:
        fwd, rev = f"{short(x)}__{short(y)}", f"{short(y)}__{short(x)}"
        rel = "-"
        if "error" not in results[fwd] and "error" not in results[rev]:
            p = subprocess.run([str(directions), str(out / f"{fwd}.json"), str(out / f"{rev}.json")],
                               capture_output=True, text=True)
            rel = (p.stdout.strip() or p.stderr.strip()).split(" (")[0]
        for stem, (s, t) in ((fwd, (x, y)), (rev, (y, x))):
            r = results[stem]
            if "error" in r:
                print(f"| {short(s)} -> {short(t)} | failed: {r['error']} | | | | | {rel} | {r['wall_s']:.0f} | fails |")
                continue
            ratio = r["quality"]["energy_ratio"]
            mean, mx = r["distortion"]["mean"], r["distortion"]["max"]
            fails = []
            if not r["converged"]:
                fails.append("not converged")
            if r["flipped_triangles"]:
                fails.append("flips")
            if ratio is None or not ratio <= 2:
                fails.append("ratio > 2")
            if mean is None or not mean <= 5:
                fails.append("D' > 5")
            if not rel.startswith("inverse"):
                fails.append("classes not inverse")
            print(f"| {short(s)} -> {short(t)} | {fmt(ratio)} | {fmt(mean, 3)} | {fmt(mx, 3)} | "
                  f"{r['flipped_triangles']} | {'yes' if r['converged'] else 'no'} | {rel} | "
                  f"{r.get('wall_s', r['time_s']['total']):.0f} | {'; '.join(fails) or 'pass'} |")


if __name__ == "__main__":
    main()
