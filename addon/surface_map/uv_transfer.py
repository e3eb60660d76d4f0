"""UV transfer that respects seams (no bpy, DESIGN in docs/addon.md): the source's UV maps
carried onto the target's polygon corners through the inverse map, plus the counts that catch a
bad transfer and a cube projection for a source without UVs.

corner_uv (m,3,2) holds the UV of every triangle corner of the source's triangles F.
"""
import heapq
import math
import time

import numpy as np

from .geometry import points_at


def face_adjacency(F):
    """For triangle f and its edge k (corner k -> corner k+1): the neighbouring triangle across
    it and the neighbour's matching edge index. (m,3) each, -1 on a boundary edge. On a
    non-manifold edge (more than two triangles) the first other triangle is taken."""
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    a = F.reshape(-1)
    b = F[:, [1, 2, 0]].reshape(-1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * (int(a.max(initial=0)) + 1) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    nbr = -np.ones(3 * m, dtype=np.int64)
    same = ks[1:] == ks[:-1]
    i0 = order[:-1][same]
    i1 = order[1:][same]
    nbr[i0] = i1
    nbr[i1] = np.where(nbr[i1] < 0, i0, nbr[i1])
    face = np.where(nbr >= 0, nbr // 3, -1).reshape(m, 3)
    edge = np.where(nbr >= 0, nbr % 3, -1).reshape(m, 3)
    return face, edge


def uv_seams(F, corner_uv, tol=None):
    """(m,3) bool: True where edge k of triangle f is a UV seam (the UVs of its two vertices
    differ on the two sides) or a mesh boundary. tol: absolute UV tolerance (default 1e-6 of the
    UV extent)."""
    F = np.asarray(F, dtype=np.int64)
    uv = np.asarray(corner_uv, dtype=np.float64)
    nf, ne = face_adjacency(F)
    if tol is None:
        ext = float(np.ptp(uv.reshape(-1, 2), axis=0).max()) if len(uv) else 1.0
        tol = 1e-6 * (ext if ext > 0 else 1.0)
    m = len(F)
    fi = np.repeat(np.arange(m), 3)
    ki = np.tile(np.arange(3), m)
    g = nf.reshape(-1)
    j = ne.reshape(-1)
    seam = np.ones(3 * m, dtype=bool)
    ok = g >= 0
    # edge k of f runs F[f,k] -> F[f,k+1]; in the neighbour it runs F[g,j] -> F[g,j+1] reversed
    u_p = uv[fi[ok], ki[ok]]
    u_q = uv[fi[ok], (ki[ok] + 1) % 3]
    w_q = uv[g[ok], j[ok]]
    w_p = uv[g[ok], (j[ok] + 1) % 3]
    same = (np.abs(u_p - w_p).max(axis=1) <= tol) & (np.abs(u_q - w_q).max(axis=1) <= tol)
    seam[ok] = ~same
    return seam.reshape(m, 3)


def uv_islands(F, corner_uv, seams=None):
    """Island index per triangle: triangles connected across edges that are not seams."""
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    if seams is None:
        seams = uv_seams(F, corner_uv)
    nf, _ = face_adjacency(F)
    fs, ks = np.nonzero(~seams & (nf >= 0))
    f, g = fs, nf[fs, ks]
    # connected components by hooking and pointer jumping (Shiloach-Vishkin style, vectorised)
    roots = np.arange(m)
    while True:
        rf, rg = roots[f], roots[g]
        if np.array_equal(rf, rg):
            break
        lo = np.minimum(rf, rg)
        np.minimum.at(roots, rf, lo)
        np.minimum.at(roots, rg, lo)
        while True:
            nxt = roots[roots]
            if np.array_equal(nxt, roots):
                break
            roots = nxt
    _, island = np.unique(roots, return_inverse=True)
    return island


def _affine_from(src, dst):
    """2x3 real A with A @ [x, y, 1] mapping the three points src (3,2) onto dst (3,2); None
    when src is degenerate."""
    S = np.hstack([np.asarray(src, dtype=np.float64), np.ones((3, 1))])
    if abs(np.linalg.det(S)) < 1e-300:
        return None
    return np.linalg.solve(S, np.asarray(dst, dtype=np.float64)).T


def _apply(A, uv):
    return uv @ A[:, :2].T + A[:, 2]


IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _compose(A, B):
    """The 2x3 affine map A after B."""
    return np.hstack([A[:, :2] @ B[:, :2], (A[:, :2] @ B[:, 2] + A[:, 2])[:, None]])


class UVTransfer:
    """Carries one UV map of the source onto the target's polygon corners through the inverse
    map, without UV triangles that straddle a seam.

    For every target polygon the preimages of its corners (source triangle, barycentrics) are
    expressed in ONE chart of the source's UV map: the chart of a reference triangle (a corner's
    preimage triangle in the island most corners fall in), continued across seams by walking
    the source mesh triangle to triangle (breadth first, so along the shortest chain). Across
    a non-seam edge the chart does not change. Across a seam edge the neighbouring triangle is
    unfolded about the shared edge into the current triangle's plane and mapped by the current
    triangle's affine UV map (the chart's continuation); the affine map taking the neighbour's
    own UVs onto those continued UVs then carries its whole island along. A polygon whose
    corners are all in the reference chart gets exactly the per-vertex (naive) UVs; one that
    straddles a seam gets the continued chart's UVs (no stretched triangle across the layout),
    which run a little past the island's border into the texture's padding.
    """

    def __init__(self, F_src, corner_uv, V_src=None, max_visits=4000):
        self.F = np.asarray(F_src, dtype=np.int64)
        self.uv = np.asarray(corner_uv, dtype=np.float64)
        self.V = None if V_src is None else np.asarray(V_src, dtype=np.float64)
        self.nf, self.ne = face_adjacency(self.F)
        self.seam = uv_seams(self.F, self.uv)
        self.island = uv_islands(self.F, self.uv, self.seam)
        self.max_visits = max_visits
        self.unresolved = 0   # corners the walk did not reach (naive UV kept)
        self.folded = 0       # straddling polygons left folded in every chart tried
        self._steps = {}

    def naive(self, face, bary):
        """Per-point UV in the point's own triangle: sum_k bary_k uv[face, k] (n',2)."""
        return np.einsum("ik,ikj->ij", np.asarray(bary, dtype=np.float64),
                         self.uv[np.asarray(face, dtype=np.int64)])

    def _stretched_polygons(self, uv, face, bary, start, total, factor=3.0):
        """Per polygon: True when some edge's UV length exceeds `factor` times the source's
        largest UV-per-length ratio times the distance of its corners' preimages."""
        if not hasattr(self, "_max_ratio"):
            self._max_ratio = float(np.max(uv_stretch(self.uv, self.V[self.F])))
        Pp = points_at(self.V, self.F, face, bary)
        nxt = np.arange(len(face)) + 1
        nxt[start + total - 1] = start
        d = np.linalg.norm(Pp[nxt] - Pp, axis=1)
        du = np.linalg.norm(uv[nxt] - uv, axis=1)
        bad = du > factor * self._max_ratio * np.maximum(d, 1e-300)
        return np.logical_or.reduceat(bad, start)

    def _seam_step(self, h, k):
        """Affine map taking the own UVs of the triangle across h's seam edge k into h's own
        chart (cached: the continuation is affine-equivariant, so a chart T_h continues as
        T_h composed with this)."""
        key = (h, k)
        A = self._steps.get(key)
        if A is None:
            A = self._across(h, k, IDENTITY, int(self.nf[h, k]), int(self.ne[h, k]))
            self._steps[key] = A
        return A

    def _across(self, h, k, T_h, g, j):
        """Chart transform of triangle g reached from h across h's seam edge k (g's edge j)."""
        F, uv = self.F, self.uv
        ch = _apply(T_h, uv[h])                      # h's corners in the chart
        kp, kq = k, (k + 1) % 3
        jr = (j + 2) % 3                             # g's corner off the shared edge
        jq, jp = j, (j + 1) % 3                      # g's edge runs q -> p (reversed)
        if self.V is not None:
            X = self.V
            p, q, o = X[F[h, kp]], X[F[h, kq]], X[F[h, (k + 2) % 3]]
            r = X[F[g, jr]]
            e = q - p
            L2 = float(e @ e)
            if L2 > 0:
                s = float((r - p) @ e) / L2
                t = float(np.linalg.norm((r - p) - s * e)) / math.sqrt(L2)
                # h's own affine UV map, applied to r unfolded into h's plane on the far side
                Ah = _affine_from(np.array([[0.0, 0.0], [1.0, 0.0],
                                            _edge_coords(p, q, o)]), ch[[kp, kq, (k + 2) % 3]])
                if Ah is not None:
                    c_r = _apply(Ah, np.array([[s, -t]]))[0]
                    dst = np.array([ch[kq], ch[kp], c_r])      # g's corners jq, jp, jr
                    A = _affine_from(uv[g, [jq, jp, jr]], dst)
                    if A is not None:
                        return A
        # no 3D positions or degenerate: the rotation-scaling that matches the shared edge
        P0, P1 = ch[kp, 0] + 1j * ch[kp, 1], ch[kq, 0] + 1j * ch[kq, 1]
        Q0 = uv[g, jp, 0] + 1j * uv[g, jp, 1]
        Q1 = uv[g, jq, 0] + 1j * uv[g, jq, 1]
        a = (P1 - P0) / (Q1 - Q0) if abs(Q1 - Q0) > 0 else 1.0 + 0j
        b = P0 - a * Q0
        return np.array([[a.real, -a.imag, b.real], [a.imag, a.real, b.imag]])

    SEAM_COST = 6  # a seam crossing counts as this many steps: stay in one island if near

    def _continue(self, ref, goals):
        """Chart transforms (2x3: chart uv = A @ [own uv, 1]) of the triangles in `goals`,
        reached from `ref` along the cheapest chain of triangles (a step costs 1, a step
        across a seam SEAM_COST)."""
        found = {}
        goals = set(goals)
        T = {ref: IDENTITY}
        cost = {ref: 0}
        heap = [(0, ref)]
        done = set()
        visits = 0
        nf, ne, seam = self.nf, self.ne, self.seam
        while heap and len(found) < len(goals) and visits < self.max_visits:
            c, h = heapq.heappop(heap)
            if h in done:
                continue
            done.add(h)
            visits += 1
            if h in goals:
                found[h] = T[h]
            T_h = T[h]
            for k in range(3):
                g = int(nf[h, k])
                if g < 0 or g in done:
                    continue
                cg = c + (self.SEAM_COST if seam[h, k] else 1)
                if cg < cost.get(g, 1 << 60):
                    cost[g] = cg
                    T[g] = _compose(T_h, self._seam_step(h, k)) if seam[h, k] else T_h
                    heapq.heappush(heap, (cg, g))
        return found

    def polygon_uvs(self, loop_face, loop_bary, loop_start, loop_total):
        """UVs (L,2) for the target's polygon corners.

        loop_face (L,), loop_bary (L,3): preimage of each target corner's vertex (the inverse
        map, indexed through the corner's vertex); loop_start/loop_total (P,): Blender's polygon
        layout. Returns (uv (L,2), straddling (P,) bool: polygons that needed a continued
        chart)."""
        for _ in self.iter_polygon_uvs(loop_face, loop_bary, loop_start, loop_total):
            pass
        return self.result

    def iter_polygon_uvs(self, loop_face, loop_bary, loop_start, loop_total,
                         slice_seconds=0.04):
        """polygon_uvs in slices: yields the fraction done about every `slice_seconds` of the
        walks across seams (so a UI timer can run between slices); the answer is then
        self.result."""
        lf = np.asarray(loop_face, dtype=np.int64)
        lb = np.asarray(loop_bary, dtype=np.float64)
        start = np.asarray(loop_start, dtype=np.int64)
        total = np.asarray(loop_total, dtype=np.int64)
        out = self.naive(lf, lb)
        P = len(start)
        # Fast path: every corner's preimage triangle is the polygon's first one or a neighbour
        # of it across a non-seam edge (then all lie in one chart without any walk).
        ref = np.repeat(lf[start], total)
        ok = lf == ref
        for k in range(3):
            ok |= (lf == self.nf[ref, k]) & ~self.seam[ref, k]
        poly_ok = np.logical_and.reduceat(ok, start) if P else np.zeros(0, dtype=bool)
        if self.V is not None and P:
            # also kept: polygons in one island whose UVs are not spread across the layout
            li = self.island[lf]
            one = np.minimum.reduceat(li, start) == np.maximum.reduceat(li, start)
            poly_ok |= one & ~self._stretched_polygons(out, lf, lb, start, total)
        straddling = np.zeros(P, dtype=bool)
        isl = self.island
        todo = np.nonzero(~poly_ok)[0].tolist()
        t_slice = time.perf_counter()
        for done, p in enumerate(todo):
            if time.perf_counter() - t_slice > slice_seconds:
                yield done / len(todo)
                t_slice = time.perf_counter()
            s, n = int(start[p]), int(total[p])
            faces = lf[s:s + n].tolist()
            islands = [int(isl[f]) for f in faces]
            # reference charts to try: the island most corners are in first, then the others;
            # the first whose UV polygon keeps the reference triangle's orientation wins
            order = sorted(range(n), key=lambda c: (-islands.count(islands[c]), c))
            refs = list(dict.fromkeys(faces[c] for c in order))
            best = None
            for refp in refs:
                T = self._continue(refp, set(faces))
                uvp = out[s:s + n].copy()
                changed = False
                for c, f in enumerate(faces):
                    t = T.get(f)
                    if t is None or t is IDENTITY:
                        continue
                    uvp[c] = _apply(t, uvp[c][None])[0]
                    changed = True
                missing = sum(1 for f in faces if f not in T)
                want = np.sign(_polygon_area(self.uv[refp])) or 1.0
                good = missing == 0 and np.all(_fan_areas(uvp) * want > 0)
                if best is None or (good and not best[0]):
                    best = (good, uvp, changed, missing)
                if good:
                    break
            good, uvp, changed, missing = best
            self.unresolved += missing
            self.folded += 0 if good else 1
            out[s:s + n] = uvp
            straddling[p] = changed
        self.result = (out, straddling)


def _polygon_area(uv):
    """Twice the signed area of a UV polygon (k,2) (shoelace)."""
    x, y = uv[:, 0], uv[:, 1]
    return float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _fan_areas(uv):
    """Twice the signed areas of the fan triangles (0, i, i+1) of a UV polygon (k,2)."""
    e = uv[1:] - uv[0]
    return e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0]


def _edge_coords(p, q, o):
    """o in the frame of the edge p -> q: p = (0,0), q = (1,0), lengths in units of |q - p|,
    o on the positive side."""
    e = q - p
    L2 = float(e @ e)
    s = float((o - p) @ e) / L2
    t = float(np.linalg.norm((o - p) - s * e)) / math.sqrt(L2)
    return np.array([s, t])


def signed_uv_areas(uv_tri):
    """Twice the signed area of UV triangles (m,3,2)."""
    u = np.asarray(uv_tri, dtype=np.float64)
    e1 = u[:, 1] - u[:, 0]
    e2 = u[:, 2] - u[:, 0]
    return e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]


def uv_stretch(uv_tri, xyz_tri):
    """Per triangle: the longest UV edge over the matching 3D edge (m,)."""
    u = np.asarray(uv_tri, dtype=np.float64)
    x = np.asarray(xyz_tri, dtype=np.float64)
    r = np.zeros(len(u))
    for k in range(3):
        du = np.linalg.norm(u[:, (k + 1) % 3] - u[:, k], axis=1)
        dx = np.linalg.norm(x[:, (k + 1) % 3] - x[:, k], axis=1)
        r = np.maximum(r, du / np.maximum(dx, 1e-300))
    return r


def uv_quality(uv_tri, xyz_tri, reference_stretch=None, factor=8.0):
    """Counts that catch a bad transfer: (flipped, straddling) UV triangles.

    flipped: signed UV area against the majority orientation (or zero);
    straddling: UV edges longer than `factor` times the reference UV-per-length ratio (default:
    the median ratio of these triangles), i.e. a triangle stretched across the UV layout."""
    A = signed_uv_areas(uv_tri)
    orient = 1.0 if np.sum(A > 0) >= np.sum(A < 0) else -1.0
    flipped = int(np.sum(A * orient <= 0))
    r = uv_stretch(uv_tri, xyz_tri)
    ref = float(np.median(r)) if reference_stretch is None else float(reference_stretch)
    straddling = int(np.sum(r > factor * ref))
    return flipped, straddling


def seam_straddling(uv_tri, preimage_tri, source_uv_tri, source_xyz_tri, factor=3.0):
    """Counts transferred UV triangles that span a seam of the source's UV layout.

    uv_tri (m,3,2): the transferred UVs of the target triangles; preimage_tri (m,3,3): the
    preimages of their corners on the source (3D). On the source, UV distance per 3D distance is
    at most r = max over its triangles of uv_stretch; a transferred triangle whose UV edge is
    more than `factor` * r times the 3D distance of its corners' preimages crosses a seam
    (its corners are close on the surface but far apart in the UV layout)."""
    r = float(np.max(uv_stretch(source_uv_tri, source_xyz_tri)))
    s = uv_stretch(uv_tri, preimage_tri)
    return int(np.sum(s > factor * r))


# --- a UV map for a source that has none --------------------------------------------------------

def box_projection(V, loop_vertex, loop_start, loop_total):
    """Cube-projection UVs per polygon corner (L,2): each polygon is projected along the axis its
    (Newell) normal is closest to, mirrored on the negative sides so every island keeps the
    outward orientation, the six sides in the cells of a 3 x 2 grid. Islands are the connected
    polygons of one side; no UV triangle is flipped."""
    V = np.asarray(V, dtype=np.float64)
    lv = np.asarray(loop_vertex, dtype=np.int64)
    start = np.asarray(loop_start, dtype=np.int64)
    total = np.asarray(loop_total, dtype=np.int64)
    poly = np.repeat(np.arange(len(start)), total)
    nxt = np.arange(len(lv)) + 1
    last = start + total - 1
    nxt[last] = start
    P, Q = V[lv], V[lv[nxt]]
    cr = np.cross(P, Q)                      # Newell: the polygon normal is the sum
    N = np.add.reduceat(cr, start, axis=0) if len(start) else np.zeros((0, 3))
    ax = np.argmax(np.abs(N), axis=1)
    sg = np.sign(N[np.arange(len(N)), ax])
    sg[sg == 0] = 1.0
    lo = V.min(axis=0) if len(V) else np.zeros(3)
    size = float(np.ptp(V, axis=0).max()) if len(V) else 1.0
    size = size if size > 0 else 1.0
    a, s = ax[poly], sg[poly]
    u = (P[np.arange(len(P)), (a + 1) % 3] - lo[(a + 1) % 3]) / size
    v = (P[np.arange(len(P)), (a + 2) % 3] - lo[(a + 2) % 3]) / size
    u = np.where(s < 0, 1.0 - u, u)
    cell = a * 2 + (s < 0)
    return np.stack([((cell % 3) + 0.05 + 0.9 * u) / 3.0,
                     ((cell // 3) + 0.05 + 0.9 * v) / 2.0], axis=1)
