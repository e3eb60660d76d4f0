"""The Blender-free maths of the map's outputs (DESIGN.md §2.13, paper §VIII): UV transfer that
respects seams, morph positions, per-face dilatation, conformal factor, mean curvature, colour
scales, landmark pairs and the fingerprints that tell when a stored correspondence is stale.

Plain numpy in, plain numpy out; nothing here imports bpy (the module is imported by file in the
pytest suite too). Conventions:
  V (n,3) float64 vertices, F (m,3) int triangles (the triangulation the map was computed on);
  a "point on a surface" is (face index into F, barycentric weights (3,)) as returned by
  surfmap.surface_map ('forward': per source vertex on the target, 'inverse': per target vertex
  on the source); corner_uv (m,3,2) holds the UV of every triangle corner.
"""
import hashlib
import math
import heapq

import numpy as np


# --- fingerprints (stale correspondence) ------------------------------------------------------

def fingerprint(V, F):
    """Hex digest of a triangulated mesh's vertex positions (float32) and triangles: changes
    when a vertex moves or the connectivity changes, not when the object is moved."""
    h = hashlib.sha1()
    V = np.ascontiguousarray(V, dtype=np.float32)
    F = np.ascontiguousarray(F, dtype=np.int32)
    h.update(np.int64([len(V), len(F)]).tobytes())
    h.update(V.tobytes())
    h.update(F.tobytes())
    return h.hexdigest()[:20]


# --- basic geometry ---------------------------------------------------------------------------

def points_at(V, F, face, bary):
    """3D points sum_k bary[i,k] V[F[face[i],k]] (n',3)."""
    V = np.asarray(V, dtype=np.float64)
    tri = np.asarray(F, dtype=np.int64)[np.asarray(face, dtype=np.int64)]
    return np.einsum("ik,ikj->ij", np.asarray(bary, dtype=np.float64), V[tri])


def face_normals(V, F):
    """Unnormalised normals (m,3): cross(b - a, c - a); their length is twice the area."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return np.cross(b - a, c - a)


def face_areas(V, F):
    return 0.5 * np.linalg.norm(face_normals(V, F), axis=1)


def vertex_normals(V, F):
    n = np.zeros((len(V), 3))
    N = face_normals(V, F)
    F = np.asarray(F, dtype=np.int64)
    for k in range(3):
        np.add.at(n, F[:, k], N)
    L = np.linalg.norm(n, axis=1)
    L[L == 0] = 1.0
    return n / L[:, None]


def apply_matrix(M, P):
    """Points P (n,3) through the 4x4 affine matrix M."""
    M = np.asarray(M, dtype=np.float64)
    P = np.asarray(P, dtype=np.float64)
    return P @ M[:3, :3].T + M[:3, 3]


def bounding_diagonal(V):
    V = np.asarray(V, dtype=np.float64)
    if len(V) == 0:
        return 1.0
    d = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    return d if d > 0 and math.isfinite(d) else 1.0


# --- distortion -------------------------------------------------------------------------------

def _local_2d(P):
    """Triangles P (m,3,3) in their own plane: (m,2,2) edge matrix [e1 e2] (columns), so that
    the affine map between two triangles is E_img @ inv(E_src)."""
    e1 = P[:, 1] - P[:, 0]
    e2 = P[:, 2] - P[:, 0]
    l1 = np.linalg.norm(e1, axis=1)
    l1[l1 == 0] = 1e-300
    x = e1 / l1[:, None]
    n = np.cross(e1, e2)
    y = np.cross(n, x)
    ly = np.linalg.norm(y, axis=1)
    ly[ly == 0] = 1e-300
    y = y / ly[:, None]
    E = np.empty((len(P), 2, 2))
    E[:, 0, 0] = l1
    E[:, 1, 0] = 0.0
    E[:, 0, 1] = np.einsum("ij,ij->i", e2, x)
    E[:, 1, 1] = np.einsum("ij,ij->i", e2, y)
    return E


def dilatation(V_src, F_src, image, image_normals=None):
    """Per-face dilatation D' = Γ/γ (paper §VII-A): the ratio of the singular values of the
    affine map from each source triangle onto the triangle of its corners' images.

    V_src (n,3), F_src (m,3); image (n,3): the image of every source vertex (e.g. the forward
    positions on the target). image_normals (m,3), optional: the target surface's normal near each
    image triangle; an image triangle facing against it counts as flipped (D' = inf).
    Returns (D (m,), flipped (m,) bool). Degenerate images give D' = inf.
    """
    F = np.asarray(F_src, dtype=np.int64)
    Ps = np.asarray(V_src, dtype=np.float64)[F]
    Pi = np.asarray(image, dtype=np.float64)[F]
    Es, Ei = _local_2d(Ps), _local_2d(Pi)
    det_s = Es[:, 0, 0] * Es[:, 1, 1]
    ok = np.abs(det_s) > 0
    inv = np.zeros_like(Es)
    inv[ok, 0, 0] = 1.0 / Es[ok, 0, 0]
    inv[ok, 0, 1] = -Es[ok, 0, 1] / det_s[ok]
    inv[ok, 1, 1] = 1.0 / Es[ok, 1, 1]
    A = np.einsum("mij,mjk->mik", Ei, inv)
    s = np.linalg.svd(A, compute_uv=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        D = s[:, 0] / s[:, 1]
    D[~np.isfinite(D) | ~ok] = np.inf
    flipped = np.zeros(len(F), dtype=bool)
    if image_normals is not None:
        n_img = np.cross(Pi[:, 1] - Pi[:, 0], Pi[:, 2] - Pi[:, 0])
        flipped = np.einsum("ij,ij->i", n_img, np.asarray(image_normals)) < 0
        D[flipped] = np.inf
    return D, flipped


def conformal_factor(V_src, F_src, image):
    """Conformal factor λ per source vertex (paper §VIII-D): area of the image of its one-ring
    over the area of the one-ring, divided by the ratio of the total areas (so λ = 1 means 'as
    much area as on average'). Returns (n,)."""
    F = np.asarray(F_src, dtype=np.int64)
    a_s = face_areas(V_src, F)
    a_i = face_areas(image, F)
    n = len(V_src)
    ring_s = np.zeros(n)
    ring_i = np.zeros(n)
    for k in range(3):
        np.add.at(ring_s, F[:, k], a_s)
        np.add.at(ring_i, F[:, k], a_i)
    scale = a_s.sum() / max(a_i.sum(), 1e-300)
    ring_s[ring_s == 0] = 1e-300
    return ring_i / ring_s * scale


def mean_curvature(V, F):
    """Signed mean curvature per vertex, scale-free: H · sqrt(A / 4π) with A the total area
    (1 on any round sphere), from the cotangent Laplacian (|Δx| = 2H) over the barycentric
    one-ring area; positive where the surface is convex along its outward normal."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    n = len(V)
    L = np.zeros((n, 3))
    for k in range(3):
        i, j, o = F[:, k], F[:, (k + 1) % 3], F[:, (k + 2) % 3]
        u, w = V[i] - V[o], V[j] - V[o]
        cot = np.einsum("ij,ij->i", u, w) / np.maximum(np.linalg.norm(np.cross(u, w), axis=1),
                                                        1e-300)
        d = (V[j] - V[i]) * cot[:, None] * 0.5
        np.add.at(L, i, d)
        np.add.at(L, j, -d)
    area = np.zeros(n)
    a = face_areas(V, F) / 3.0
    for k in range(3):
        np.add.at(area, F[:, k], a)
    area[area == 0] = 1e-300
    Hn = L / area[:, None]  # = -2 H n for the outward normal n (Δx = -2Hn convention)
    H = 0.5 * np.linalg.norm(Hn, axis=1)
    sign = -np.sign(np.einsum("ij,ij->i", Hn, vertex_normals(V, F)))
    sign[sign == 0] = 1.0
    return H * sign * math.sqrt(max(a.sum() * 3.0, 0.0) / (4 * math.pi))


def mean_curvature_difference(V_src, F_src, V_tgt, F_tgt, face, bary):
    """H_source(v) − H_target(f(v)) per source vertex (scale-free curvatures, see
    mean_curvature; the target's value interpolated at the image point)."""
    Hs = mean_curvature(V_src, F_src)
    Ht = mean_curvature(V_tgt, F_tgt)
    tri = np.asarray(F_tgt, dtype=np.int64)[np.asarray(face, dtype=np.int64)]
    return Hs - np.einsum("ik,ik->i", np.asarray(bary, dtype=np.float64), Ht[tri])


def per_polygon(values, tri_polygon, num_polygons, weights=None):
    """Triangle values -> polygon values (weighted mean over the polygon's triangles; the
    infinite values of flipped/degenerate triangles are kept infinite)."""
    values = np.asarray(values, dtype=np.float64)
    w = np.ones_like(values) if weights is None else np.asarray(weights, dtype=np.float64)
    tri_polygon = np.asarray(tri_polygon, dtype=np.int64)
    bad = ~np.isfinite(values)
    s = np.zeros(num_polygons)
    ws = np.zeros(num_polygons)
    np.add.at(s, tri_polygon, np.where(bad, 0.0, values * w))
    np.add.at(ws, tri_polygon, np.where(bad, 0.0, w))
    out = s / np.where(ws == 0, 1.0, ws)
    anybad = np.zeros(num_polygons, dtype=bool)
    np.logical_or.at(anybad, tri_polygon, bad)
    out[anybad] = np.inf
    return out


# --- colour scales ----------------------------------------------------------------------------

def _srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


# display (sRGB) stops: a viridis-like sequential scale and a blue-white-red diverging one
SEQUENTIAL = np.array([[0.267, 0.005, 0.329], [0.230, 0.322, 0.546], [0.128, 0.567, 0.551],
                       [0.369, 0.789, 0.383], [0.993, 0.906, 0.144]])
DIVERGING = np.array([[0.230, 0.299, 0.754], [0.552, 0.690, 0.996], [0.866, 0.866, 0.866],
                      [0.958, 0.604, 0.482], [0.706, 0.016, 0.150]])
INVALID = (1.0, 0.0, 1.0)  # magenta: flipped or degenerate


def colour_scale(values, lo, hi, stops=SEQUENTIAL):
    """Linear RGBA (n,4) of values on the scale [lo, hi] (clamped); non-finite -> magenta."""
    v = np.asarray(values, dtype=np.float64)
    t = (v - lo) / (hi - lo) if hi > lo else np.zeros_like(v)
    t = np.clip(np.nan_to_num(t, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    x = t * (len(stops) - 1)
    i = np.minimum(x.astype(np.int64), len(stops) - 2)
    f = (x - i)[:, None]
    rgb = stops[i] * (1 - f) + stops[i + 1] * f
    rgb[~np.isfinite(v)] = INVALID
    out = np.ones((len(v), 4))
    out[:, :3] = _srgb_to_linear(rgb)
    return out


def robust_range(values, lo_q=0.0, hi_q=0.99, floor=None):
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return (0.0, 1.0)
    lo = float(np.quantile(v, lo_q)) if floor is None else float(floor)
    hi = float(np.quantile(v, hi_q))
    if hi <= lo:
        hi = lo + 1e-6
    return lo, hi


def symmetric_range(values, q=0.99):
    v = np.asarray(values, dtype=np.float64)
    v = np.abs(v[np.isfinite(v)])
    m = float(np.quantile(v, q)) if len(v) else 1.0
    m = m if m > 0 else 1e-6
    return -m, m


# --- UV transfer with seams -------------------------------------------------------------------

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
        for p in np.nonzero(~poly_ok)[0].tolist():
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
        return out, straddling


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


# --- landmarks --------------------------------------------------------------------------------

LANDMARK_PREFIX = "lm_"


def landmark_pairs(source_groups, target_groups, prefix=LANDMARK_PREFIX):
    """Landmark pairs from vertex groups of matching names (e.g. 'lm_nose' on both objects).

    source_groups / target_groups: {group name: (vertex indices, weights)} of the groups whose
    names start with `prefix`. Each group names one landmark: its vertex of largest weight.
    Returns (pairs (k,2) int, names, problems): problems lists groups present on one object only
    or empty; the caller decides whether they are errors."""
    names, pairs, problems = [], [], []
    for name in sorted(set(source_groups) | set(target_groups)):
        if not name.startswith(prefix):
            continue
        if name not in source_groups or name not in target_groups:
            side = "source" if name in source_groups else "target"
            problems.append(f"vertex group '{name}' is only on the {side}")
            continue
        picks = []
        for side, groups in (("source", source_groups), ("target", target_groups)):
            idx, w = groups[name]
            if len(idx) == 0:
                problems.append(f"vertex group '{name}' on the {side} has no vertices")
                break
            picks.append(int(np.asarray(idx)[int(np.argmax(w))]))
        if len(picks) == 2:
            names.append(name)
            pairs.append(picks)
    return np.asarray(pairs, dtype=np.int64).reshape(-1, 2), names, problems


def check_landmarks(pairs, n_source, n_target):
    """Raises ValueError for out-of-range or repeated landmark vertices."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    for side, col, n in (("source", 0, n_source), ("target", 1, n_target)):
        v = pairs[:, col]
        if len(v) and (v.min() < 0 or v.max() >= n):
            raise ValueError(f"landmark vertex out of range on the {side} "
                             f"(the mesh has {n} vertices)")
        u, c = np.unique(v, return_counts=True)
        if np.any(c > 1):
            raise ValueError(f"{side} vertex {int(u[c > 1][0])} is used by two landmarks")


def landmark_summary(res, count):
    """How the landmarks of a surface_map result were held, in one line (None without any).

    Genus 0: the Möbius map they fix (exact up to 3, least squares beyond). Genus >= 1, from
    res['landmark_method']: plain pins (the exact held optimum), the barrier continuation (the
    landmarks walked to their targets with the map bijective at every step; its steps), or
    carried neighbourhoods (rings of neighbours held rigidly with each landmark; tried when
    the continuation stalls)."""
    if not count:
        return None
    if res.get("genus", 0) == 0:
        err = float(res.get("landmark_error", 0.0))
        return (f"{count} landmark(s): the Möbius map they fix"
                + (" (exact)" if count <= 3 else f" (least squares, largest miss {err:.3g})"))
    method = res.get("landmark_method", "")
    steps, solves = int(res.get("landmark_steps", 0)), int(res.get("landmark_solves", 0))
    if method == "pinned":
        how = "plain pins (the exact held optimum; nothing folded)"
    elif method == "barrier continuation":
        how = (f"barrier continuation in {steps} step(s) (plain pins folded the map; bijective "
               f"at every step)")
    elif method == "carried neighbourhoods":
        rings = [int(r) for r in res.get("landmark_rings", [])]
        how = (f"carried neighbourhoods (rings {rings}, {int(res.get('landmark_held_vertices', 0))} "
               f"vertices held rigidly, {solves} solve(s)"
               + (f"; the barrier continuation stalled after {steps} step(s)" if steps else "") + ")")
    else:
        how = method or "held"
    return f"{count} landmark(s) held by {how}"


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


# --- connectivity refinement for the morph (paper §VII-E) -------------------------------------

def _split_triangles(F, origin_bary, split, new):
    """One round of red-green refinement, vectorised. F (m,3); origin_bary (m,3,3): per corner
    its barycentrics in the original source triangle; split (k,2) sorted edges to split at
    their midpoints, new (k,) the midpoint vertices. Triangles with 1, 2 or 3 split edges become
    2, 3 or 4 (orientation kept). Returns (F', parent index into F, origin_bary')."""
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    n = int(max(F.max(initial=0), split.max(initial=0))) + 1
    codes = split[:, 0] * n + split[:, 1]
    order = np.argsort(codes)
    codes, new = codes[order], np.asarray(new)[order]
    nxt = np.roll(F, -1, axis=1)
    ec = np.minimum(F, nxt) * n + np.maximum(F, nxt)          # (m,3) edge k = corner k -> k+1
    pos = np.clip(np.searchsorted(codes, ec), 0, max(len(codes) - 1, 0))
    hit = (codes[pos] == ec) if len(codes) else np.zeros_like(ec, dtype=bool)
    mid = np.where(hit, new[pos] if len(codes) else -1, -1)     # (m,3) midpoint or -1
    ns = hit.sum(axis=1)
    outs_f, outs_p, outs_b = [F[ns == 0]], [np.nonzero(ns == 0)[0]], [origin_bary[ns == 0]]
    # rotate each triangle: ns == 1 -> its split edge is edge 0; ns == 2 -> its unsplit edge
    # is edge 2 (split edges 0, 1); ns == 3 -> no rotation
    r = np.zeros(m, dtype=np.int64)
    r[ns == 1] = np.argmax(hit[ns == 1], axis=1)
    r[ns == 2] = (np.argmin(hit[ns == 2], axis=1) + 1) % 3
    idx = (r[:, None] + np.arange(3)[None, :]) % 3
    rows = np.arange(m)[:, None]
    C, Mi, B = F[rows, idx], mid[rows, idx], origin_bary[rows, idx]
    MB = 0.5 * (B + np.roll(B, -1, axis=1))                      # barycentrics of the midpoints

    def emit(sel, corners):
        t = np.nonzero(sel)[0]
        for tri in corners:
            f = np.stack([(C if w == "c" else Mi)[t, k] for w, k in tri], axis=1)
            bb = np.stack([(B if w == "c" else MB)[t, k] for w, k in tri], axis=1)
            outs_f.append(f)
            outs_p.append(t)
            outs_b.append(bb)
    # corner k: ("c", k); midpoint of edge k (k -> k+1): ("m", k)
    emit(ns == 1, [(("c", 0), ("m", 0), ("c", 2)), (("m", 0), ("c", 1), ("c", 2))])
    emit(ns == 2, [(("m", 0), ("c", 1), ("m", 1)), (("c", 0), ("m", 0), ("m", 1)),
                   (("c", 0), ("m", 1), ("c", 2))])
    emit(ns == 3, [(("c", 0), ("m", 0), ("m", 2)), (("m", 0), ("c", 1), ("m", 1)),
                   (("m", 2), ("m", 1), ("c", 2)), (("m", 0), ("m", 1), ("m", 2))])
    return (np.concatenate(outs_f).astype(np.int64), np.concatenate(outs_p).astype(np.int64),
            np.concatenate(outs_b))


def refine_for_morph(V, F, image, image_normal, project, max_length, max_bend=0.02,
                     rounds=4, max_vertices=250000):
    """Connectivity refinement of the source for a morph that follows the target's detail
    (paper §VII-E): source edges whose image is long (|f(v_i) − f(v_j)| > max_length) or bends
    ((1 − N_i·N_j)/2 > max_bend, N the target's normals at the images) are split at their
    midpoints, red-green style (1, 2 or 3 split edges per triangle), for up to `rounds` rounds.

    V (n,3), F (m,3): the source; image (n,3), image_normal (n,3): the images on the target and
    the target's unit normals there; project(points (k,3)) -> (positions (k,3), normals (k,3)):
    puts the new vertices' images on the target. The new vertex's image is the target point
    closest to the midpoint of the edge's image (an approximation of the paper's midpoint in
    the uniformization domain, good once the edges are short).
    Returns dict(V (n',3) on the source, F (m',3), image (n',3), origin_face (m',) triangle of F
    each new triangle lies in, origin_bary (m',3,3) barycentrics of its corners there, rounds)."""
    V = np.asarray(V, dtype=np.float64).copy()
    F0 = np.asarray(F, dtype=np.int64)
    F = F0.copy()
    img = np.asarray(image, dtype=np.float64).copy()
    nrm = np.asarray(image_normal, dtype=np.float64).copy()
    origin = np.arange(len(F))
    obary = np.tile(np.eye(3), (len(F), 1, 1))
    done_rounds = 0
    for _ in range(rounds):
        e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        e = np.unique(np.sort(e, axis=1), axis=0)
        d = np.linalg.norm(img[e[:, 0]] - img[e[:, 1]], axis=1)
        bend = 0.5 * (1.0 - np.einsum("ij,ij->i", nrm[e[:, 0]], nrm[e[:, 1]]))
        split = e[(d > max_length) | (bend > max_bend)]
        if len(split) == 0 or len(V) + len(split) > max_vertices:
            break
        new = np.arange(len(V), len(V) + len(split))
        pos, nn = project(0.5 * (img[split[:, 0]] + img[split[:, 1]]))
        V = np.vstack([V, 0.5 * (V[split[:, 0]] + V[split[:, 1]])])
        img = np.vstack([img, np.asarray(pos, dtype=np.float64)])
        nrm = np.vstack([nrm, np.asarray(nn, dtype=np.float64)])
        F, o, obary = _split_triangles(F, obary, split, new)
        origin = origin[o]
        done_rounds += 1
    return {"V": V, "F": F, "image": img, "origin_face": origin, "origin_bary": obary,
            "rounds": done_rounds}


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
