#!/usr/bin/env python3
"""Issue 14's check on every equal-genus pair of the development meshes of genus 2-4, both
directions (docs/history/handle_classes.md "The issue-14 check, every pair"):

  python3 bench/issue14_check.py --meshes DIR [--build build] [--out DIR] [--jobs 2] [--genus 2 3]
                                 [--set dev|held-out|all] [--pair A B ...]
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

`--self-maps` also maps every source of the table onto itself (`surfmap map A A --no-two-way
--no-through-shape`) and adds a column: the row's ratio over its source's self-map ratio. That
self-map ratio is a discretisation baseline, not a bound: the identity is the conformal map, so
what it costs above 1 is the source mesh's own discretisation (a coarse CAD plate: 1.2; it is
the source's mesh that counts: the genus-3 plate onto a fine n-hole torus 1.218, the torus onto
the plate 1.034; docs/handle_classes.md "Quality signal"). The criteria are unchanged: the
column is beside them.

`--refined-source` also solves each row's chosen class on its source refined once by 1-to-4 midpoint
subdivision (bench/refined_source.py --levels 1: the same surface, only the triangulation finer)
and adds a column, the ratio there: how much of the row's ratio is the source's discretisation
(session 30, once refined: at most 0.5% on every fine source of the held-out-like set, 3.5-7.3%
on the coarse CAD plates;
docs/handle_classes.md "Quality signal"). Beside the criteria, which it does not change.

`--set held-out` runs instead pairs nobody tuned the search on (docs/history/handle_classes.md "Session 27, branch class27"):
generated shapes of other kinds at equal genus (cup, amphora, vase, polycube, wheel, thick and
thin cad-plate, a raw jittered n-hole torus), each at a low resolution, against each other and
against development meshes in combinations the development set does not run. `--pair A B`
(repeatable) runs the given pairs instead; A and B are file names in --meshes, names of
GENERATED below, or paths. A generated or given name must start with its genus (`g3_...`).
"""
import argparse
import concurrent.futures
import json
import math
import os
import pathlib
import subprocess
import sys
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
HELD_OUT = [
    ("g2_amphora36.obj", "g2_cup32.obj"),
    ("g2_teapot_vhacd.obj", "g2_cup32.obj"),
    ("g2_vase36.obj", "g2_double-torus_gpjs.obj"),
    ("g2_polycube32.obj", "g2_eight_summer.off"),
    ("g2_cadblock.obj", "g2_modular_universal_joint.off"),
    ("g2_nholetorus36_raw_jitter.obj", "g2_amphora36.obj"),
    ("g3_block.off", "g3_cadplate.obj"),
    ("g3_block.off", "g3_polycube36.obj"),
    ("g3_3holes.off", "g3_wheel36.obj"),
    ("g3_cup36_jitter.obj", "g3_cadplate.obj"),
    ("g4_fertility_libigl.off", "g4_polycube36.obj"),
    ("g4_fertility_libigl.off", "g4_cup36.obj"),
    ("g4_wheel36.obj", "g4_cadblock.obj"),
]
GENERATED = {"g4_cadplate.obj": ["cad-plate", "--genus", "4"],
             "g4_nholetorus.obj": ["n-hole-torus", "--genus", "4"],
             # the held-out set's shapes (`surfmap generate ...`)
             "g2_amphora36.obj": ["amphora", "--resolution", "36"],
             "g2_cup32.obj": ["cup", "--genus", "2", "--resolution", "32"],
             "g2_vase36.obj": ["vase", "--resolution", "36"],
             "g2_polycube32.obj": ["polycube", "--genus", "2", "--resolution", "32"],
             "g2_cadblock.obj": ["cad-plate", "--genus", "2", "--thickness", "1"],
             "g2_nholetorus36_raw_jitter.obj": ["n-hole-torus", "--genus", "2", "--resolution", "36",
                                                "--raw", "--jitter", "0.2", "--seed", "3"],
             "g3_cadplate.obj": ["cad-plate", "--genus", "3"],
             "g3_polycube36.obj": ["polycube", "--genus", "3", "--resolution", "36"],
             "g3_wheel36.obj": ["wheel", "--genus", "3", "--resolution", "36"],
             "g3_cup36_jitter.obj": ["cup", "--genus", "3", "--resolution", "36", "--jitter", "0.2",
                                     "--seed", "5"],
             "g4_polycube36.obj": ["polycube", "--genus", "4", "--resolution", "36"],
             "g4_cup36.obj": ["cup", "--genus", "4", "--resolution", "36"],
             "g4_wheel36.obj": ["wheel", "--genus", "4", "--resolution", "36"],
             "g4_cadblock.obj": ["cad-plate", "--genus", "4", "--thickness", "1"]}


def genus_of(name):
    """The genus a mesh's name starts with ("g3_block.off": 3)."""
    return int(pathlib.Path(name).name.split("_")[0][1:])


def short(name):
    return pathlib.Path(name).name.split(".")[0]


def run_map(exe, meshes, out, a, b, timeout, extra=(), kept_only=False):
    stem = f"{short(a)}__{short(b)}"
    rep = out / f"{stem}.json"
    if rep.exists():
        return stem, json.loads(rep.read_text())
    if kept_only:
        return stem, {"error": "not run (--kept-only)", "wall_s": 0.0}
    t0 = time.time()
    try:
        p = subprocess.run(["nice", str(exe), "map", str(meshes[a]), str(meshes[b]), "--out",
                            str(out / f"{stem}.obj"), "--report", str(rep), "--quiet", *extra],
                           capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return stem, {"error": f"timed out after {timeout:g} s", "wall_s": time.time() - t0}
    wall = time.time() - t0
    if p.returncode != 0:
        return stem, {"error": (p.stderr.strip().splitlines() or ["?"])[-1], "wall_s": wall}
    r = json.loads(rep.read_text())
    r["wall_s"] = wall
    rep.write_text(json.dumps(r))
    (out / f"{stem}.obj").unlink(missing_ok=True)
    return stem, r


def run_self_map(exe, meshes, out, a, timeout):
    """`a` mapped onto itself, one way (the discretisation baseline of --self-maps)."""
    stem = f"self__{short(a)}"
    rep = out / f"{stem}.json"
    if rep.exists():
        return stem, json.loads(rep.read_text())
    t0 = time.time()
    try:
        p = subprocess.run(["nice", str(exe), "map", str(meshes[a]), str(meshes[a]), "--out",
                            str(out / f"{stem}.obj"), "--report", str(rep), "--quiet", "--no-two-way",
                            "--no-through-shape"], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return stem, {"error": f"timed out after {timeout:g} s", "wall_s": time.time() - t0}
    if p.returncode != 0:
        return stem, {"error": (p.stderr.strip().splitlines() or ["?"])[-1], "wall_s": time.time() - t0}
    r = json.loads(rep.read_text())
    r["wall_s"] = time.time() - t0
    rep.write_text(json.dumps(r))
    (out / f"{stem}.obj").unlink(missing_ok=True)
    return stem, r


def vertex_count(path):
    """The vertices of an .obj or .off file ("-" for another format)."""
    path = pathlib.Path(path)
    if path.suffix == ".obj":
        with open(path) as f:
            return sum(1 for line in f if line.startswith("v "))
    if path.suffix == ".off":
        with open(path) as f:
            words = []
            for line in f:
                line = line.split("#")[0].strip()
                if line:
                    words += line.split()
                if len(words) >= 2 and words[0] == "OFF":
                    return int(words[1])
    return "-"


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
    ap.add_argument("--set", choices=("dev", "held-out", "all"), default="dev",
                    help="dev: the development pairs (default); held-out: generated shapes and pairs "
                         "nobody tuned on; all: both")
    ap.add_argument("--pair", nargs=2, action="append", metavar=("A", "B"),
                    help="run this pair (both directions) instead of a set; repeat for more")
    ap.add_argument("--self-maps", action="store_true",
                    help="also map each source onto itself and give each row's ratio over that "
                         "self-map ratio (a discretisation baseline, beside the criteria)")
    ap.add_argument("--refined-source", action="store_true",
                    help="also solve each row's class on its source refined once (bench/refined_source.py) "
                         "and give that ratio (the source's discretisation, beside the criteria)")
    ap.add_argument("--kept-only", action="store_true",
                    help="map nothing: print the table from the reports kept in --out")
    a = ap.parse_args()
    if not a.meshes:
        ap.error("--meshes DIR (or $SURFMAP_MESHES) is required")
    chosen = ([tuple(p) for p in a.pair] if a.pair else
              {"dev": PAIRS, "held-out": HELD_OUT, "all": PAIRS + HELD_OUT}[a.set])
    for x, y in chosen:
        for name in (x, y):
            if not pathlib.Path(name).name[:1] == "g" or not pathlib.Path(name).name.split("_")[0][1:].isdigit():
                ap.error(f"--pair: {name} does not start with its genus (g2_..., g3_...)")
        if genus_of(x) != genus_of(y):
            ap.error(f"--pair {x} {y}: the genera differ ({genus_of(x)} and {genus_of(y)})")
    pairs = [(x, y) for x, y in chosen if a.genus is None or genus_of(x) in a.genus]
    if not pairs:
        ap.error(f"--genus {' '.join(map(str, a.genus))}: no pair of these genera (the pairs have genus "
                 f"{', '.join(sorted({str(genus_of(x)) for x, _ in chosen}))})")
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
            elif (pathlib.Path(a.meshes) / name).exists() or not pathlib.Path(name).exists():
                meshes[name] = pathlib.Path(a.meshes) / name
            else:
                meshes[name] = pathlib.Path(name)
            if not meshes[name].exists():
                ap.error(f"{name}: no such mesh in {a.meshes}, generated name or file")
    jobs = [job for x, y in pairs for job in ((x, y), (y, x))]   # quick pairs first
    results = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        futures = [pool.submit(run_map, exe, meshes, out, x, y, a.timeout, a.map_arg, a.kept_only)
                   for x, y in jobs]
        for f in concurrent.futures.as_completed(futures):
            stem, r = f.result()
            results[stem] = r
            if not a.kept_only:
                print(f"{time.strftime('%H:%M:%S')} {stem}: "
                      + (r["error"] if "error" in r else f"ratio {fmt(r['quality']['energy_ratio'])}"),
                      file=sys.stderr, flush=True)
    selfs = {}
    if a.self_maps:
        sources = sorted({x for x, _ in pairs} | {y for _, y in pairs})
        for name in sources:
            stem, r = (run_self_map(exe, meshes, out, name, a.timeout) if not a.kept_only else
                       (f"self__{short(name)}", json.loads((out / f"self__{short(name)}.json").read_text())
                        if (out / f"self__{short(name)}.json").exists() else {"error": "not run"}))
            selfs[name] = r
            print(f"{time.strftime('%H:%M:%S')} {stem}: "
                  + (r["error"] if "error" in r else f"ratio {fmt(r['quality']['energy_ratio'])}"),
                  file=sys.stderr, flush=True)
        print("| mesh | vertices | self-map ratio | s |")
        print("|---|---|---|---|")
        for name in sources:
            r = selfs[name]
            if "error" in r:
                print(f"| {short(name)} | | failed: {r['error']} | {r.get('wall_s', 0):.0f} |")
            else:
                print(f"| {short(name)} | {vertex_count(meshes[name])} | {fmt(r['quality']['energy_ratio'])} "
                      f"| {r.get('wall_s', r['time_s']['total']):.0f} |")
        print()

    refined = {}
    if a.refined_source:
        env = dict(os.environ, SURFMAP_PYTHONPATH=str(build / "python"))
        for x, y in pairs:
            for s, t in ((x, y), (y, x)):
                stem = f"{short(s)}__{short(t)}"
                rep, out_json = out / f"{stem}.json", out / f"refined__{stem}.json"
                if "error" in results[stem] or (not out_json.exists() and a.kept_only):
                    continue
                if not out_json.exists():
                    p = subprocess.run(["nice", sys.executable, str(REPO / "bench" / "refined_source.py"),
                                        str(meshes[s]), str(meshes[t]), "--words-from", str(rep), "--levels", "1",
                                        "--json", str(out_json)], env=env, capture_output=True, text=True,
                                       timeout=a.timeout)
                    if p.returncode != 0:
                        print(f"refined {stem}: " + (p.stderr.strip().splitlines() or ["?"])[-1], file=sys.stderr)
                rows = json.loads(out_json.read_text())["rows"] if out_json.exists() else []
                refined[stem] = rows[1]["energy_ratio"] if len(rows) > 1 and "energy_ratio" in rows[1] else None
                print(f"{time.strftime('%H:%M:%S')} refined {stem}: {fmt(refined[stem])}", file=sys.stderr,
                      flush=True)

    def over_self(ratio, s):
        base = selfs.get(s, {}).get("quality", {}).get("energy_ratio") if a.self_maps else None
        return fmt(ratio / base) if ratio is not None and base else "-"

    extra_head, extra_rule = (" ratio / source's self-map |", "---|") if a.self_maps else ("", "")
    if a.refined_source:
        extra_head, extra_rule = extra_head + " ratio, source refined once |", extra_rule + "---|"
    print("| pair (source -> target) | ratio | mean D' | max D' | flips | converged | directions inverse "
          f"| s |{extra_head} criteria |")
    print(f"|---|---|---|---|---|---|---|---|{extra_rule}---|")
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
                print(f"| {short(s)} -> {short(t)} | failed: {r['error']} | | | | | {rel} | {r['wall_s']:.0f} |"
                      f"{' - |' if a.self_maps else ''}{' - |' if a.refined_source else ''} fails |")
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
                  f"{r.get('wall_s', r['time_s']['total']):.0f} |"
                  f"{' ' + over_self(ratio, s) + ' |' if a.self_maps else ''}"
                  f"{' ' + fmt(refined.get(stem)) + ' |' if a.refined_source else ''} {'; '.join(fails) or 'pass'} |")


if __name__ == "__main__":
    main()
