"""The add-on's bpy-free texture bake (addon/surface_map/texture_bake.py), imported as a package
module outside Blender: unfolded source charts, the split target, rasterisation, bleed, and the bake
itself through the identity map (exact) and through a computed map between two tori."""
import pathlib
import sys

import numpy as np
import pytest

import surfmap

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "addon"))
from surface_map import texture_bake as TB  # noqa: E402  (the add-on's bpy-free half)


def torus(R, r, n, m):
    V, F = surfmap.shapes.torus_of_revolution(R, r, n, m)
    return np.asarray(V, dtype=float), np.asarray(F)


def torus_uv(V, F, R, du=0.0, dv=0.0, scale=1.0, offset=0.0):
    """(u, v) angles per triangle corner (shifted by du, dv), unwrapped per triangle: one
    island whose seams are at u = du, v = dv; scaled into [offset, offset + scale * 1.1]."""
    P = V[F]
    u = (np.arctan2(P[..., 1], P[..., 0]) / (2 * np.pi) + du) % 1.0
    v = (np.arctan2(P[..., 2], np.hypot(P[..., 0], P[..., 1]) - R) / (2 * np.pi) + dv) % 1.0
    for a in (u, v):
        a[:] = np.where(a.max(axis=1, keepdims=True) - a > 0.5, a + 1.0, a)
    return offset + scale * np.stack([u, v], -1)


def gradient_image(h=128, w=128):
    """R = u, G = v (jumps across the source's seams), B a smooth wave."""
    yy, xx = np.mgrid[0:h, 0:w]
    img = np.ones((h, w, 4))
    img[..., 0] = (xx + 0.5) / w
    img[..., 1] = (yy + 0.5) / h
    img[..., 2] = 0.5 + 0.5 * np.sin(6 * np.pi * xx / w)
    return img


def identity_map(F, n):
    """Every vertex of a mesh onto itself: (face (n,), bary (n,3))."""
    face = np.zeros(n, dtype=np.int64)
    bary = np.zeros((n, 3))
    for k in range(3):
        face[F[:, k]] = np.arange(len(F))
    for k in range(3):
        hit = F[face, k] == np.arange(n)
        bary[hit, k] = 1.0
    return face, bary


def test_charts_are_isometric_unfoldings():
    V, F = torus(1.0, 0.4, 16, 10)
    ch = TB.SourceCharts(V, F, rings=3)
    assert np.all(ch.faces[:, 0] == np.arange(len(F)))            # the anchor first
    for a in (0, 7, 55, len(F) - 1):
        for s, f in enumerate(ch.faces[a]):
            if f < 0:
                continue
            C = ch.corners[a, s]
            for k in range(3):
                d2 = np.linalg.norm(C[(k + 1) % 3] - C[k])
                d3 = np.linalg.norm(V[F[f, (k + 1) % 3]] - V[F[f, k]])
                assert d2 == pytest.approx(d3, rel=1e-9)
            # the unfolding keeps the orientation (no mirrored triangle)
            e1, e2 = C[1] - C[0], C[2] - C[0]
            assert e1[0] * e2[1] - e1[1] * e2[0] > 0
        # the anchor's three neighbours are unfolded across its edges: the shared corners
        # coincide in the chart (an unfolding, not a scatter of triangles)
        pos = {int(f): ch.corners[a, s] for s, f in enumerate(ch.faces[a]) if f >= 0}
        nbrs = [g for g in pos if g != a and len(set(F[g]) & set(F[a])) == 2]
        assert len(nbrs) == 3
        for g in nbrs:
            for v in set(F[g]) & set(F[a]):
                pa = pos[a][list(F[a]).index(v)]
                pg = pos[g][list(F[g]).index(v)]
                assert np.linalg.norm(pa - pg) < 1e-9
    assert ch.slot(0, 0) == 0
    far = int(np.argmax(np.linalg.norm(V[F].mean(1) - V[F[0]].mean(0), axis=1)))
    assert ch.slot(0, far) == -1                  # the far side of the torus is in no chart of 0


def test_rasterize_covers_the_unit_square_once_per_sample():
    uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], dtype=float)
    got = np.zeros(32 * 16, dtype=int)
    for t, w, texel in TB.rasterize(uv, 32, 16, supersample=3):
        assert np.all(w >= -1e-9) and np.allclose(w.sum(1), 1.0)
        got += np.bincount(texel, minlength=32 * 16)
    # 9 samples per texel; the diagonal's samples may come from both triangles
    assert got.min() >= 9 and got.sum() < 9 * 32 * 16 + 3 * 48
    assert TB.island_mask(uv * 0.5, 32, 16).sum() == pytest.approx(32 * 16 / 4, abs=20)


def test_bleed_grows_by_margin_texels():
    filled = np.zeros((20, 20), dtype=bool)
    filled[8:12, 8:12] = True
    img = np.zeros((20, 20, 4))
    img[filled] = (0.2, 0.4, 0.6, 1.0)
    out, ok = TB.bleed(img, filled, 3)
    yy, xx = np.mgrid[0:20, 0:20]
    cheb = np.maximum(np.maximum(8 - yy, yy - 11), np.maximum(8 - xx, xx - 11))
    assert np.array_equal(ok, cheb <= 3)
    assert np.allclose(out[ok], (0.2, 0.4, 0.6, 1.0))
    assert np.all(out[~ok] == 0)


def test_identity_map_bakes_the_source_exactly():
    """Source = target, every vertex onto itself: each texel (one sample at its centre) must
    be the source's colour at the same surface point, in another UV layout of the target."""
    V, F = torus(1.0, 0.5, 24, 12)
    uv_src = torus_uv(V, F, 1.0)
    uv_tgt = torus_uv(V, F, 1.0, du=0.3, dv=0.55, scale=0.8, offset=0.05)
    img = gradient_image()
    colour = TB.SourceColour(materials=[{"image": img, "corner_uv": uv_src}])
    ident = identity_map(F, len(V))
    res = TB.bake(V, F, F, uv_tgt, ident, ident, colour, 96, 96, supersample=1, margin=2)
    assert res["unlocated"] == 0 and res["clamped"] == 0 and res["inserted"] == 0
    assert res["fill_fraction"] == 1.0
    worst = 0.0
    for t, w, texel in TB.rasterize(uv_tgt, 96, 96, 1):
        want = colour(t, w)
        got = res["image"].reshape(-1, 4)[texel]
        worst = max(worst, float(np.abs(got - want).max()))
    assert worst < 1e-5   # float32 image


@pytest.fixture(scope="module")
def tori():
    Vs, Fs = torus(1.0, 0.5, 48, 24)
    Vt, Ft = torus(1.5, 0.5, 40, 20)
    # The default target metric (the flip-based one). Its map puts 272 of the source's
    # vertices exactly on target edges here (base vertex on base vertex of two symmetric
    # tori); the split inserts them on both sides of their edge (docs/baking.md).
    m = surfmap.surface_map(Vs, Fs, Vt, Ft)
    fw = (m["forward"]["face"], m["forward"]["barycentric"])
    iv = (m["inverse"]["face"], m["inverse"]["barycentric"])
    return Vs, Fs, Vt, Ft, fw, iv


def test_split_target_nodes_are_the_map_itself(tori):
    Vs, Fs, Vt, Ft, fw, iv = tori
    st = TB.SplitTarget(Fs, Ft, *fw, *iv, V_tgt=Vt)
    assert st.inserted > 0.5 * len(Vs)           # most source vertices lie inside triangles
    assert len(st.parent) == len(Ft) + 2 * st.inserted
    # the sub-triangles tile their parents: same orientation, areas adding up to the parent's
    T = st.node_bary[..., 1:]                      # in the parent's (b1, b2) plane, area 1/2
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    assert det.min() > -1e-12
    assert np.allclose(np.bincount(st.parent, weights=det, minlength=len(Ft)), 1.0)
    pre = TB.Preimages(TB.SourceCharts(Vs, Fs), st, Fs, Vs)
    # the images of the source vertices go back to the vertices ...
    f, b = TB.locate_target_points(st, pre, *fw)
    back = np.einsum("ij,ijk->ik", b, Vs[Fs[f]])
    inside = fw[1].min(axis=1) > 1e-6
    assert np.abs(back - Vs)[inside].max() < 1e-9
    # ... and the target's vertices to their stored preimages
    for k in range(3):
        unit = np.zeros((len(Ft), 3))
        unit[:, k] = 1.0
        f, b = TB.locate_target_points(st, pre, np.arange(len(Ft)), unit)
        got = np.einsum("ij,ijk->ik", b, Vs[Fs[f]])
        want = np.einsum("ij,ijk->ik", iv[1][Ft[:, k]], Vs[Fs[iv[0][Ft[:, k]]]])
        assert np.abs(got - want).max() < 1e-9
    # between the nodes the preimage moves continuously: random points and their neighbours
    face, bary = TB.random_target_points(Ft, Vt, 2000, seed=1)
    f0, b0 = TB.locate_target_points(st, pre, face, bary)
    nudge = bary + 1e-4 * (np.roll(bary, 1, axis=1) - bary)
    f1, b1 = TB.locate_target_points(st, pre, face, nudge)
    p0 = np.einsum("ij,ijk->ik", b0, Vs[Fs[f0]])
    p1 = np.einsum("ij,ijk->ik", b1, Vs[Fs[f1]])
    step = np.linalg.norm(np.einsum("ij,ijk->ik", nudge - bary, Vt[Ft[face]]), axis=1)
    assert np.percentile(np.linalg.norm(p1 - p0, axis=1) / step, 99) < 10


def test_split_target_inserts_images_on_edges_into_both_triangles():
    """A source vertex whose image lies exactly on a target edge becomes a node of both
    triangles of that edge, at the same point (no T-junction); one on a target vertex is
    that vertex's node already; one inside a triangle splits it alone."""
    Vt = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    Ft = np.array([[0, 1, 2], [0, 2, 3]])                  # edge 0-2 shared
    Fs = np.array([[0, 1, 2], [0, 2, 3], [1, 4, 2]])
    fw_face = np.array([0, 1, 0, 0, 1])
    fw_bary = np.array([[0.5, 0.0, 0.5],                   # on edge 0-2 (in triangle 0)
                        [0.0, 1.0, 0.0],                   # on target vertex 2
                        [0.2, 0.5, 0.3],                   # inside triangle 0
                        [0.7, 0.3, 0.0],                   # on the boundary edge 0-1 (no twin)
                        [0.3, 0.3, 0.4]])                  # inside triangle 1
    inv_face = np.array([0, 0, 1, 2])                      # target vertices inside source faces
    inv_bary = np.array([[0.6, 0.2, 0.2], [0.2, 0.6, 0.2], [0.2, 0.2, 0.6], [0.3, 0.3, 0.4]])
    st = TB.SplitTarget(Fs, Ft, fw_face, fw_bary, inv_face, inv_bary, V_tgt=Vt)
    assert st.inserted == 4                                # all but the one on a vertex
    # each point inside or on a shared edge adds two triangles, on a boundary edge one
    assert len(st.parent) == len(Ft) + 2 * 3 + 1
    T = st.node_bary[..., 1:]
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    assert det.min() > 1e-9                                # no zero-area sliver on an edge
    assert np.allclose(np.bincount(st.parent, weights=det, minlength=2), 1.0)
    # source vertex 0 (node: its triangle with a unit weight) is a node of both parents, at
    # the midpoint of the diagonal in 3D from either side
    at = []
    for e, c in zip(*np.nonzero(st.node_src_bary.max(axis=2) == 1.0)):
        if Fs[st.node_face[e, c], np.argmax(st.node_src_bary[e, c])] == 0:
            at.append((st.parent[e], st.node_bary[e, c] @ Vt[Ft[st.parent[e]]]))
    assert {p for p, _ in at} == {0, 1}
    assert all(np.allclose(X, [0.5, 0.5, 0.0]) for _, X in at)


def test_bake_through_a_map_fills_islands_and_matches_the_source(tori):
    """The source's (u, v) gradient jumps along its seams; the bake must reproduce it at the
    exact points of the map, also one and two rings from the seams (where a per-corner UV
    transfer puts whole target triangles into the wrong chart)."""
    Vs, Fs, Vt, Ft, fw, iv = tori
    uv_src = torus_uv(Vs, Fs, 1.0)
    uv_tgt = torus_uv(Vt, Ft, 1.5, du=0.37, dv=0.61, scale=0.8, offset=0.05)
    colour = TB.SourceColour(materials=[{"image": gradient_image(256, 256), "corner_uv": uv_src}])
    res = TB.bake(Vs, Fs, Ft, uv_tgt, fw, iv, colour, 512, 512, supersample=2, margin=4)
    assert res["fill_fraction"] > 0.999
    assert res["unlocated"] <= 2 and res["clamped"] < 1e-3 * res["samples"]
    near = TB.seam_vertices(Fs, uv_src, rings=2) & ~TB.seam_vertices(Fs, uv_src, rings=0)
    err = TB.bake_error_at_nodes(res["image"], Fs, Ft, uv_tgt, fw, iv, colour, near)
    assert len(err["near_seams"]) > 50
    assert np.percentile(err["source_vertices"], 90) < 0.01
    assert np.percentile(err["target_vertices"], 90) < 0.01
    assert err["near_seams"].max() < 0.02
    # a wrong map (the target's vertices shifted to other preimages) is caught
    bad = (np.roll(iv[0], 7), np.roll(iv[1], 7, axis=0))
    res_bad = TB.bake(Vs, Fs, Ft, uv_tgt, fw, bad, colour, 128, 128, supersample=1, margin=1,
                      split=False)
    err_bad = TB.bake_error_at_nodes(res_bad["image"], Fs, Ft, uv_tgt, fw, iv, colour)
    assert np.percentile(err_bad["target_vertices"], 90) > 0.05
