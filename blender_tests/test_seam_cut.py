"""surfmap.cut_along_seams: a copy of the target cut along the images of the source's UV seams.

Checked independently of the cut's own bookkeeping, by locating every UV of the cut copy in the
source's UV triangles: no face of the copy has corners in two islands (the transferred map on
the uncut target does, so the check can fail), and where the copy has several UVs at one
vertex they all show the same source point (a texture is continuous across the cut)."""
import bpy
import numpy as np

import helpers
from helpers import run, select


def _pair(uv_name):
    a = helpers.torus("Source", 1.0, 0.5, (-3, 0, 0))
    bpy.ops.mesh.primitive_torus_add(major_segments=40, minor_segments=16, major_radius=1.5,
                                     minor_radius=0.5, location=(3, 0, 0))
    b = bpy.context.active_object
    b.name = "Target"
    helpers.set_loop_uvs(a, "UVMap", helpers.torus_uvs(a, 1.0))
    helpers.set_loop_uvs(a, "Box", helpers.box_uvs(a))
    a.data.uv_layers.active = a.data.uv_layers[uv_name]
    select([a, b], b)
    return a, b


class _SourceUV:
    """Locates UV points in the source's UV triangles. A layout may overlap (a cube projection
    of a torus puts the outer and the inner wall facing +x in one cell), so each point gets
    every (source 3D point, island) whose UV triangle holds it."""

    def __init__(self, src, uv_name):
        from surface_map import uv_transfer
        F, L = helpers.triangles_of(src)
        self.U = helpers.loop_uv_array(src, uv_name)[L]
        self.X = helpers.coords(src)[F]
        self.island = uv_transfer.uv_islands(F, self.U)

    def locate(self, uv):
        U = self.U
        e1, e2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        ok = np.abs(det) > 1e-14
        out = []
        for p in uv:
            r = p - U[:, 0]
            with np.errstate(divide="ignore", invalid="ignore"):
                l1 = (r[:, 0] * e2[:, 1] - e2[:, 0] * r[:, 1]) / det
                l2 = (e1[:, 0] * r[:, 1] - r[:, 0] * e1[:, 1]) / det
            t = 1e-5
            inside = np.nonzero(ok & (l1 >= -t) & (l2 >= -t) & (l1 + l2 <= 1 + t))[0]
            X = self.X[inside]
            P = X[:, 0] + l1[inside, None] * (X[:, 1] - X[:, 0]) \
                + l2[inside, None] * (X[:, 2] - X[:, 0])
            out.append((P, set(self.island[inside].tolist())))
        return out


def _mixed(me, found):
    """Faces whose corners' UVs are not all in one island."""
    n = 0
    for p in me.polygons:
        sets = [found[l][1] for l in range(p.loop_start, p.loop_start + p.loop_total)]
        n += not set.intersection(*sets)
    return n


def _check(uv_name):
    a, b = _pair(uv_name)
    bpy.context.scene.surfmap.write_distortion = False
    res, err = run("compute_map")
    assert err is None and res == {'FINISHED'}, err
    loc = _SourceUV(a, uv_name)
    # the transferred map on the uncut target: faces across seams (continued charts)
    before = _mixed(b.data, loc.locate(helpers.loop_uv_array(b, f"surfmap {uv_name}")))
    n_faces = len(b.data.polygons)
    res, err = run("cut_along_seams")
    assert err is None and res == {'FINISHED'}, err
    cut = bpy.data.objects.get("Target cut along seams")
    assert cut is not None and len(b.data.polygons) == n_faces       # the target unchanged
    me = cut.data
    assert len(me.polygons) > n_faces
    uv = helpers.loop_uv_array(cut, uv_name)
    found = loc.locate(uv)
    after = _mixed(me, found)
    # continuity: at every vertex with several UVs, they show one source point (the closest
    # pair of candidates when the layout overlaps)
    lv = np.array([l.vertex_index for l in me.loops])
    worst, shared = 0.0, 0
    for v in np.unique(lv):
        at = np.nonzero(lv == v)[0]
        if np.ptp(uv[at], axis=0).max() <= 1e-6:
            continue
        shared += 1
        P0 = found[at[0]][0]
        for l in at[1:]:
            P1 = found[l][0]
            d = np.linalg.norm(P0[:, None] - P1[None], axis=2).min() if len(P0) and len(P1) \
                else np.inf
            worst = max(worst, float(d))
    return before, after, shared, worst


def test_cut_along_box_seams():
    before, after, shared, worst = _check("Box")
    print("box: straddling before", before, "after", after, "cut vertices", shared,
          "worst gap", worst)
    assert before >= 10 and after == 0, (before, after)
    assert shared >= 50 and worst < 1e-4, (shared, worst)


def test_cut_along_torus_wrap_seams():
    before, after, shared, worst = _check("UVMap")
    print("torus: straddling before", before, "after", after, "cut vertices", shared,
          "worst gap", worst)
    assert before >= 10 and after == 0, (before, after)
    assert shared >= 20 and worst < 1e-4, (shared, worst)


def test_cut_needs_a_stored_map():
    a, b = _pair("Box")
    before = helpers.scene_snapshot()
    res, err = run("cut_along_seams")
    assert res is None and "no stored map" in err, err
    assert helpers.scene_snapshot() == before
