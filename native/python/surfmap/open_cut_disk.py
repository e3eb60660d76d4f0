"""The symmetric class of an open pair of genus 0 from its boundary pairing alone (issue 16;
docs/open_surfaces.md, "Doubling", step 2): a homeomorphism of the halves built from their topology,
not from a geometric rough map.

Each half (genus 0, b >= 2 loops) is cut into a disk along a chain of b - 1 vertex-disjoint shortest
paths: loop c_0 to loop c_1, c_1 to c_2, ... (the source's chain 0, 1, ..., b - 1; the target's the
paired loops pairing[0], pairing[1], ...). The disk's boundary is 4(b - 1) runs (each path twice, the
end loops once, the middle loops in two arcs) in an order fixed by the chain, so source run r
corresponds to target run r. Both disks are laid out by Tutte's embedding (uniform weights) with run r
on the same arc of the unit circle (by arc length within the run); for positive weights and a
strictly convex boundary the embedding is bijective (a Tutte-type theorem), so composing the source's with
the inverse of the target's is a homeomorphism of the halves sending loop i onto loop pairing[i]. Its
class is the one the doubles need: for b <= 3 the only one with that pairing and orientation (the
mapping class group of a pair of pants with free boundary is finite, and its elements permute the
loops), for b >= 4 the one in which the chains' shortest arcs correspond.

Why not the rough geometric maps: the Möbius map of the capped spheres holds three cap centres, not
the caps, and a map of the capped spheres holding every centre folds once the holes move far; moved
onto the target's vertices, their images carried loops that were not an isomorphism (the poncho onto
its bend 0.3, the artery onto its bend 0.2).
"""
import numpy as np

from . import _core


def _edges(F):
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    E = np.sort(E, axis=1)
    return np.unique(E, axis=0)


def _chain_paths(V, F, loops, chain):
    """b - 1 vertex-disjoint shortest paths, path k from loop chain[k] to loop chain[k + 1], through
    interior vertices; a path leaves loop chain[k] at another vertex than the previous path reached
    it. Raises SolveError when a path does not exist."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import dijkstra
    n = len(V)
    E = _edges(F)
    L = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    free = np.ones(n, dtype=bool)          # interior vertices no path uses yet
    for loop in loops:
        free[loop] = False
    paths, arrived = [], -1
    for k in range(len(chain) - 1):
        sources = np.array([v for v in loops[chain[k]] if v != arrived], dtype=np.int64)
        targets = np.asarray(loops[chain[k + 1]], dtype=np.int64)
        # Edges with one free end (or two), the other free, a source or a target: never along a
        # loop, never through another loop or an earlier path.
        ends = free.copy()
        ends[sources] = True
        ends[targets] = True
        use = ends[E[:, 0]] & ends[E[:, 1]] & (free[E[:, 0]] | free[E[:, 1]])
        G = sp.coo_matrix((L[use], (E[use, 0], E[use, 1])), shape=(n, n)).tocsr()
        dist, prev, _ = dijkstra(G, directed=False, indices=sources, min_only=True, return_predecessors=True)
        end = int(targets[np.argmin(dist[targets])])
        if not np.isfinite(dist[end]):
            raise _core.SolveError(f"cut into a disk: no path from boundary loop {chain[k]} to loop {chain[k + 1]} "
                                   f"through interior vertices")
        path = [end]
        while prev[path[-1]] >= 0:
            path.append(int(prev[path[-1]]))
        path = path[::-1]
        if len(path) < 3:
            raise _core.SolveError(f"cut into a disk: loops {chain[k]} and {chain[k + 1]} share an edge")
        free[path] = False
        arrived = path[-1]
        paths.append(path)
    return paths


def _cut(F, n, cut_edges):
    """The mesh cut open along `cut_edges` (a set of sorted vertex pairs): each vertex split into one
    copy per wedge of its faces between cut or boundary edges (the corners joined across every other
    edge). Returns (faces of the copies (m,3), original vertex of each copy)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components
    m = len(F)
    # Half-edge 3 f + k runs F[f, k] -> F[f, k + 1]; its twin runs back in the neighbouring face.
    a, b = F.reshape(-1), np.roll(F, -1, axis=1).reshape(-1)
    key = a * n + b
    order = np.argsort(key)
    sorted_key = key[order]
    twin_key = b * n + a
    at = np.minimum(np.searchsorted(sorted_key, twin_key), len(key) - 1)
    has_twin = sorted_key[at] == twin_key
    twin = np.where(has_twin, order[at], -1)
    cut_key = np.array(sorted(u * n + w for u, w in cut_edges), dtype=np.int64)
    is_cut = np.isin(np.minimum(a, b) * n + np.maximum(a, b), cut_key)
    h = np.flatnonzero(has_twin & ~is_cut & (a < b))
    g = twin[h]
    f_h, k_h, f_g, k_g = h // 3, h % 3, g // 3, g % 3
    # u = corner k of f = corner k + 1 of g; w = corner k + 1 of f = corner k of g.
    rows = np.r_[3 * f_h + k_h, 3 * f_h + (k_h + 1) % 3]
    cols = np.r_[3 * f_g + (k_g + 1) % 3, 3 * f_g + k_g]
    A = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(3 * m, 3 * m))
    _, copy = connected_components(A, directed=False)
    copies = copy.reshape(m, 3)
    original = np.empty(copy.max() + 1, dtype=np.int64)
    original[copies.reshape(-1)] = F.reshape(-1)
    return copies, original


def _boundary_walk(Fc):
    """The boundary of a disk (faces Fc) as a vertex cycle, surface on the left."""
    n = int(Fc.max()) + 1
    a, b = Fc.reshape(-1), np.roll(Fc, -1, axis=1).reshape(-1)
    on_boundary = ~np.isin(a * n + b, b * n + a)
    u, w = a[on_boundary], b[on_boundary]
    if len(np.unique(u)) != len(u):
        raise _core.SolveError("cut into a disk: the cut mesh's boundary is not one simple loop")
    nxt = -np.ones(n, dtype=np.int64)
    nxt[u] = w
    start = int(u.min())
    walk = [start]
    while int(nxt[walk[-1]]) != start and len(walk) <= len(u):
        walk.append(int(nxt[walk[-1]]))
    if len(walk) != len(u):
        raise _core.SolveError("cut into a disk: the cut mesh has more than one boundary loop")
    return walk


def _runs(walk, original, edge_label):
    """The boundary walk split into runs of equal label, rotated to start right after the run of
    chain[0]'s loop (the one loop run that is a whole loop and has label ('L', 0) in chain order).
    Returns [(label, [copy vertices of the run, its first and last included])]."""
    labels = [edge_label[tuple(sorted((int(original[walk[i]]), int(original[walk[(i + 1) % len(walk)]]))))]
              for i in range(len(walk))]
    starts = [i for i in range(len(walk)) if labels[i] != labels[i - 1]]
    if not starts:
        raise _core.SolveError("cut into a disk: the boundary has one label only")
    runs = []
    for a, s in enumerate(starts):
        e = starts[(a + 1) % len(starts)]
        count = (e - s) % len(walk) or len(walk)
        runs.append((labels[s], [walk[(s + i) % len(walk)] for i in range(count + 1)]))
    first = [i for i, (lab, _) in enumerate(runs) if lab == ("L", 0)]
    if len(first) != 1:
        raise _core.SolveError("cut into a disk: the first loop of the chain is not one run")
    return runs[first[0] + 1:] + runs[:first[0] + 1]


def _tutte(Fc, n_copies, boundary, boundary_xy):
    """Tutte's embedding (uniform weights) of the disk with the boundary copies fixed at
    boundary_xy: (n_copies, 2)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    E = _edges(Fc)
    A = sp.coo_matrix((np.ones(2 * len(E)), (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])),
                      shape=(n_copies, n_copies)).tocsr()
    A.data[:] = 1.0
    deg = np.asarray(A.sum(axis=1)).ravel()
    Lap = (sp.diags(deg) - A).tocsr()
    fixed = np.zeros(n_copies, dtype=bool)
    fixed[boundary] = True
    X = np.zeros((n_copies, 2))
    X[boundary] = boundary_xy
    free = np.flatnonzero(~fixed)
    if len(free):
        rhs = -Lap[free][:, np.flatnonzero(fixed)] @ X[fixed]
        K = Lap[free][:, free].tocsr()
        for c in range(2):
            # Symmetric positive definite (every free vertex connects to the fixed boundary):
            # conjugate gradients from the boundary's centre, far cheaper than a factorization here.
            try:
                x, info = spla.cg(K, rhs[:, c], rtol=1e-10, atol=0.0, maxiter=20 * len(free))
            except TypeError:  # scipy < 1.12 names it tol
                x, info = spla.cg(K, rhs[:, c], tol=1e-10, atol=0.0, maxiter=20 * len(free))
            X[free, c] = x if info == 0 else spla.spsolve(K.tocsc(), rhs[:, c])
    return X


class _CutDisk:
    """One half cut into a disk along its chain and laid out by Tutte's embedding."""

    def __init__(self, V, F, loops, chain):
        b = len(loops)
        if b < 2:
            raise _core.SolveError("cut into a disk: needs two or more boundary loops")
        paths = _chain_paths(V, F, loops, chain)
        label = {}
        loop_rank = {loop_index: rank for rank, loop_index in enumerate(chain)}
        for loop_index, loop in enumerate(loops):
            for i in range(len(loop)):
                label[tuple(sorted((int(loop[i]), int(loop[(i + 1) % len(loop)]))))] = ("L", loop_rank[loop_index])
        cut = set()
        for k, path in enumerate(paths):
            for u, w in zip(path[:-1], path[1:]):
                e = (min(u, w), max(u, w))
                cut.add(e)
                label[e] = ("P", k)
        self.F, self.original = _cut(np.asarray(F, dtype=np.int64), len(V), cut)
        walk = _boundary_walk(self.F)
        self.runs = _runs(walk, self.original, label)
        if len(self.runs) != 4 * (b - 1):
            raise _core.SolveError(f"cut into a disk: {len(self.runs)} boundary runs, expected {4 * (b - 1)}")
        self.V = V
        self.labels = [lab for lab, _ in self.runs]

    def layout(self):
        """Run r on the arc [2 pi r / R, 2 pi (r + 1) / R] of the unit circle, by arc length."""
        R = len(self.runs)
        boundary, angle, run_of, frac = [], [], [], []
        for r, (_, verts) in enumerate(self.runs):
            P = self.V[self.original[verts]]
            s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
            t = s / s[-1] if s[-1] > 0 else np.linspace(0, 1, len(s))
            for v, tv in zip(verts[:-1], t[:-1]):   # each run's last vertex is the next run's first
                boundary.append(v)
                angle.append(2 * np.pi * (r + tv) / R)
                run_of.append(r)
                frac.append(tv)
        boundary = np.array(boundary)
        xy = np.column_stack([np.cos(angle), np.sin(angle)])
        self.boundary, self.boundary_run, self.boundary_frac = boundary, np.array(run_of), np.array(frac)
        self.X = _tutte(self.F, len(self.original), boundary, xy)
        return self.X


def cut_disk_class_images(S, T, pairing, mirrored=False, chain=None):
    """Per vertex of the source's split half (S.V2, n2 of them) a vertex of the target's split half
    (T.V2) under the homeomorphism of the cut disks (module docstring): source loop i onto target
    loop pairing[i]; `mirrored`: orientation reversing (the target's half with its faces reversed);
    `chain`: the order in which the source's loops are chained (default 0, 1, ..., b - 1; the
    target's follows through the pairing). For b >= 4 another chain can give another class of the
    same pairing (its shortest arcs correspond instead). S, T: open_double._Side of genus 0. Raises
    SolveError when a half cannot be cut or the disks' runs do not correspond."""
    try:
        import scipy.sparse  # noqa: F401  (sparse graphs and solves; Blender's own Python may lack it)
    except ImportError:
        raise _core.SolveError("cut into a disk: scipy is not available") from None
    chain_s = list(range(S.b)) if chain is None else [int(c) for c in chain]
    chain_t = [int(pairing[i]) for i in chain_s]
    Ft = T.F2[:, ::-1] if mirrored else T.F2
    ds = _CutDisk(S.V2, S.F2, S.loops, chain_s)
    dt = _CutDisk(T.V2, Ft, T.loops, chain_t)
    if ds.labels != dt.labels:
        raise _core.SolveError(f"cut into a disk: the boundary runs differ ({ds.labels} / {dt.labels})")
    Xs, Xt = ds.layout(), dt.layout()
    from scipy.spatial import cKDTree
    image_copy = np.empty(len(ds.original), dtype=np.int64)
    # Boundary copies: the target copy of the same run at the nearest arc-length fraction.
    for r in range(len(ds.runs)):
        s_sel = np.flatnonzero(ds.boundary_run == r)
        t_sel = np.flatnonzero(dt.boundary_run == r)
        j = np.abs(ds.boundary_frac[s_sel][:, None] - dt.boundary_frac[t_sel][None, :]).argmin(axis=1)
        image_copy[ds.boundary[s_sel]] = dt.boundary[t_sel[j]]
    # Interior copies: the target copy nearest in the common disk.
    on_b = np.zeros(len(ds.original), dtype=bool)
    on_b[ds.boundary] = True
    inner = np.flatnonzero(~on_b)
    if len(inner):
        # Nearest among all target copies (a source point near the rim may be nearest a boundary one).
        image_copy[inner] = cKDTree(Xt).query(Xs[inner])[1]
    target_vertex = np.empty(S.n2, dtype=np.int64)
    target_vertex[ds.original] = dt.original[image_copy]
    return target_vertex
