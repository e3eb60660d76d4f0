"""Plain geometry of triangle meshes (no bpy): points given as (face, barycentrics), normals,
areas, affine matrices. Conventions used by every bpy-free module of the add-on:
  V (n,3) float64 vertices, F (m,3) int triangles (the triangulation the map was computed on);
  a "point on a surface" is (face index into F, barycentric weights (3,)) as returned by
  surfmap.surface_map ('forward': per source vertex on the target, 'inverse': per target vertex
  on the source).
"""
import math

import numpy as np


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
