"""The symmetric class of an open pair of genus 0 from its boundary pairing alone (issue 16;
docs/open_surfaces.md, "Doubling", step 2): a homeomorphism of the halves built from their topology,
not from a geometric rough map.

Each half (genus 0, b >= 2 loops) is cut into a disk along a chain of b - 1 vertex-disjoint shortest
paths: loop c_0 to loop c_1, c_1 to c_2, ... (the source's chain 0, 1, ..., b - 1; the target's the
paired loops pairing[0], pairing[1], ...). The disk's boundary is 4(b - 1) runs (each path twice, the
end loops once, the middle loops in two arcs) in an order fixed by the chain, so source run r
corresponds to target run r. Both disks are laid out by Tutte's embedding (uniform weights) with run r
on the same arc of the unit circle (by arc length within the run); for positive weights and a
strictly convex boundary the embedding is bijective (Floater 2003), so composing the source's with
the inverse of the target's is a homeomorphism of the halves sending loop i onto loop pairing[i]. Its
class is the one the doubles need: for b <= 3 the only one with that pairing and orientation (the
mapping class group of a pair of pants with free boundary is finite, and its elements permute the
loops), for b >= 4 the one in which the chains' shortest arcs correspond.

Why not the rough geometric maps: the Möbius map of the capped spheres holds three cap centres, not
the caps, and a map of the capped spheres holding every centre folds once the holes move far; moved
onto the target's vertices, their images carried loops that were not an isomorphism (the poncho onto
its bend 0.3, the artery onto its bend 0.2).
"""
import heapq

import numpy as np

from . import _core


def _edges(F):
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    E = np.sort(E, axis=1)
    return np.unique(E, axis=0)


def _shortest_path(n, adjacency, lengths, sources, targets, allowed):
    """Dijkstra from any of `sources` to the nearest of `targets` through `allowed` vertices only
    (sources and targets themselves need not be allowed), never along an edge between two
    non-allowed vertices. Returns the vertex path (source first) or None."""
    dist = np.full(n, np.inf)
    prev = -np.ones(n, dtype=np.int64)
    is_target = np.zeros(n, dtype=bool)
    is_target[targets] = True
    heap = []
    for s in sources:
        dist[s] = 0.0
        heap.append((0.0, int(s)))
    heapq.heapify(heap)
    while heap:
        d, v = heapq.heappop(heap)
        if d > dist[v]:
            continue
        if is_target[v]:
            path = [v]
            while prev[path[-1]] >= 0:
                path.append(int(prev[path[-1]]))
            return path[::-1]
        for w, length in zip(adjacency[v], lengths[v]):
            if not (allowed[w] or is_target[w]) or not (allowed[v] or allowed[w]):
                continue
            if d + length < dist[w]:
                dist[w] = d + length
                prev[w] = v
                heapq.heappush(heap, (d + length, w))
    return None


def _chain_paths(V, F, loops, chain):
    """b - 1 vertex-disjoint shortest paths, path k from loop chain[k] to loop chain[k + 1], through
    interior vertices; a path leaves loop chain[k] at another vertex than the previous path reached
    it. Raises SolveError when a path does not exist."""
    n = len(V)
    E = _edges(F)
    L = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    adjacency = [[] for _ in range(n)]
    lengths = [[] for _ in range(n)]
    for (a, b), length in zip(E, L):
        adjacency[a].append(b)
        adjacency[b].append(a)
        lengths[a].append(length)
        lengths[b].append(length)
    allowed = np.ones(n, dtype=bool)
    for loop in loops:
        allowed[loop] = False
    paths, arrived = [], -1
    for k in range(len(chain) - 1):
        sources = [v for v in loops[chain[k]] if v != arrived]
        path = _shortest_path(n, adjacency, lengths, sources, loops[chain[k + 1]], allowed)
        if path is None or len(path) < 3:
            raise _core.SolveError(f"cut into a disk: no path from boundary loop {chain[k]} to loop {chain[k + 1]} "
                                   f"through interior vertices")
        allowed[path] = False
        arrived = path[-1]
        paths.append(path)
    return paths


def _cut(F, n, cut_edges):
    """The mesh cut open along `cut_edges` (a set of sorted vertex pairs): each vertex split into one
    copy per wedge of its faces between cut or boundary edges. Returns (faces of the copies (m,3),
    original vertex of each copy)."""
    m = len(F)
    parent = np.arange(3 * m)

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    halfedge = {}
    for f in range(m):
        for k in range(3):
            halfedge[(int(F[f, k]), int(F[f, (k + 1) % 3]))] = (f, k)
    for (u, w), (f, k) in halfedge.items():
        if u > w or (u, w) in cut_edges:
            continue
        other = halfedge.get((w, u))
        if other is None:
            continue
        g, j = other  # g runs w -> u: its corner j is w, j + 1 is u
        for a, b in (((f, k), (g, (j + 1) % 3)), ((f, (k + 1) % 3), (g, j))):
            ra, rb = find(3 * a[0] + a[1]), find(3 * b[0] + b[1])
            if ra != rb:
                parent[ra] = rb
    roots = np.array([find(x) for x in range(3 * m)])
    _, copy = np.unique(roots, return_inverse=True)
    copies = copy.reshape(m, 3)
    original = np.empty(copy.max() + 1, dtype=np.int64)
    original[copies.reshape(-1)] = F.reshape(-1)
    return copies, original


def _boundary_walk(Fc):
    """The boundary of a disk (faces Fc) as a vertex cycle, surface on the left."""
    nxt = {}
    inner = set()
    for f in Fc:
        for k in range(3):
            inner.add((int(f[k]), int(f[(k + 1) % 3])))
    for (u, w) in inner:
        if (w, u) not in inner:
            if u in nxt:
                raise _core.SolveError("cut into a disk: the cut mesh's boundary is not one simple loop")
            nxt[u] = w
    start = min(nxt)
    walk = [start]
    while nxt[walk[-1]] != start:
        walk.append(nxt[walk[-1]])
        if len(walk) > len(nxt):
            break
    if len(walk) != len(nxt):
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
        solve = spla.factorized(Lap[free][:, free].tocsc())
        X[free, 0] = solve(np.ascontiguousarray(rhs[:, 0]))
        X[free, 1] = solve(np.ascontiguousarray(rhs[:, 1]))
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


def cut_disk_class_images(S, T, pairing, mirrored=False):
    """Per vertex of the source's split half (S.V2, n2 of them) a vertex of the target's split half
    (T.V2) under the homeomorphism of the cut disks (module docstring): source loop i onto target
    loop pairing[i]; `mirrored`: orientation reversing (the target's half with its faces reversed).
    S, T: open_double._Side of genus 0. Raises SolveError when a half cannot be cut or the disks'
    runs do not correspond."""
    chain_s = list(range(S.b))
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
