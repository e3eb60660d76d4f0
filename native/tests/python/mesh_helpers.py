"""Mesh helpers shared by the Python tests and bench/bench_landmark_reach.py (not a test file):
grid tori, vertex adjacency, shortest edge paths, nearest vertices, mean edge length."""
import collections
import math

import numpy as np


def torus(R, r, n, m, shift=0, alternate=True):
    """Torus of revolution, n x m grid, outward oriented, quads split along alternating
    diagonals (alternate=False: all along the same one; shift varies the connectivity and
    offsets the minor angle by half a step per unit)."""
    u, v = np.meshgrid(np.arange(n) * 2 * math.pi / n, (np.arange(m) + 0.5 * shift) * 2 * math.pi / m, indexing="ij")
    V = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u), r * np.sin(v)], -1).reshape(-1, 3)
    F = []
    for i in range(n):
        for j in range(m):
            a, b = i * m + j, ((i + 1) % n) * m + j
            c, d = ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m
            F += [[a, b, c], [a, c, d]] if not alternate or (i + j + shift) % 2 == 0 else [[a, b, d], [b, c, d]]
    return V, np.array(F)


def adjacency(F, n):
    """Per vertex, the set of its neighbours along the faces' edges."""
    nb = [set() for _ in range(n)]
    for f in np.asarray(F):
        for k in range(3):
            a, b = int(f[k]), int(f[(k + 1) % 3])
            nb[a].add(b)
            nb[b].add(a)
    return nb


def shortest_path(nb, a, b):
    """Vertices of a shortest edge path from a to b (breadth first), a first."""
    prev = {a: -1}
    queue = collections.deque([a])
    while queue:
        u = queue.popleft()
        if u == b:
            break
        for v in nb[u]:
            if v not in prev:
                prev[v] = u
                queue.append(v)
    path = [b]
    while prev[path[-1]] != -1:
        path.append(prev[path[-1]])
    return path[::-1]


def nearest_vertex(V, p):
    """Index of the row of V nearest to the point p."""
    return int(np.argmin(((np.asarray(V) - p) ** 2).sum(1)))


def mean_edge_length(V, F):
    V, F = np.asarray(V), np.asarray(F)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean())
