"""EXPERIMENTAL: open surfaces of any (g, b) through their doubles (issue 16; docs/open_surfaces.md,
"Doubling"). Not reliable yet: the closed genus >= 2 pipeline sometimes fails on the thin
double (its Ricci flow on the coincident sheets) or misses the identity class when the pose is
strong; use it for experiments only.

A surface M of genus g with b >= 1 boundary loops is doubled along its boundary: a mirror copy
with reversed faces glued to M along the boundary vertices is a closed surface of genus
2g + b - 1 with the orientation-reversing reflection sigma (swap the copies, fix the boundary).
Two open surfaces of equal (g, b) are mapped through their doubles with the closed pipeline
(surfmap.surface_map); the unique harmonic map in a class that commutes with the reflections is
symmetric, f(sigma_S x) = sigma_T f(x), and maps the boundary onto the boundary. A class is
accepted when the map is symmetric within `symmetry_tolerance` and maps the source's half onto
the target's half (the other symmetric classes send it onto the mirror half: orientation
reversing on the halves); candidates are tried in energy order. One half is kept.

Before doubling, every interior edge joining two boundary vertices is split at its midpoint
(the double would otherwise have edges with four faces); the mirror sheet is moved inward by
1e-6 of the bounding diagonal along the vertex normals so that the double has positive volume
(the intake orients closed surfaces by the sign of their volume).
"""
import numpy as np

from . import _core


def boundary_loops(V, F):
    """The boundary loops (vertex index arrays, longest first) of an open mesh; raises InputError."""
    return [np.asarray(l, dtype=np.int64) for l in _core.intake(V, F, allow_boundary=True)["boundary_loops"]]


def split_boundary_chords(V, F):
    """Splits every interior edge whose two ends lie on the boundary at its midpoint.

    V (n,3), F (m,3). Returns (V2 (n+k,3), F2 (m+2k,3), parent (m+2k,) the input face each new face
    lies in). The first n vertices are the input's."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    on_b = np.zeros(len(V), dtype=bool)
    bedges = set()
    for loop in boundary_loops(V, F):
        on_b[loop] = True
        for i in range(len(loop)):
            bedges.add((min(loop[i], loop[(i + 1) % len(loop)]), max(loop[i], loop[(i + 1) % len(loop)])))
    faces = [(list(f), i) for i, f in enumerate(F)]
    verts = list(V)
    midpoint = {}
    # Repeat until no chord is left (a face may have two chords: split one per pass).
    while True:
        out, changed = [], False
        for f, parent in faces:
            for k in range(3):
                u, w = f[k], f[(k + 1) % 3]
                e = (min(u, w), max(u, w))
                if e in bedges or not (on_b[u] and on_b[w]) and e not in midpoint:
                    continue
                if e not in midpoint:
                    midpoint[e] = len(verts)
                    verts.append(0.5 * (verts[u] + verts[w]))
                m, c = midpoint[e], f[(k + 2) % 3]
                out += [([u, m, c], parent), ([m, w, c], parent)]
                changed = True
                break
            else:
                out.append((f, parent))
        faces = out
        on_b = np.concatenate([on_b, np.zeros(len(verts) - len(on_b), dtype=bool)])
        if not changed:
            break
    return (np.array(verts), np.array([f for f, _ in faces], dtype=np.int64),
            np.array([p for _, p in faces], dtype=np.int64))


def double_surface(V, F):
    """The double of an open mesh without boundary chords (split_boundary_chords first).

    Returns a dict: V (n+i,3), F (2m,3) (faces m.. are the mirror copies of faces 0.., corners
    reversed), sigma (n+i,) the reflection as a vertex permutation (fixing the boundary),
    boundary_loops, half_faces m."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    loops = boundary_loops(V, F)
    on_b = np.zeros(len(V), dtype=bool)
    for loop in loops:
        on_b[loop] = True
    interior = np.flatnonzero(~on_b)
    mirror = np.arange(len(V))
    mirror[interior] = len(V) + np.arange(len(interior))
    N = np.zeros_like(V)
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for k in range(3):
        np.add.at(N, F[:, k], fn)
    N /= np.maximum(np.linalg.norm(N, axis=1), 1e-300)[:, None]
    eps = 1e-6 * np.linalg.norm(V.max(axis=0) - V.min(axis=0))
    V2 = np.vstack([V, V[interior] - eps * N[interior]])
    F2 = np.vstack([F, mirror[F][:, ::-1]])
    sigma = np.arange(len(V2))
    sigma[interior], sigma[mirror[interior]] = mirror[interior], interior
    return {"V": V2, "F": F2, "sigma": sigma, "boundary_loops": loops, "half_faces": len(F)}


def _to_half(face, bary, half_faces):
    """Points on a double (face, bary) reflected onto the first copy."""
    face = np.asarray(face, dtype=np.int64).copy()
    bary = np.asarray(bary, dtype=np.float64).copy()
    m = face >= half_faces
    face[m] -= half_faces
    bary[m] = bary[m][:, ::-1]   # the mirror face lists the corners in reverse order
    return face, bary


def _symmetry(res, Ds, n_half_vertices):
    """(max symmetry error over the diagonal, fraction of interior source vertices whose image
    lies on the target's first copy) of a map between doubles."""
    pos = np.asarray(res["forward"]["position"])
    face = np.asarray(res["forward"]["face"])
    sig = Ds["sigma"]
    diag = np.linalg.norm(pos.max(axis=0) - pos.min(axis=0))
    err = np.linalg.norm(pos[sig] - pos, axis=1).max() / diag   # sigma_T moves points by ~1e-6 only
    interior = np.flatnonzero(sig[:n_half_vertices] != np.arange(n_half_vertices))
    return float(err), float(np.mean(face[interior] < Ds.get("target_half_faces", Ds["half_faces"])))


def _snap_to_boundary(P, Vt, Ft, loops):
    """(face, bary, position, loop index) of the nearest point of the boundary polylines."""
    edge_face = {}
    for f, tri in enumerate(Ft):
        for k in range(3):
            edge_face[(tri[k], tri[(k + 1) % 3])] = (f, k)
    segs = [(loop[i], loop[(i + 1) % len(loop)], li) for li, loop in enumerate(loops) for i in range(len(loop))]
    A = Vt[[s[0] for s in segs]]
    B = Vt[[s[1] for s in segs]]
    out_f, out_b, out_p, out_l = [], [], [], []
    for p in P:
        d = B - A
        t = np.clip(np.einsum("ij,ij->i", p - A, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
        q = A + t[:, None] * d
        j = int(np.argmin(np.linalg.norm(q - p, axis=1)))
        u, w, li = segs[j]
        f, k = edge_face.get((u, w)) or edge_face[(w, u)]
        bary = np.zeros(3)
        tri = list(Ft[f])
        bary[tri.index(u)] += 1 - t[j]
        bary[tri.index(w)] += t[j]
        out_f.append(f), out_b.append(bary), out_p.append(q[j]), out_l.append(li)
    return np.array(out_f), np.array(out_b), np.array(out_p), np.array(out_l)


def map_by_doubling(Vs, Fs, Vt, Ft, symmetry_tolerance=0.02, same_sheet=0.9, max_classes=4, **options):
    """EXPERIMENTAL map between two open surfaces of equal (g, b) through their doubles.

    Returns a dict: forward {face, barycentric, position} per source vertex on the target's input
    faces (boundary vertices on the target's boundary), boundary_pairing (target loop of each source
    loop), symmetry_error, same_sheet, chosen (handle class index of the doubles' map), tried
    [(class, energy, symmetry_error, same_sheet)], double_genus, flipped_triangles (source faces,
    ears excepted, whose image turns against the target's normal), ear_triangles (faces with all
    corners on the boundary), ear_triangles_turned, snap_distance (largest move of a boundary
    vertex's image onto the target's boundary), the doubles' result under 'double'.
    Raises InputError for different (g, b), SolveError when no tried class is symmetric."""
    Vs, Vt = np.asarray(Vs, dtype=np.float64), np.asarray(Vt, dtype=np.float64)
    Fs, Ft = np.asarray(Fs, dtype=np.int64), np.asarray(Ft, dtype=np.int64)
    src_it = _core.intake(Vs, Fs, allow_boundary=True)
    tgt_it = _core.intake(Vt, Ft, allow_boundary=True)
    gs, bs = src_it["info"]["genus"], len(src_it["boundary_loops"])
    gt, bt = tgt_it["info"]["genus"], len(tgt_it["boundary_loops"])
    if (gs, bs) != (gt, bt) or bs == 0:
        raise _core.InputError(f"doubling: the source has genus {gs} with {bs} boundary loop(s) but the "
                               f"target has genus {gt} with {bt}; both must be open with the same (g, b)")
    Vs2, Fs2, _ = split_boundary_chords(Vs, Fs)
    Vt2, Ft2, t_parent = split_boundary_chords(Vt, Ft)
    Ds, Dt = double_surface(Vs2, Fs2), double_surface(Vt2, Ft2)
    Ds["target_half_faces"] = Dt["half_faces"]
    res = _core.surface_map(Ds["V"], Ds["F"], Dt["V"], Dt["F"], **options)
    energies = [(c["energy"] if c["solved"] else np.inf, i) for i, c in enumerate(res["homotopy"]["candidates"])]
    order = [res["homotopy"]["chosen"]] + [i for _, i in sorted(energies) if i != res["homotopy"]["chosen"]]
    tried, chosen = [], None
    for i in order[:max_classes]:
        r = res if i == res["homotopy"]["chosen"] else _core.surface_map(Ds["V"], Ds["F"], Dt["V"], Dt["F"],
                                                                         homotopy=i, **options)
        err, sheet = _symmetry(r, Ds, len(Vs2))
        tried.append((i, float(r["energy"]["final"]), err, sheet))
        if err <= symmetry_tolerance and sheet >= same_sheet:
            chosen, res = i, r
            break
    if chosen is None:
        raise _core.SolveError("doubling: no symmetric, half-preserving class among the "
                               + ", ".join(f"{i} (E {e:.4g}, symmetry {s:.3g}, same half {h:.2f})" for i, e, s, h in tried))
    n = len(Vs)
    face, bary = _to_half(res["forward"]["face"][:n], res["forward"]["barycentric"][:n], Dt["half_faces"])
    # On the split target: positions, then the input face each lies in.
    pos = np.einsum("ij,ijk->ik", bary, Vt2[Ft2[face]])
    face_in = t_parent[face]
    # Boundary vertices onto the target's boundary (the symmetric map puts them there up to the
    # tolerance; snapping makes it exact).
    s_loops = src_it["boundary_loops"]
    t_loops = tgt_it["boundary_loops"]
    on_b = np.concatenate([np.asarray(l) for l in s_loops])
    sf, sb, sp, sl = _snap_to_boundary(pos[on_b], Vt, Ft, t_loops)
    snap_distance = float(np.linalg.norm(sp - pos[on_b], axis=1).max())
    pos[on_b] = sp
    # Barycentrics in the input faces (planar sub-triangles: exact up to round-off).
    out_b = np.empty((n, 3))
    for v in range(n):
        a, b, c = Vt[Ft[face_in[v]]]
        M = np.stack([b - a, c - a], axis=1)
        st = np.linalg.lstsq(M, pos[v] - a, rcond=None)[0]
        out_b[v] = np.clip([1 - st.sum(), st[0], st[1]], 0, 1)
        out_b[v] /= out_b[v].sum()
    face_in[on_b], out_b[on_b] = sf, sb
    pairing = []
    start = 0
    for l in s_loops:
        votes = sl[start:start + len(l)]
        start += len(l)
        pairing.append(int(np.bincount(votes).argmax()))
    # Flips: the image triangle against the target's normal at its first corner. Ears (source
    # faces with all three corners on the boundary) take three points of the target's boundary
    # (their inner edge was split in the double): counted apart, as in map/open_map.h.
    nt = np.cross(Vt[Ft[:, 1]] - Vt[Ft[:, 0]], Vt[Ft[:, 2]] - Vt[Ft[:, 0]])
    q = pos[Fs]
    img_n = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    turned = np.einsum("ij,ij->i", img_n, nt[face_in[Fs[:, 0]]]) < 0
    src_on_b = np.zeros(n, dtype=bool)
    src_on_b[on_b] = True
    ear = np.all(src_on_b[Fs], axis=1)
    flipped = int(np.sum(turned & ~ear))
    return {"forward": {"face": face_in, "barycentric": out_b, "position": pos},
            "boundary_pairing": pairing, "symmetry_error": tried[-1][2], "same_sheet": tried[-1][3],
            "snap_distance": snap_distance, "chosen": chosen, "tried": tried,
            "double_genus": int(res["genus"]), "flipped_triangles": flipped, "double": res,
            "ear_triangles": int(ear.sum()), "ear_triangles_turned": int(np.sum(turned & ear)),
            "genus": gs, "boundary_loops": bs}
