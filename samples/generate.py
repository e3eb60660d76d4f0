#!/usr/bin/python3
"""Writes the committed sample meshes into samples/meshes/.

Run with the system Python after building (either is enough):
    /usr/bin/python3 samples/generate.py [--build BUILD_DIR]
It uses the native module at BUILD_DIR/python (surfmap._core.shapes) when it
imports, otherwise the CLI at BUILD_DIR/bin/surfmap (`surfmap generate`).
Every shape is procedural and deterministic (samples/shapes.h), so the files
can always be regenerated; README.md lists them with genus, V and F.
"""
import argparse
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
OUT = os.path.join(HERE, "meshes")

# name, genus, CLI arguments, Python call (module, kwargs), description
SAMPLES = [
    ("torus_R1_r0.5.obj", 1, ["torus", "--R", "1", "--r", "0.5", "--n-major", "96", "--n-minor", "48"],
     ("torus_of_revolution", dict(R=1.0, r=0.5, n_major=96, n_minor=48)),
     "torus of revolution R=1, r=0.5 (paper Fig. 9c; modulus r/sqrt(R^2-r^2))"),
    ("torus_R1.5_r0.5.obj", 1, ["torus", "--R", "1.5", "--r", "0.5", "--n-major", "120", "--n-minor", "40"],
     ("torus_of_revolution", dict(R=1.5, r=0.5, n_major=120, n_minor=40)),
     "torus of revolution R=1.5, r=0.5 (paper Fig. 9c partner; extremal K ~ 1.633)"),
    ("vase_g2.obj", 2, ["vase", "--resolution", "34"], ("vase", dict(resolution=34)),
     "vase with two handles"),
    ("double_torus_g2.obj", 2, ["n-hole-torus", "--genus", "2", "--resolution", "42"],
     ("n_hole_torus", dict(n=2, resolution=42)), "two holes in a row"),
    ("polycube_g3.obj", 3, ["polycube", "--genus", "3", "--resolution", "38"],
     ("polycube", dict(holes=3, resolution=38)), "rounded block with three square through-holes"),
    ("triple_torus_g3.obj", 3, ["n-hole-torus", "--genus", "3", "--resolution", "50"],
     ("n_hole_torus", dict(n=3, resolution=50)), "three holes in a row"),
]


def write_obj(path, V, F):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        for v in V:
            f.write("v %.9g %.9g %.9g\n" % (v[0], v[1], v[2]))
        for t in F:
            f.write("f %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1))
    os.replace(tmp, path)


def count_obj(path):
    nv = nf = 0
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                nv += 1
            elif line.startswith("f "):
                nf += 1
    return nv, nf


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(ROOT, "build"), help="build directory (default: build)")
    ap.add_argument("--cli", action="store_true", help="use the CLI even if the module imports")
    args = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)

    shapes = None
    if not args.cli:
        sys.path.insert(0, os.path.join(args.build, "python"))
        try:
            from surfmap import _core  # noqa: E402
            shapes = _core.shapes
        except ImportError as e:
            print("native module not importable (%s); using the CLI" % e)
    cli = os.path.join(args.build, "bin", "surfmap")
    if shapes is None and not os.access(cli, os.X_OK):
        sys.exit("neither %s/python/surfmap nor %s exists: build first" % (args.build, cli))

    rows = []
    for name, genus, cli_args, (fn, kwargs), what in SAMPLES:
        path = os.path.join(OUT, name)
        t0 = time.time()
        if shapes is not None:
            V, F = getattr(shapes, fn)(**kwargs)
            write_obj(path, V, F)
        else:
            subprocess.run([cli, "generate"] + cli_args + ["--out", path], check=True)
        nv, nf = count_obj(path)
        assert nv - nf // 2 * 3 + nf == 2 - 2 * genus, name  # Euler: V - E + F with E = 3F/2
        size = os.path.getsize(path)
        print("%-24s genus %d  V %6d  F %6d  %7.1f kB  %.2fs" % (name, genus, nv, nf, size / 1024, time.time() - t0))
        rows.append((name, genus, nv, nf, what, "surfmap generate " + " ".join(cli_args)))

    lines = ["# Sample meshes", "",
             "Procedural, deterministic closed surfaces written by `samples/generate.py`",
             "(`/usr/bin/python3 samples/generate.py`, after building; see `native/include/surfmap/samples/shapes.h`).",
             "All are closed, manifold, one component, outward oriented (signed volume > 0).", "",
             "| file | genus | V | F | shape | command |", "|---|---|---|---|---|---|"]
    for name, genus, nv, nf, what, cmd in rows:
        lines.append("| `%s` | %d | %d | %d | %s | `%s --out %s` |" % (name, genus, nv, nf, what, cmd, name))
    lines += ["", "Pairs: the two tori are the paper's Fig. 9c pair (flat-torus ground truth, docs/method.md §3);",
              "`vase_g2`/`double_torus_g2` and `polycube_g3`/`triple_torus_g3` are equal-genus pairs of",
              "different-looking shapes for the demo.", ""]
    with open(os.path.join(OUT, "README.md"), "w") as f:
        f.write("\n".join(lines))


if __name__ == "__main__":
    main()
