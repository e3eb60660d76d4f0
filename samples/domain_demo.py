"""Shapes onto canonical domains (docs/many_shapes.md; the paper's Figs. 14-15), in Blender:

  blender -b --factory-startup --python-exit-code 1 --python samples/domain_demo.py -- --out DIR
          [--g4 MESH] [--samples N] [--size WxH]

A real genus-2 mesh (samples/meshes/double_torus_gpjs_g2.obj, geometry-processing-js, MIT)
and a genus-4 mesh (--g4: default the real fertility model from ../shared/meshes when it is
there — it cannot ship in samples/, its licence is not stated — else the generated
`surfmap generate polycube --genus 4`) are each mapped onto the canonical domain of their
genus (`surfmap domain --genus g`, holes in a row), with samples/demo.py's pipeline: cut loops,
the shape unwrapped along them with a checker, the map, and renders DIR/d<g>_*.png (the
checker carried onto the domain, the shape at 50% of its morph onto the domain, the
distortion before/after, ...); DIR/domain_demo.blend keeps everything.
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import demo  # noqa: E402  (samples/demo.py: its functions, not its main)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

# ../shared/meshes beside the repository (the project's development meshes).
SHARED_G4 = os.path.join(os.path.dirname(demo.REPO), "shared", "meshes", "g4_fertility_libigl.off")


def posed_like(V, V_shape):
    """The domain turned onto the shape's principal axes (longest along longest) and scaled to
    its size, so the linear morph between them does not have to turn it (the map itself does
    not depend on the pose)."""
    def axes(X):
        c = X.mean(axis=0)
        w, U = np.linalg.eigh(np.cov((X - c).T))
        U = U[:, ::-1]
        if np.linalg.det(U) < 0:
            U[:, 2] *= -1
        return c, np.sqrt(w[::-1]), U
    c0, s0, U0 = axes(np.asarray(V))
    c1, s1, U1 = axes(np.asarray(V_shape))
    return (np.asarray(V) - c0) @ U0 @ U1.T * (s1[0] / s0[0]) + c1


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    opts = {"out": os.path.join(demo.REPO, "demo_out", "domains"), "g4": "", "samples": "12",
            "size": "560x420"}
    for i in range(0, len(argv) - 1, 2):
        key = argv[i].lstrip("-")
        if key not in opts:
            raise SystemExit(f"domain_demo.py: unknown option {argv[i]!r}")
        opts[key] = argv[i + 1]
    out = opts["out"]
    os.makedirs(out, exist_ok=True)
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    sm = demo.enable_addon()
    w, h = (int(x) for x in opts["size"].split("x"))
    cam = demo.setup_scene(int(opts["samples"]), (w, h))
    g4 = opts["g4"] or (SHARED_G4 if os.path.exists(SHARED_G4) else "")
    if not g4:
        V, F = sm.shapes.polycube(4, 40)
        g4 = os.path.join(out, "polycube_g4.obj")
        sm.write_obj(g4, V, F)
        print("domain_demo: no real genus-4 mesh; using the generated polycube_g4")
    shapes = {2: os.path.join(demo.MESHES, "double_torus_gpjs_g2.obj"), 4: os.path.abspath(g4)}
    written, objs = [], []
    for i, (genus, path) in enumerate(shapes.items()):
        shape = sm.load_mesh(path)
        name = os.path.splitext(os.path.basename(path))[0]
        sm.write_obj(os.path.join(out, f"{name}.obj"), shape["V"], shape["F"])
        V, F, q = sm.shapes.canonical_domain(genus, "n-torus", "row", 20 if genus == 2 else 16)
        V = posed_like(V, shape["V"])
        sm.write_obj(os.path.join(out, f"domain_g{genus}.obj"), V, F)
        print(f"domain_demo: {q['description']}: {len(V)} vertices, min angle "
              f"{q['min_angle_deg']:.1f} deg")
        tag = f"d{genus}"
        demo.PAIRS[tag] = (genus, f"{name}.obj", f"domain_g{genus}.obj")
        objs += demo.demo_pair(sm, out, tag, 6.0 * i, cam, out, written)
    demo.show_only(objs, curves=True)
    blend = os.path.join(out, "domain_demo.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    print("domain_demo: wrote", ", ".join(os.path.basename(p) for p in written + [blend]))


main()
