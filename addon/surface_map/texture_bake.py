"""The Blender-free maths of baking the source's textures into the target's own UV layout
through the stored correspondence (docs/baking.md).

Every texel of the target's image takes the source's colour at the texel's preimage: the
target point under the texel (rasterised target UV triangles, supersampled), mapped to the
source by the INVERSE map (target point -> source point), then the source's texture at that
point's UV in the source triangle's own chart. Since the colour is looked up per texel on the
source, the source's UV seams leave no trace on the target (the only seams are the target's
own UV seams, bled over by a margin).

What is exact (docs/baking.md, "What is exact"): the stored correspondence gives the map at
the target's vertices (inverse) and at the images of the source's vertices (forward). Each
target triangle is split at the images of the source vertices inside it (Delaunay), so
both sets of points are nodes; a texel's preimage is the linear interpolation of its
sub-triangle's three node preimages in one chart of the source unfolded from its 3D edge
lengths, located in the source triangle it falls in. At the nodes this is the map itself;
inside a target triangle whose corners map into one source triangle it is the solver's
piecewise-linear map exactly; elsewhere it differs from the solver's map (linear in the
uniformization domain) by the change of metric between the domain and 3D within one
sub-triangle.

Conventions as in uv_transfer.py: V (n,3) float64, F (m,3) int triangles; a point on a surface is
(face, barycentrics (3,)). Images are (h, w, 4) float32 RGBA arrays with row 0 at v = 0 (the
layout of Blender's Image.pixels); UV (0,0) is the lower-left corner of texel (0,0).
"""
import math

import numpy as np

from .uv_transfer import face_adjacency, uv_seams


# --- charts of the source: each face and its neighbourhood unfolded into the plane ------------

def face_frames(V, F):
    """Each triangle in its own plane: (m,3,2) corner coordinates, corner 0 at the origin,
    corner 1 on the positive x axis, corner 2 above it (the triangle's orientation)."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    e1, e2 = b - a, c - a
    l1 = np.linalg.norm(e1, axis=1)
    x = e1 / np.where(l1 > 0, l1, 1.0)[:, None]
    px = np.einsum("ij,ij->i", e2, x)
    py = np.linalg.norm(e2 - px[:, None] * x, axis=1)
    L = np.zeros((len(F), 3, 2))
    L[:, 1, 0] = l1
    L[:, 2, 0] = px
    L[:, 2, 1] = py
    return L


class SourceCharts:
    """Source triangles (the anchors: all, or the given ones) with the triangles within
    `rings` edge steps of them, unfolded into the anchor's plane (face_frames) across the
    shared edges, breadth first (one unfolding per triangle: around a vertex with angle
    defect the chart has a slit where the two ways round meet).

    row_of (m,): each triangle's row (-1: not an anchor); faces (R,K) int: the triangles of
    each row's chart (-1 pads), the anchor first; corners (R,K,3,2): their corners in the
    anchor's chart."""

    def __init__(self, V, F, rings=4, anchors=None):
        F = np.asarray(F, dtype=np.int64)
        m = len(F)
        L = face_frames(V, F)
        nf, ne = face_adjacency(F)
        anchors = np.arange(m) if anchors is None else np.unique(np.asarray(anchors, np.int64))
        R = len(anchors)
        row = np.arange(R)
        face = anchors.copy()
        pos = L[anchors].copy()
        all_a, all_f, all_p = [row], [face], [pos]
        seen = np.sort(row * m + face)
        fa, ff, fp = row, face, pos
        for _ in range(rings):
            na, nff, npos = [], [], []
            for k in range(3):
                g = nf[ff, k]
                ok = g >= 0
                a_, f_, p_, g, j = fa[ok], ff[ok], fp[ok], g[ok], ne[ff[ok], k]
                # edge k of f runs corner k -> k+1; in g it is corner j -> j+1, reversed
                P = p_[:, k, 0] + 1j * p_[:, k, 1]
                Q = p_[:, (k + 1) % 3, 0] + 1j * p_[:, (k + 1) % 3, 1]
                Lg = L[g]
                zg = Lg[..., 0] + 1j * Lg[..., 1]
                rows = np.arange(len(g))
                gq = zg[rows, j]             # g's corner j is f's corner k+1 (Q)
                gp = zg[rows, (j + 1) % 3]   # g's corner j+1 is f's corner k (P)
                d = gq - gp
                rot = (Q - P) / np.where(np.abs(d) > 0, d, 1.0)
                rot = rot / np.where(np.abs(rot) > 0, np.abs(rot), 1.0)  # rigid (lengths agree)
                z = P[:, None] + (zg - gp[:, None]) * rot[:, None]
                na.append(a_)
                nff.append(g)
                npos.append(np.stack([z.real, z.imag], -1))
            na, nff, npos = np.concatenate(na), np.concatenate(nff), np.concatenate(npos)
            key = na * m + nff
            key_u, first = np.unique(key, return_index=True)
            fresh = ~np.isin(key_u, seen, assume_unique=True)
            first = first[fresh]
            if len(first) == 0:
                break
            fa, ff, fp = na[first], nff[first], npos[first]
            all_a.append(fa)
            all_f.append(ff)
            all_p.append(fp)
            seen = np.union1d(seen, key_u[fresh])
        a = np.concatenate(all_a)
        f = np.concatenate(all_f)
        p = np.concatenate(all_p)
        order = np.argsort(a, kind="stable")     # anchor first within each row (ring order)
        a, f, p = a[order], f[order], p[order]
        counts = np.bincount(a, minlength=R)
        K = int(counts.max(initial=1))
        slot = np.arange(len(a)) - np.repeat(np.cumsum(counts) - counts, counts)
        self.faces = -np.ones((R, K), dtype=np.int64)
        self.corners = np.zeros((R, K, 3, 2))
        self.faces[a, slot] = f
        self.corners[a, slot] = p
        self.row_of = -np.ones(m, dtype=np.int64)
        self.row_of[anchors] = row
        keys = a * m + f
        kord = np.argsort(keys)
        self._keys_sorted = keys[kord]
        self._slot_sorted = slot[kord]
        self.m = m

    def slot(self, anchor, face):
        """Position of `face` in the chart of `anchor` (-1 when it is not in it, or anchor has
        no chart here)."""
        r = self.row_of[np.asarray(anchor, dtype=np.int64)]
        key = r * self.m + np.asarray(face, dtype=np.int64)
        i = np.clip(np.searchsorted(self._keys_sorted, key), 0, len(self._keys_sorted) - 1)
        return np.where((r >= 0) & (self._keys_sorted[i] == key), self._slot_sorted[i], -1)


def _bary_2d(P, T):
    """Barycentrics (...,3) of 2D points P (...,2) in triangles T (...,3,2); nan when degenerate."""
    a, b, c = T[..., 0, :], T[..., 1, :], T[..., 2, :]
    v0, v1, v2 = b - a, c - a, P - a
    det = v0[..., 0] * v1[..., 1] - v0[..., 1] * v1[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        w1 = (v2[..., 0] * v1[..., 1] - v2[..., 1] * v1[..., 0]) / det
        w2 = (v0[..., 0] * v2[..., 1] - v0[..., 1] * v2[..., 0]) / det
    return np.stack([1.0 - w1 - w2, w1, w2], -1)


# --- target triangles split at the images of the source vertices --------------------------------

EQUILATERAL = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, math.sqrt(3) / 2]])


class SplitTarget:
    """The target's triangles split at the images of the source's vertices that lie inside
    them or on their edges (forward map; Delaunay in each triangle's plane, from V_tgt (n_t,3)
    when given, else an equilateral triangle), so that the map is known exactly at every node.
    A point on a target edge (one barycentric within `eps` of 0: symmetric meshes put source
    vertices exactly on target edges, e.g. the flat torus's translation that puts base vertex
    on base vertex) splits the edge and is a node of the triangles on both sides (no
    T-junction); left out, the sub-triangles around it would interpolate across its source
    vertex, whose unfolded charts have a slit there (docs/baking.md "What is exact").

    parent (E,): the target triangle of each sub-triangle; node_bary (E,3,3): its corners'
    barycentrics in the parent; node_face (E,3), node_src_bary (E,3,3): the corners' preimages
    on the source (target vertices: the stored inverse; inserted points: their source vertex);
    inserted: how many source vertices became nodes (the others lie on target vertices, two
    barycentrics within `eps` of 0)."""

    def __init__(self, F_src, F_tgt, forward_face, forward_bary, inverse_face, inverse_bary,
                 eps=1e-6, insert=True, V_tgt=None):
        F_src = np.asarray(F_src, dtype=np.int64)
        F_tgt = np.asarray(F_tgt, dtype=np.int64)
        mt = len(F_tgt)
        inv_f = np.asarray(inverse_face, dtype=np.int64)
        inv_b = np.asarray(inverse_bary, dtype=np.float64)
        # a source vertex as a point: one triangle around it with the unit barycentric
        vf = np.full(int(F_src.max(initial=-1)) + 1, -1, dtype=np.int64)
        vk = np.zeros_like(vf)
        for k in range(3):
            vf[F_src[:, k]] = np.arange(len(F_src))
            vk[F_src[:, k]] = k
        parent = [np.arange(mt)]
        nb = [np.tile(np.eye(3), (mt, 1, 1))]
        nface = [inv_f[F_tgt]]
        nsb = [inv_b[F_tgt]]
        self.inserted = 0
        if insert and len(forward_face):
            fw_t, fw_w, verts = self._points_per_triangle(F_tgt, forward_face, forward_bary, eps)
            self.inserted = len(np.unique(verts))
            order = np.argsort(fw_t, kind="stable")
            fw_t, fw_w, verts = fw_t[order], fw_w[order], verts[order]
            keep = np.ones(mt, dtype=bool)
            frames = None if V_tgt is None else face_frames(V_tgt, F_tgt)
            sub_p, sub_b, sub_f, sub_s = [], [], [], []
            bounds = np.flatnonzero(np.diff(fw_t)) + 1
            for rows in np.split(np.arange(len(verts)), bounds) if len(verts) else []:
                t = int(fw_t[rows[0]])
                keep[t] = False
                tris = self._split_one(t, verts[rows], fw_w[rows], F_tgt, inv_f, inv_b, vf, vk,
                                       frames[t] if frames is not None else EQUILATERAL)
                for bary, faces, sb in tris:
                    sub_p.append(t)
                    sub_b.append(bary)
                    sub_f.append(faces)
                    sub_s.append(sb)
            parent = [parent[0][keep]] + ([np.asarray(sub_p, dtype=np.int64)] if sub_p else [])
            nb = [nb[0][keep]] + ([np.asarray(sub_b)] if sub_b else [])
            nface = [nface[0][keep]] + ([np.asarray(sub_f, dtype=np.int64)] if sub_f else [])
            nsb = [nsb[0][keep]] + ([np.asarray(sub_s)] if sub_s else [])
        self.parent = np.concatenate(parent)
        self.node_bary = np.concatenate(nb)
        self.node_face = np.concatenate(nface)
        self.node_src_bary = np.concatenate(nsb)

    @staticmethod
    def _points_per_triangle(F_tgt, forward_face, forward_bary, eps):
        """The source vertices to insert, as rows (target triangle (k,), barycentrics there
        (k,3), source vertex (k,)): each image strictly inside its triangle once, each image on
        a target edge (one barycentric <= eps, set to 0) once for each triangle of the edge."""
        fw_f = np.asarray(forward_face, dtype=np.int64)
        fw_b = np.asarray(forward_bary, dtype=np.float64)
        low = (fw_b <= eps).sum(axis=1)
        ok = fw_f >= 0
        inner = np.nonzero(ok & (low == 0))[0]
        edge = np.nonzero(ok & (low == 1))[0]
        t_in, w_in = fw_f[inner], fw_b[inner]
        k0 = np.argmin(fw_b[edge], axis=1)               # the corner off the edge
        w_e = fw_b[edge].copy()
        w_e[np.arange(len(edge)), k0] = 0.0
        w_e /= w_e.sum(axis=1, keepdims=True)
        t_e = fw_f[edge]
        # the same point in the triangle across the edge (corner k0+1 -> k0+2 is edge k of t,
        # uv_transfer.face_adjacency's numbering; the neighbour runs it reversed as its edge j)
        nf, ne = face_adjacency(F_tgt)
        k = (k0 + 1) % 3
        t2, j = nf[t_e, k], ne[t_e, k]
        has = t2 >= 0
        r = np.nonzero(has)[0]
        w2 = np.zeros((len(r), 3))
        w2[np.arange(len(r)), j[r]] = w_e[r, (k[r] + 1) % 3]
        w2[np.arange(len(r)), (j[r] + 1) % 3] = w_e[r, k[r]]
        return (np.concatenate([t_in, t_e, t2[r]]), np.concatenate([w_in, w_e, w2]),
                np.concatenate([inner, edge, edge[r]]))

    @staticmethod
    def _split_one(t, group, weights, F_tgt, inv_f, inv_b, vf, vk, corners2d):
        """The sub-triangles of target triangle t with the source vertices `group` inserted
        at barycentrics `weights` (k,3): the Delaunay triangulation of its corners and those
        points (Bowyer-Watson, in the triangle's own plane `corners2d` (3,2); a point on an
        edge of t splits it, the zero-area triangle it would close with that edge dropped),
        so that the sub-triangles are as round as the points allow and their corners close
        on the source. Returns [(node bary in t (3,3), source faces (3,), source barys
        (3,3))]."""
        pts = [np.eye(3)[k] for k in range(3)]
        xy = [corners2d[k] for k in range(3)]
        faces = [int(inv_f[F_tgt[t, k]]) for k in range(3)]
        sbs = [inv_b[F_tgt[t, k]] for k in range(3)]
        tris = [(0, 1, 2)]
        scale = float(np.abs(corners2d).max()) or 1.0
        for v, p in zip(group, weights):
            q = p @ corners2d
            if min(float(np.linalg.norm(q - x)) for x in xy) <= 1e-9 * scale:
                continue
            i = len(pts)
            pts.append(p)
            xy.append(q)
            faces.append(int(vf[v]))
            unit = np.zeros(3)
            unit[vk[v]] = 1.0
            sbs.append(unit)
            bad, keep = [], []
            for tr in tris:
                (bad if _in_circumcircle(xy[tr[0]], xy[tr[1]], xy[tr[2]], q) else keep).append(tr)
            if not bad:                       # round-off: the triangle containing q
                w = [min(_bary_2d(q, np.array([xy[a], xy[b], xy[c]]))) for a, b, c in tris]
                bad = [tris[int(np.nanargmax(w))]]
                keep = [tr for tr in tris if tr != bad[0]]
            count = {}
            for a, b, c in bad:
                for e in ((a, b), (b, c), (c, a)):
                    count[e] = count.get(e, 0) + 1
            rim = [e for e in count if (e[1], e[0]) not in count]
            tris = keep + [(a, b, i) for a, b in rim
                           if abs(_cross2(xy[b] - xy[a], q - xy[a])) > 1e-12 * scale * scale]
        return [(np.array([pts[a], pts[b], pts[c]]), [faces[a], faces[b], faces[c]],
                 np.array([sbs[a], sbs[b], sbs[c]])) for a, b, c in tris]


def _cross2(u, v):
    return float(u[0] * v[1] - u[1] * v[0])


def _in_circumcircle(a, b, c, p):
    """p strictly inside the circumcircle of the counter-clockwise triangle (a, b, c)."""
    m = np.array([[a[0] - p[0], a[1] - p[1], (a[0] - p[0]) ** 2 + (a[1] - p[1]) ** 2],
                  [b[0] - p[0], b[1] - p[1], (b[0] - p[0]) ** 2 + (b[1] - p[1]) ** 2],
                  [c[0] - p[0], c[1] - p[1], (c[0] - p[0]) ** 2 + (c[1] - p[1]) ** 2]])
    return float(np.linalg.det(m)) > 0


# --- the preimage of target points --------------------------------------------------------------

def common_triangle(F_src, node_face, node_bary, eps=1e-12):
    """Re-expresses the three source points of each row in ONE source triangle when one holds
    them all (points on a vertex or an edge belong to every triangle around it), so that the
    interpolation between them is the exact linear one in that triangle.

    node_face (E,3), node_bary (E,3,3) -> (face (E,3), bary (E,3,3)), rows without a common
    triangle unchanged."""
    F = np.asarray(F_src, dtype=np.int64)
    face = np.array(node_face, dtype=np.int64)
    bary = np.array(node_bary, dtype=np.float64)
    E = len(face)
    if E == 0:
        return face, bary
    n = int(F.max()) + 1
    deg = np.bincount(F.reshape(-1), minlength=n)
    D = int(deg.max())
    vf = -np.ones((n, D), dtype=np.int64)
    order = np.argsort(F.reshape(-1), kind="stable")
    vs = F.reshape(-1)[order]
    col = np.arange(len(vs)) - np.repeat(np.cumsum(deg) - deg, deg)
    vf[vs, col] = order // 3
    verts = F[face]                                    # (E,3 nodes,3 corners)
    used = bary > eps
    v0 = verts[np.arange(E), 0, np.argmax(bary[:, 0], axis=1)]
    done = np.zeros(E, dtype=bool)
    for d in range(D):
        g = vf[v0, d]
        todo = (~done) & (g >= 0)
        if not np.any(todo):
            continue
        idx = np.nonzero(todo)[0]
        Fg = F[g[idx]]                                  # (e,3)
        match = verts[idx][..., None] == Fg[:, None, None, :]   # (e,3,3,3): node, corner, g corner
        ok = np.all(match.any(axis=3) | ~used[idx], axis=(1, 2))
        if not np.any(ok):
            continue
        idx, Fg, match = idx[ok], Fg[ok], match[ok]
        w = np.where(used[idx], bary[idx], 0.0)
        nb = np.einsum("enc,encg->eng", w, match.astype(np.float64))
        face[idx] = g[idx][:, None]
        bary[idx] = nb
        done[idx] = True
    return face, bary


class Preimages:
    """Locates points of the split target's sub-triangles on the source.

    For sub-triangle e the three node preimages are put in one chart of the source (the chart
    of the first node's triangle that holds the other two: first in `charts`, else in a wider
    chart of `wide_rings` edge steps made for those anchors only); the point with weights w is
    sum_k w_k Q_k there, found in the chart's triangle containing it."""

    def __init__(self, charts, split, F_src, V_src=None, wide_rings=12):
        E = len(split.parent)
        nf, nsb = common_triangle(F_src, split.node_face, split.node_src_bary)
        self.node_face, self.node_bary = nf, nsb
        self.chart_sets = [charts]
        self.which = -np.ones(E, dtype=np.int64)     # index into chart_sets
        self.row = -np.ones(E, dtype=np.int64)
        self.slots = -np.ones((E, 3), dtype=np.int64)
        self._assign(0)
        if V_src is not None and np.any(self.which < 0) and wide_rings > 0:
            need = np.unique(nf[self.which < 0])
            self.chart_sets.append(SourceCharts(V_src, F_src, rings=wide_rings, anchors=need))
            self._assign(1)
        self.unlocated = int(np.sum(self.which < 0))
        Q = np.zeros((E, 3, 2))
        for c, ch in enumerate(self.chart_sets):
            sel = self.which == c
            for k in range(3):
                T = ch.corners[self.row[sel], self.slots[sel, k]]        # (e,3,2)
                Q[sel, k] = np.einsum("ij,ijk->ik", nsb[sel, k], T)
        self.Q = Q
        self.split = split

    def _assign(self, c):
        ch = self.chart_sets[c]
        nf = self.node_face
        for k in range(3):                       # try each node's triangle as the anchor
            todo = self.which < 0
            cand = nf[:, k]
            s = np.stack([ch.slot(cand, nf[:, j]) for j in range(3)], -1)
            take = todo & np.all(s >= 0, axis=1)
            self.which[take] = c
            self.row[take] = ch.row_of[cand[take]]
            self.slots[take] = s[take]

    def locate(self, element, weights):
        """Source (face (k,), bary (k,3)) of the points with `weights` (k,3) in sub-triangles
        `element` (k,). Points whose three node preimages are in no chart together take the
        preimage of their nearest node; points in no chart triangle (across a slit or past the
        chart) take the nearest chart triangle's clamped barycentrics. Also returns the count
        of such clamped points (barycentric below -1e-6)."""
        element = np.asarray(element, dtype=np.int64)
        w = np.asarray(weights, dtype=np.float64)
        P = np.einsum("ij,ijk->ik", w, self.Q[element])
        face = np.empty(len(element), dtype=np.int64)
        bary = np.empty((len(element), 3))
        which = self.which[element]
        lost = which < 0
        if np.any(lost):                         # nearest node's preimage
            k = np.argmax(w[lost], axis=1)
            face[lost] = self.node_face[element[lost], k]
            bary[lost] = self.node_bary[element[lost], k]
        clamped = 0
        for c, ch in enumerate(self.chart_sets):
            sel = np.nonzero(which == c)[0]
            if len(sel):
                f, b, n = self._in_chart(ch, self.row[element[sel]], self.slots[element[sel]],
                                         P[sel], w[sel])
                face[sel], bary[sel] = f, b
                clamped += n
        return face, bary, clamped

    @staticmethod
    def _in_chart(ch, row, sl, P, w):
        """The chart triangles holding the points P (k,2) of chart rows `row`: first among
        the node triangles `sl` (k,3) (most points fall in one; where unfolded triangles
        overlap, around a vertex of negative curvature, the triangle of the node with the
        largest weight w (k,3) wins, so each node maps to its own preimage), then the whole
        chart."""
        T = ch.corners[row[:, None], sl]                          # (k,3,3,2)
        B = _bary_2d(P[:, None, :], T)
        score = np.nan_to_num(B.min(axis=2), nan=-np.inf)
        best = np.argmax(np.where(score >= -1e-12, 10.0 + w, score), axis=1)
        rows = np.arange(len(best))
        got_b = B[rows, best]
        got_s = sl[rows, best]
        got_score = score[rows, best]
        K = ch.faces.shape[1]
        for lim in (12, 48, K):              # the chart's triangles in ring order: near first
            lim = min(lim, K)
            miss = np.nonzero(got_score < -1e-12)[0]
            step = max(1, 2_000_000 // lim)
            for start in range(0, len(miss), step):
                idx = miss[start:start + step]
                rm = row[idx]
                Bm = _bary_2d(P[idx][:, None, :], ch.corners[rm, :lim])   # (k',lim,3)
                sc = np.nan_to_num(Bm.min(axis=2), nan=-np.inf)
                sc[ch.faces[rm, :lim] < 0] = -np.inf
                bm = np.argmax(sc, axis=1)
                r = np.arange(len(idx))
                better = sc[r, bm] > got_score[idx]
                got_b[idx[better]] = Bm[r, bm][better]
                got_s[idx[better]] = bm[better]
                got_score[idx[better]] = sc[r, bm][better]
            if lim == K:
                break
        clamped = int(np.sum(got_score < -1e-6))
        got_b = np.clip(got_b, 0.0, None)
        got_b /= np.maximum(got_b.sum(axis=1, keepdims=True), 1e-300)
        return ch.faces[row, got_s], got_b, clamped


# --- rasterisation ------------------------------------------------------------------------------

def rasterize(uv_tri, width, height, supersample=1, max_candidates=1_000_000):
    """Samples of a (width*S) x (height*S) grid (S = supersample; sample (x, y) at UV
    ((x + 0.5) / (width*S), (y + 0.5) / (height*S))) inside the UV triangles (m,3,2).

    Yields, chunk by chunk, (triangle (k,), barycentrics (k,3), texel (k,) = row * width +
    column of the texel holding the sample). A sample on an edge shared by two triangles may
    come twice; degenerate UV triangles give none."""
    uv = np.asarray(uv_tri, dtype=np.float64)
    W, H = width * supersample, height * supersample
    P = uv * np.array([W, H]) - 0.5                # sample (x, y) sits at P == (x, y)
    lo = np.ceil(P.min(axis=1) - 1e-9).astype(np.int64)
    hi = np.floor(P.max(axis=1) + 1e-9).astype(np.int64)
    lo = np.maximum(lo, 0)
    hi[:, 0] = np.minimum(hi[:, 0], W - 1)
    hi[:, 1] = np.minimum(hi[:, 1], H - 1)
    nx = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0)
    ny = np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    count = nx * ny
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    count[np.abs(det) < 1e-14] = 0
    csum = np.cumsum(count)
    start = 0
    while start < len(uv):
        base = csum[start - 1] if start else 0
        stop = int(np.searchsorted(csum, base + max_candidates, side="right"))
        stop = max(stop, start + 1)
        tris = np.arange(start, stop)
        c = count[tris]
        t = np.repeat(tris, c)
        if len(t):
            r = np.arange(len(t)) - np.repeat(np.cumsum(c) - c, c)
            x = lo[t, 0] + r % nx[t]
            y = lo[t, 1] + r // nx[t]
            d = np.stack([x, y], -1) - P[t, 0]
            w1 = (d[:, 0] * e2[t, 1] - d[:, 1] * e2[t, 0]) / det[t]
            w2 = (e1[t, 0] * d[:, 1] - e1[t, 1] * d[:, 0]) / det[t]
            w = np.stack([1.0 - w1 - w2, w1, w2], -1)
            inside = w.min(axis=1) >= -1e-9
            t, w, x, y = t[inside], w[inside], x[inside], y[inside]
            texel = (y // supersample) * width + (x // supersample)
            yield t, w, texel
        start = stop


def island_mask(uv_tri, width, height):
    """(height, width) bool: texels whose centre lies in some UV triangle (the islands)."""
    mask = np.zeros(width * height, dtype=bool)
    for _, _, texel in rasterize(uv_tri, width, height, 1):
        mask[texel] = True
    return mask.reshape(height, width)


def bleed(rgba, filled, margin):
    """Extends the filled texels `margin` texels outwards (each empty texel next to filled
    ones takes their mean, 8-neighbourhood, repeated), so that filtering and mip-mapping near
    the islands' borders do not pick up the background. Returns (rgba, filled) new arrays."""
    img = np.array(rgba, dtype=np.float64)
    ok = np.array(filled, dtype=bool)
    H, W = ok.shape
    for _ in range(int(margin)):
        if ok.all():
            break
        s = np.zeros_like(img)
        n = np.zeros((H, W))
        pad_i = np.pad(img * ok[..., None], ((1, 1), (1, 1), (0, 0)))
        pad_o = np.pad(ok.astype(np.float64), 1)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dx == 0 and dy == 0:
                    continue
                s += pad_i[1 + dy:1 + dy + H, 1 + dx:1 + dx + W]
                n += pad_o[1 + dy:1 + dy + H, 1 + dx:1 + dx + W]
        grow = (~ok) & (n > 0)
        img[grow] = s[grow] / n[grow][:, None]
        ok = ok | grow
    return img, ok


# --- sampling the source ------------------------------------------------------------------------

def sample_image(image, uv, wrap=True):
    """Bilinear samples (k,C) of an image (h,w,C) at UV (k,2), like Blender's Image Texture
    node (Linear interpolation; Repeat extension when wrap, else Extend)."""
    img = np.asarray(image)
    h, w = img.shape[:2]
    x = np.asarray(uv[:, 0], dtype=np.float64) * w - 0.5
    y = np.asarray(uv[:, 1], dtype=np.float64) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    if wrap:
        xs = (x0 % w, (x0 + 1) % w)
        ys = (y0 % h, (y0 + 1) % h)
    else:
        xs = (np.clip(x0, 0, w - 1), np.clip(x0 + 1, 0, w - 1))
        ys = (np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1))
    c00, c10 = img[ys[0], xs[0]], img[ys[0], xs[1]]
    c01, c11 = img[ys[1], xs[0]], img[ys[1], xs[1]]
    return ((c00 * (1 - fx) + c10 * fx) * (1 - fy) + (c01 * (1 - fx) + c11 * fx) * fy)


class SourceColour:
    """The source's colour at points (face, bary): per source triangle one material; each
    material either an image on a UV map (corner_uv (m,3,2), in the triangle's own chart, so
    the source's seams do not matter) or a constant colour; or corner colours (m,3,4)."""

    def __init__(self, face_material=None, materials=None, corner_colour=None):
        self.face_material = None if face_material is None else np.asarray(face_material)
        self.materials = materials or []
        self.corner_colour = None if corner_colour is None else np.asarray(corner_colour)

    def __call__(self, face, bary):
        face = np.asarray(face, dtype=np.int64)
        if self.corner_colour is not None:
            return np.einsum("ij,ijk->ik", bary, self.corner_colour[face])
        out = np.zeros((len(face), 4))
        mat = np.zeros(len(face), dtype=np.int64) if self.face_material is None \
            else self.face_material[face]
        for i, spec in enumerate(self.materials):
            sel = np.nonzero(mat == i)[0]
            if len(sel) == 0:
                continue
            if spec.get("image") is not None:
                uv = np.einsum("ij,ijk->ik", bary[sel], spec["corner_uv"][face[sel]])
                out[sel] = sample_image(spec["image"], uv)[:, :4]
            else:
                out[sel] = spec.get("colour", (0.8, 0.8, 0.8, 1.0))
        return out


# --- the bake -----------------------------------------------------------------------------------

def bake(V_src, F_src, F_tgt, target_corner_uv, forward, inverse, colour, width, height,
         supersample=2, margin=8, rings=4, split=True, V_tgt=None):
    """Bakes `colour` (SourceColour, or any callable (face, bary) -> (k,4)) of the source into
    a width x height image in the target's UV layout through the inverse map.

    V_src (n_s,3), F_src (m_s,3): the source; F_tgt (m_t,3) the target's triangles and
    target_corner_uv (m_t,3,2) their corners' UVs; forward = (face (n_s,), bary (n_s,3)):
    each source vertex on the target; inverse = (face (n_t,), bary (n_t,3)): each target
    vertex on the source; V_tgt (n_t,3), optional: the target's vertices (the sub-triangles
    are Delaunay in the 3D triangles' planes). supersample S: S x S samples per texel, averaged; margin: texels of
    bleed around the islands.

    Returns dict(image (h,w,4) float32, filled (h,w) bool before the bleed, islands (h,w) bool
    (texel centres inside the target's UV triangles), fill_fraction (island texels filled),
    samples, unlocated (sub-triangles whose node preimages share no chart), clamped (samples
    found in no chart triangle), inserted (source vertices made nodes), sub_triangles)."""
    charts = SourceCharts(V_src, F_src, rings=rings)
    st = SplitTarget(F_src, F_tgt, forward[0], forward[1], inverse[0], inverse[1], insert=split,
                     V_tgt=V_tgt)
    pre = Preimages(charts, st, F_src, V_src)
    uv = np.asarray(target_corner_uv, dtype=np.float64)
    sub_uv = np.einsum("eij,ejk->eik", st.node_bary, uv[st.parent])
    acc = np.zeros((height * width, 4))
    cnt = np.zeros(height * width)
    samples = clamped = 0
    for e, w, texel in rasterize(sub_uv, width, height, supersample):
        f, b, c = pre.locate(e, w)
        rgba = np.asarray(colour(f, b), dtype=np.float64)
        for k in range(4):
            acc[:, k] += np.bincount(texel, weights=rgba[:, k], minlength=height * width)
        cnt += np.bincount(texel, minlength=height * width)
        samples += len(e)
        clamped += c
    filled = cnt > 0
    img = np.zeros((height * width, 4))
    img[filled] = acc[filled] / cnt[filled][:, None]
    img = img.reshape(height, width, 4)
    filled = filled.reshape(height, width)
    islands = island_mask(uv, width, height)
    out_img, _ = bleed(img, filled, margin)
    n_island = int(islands.sum())
    return {"image": out_img.astype(np.float32), "filled": filled, "islands": islands,
            "fill_fraction": float((filled & islands).sum() / n_island) if n_island else 1.0,
            "samples": samples, "unlocated": pre.unlocated, "clamped": clamped,
            "inserted": st.inserted, "sub_triangles": len(st.parent)}


# --- measuring a bake ---------------------------------------------------------------------------

def bake_error_at_nodes(image, F_src, F_tgt, target_corner_uv, forward, inverse, colour,
                        source_seam_vertices=None):
    """Colour difference (max over RGB) between the baked image and the source at points
    where the stored map is exact: the images of the source vertices (forward; the source
    colour taken in each triangle around the vertex, and the vertex skipped when those differ
    by more than 1e-3: it sits on a jump of the texture) and the target vertices (inverse).

    Returns dict(source_vertices (k,), target_vertices (k',), near_seams (k'') errors),
    near_seams: source vertices flagged in source_seam_vertices (bool (n_s,))."""
    F_src = np.asarray(F_src, dtype=np.int64)
    F_tgt = np.asarray(F_tgt, dtype=np.int64)
    uv = np.asarray(target_corner_uv, dtype=np.float64)
    fw_f, fw_b = np.asarray(forward[0], dtype=np.int64), np.asarray(forward[1])
    iv_f, iv_b = np.asarray(inverse[0], dtype=np.int64), np.asarray(inverse[1])
    # source side: per (vertex, incident triangle) the source colour
    tri = np.repeat(np.arange(len(F_src)), 3)
    corner = np.tile(np.arange(3), len(F_src))
    vert = F_src.reshape(-1)
    unit = np.eye(3)[corner]
    c = np.asarray(colour(tri, unit))[:, :3]
    n_s = len(fw_f)
    lo = np.full((n_s, 3), np.inf)
    hi = np.full((n_s, 3), -np.inf)
    np.minimum.at(lo, vert, c)
    np.maximum.at(hi, vert, c)
    smooth = np.max(hi - lo, axis=1) <= 1e-3
    tex_uv = np.einsum("ij,ijk->ik", fw_b, uv[fw_f])
    baked = sample_image(image, tex_uv)[:, :3]
    err_s = np.max(np.abs(baked - lo), axis=1)
    # target side: each target corner's texel against the source at the vertex's preimage
    src_c = np.asarray(colour(iv_f, iv_b))[:, :3]
    tv = F_tgt.reshape(-1)
    baked_t = sample_image(image, uv.reshape(-1, 2))[:, :3]
    err_t = np.max(np.abs(baked_t - src_c[tv]), axis=1)
    out = {"source_vertices": err_s[smooth], "target_vertices": err_t}
    if source_seam_vertices is not None:
        out["near_seams"] = err_s[smooth & np.asarray(source_seam_vertices, dtype=bool)]
    return out


def seam_vertices(F, corner_uv, rings=1, seams=None):
    """(n,) bool: vertices on a UV seam of the mesh and `rings` rings around them (uv_transfer's
    uv_seams decides which edges are seams)."""
    F = np.asarray(F, dtype=np.int64)
    if seams is None:
        seams = uv_seams(F, corner_uv)
    n = int(F.max(initial=-1)) + 1
    on = np.zeros(n, dtype=bool)
    fs, ks = np.nonzero(seams)
    on[F[fs, ks]] = True
    on[F[fs, (ks + 1) % 3]] = True
    for _ in range(rings):
        touch = on[F].any(axis=1)
        on[F[touch].reshape(-1)] = True
    return on


def random_target_points(F_tgt, V_tgt, count, seed=0):
    """`count` points uniformly distributed by area on the target: (face (k,), bary (k,3))."""
    rng = np.random.default_rng(seed)
    V = np.asarray(V_tgt, dtype=np.float64)
    F = np.asarray(F_tgt, dtype=np.int64)
    A = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    face = rng.choice(len(F), size=count, p=A / A.sum())
    r1, r2 = rng.random(count), rng.random(count)
    s = np.sqrt(r1)
    bary = np.stack([1 - s, s * (1 - r2), s * r2], -1)
    return face, bary


def locate_target_points(split, preimages, face, bary):
    """Source points (face, bary) of target points (target face (k,), bary (k,3)) through the
    same interpolation as the bake: each point is found in its target triangle's
    sub-triangles (SplitTarget) and mapped by Preimages.locate."""
    face = np.asarray(face, dtype=np.int64)
    bary = np.asarray(bary, dtype=np.float64)
    order = np.argsort(split.parent, kind="stable")
    counts = np.bincount(split.parent, minlength=int(face.max(initial=0)) + 1)
    starts = np.cumsum(counts) - counts
    K = int(counts.max(initial=1))
    best_e = np.full(len(face), -1, dtype=np.int64)
    best_w = np.zeros((len(face), 3))
    best_s = np.full(len(face), -np.inf)
    best_area = np.zeros(len(face))
    for j in range(K):
        has = counts[face] > j
        e = np.full(len(face), -1, dtype=np.int64)
        e[has] = order[starts[face[has]] + j]
        idx = np.nonzero(has)[0]
        T = split.node_bary[e[idx]][..., 1:]              # nodes in the parent's (b1, b2) plane
        w = _bary_2d(bary[idx][:, 1:], T)
        w = np.where(np.isfinite(w), w, -np.inf)
        # inside (up to round-off) counts as inside; ties (a point on a shared edge or node)
        # go to the rounder sub-triangle, whose barycentrics are the better conditioned
        sc = np.minimum(np.where(w.min(axis=1) >= -1e-12, 0.0, w.min(axis=1)), 0.0)
        e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
        area = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        better = (sc > best_s[idx]) | ((sc == best_s[idx]) & (area > best_area[idx]))
        best_e[idx[better]] = e[idx[better]]
        best_w[idx[better]] = w[better]
        best_s[idx[better]] = sc[better]
        best_area[idx[better]] = area[better]
    w = np.clip(best_w, 0.0, None)
    w /= np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
    f, b, _ = preimages.locate(best_e, w)
    return f, b
