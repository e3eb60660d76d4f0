"""uv_transfer.SeamCut (bpy-free): the target cut along the images of the source's UV seams.

Source and target are two triangulations of one torus, both given as grids over the parameter
square [0,1)^2 (the target's sheared against the source's, with quads), so the inverse and
forward maps are exact point locations in the parameter square. The source's UV map has three
islands (x < 0.5; x >= 0.5, y < 0.7; x >= 0.5, y >= 0.7), each an affine image of the parameter
square in its own box, plus the wrap-around seams; so its seam graph has junctions. Every
check below locates UVs in the SOURCE's UV triangles by brute force, independently of the cut:
- after the cut, no polygon has corners in different islands (or outside every island);
- at every vertex and chord midpoint where the cut target has several UVs, they all lead back
  to the same source point (a texture is continuous across the cut);
- the pieces of each target polygon cover it exactly, with the polygon's orientation.
"""
import importlib
import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "addon"))
uv_transfer = importlib.import_module("surface_map.uv_transfer")

R_MAJOR, R_MINOR = 2.0, 0.7


def embed(xy):
    x, y = 2 * np.pi * xy[:, 0], 2 * np.pi * xy[:, 1]
    return np.stack([(R_MAJOR + R_MINOR * np.cos(y)) * np.cos(x),
                     (R_MAJOR + R_MINOR * np.cos(y)) * np.sin(x), R_MINOR * np.sin(y)], 1)


def source_grid(n1, n2):
    """Parameters (n,2), triangles (m,3), the unwrapped parameter of every triangle corner
    (m,3,2)."""
    i, j = np.meshgrid(np.arange(n1), np.arange(n2), indexing="ij")
    P = np.stack([i.ravel() / n1, j.ravel() / n2], 1)
    vid = lambda a, b: (a % n1) * n2 + (b % n2)
    F, Q = [], []
    for a in range(n1):
        for b in range(n2):
            c = [(a, b), (a + 1, b), (a + 1, b + 1), (a, b + 1)]
            for tri in ((0, 1, 2), (0, 2, 3)):
                F.append([vid(*c[t]) for t in tri])
                Q.append([(c[t][0] / n1, c[t][1] / n2) for t in tri])
    return P, np.asarray(F), np.asarray(Q, dtype=float)


# island boxes: island k maps the parameter (x, y) affinely into its own part of the UV square
def island_of(xy):
    x, y = xy[..., 0], xy[..., 1]
    return np.where(x < 0.5, 0, np.where(y < 0.7, 1, 2))


def island_uv(k, xy):
    x, y = xy[..., 0], xy[..., 1]
    return [np.stack([0.9 * x, 0.45 * y], -1),
            np.stack([0.5 + 0.6 * y, 0.5 + 0.8 * (x - 0.5)], -1),
            np.stack([0.5 + 0.8 * (x - 0.5), 0.05 + 1.2 * (y - 0.7)], -1)][k]


def locate(n1, n2, xy):
    """(face, barycentric) of parameter points in source_grid(n1, n2)."""
    xy = np.mod(xy, 1.0)
    a = np.minimum((xy[:, 0] * n1).astype(int), n1 - 1)
    b = np.minimum((xy[:, 1] * n2).astype(int), n2 - 1)
    fx, fy = xy[:, 0] * n1 - a, xy[:, 1] * n2 - b
    lower = fx >= fy
    face = 2 * (a * n2 + b) + (~lower)
    bary = np.where(lower[:, None], np.stack([1 - fx, fx - fy, fy], 1),
                    np.stack([1 - fy, fx, fy - fx], 1))
    return face, bary


@pytest.fixture(scope="module")
def pair():
    return make_pair(0.013, 0.021)


@pytest.fixture(scope="module")
def aligned_pair():
    """The same pair with the target's vertex 0 exactly on the source's vertex 0, where the
    wrap-around seams cross (a seam junction), and the target's row j = 0 exactly along the
    seam y = 0: target vertices on source vertices and seam edges, target edges along a seam,
    a junction on a target vertex, as symmetric meshes give (a torus onto a torus with base
    vertex on base vertex)."""
    return make_pair(0.0, 0.0)


def make_pair(dx, dy):
    n1, n2 = 20, 20
    Ps, Fs, Q = source_grid(n1, n2)
    isl = island_of(Q.mean(axis=1))
    corner_uv = np.zeros_like(Q)
    for k in range(3):
        corner_uv[isl == k] = island_uv(k, Q[isl == k])
    # the target: a sheared 7 x 9 quad grid (its parameter wraps consistently)
    m1, m2 = 7, 9
    i, j = np.meshgrid(np.arange(m1), np.arange(m2), indexing="ij")
    Pt = np.stack([i.ravel() / m1 + j.ravel() / m2 + dx, j.ravel() / m2 + dy], 1) % 1.0
    vid = lambda a, b: (a % m1) * m2 + (b % m2)
    quads = [[vid(a, b), vid(a + 1, b), vid(a + 1, b + 1), vid(a, b + 1)]
             for a in range(m1) for b in range(m2)]
    lv = np.asarray(quads).ravel()
    start, total = np.arange(0, len(lv), 4), np.full(len(quads), 4)
    Ft = np.asarray([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])
    tri_poly = np.concatenate([np.arange(len(quads))] * 2)
    inv_f, inv_b = locate(n1, n2, Pt)
    # forward: source vertices in the target's triangles (located in the sheared grid)
    u = Ps[:, 1] * m2 - dy * m2
    v = (Ps[:, 0] - dx - (Ps[:, 1] - dy)) * m1
    lt = np.stack([np.mod(v, m1), np.mod(u, m2)], 1)   # (i, j) continuous target grid coords
    a, b = np.floor(lt[:, 0]).astype(int), np.floor(lt[:, 1]).astype(int)
    fx, fy = lt[:, 0] - a, lt[:, 1] - b
    lower = fx >= fy
    q = a * m2 + b
    fw_f = np.where(lower, q, q + len(quads))
    fw_b = np.where(lower[:, None], np.stack([1 - fx, fx - fy, fy], 1),
                    np.stack([1 - fy, fx, fy - fx], 1))
    return dict(n1=n1, n2=n2, Ps=Ps, Fs=Fs, Q=Q, uv=corner_uv, isl=isl, Pt=Pt, lv=lv,
                start=start, total=total, Ft=Ft, tri_poly=tri_poly, inv=(inv_f, inv_b),
                fw=(fw_f, fw_b))


def uv_to_param(d, uv):
    """For UV points (k,2): the parameter point of the source they show (nan when outside
    every island) and the island (-1 outside), by locating them in the source's UV triangles."""
    U = d["uv"]
    e1, e2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    out = np.full((len(uv), 2), np.nan)
    isl = -np.ones(len(uv), dtype=int)
    for n, p in enumerate(uv):
        r = p - U[:, 0]
        l1 = (r[:, 0] * e2[:, 1] - e2[:, 0] * r[:, 1]) / det
        l2 = (e1[:, 0] * r[:, 1] - r[:, 0] * e1[:, 1]) / det
        inside = np.nonzero((l1 >= -1e-9) & (l2 >= -1e-9) & (l1 + l2 <= 1 + 1e-9))[0]
        if len(inside):
            f = inside[0]
            Qf = d["Q"][f]
            out[n] = Qf[0] + l1[f] * (Qf[1] - Qf[0]) + l2[f] * (Qf[2] - Qf[0])
            isl[n] = d["isl"][f]
    return out, isl


def param_dist(p, q):
    d = np.abs(p - q) % 1.0
    return np.hypot(*np.minimum(d, 1 - d).T)


def mixed_polygons(d, start, total, loop_uv):
    """Polygons whose corners' UVs are not all inside one island."""
    _, isl = uv_to_param(d, loop_uv)
    return sum(1 for s, n in zip(start, total)
               if isl[s] < 0 or np.any(isl[s:s + n] != isl[s]))


def make_cut(d, with_forward=True):
    tr = uv_transfer.UVTransfer(d["Fs"], d["uv"], embed(d["Ps"]))
    kw = dict(fw_face=d["fw"][0], fw_bary=d["fw"][1], F_t=d["Ft"],
              tri_polygon=d["tri_poly"]) if with_forward else {}
    return tr, uv_transfer.SeamCut(tr, embed(d["Pt"]), d["start"], d["total"], d["lv"],
                                   *d["inv"], **kw).run()


def test_forward_and_inverse_agree(pair):
    """The fixture's maps are exact: a source vertex's image lands on its own parameter."""
    d = pair
    fw_f, fw_b = d["fw"]
    quads = d["lv"].reshape(-1, 4)
    Ft = d["Ft"]
    # target corner parameters unwrapped around the triangle's first corner
    P = d["Pt"][Ft[fw_f]]
    P = P[:, :1] + ((P - P[:, :1] + 0.5) % 1.0 - 0.5)
    img = np.einsum("ik,ikj->ij", fw_b, P)
    assert np.all(fw_b >= -1e-9) and param_dist(img, d["Ps"]).max() < 1e-9
    assert len(quads) == 63


def test_naive_transfer_straddles(pair):
    """Without the cut, many target polygons have corners in different islands (the test
    below can fail)."""
    d = pair
    tr = uv_transfer.UVTransfer(d["Fs"], d["uv"], embed(d["Ps"]))
    lf, lb = d["inv"][0][d["lv"]], d["inv"][1][d["lv"]]
    assert mixed_polygons(d, d["start"], d["total"], tr.naive(lf, lb)) >= 15
    uv, _ = tr.polygon_uvs(lf, lb, d["start"], d["total"])   # continued charts: outside islands
    assert mixed_polygons(d, d["start"], d["total"], uv) >= 15


def test_cut_leaves_no_polygon_across_charts(pair):
    d = pair
    _, cut = make_cut(d)
    assert cut.unresolved == 0 and cut.cut >= 15 and cut.junctions >= 3, vars(cut).keys()
    assert mixed_polygons(d, cut.loop_start, cut.loop_total, cut.loop_uv) == 0
    # every corner's UV shows the source point at the corner: exactly at the target's own
    # vertices; at the new ones within a fraction of a target edge (the trace runs straight in
    # the unfolded chart, the fixture's map straight in the parameter square: between
    # vertices a map is only known up to such a choice)
    param, _ = uv_to_param(d, cut.loop_uv)
    assert np.all(np.isfinite(param))
    want = np.full_like(param, np.nan)
    old = cut.loop_vertex < len(d["Pt"])
    want[old] = d["Pt"][cut.loop_vertex[old]]
    P3 = embed(d["Pt"])
    q = d["lv"].reshape(-1, 4)
    for a, b in zip(q.ravel(), np.roll(q, -1, axis=1).ravel()):   # new vertices on edge a-b
        e = P3[b] - P3[a]
        t = (cut.V - P3[a]) @ e / (e @ e)
        on = np.linalg.norm(cut.V - P3[a] - t[:, None] * e, axis=1) < 1e-9 * np.sqrt(e @ e)
        pa, pb = d["Pt"][a], d["Pt"][b]
        pb = pa + (pb - pa + 0.5) % 1.0 - 0.5
        for v in np.nonzero(on & (t > 0) & (t < 1))[0]:
            want[cut.loop_vertex == v] = (pa + t[v] * (pb - pa)) % 1.0
    err = param_dist(param, want)
    placed = np.isfinite(want[:, 0])       # (the rest: junction images, their UV is exact)
    edge = 1 / 7                           # the target's edges are about 1/7 long
    new = err[placed & ~old]
    assert err[old].max() < 1e-9 and np.median(new) < 0.1 * edge and new.max() < 0.3 * edge
    assert np.count_nonzero(placed & ~old) >= 40


def test_cut_is_continuous(pair):
    """Where the cut target has several UVs at one vertex, or along a cut edge, they show the
    same source point."""
    d = pair
    _, cut = make_cut(d)
    param, _ = uv_to_param(d, cut.loop_uv)
    worst, shared = 0.0, 0
    for v in np.unique(cut.loop_vertex):
        at = np.nonzero(cut.loop_vertex == v)[0]
        if np.ptp(cut.loop_uv[at], axis=0).max() > 1e-9:
            shared += 1
            worst = max(worst, float(param_dist(param[at], param[at[:1]]).max()))
    assert shared >= 30 and worst < 1e-7, (shared, worst)
    # chord midpoints: each edge used by two polygons with different UVs at its ends
    edges = {}
    nxt = np.arange(len(cut.loop_vertex)) + 1
    nxt[cut.loop_start + cut.loop_total - 1] = cut.loop_start
    for l in range(len(cut.loop_vertex)):
        a, b = int(cut.loop_vertex[l]), int(cut.loop_vertex[nxt[l]])
        mid = 0.5 * (cut.loop_uv[l] + cut.loop_uv[nxt[l]])
        edges.setdefault((min(a, b), max(a, b)), []).append(mid)
    mids = [m for m in edges.values() if len(m) == 2 and np.abs(m[0] - m[1]).max() > 1e-9]
    assert len(mids) >= 30
    p0, _ = uv_to_param(d, np.asarray([m[0] for m in mids]))
    p1, _ = uv_to_param(d, np.asarray([m[1] for m in mids]))
    assert param_dist(p0, p1).max() < 1e-7


def test_pieces_cover_their_polygon(pair):
    """The pieces' parameter areas (from their UVs, each island's map is affine) add up to their
    target polygon's (within the new vertices' placement, see above), all with the polygon's
    orientation: no overlap, no gap."""
    d = pair
    _, cut = make_cut(d)
    param, _ = uv_to_param(d, cut.loop_uv)

    def area(P):
        P = P[:1] + ((P - P[:1] + 0.5) % 1.0 - 0.5)
        x, y = P[:, 0], P[:, 1]
        return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))

    got = np.zeros(len(d["start"]))
    for s, n, o in zip(cut.loop_start, cut.loop_total, cut.polygon_origin):
        a = area(param[s:s + n])
        assert a > -1e-12
        got[o] += a
    want = np.array([area(d["Pt"][d["lv"][s:s + 4]]) for s in d["start"]])
    assert np.abs(got / want - 1).max() < 0.15, np.abs(got / want - 1).max()
    assert np.abs(got.sum() / want.sum() - 1) < 0.01          # the whole torus


def test_without_forward_map_junction_polygons_are_counted(pair):
    """Without the source vertices' images the junction polygons cannot be cut: they are
    reported as unresolved (and keep one continued chart), the others still cut."""
    d = pair
    _, cut = make_cut(d, with_forward=False)
    assert cut.junctions == 0 and cut.unresolved >= 3 and cut.cut >= 10
    mixed = mixed_polygons(d, cut.loop_start, cut.loop_total, cut.loop_uv)
    assert mixed <= cut.unresolved


def test_aligned_pair_is_degenerate(aligned_pair):
    """The aligned fixture really has the degenerate positions (so the test below can fail):
    target vertices exactly on source edges, and a source vertex image on a target vertex."""
    d = aligned_pair
    assert np.sum(d["inv"][1].min(axis=1) <= 1e-12) >= 7
    assert np.sum(d["fw"][1].max(axis=1) >= 1 - 1e-12) >= 1


def test_cut_of_the_aligned_pair_is_resolved_and_continuous(aligned_pair):
    """Degenerate positions (target vertices on seam edges and on a seam junction, target edges
    along a seam; the stored map's float32 weights) are cut like generic ones: nothing
    unresolved, no polygon across charts, UVs continuous across the cut."""
    d = dict(aligned_pair)
    d["inv"] = (d["inv"][0], d["inv"][1].astype(np.float32))     # as read back from Blender
    _, cut = make_cut(d)
    assert cut.unresolved == 0 and cut.cut >= 15 and cut.junctions >= 3, cut.reasons
    assert mixed_polygons(d, cut.loop_start, cut.loop_total, cut.loop_uv) == 0
    param, _ = uv_to_param(d, cut.loop_uv)
    assert np.all(np.isfinite(param))
    worst = 0.0
    for v in np.unique(cut.loop_vertex):
        at = np.nonzero(cut.loop_vertex == v)[0]
        worst = max(worst, float(param_dist(param[at], param[at[:1]]).max()))
    assert worst < 1e-5, worst
