"""The morph (no bpy): the matrix placing the other object's shape, and the connectivity
refinement of the source for a morph that follows the target's detail (docs/method.md §2.12)."""
import numpy as np


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
    (docs/method.md §2.12): source edges whose image is long (|f(v_i) − f(v_j)| > max_length) or bends
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


def morph_matrix(from_matrix, to_matrix, space):
    """4x4 taking the other object's local coordinates into this object's local coordinates.
    'WORLD': onto the other object where it stands; 'IN_PLACE': the other object's shape
    (rotation and scale included) placed at this object's origin, so the morph stays in place."""
    A = np.asarray(from_matrix, dtype=np.float64)   # the other object's world matrix
    B = np.asarray(to_matrix, dtype=np.float64)     # this object's world matrix
    shift = np.eye(4)
    if space == "IN_PLACE":
        shift[:3, 3] = B[:3, 3] - A[:3, 3]
    return np.linalg.inv(B) @ shift @ A
