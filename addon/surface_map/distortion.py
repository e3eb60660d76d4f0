"""How much a map distorts (no bpy): per-face dilatation D' (docs/method.md §2.11), the conformal
factor (docs/method.md §2.13), the scale-free mean curvature and its difference across the map, and
triangle values gathered per polygon."""
import math

import numpy as np

from .geometry import face_areas, vertex_normals


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
    """Per-face dilatation D' = Γ/γ (docs/method.md §2.11): the ratio of the singular values of the
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
    """Conformal factor λ per source vertex (docs/method.md §2.13): area of the image of its one-ring
    over the area of the one-ring, divided by the ratio of the total areas (so λ = 1 means 'as
    much area as on average'). Returns (n,)."""
    F = np.asarray(F_src, dtype=np.int64)
    a_s = face_areas(V_src, F)
    a_i = face_areas(image, F)
    n = len(V_src)
    ring_s = np.bincount(F.reshape(-1), np.repeat(a_s, 3), minlength=n)
    ring_i = np.bincount(F.reshape(-1), np.repeat(a_i, 3), minlength=n)
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
