"""The reflection-aware solve of the doubles (docs/open_surfaces.md "The half's solve"): the harmonic map
between two doubles restricted to the maps that commute with their reflections, solved on the
source's half alone.

Why: the doubles' harmonic map (surfmap/open_double.py) is symmetric only up to the
discretization (the closed pipeline's system of loops refines each double's faces where its loops
cross them, which no reflection respects, so neither the target's metric nor the source's weights
are exactly symmetric): 0.2-1% of the diagonal. Where the map crushes a wide source band into a
narrow rim of the target (the artery's tubes onto the small holes of a cow) that asymmetry decides
on which side of the rim an image lands, and the half folds onto itself.

What: a map f of the doubles with f sigma_S = sigma_T f is given by its restriction to the source's
half, each mirror vertex's image being its twin's reflected, and it keeps the boundary (the fixed
curve of sigma_S) on the fixed curve of sigma_T: the target's boundary, a geodesic of the double's
hyperbolic metric. Its energy is twice the half's. So the unknowns are one point per vertex of the
source's half in the target half's hyperbolic metric with geodesic boundary; each boundary vertex
slides along the geodesic its loop's image lies on (one real unknown: its arc length), interior
vertices move freely. The restricted energy is geodesically convex (the constraint sets are
geodesics of a Hadamard space), so the minimiser in the class is unique, and the mirror half is its
exact reflection: symmetric to round-off, boundary onto boundary exactly.

The target half's metric is the double's hyperbolic metric on the double's own connectivity
(`_core.ricci_flow`, fixed connectivity, symmetric up to the mirror sheet's 1e-6 offset), each
edge's length averaged with its mirror's so that it is exactly symmetric; its boundary vertices'
angles then sum to pi (geodesic boundary). The half is laid out in the Poincare disk along a
breadth-first tree of its faces (one fundamental domain cut along the tree's complement); the
class is the doubles' map's (open_double._double_map: its images reflected onto the half give
each source vertex a target face, each source edge the deck element of the shortest path of faces
between its ends' faces). Solved by Newton-like steps preconditioned by the weighted connection
Laplacian (the Hessian of a flat target; the hyperbolic one is larger, so the steps are descent
directions), with a line search on the energy. Applies to any (g, b) through the doubles;
open_double uses it for every candidate whose doubles' map was computed, the doubles' own half as
the fallback when it fails (metric not converged, a vertex not located, not converged)."""
from collections import deque

import numpy as np

from . import _core


class ReflectionSolveError(_core.SolveError):
    """The reflection-aware solve cannot be done on this pair (open_double falls back)."""


# Moebius maps of the disk as 2x2 complex matrices [[a, b], [c, d]]: z -> (a z + b) / (c z + d).

def _apply(M, z):
    return (M[..., 0, 0] * z + M[..., 0, 1]) / (M[..., 1, 0] * z + M[..., 1, 1])


def _inv(M):
    out = np.empty_like(M)
    out[..., 0, 0], out[..., 0, 1] = M[..., 1, 1], -M[..., 0, 1]
    out[..., 1, 0], out[..., 1, 1] = -M[..., 1, 0], M[..., 0, 0]
    return out


def _normalized(M):
    det = M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]
    return M / np.sqrt(det)[..., None, None]


def _to_origin(z):
    """(..., 2, 2): the isometry z' -> (z' - z) / (1 - conj(z) z') taking z to 0."""
    z = np.asarray(z, dtype=complex)
    M = np.empty(z.shape + (2, 2), dtype=complex)
    M[..., 0, 0], M[..., 0, 1] = 1, -z
    M[..., 1, 0], M[..., 1, 1] = -np.conj(z), 1
    return M


def _frame(p, q):
    """The isometry taking p to 0 and q onto the positive real axis."""
    A = _to_origin(p)
    w = _apply(A, q)
    rot = np.exp(-1j * np.angle(w))
    R = np.zeros(np.shape(rot) + (2, 2), dtype=complex)
    R[..., 0, 0], R[..., 1, 1] = rot, 1
    return R @ A


def _klein(z):
    return 2 * z / (1 + np.abs(z) ** 2)


def _poincare(k):
    return k / (1 + np.sqrt(np.maximum(1 - np.abs(k) ** 2, 0)))


def _centred(p, z):
    """T_p(z) = (z - p) / (1 - conj(p) z), the points z in the chart centring p (the core's
    hyperbolic::centred: the denominator as (1 - |p|^2) - conj(p) (z - p), which keeps its digits
    near |z| = 1)."""
    d = z - p
    r = np.abs(p)
    return d / ((1 - r) * (1 + r) - np.conj(p) * d)


def _hyperboloid_barycentric(Z, q):
    """Barycentrics (n, 3) of the points q (n,) in the geodesic triangles Z (n, 3) (Poincare disk):
    q proportional to sum_k l_k X_k with X_k the corners on the hyperboloid, the barycentrics of the
    hyperbolic triangle the core uses (geometry/hyperbolic.h triangle_barycentric). Unlike Klein
    barycentrics they do not depend on where the triangle is laid out (isometries act linearly on
    the hyperboloid); all are >= 0 exactly when q is in the triangle. Computed in the chart
    centring q: the Klein barycentrics mu of the origin there, l_k proportional to
    mu_k / cosh d(q, c_k). Sum 1 when q is inside (or the weights' sum is positive); else divided
    by the sum of their absolute values, so that the signs still say which sides q lies beyond."""
    w = _centred(np.asarray(q)[:, None], np.asarray(Z))
    n = np.abs(w) ** 2
    k = 2 * w / (1 + n)
    inv_cosh = (1 - n) / (1 + n)
    cross = np.stack([(np.conj(k[:, (i + 1) % 3]) * k[:, (i + 2) % 3]).imag for i in range(3)], axis=1)
    area = cross.sum(axis=1)
    area = np.where(np.abs(area) > 0, area, 1e-300)
    lam = cross / area[:, None] * inv_cosh
    total = lam.sum(axis=1)
    den = np.where(total > 0, total, np.abs(lam).sum(axis=1))
    return lam / np.maximum(den, 1e-300)[:, None]


def _hyperboloid_point(Z, bary):
    """The points (n,) of the geodesic triangles Z (n, 3) with hyperboloid barycentrics bary (n, 3)
    (the inverse of _hyperboloid_barycentric), computed in the chart centring each first corner."""
    Z = np.asarray(Z)
    c0 = Z[:, 0]
    w = _centred(c0[:, None], Z)
    n = np.abs(w) ** 2
    x0 = (1 + n) / (1 - n)
    xs = 2 * w / (1 - n)
    X0 = np.einsum("ij,ij->i", bary, x0)
    Xs = np.einsum("ij,ij->i", bary, xs)
    norm = np.sqrt(np.maximum((X0 - np.abs(Xs)) * (X0 + np.abs(Xs)), 1e-300))
    p = Xs / (norm + X0)
    return (p + c0) / (1 + np.conj(c0) * p)


def symmetric_metric(double, ricci_tolerance=1e-12):
    """The double's hyperbolic metric on its own edges (`_core.ricci_flow`), each edge's length
    averaged with its mirror's: (sorted edge keys a * n + b with a < b, lengths, the largest
    relative difference averaged out, the scheme in words). Shared by both orientations' layouts. The vertex-scaling
    scheme first; where it leaves a face degenerate (a triangle inequality violated: the metric
    needs other edges), the inversive-distance one, another discrete conformal metric on the same
    edges (the torus_1 bench shape's double, its faces at the boundary split: vertex scaling
    leaves 2 degenerate faces, inversive distance converges; docs/history/open_surfaces.md "Session 23")."""
    D = double
    why = []
    for scheme in ("yamabe", "inversive"):
        r = _core.ricci_flow(D["V"], D["F"], background="hyperbolic", scheme=scheme, tolerance=ricci_tolerance)
        if r["converged"]:
            break
        why.append(f"{'vertex scaling' if scheme == 'yamabe' else 'inversive distance'}: {r['message']}")
    else:
        raise ReflectionSolveError("the double's hyperbolic metric on its own edges: " + "; ".join(why))
    ev = np.asarray(r["edge_vertices"], dtype=np.int64)
    L = np.asarray(r["edge_lengths"], dtype=np.float64)
    n = len(D["V"])
    key = np.minimum(ev[:, 0], ev[:, 1]) * n + np.maximum(ev[:, 0], ev[:, 1])
    order = np.argsort(key)
    key, L = key[order], L[order]
    sig = D["sigma"]
    ms = np.minimum(sig[ev[order, 0]], sig[ev[order, 1]]) * n + np.maximum(sig[ev[order, 0]], sig[ev[order, 1]])
    Lm = L[np.searchsorted(key, ms)]
    return key, 0.5 * (L + Lm), float(np.max(np.abs(L - Lm) / L)), (
        "vertex scaling" if scheme == "yamabe" else "inversive distance (" + why[0] + ")")


class HalfLayout:
    """The target half in the Poincare disk: the double's hyperbolic metric made exactly symmetric,
    the half's faces laid out along a breadth-first tree of faces from the face deepest inside.

    F: (m, 3) the half's faces as mapped (orientation reversing: the corners reversed); double: the
    double_surface dict of the half. Attributes: pos (m, 3) complex corner positions of each face,
    neighbour (m, 3) the face across the edge opposite corner k (-1: boundary), transition
    (m, 3, 2, 2) the isometry taking the neighbour's placement to the one adjacent to this face
    across that edge (identity along the tree), metric_scheme (symmetric_metric's, in words),
    metric_error (the largest relative difference of an
    edge's length and its mirror's before averaging)."""

    def __init__(self, F, double, metric=None):
        F = np.asarray(F, dtype=np.int64)
        D = double
        key, L, self.metric_error, self.metric_scheme = symmetric_metric(D) if metric is None else metric
        n = len(D["V"])

        def length(a, b):
            return L[np.searchsorted(key, np.minimum(a, b) * n + np.maximum(a, b))]

        m = len(F)
        # lengths[f, k]: the edge opposite corner k.
        lengths = np.stack([length(F[:, (k + 1) % 3], F[:, (k + 2) % 3]) for k in range(3)], axis=1)
        self.F, self.lengths = F, lengths
        edge_face = {}
        for f, tri in enumerate(F):
            for k in range(3):
                edge_face[(int(tri[(k + 1) % 3]), int(tri[(k + 2) % 3]))] = (f, k)
        neighbour = -np.ones((m, 3), dtype=np.int64)
        across = -np.ones((m, 3), dtype=np.int64)  # the corner of the neighbour opposite the shared edge
        for f, tri in enumerate(F):
            for k in range(3):
                g = edge_face.get((int(tri[(k + 2) % 3]), int(tri[(k + 1) % 3])))
                if g is not None:
                    neighbour[f, k], across[f, k] = g
        self.neighbour, self.across = neighbour, across
        # Root: the face farthest (in faces) from the boundary.
        depth = np.full(m, -1, dtype=np.int64)
        queue = deque(np.flatnonzero((neighbour < 0).any(axis=1)).tolist())
        depth[list(queue)] = 0
        while queue:
            f = queue.popleft()
            for g in neighbour[f]:
                if g >= 0 and depth[g] < 0:
                    depth[g] = depth[f] + 1
                    queue.append(g)
        root = int(np.argmax(depth))
        pos = np.zeros((m, 3), dtype=complex)
        a, b, c = lengths[root]  # opposite corners 0, 1, 2
        pos[root, 1] = np.tanh(c / 2)
        pos[root, 2] = np.tanh(b / 2) * np.exp(1j * self._angle(b, c, a))
        placed = np.zeros(m, dtype=bool)
        placed[root] = True
        tree = np.zeros((m, 3), dtype=bool)
        queue = deque([root])
        while queue:
            f = queue.popleft()
            for k in range(3):
                g = neighbour[f, k]
                if g < 0 or placed[g]:
                    continue
                kg = across[f, k]
                # The shared edge runs (k+1) -> (k+2) in f, (kg+1) -> (kg+2) in g reversed.
                p, q = pos[f, (k + 2) % 3], pos[f, (k + 1) % 3]  # g's corners kg+1, kg+2
                pos[g, (kg + 1) % 3], pos[g, (kg + 2) % 3] = p, q
                pos[g, kg] = self._third(p, q, lengths[g, (kg + 2) % 3], lengths[g, (kg + 1) % 3], lengths[g, kg])
                placed[g] = True
                tree[f, k] = tree[g, kg] = True
                queue.append(g)
        if not placed.all():
            raise ReflectionSolveError("the target half's faces are not connected")
        self.pos, self.root, self.tree = pos, root, tree
        # Transitions across the tree's complement: g's placement onto the one adjacent to f.
        transition = np.zeros((m, 3, 2, 2), dtype=complex)
        transition[..., 0, 0] = transition[..., 1, 1] = 1
        f_idx, k_idx = np.nonzero((neighbour >= 0) & ~tree)
        g_idx, kg_idx = neighbour[f_idx, k_idx], across[f_idx, k_idx]
        pf, qf = pos[f_idx, (k_idx + 2) % 3], pos[f_idx, (k_idx + 1) % 3]
        pg, qg = pos[g_idx, (kg_idx + 1) % 3], pos[g_idx, (kg_idx + 2) % 3]
        transition[f_idx, k_idx] = _normalized(_inv(_frame(pf, qf)) @ _frame(pg, qg))
        self.transition = transition
        self.klein = _klein(pos)

    @staticmethod
    def _angle(b, c, a):
        """The angle between sides b and c of a hyperbolic triangle with opposite side a."""
        cos = (np.cosh(b) * np.cosh(c) - np.cosh(a)) / (np.sinh(b) * np.sinh(c))
        return np.arccos(np.clip(cos, -1, 1))

    def _third(self, p, q, lp, lq, lpq):
        """The point at distance lp from p and lq from q, left of p -> q."""
        M = _frame(p, q)
        ang = self._angle(lp, lpq, lq)
        w = np.tanh(lp / 2) * np.exp(1j * ang)
        return _apply(_inv(M), w)

    def point(self, face, bary):
        """Points given by (hyperboloid) barycentrics on laid-out faces."""
        return _hyperboloid_point(self.pos[face], bary)

    def path_element(self, start, goal, max_faces=20000):
        """The element carrying `start`'s placement to the lift adjacent to `goal`'s along the
        shortest path of faces between them (breadth first)."""
        if start == goal:
            return np.eye(2, dtype=complex)
        prev = {start: (-1, -1)}
        queue = deque([start])
        while queue:
            f = queue.popleft()
            if f == goal:
                break
            for k in range(3):
                g = int(self.neighbour[f, k])
                if g >= 0 and g not in prev:
                    prev[g] = (f, k)
                    queue.append(g)
            if len(prev) > max_faces:
                raise ReflectionSolveError("a source edge's image spans too many target faces")
        if goal not in prev:
            raise ReflectionSolveError("a source edge's ends lie on unconnected target faces")
        # rho = A(f_{k-1} -> f_k) ... A(f_0 -> f_1) along start = f_0, ..., f_k = goal, where
        # A(f -> g) = transition[g, corner opposite the shared edge] takes f's placement onto the
        # lift adjacent to g (the identity along the tree).
        path = []
        g = goal
        while g != start:
            f, k = prev[g]
            path.append((f, k))
            g = f
        M = np.eye(2, dtype=complex)
        for f, k in path[::-1]:
            g, kg = int(self.neighbour[f, k]), int(self.across[f, k])
            M = self.transition[g, kg] @ M
        return _normalized(M)


def _own_edges(F):
    """The mesh's undirected edges (k, 2), smaller vertex first, sorted."""
    a = np.concatenate([F[:, (k + 1) % 3] for k in range(3)])
    b = np.concatenate([F[:, (k + 2) % 3] for k in range(3)])
    return np.unique(np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1), axis=0)


def _cotangent_weights(V, F, edges):
    """Each own edge's cotangent weight (the two faces' halves; a boundary edge has one: the
    double's weight is twice it)."""
    P = V[F]
    cot = np.empty((len(F), 3))
    for k in range(3):
        u = P[:, (k + 1) % 3] - P[:, k]
        v = P[:, (k + 2) % 3] - P[:, k]
        cot[:, k] = np.einsum("ij,ij->i", u, v) / np.maximum(np.linalg.norm(np.cross(u, v), axis=1), 1e-300)
    a = np.concatenate([F[:, (k + 1) % 3] for k in range(3)])
    b = np.concatenate([F[:, (k + 2) % 3] for k in range(3)])
    key = np.minimum(a, b) * len(V) + np.maximum(a, b)
    w = np.zeros(len(edges))
    np.add.at(w, np.searchsorted(edges[:, 0] * len(V) + edges[:, 1], key), 0.5 * cot.T.ravel())
    return w


def _floored(w, floor):
    """Each weight at least `floor` times the mean positive one (the closed pipeline's own-edge
    weights, SolveOptions::own_weights_floor: positive weights keep the energy convex)."""
    positive = w[w > 0]
    return np.maximum(w, floor * (positive.mean() if len(positive) else 1.0))


def _energy_edges(S, edges, rho, rho_inv, geodesic_of, weights, weight_floor):
    """The terms of the half's energy: (edges (k, 2), w (k,), rho (k, 2, 2), direct (k,): the edge
    is one of the mesh's own, pulls (vertices, weights, geodesics (p, 2, 2)) or None, note).

    weights 'delaunay': the doubles' own weights. The intrinsic Delaunay triangulation of S's double
    (the core's intrinsic_delaunay; 3D lengths of the half on both sheets, so both are the same
    metric) is symmetric, so each of its edges lies in one half, or crosses the boundary from a
    vertex v to its own mirror image (a boundary edge flipped: the angles opposite it obtuse).
    The half's energy is half the doubles' energy of the symmetric map: the half's edges (each
    element the product of its path's own edges' elements), a boundary edge at half its weight,
    and per crossing edge of weight w a pull 2 w dist(z_v, boundary geodesic)^2 (w d(z_v,
    sigma z_v)^2 / 2; the geodesic's lift is the one the path's first boundary vertex slides on:
    geodesic_of, (n, 2, 2), carried by the path's element). Weights within the flip tolerance
    below 0 are 0.
    weights 'own': the half's own cotangents, with `weight_floor` each at least that times the
    mean positive one (None: as they are, refused when one is negative)."""
    n = S.n2
    if weights == "own":
        w = _cotangent_weights(S.V2, S.F2, edges)
        if weight_floor is not None:
            w = _floored(w, weight_floor)
        elif np.any(w < 0):
            raise ReflectionSolveError(f"{int(np.sum(w < 0))} negative cotangent weights (the core's solve needs "
                                       "w >= 0: a weight floor)")
        return edges, w, rho, np.ones(len(edges), dtype=bool), None, (
            "own cotangents" + (f" floored at {weight_floor}" if weight_floor is not None else ""))
    if weights != "delaunay":
        raise ValueError(f"weights must be 'delaunay' or 'own', not {weights!r}")
    D = S.D
    sigma = D["sigma"]
    half_of = np.where(np.arange(len(D["V"])) < n, np.arange(len(D["V"])), sigma)
    idt = _core.intrinsic_delaunay(S.V2[half_of], D["F"])
    off, pv = np.asarray(idt["path_offsets"]), np.asarray(idt["path_vertices"])
    eindex = {(int(a), int(b)): k for k, (a, b) in enumerate(edges)}
    on_b = S.loop_of_vertex() >= 0

    def element(path):
        M = np.eye(2, dtype=complex)
        for a, b in zip(path[:-1], path[1:]):
            k = eindex[(min(a, b), max(a, b))]
            M = M @ (rho[k] if a < b else rho_inv[k])
        return _normalized(M)

    def same_geodesic(G, H):
        """Whether the geodesics G(real diameter), H(real diameter) are one (either direction)."""
        g, h = _apply(G, np.array([-1.0, 1.0])), _apply(H, np.array([-1.0, 1.0]))
        return min(np.abs(g - h).max(), np.abs(g - h[::-1]).max()) < 1e-8

    raw = np.asarray(idt["weights"], dtype=np.float64)
    tie = 1e-12 * max(float(np.abs(raw).max(initial=0.0)), 1e-300)
    # Per vertex of the double: +1 on the half's interior, -1 on the mirror's, 0 on the boundary.
    sheet = np.where(np.arange(len(D["V"])) < n, 1, -1)
    sheet[:n][on_b] = 0
    out_e, out_w, out_rho, direct, seen = [], [], [], [], set()
    pull_v, pull_w, pull_g = [], [], []
    ties, folded = 0, 0
    for e, (i, j) in enumerate(np.asarray(idt["edges"])):
        path = pv[off[e]:off[e + 1]]
        we = max(float(raw[e]), 0.0)
        if i != j and sigma[i] == j:
            # Across the boundary from v to its mirror image: the pull on v.
            if i >= n:
                path = path[::-1]
            b = next((k for k, x in enumerate(path) if x < n and on_b[x]), None)
            if b is None or np.any(path[:b + 1] >= n):
                if abs(raw[e]) <= tie:
                    ties += 1
                    continue
                raise ReflectionSolveError("an intrinsic edge crosses the boundary off the half's vertices")
            if we > 0:
                pull_v.append(int(path[0]))
                pull_w.append(2 * we)
                pull_g.append(element(path[:b + 1]) @ geodesic_of[path[b]])
            continue
        # The path of the double's own edges folded onto the half (its mirror stretches reflected:
        # the symmetric map's images of a mirror stretch are the reflections of its twin's).
        # Where it goes from one sheet to the other at a boundary vertex, the true end's lift is the
        # folded one reflected in that vertex's boundary geodesic; all those crossings on one
        # geodesic lift, an even number of them cancel, and an odd number leaves the end unmoved
        # when the end lies on that geodesic (a boundary vertex). Otherwise (an edge from a vertex
        # to another's mirror image: a reflection, which the half's Moebius elements cannot
        # express) only a tie is left out: a diagonal of a cocircular quad, weight 0 (to round-off),
        # which the two sheets may break differently.
        sides = sheet[path]
        nz = np.flatnonzero(sides != 0)
        fp = half_of[path]
        crossings = [int(k) for a_, b_ in zip(nz[:-1], nz[1:]) if sides[a_] != sides[b_]
                     for k in [next(x for x in range(a_ + 1, b_) if sides[x] == 0)]]
        if len(nz) and sides[nz[0]] < 0 and not crossings:
            continue  # on the mirror sheet (and the boundary): its twin on the half is kept
        if crossings:
            # (Relative to the sheet it starts on: the whole path reflected onto the half first,
            # which moves no distance, a boundary start staying where it is.)
            G = [element(fp[:k + 1]) @ geodesic_of[fp[k]] for k in crossings]
            ok = all(same_geodesic(G[0], H) for H in G[1:])
            if ok and len(crossings) % 2 == 1:
                # The end reflected: unmoved only on the geodesic itself.
                ok = sides[-1] == 0 and same_geodesic(G[0], element(fp) @ geodesic_of[fp[-1]])
            if not ok:
                if abs(raw[e]) <= tie:
                    ties += 1
                    continue
                raise ReflectionSolveError("an intrinsic edge of the double crosses the boundary between two vertices")
            folded += 1
        key = tuple(int(x) for x in fp)
        if key in seen:
            continue  # the twin of an edge kept (or of one along the boundary)
        seen.add(key)
        along_boundary = not len(nz)  # every vertex of its path on the boundary: its own twin
        out_e.append((int(fp[0]), int(fp[-1])))
        out_w.append(we * (0.5 if along_boundary else 1.0))
        out_rho.append(element(fp))
        direct.append(len(path) == 2)
    pulls = (np.array(pull_v, dtype=np.int64), np.array(pull_w), np.array(pull_g)) if pull_v else None
    return (np.array(out_e, dtype=np.int64), np.array(out_w), np.array(out_rho), np.array(direct), pulls,
            f"intrinsic Delaunay ({idt['flips']} flips, {len(pull_v)} boundary edges flipped: pulls"
            + (f", {folded} paths folded onto the half" if folded else "")
            + (f", {ties} tied diagonals across the boundary left out" if ties else "") + ")")


class RefinedHalf:
    """A side's split half (open_double._Side) with its faces touching the boundary split, for the
    half's solve: on the target (split_boundary) into four, the boundary edges halved too (their
    midpoints new boundary vertices, on the 3D polyline of the loop); on the source the interior
    edges of those faces only, the boundary vertices kept (refine_near_boundary with one ring).
    Why: the half's boundary strip is one face wide, so a source face with two corners on the
    boundary had one free corner to follow the target's boundary geodesic with, and the target's
    boundary faces, the largest in its metric next to a small hole, carried the change of scale
    from the metric to 3D over one face (docs/history/open_surfaces.md "Session 23").

    The attributes solve_half and open_double._reflected_correspondence read: the input mesh's
    (V, F, loops, n, ...), the refined half's V2, F2, D (its double), n2, half_loops (the loops
    through the new boundary vertices), parent / corner_in_parent (each face's input face and
    corners there), refined_from (the edge of the side's split half each new vertex halves),
    within / corners (each face's face of the side's split half and its corners there). rings
    (default 1): refine_near_boundary's (0: nothing split, the side's split half as it is, for a
    pair of which only the target is refined)."""

    def __init__(self, side, split_boundary, rings=1):
        from .open_double import double_surface, refine_near_boundary  # (open_double imports this module)
        self.base = side
        for k in ("name", "V", "F", "genus", "loops", "b", "describe", "n", "diag"):
            setattr(self, k, getattr(side, k))
        self.V2, self.F2, self.within, self.corners, ends = refine_near_boundary(
            side.V2, side.F2, side.half_loops, rings, split_boundary=split_boundary)
        self.parent = side.parent[self.within]
        self.corner_in_parent = np.einsum("fkl,flj->fkj", self.corners, side.corner_in_parent[self.within])
        self.refined_from = ends
        mid = {(int(min(a, b)), int(max(a, b))): side.n2 + k for k, (a, b) in enumerate(ends)}
        loops = []
        for loop in side.half_loops:
            out = []
            for u, w in zip(loop, np.roll(loop, -1)):
                out.append(int(u))
                m = mid.get((int(min(u, w)), int(max(u, w))))
                if m is not None:
                    out.append(m)
            loops.append(np.array(out, dtype=np.int64))
        self.half_loops = loops
        self.n2 = len(self.V2)
        self.D = double_surface(self.V2, self.F2, loops)
        # Per face of the side's split half its (up to four) faces here.
        order = np.argsort(self.within, kind="stable")
        count = np.bincount(self.within, minlength=len(side.F2))
        first = np.concatenate([[0], np.cumsum(count)[:-1]])
        self.children = -np.ones((len(side.F2), 4), dtype=np.int64)
        for c in range(4):
            has = count > c
            self.children[has, c] = order[first[has] + c]

    def to_input_faces(self, face2, bary2):
        """Points on the refined half (face of F2, barycentrics) on the input faces."""
        bary = np.einsum("ik,ikj->ij", bary2, self.corner_in_parent[face2])
        return self.parent[face2], bary

    def half_points(self, face, bary):
        """Points on the double (face, barycentrics) reflected onto the half; also whether each was
        on the mirror sheet."""
        face = np.asarray(face, dtype=np.int64).copy()
        bary = np.asarray(bary, dtype=np.float64).copy()
        m = face >= self.D["half_faces"]
        face[m] -= self.D["half_faces"]
        bary[m] = bary[m][:, ::-1]
        return face, bary, m

    def snap_to_loops(self, P, loop_of_point):
        """The side's (open_double._Side.snap_to_loops: on the input mesh's loops)."""
        return self.base.snap_to_loops(P, loop_of_point)

    def loop_of_vertex(self):
        """Per vertex of the refined half the loop it lies on (-1: interior)."""
        lo = -np.ones(self.n2, dtype=np.int64)
        for i, loop in enumerate(self.half_loops):
            lo[loop] = i
        return lo

    def from_base(self, face, bary):
        """Points on the side's split half (face of its F2, barycentrics) as points of the refined
        half: the piece holding each (largest smallest barycentric), its barycentrics there."""
        face = np.asarray(face, dtype=np.int64)
        bary = np.asarray(bary, dtype=np.float64)
        best = np.full(len(face), -np.inf)
        out_f = self.children[face, 0].copy()
        out_b = np.zeros((len(face), 3))
        for c in range(4):
            child = self.children[face, c]
            ok = child >= 0
            if not np.any(ok):
                continue
            # point = sum_k beta_k corners[child, k]: beta = bary corners^-1.
            C = self.corners[child[ok]]
            # (the inverse by its adjugate: np.linalg.inv of a stack of 3 x 3 matrices costs seconds
            # under load, in threads)
            adj = np.stack([np.cross(C[:, 1], C[:, 2]), np.cross(C[:, 2], C[:, 0]), np.cross(C[:, 0], C[:, 1])], axis=2)
            det = np.einsum("ij,ij->i", C[:, 0], adj[:, :, 0])
            beta = np.einsum("ij,ijk->ik", bary[ok], adj) / det[:, None]
            low = beta.min(axis=1)
            idx = np.flatnonzero(ok)
            better = low > best[idx]
            best[idx[better]] = low[better]
            out_f[idx[better]] = child[ok][better]
            out_b[idx[better]] = beta[better]
        out_b = np.maximum(out_b, 0)
        return out_f, out_b / out_b.sum(axis=1, keepdims=True)


def refined_forward(S_r, T_r, forward):
    """The doubles' map's forward points ('face', 'barycentric' on the unrefined target's double per
    vertex of the unrefined source's double) as a start for the refined halves (RefinedHalf):
    per vertex of S_r's half a point of T_r's half. A new source vertex takes the image of an end of
    the edge it halves, one not on the boundary (the chords were split first, so one is not)."""
    S, T = S_r.base, T_r.base
    n = S.n2
    face, bary, _ = T.half_points(np.asarray(forward["face"])[:n], np.asarray(forward["barycentric"])[:n])
    f0, b0 = T_r.from_base(face, bary)
    out_f = np.empty(S_r.n2, dtype=np.int64)
    out_b = np.empty((S_r.n2, 3))
    out_f[:n], out_b[:n] = f0, b0
    on_b = S_r.loop_of_vertex() >= 0
    for k, (a, b) in enumerate(S_r.refined_from):  # in order: an end may be an earlier new vertex
        src = b if on_b[a] else a
        out_f[n + k], out_b[n + k] = out_f[src], out_b[src]
    return {"face": out_f, "barycentric": out_b}


def _as_core(M):
    """(..., 2, 2) disk isometries (normalised: +-SU(1,1)) as the core's rows [a.re, a.im, b.re, b.im]."""
    M = _normalized(np.asarray(M, dtype=complex))
    a, b = M[..., 0, 0], M[..., 0, 1]
    return np.stack([a.real, a.imag, b.real, b.imag], axis=-1)


def solve_half(S, T, forward, pairing, reversing, layout=None, tolerance=1e-10, max_iterations=60,
               weights="delaunay", weight_floor=None):
    """The reflection-aware harmonic map of the doubles of S onto T (open_double._Side, unrefined or
    refined alike), in the class of `forward` (the doubles' map's forward points: 'face',
    'barycentric' on T's double per vertex of S's double), source loop i onto target loop
    pairing[i]; reversing: the half onto the target's mirror half. layout: a HalfLayout of T's
    half for this orientation (built when None). weights: 'delaunay' (default) the half's intrinsic
    Delaunay weights with its boundary kept (_energy_edges: the doubles' own weights, so the energy
    is half the symmetric doubles' map's); 'own' the source's own cotangents (session 20's), with
    weight_floor each at least that times the mean positive one (0.1: convex; None: as they are,
    refused when one is negative).

    The solve is the core's (`_core.hyperbolic_harmonic_map`, map/hyperbolic_harmonic.h with
    BoundarySlideOptions): every boundary vertex slides along the geodesic through the paired
    target loop's edge nearest its start image (one unknown, its arc length; on the geodesic to
    round-off), consecutive boundary vertices keep their order along it.

    Returns a dict: 'forward' (face, barycentric on T's split half faces F2, per vertex of S's
    split half), 'inverse' (face, barycentric on S's F2 per vertex of T's split half), 'energy'
    (the half's: the symmetric doubles' map's is twice it), 'converged', 'iterations',
    'gradient' (the largest vertex gradient at the end over the largest weight),
    'boundary_off_geodesic' (largest hyperbolic distance of a boundary image from its geodesic),
    'order_rejections' (line-search trials shortened to keep the boundary's order), 'weights'
    (which, in words), 'intrinsic_flipped' (source faces whose image turns over in the metric),
    'inverse_unlocated' (target vertices found in no source face's image, given the nearest),
    'metric_error', 'metric_scheme', 'layout'. Raises ReflectionSolveError when the solve cannot be set up or a
    point cannot be located."""
    if layout is None:
        layout = HalfLayout(T.F2[:, ::-1] if reversing else T.F2, T.D)
    n = S.n2
    face2, bary2, _ = T.half_points(np.asarray(forward["face"])[:n], np.asarray(forward["barycentric"])[:n])
    if reversing:
        bary2 = bary2[:, ::-1]
    home = face2.copy()
    z = layout.point(face2, bary2)
    # Boundary vertices: on the geodesic through the paired target loop's edge nearest to their
    # start image (3D), parametrised by arc length s along it: z = M_b(tanh(s / 2)). (T's
    # half_loops: a RefinedHalf's loops run through its new boundary vertices.)
    s_loop = S.loop_of_vertex()
    bnd = np.flatnonzero(s_loop >= 0)
    Fl = layout.F
    start_xyz = np.einsum("ij,ijk->ik", bary2, T.V2[Fl[face2]])
    edge_of = {}
    for f in range(len(Fl)):
        for k in range(3):
            if layout.neighbour[f, k] < 0:
                edge_of[(int(Fl[f, (k + 1) % 3]), int(Fl[f, (k + 2) % 3]))] = (f, k)
    Mb = np.zeros((len(bnd), 2, 2), dtype=complex)
    s = np.zeros(len(bnd))
    for idx, v in enumerate(bnd):
        loop = T.half_loops[pairing[s_loop[v]]]
        A, B = T.V2[loop], T.V2[np.roll(loop, -1)]
        d = B - A
        t = np.clip(np.einsum("ij,ij->i", start_xyz[v] - A, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
        j = int(np.argmin(np.linalg.norm(A + t[:, None] * d - start_xyz[v], axis=1)))
        u, w = int(loop[j]), int(loop[(j + 1) % len(loop)])
        f, k = edge_of[(u, w)] if (u, w) in edge_of else edge_of[(w, u)]
        pu = layout.pos[f, list(Fl[f]).index(u)]
        pw = layout.pos[f, list(Fl[f]).index(w)]
        Mb[idx] = _normalized(_inv(_frame(pu, pw)))
        # The point with hyperboloid barycentrics (1 - t, t) on the edge, of length L, as arc length.
        L = 2 * np.arctanh(np.abs(_apply(_frame(pu, pw), pw)))
        s[idx] = np.arctanh(t[j] * np.sinh(L) / ((1 - t[j]) + t[j] * np.cosh(L)))
        home[v] = f
    # The mesh's own edges and their elements: start's placement (the j end's home face) onto the
    # lift next to i's (for the energy's edges below and for the way back to the meshes).
    edges = _own_edges(S.F2)
    cache = {}
    rho = np.empty((len(edges), 2, 2), dtype=complex)
    for e, (i, j) in enumerate(edges):
        key = (int(home[j]), int(home[i]))
        if key not in cache:
            cache[key] = layout.path_element(*key)
        rho[e] = cache[key]
    rho_inv = _inv(rho)
    geodesic_of = np.tile(np.eye(2, dtype=complex), (n, 1, 1))
    geodesic_of[bnd] = Mb
    energy_edges, w, energy_rho, direct, pulls, weights_note = _energy_edges(S, edges, rho, rho_inv, geodesic_of,
                                                                             weights, weight_floor)
    # Consecutive boundary vertices keep their order along the geodesic (the core's order check).
    eindex = {(int(i), int(j)): k for k, (i, j) in enumerate(energy_edges) if direct[k]}
    eindex.update({(j, i): k for (i, j), k in list(eindex.items())})
    ordered = [eindex[(int(u), int(v))] for loop in S.half_loops for u, v in zip(loop, np.roll(loop, -1))
               if (int(u), int(v)) in eindex]
    slides = np.zeros(n, dtype=bool)
    slides[bnd] = True
    geodesics = np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (n, 1))
    geodesics[bnd] = _as_core(Mb)
    z0 = z.copy()
    z0[bnd] = _apply(Mb, np.tanh(s / 2))
    res = _core.hyperbolic_harmonic_map(energy_edges, w, _as_core(energy_rho), z0, slides=slides,
                                        geodesics=geodesics, ordered_edges=np.array(ordered, dtype=np.int64),
                                        pulls=None if pulls is None else (pulls[0], pulls[1], _as_core(pulls[2])),
                                        tolerance=tolerance, max_iterations=max_iterations)
    z = np.asarray(res["z"])
    converged = bool(res["converged"])
    gnorm = float(res["gradient_history"][-1]) / max(float(np.max(w)), 1e-300)
    back = _maps_back(S, T, layout, z, home, bnd, edges, rho, rho_inv, reversing, inverse=converged)
    back.update(energy=float(res["energy"]), energy_history=list(res["energy_history"]),
                gradient_history=list(res["gradient_history"]), converged=converged, iterations=int(res["iterations"]),
                gradient=gnorm, boundary_off_geodesic=float(res["slide_off_geodesic"]),
                order_rejections=int(res["order_rejections"]), metric_error=layout.metric_error,
                metric_scheme=layout.metric_scheme,
                weights=weights_note, weight_floor=weight_floor, layout=layout)
    return back


def _maps_back(S, T, layout, z, home, bnd, edges, rho, rho_inv, reversing, inverse=True, max_walks=0.1):
    """solve_half's points z (per vertex of S's split half, in the layout's disk, vertex i near its
    home face) back on the meshes: 'forward' (face of T.F2, barycentrics), 'inverse' (face of S.F2,
    barycentrics per vertex of T's split half), 'intrinsic_flipped' (source faces whose image turns
    over in the metric), 'escaped' (interior images located beyond the boundary),
    'inverse_unlocated' (target vertices in no source face's image). The inverse is computed only
    when `inverse` and the forward map is bijective in the metric (else every target vertex is
    unlocated: the map is refused anyway), and the walks only for at most `max_walks` of the target's
    vertices (more left unlocated mean a tangled image: a candidate of another class, whose walks
    would cost minutes)."""
    n = S.n2
    # Orientation of each source face's image in the metric (Klein: straight sides).
    eindex = {(int(a), int(b)): k for k, (a, b) in enumerate(edges)}

    def element(a, b):
        """Per pair of vertex arrays the element taking b's lift next to a's."""
        out = np.empty((len(a), 2, 2), dtype=complex)
        for k, (x, y) in enumerate(zip(a, b)):
            out[k] = rho[eindex[(x, y)]] if x < y else rho_inv[eindex[(y, x)]]
        return out

    Fs = S.F2
    r_ab, r_ac = element(Fs[:, 0], Fs[:, 1]), element(Fs[:, 0], Fs[:, 2])
    tri = np.stack([z[Fs[:, 0]], _apply(r_ab, z[Fs[:, 1]]), _apply(r_ac, z[Fs[:, 2]])], axis=1)
    kt = _klein(tri)
    orient = ((kt[:, 1] - kt[:, 0]) * np.conj(kt[:, 2] - kt[:, 0])).imag
    intrinsic_flipped = int(np.sum(orient >= 0))  # Im((b - a) conj(c - a)) < 0: counterclockwise
    # Forward: each source vertex located on the laid-out half.
    f_out, b_out, W, outside = _locate_all(layout, z, home)
    on_b = np.zeros(n, dtype=bool)
    on_b[bnd] = True
    escaped = int(np.sum(outside & ~on_b))
    b_out = np.maximum(b_out, 0)
    b_out /= b_out.sum(axis=1, keepdims=True)
    if not inverse or intrinsic_flipped or escaped:
        return {"forward": {"face": f_out, "barycentric": b_out[:, ::-1] if reversing else b_out},
                "inverse": {"face": np.zeros(T.n2, dtype=np.int64), "barycentric": np.full((T.n2, 3), 1 / 3)},
                "intrinsic_flipped": intrinsic_flipped, "escaped": escaped,
                "inverse_unlocated": np.arange(T.n2)}
    # Inverse: every placed corner of the target half in the source faces' images, each image
    # brought next to the laid-out face of each of its corners in turn.
    versions = [
        (np.einsum("fij,fjk->fik", W[Fs[:, 0]], np.broadcast_to(np.eye(2), r_ab.shape)), 0),
        (W[Fs[:, 1]] @ _inv(r_ab), 1),
        (W[Fs[:, 2]] @ _inv(r_ac), 2)]
    # An image straddling a cut edge of the layout next to that corner's face: also the copy beyond
    # each of the face's cut edges.
    more = []
    for M, corner in versions:
        loc = f_out[Fs[:, corner]]
        for k in range(3):
            cut = np.flatnonzero(~layout.tree[loc, k] & (layout.neighbour[loc, k] >= 0))
            more.append((_inv(layout.transition[loc[cut], k]) @ M[cut], cut))
    K = np.concatenate([_apply(M[:, None], tri) for M, _ in versions] +
                       [_apply(M[:, None], tri[cut]) for M, cut in more])
    src_face = np.concatenate([np.tile(np.arange(len(Fs)), 3)] + [cut for _, cut in more])
    inv_face, inv_bary, unlocated, unlocated_start = _locate_in_triangles(K, src_face, layout, T.n2)
    if 0 < len(unlocated) <= max_walks * T.n2:
        # A placement in no nearby copy of an image (a long, thin image next to a rim crushed by the
        # map): walk across the source's faces from the nearest candidate's copy, each new corner
        # carried by its edge's element, to the image holding the placement.
        Ms = np.concatenate([M for M, _ in versions] + [M for M, _ in more])
        from .open_double import _face_neighbours  # (open_double imports this module)
        across = np.roll(_face_neighbours(Fs), -1, axis=1)  # column k: across the edge opposite corner k
        still = []
        for v, (t, P) in zip(unlocated, unlocated_start):
            got = _walk_images(P, int(src_face[t]), Ms[t], Fs, across, z, element)
            if got is None:
                still.append(int(v))
            else:
                inv_face[v], inv_bary[v] = got
        unlocated = np.array(still, dtype=np.int64)
    if reversing:
        f_fw, b_fw = f_out, b_out[:, ::-1]
    else:
        f_fw, b_fw = f_out, b_out
    return {"forward": {"face": f_fw, "barycentric": b_fw}, "inverse": {"face": inv_face, "barycentric": inv_bary},
            "intrinsic_flipped": intrinsic_flipped, "escaped": escaped, "inverse_unlocated": unlocated}


def _locate_all(layout, z, face, max_steps=20000):
    """Walks every point z (in the frame of its start face) to the laid-out face holding it:
    (face, barycentrics, W (n, 2, 2) with W z in that face's placement, outside: the walk stopped at
    the boundary)."""
    n = len(z)
    face = face.copy()
    w = z.copy()
    W = np.broadcast_to(np.eye(2, dtype=complex), (n, 2, 2)).copy()
    bary = np.zeros((n, 3))
    outside = np.zeros(n, dtype=bool)
    active = np.arange(n)
    for _ in range(max_steps):
        if len(active) == 0:
            break
        b = _hyperboloid_barycentric(layout.pos[face[active]], w[active])
        bary[active] = b
        k = np.argmin(b, axis=1)
        low = b[np.arange(len(active)), k] < -1e-12
        g = layout.neighbour[face[active], k]
        stop = ~low | (g < 0)
        outside[active[low & (g < 0)]] = True
        mv = active[~stop]
        if len(mv):
            step = _inv(layout.transition[face[mv], k[~stop]])
            w[mv] = _apply(step, w[mv])
            W[mv] = _normalized(step @ W[mv])
            face[mv] = g[~stop]
        active = mv
    else:
        raise ReflectionSolveError("points could not be located on the target half")
    return face, bary, W, outside


#: The coordinates the inverse's candidate triangles are found in (_locate_in_triangles):
#: "poincare" (default; the Poincare disk is conformal, so the nearest centroids of a point are
#: those around it in every direction) or "klein" (session 23's: the Klein model squeezes
#: triangles radially near the rim of the disk, cosh d to one at distance d from the origin).
LOCATE_CHART = "poincare"


def _locate_in_triangles(K, tri_face, layout, n_vertices, k_nearest=48):
    """Per target vertex (of the laid-out faces' corners) the source face and (hyperboloid)
    barycentrics of the geodesic triangle K (t, 3, Poincare disk) holding one of its placed
    positions; those in none get the nearest triangle's clamped barycentrics and are returned with
    that triangle and their placement for solve_half's walk. Candidates: the triangles whose Klein
    centroids are nearest."""
    from scipy.spatial import cKDTree
    F = layout.F
    vert = F.ravel()
    pts = layout.pos.ravel()
    pts_k = layout.klein.ravel()
    if LOCATE_CHART == "klein":
        cen, query = _klein(K).mean(axis=1), pts_k
    else:
        cen, query = _poincare(_klein(K).mean(axis=1)), pts
    tree = cKDTree(np.stack([cen.real, cen.imag], axis=1))
    kq = min(k_nearest, len(K))
    _, cand = tree.query(np.stack([query.real, query.imag], axis=1), k=kq)
    cand = cand.reshape(len(pts), kq)
    best = np.full(len(pts), -np.inf)
    best_t = np.zeros(len(pts), dtype=np.int64)
    best_b = np.zeros((len(pts), 3))
    for c in range(kq):
        t = cand[:, c]
        b = _hyperboloid_barycentric(K[t], pts)
        m = b.min(axis=1)
        better = m > best
        best[better], best_t[better], best_b[better] = m[better], t[better], b[better]
    # Per vertex the placement with the best (largest least) barycentric.
    order = np.lexsort((-best, vert))
    first = np.ones(len(order), dtype=bool)
    first[1:] = vert[order][1:] != vert[order][:-1]
    pick = order[first]
    face = np.zeros(n_vertices, dtype=np.int64)
    bary = np.zeros((n_vertices, 3))
    face[vert[pick]] = tri_face[best_t[pick]]
    b = np.maximum(best_b[pick], 0)
    bary[vert[pick]] = b / b.sum(axis=1, keepdims=True)
    unlocated = np.flatnonzero(best[pick] < -1e-9)
    # Per vertex left: its best candidate triangle and the placement tested in it.
    return face, bary, vert[pick][unlocated], list(zip(best_t[pick][unlocated], pts[pick][unlocated]))


def _walk_images(P, face, M, F, across, z, element, max_steps=5000):
    """The source face (and barycentrics) whose image holds the point P: a straight walk over
    the source's faces' images from `face`'s image carried by M (its first corner's point z[a]
    at M z[a]); each corner's copy is N_v z[v], a new corner d next to a known u taking
    N_u element(u, d). None when the walk leaves the source."""
    N = {int(F[face, 0]): M}
    N[int(F[face, 1])] = M @ element(F[face, :1], F[face, 1:2])[0]
    N[int(F[face, 2])] = M @ element(F[face, :1], F[face, 2:3])[0]
    for _ in range(max_steps):
        tri = F[face]
        X = np.array([_apply(N[int(v)], z[v]) for v in tri])
        b = _hyperboloid_barycentric(X[None], np.array([P]))[0]
        k = int(np.argmin(b))
        if b[k] >= -1e-10:
            b = np.maximum(b, 0)
            return face, b / b.sum()
        g = int(across[face, k])
        if g < 0:
            # Beyond a boundary edge of the source: a target boundary vertex's placement lies on
            # that edge's geodesic up to round-off (a straight line in Klein coordinates; a thin
            # image makes the barycentric large all the same). On the edge: found; beyond one
            # of its ends: on across the edge opposite that end.
            K, Pk = _klein(X), _klein(P)
            e0, e1 = K[(k + 1) % 3], K[(k + 2) % 3]
            off_line = abs(((e1 - e0) * np.conj(Pk - e0)).imag) / max(abs(e1 - e0), 1e-300)
            if off_line > 1e-9:
                return None
            t = ((Pk - e0) * np.conj(e1 - e0)).real / max(abs(e1 - e0) ** 2, 1e-300)
            if 0 <= t <= 1:
                b = _hyperboloid_barycentric(X[None], np.array([_poincare(e0 + t * (e1 - e0))]))[0]
                b[k] = 0
                b = np.maximum(b, 0)
                return face, b / max(b.sum(), 1e-300)
            k = (k + 1) % 3 if t > 1 else (k + 2) % 3  # the corner P lies beyond
            g = int(across[face, k])
            if g < 0:
                return None
        u = int(tri[(k + 1) % 3])
        for d in F[g]:
            if d not in tri:
                N[int(d)] = N[u] @ element(np.array([u]), np.array([d]))[0]
        face = g
    return None
