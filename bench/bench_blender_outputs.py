"""Blender-side benchmark: surfmap.compute_map on pairs of real meshes of equal genus, with a
cube-projection UV map (many islands) on the source; prints one table row per pair.

  blender -b --factory-startup --python bench/bench_blender_outputs.py -- [MESH_DIR]

MESH_DIR defaults to shared/meshes beside the repository (or beside a parent folder) (files named g<genus>_*.{obj,off}).
Columns: time of compute_map; transferred UV triangles flipped / straddling a seam, and the
naive per-vertex transfer's straddling count; Data Transfer's (nearest face interpolated)
flipped / stretched triangles with both objects on top of each other; the worst distance of a
morphed vertex from the other surface (fraction of its bounding-box diagonal); mean D'.
"""
import glob
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "blender_tests"))
sys.path.insert(0, os.path.join(REPO, "addon"))

import addon_utils  # noqa: E402

addon_utils.enable("surface_map", default_set=True, handle_error=None)
import helpers  # noqa: E402
from surface_map import geometry, uv_transfer  # noqa: E402


def load(path, name, location):
    V, polys = helpers.sm().read_polygon_soup(path)
    return helpers.mesh_object(name, np.asarray(V), [list(p) for p in polys], location)


def uv_counts(src, tgt, uv_name):
    Fs, Ls = helpers.triangles_of(src)
    Ft, Lt = helpers.triangles_of(tgt)
    Vs, Vt = helpers.coords(src), helpers.coords(tgt)
    suv = helpers.loop_uv_array(src, uv_name)[Ls]
    tuv = helpers.loop_uv_array(tgt, f"surfmap {uv_name}")[Lt]
    face = np.array([d.value for d in tgt.data.attributes["surfmap_map_face"].data])
    bary = np.array([tuple(d.vector) for d in tgt.data.attributes["surfmap_map_bary"].data])
    pre = geometry.points_at(Vs, Fs, face, bary)[Ft]
    flipped = int(np.sum(uv_transfer.signed_uv_areas(tuv) <= 0))
    strad = uv_transfer.seam_straddling(tuv, pre, suv, Vs[Fs])
    naive = uv_transfer.seam_straddling(np.einsum("ik,ikj->ij", bary, suv[face])[Ft], pre, suv, Vs[Fs])
    return flipped, strad, naive, len(Ft)


def data_transfer(src, tgt, uv_name):
    Ft, Lt = helpers.triangles_of(tgt)
    Vt = helpers.coords(tgt)
    saved = src.location.copy(), tgt.location.copy()
    src.location = tgt.location = (0, 0, 0)
    tgt.data.uv_layers.active = tgt.data.uv_layers.new(name="DT")
    mod = tgt.modifiers.new("DT", 'DATA_TRANSFER')
    mod.object = src
    mod.use_loop_data = True
    mod.data_types_loops = {'UV'}
    mod.loop_mapping = 'POLYINTERP_NEAREST'
    mod.layers_uv_select_src = uv_name
    mod.layers_uv_select_dst = 'DT'
    ev = tgt.evaluated_get(bpy.context.evaluated_depsgraph_get())
    me = ev.to_mesh()
    dt = np.empty(len(me.loops) * 2)
    me.uv_layers["DT"].data.foreach_get("uv", dt)
    ev.to_mesh_clear()
    tgt.modifiers.remove(mod)
    tgt.data.uv_layers.remove(tgt.data.uv_layers["DT"])
    src.location, tgt.location = saved
    return uv_transfer.uv_quality(dt.reshape(-1, 2)[Lt], Vt[Ft])


def morph_error(src, tgt):
    kb = src.data.shape_keys.key_blocks[f"surfmap to {tgt.name}"]
    co = np.empty(len(src.data.vertices) * 3)
    kb.data.foreach_get("co", co)
    A, B = np.array(src.matrix_world), np.array(tgt.matrix_world)
    shift = np.eye(4)
    shift[:3, 3] = B[:3, 3] - A[:3, 3]
    P = geometry.apply_matrix(np.linalg.inv(B) @ shift @ A, co.reshape(-1, 3))
    worst = 0.0
    for p in P:
        _, loc, _, _ = tgt.closest_point_on_mesh(p)
        worst = max(worst, float(np.linalg.norm(np.array(loc) - p)))
    return worst / geometry.bounding_diagonal(helpers.coords(tgt))


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    mesh_dir = argv[0] if argv else None
    d = REPO
    while mesh_dir is None and os.path.dirname(d) != d:   # ../shared/meshes, from a worktree too
        d = os.path.dirname(d)
        if os.path.isdir(os.path.join(d, "shared", "meshes")):
            mesh_dir = os.path.join(d, "shared", "meshes")
    if mesh_dir is None:
        raise SystemExit("bench_blender_outputs.py: no shared/meshes folder found; pass MESH_DIR")
    files = sorted(glob.glob(os.path.join(mesh_dir, "g*_*.*")))
    by_genus = {}
    for f in files:
        by_genus.setdefault(int(os.path.basename(f)[1]), []).append(f)
    pairs = []
    for g, fs in sorted(by_genus.items()):
        fs = [f for f in fs if os.path.getsize(f) < 2_000_000]   # keep the run short
        pairs += [(g, fs[i], fs[i + 1]) for i in range(len(fs) - 1)] or \
            [(g, fs[0], fs[0])] if fs else []
    print("| genus | source -> target | result | time s | UV flipped | UV straddling | naive "
          "straddling | Data Transfer flipped/stretched | triangles | morph err | mean D' |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for g, a, b in pairs:
        helpers.reset_scene()
        na, nb = os.path.basename(a).split(".")[0], os.path.basename(b).split(".")[0]
        src = load(a, "S_" + na, (-3, 0, 0))
        tgt = load(b, "T_" + nb, (3, 0, 0))
        helpers.set_loop_uvs(src, "Box", helpers.box_uvs(src))
        helpers.select([src, tgt], tgt)
        t = time.time()
        res, err = helpers.run("compute_map")
        dt = time.time() - t
        if res != {'FINISHED'}:
            print(f"| {g} | {na} -> {nb} | CANCELLED: {(err or '').strip()[:80]} | {dt:.1f} "
                  f"| | | | | | | |")
            continue
        fl, st, nv, m = uv_counts(src, tgt, "Box")
        dfl, dst = data_transfer(src, tgt, "Box")
        me = max(morph_error(src, tgt), morph_error(tgt, src))
        meta = src.data["surfmap_map"]
        print(f"| {g} | {na} -> {nb} | ok | {dt:.1f} | {fl} | {st} | {nv} | {dfl}/{dst} | {m} "
              f"| {me:.1e} | {meta['mean_dilatation']:.3g} |")
        sys.stdout.flush()


main()
