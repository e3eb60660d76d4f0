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
    # closed form (a 2x2 inverse): LAPACK calls cost more than the arithmetic at this size
    s = np.asarray(src, dtype=np.float64)
    d = np.asarray(dst, dtype=np.float64)
    E = np.array([s[1] - s[0], s[2] - s[0]]).T          # columns: the source's edges
    det = E[0, 0] * E[1, 1] - E[0, 1] * E[1, 0]
    if abs(det) < 1e-300:
        return None
    Einv = np.array([[E[1, 1], -E[0, 1]], [-E[1, 0], E[0, 0]]]) / det
    M = np.array([d[1] - d[0], d[2] - d[0]]).T @ Einv
    return np.hstack([M, (d[0] - M @ s[0])[:, None]])


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


def _winding(P, X):
    """Winding number of the closed polygon P (k,2) around the point X (2,)."""
    d = P - X
    a = np.arctan2(d[:, 1], d[:, 0])
    turn = np.diff(np.append(a, a[0]))
    turn = (turn + np.pi) % (2 * np.pi) - np.pi
    return int(round(turn.sum() / (2 * np.pi)))


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


# --- cutting the target along the images of the source's seams ---------------------------------

def _bary2(C, X):
    """Barycentric coordinates (3,) of the 2D point X in the 2D triangle C (3,2); None when the
    triangle is degenerate."""
    d = (C[1, 0] - C[0, 0]) * (C[2, 1] - C[0, 1]) - (C[2, 0] - C[0, 0]) * (C[1, 1] - C[0, 1])
    if abs(d) < 1e-300:
        return None
    l1 = ((X[0] - C[0, 0]) * (C[2, 1] - C[0, 1]) - (C[2, 0] - C[0, 0]) * (X[1] - C[0, 1])) / d
    l2 = ((C[1, 0] - C[0, 0]) * (X[1] - C[0, 1]) - (X[0] - C[0, 0]) * (C[1, 1] - C[0, 1])) / d
    return np.array([1.0 - l1 - l2, l1, l2])


def _invert(A):
    """The inverse of the 2x3 affine map A."""
    a, b, c, d = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    M = np.array([[d, -b], [-c, a]]) / (a * d - b * c)
    return np.hstack([M, (-M @ A[:, 2])[:, None]])


class SeamCut:
    """The target cut along the images of the source's UV seams, so that every piece lies in ONE
    chart of the source's UV map and the transferred UVs need no continuation (no saw-teeth,
    no UV polygon reaching into the padding): a new polygon mesh (new topology).

    How: every target edge whose ends' preimages lie in different source triangles is traced
    on the source as the straight segment between them in the UV chart (continued across seams
    by UVTransfer's unfolding, docs/addon.md); each seam it crosses becomes a new vertex on the
    edge (shared by both polygons of the edge), carrying the UVs of both sides. A polygon with
    crossings on its boundary is split into pieces: by straight chords pairing its crossings
    (one seam curve through it: two pieces), or, when the image of a seam junction (a source
    vertex where three or more seams meet, or where one ends) lies in it, into a star around
    that image. Polygons neither rule resolves keep one chart per polygon (UVTransfer) and are
    counted in `unresolved`.

    Degenerate positions: a map can put a target vertex exactly on a source edge, vertex or seam,
    or a seam junction exactly on a target vertex or edge (symmetric meshes, e.g. a torus onto a
    torus with the translation that puts base vertex on base vertex; docs/addon.md "Outputs on
    the flip-based metric"). Then a target edge may run along a seam and a straight trace has no
    well-defined side. The cut works on a consistent infinitesimal perturbation instead: every
    target vertex's preimage moved a fraction INWARD (1e-6) of the way to its source triangle's
    centroid (one position per vertex, shared by all its edges; 1e-6 of a triangle is far below
    what a texture shows). A junction goes to the polygon whose preimage (its corners' perturbed
    preimages joined by the straight sides the traces draw, in one chart) winds around it, so
    that the crossings on that polygon's edges and the junction agree also where the trace and
    the forward map differ slightly (a junction next to a target edge, or on a target vertex or
    edge); its vertex is the forward image, moved just inside that polygon when it lies outside.

    Inputs: tr (UVTransfer of the source map to cut along); V_t (n,3), loop_start/loop_total (P,),
    loop_vertex (L,): the target's polygons; inv_face (n,), inv_bary (n,3): the preimage of each
    target vertex; optional fw_face (ns,), fw_bary (ns,3), F_t (mt,3), tri_polygon (mt,): the
    image of each source vertex on the target's triangles (to place seam junctions).
    Result (after run()): V (n',3) = V_t followed by the new vertices, loop_start/loop_total/
    loop_vertex/loop_uv of the new polygons, polygon_origin (P',) the target polygon each piece
    came from, and counts (cut, pieces, junctions, unresolved, crossings).
    """

    def __init__(self, tr, V_t, loop_start, loop_total, loop_vertex, inv_face, inv_bary,
                 fw_face=None, fw_bary=None, F_t=None, tri_polygon=None):
        self.tr = tr
        self.Vt = np.asarray(V_t, dtype=np.float64)
        self.start = np.asarray(loop_start, dtype=np.int64)
        self.total = np.asarray(loop_total, dtype=np.int64)
        self.lv = np.asarray(loop_vertex, dtype=np.int64)
        self.inv_face = np.asarray(inv_face, dtype=np.int64)
        b = np.clip(np.asarray(inv_bary, dtype=np.float64), 0.0, None)   # a stored map is float32:
        b /= np.maximum(b.sum(axis=1, keepdims=True), 1e-300)              # weights summing to 1
        self.inv_bary = b                   # the corners' UVs: the map itself
        self.trace_bary = (1.0 - self.INWARD) * b + self.INWARD / 3.0    # the traces (class doc)
        self.junction_at = self._junction_images(fw_face, fw_bary, F_t, tri_polygon)
        src_scale = float(np.ptp(tr.uv.reshape(-1, 2), axis=0).max()) if len(tr.uv) else 1.0
        self.uv_tol = 1e-7 * (src_scale if src_scale > 0 else 1.0)
        self.cut = self.pieces = self.junctions = self.unresolved = self.crossings = 0
        self.reasons = {}    # why polygons stayed unresolved: reason -> count

    INWARD = 1e-6   # the perturbation of the target vertices' preimages (class doc)

    # -- seam junctions ------------------------------------------------------------------------

    def _junction_images(self, fw_face, fw_bary, F_t, tri_polygon):
        """{target polygon: [(source vertex, 3D image)]} for the source vertices where the
        seam graph (mesh boundary edges excluded) does not simply pass through: 1 or >= 3
        seam edges meet there."""
        if fw_face is None or F_t is None or tri_polygon is None:
            return {}
        tr = self.tr
        F = tr.F
        fs, ks = np.nonzero(tr.seam & (tr.nf >= 0))
        a, b = F[fs, ks], F[fs, (ks + 1) % 3]
        key = np.unique(np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1), axis=0)
        valence = np.bincount(key.reshape(-1), minlength=int(F.max(initial=-1)) + 1)
        where = {}
        F_t = np.asarray(F_t, dtype=np.int64)
        tri_polygon = np.asarray(tri_polygon, dtype=np.int64)
        fw_face = np.asarray(fw_face, dtype=np.int64)
        fw_bary = np.asarray(fw_bary, dtype=np.float64)
        corners_of = None
        for s in np.nonzero((valence == 1) | (valence >= 3))[0].tolist():
            t = int(fw_face[s])
            if t < 0:
                continue
            X = fw_bary[s] @ self.Vt[F_t[t]]
            p = int(tri_polygon[t])
            # the polygon whose traced preimage holds the junction (class doc), among those
            # around the forward image's triangle
            if corners_of is None:
                corners_of = self._polygons_at_vertices()
            near = {q for k in range(3) for q in corners_of.get(int(F_t[t, k]), ())}
            q = self._polygon_holding(s, sorted(near), p)
            if q != p:
                X = self._just_inside(q, X)
            where.setdefault(q, []).append((s, X))
        return where

    def _just_inside(self, q, X):
        """A point of polygon q near X: the nearest point of its boundary, a tenth of the
        way to its centroid."""
        verts = self.lv[self.start[q]:self.start[q] + self.total[q]]
        P = self.Vt[verts]
        best = None
        for a, b in zip(P, np.roll(P, -1, axis=0)):
            e = b - a
            t = float(np.clip((X - a) @ e / max(float(e @ e), 1e-300), 0.0, 1.0))
            Y = a + t * e
            if best is None or np.linalg.norm(X - Y) < np.linalg.norm(X - best):
                best = Y
        return best + 0.1 * (P.mean(axis=0) - best)

    def _polygons_at_vertices(self):
        """{target vertex: [polygons with it as a corner]}."""
        out = {}
        poly = np.repeat(np.arange(len(self.start)), self.total)
        for v, q in zip(self.lv.tolist(), poly.tolist()):
            out.setdefault(v, []).append(q)
        return out

    def _polygon_holding(self, s, candidates, default):
        """The polygon among `candidates` whose perturbed preimage (corners' preimages in one
        chart continued from a source triangle at vertex s, straight sides as the trace draws
        them) winds around source vertex s; `default` when none or several do."""
        tr = self.tr
        fs, cs = np.nonzero(tr.F == s)
        if not len(fs):
            return default
        f0, c0 = int(fs[0]), int(cs[0])
        J = tr.uv[f0, c0]
        holding = []
        for q in candidates:
            verts = self.lv[self.start[q]:self.start[q] + self.total[q]]
            faces = self.inv_face[verts].tolist()
            T = tr._continue(f0, set(faces))
            if any(f not in T for f in faces):
                continue
            P = np.array([_apply(T[f], (self.trace_bary[v] @ tr.uv[f])[None])[0]
                          for v, f in zip(verts.tolist(), faces)])
            if _winding(P, J) != 0:
                holding.append(q)
        return holding[0] if len(holding) == 1 else default

    def _junction_uv(self, s, island, near):
        """UV of source vertex s in the given island, the corner nearest `near` (an island can
        meet itself at s across a seam)."""
        tr = self.tr
        fs, cs = np.nonzero(tr.F == s)
        best = None
        for f, c in zip(fs.tolist(), cs.tolist()):
            if int(tr.island[f]) != island:
                continue
            uv = tr.uv[f, c]
            d = float(np.linalg.norm(uv - near))
            if best is None or d < best[0]:
                best = (d, uv)
        return None if best is None else best[1].copy()

    # -- tracing one target edge on the source -------------------------------------------------

    def trace(self, a, b, max_steps=2000):
        """Seams crossed by the target edge a -> b (target vertices): a list of
        (s in (0,1) along the edge, UV on a's side, UV on b's side, island on a's side, island
        on b's side), or None when the edge cannot be traced (no short path on the source, a
        mesh boundary in the way, or the trace ends away from b's preimage)."""
        tr = self.tr
        uv, nf, ne, seam = tr.uv, tr.nf, tr.ne, tr.seam
        fa, fb = int(self.inv_face[a]), int(self.inv_face[b])
        if fa == fb:
            return []
        T_b = tr._continue(fa, {fb}).get(fb)
        # On a curved surface the unfolding depends on the path: the straight segment may
        # cross other seam edges than the shortest chain did, so b lands a little off its own
        # UV. Then b is placed by the trace's own chart and traced again (this converges at
        # once when both cross the same edges; near a seam junction the two sides of the
        # junction differ by the curvature there, and a trace ending in b's island within
        # about a triangle of b is taken).
        own_b = self.trace_bary[b] @ tr.uv[fb]
        size = float(np.ptp(tr.uv[fb], axis=0).max())
        best = None
        for _ in range(4):
            if T_b is None:
                break
            got = self._trace_once(fa, fb, T_b, a, b, max_steps)
            if got is None:
                break
            out, T_end, h = got
            if tr.island[h] != tr.island[fb]:
                # b's preimage lies just across a seam from where the straight trace ends
                # (it is on or next to that seam): the crossing is at b itself
                k = next((k for k in range(3) if tr.nf[h, k] == fb and tr.seam[h, k]), None)
                if k is None:
                    break
                B = _apply(T_b, own_b[None])
                out = out + [(1.0 - 1e-6, _apply(_invert(T_end), B)[0], own_b.copy(),
                              int(tr.island[h]), int(tr.island[fb]))]
                T_end = _compose(T_end, tr._seam_step(h, k))
                h = fb
            miss = float(np.abs(_apply(_invert(T_end), _apply(T_b, own_b[None]))[0]
                                - own_b).max())
            if best is None or miss < best[0]:
                best = (miss, out)
            if miss <= 1e-12:
                break
            T_b = T_end
        if best is None or best[0] > 2 * size:
            return None
        return best[1]

    def _trace_once(self, fa, fb, T_b, a, b, max_steps):
        """One straight trace from a's preimage to b's placed by the chart transform T_b:
        (crossings, chart transform of the triangle it ends in, that triangle) or None."""
        tr = self.tr
        uv, nf, ne, seam = tr.uv, tr.nf, tr.ne, tr.seam
        ba, bb = self.trace_bary[a], self.trace_bary[b]
        A = ba @ uv[fa]
        B = _apply(T_b, (bb @ uv[fb])[None])[0]
        h, T_h, s, came = fa, IDENTITY, 0.0, -1
        out = []
        for _ in range(max_steps):
            C = _apply(T_h, uv[h])
            la, lb = _bary2(C, A), _bary2(C, B)
            if la is None:
                return None
            if np.all(lb >= -1e-12):
                break
            # leave h where a barycentric coordinate falls to zero (edge k = corner k+1 -> k+2
            # is opposite corner k+2 ... so corner i's coordinate vanishes on edge (i+1) % 3)
            exit_s, exit_k = None, None
            for i in range(3):
                k = (i + 1) % 3
                if k == came or lb[i] >= la[i] or lb[i] >= 0:
                    continue
                si = la[i] / (la[i] - lb[i])
                if si >= s - 1e-12 and (exit_s is None or si < exit_s):
                    exit_s, exit_k = si, k
            if exit_k is None:
                return None
            g = int(nf[h, exit_k])
            if g < 0:
                return None
            if seam[h, exit_k]:
                T_g = _compose(T_h, tr._seam_step(h, exit_k))
                X = A + exit_s * (B - A)
                out.append((float(min(max(exit_s, 1e-9), 1 - 1e-9)),
                            _apply(_invert(T_h), X[None])[0], _apply(_invert(T_g), X[None])[0],
                            int(tr.island[h]), int(tr.island[g])))
                T_h = T_g
            came = int(ne[h, exit_k])
            h, s = g, exit_s
        else:
            return None
        return out, T_h, h

    # -- cutting -------------------------------------------------------------------------------

    def run(self):
        """Cuts every polygon; fills the result fields (see the class doc)."""
        nv0 = len(self.Vt)
        new_V = []
        edge_x = self._edges_without_crossings()
        # (lo, hi) -> [(s from lo, uv lo side, uv hi side, isl lo, isl hi, new vertex)]
        ls, lt, lvo, luv, origin = [], [], [], [], []
        fallback = []
        tr = self.tr
        naive = tr.naive(self.inv_face, self.inv_bary)    # per target vertex, its own chart
        for p in range(len(self.start)):
            s0, n = int(self.start[p]), int(self.total[p])
            verts = self.lv[s0:s0 + n].tolist()
            ring = []      # entries: [vertex, uv_in, uv_out, island_in, island_out, crossing]
            ok = True
            for c in range(n):
                a, b = verts[c], verts[(c + 1) % n]
                isl = int(tr.island[self.inv_face[a]])
                ring.append([a, naive[a], naive[a], isl, isl, False])
                key = (min(a, b), max(a, b))
                if key not in edge_x:
                    xs = self.trace(*key)
                    if xs is not None:
                        P0, P1 = self.Vt[key[0]], self.Vt[key[1]]
                        xs = [x + (nv0 + len(new_V) + i,) for i, x in enumerate(xs)]
                        new_V += [P0 + x[0] * (P1 - P0) for x in xs]
                        self.crossings += len(xs)
                    edge_x[key] = xs
                xs = edge_x[key]
                if xs is None:
                    ok = False
                    break
                if a < b:
                    ring += [[x[5], x[1], x[2], x[3], x[4], True] for x in xs]
                else:
                    ring += [[x[5], x[2], x[1], x[4], x[3], True] for x in reversed(xs)]
            pieces = self._pieces(p, ring, new_V, nv0) if ok else None
            if not ok:
                self._why("an edge could not be traced")
            if pieces is None:
                self.unresolved += 1
                fallback.append(p)
                pieces = [None]
            elif len(pieces) > 1:
                self.cut += 1
            for piece in pieces:
                ls.append(len(lvo))
                origin.append(p)
                if piece is None:
                    lt.append(n)
                    lvo += verts
                    luv += [None] * n          # filled from UVTransfer below
                    continue
                lt.append(len(piece))
                lvo += [v for v, _ in piece]
                luv += [uv for _, uv in piece]
                self.pieces += 1
        if fallback:
            lf = self.inv_face[self.lv]
            lb = self.inv_bary[self.lv]
            idx = np.concatenate([np.arange(self.start[p], self.start[p] + self.total[p])
                                  for p in fallback])
            sub_start = np.concatenate([[0], np.cumsum(self.total[fallback])[:-1]])
            uv_fb, _ = tr.polygon_uvs(lf[idx], lb[idx], sub_start, self.total[fallback])
            k = 0
            for i, u in enumerate(luv):
                if u is None:
                    luv[i] = uv_fb[k]
                    k += 1
        self.V = np.vstack([self.Vt] + ([np.asarray(new_V)] if new_V else []))
        self.loop_start = np.asarray(ls, dtype=np.int64)
        self.loop_total = np.asarray(lt, dtype=np.int64)
        self.loop_vertex = np.asarray(lvo, dtype=np.int64)
        self.loop_uv = np.asarray(luv, dtype=np.float64).reshape(-1, 2)
        self.polygon_origin = np.asarray(origin, dtype=np.int64)
        return self

    def _edges_without_crossings(self, factor=1.5):
        """{(lo, hi): []} for the target edges that need no trace: both ends' preimages in one
        triangle, or in one island with a UV distance within `factor` times the larger
        UV-per-length ratio of their two triangles times their 3D distance (a straight
        segment inside the island is that short; one that jumps across a seam of the island
        with itself is as long as the island)."""
        tr = self.tr
        nxt = np.arange(len(self.lv)) + 1
        nxt[self.start + self.total - 1] = self.start
        a, b = self.lv, self.lv[nxt]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        f_lo, f_hi = self.inv_face[lo], self.inv_face[hi]
        easy = f_lo == f_hi
        if tr.V is not None:
            ratio = uv_stretch(tr.uv, tr.V[tr.F])
            P_lo = points_at(tr.V, tr.F, f_lo, self.inv_bary[lo])
            P_hi = points_at(tr.V, tr.F, f_hi, self.inv_bary[hi])
            naive = tr.naive(self.inv_face, self.inv_bary)
            du = np.linalg.norm(naive[hi] - naive[lo], axis=1)
            dx = np.linalg.norm(P_hi - P_lo, axis=1)
            local = np.maximum(ratio[f_lo], ratio[f_hi])
            easy |= (tr.island[f_lo] == tr.island[f_hi]) & (du <= factor * local * dx)
        return {(int(x), int(y)): [] for x, y in zip(lo[easy], hi[easy])}

    def _pieces(self, p, ring, new_V, nv0):
        """The pieces [(vertex, uv)] of polygon p from its ring (corners and crossings in
        order); None when unresolved."""
        xs = [i for i, e in enumerate(ring) if e[5]]
        junction = self.junction_at.get(p, [])
        if len(junction) > 1:
            return self._why("several seam junctions in one face")
        if junction and xs:
            return self._star(ring, xs, junction[0], new_V, nv0)
        if not xs:
            return [[(e[0], e[2]) for e in ring]]
        if len(xs) % 2:
            return self._why("an odd number of crossings and no junction")
        return self._chords(ring)

    def _why(self, reason):
        self.reasons[reason] = self.reasons.get(reason, 0) + 1
        return None

    @staticmethod
    def _arc(ring, i, j):
        """Ring entries from crossing i to crossing j (cyclic) as (vertex, uv): i's uv_out,
        the entries between with their one UV, j's uv_in."""
        n = len(ring)
        out = [(ring[i][0], ring[i][2])]
        k = (i + 1) % n
        while k != j:
            out.append((ring[k][0], ring[k][2]))
            k = (k + 1) % n
        out.append((ring[j][0], ring[j][1]))
        return out

    def _chords(self, ring):
        """Peels pieces bounded by one arc and one chord between consecutive crossings, the
        chord whose two crossings see the same region outside it and the same seam (the UV
        jump across the chord agrees at both ends), until two crossings remain."""
        ring = [list(e) for e in ring]
        pieces = []
        while True:
            xs = [i for i, e in enumerate(ring) if e[5]]
            if len(xs) == 2:
                i, j = xs
                for a, b in ((i, j), (j, i)):
                    arc = self._arc(ring, a, b)
                    if len(arc) >= 3:
                        pieces.append(arc)
                return pieces
            best = None
            for t in range(len(xs)):
                i, j = xs[t], xs[(t + 1) % len(xs)]
                if ring[i][3] != ring[j][4]:
                    continue
                # the UV jump across the chord, arc side -> outside: in - out at i, out - in
                # at j (equal when the seam's identification is a translation)
                mism = float(np.linalg.norm((ring[i][1] - ring[i][2])
                                            - (ring[j][2] - ring[j][1])))
                if best is None or mism < best[0]:
                    best = (mism, i, j)
            if best is None:
                return self._why("no consistent chord")
            _, i, j = best
            arc = self._arc(ring, i, j)
            if len(arc) >= 3:
                pieces.append(arc)
            # the remainder: i and j become plain points seen from outside the chord
            ring[i] = [ring[i][0], ring[i][1], ring[i][1], ring[i][3], ring[i][3], False]
            ring[j] = [ring[j][0], ring[j][2], ring[j][2], ring[j][4], ring[j][4], False]
            n = len(ring)
            drop = set()
            k = (i + 1) % n
            while k != j:
                drop.add(k)
                k = (k + 1) % n
            ring = [e for k, e in enumerate(ring) if k not in drop]

    def _star(self, ring, xs, junction, new_V, nv0):
        """Pieces around the image J of a seam junction: one per arc between consecutive
        crossings, closed through J (with J's UV in that arc's island)."""
        s, X = junction
        jv = nv0 + len(new_V)
        pieces = []
        for t in range(len(xs)):
            i, j = xs[t], xs[(t + 1) % len(xs)]
            arc = self._arc(ring, i, j)
            uv_j = self._junction_uv(s, ring[i][4], arc[0][1])
            if uv_j is None:
                return self._why("a junction without a corner in the face's island")
            if len(xs) == 1 and len(arc) >= 4:
                # one seam ending inside: split the arc (which goes all around) at a corner
                m = len(arc) // 2
                pieces += [arc[:m + 1] + [(jv, uv_j)], arc[m:] + [(jv, uv_j)]]
            else:
                pieces.append(arc + [(jv, uv_j)])
        new_V.append(np.asarray(X, dtype=np.float64))
        self.junctions += 1
        return pieces


def boundary_loops(F):
    """Boundary loops of a triangle mesh F (m,3): vertex arrays, each in the direction of its
    faces' boundary halfedges (the surface on the left). [] for a closed mesh."""
    F = np.asarray(F, dtype=np.int64)
    a, b = F.reshape(-1), F[:, [1, 2, 0]].reshape(-1)
    inner = set(zip(a.tolist(), b.tolist()))
    nxt = {u: w for u, w in zip(a.tolist(), b.tolist()) if (w, u) not in inner}
    loops, seen = [], set()
    for u in nxt:
        if u in seen:
            continue
        loop = [u]
        seen.add(u)
        while nxt[loop[-1]] not in seen:
            loop.append(nxt[loop[-1]])
            seen.add(loop[-1])
        loops.append(np.array(loop, dtype=np.int64))
    return loops


def _kept_positive(uv3, want):
    """Whether a UV triangle (3,2) has the orientation `want` (+1 / -1) with room to spare for
    Blender's float32 UVs (coordinates off by up to ~6e-8 each: twice the area off by up to
    ~2.4e-7 times the longest side): twice its area above 1e-6 times its longest side and 1e-6
    times that side squared."""
    longest = max(float(np.linalg.norm(uv3[i] - uv3[(i + 1) % 3])) for i in range(3))
    return signed_uv_areas(uv3[None])[0] * want > 1e-6 * longest * max(longest, 1.0)


def right_ear_uvs(tr, uv, V_t, loop_start, loop_total, loop_vertex, loop_face, loop_bary):
    """Ears of an open target whose transferred UVs turn over, righted in UV (docs/open_surfaces.md
    "Ears"). An ear is a triangle with all three corners on the boundary: its corners' preimages
    lie on the source's boundary, so its UVs are the chord of three points of the source's
    boundary in the UV chart, which turns over wherever that boundary curve turns the wrong way
    between them (a jagged rim; a steep rim seen by a box projection). When the middle corner
    (between the ear's two boundary edges) is on no other polygon, its UV belongs to the ear
    alone: it is moved to the UV of the source boundary vertex, on the arc between the other two
    corners' preimages, nearest (in 3D) to its own preimage among those that make the ear
    positive in the same island's chart; when none does (the source's boundary runs concave in
    the chart all along the arc), to the UV that makes the ear's UV triangle similar to the ear
    (just past the island's border). tr: the UVTransfer (its F, uv, island, V); uv (L,2) the
    target's corner UVs (changed in place); loop_face / loop_bary: the preimage of each corner's
    vertex. Returns (ears turned, righted along the boundary, given their own shape)."""
    start = np.asarray(loop_start, dtype=np.int64)
    total = np.asarray(loop_total, dtype=np.int64)
    lv = np.asarray(loop_vertex, dtype=np.int64)
    n_t = len(V_t)
    # The target's boundary: polygon edges used once, with their direction in the polygon.
    count = {}
    for p in range(len(start)):
        vs = lv[start[p]:start[p] + total[p]].tolist()
        for k in range(len(vs)):
            e = (vs[k], vs[(k + 1) % len(vs)])
            count[(min(e), max(e))] = count.get((min(e), max(e)), 0) + 1
    directed = set()
    polygons_at = np.zeros(n_t, dtype=np.int64)
    for p in range(len(start)):
        vs = lv[start[p]:start[p] + total[p]].tolist()
        for k in range(len(vs)):
            polygons_at[vs[k]] += 1
            e = (vs[k], vs[(k + 1) % len(vs)])
            if count[(min(e), max(e))] == 1:
                directed.add(e)
    if not directed:
        return 0, 0, 0
    # The source's boundary loops, and each boundary vertex's place and a face holding it.
    F = tr.F
    src_loops = boundary_loops(F)
    place = {}
    for li, loop in enumerate(src_loops):
        for i, v in enumerate(loop.tolist()):
            place[v] = (li, i)
    face_of_corner = {}
    for f in range(len(F)):
        for k in range(3):
            face_of_corner.setdefault(int(F[f, k]), []).append((f, k))
    Vs = tr.V

    def on_loop(face, bary):
        """(loop, position along it) of a point of the source's boundary: its two heaviest
        corners are consecutive boundary vertices."""
        tri = F[face]
        order = np.argsort(-bary)
        u, w = int(tri[order[0]]), int(tri[order[1]])
        if u in place and bary[order[0]] > 1 - 1e-9:
            return place[u][0], float(place[u][1])     # on a boundary vertex
        if u not in place or w not in place or place[u][0] != place[w][0]:
            return None
        li = place[u][0]
        n = len(src_loops[li])
        iu, iw = place[u][1], place[w][1]
        t = bary[order[1]] / max(bary[order[0]] + bary[order[1]], 1e-300)
        if (iu + 1) % n == iw:
            return li, iu + t
        if (iw + 1) % n == iu:
            return li, iw + (1 - t)
        return li, float(iu)

    # The orientation the transfer keeps: the sign most triangles have (an orientation-reversing
    # map turns them all).
    tri = np.flatnonzero(total == 3)
    signs = np.sign(signed_uv_areas(uv[start[tri][:, None] + np.arange(3)[None]])) if len(tri) else np.zeros(0)
    want = 1.0 if np.sum(signs > 0) >= np.sum(signs < 0) else -1.0
    turned = righted = shaped = 0
    for p in tri.tolist():
        s = int(start[p])
        vs = lv[s:s + 3].tolist()
        if _kept_positive(uv[s:s + 3], want):
            continue
        # The middle corner k: edges (k-1 -> k) and (k -> k+1) on the boundary.
        k = next((k for k in range(3) if (vs[k - 1], vs[k]) in directed and (vs[k], vs[(k + 1) % 3]) in directed),
                 None)
        if k is None:
            continue
        turned += 1
        if polygons_at[vs[k]] != 1:
            continue
        ia, ic = s + (k - 1) % 3, s + (k + 1) % 3
        la = on_loop(int(loop_face[ia]), np.asarray(loop_bary[ia]))
        lc = on_loop(int(loop_face[ic]), np.asarray(loop_bary[ic]))
        lb = on_loop(int(loop_face[s + k]), np.asarray(loop_bary[s + k]))
        if la is None or lc is None or lb is None or not la[0] == lb[0] == lc[0]:
            continue
        n = len(src_loops[la[0]])
        ahead = lambda x, y: (y - x) % n       # noqa: E731
        forward = ahead(la[1], lb[1]) <= ahead(la[1], lc[1])
        span = ahead(la[1], lc[1]) if forward else ahead(lc[1], la[1])
        if span > n / 2:
            continue
        here = points_at(Vs, F, np.array([int(loop_face[s + k])]), np.asarray(loop_bary[s + k])[None])[0]
        islands = {int(tr.island[int(loop_face[ia])]), int(tr.island[int(loop_face[ic])])}
        best = None
        for step in range(1, int(span) + 2):
            pos = (math.floor(la[1]) + step) if forward else (math.ceil(la[1]) - step)
            along = ahead(la[1], pos) if forward else ahead(pos, la[1])
            if along <= 0 or along >= span:
                continue
            w = int(src_loops[la[0]][int(pos) % n])
            for f, kk in face_of_corner.get(w, []):
                if int(tr.island[f]) not in islands:
                    continue
                cand = uv[s:s + 3].copy()
                cand[k] = tr.uv[f, kk]
                if _kept_positive(cand, want):
                    d = float(np.linalg.norm(Vs[w] - here))
                    if best is None or d < best[0]:
                        best = (d, tr.uv[f, kk])
        if best is not None:
            uv[s + k] = best[1]
            righted += 1
            continue
        # No boundary vertex will do: the source's boundary runs concave in the chart all along
        # the arc (a box projection's steep rim), so every three points of it turn. The middle
        # corner's UV then makes the ear's UV triangle similar to the ear itself (its angle at
        # the first corner, its sides' ratio), on the side that keeps the orientation: just past
        # the island's border, as the continued charts run into the texture's padding.
        A_, B_, C_ = (np.asarray(V_t[vs[(k + j) % 3]], dtype=np.float64) for j in (-1, 0, 1))
        ab, ac = B_ - A_, C_ - A_
        lac = float(np.linalg.norm(ac))
        if lac <= 0:
            continue
        alpha = math.atan2(float(np.linalg.norm(np.cross(ab, ac))), float(ab @ ac))
        rho = float(np.linalg.norm(ab)) / lac
        e = uv[ic] - uv[ia]
        ang = -alpha * want
        rot = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
        cand = uv[s:s + 3].copy()
        cand[k] = uv[ia] + rho * (rot @ e)
        if _kept_positive(cand, want):
            uv[s + k] = cand[k]
            shaped += 1
    return turned, righted, shaped
