"""Untangling the half's few folded faces (issue 16; docs/open_surfaces.md, "The half's solve").

Why: the doubles' harmonic map is computed in the target's uniformized metric, where the image of
every source face is positively oriented (`intrinsic_flipped_triangles` 0). The output, though, is
the chord triangle of the three corners' images on the target's own faces. Where the map compresses
strongly (a garment's collar squeezed ~4.5x normal to its loop; on a double torus next to its thin
tube: D' 8-16 on those faces) an image triangle is a sliver whose third corner lies within a few
percent of an edge from the line through the other two, and the piecewise linear change from the
uniformized metric to the target's 3D faces (another affine map per target face: the conformal
factor varies) carries it across that line. Measured on the generated shirt A -> B: the two folded
faces fold the same way on the doubles' raw images (before the half is cut out and its boundary
snapped) and in the target's faces unfolded into a plane; they are folds of the output, not of the
test.

What: each interior corner of a folded face is moved, within a planar chart of the target around its
image (the tangent plane; where the normals turn more than `crease_angle`, the target's faces
unfolded along a breadth-first tree), to the least distorted point (the sum of its star's squared D')
inside the kernel of its star polygon shrunk by 5% of the kernel's depth. The kernel's deepest point
(its Chebyshev centre, a small linear program) starts a Nelder-Mead search; the point is put back on
the target face holding it. A move is kept only if it leaves no face of the star turned by the
pipeline's own test (open_double._turned), keeps the vertex inside the target (at least 1/10 of its
distance to the boundary), so the count can only go down; boundary vertices never move. A pass that
unfolds nothing is undone and retried after relaxing the interior vertices within 1, 2, 3 rings
(each to its own star's least distorted point, kept only where that lowers the distortion), which
widens the folded corners' kernels; the moved vertices and their neighbours are relaxed the same way
at the end. Folds that no vertex alone can clear (a cluster whose corners' kernels are all empty,
because the neighbours' images are folded too) are untangled jointly: the interior vertices within
1, 2, ... PATCH_RINGS rings of the cluster moved together in the target's chart, where an untangling
energy (finite for turned faces, a barrier against turning once none is) is least, the ring around
them held; kept only when nothing in the patch is turned afterwards and every point lands inside the
target. A patch whose held rim admits no unfolded placing (it encloses no positive area, or winds
negatively about a point: _rim_refuses) is refused before the minimization. Folds held by the boundary's images (a face whose rim corners' images cut across a reflex
corner of the other rim, so that no interior position unfolds it) get their boundary corners slid
along the other rim, between their loop neighbours' images, then the joint step again
(_slide_boundary_corners; docs/history/open_surfaces.md "Session 27 (open27)"). Folds the joint step cannot
clear because its positions fall beyond the rim (into the target's hole, next to a boundary edge
whose image chords across a notch of the other rim) get it once more with the boundary vertices
within its rings sliding along the rim as unknowns too and the free ones kept inside the chart's
faces by a penalty (_rim_sliders, _walls; docs/open_surfaces.md "The half's solve"). What
none of these clears is left as it was (its faces stay counted).
"""
import numpy as np


def _closest_on_triangles(p, A, B, C):
    """Closest point to p on each triangle (A[i], B[i], C[i]): (points (k,3), barycentrics (k,3))."""
    def seg(P, Q):
        d = Q - P
        t = np.clip(np.einsum("ij,ij->i", p - P, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
        return P + t[:, None] * d, t
    n = np.cross(B - A, C - A)
    nn = np.maximum(np.einsum("ij,ij->i", n, n), 1e-300)
    # Barycentrics of p's projection onto each plane.
    w = p - A
    bb = np.einsum("ij,ij->i", np.cross(w, C - A), n) / nn
    bc = np.einsum("ij,ij->i", np.cross(B - A, w), n) / nn
    bary = np.stack([1 - bb - bc, bb, bc], axis=1)
    pts = A + bb[:, None] * (B - A) + bc[:, None] * (C - A)
    outside = np.any(bary < 0, axis=1)
    if np.any(outside):
        cands = []
        for (P, Q, i, j) in ((A, B, 0, 1), (B, C, 1, 2), (C, A, 2, 0)):
            q, t = seg(P[outside], Q[outside])
            b = np.zeros((int(outside.sum()), 3))
            b[:, i], b[:, j] = 1 - t, t
            cands.append((q, b))
        dist = np.stack([np.linalg.norm(q - p, axis=1) for q, _ in cands], axis=1)
        best = np.argmin(dist, axis=1)
        rows = np.arange(len(best))
        pts[outside] = np.stack([c[0] for c in cands], axis=1)[rows, best]
        bary[outside] = np.stack([c[1] for c in cands], axis=1)[rows, best]
    return pts, bary


def _tangent_chart(T, tf, origin, normal, held, sign):
    """A chart of the target around smooth ground: the plane through `origin` normal to `normal`
    (y turned by `sign`: an orientation-reversing map's images counter-clockwise too). Returns
    (plane(face, bary, position) -> (k, 2), place(point) -> (face, bary, position) on the nearest of
    the target faces within two rings of `held`)."""
    ex = np.cross(normal, [1.0, 0.0, 0.0])
    if np.linalg.norm(ex) < 0.5:
        ex = np.cross(normal, [0.0, 1.0, 0.0])
    ex /= np.linalg.norm(ex)
    ey = np.cross(normal, ex) * sign
    near = tf.around(held, 2)

    def plane(face, bary, position):
        return np.stack([(position - origin) @ ex, (position - origin) @ ey], axis=-1)

    def place(p):
        Y = origin + p[0] * ex + p[1] * ey
        pts, bary = _closest_on_triangles(Y, T.V[T.F[near, 0]], T.V[T.F[near, 1]], T.V[T.F[near, 2]])
        k = int(np.argmin(np.linalg.norm(pts - Y, axis=1)))
        if _on_boundary_edge(T, near[k], bary[k]):
            return None     # beyond the target's boundary: an interior vertex stays inside
        return near[k], bary[k], pts[k]
    return plane, place


def _on_boundary_edge(T, face, bary):
    """Whether the point (face, bary) of T lies on one of T's boundary edges."""
    if getattr(T, "boundary_edges", None) is None:
        T.boundary_edges = {(int(min(u, w)), int(max(u, w))) for loop in T.loops
                            for u, w in zip(loop, np.roll(loop, -1))}
    tri = T.F[face]
    for k in range(3):
        if bary[k] <= 0 and (int(min(tri[(k + 1) % 3], tri[(k + 2) % 3])),
                             int(max(tri[(k + 1) % 3], tri[(k + 2) % 3]))) in T.boundary_edges:
            return True
    return False


def _unfolded_chart(T, root, held, sign):
    """A chart of the target where its normals turn too much for a plane (a thin tube, a crease):
    its faces unfolded isometrically along a breadth-first tree from `root` to every face of `held`
    (open_double._unfold). place: the first unfolded face (in the tree's order) holding the point,
    else the nearest. None when `held` is too far apart."""
    from .open_double import _face_neighbours, _unfold
    if getattr(T, "face_neighbours", None) is None:
        T.face_neighbours = _face_neighbours(T.F)
    planar = _unfold(T.V, T.F, T.face_neighbours, root, held)
    if planar is None:
        return None
    faces = np.array(list(planar.keys()))
    corners = np.array([planar[int(f)] for f in faces]) * np.array([1.0, sign])

    def plane(face, bary, position):
        return np.einsum("ij,ijk->ik", bary, np.array([planar[int(f)] for f in face])) * np.array([1.0, sign])

    def place(p):
        A, B, C = corners[:, 0], corners[:, 1], corners[:, 2]
        det = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
        l1 = ((p[0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (p[1] - A[:, 1]) * (C[:, 0] - A[:, 0])) / det
        l2 = ((B[:, 0] - A[:, 0]) * (p[1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (p[0] - A[:, 0])) / det
        bary = np.stack([1 - l1 - l2, l1, l2], axis=1)
        inside = np.flatnonzero(bary.min(axis=1) > 0)
        if len(inside) == 0:
            return None     # outside the unfolded faces (beyond the boundary, or past the tree)
        k = int(inside[0])
        f = int(faces[k])
        return f, bary[k], bary[k] @ T.V[T.F[f]]
    place.region = (faces, corners)
    return plane, place


#: untangle_half's joint re-embedding of the folds no vertex alone clears: up to this many rings
#: around a cluster's corners (0: off; docs/open_surfaces.md "The half's solve").
PATCH_RINGS = 4


def _clusters(F, faces):
    """The faces `faces` of F grouped by shared corners (connected through vertices)."""
    faces = [int(f) for f in faces]
    parent = {f: f for f in faces}

    def find(f):
        while parent[f] != f:
            parent[f] = parent[parent[f]]
            f = parent[f]
        return f
    by_vertex = {}
    for f in faces:
        for v in F[f]:
            if int(v) in by_vertex:
                parent[find(f)] = find(by_vertex[int(v)])
            else:
                by_vertex[int(v)] = f
    groups = {}
    for f in faces:
        groups.setdefault(find(f), []).append(f)
    return [np.array(g) for g in groups.values()]


def _projected_place(T, faces, corners):
    """place(p) for a chart given by the target faces' planar corners (k, 3, 2): the face holding p
    deepest (its barycentrics there, the 3D point), None when none does; each face's projected
    orientation must be positive (a face seen from behind does not count)."""
    A, B, C = corners[:, 0], corners[:, 1], corners[:, 2]
    det = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])

    def place(p):
        with np.errstate(divide="ignore", invalid="ignore"):
            l1 = ((p[0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (p[1] - A[:, 1]) * (C[:, 0] - A[:, 0])) / det
            l2 = ((B[:, 0] - A[:, 0]) * (p[1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (p[0] - A[:, 0])) / det
        bary = np.stack([1 - l1 - l2, l1, l2], axis=1)
        least = np.where(det > 0, bary.min(axis=1), -np.inf)
        k = int(np.argmax(least))
        if not least[k] > -1e-12:     # (a point on an edge or a vertex counts)
            return None
        b = np.clip(bary[k], 0.0, None)
        b /= b.sum()
        f = int(faces[k])
        return f, b, b @ T.V[T.F[f]]
    return place


def _patch_untangle(S, T, fw, free, star_of, turned_of, ear, unit, tf, sign, crease_angle, sliding=()):
    """The source vertices `free` (interior) moved together: in a planar chart of the target around
    their images and their neighbours' (the tangent plane where the normals agree within
    crease_angle, else the target's faces unfolded), placed where the patch's untangling energy is
    least (_untangled_positions; the neighbours outside `free` held), put back on the target.
    sliding: boundary source vertices that move with them, each along the target's rim between
    its held loop neighbours' images (_rim_sliders; the chart holds the rim's faces there). Kept (fw changed, True)
    when every point lands inside the target, the sliding images keep their order along the rim,
    and no face of the patch (the stars of `free` and `sliding`, ears apart) is turned by turned_of
    afterwards; else fw is left as it was (False)."""
    if len(free) == 0:
        return False
    sliding = np.asarray(sliding, dtype=np.int64)
    faces = np.unique(np.concatenate([star_of(int(v)) for v in np.concatenate([free, sliding])]))
    verts = np.unique(S.F[faces])
    held = np.unique(fw["face"][verts])
    rims = None
    if len(sliding):
        rims = _rim_sliders(S, T, fw, sliding)
        if rims is None:
            return False
        held = np.union1d(held, rims["faces"])
    nrm = unit[held].sum(axis=0)
    if np.linalg.norm(nrm) > 1e-12 and np.min(unit[held] @ (nrm / np.linalg.norm(nrm))) >= np.cos(crease_angle):
        plane, _ = _tangent_chart(T, tf, fw["position"][int(free[0])], nrm / np.linalg.norm(nrm), held, sign)
        # The inverse of the projection itself (the tangent chart's own `place` takes the nearest
        # point in 3D, which next to the rim of a curved target can fall on a boundary edge for a
        # point the projection puts inside).
        near = tf.around(held, 2)
        corners = plane(np.repeat(near, 3), np.tile(np.eye(3), (len(near), 1)),
                        T.V[T.F[near]].reshape(-1, 3)).reshape(-1, 3, 2)
        place = _projected_place(T, near, corners)
        place.region = (near, corners)
    else:
        # (With the rim sliding, the faces around the rim's arcs too: the free vertices may go
        # where the tree to the images alone does not reach.)
        chart = _unfolded_chart(T, fw["face"][int(free[0])], tf.around(held, 2) if len(sliding) else held, sign)
        if chart is None:
            return False
        plane, place = chart
    xy = plane(fw["face"][verts], fw["barycentric"][verts], fw["position"][verts])
    if rims is not None:
        if not rims["lay_out"](plane):
            return False
        for i, v in enumerate(sliding):    # (the chart's own rim point: the same image)
            xy[np.searchsorted(verts, v)] = rims["xy"](np.array([rims["s"][i]]), [i])[0]
    # With the rim sliding, the free vertices are also kept inside the chart's faces (a penalty
    # near its walls: _walls), where the positions would otherwise fall into the hole.
    walls = _walls(T, *place.region, sign) if rims is not None else None
    solved = _untangled_positions(S, faces, verts, xy, free, rims=rims, walls=walls)
    if solved is None:
        # From the images as they are the energy can sit still (a ring collapsed onto one point:
        # every Jacobian 0, so is the gradient); again from each free vertex at the average of its
        # neighbours (a Tutte embedding of the patch, the ring around it held).
        solved = _untangled_positions(S, faces, verts, _averaged(S.F[faces], verts, xy, free), free, rims=rims,
                                      walls=walls)
    if solved is None or not np.all(np.isfinite(solved[0])):
        return False
    p, s = solved   # (positions of `free`; the rim's parameters)
    moving = np.concatenate([free, sliding])
    old = {k: np.array(fw[k][moving], copy=True) for k in ("face", "barycentric", "position")}

    def undo():
        for k, x in old.items():
            fw[k][moving] = x
        return False
    for i, v in enumerate(free):
        got = place(p[i])
        if got is None:     # beyond the target's boundary or the chart
            return undo()
        fw["face"][v], fw["barycentric"][v], fw["position"][v] = got
    if rims is not None:
        if not rims["ordered"](s):
            return undo()
        for i, v in enumerate(sliding):
            fw["face"][v], fw["barycentric"][v], fw["position"][v] = _loop_point(T, rims["loop"][i], s[i] % rims["n"][i])
    if np.any(turned_of(faces) & ~ear[faces]):
        return undo()
    return True


def _walls(T, faces, corners, sign=1.0):
    """The region of a chart: the target faces `faces` at planar corners (k, 3, 2), those seen
    turned in it left out. Returns sd(P) -> (signed distances (m,) of the points P (m, 2) to the
    region's walls (the edges of its faces with no neighbour in it: the rim, the chart's edge),
    positive inside a face, and their gradients (m, 2))."""
    from .open_double import _face_neighbours
    if getattr(T, "face_neighbours", None) is None:
        T.face_neighbours = _face_neighbours(T.F)
    A, B, C = corners[:, 0], corners[:, 1], corners[:, 2]
    det = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
    keep = det * sign > 0
    faces, corners, det = np.asarray(faces)[keep], corners[keep], det[keep]
    inset = set(int(f) for f in faces)
    seg = np.array([(corners[i][k], corners[i][(k + 1) % 3]) for i, f in enumerate(faces) for k in range(3)
                    if int(T.face_neighbours[f, k]) not in inset]).reshape(-1, 2, 2)
    A, B, C = corners[:, 0], corners[:, 1], corners[:, 2]

    def sd(P):
        l1 = (((P[:, None, 0] - A[None, :, 0]) * (C[None, :, 1] - A[None, :, 1])
               - (P[:, None, 1] - A[None, :, 1]) * (C[None, :, 0] - A[None, :, 0])) / det)
        l2 = (((B[None, :, 0] - A[None, :, 0]) * (P[:, None, 1] - A[None, :, 1])
               - (B[None, :, 1] - A[None, :, 1]) * (P[:, None, 0] - A[None, :, 0])) / det)
        inside = np.any(np.minimum(np.minimum(l1, l2), 1 - l1 - l2) >= 0, axis=1)
        d = seg[None, :, 1] - seg[None, :, 0]
        t = np.clip(np.einsum("mkj,mkj->mk", P[:, None] - seg[None, :, 0], d)
                    / np.maximum(np.einsum("mkj,mkj->mk", d, d), 1e-300), 0, 1)
        q = seg[None, :, 0] + t[..., None] * d
        dist = np.linalg.norm(P[:, None] - q, axis=2)
        k = np.argmin(dist, axis=1)
        rows = np.arange(len(P))
        away = (P - q[rows, k]) / np.maximum(dist[rows, k], 1e-300)[:, None]
        sgn = np.where(inside, 1.0, -1.0)
        return sgn * dist[rows, k], sgn[:, None] * away
    return sd


def _rim_sliders(S, T, fw, sliding):
    """The boundary source vertices `sliding` as unknowns of the joint step: each one's image a
    parameter s along the target loop holding it (_loop_parameter), bounded by the images of the
    nearest loop neighbours on each side that do not slide (the run of sliding vertices between
    them keeps its order: `ordered`), its chart position piecewise linear in s. None when a
    vertex's image or a run's ends are off the boundary, on different target loops, or a run
    covers its whole loop. Returns {sliding, s (start, unwrapped), bounds [(lo, hi)], loop, n,
    faces (the target faces holding the loop edges within the bounds), lay_out(plane) (the chart's
    rim: False when the chart misses one of those faces), xy(s, idx) -> (k, 2) chart points (and
    their derivatives d xy / d s: xy(..., derivative=True)), ordered(s)}."""
    if getattr(S, "loop_neighbours", None) is None:
        S.loop_neighbours = {int(v): (int(loop[k - 1]), int(loop[(k + 1) % len(loop)]))
                             for loop in S.loops for k, v in enumerate(loop)}
    moving = {int(v) for v in sliding}
    s0, bounds, loops, ns, runs = [], [], [], [], {}
    for v in sliding:
        v = int(v)
        here = _loop_parameter(T, fw["face"][v], fw["barycentric"][v])
        if here is None:
            return None
        # The run of sliding loop neighbours around v, to the held vertices at its ends.
        ends = []
        for side in (0, 1):
            u, steps = v, 0
            while u in moving:
                u = S.loop_neighbours[u][side]
                steps += 1
                if steps > len(S.loop_neighbours):
                    return None
            if u == v:
                return None     # the whole loop slides
            ends.append(_loop_parameter(T, fw["face"][u], fw["barycentric"][u]))
        prev, nxt = ends
        if prev is None or nxt is None or not here[0] == prev[0] == nxt[0]:
            return None
        n = len(T.loops[here[0]])
        fwd = (here[1] - prev[1]) % n <= (nxt[1] - prev[1]) % n
        a, b = (prev[1], nxt[1]) if fwd else (nxt[1], prev[1])
        length = (b - a) % n
        if length <= 0:
            return None
        gap = min(1e-3, 1e-3 * length)
        s0.append(a + (here[1] - a) % n)
        bounds.append((a + gap, a + length - gap))
        loops.append(here[0])
        ns.append(n)
        runs[v] = (a, fwd)
    # The loop edges each vertex may slide over, with the faces holding them (the chart must
    # hold those faces).
    places = _loop_places(T)
    edges = sorted({(li, j % n) for li, n, (lo, hi) in zip(loops, ns, bounds)
                    for j in range(int(np.floor(lo)), int(np.floor(hi)) + 1)})
    ends = {}

    def lay_out(plane):
        """The arcs' edges in the chart (each edge's two ends through the face holding it); False
        when the chart does not hold them all."""
        rows = np.array([places[li][j] for li, j in edges])
        bary = np.zeros((len(edges), 2, 3))
        bary[np.arange(len(edges)), 0, rows[:, 1]] = 1.0
        bary[np.arange(len(edges)), 1, rows[:, 2]] = 1.0
        f = np.repeat(rows[:, 0], 2)
        try:
            xy_ends = plane(f, bary.reshape(-1, 3), np.einsum("ij,ijk->ik", bary.reshape(-1, 3), T.V[T.F[f]]))
        except KeyError:
            return False
        xy_ends = xy_ends.reshape(-1, 2, 2)
        ends.update({e: xy_ends[k] for k, e in enumerate(edges)})
        return True

    def xy(s, idx, derivative=False):
        out, der = np.zeros((len(idx), 2)), np.zeros((len(idx), 2))
        for k, i in enumerate(idx):
            C = ends[(loops[i], int(np.floor(s[k])) % ns[i])]
            t = s[k] - np.floor(s[k])
            der[k] = C[1] - C[0]
            out[k] = C[0] + t * der[k]
        return (out, der) if derivative else out

    def ordered(s):
        # Consecutive sliding loop neighbours keep their order along the rim (the direction each
        # run's arc runs in).
        at = {int(v): i for i, v in enumerate(sliding)}
        for i, v in enumerate(sliding):
            w = S.loop_neighbours[int(v)][1]
            if w in at and runs[int(v)] == runs[w] and not (s[at[w]] - s[i]) * (1 if runs[int(v)][1] else -1) > 0:
                return False
        return True
    return {"sliding": np.asarray(sliding), "s": np.array(s0), "bounds": bounds, "loop": loops, "n": ns, "xy": xy,
            "ordered": ordered, "faces": np.unique([places[li][j][0] for li, j in edges]), "lay_out": lay_out}


def _averaged(F, verts, xy, free):
    """xy (of `verts`, the vertices of faces F) with each vertex of `free` at the average of its
    neighbours in F, the others held: a sparse linear solve."""
    from scipy.sparse import coo_matrix, identity
    from scipy.sparse.linalg import spsolve
    idx = np.searchsorted(verts, F)
    e = np.concatenate([idx[:, [0, 1]], idx[:, [1, 2]], idx[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    n = len(verts)
    A = coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)).tocsr()
    deg = np.asarray(A.sum(axis=1)).ravel()
    f = np.searchsorted(verts, free)
    held = np.setdiff1d(np.arange(n), f)
    L = (identity(n, format="csr").multiply(deg[:, None]) - A).tocsr()
    out = np.array(xy, dtype=float)
    rhs = -L[f][:, held] @ out[held]
    M = L[f][:, f].tocsc()
    out[f] = np.column_stack([spsolve(M, rhs[:, 0]), spsolve(M, rhs[:, 1])])
    return out


#: The joint step's minimizer (_untangled_positions): "lbfgs" (the default: scipy's L-BFGS-B, which
#: takes thousands of evaluations per round on the artery's patches) or "newton" (Newton steps on
#: the patch's sparse Hessian, each face's 4 x 4 Hessian in its Jacobian made positive
#: semi-definite, with a backtracking line search and the rim's parameters kept in their bounds:
#: fewer evaluations, but slower than L-BFGS-B on the artery's patches; docs/open_surfaces.md
#: "The half's solve").
JOINT_METHOD = "lbfgs"


def _newton(fun, z, lo, hi, maxiter=200, ftol=2.2e-9, gtol=1e-5, done=None):
    """Minimizes fun(z, order) (order 0: value; 1: value, gradient; 2: value, gradient, sparse
    Hessian, positive semi-definite) from z within the bounds lo <= z <= hi (arrays, +-inf where
    free): projected Newton steps (the variables at a bound that the gradient pushes outwards held),
    a backtracking (Armijo) line search on the clipped step. Stops on L-BFGS-B's tests (the relative
    decrease below ftol, the projected gradient below gtol), when the line search finds no
    decrease, or when done(z) holds after a step. Returns z."""
    from scipy.sparse import identity
    from scipy.sparse.linalg import spsolve
    f, g, H = fun(z, 2)
    for _ in range(maxiter):
        at_lo, at_hi = z <= lo, z >= hi
        if np.max(np.abs(z - np.clip(z - g, lo, hi)), initial=0.0) <= gtol:
            break
        held = (at_lo & (g > 0)) | (at_hi & (g < 0))
        move = np.flatnonzero(~held)
        Hm = H[move][:, move].tocsc()
        diag = Hm.diagonal()
        delta = 1e-12 * max(float(np.mean(np.abs(diag))), 1e-300)
        p = np.zeros_like(z)
        for _ in range(6):
            with np.errstate(all="ignore"):
                step = spsolve(Hm + delta * identity(len(move), format="csc"), -g[move])
            step = np.atleast_1d(step)
            if np.all(np.isfinite(step)) and float(step @ g[move]) < 0:
                break
            delta *= 1e3
        else:
            step = -g[move]
        p[move] = step
        t, accepted = 1.0, False
        for _ in range(60):
            zn = np.clip(z + t * p, lo, hi)
            fn = fun(zn, 0)
            if np.isfinite(fn) and fn <= f + 1e-4 * float(g @ (zn - z)):
                accepted = True
                break
            t *= 0.5
        if not accepted:
            break
        decrease = f - fn
        z = zn
        if decrease <= ftol * max(abs(f), abs(fn), 1.0) or (done is not None and done(z)):
            break
        f, g, H = fun(z, 2)
    return z


def _rim_refuses(Fi, X):
    """Why no placing of a patch's free vertices leaves every face positive, its rim held: '' when
    nothing proves it. Fi: the patch's faces (rows of X); X: planar positions, the rim's held (the
    rim's edges: those of a face whose reverse is in no face, joining held vertices only).
    Each positive triangle adds 1 to the number of times the map covers a point, so wherever the
    faces are all positive that count is >= 0 everywhere; it is the rim's winding number about the
    point, which the free vertices do not change, and so is the total area (the integral of the
    winding number; the faces' signed areas add up to it whatever the free vertices do). Refused:
    the total area <= 0, or a winding number < 0 on either side of a rim edge's midpoint (the
    rim edges' sides point into every cell of the plane the rim bounds that reaches the middle of
    one of its edges; a point within 1e-9 of the rim's scale of an edge's line is not read)."""
    Q = X[Fi]
    signed = ((Q[:, 1, 0] - Q[:, 0, 0]) * (Q[:, 2, 1] - Q[:, 0, 1]) - (Q[:, 1, 1] - Q[:, 0, 1]) * (Q[:, 2, 0] - Q[:, 0, 0]))
    if not float(np.sum(signed)) > 0:
        return f"the rim encloses the area {0.5 * float(np.sum(signed)):.3g}"
    edges = np.concatenate([Fi[:, [0, 1]], Fi[:, [1, 2]], Fi[:, [2, 0]]])
    n = len(X)
    code = edges[:, 0] * n + edges[:, 1]
    rim = edges[~np.isin(code, edges[:, 1] * n + edges[:, 0])]
    if len(rim) == 0:
        return ""
    A, B = X[rim[:, 0]], X[rim[:, 1]]
    d = B - A
    length = np.linalg.norm(d, axis=1)
    scale = float(length.max())
    if not scale > 0:
        return ""
    side = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.maximum(length, 1e-300)[:, None] * (1e-6 * length)[:, None]
    mid = 0.5 * (A + B)
    P = np.concatenate([mid + side, mid - side])
    a, b = A[None] - P[:, None], B[None] - P[:, None]
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    dot = np.einsum("pkj,pkj->pk", a, b)
    # (distance of each point to each edge's line, to leave out points on or next to an edge)
    near = np.abs(cross) / np.maximum(length[None], 1e-300) <= 1e-9 * scale
    turn = np.arctan2(cross, dot).sum(axis=1) / (2 * np.pi)
    read = ~np.any(near & (dot <= 0), axis=1)
    winding = np.rint(turn[read])
    if len(winding) and float(winding.min()) < 0:
        return f"the rim winds {int(winding.min())} times about a point beside it"
    return ""


def _untangled_positions(S, faces, verts, xy, free, rounds=12, lam=1.0, polish=2, polish_lam=0.01, rims=None,
                         walls=None, wall_margin=0.1, wall_weight=100.0, method=None, stats=None, refuse=True):
    """Planar positions of `free` (among `verts`, at xy now; the others held) minimizing the
    untangling energy of the patch `faces` of S: per face, area-weighted, with J its Jacobian from
    the source triangle (in its own plane) to the chart, (|J|^2 / 2 + lam (det J^2 + 1) / 2) /
    chi(det J, eps), chi(D, eps) = (D + sqrt(eps^2 + D^2)) / 2, which is finite for turned faces
    and becomes a barrier against turning as eps -> 0; eps (relative to the faces' median |det J|)
    is lowered tenfold each round while a face stays turned. Once none is, `polish` rounds at
    eps 1e-3 times smaller with lam = polish_lam (mostly the conformal term |J|^2 / det J, which
    D' measures) lower the distortion, each kept only while nothing turns. None when a face is
    still turned after `rounds`; else (positions (k, 2) of `free`, parameters of the rim's
    vertices). rims (_rim_sliders): its vertices are unknowns too, each a parameter along the
    target's rim within its bounds (no rims: no parameters, an empty array).
    walls (_walls): a penalty wall_weight * (patch area) / delta^2 * max(0, delta - sd)^2 per free
    vertex, delta = wall_margin times the patch's median image edge, keeps the free vertices inside
    the chart's faces; None when one ends outside them.
    method: the minimizer of each round (JOINT_METHOD when None; "newton": _newton on the energy's
    gradient and Hessian, the faces' Hessians in J projected onto the positive semi-definite ones;
    "lbfgs": scipy's L-BFGS-B on the gradient). stats (a dict): gets "evaluations" (the energy's
    evaluations, each with its gradient, and with the Newton step's line search the values alone),
    "rounds" (per round the evaluations so far and the faces turned after it) and, when the rim
    is refused, "refused" (why). refuse (default True): a held rim that admits no unfolded placing
    (_rim_refuses) returns None at once, without the rounds."""
    from scipy.optimize import minimize
    from scipy.sparse import coo_matrix
    method = JOINT_METHOD if method is None else method
    if method not in ("newton", "lbfgs"):
        raise ValueError(f"unknown joint step method {method!r}: 'newton' or 'lbfgs'")
    pos = {int(v): i for i, v in enumerate(verts)}
    Fi = np.array([[pos[int(x)] for x in S.F[f]] for f in faces])
    P = S.V[S.F[faces]]
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    l1 = np.linalg.norm(e1, axis=1)
    x = e1 / l1[:, None]
    n = np.cross(e1, e2)
    y = np.cross(n / np.linalg.norm(n, axis=1)[:, None], x)
    # Reference triangles (0, 0), (l1, 0), (u, w): Jacobian J = [q1 - q0, q2 - q0] R^-1.
    u, w = np.einsum("ij,ij->i", e2, x), np.einsum("ij,ij->i", e2, y)
    area = 0.5 * l1 * w
    if not np.all(area > 0):
        return None     # a degenerate source face: no Jacobian
    Rinv = np.zeros((len(faces), 2, 2))
    Rinv[:, 0, 0], Rinv[:, 0, 1], Rinv[:, 1, 1] = 1 / l1, -u / (l1 * w), 1 / w
    is_free = np.zeros(len(verts), dtype=bool)
    is_free[[pos[int(v)] for v in free]] = True
    X0 = np.array(xy, dtype=float)
    slid = np.array([pos[int(v)] for v in rims["sliding"]], dtype=np.int64) if rims else np.zeros(0, np.int64)
    m = 2 * int(is_free.sum())
    scale, margin, mu = [1.0], [0.0], [0.0]
    count = [0]
    k = len(faces)
    # The gradient gathered onto the vertices (rows: patch vertices; columns: face corners) with
    # one sparse product instead of np.add.at.
    gather = coo_matrix((np.ones(3 * k), (Fi.T.ravel(), np.arange(3 * k))), shape=(len(verts), 3 * k)).tocsr()
    # d J / d (corner c, coordinate i): J_ij = sum_c q_c,i B_cj.
    Bc = np.stack([-(Rinv[:, 0] + Rinv[:, 1]), Rinv[:, 0], Rinv[:, 1]], axis=1)    # (k, 3, 2)
    M = np.zeros((k, 4, 6))
    for i in range(2):
        for j in range(2):
            for c in range(3):
                M[:, 2 * i + j, 2 * c + i] = Bc[:, c, j]
    # Each face corner's unknowns: a free vertex's two coordinates, a sliding vertex's parameter.
    free_index = np.full(len(verts), -1, dtype=np.int64)
    free_index[is_free] = np.arange(int(is_free.sum()))
    slid_index = np.full(len(verts), -1, dtype=np.int64)
    slid_index[slid] = np.arange(len(slid))
    corner_dof = np.full((k, 6), -1, dtype=np.int64)
    for c in range(3):
        fr, sl = free_index[Fi[:, c]], slid_index[Fi[:, c]]
        for i in range(2):
            corner_dof[:, 2 * c + i] = np.where(fr >= 0, 2 * fr + i, np.where(sl >= 0, m + sl, -1))
    pair_rows = np.repeat(corner_dof, 6, axis=1).reshape(k, 6, 6)
    pair_cols = np.tile(corner_dof, (1, 6)).reshape(k, 6, 6)
    pair_ok = (pair_rows >= 0) & (pair_cols >= 0)
    n_dof = m + len(slid)
    HD = np.zeros((4, 4))
    HD[0, 3] = HD[3, 0] = 1.0
    HD[1, 2] = HD[2, 1] = -1.0

    def put(z):
        X = X0.copy()
        X[is_free] = z[:m].reshape(-1, 2)
        der = None
        if len(slid):
            at, der = rims["xy"](z[m:], range(len(slid)), derivative=True)
            X[slid] = at / scale[0]
            der = der / scale[0]
        return X, der

    def jac(X):
        Q = X[Fi]
        E = np.stack([Q[:, 1] - Q[:, 0], Q[:, 2] - Q[:, 0]], axis=2)    # columns q1 - q0, q2 - q0
        return E @ Rinv

    def energy(z, eps, lam=lam, order=1):
        count[0] += 1
        X, der = put(z)
        J = jac(X)
        D = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        r = np.sqrt(eps * eps + D * D)
        # (D + r) / 2 without the cancellation for D << 0
        with np.errstate(divide="ignore", invalid="ignore"):   # np.where evaluates both
            chi = np.where(D >= 0, 0.5 * (D + r), 0.5 * eps * eps / (r - D))
        num = 0.5 * np.einsum("ijk,ijk->i", J, J) + 0.5 * lam * (D * D + 1)
        value = float(np.dot(area, num / chi))
        if walls is not None:
            d, dd = walls(X[is_free] * scale[0])
            short = np.maximum(0.0, margin[0] - d / scale[0])
            value += mu[0] * float(np.sum(short * short))
        if order == 0:
            return value
        dchi = 0.5 * (1 + D / r)
        # d f / dJ = J / chi + (lam D / chi - num dchi / chi^2) cof(J), cof(J) = d det J / dJ
        cof = np.stack([np.stack([J[:, 1, 1], -J[:, 1, 0]], 1), np.stack([-J[:, 0, 1], J[:, 0, 0]], 1)], 1)
        G = J / chi[:, None, None] + (lam * D / chi - num * dchi / chi ** 2)[:, None, None] * cof
        G = G * area[:, None, None]
        dE = G @ np.transpose(Rinv, (0, 2, 1))   # d energy / d (q1 - q0, q2 - q0)
        grad = gather @ np.concatenate([-dE[:, :, 0] - dE[:, :, 1], dE[:, :, 0], dE[:, :, 1]])
        if walls is not None:
            grad[is_free] -= 2 * mu[0] * short[:, None] * dd
        g = grad[is_free].ravel()
        if len(slid):
            g = np.concatenate([g, np.einsum("ij,ij->i", grad[slid], der)])
        if order == 1:
            return value, g
        # The Hessian of f(J) = num / chi (J flattened row by row; gD = cof flattened = d det / dJ,
        # HD = d^2 det / dJ^2): d^2 num / chi - (d num gD' + gD d num') chi' / chi^2
        # + num (2 chi'^2 / chi^3 - chi'' / chi^2) gD gD' - num chi' / chi^2 HD.
        j = J.reshape(k, 4)
        gD = cof.reshape(k, 4)
        dnum = j + (lam * D)[:, None] * gD
        ddchi = 0.5 * eps * eps / r ** 3
        outer = gD[:, :, None] * gD[:, None, :]
        Hf = ((np.eye(4)[None] + lam * (outer + D[:, None, None] * HD[None])) / chi[:, None, None]
              - (dnum[:, :, None] * gD[:, None, :] + gD[:, :, None] * dnum[:, None, :]) * (dchi / chi ** 2)[:, None, None]
              + (num * (2 * dchi ** 2 / chi ** 3 - ddchi / chi ** 2))[:, None, None] * outer
              - (num * dchi / chi ** 2)[:, None, None] * HD[None])
        Hf = 0.5 * (Hf + np.transpose(Hf, (0, 2, 1)))
        lam_, vec = np.linalg.eigh(Hf)
        Hf = np.einsum("kab,kb,kcb->kac", vec, np.maximum(lam_, 0.0), vec)
        Hl = np.einsum("kai,kab,kbj->kij", M, Hf, M) * area[:, None, None]     # (k, 6, 6) in the corners
        coef = np.ones((k, 6))
        if len(slid):
            for c in range(3):
                sl = slid_index[Fi[:, c]]
                on = sl >= 0
                coef[on, 2 * c] = der[sl[on], 0]
                coef[on, 2 * c + 1] = der[sl[on], 1]
        data = (Hl * coef[:, :, None] * coef[:, None, :])[pair_ok]
        rows, cols = pair_rows[pair_ok], pair_cols[pair_ok]
        if walls is not None:
            hit = np.flatnonzero(short > 0)
            ww = 2 * mu[0] * dd[hit][:, :, None] * dd[hit][:, None, :]
            r2 = 2 * hit[:, None, None] + np.arange(2)[None, :, None] + np.zeros((1, 1, 2), dtype=np.int64)
            c2 = 2 * hit[:, None, None] + np.arange(2)[None, None, :] + np.zeros((1, 2, 1), dtype=np.int64)
            data, rows, cols = np.r_[data, ww.ravel()], np.r_[rows, r2.ravel()], np.r_[cols, c2.ravel()]
        H = coo_matrix((data, (rows, cols)), shape=(n_dof, n_dof)).tocsr()
        return value, g, H

    # Without sliding vertices the patch's rim is held (the free vertices are interior to the patch:
    # their whole stars are in it), and some rims admit no unfolded placing at all (_rim_refuses):
    # then no round can end unfolded, and none is run.
    if refuse and not len(slid):
        refused = _rim_refuses(Fi, X0)
        if refused:
            if stats is not None:
                stats.update(evaluations=0, rounds=[], refused=refused)
            return None
    # The chart scaled so that the faces' median |det J| is 1 (eps is relative to it).
    J = jac(X0)
    unit_scale = np.sqrt(max(float(np.median(np.abs(J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]))), 1e-300))
    X0 = X0 / unit_scale
    scale[0] = unit_scale
    if walls is not None:
        E = X0[Fi] - X0[Fi[:, [1, 2, 0]]]
        margin[0] = wall_margin * float(np.median(np.linalg.norm(E, axis=2)))
        mu[0] = wall_weight * float(area.sum()) / max(margin[0] ** 2, 1e-300)
    z = X0[is_free].ravel()
    bounds = None
    lo, hi = np.full(n_dof, -np.inf), np.full(n_dof, np.inf)
    if len(slid):
        z = np.concatenate([z, rims["s"]])
        bounds = [(None, None)] * m + list(rims["bounds"])
        lo[m:], hi[m:] = np.array(rims["bounds"]).T

    def least(z, eps, lam, done=None):
        if method == "newton":
            return _newton(lambda y, order: energy(y, eps, lam, order), np.clip(z, lo, hi), lo, hi, done=done)
        return minimize(energy, z, args=(eps, lam), jac=True, method="L-BFGS-B", bounds=bounds,
                        options={"maxiter": 2000}).x

    def dets(z):
        J = jac(put(z)[0])
        return J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]

    def least_det(z):
        return float(np.min(dets(z)))
    eps = 1.0
    for _ in range(rounds):
        # (Newton: the round ends as soon as no face is turned; the polish below starts from there.)
        z = least(z, eps, lam, done=lambda y: least_det(y) > 0)
        if stats is not None:
            stats.setdefault("rounds", []).append((count[0], int(np.sum(dets(z) <= 0))))
        if least_det(z) > 0:
            break
        eps *= 0.1
    else:
        if stats is not None:
            stats["evaluations"] = count[0]
        return None
    # Unfolded: the same energy with eps near 0 (the barrier form, which lowers the distortion; the
    # first unfolded point is often a sliver at the edge of the feasible set), kept while unfolded.
    for _ in range(polish):
        eps *= 1e-3
        got = least(z, eps, polish_lam)
        if least_det(got) <= 0:
            break
        z = got
    if stats is not None:
        stats["evaluations"] = count[0]
    p = z[:m].reshape(-1, 2) * unit_scale
    if walls is not None and len(p) and np.min(walls(p)[0]) <= 0:
        return None
    return p, z[m:]


def _loop_places(T):
    """Per loop of T its polyline as (vertices (n,), for each loop edge j (loop[j] -> loop[j + 1]) a
    face of T holding it and the two corners' slots in that face)."""
    if getattr(T, "loop_edge_faces", None) is None:
        edge_face = {}
        for f, tri in enumerate(T.F):
            for k in range(3):
                edge_face[(int(tri[k]), int(tri[(k + 1) % 3]))] = (f, k, (k + 1) % 3)
        out = []
        for loop in T.loops:
            rows = []
            for u, w in zip(loop, np.roll(loop, -1)):
                f, a, b = edge_face[(int(u), int(w))] if (int(u), int(w)) in edge_face else (
                    lambda x: (x[0], x[2], x[1]))(edge_face[(int(w), int(u))])
                rows.append((f, a, b))
            out.append(np.array(rows, dtype=np.int64))
        T.loop_edge_faces = out
    return T.loop_edge_faces


def _loop_parameter(T, face, bary):
    """Where a point of T's boundary (face, barycentrics) lies along T's loops: (loop, s) with s =
    j + t on loop edge j at t from loop[j]; None off the boundary."""
    tri = T.F[face]
    on = [int(tri[k]) for k in range(3) if bary[k] > 1e-12]
    if getattr(T, "loop_position", None) is None:
        T.loop_position = {int(v): (li, j) for li, loop in enumerate(T.loops) for j, v in enumerate(loop)}
    if len(on) == 1 and on[0] in T.loop_position:
        return T.loop_position[on[0]][0], float(T.loop_position[on[0]][1])
    if len(on) != 2 or any(v not in T.loop_position for v in on):
        return None
    (l0, j0), (l1, j1) = T.loop_position[on[0]], T.loop_position[on[1]]
    n = len(T.loops[l0])
    if l0 != l1:
        return None
    t_of = {on[0]: float(bary[list(tri).index(on[0])]), on[1]: float(bary[list(tri).index(on[1])])}
    if (j1 - j0) % n == 1:
        return l0, j0 + t_of[on[1]]
    if (j0 - j1) % n == 1:
        return l0, j1 + t_of[on[0]]
    return None


def _loop_point(T, loop, s):
    """The point at parameter s (_loop_parameter) of T's loop `loop`: (face, barycentrics, position)."""
    L = T.loops[loop]
    n = len(L)
    j = int(np.floor(s)) % n
    t = s - np.floor(s)
    f, a, b = _loop_places(T)[loop][j]
    bary = np.zeros(3)
    bary[a], bary[b] = 1 - t, t
    return int(f), bary, bary @ T.V[T.F[f]]


def _slide_boundary_corners(S, T, fw, turned_of, ear, bad, on_b, star_of, steps=4):
    """Boundary corners of the folded faces `bad` slid along the target's loop (a boundary vertex's
    image may lie anywhere between its two loop neighbours' images: the map still sends boundary
    onto boundary in the same order). Each corner v's image tried at every target loop vertex in
    that arc and at `steps` - 1 points evenly along each arc edge; kept at the point where the
    fewest faces of v's star turn (pipeline's test, ears apart), then the least largest D', when
    that is fewer than now. Returns the vertices slid."""
    from .open_double import _dilatation
    if getattr(S, "loop_neighbours", None) is None:
        S.loop_neighbours = {int(v): (int(loop[k - 1]), int(loop[(k + 1) % len(loop)]))
                             for loop in S.loops for k, v in enumerate(loop)}
    slid = []
    for v in np.unique(S.F[bad]):
        v = int(v)
        if not on_b[v]:
            continue
        star = star_of(v)
        star = star[~ear[star]]
        now = int(np.sum(turned_of(star)))
        if now == 0:
            continue
        here = _loop_parameter(T, fw["face"][v], fw["barycentric"][v])
        prev, nxt = (_loop_parameter(T, fw["face"][u], fw["barycentric"][u]) for u in S.loop_neighbours[v])
        if here is None or prev is None or nxt is None or not here[0] == prev[0] == nxt[0]:
            continue
        n = len(T.loops[here[0]])
        # The arc from prev to nxt that holds v's image now (either way round the loop).
        fwd = (here[1] - prev[1]) % n <= (nxt[1] - prev[1]) % n
        a, b = (prev[1], nxt[1]) if fwd else (nxt[1], prev[1])
        length = (b - a) % n
        if length <= 0:
            continue
        grid = np.concatenate([np.arange(np.floor(a) + k / steps, np.floor(a) + length + 1, 1.0)
                               for k in range(steps)])
        grid = np.sort(grid[((grid - a) > 1e-9) & ((grid - a) < length - 1e-9)])
        old = (fw["face"][v], fw["barycentric"][v].copy(), fw["position"][v].copy())
        best = None
        for s in grid:
            fw["face"][v], fw["barycentric"][v], fw["position"][v] = _loop_point(T, here[0], s % n)
            k = int(np.sum(turned_of(star)))
            if k < now:
                worst = float(np.max(_dilatation(S.V, fw["position"], S.F[star]), initial=0.0))
                if best is None or (k, worst) < best[:2]:
                    best = (k, worst, s % n)
        if best is None:
            fw["face"][v], fw["barycentric"][v], fw["position"][v] = old
            continue
        fw["face"][v], fw["barycentric"][v], fw["position"][v] = _loop_point(T, here[0], best[2])
        slid.append(v)
    return slid


class _TargetFaces:
    """The target's faces around a set of faces (rings of faces sharing a vertex)."""

    def __init__(self, F, n):
        order = np.argsort(F.reshape(-1), kind="stable")
        self.F = F
        self.vf_face = order // 3
        self.vf_start = np.searchsorted(F.reshape(-1)[order], np.arange(n + 1))

    def around(self, faces, rings):
        faces = np.unique(faces)
        for _ in range(rings):
            verts = np.unique(self.F[faces])
            faces = np.unique(np.concatenate([self.vf_face[self.vf_start[v]:self.vf_start[v + 1]] for v in verts]))
        return faces


# Long on purpose: its steps (the single moves with ring relaxation, the joint patches, the final
# sweeps) share the closures star_of, try_move and within and the state they keep over fw; split,
# each piece would take all of them as arguments.
def untangle_half(S, T, fw, turned_of, reversing=False, crease_angle=np.pi / 3, max_passes=4, max_rings=3,
                  relax_sweeps=2, kernel_radii=(0.5, 1.0, 2.0, 4.0), kernel_directions=12, patch_rings=None,
                 boundary_slides=True):
    """Moves interior source vertices of folded faces (module docstring). S, T: open_double._Side;
    fw: the half's forward map {face, barycentric, position} on T's input faces (changed in place);
    turned_of(faces) -> bool array: the pipeline's test of those source faces (open_double._turned);
    reversing: an orientation-reversing map (the charts' y axis turned). Ears (three boundary
    corners) are never counted. crease_angle: beyond it the unfolded chart; max_passes, max_rings,
    relax_sweeps: the passes, the rings relaxed around corners that cannot move, the final sweeps;
    kernel_radii (times the kernel's depth) and kernel_directions: the further points of the shrunk
    kernel a folded corner tries, least distorted first, when its best point and the kernel's centre
    leave its star turned by turned_of. patch_rings (default PATCH_RINGS; 0: off): the folds no
    vertex alone can clear (every corner's kernel empty) re-embedded a cluster at a time, its
    interior vertices within 1..patch_rings rings moved together (_patch_untangle). Returns the
    moved vertices (sorted, each once)."""
    from scipy.optimize import linprog, minimize

    on_b = np.zeros(S.n, dtype=bool)
    on_b[np.concatenate(S.loops)] = True
    ear = np.all(on_b[S.F], axis=1)
    order = np.argsort(S.F.reshape(-1), kind="stable")
    s_face = order // 3
    s_start = np.searchsorted(S.F.reshape(-1)[order], np.arange(S.n + 1))
    if getattr(T, "face_normals", None) is None:
        T.face_normals = np.cross(T.V[T.F[:, 1]] - T.V[T.F[:, 0]], T.V[T.F[:, 2]] - T.V[T.F[:, 0]])
    unit = T.face_normals / np.maximum(np.linalg.norm(T.face_normals, axis=1), 1e-300)[:, None]
    tf = _TargetFaces(T.F, len(T.V))
    sign = -1.0 if reversing else 1.0
    moved = []

    seg_a = np.concatenate([T.V[loop] for loop in T.loops])
    seg_d = np.concatenate([T.V[np.roll(loop, -1)] for loop in T.loops]) - seg_a
    seg_dd = np.maximum(np.einsum("ij,ij->i", seg_d, seg_d), 1e-300)

    def boundary_distance(x):
        t = np.clip(np.einsum("ij,ij->i", x - seg_a, seg_d) / seg_dd, 0, 1)
        return float(np.min(np.linalg.norm(seg_a + t[:, None] * seg_d - x, axis=1)))

    def star_of(v):
        return s_face[s_start[v]:s_start[v + 1]]

    def try_move(v, improve=False):
        """Moves v to the least distorted point of its star's shrunk kernel; improve: only when its
        star is not folded now, and only if that lowers the star's distortion."""
        star = star_of(v)
        if improve and np.any(turned_of(star)):
            return False
        # Each star face as (v, a, b) in the source's order: counter-clockwise around v.
        ab = []
        for f in star:
            k = list(S.F[f]).index(v)
            ab.append((S.F[f][(k + 1) % 3], S.F[f][(k + 2) % 3]))
        ab = np.array(ab)
        ring = np.unique(ab)
        held = np.concatenate([[fw["face"][v]], fw["face"][ring]])
        nrm = unit[held].sum(axis=0)
        if np.linalg.norm(nrm) > 1e-12 and np.min(unit[held] @ (nrm / np.linalg.norm(nrm))) >= np.cos(crease_angle):
            plane, place = _tangent_chart(T, tf, fw["position"][v], nrm / np.linalg.norm(nrm), held, sign)
        else:
            chart = _unfolded_chart(T, fw["face"][v], held, sign)
            if chart is None:
                return False
            plane, place = chart

        def at(x):
            return plane(fw["face"][x], fw["barycentric"][x], fw["position"][x])
        o = at(np.array([v]))[0]
        a, b = at(ab[:, 0]) - o, at(ab[:, 1]) - o
        d = a - b
        length = np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        # Signed distance of p to the line a -> b (positive on its left, where v belongs):
        # (a x b + p x (a - b)) / |a - b|, linear in p.
        axb = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]

        def dist(p):
            return (axb + p[0] * d[:, 1] - p[1] * d[:, 0]) / length
        # max t subject to dist_k(p) >= t: -(d_y px - d_x py)/|d| + t <= axb/|d|.
        A_ub = np.stack([-d[:, 1] / length, d[:, 0] / length, np.ones(len(d))], axis=1)
        scale = float(length.max())
        res = linprog([0, 0, -1], A_ub=A_ub, b_ub=axb / length, bounds=[(-10 * scale, 10 * scale)] * 2 + [(None, scale)],
                      method="highs")
        if res.status != 0 or res.x[2] <= 1e-12 * scale:
            return False
        centre, depth = res.x[:2], res.x[2]
        # D' of each star face's image (open_double._dilatation's, here in the chart): the image's
        # edges E = [a - p, b - p] against the source triangle's edges, whose Gram matrix G is
        # fixed, |J|^2 = tr(E G^-1 E') and det J = det E / sqrt(det G) with J = E (source frame)^-1.
        src = S.V[np.stack([np.full(len(ab), v), ab[:, 0], ab[:, 1]], axis=1)]
        s1, s2 = src[:, 1] - src[:, 0], src[:, 2] - src[:, 0]
        g11, g12, g22 = np.einsum("ij,ij->i", s1, s1), np.einsum("ij,ij->i", s1, s2), np.einsum("ij,ij->i", s2, s2)
        det_g = g11 * g22 - g12 * g12
        root_g = np.sqrt(np.maximum(det_g, 0.0))

        def squared_dilatation(p):
            e1, e2 = a - p, b - p
            with np.errstate(divide="ignore", invalid="ignore"):
                fro = (g22 * np.einsum("ij,ij->i", e1, e1) - 2 * g12 * np.einsum("ij,ij->i", e1, e2)
                       + g11 * np.einsum("ij,ij->i", e2, e2)) / det_g
                det = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) / root_g
                t = fro / det   # D' + 1 / D'
                d = 0.5 * (t + np.sqrt(np.maximum(t * t - 4, 0)))
            d[~np.isfinite(d)] = np.inf
            return float(np.sum(d * d))

        def worst(p):
            if np.min(dist(p)) <= 0.05 * depth:
                return np.inf
            return squared_dilatation(p)
        # From the kernel's deepest point, the position of least distortion of the star (the sum of
        # the squared D', infinite at the kernel's shrunk sides): the harmonic position itself has
        # folded, and the least move out of the fold leaves a sliver (D' 20-45 measured).
        with np.errstate(invalid="ignore"):     # inf - inf where the simplex leaves the kernel
            best = minimize(worst, centre, method="Nelder-Mead",
                            options={"initial_simplex": [centre, centre + [0.5 * depth, 0], centre + [0, 0.5 * depth]],
                                     "xatol": 1e-3 * depth, "fatol": 1e-6, "maxiter": 400})
        if improve:
            now = squared_dilatation(np.zeros(2))
            if not (np.isfinite(best.fun) and best.fun < 0.99 * now):
                return False
        candidates = [best.x if np.isfinite(best.fun) else centre]
        if not improve:
            # A folded corner: the centre, then points spread over the shrunk kernel, least distorted
            # first. Where the target's normals turn strongly across the star's images (a saddle of
            # the double torus), the pipeline's test (faces unfolded from a corner's face) can
            # still read a face as turned at the chart's best point and centre, and not elsewhere
            # in the kernel (double_torus_2 A -> B's inverse: its one face left folded unfolds at
            # such a point).
            ring = [centre + r * depth * np.array([np.cos(t), np.sin(t)])
                    for r in kernel_radii for t in np.linspace(0, 2 * np.pi, kernel_directions, endpoint=False)]
            ring = [p for p in ring if np.min(dist(p)) > 0.05 * depth]
            candidates += [centre] + [ring[k] for k in np.argsort([worst(p) for p in ring], kind="stable")]
        for p in candidates:
            got = place(o + p)
            # An interior vertex stays inside: a fold's corner at least a tenth of its distance to the
            # boundary away from it (the shirt's collar apex has to go nearer), an unfolded one at
            # least half (else the least distorted point can be on the boundary itself).
            if got is None or boundary_distance(got[2]) < (0.5 if improve else 0.1) * boundary_distance(fw["position"][v]):
                continue
            old = (fw["face"][v], fw["barycentric"][v].copy(), fw["position"][v].copy())
            fw["face"][v], fw["barycentric"][v], fw["position"][v] = got
            if not np.any(turned_of(star) & ~ear[star]):
                return True
            fw["face"][v], fw["barycentric"][v], fw["position"][v] = old
        return False

    def within(verts, rings):
        for _ in range(rings):
            verts = np.unique(S.F[np.concatenate([star_of(v) for v in verts])])
        return verts

    # Each pass moves the interior corners of the folded faces; when a pass leaves as many folded
    # faces as before (a corner's kernel is empty: its neighbours' images are cramped too), the
    # interior vertices within one more ring of them are first moved to their stars' least
    # distorted points (unfolded stars only, and only where that lowers the distortion), which
    # widens the folded corners' kernels, up to `max_rings` rings.
    rings, bad = 0, np.flatnonzero(turned_of(np.arange(len(S.F))) & ~ear)
    for _ in range(max_passes + max_rings):
        if len(bad) == 0:
            break
        corners = np.unique(S.F[bad])
        saved = ({k: np.array(fw[k], copy=True) for k in ("face", "barycentric", "position")}, len(moved))
        if rings:
            for v in within(corners, rings):
                if not on_b[v] and try_move(int(v), improve=True):
                    moved.append(int(v))
        for v in corners:
            if not on_b[v] and try_move(int(v)):
                moved.append(int(v))
        now = np.flatnonzero(turned_of(np.arange(len(S.F))) & ~ear)
        if len(now) >= len(bad):
            # Nothing gained: the pass is undone (no vertex moves without unfolding something).
            for k, x in saved[0].items():
                fw[k][...] = x
            del moved[saved[1]:]
            rings += 1
            if rings > max_rings:
                break
            continue
        bad = now
    # Folds that no vertex alone can clear: every corner's kernel is empty because its neighbours'
    # images are folded too (poncho -> spot: 4 faces next to a 306-degree corner of one of spot's
    # rims, 8 corners, every kernel empty; docs/history/open_surfaces.md "Session 26: poncho"). Each
    # cluster of such faces is untangled jointly: the interior vertices within k rings of its
    # corners (k = 1 .. patch_rings) moved together in the target's chart (_patch_untangle), the
    # ring around them held.
    patch_rings = PATCH_RINGS if patch_rings is None else patch_rings

    def joint(slide_rim=False):
        bad = np.flatnonzero(turned_of(np.arange(len(S.F))) & ~ear)
        if len(bad) and patch_rings:
            for cluster in _clusters(S.F, bad):
                corners = np.unique(S.F[cluster])
                for k in range(1, patch_rings + 1):
                    free = within(corners, k)
                    sliding = free[on_b[free]] if slide_rim else ()
                    free = free[~on_b[free]]
                    if (not slide_rim or len(sliding)) and _patch_untangle(
                            S, T, fw, free, star_of, turned_of, ear, unit, tf, sign, crease_angle, sliding):
                        moved.extend(int(v) for v in np.concatenate([free, sliding]))
                        break
    joint()
    # Folds held by the boundary's images (no interior vertex can unfold a face whose boundary
    # corners' images cut across a reflex corner of the other rim): those corners slid along the
    # target's loop between their loop neighbours' images, then the joint step again.
    bad = np.flatnonzero(turned_of(np.arange(len(S.F))) & ~ear)
    if len(bad) and boundary_slides:
        slid = _slide_boundary_corners(S, T, fw, turned_of, ear, bad, on_b, star_of)
        if slid:
            moved.extend(slid)
            joint()
        # Folds whose patch positions fall beyond the rim (the untangled positions land in the
        # target's hole): the boundary vertices within the patch's rings slide along the rim with
        # the interior ones, in the same joint step (_rim_sliders).
        joint(slide_rim=True)
    # The moved vertices' stars were made unfolded by the least distorted point of each star given
    # its neighbours, one vertex at a time, so a star next to a moved one can be left far more
    # distorted than before (a valence-4 corner's faces at D' 22-29 on the double torus, from
    # 10-16): `relax_sweeps` sweeps of the same least-distortion move over the moved vertices and
    # their neighbours, each kept only where it lowers its star's distortion and folds nothing.
    if moved:
        patch = within(np.unique(moved), 1)
        for _ in range(relax_sweeps):
            for v in patch:
                if not on_b[v] and try_move(int(v), improve=True):
                    moved.append(int(v))
        # The sweeps widen the room around folds still left: the rim-sliding joint step once more
        # (spot -> poncho's full run left poncho face 3842 folded; a second pass over its delivered
        # inverse clears it; docs/open_surfaces.md "The half's solve").
        if boundary_slides and np.any(turned_of(np.arange(len(S.F))) & ~ear):
            joint(slide_rim=True)
    return sorted(set(moved))
