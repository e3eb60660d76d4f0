"""Blender-side measurement of surfmap.bake_textures against the transferred UVs and Blender's
own Selected-to-Active bake, on the shipped genus-2 sample pair and on real genus-2 meshes.

  blender -b --factory-startup --python bench/bench_bake.py -- [MESH_DIR] [--resolution N]
      [--no-cycles] [--only LABEL] [--target-metric auto|flips|fixed|fixed-first]

MESH_DIR: the real meshes (default shared/meshes beside the repository); the pairs are
samples/meshes double_torus_g2 -> vase_g2 and triple_torus_g3 -> polycube_g3, and MESH_DIR
g2_double-torus_gpjs -> g2_eight_summer (--only: the pairs whose label contains LABEL).
--target-metric: the map's target metric (default: the add-on's, the core's default; to compare
the flip-based metric with the fixed connectivity, docs/baking.md).
The source gets a cube-projection UV map (six islands: many seams) and a checker image (16 x 16
squares of two colours). Per pair it prints:
  fill      fraction of the target's island texels the bake filled
  nodes     colour error (max over RGB, 0..1; the checker's two colours differ by 0.8) at the
            images of the source's vertices and at the target's vertices, where the stored map
            is exact; 'seams': source vertices one or two rings from a seam
  random    N target points (uniform by area), their preimages through the bake's
            interpolation (texture_bake.locate_target_points): the baked texel against the
            source's image there, and the same for the checker through the transferred UVs
            ('surfmap <uv>') and through Blender's Selected-to-Active bake into the same UV
            layout (samples/demo_bake.py: Cycles, or the same rays through mathutils.bvhtree
            when Cycles bakes black); 'seams' = points whose preimage is within one ring of a source seam;
            'wrong' = fraction of points with error > 0.25 (the other square's colour)
  bands     the same errors by how many rings the preimage's source triangle is from a source
            UV seam (on a seam, 1-3 rings, 4+ rings = away) and each band's mean over the
            away mean: saw-teeth along the seams' images show as band means well above away
"""
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "blender_tests"))
sys.path.insert(0, os.path.join(REPO, "addon"))
sys.path.insert(0, os.path.join(REPO, "samples"))

import addon_utils  # noqa: E402

addon_utils.enable("surface_map", default_set=True, handle_error=None)
import helpers  # noqa: E402
from surface_map import uv_transfer  # noqa: E402
from surface_map import texture_bake as TB  # noqa: E402


def args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    opts = {"dir": None, "resolution": 1024, "cycles": True, "points": 20000, "only": None,
            "target_metric": None}
    i = 0
    while i < len(argv):
        a = argv[i]
        if a == "--resolution":
            opts["resolution"] = int(argv[i + 1])
            i += 1
        elif a == "--only":
            opts["only"] = argv[i + 1]
            i += 1
        elif a == "--target-metric":
            opts["target_metric"] = argv[i + 1]
            i += 1
        elif a == "--no-cycles":
            opts["cycles"] = False
        elif a == "--points":
            opts["points"] = int(argv[i + 1])
            i += 1
        else:
            opts["dir"] = a
        i += 1
    if opts["dir"] is None:
        for up in (REPO, os.path.dirname(REPO), os.path.dirname(os.path.dirname(REPO))):
            d = os.path.join(os.path.dirname(up), "shared", "meshes")
            if os.path.isdir(d):
                opts["dir"] = d
                break
    return opts


def load(path, name):
    V, polys = helpers.sm().read_polygon_soup(path)
    V = np.asarray(V, dtype=float)
    V = (V - (V.max(0) + V.min(0)) / 2) * (2.0 / np.linalg.norm(V.max(0) - V.min(0)))
    return helpers.mesh_object(name, V, [list(p) for p in polys])


def checker_pixels(size=1024, cells=16):
    c = (np.arange(size) + 0.5) / size * cells
    xi = np.floor(c).astype(np.int64) % 2
    odd = xi[None, :] != xi[:, None]
    return np.where(odd[..., None], (0.85, 0.55, 0.12, 1.0), (0.08, 0.25, 0.55, 1.0)).astype(np.float32)


def image_material(name, image, uv_map):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    uv = nt.nodes.new("ShaderNodeUVMap")
    uv.uv_map = uv_map
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    nt.nodes.active = tex
    return mat


def pixels(img):
    w, h = img.size
    a = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(a)
    return a.reshape(h, w, 4)


def selected_to_active(src, tgt, uv_name, res, px):
    """Blender's Selected-to-Active bake as the demo runs it (samples/demo_bake.py: Cycles,
    or the same rays through mathutils.bvhtree when Cycles returns black)."""
    import types
    import demo_bake

    def set_material(ob, mat):
        ob.data.materials.clear()
        ob.data.materials.append(mat)
    bpy.context.scene.render.engine = 'CYCLES'
    bpy.context.scene.cycles.device = 'CPU'
    copy, seconds, how = demo_bake.selected_to_active(
        types.SimpleNamespace(set_material=set_material), src, tgt, uv_name, "UVMap", px, res)
    img = next(n.image for n in copy.data.materials[0].node_tree.nodes if n.type == 'TEX_IMAGE')
    return pixels(img), seconds, how


def stats(e, wrong=0.25):
    if len(e) == 0:
        return "-"
    return (f"mean {e.mean():.4f} p99 {np.percentile(e, 99):.3f} max {e.max():.3f} "
            f"wrong {100 * np.mean(e > wrong):.2f}% (n={len(e)})")


def run_pair(label, src_path, tgt_path, opts):
    helpers.reset_scene()
    src, tgt = load(src_path, "src"), load(tgt_path, "tgt")
    me = src.data
    lv = np.empty(len(me.loops), dtype=np.int64)
    me.loops.foreach_get("vertex_index", lv)
    st = np.empty(len(me.polygons), dtype=np.int64)
    me.polygons.foreach_get("loop_start", st)
    tot = np.empty(len(me.polygons), dtype=np.int64)
    me.polygons.foreach_get("loop_total", tot)
    helpers.set_loop_uvs(src, "UVMap", uv_transfer.box_projection(helpers.coords(src), lv, st, tot))
    px = checker_pixels()
    img = bpy.data.images.new("checker", px.shape[1], px.shape[0], alpha=True, float_buffer=True)
    img.pixels.foreach_set(px.ravel())
    src.data.materials.append(image_material("checker", img, "UVMap"))
    helpers.select([src, tgt], tgt)
    t = time.time()
    assert bpy.ops.surfmap.compute_map() == {'FINISHED'}
    t_map = time.time() - t
    res = opts["resolution"]
    t = time.time()
    assert bpy.ops.surfmap.bake_textures(resolution=res, supersample=2, margin=8) == {'FINISHED'}
    t_bake = time.time() - t
    baked = pixels(bpy.data.images["surfmap bake tgt texture"])
    Fs, Ls = helpers.triangles_of(src)
    Ft, Lt = helpers.triangles_of(tgt)
    Vs, Vt = helpers.coords(src), helpers.coords(tgt)
    suv = helpers.loop_uv_array(src, "UVMap")[Ls]
    tuv = helpers.loop_uv_array(tgt, "surfmap bake UV")[Lt]
    xuv = helpers.loop_uv_array(tgt, "surfmap UVMap")[Lt]        # the transferred UVs
    stored = {}
    for ob, key in ((src, "fw"), (tgt, "iv")):
        n = len(ob.data.vertices)
        f = np.empty(n, dtype=np.int32)
        ob.data.attributes["surfmap_map_face"].data.foreach_get("value", f)
        b = np.empty(n * 3, dtype=np.float32)
        ob.data.attributes["surfmap_map_bary"].data.foreach_get("vector", b)
        stored[key] = (f.astype(np.int64), b.reshape(-1, 3).astype(np.float64))
    colour = TB.SourceColour(materials=[{"image": px, "corner_uv": suv}])
    islands = TB.island_mask(tuv, res, res)
    fill = float(((baked[..., 3] > 0.999) & islands).sum() / islands.sum())
    near = TB.seam_vertices(Fs, suv, rings=2) & ~TB.seam_vertices(Fs, suv, rings=0)
    nodes = TB.bake_error_at_nodes(baked, Fs, Ft, tuv, stored["fw"], stored["iv"], colour, near)
    # random target points through the bake's own interpolation
    split = TB.SplitTarget(Fs, Ft, *stored["fw"], *stored["iv"], V_tgt=Vt)
    pre = TB.Preimages(TB.SourceCharts(Vs, Fs), split, Fs, Vs)
    face, bary = TB.random_target_points(Ft, Vt, opts["points"], seed=3)
    pf, pb = TB.locate_target_points(split, pre, face, bary)
    want = colour(pf, pb)[:, :3]
    seam_faces = TB.seam_vertices(Fs, suv, rings=1)[Fs[pf]].any(axis=1)
    at = lambda uv: np.einsum("ij,ijk->ik", bary, uv[face])      # noqa: E731
    err = {"bake": np.abs(TB.sample_image(baked, at(tuv))[:, :3] - want).max(1),
           "transferred UVs": np.abs(TB.sample_image(px, at(xuv))[:, :3] - want).max(1)}
    t_s2a = None
    if opts["cycles"]:
        s2a, t_s2a, how = selected_to_active(src, tgt, "surfmap bake UV", res, px)
        err[f"S2A {how}"] = np.abs(TB.sample_image(s2a, at(tuv))[:, :3] - want).max(1)
    print(f"\n## {label}: {os.path.basename(src_path)} ({len(Vs)} v) -> "
          f"{os.path.basename(tgt_path)} ({len(Vt)} v); image {res}^2")
    print(f"compute_map {t_map:.1f}s, bake_textures {t_bake:.1f}s"
          + (f", Selected to Active {t_s2a:.1f}s" if t_s2a is not None else ""))
    print(f"fill: {100 * fill:.3f}% of {int(islands.sum())} island texels")
    for k in ("source_vertices", "target_vertices", "near_seams"):
        print(f"nodes {k:16s} {stats(nodes[k])}")
    for k, e in err.items():
        print(f"random {k:26s} all:   {stats(e)}")
        print(f"random {k:26s} seams: {stats(e[seam_faces])}")
    print_bands(err, seam_ring_of_faces(Fs, suv)[pf])


def seam_ring_of_faces(Fs, suv, most=4):
    """(m,) per source triangle: 0 when a corner is on a UV seam, k when the nearest seam
    vertex is k rings away, `most` for `most` rings or more."""
    ring = np.full(len(Fs), most, dtype=np.int64)
    for k in range(most - 1, -1, -1):
        ring[TB.seam_vertices(Fs, suv, rings=k)[Fs].any(axis=1)] = k
    return ring


BANDS = (("band: on a seam", (0, 0)), ("band: 1-3 rings", (1, 3)), ("away: 4+ rings", (4, 99)))


def print_bands(err, ring):
    """The colour error in bands along the images of the source's seams against away from
    them (ring of the preimage's source triangle): a saw-tooth shows as a band error well
    above the away error. The ratio compares the means."""
    print("bands (preimage's rings from a source seam): mean error, wrong %, n; ratio = "
          "band mean / away mean")
    for k, e in err.items():
        away = e[ring >= 4]
        cells = []
        for name, (lo, hi) in BANDS:
            sel = e[(ring >= lo) & (ring <= hi)]
            if len(sel) == 0:
                cells.append(f"{name}: -")
                continue
            ratio = sel.mean() / away.mean() if len(away) and away.mean() > 0 else float("nan")
            cells.append(f"{name}: {sel.mean():.4f} / {100 * np.mean(sel > 0.25):.2f}% / "
                         f"{len(sel)} (x{ratio:.2f})")
        print(f"  {k:26s} " + "; ".join(cells))


def with_target_metric(name):
    """Makes the add-on's map job ask the native module for the target metric `name`."""
    mod = helpers.sm()
    solve = mod.surface_map

    def surface_map(*a, **kw):
        kw.setdefault("target_metric", name)
        return solve(*a, **kw)
    mod.surface_map = surface_map


def main():
    opts = args()
    if opts["target_metric"]:
        with_target_metric(opts["target_metric"])
        print(f"target metric: {opts['target_metric']}")
    samples = os.path.join(REPO, "samples", "meshes")
    pairs = [("sample g2", os.path.join(samples, "double_torus_g2.obj"),
              os.path.join(samples, "vase_g2.obj")),
             ("sample g3", os.path.join(samples, "triple_torus_g3.obj"),
              os.path.join(samples, "polycube_g3.obj"))]
    if opts["only"]:
        pairs = [p for p in pairs if opts["only"] in p[0]]
    if opts["dir"] and not opts["only"]:
        pairs.append(("real g2", os.path.join(opts["dir"], "g2_double-torus_gpjs.obj"),
                      os.path.join(opts["dir"], "g2_eight_summer.off")))
    for p in pairs:
        if all(os.path.exists(x) for x in p[1:]):
            run_pair(*p, opts)
        else:
            print(f"\n## {p[0]}: missing {p[1:]}")


main()
