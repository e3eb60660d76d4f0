"""Open surfaces of any genus g with b boundary loops through their doubles (issue 16;
docs/open_surfaces.md, "Doubling"). `surfmap.surface_map` (and so the CLI's `surfmap map` and the
add-on's Compute Map) calls `surface_map_open` for open pairs that are neither disks nor annuli.

A surface M of genus g with b >= 1 boundary loops is doubled along its boundary: a mirror copy with
reversed faces glued to M along the boundary vertices is a closed surface of genus 2g + b - 1 with
the orientation-reversing reflection sigma (swap the copies, fix the boundary). The harmonic map
between two doubles in a homotopy class that commutes with the reflections is symmetric,
f(sigma_S x) = sigma_T f(x) (sigma_T f sigma_S is harmonic in the same class, and the harmonic map of
a class is unique), so it maps the fixed curves, the boundary, onto the boundary and each half onto
one half: restricted to M it is the free-boundary harmonic map (the boundary slides along the
target's boundary).

The class is built BEFORE solving, symmetric by construction: both surfaces are capped (a fan over
each boundary loop: closed, genus g), the capped source is mapped onto the capped target by the
closed pipeline with the caps' centres as landmarks (source loop i's centre onto target loop
pairing[i]'s), and that map, moved onto the target's vertices (boundary vertices onto the paired
target loop) and mirrored on the mirror sheet, carries the double's loops: the closed pipeline then
solves that class alone (`homotopy_images`). The orientation-reversing version puts the images on
the target's mirror sheet instead. When no pairing is given and b >= 2, every pairing (b! of them,
at most `max_pairings`) is tried in both orientations and the lowest energy is kept; all energies
are reported. Beyond `max_pairings` pairings (b >= 4) the pairings and orientations are ranked by a
cheap score (loop lengths, distances between the loops along the surface; genus 0: the cap centres
under the capped spheres' Möbius map) and the best `max_pairings` of them are solved.

Before doubling, every interior edge joining two boundary vertices is split at its midpoint (the
double would otherwise have edges with four faces); the mirror sheet is moved inward by 1e-6 of the
bounding diagonal along the vertex normals so that the double has positive volume (the intake
orients closed surfaces by the sign of their volume).
"""
import heapq
import itertools
import json
import math
import sys

import numpy as np

from . import _core, open_cut_disk, open_reflection, open_untangle

#: (g, b) the conformal path of map/open_map.h maps (disk, annulus); every other open pair here.
CONFORMAL_TOPOLOGIES = {(0, 1), (0, 2)}


def boundary_loops(V, F):
    """The boundary loops (vertex index arrays, longest first) of an open mesh; raises InputError."""
    return [np.asarray(l, dtype=np.int64) for l in _core.intake(V, F, allow_boundary=True)["boundary_loops"]]


def split_boundary_chords(V, F, loops=None):
    """Splits every interior edge whose two ends lie on the boundary at its midpoint.

    V (n,3), F (m,3). Returns (V2 (n+k,3), F2 (m',3), parent (m',) the input face each new face lies
    in, midpoint_of (k,2) the input edge each new vertex halves). The first n vertices are the
    input's."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    on_b = np.zeros(len(V), dtype=bool)
    bedges = set()
    for loop in (boundary_loops(V, F) if loops is None else loops):
        on_b[loop] = True
        for i in range(len(loop)):
            bedges.add((min(loop[i], loop[(i + 1) % len(loop)]), max(loop[i], loop[(i + 1) % len(loop)])))
    faces = [(list(f), i) for i, f in enumerate(F)]
    verts = list(V)
    midpoint = {}
    # Repeat until no chord is left (a face may have two chords: split one per pass). Each chord
    # is an edge of the input, so every new vertex halves an input edge.
    while True:
        out, changed = [], False
        for f, parent in faces:
            for k in range(3):
                u, w = f[k], f[(k + 1) % 3]
                e = (min(u, w), max(u, w))
                if e in bedges or not (u < len(on_b) and w < len(on_b) and on_b[u] and on_b[w]):
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
        if not changed:
            break
    mid_of = np.zeros((len(verts) - len(V), 2), dtype=np.int64)
    for e, m in midpoint.items():
        mid_of[m - len(V)] = e
    return (np.array(verts), np.array([f for f, _ in faces], dtype=np.int64),
            np.array([p for _, p in faces], dtype=np.int64), mid_of)


def refine_near_boundary(V, F, loops, rings, split_boundary=False):
    """Splits at its midpoint every interior edge of the faces with a corner within `rings` - 1
    rings of the boundary (rings 1: the faces touching it); boundary edges are kept, so the loops
    and their vertices stay as they are and no new vertex lies on the boundary (split_boundary:
    the boundary edges of those faces are split too, their midpoints new boundary vertices, so a
    face with a boundary edge is split into four). Each face is split by how many of its edges
    are: 1 into two, 2 into three, 3 into four (conforming).

    Why: next to a target's small hole the doubles' uniformized metric changes scale fast across
    a face (the conformal factor is per vertex), so its faces are mapped onto their 3D faces
    by affine maps that shear differently on either side of an edge, and a strongly compressed
    source face whose geodesic image (positive) straddles such an edge can come out folded as
    the chord triangle of its corners' images in 3D (docs/history/open_surfaces.md "Session 19").
    Smaller faces there resolve the metric.

    V (n,3), F (m,3), loops: the boundary loops (vertex indices). Returns (V2 (n+k,3), F2
    (m',3), parent (m',) the face of F each new face lies in, corners (m',3,3) each new face's
    corners as barycentrics of its parent's corners, midpoint_of (k,2) the edge each new vertex
    halves). The first n vertices are the input's."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    n, m = len(V), len(F)
    eye = np.broadcast_to(np.eye(3), (m, 3, 3)).copy()
    if rings <= 0 or m == 0:
        return V, F, np.arange(m), eye, np.zeros((0, 2), dtype=np.int64)
    bedges = set()
    ring = np.full(n, -1, dtype=np.int64)
    for loop in loops:
        ring[loop] = 0
        for i in range(len(loop)):
            u, w = int(loop[i]), int(loop[(i + 1) % len(loop)])
            bedges.add((min(u, w), max(u, w)))
    # Rings by breadth-first search over the faces' edges.
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    for r in range(1, rings):
        front = ring[E[:, 0]] == r - 1
        nxt = E[front, 1][ring[E[front, 1]] < 0]
        back = ring[E[:, 1]] == r - 1
        nxt = np.concatenate([nxt, E[back, 0][ring[E[back, 0]] < 0]])
        ring[nxt] = r
    near = np.any(ring[F] >= 0, axis=1)
    split = {}
    verts = [V]
    count = n
    for f in np.flatnonzero(near):
        for k in range(3):
            u, w = int(F[f, k]), int(F[f, (k + 1) % 3])
            e = (min(u, w), max(u, w))
            if (split_boundary or e not in bedges) and e not in split:
                split[e] = count
                count += 1
    if not split:
        return V, F, np.arange(m), eye, np.zeros((0, 2), dtype=np.int64)
    ends = np.array(sorted(split, key=split.get), dtype=np.int64)
    verts.append(0.5 * (V[ends[:, 0]] + V[ends[:, 1]]))
    faces, parent, corners = [], [], []
    unit = np.eye(3)
    for f in range(m):
        tri = [int(x) for x in F[f]]
        mids = [split.get((min(tri[k], tri[(k + 1) % 3]), max(tri[k], tri[(k + 1) % 3]))) for k in range(3)]
        s = sum(x is not None for x in mids)
        if s == 0:
            faces.append(tri)
            parent.append(f)
            corners.append(unit)
            continue
        # Local corners: 0, 1, 2 the face's own, 3 + k the midpoint of edge k (corner k to k + 1).
        local_bary = np.vstack([unit, 0.5 * (unit + np.roll(unit, -1, axis=0))])
        idx = tri + [mids[k] if mids[k] is not None else -1 for k in range(3)]
        if s == 3:
            pieces = [(0, 3, 5), (3, 1, 4), (5, 4, 2), (3, 4, 5)]
        else:
            # Rotate so that the split edges come first (1: edge 0; 2: edges 0 and 1).
            r = next(k for k in range(3) if mids[k] is not None and (s == 1 or mids[(k + 1) % 3] is not None))
            a, b, c = r, (r + 1) % 3, (r + 2) % 3
            mab, mbc = 3 + r, 3 + (r + 1) % 3
            pieces = [(a, mab, c), (mab, b, c)] if s == 1 else [(mab, b, mbc), (a, mab, mbc), (a, mbc, c)]
        for p in pieces:
            faces.append([idx[i] for i in p])
            parent.append(f)
            corners.append(local_bary[list(p)])
    return (np.vstack(verts), np.array(faces, dtype=np.int64), np.array(parent, dtype=np.int64),
            np.array(corners), ends)


def double_surface(V, F, loops=None):
    """The double of an open mesh without boundary chords (split_boundary_chords first).

    Returns a dict: V (n+i,3), F (2m,3) (faces m.. are the mirror copies of faces 0.., corners
    reversed), sigma (n+i,) the reflection as a vertex permutation (fixing the boundary),
    mirror (n,) the mirror vertex of each vertex of the half (itself on the boundary),
    boundary_loops, half_faces m."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    loops = boundary_loops(V, F) if loops is None else loops
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
    return {"V": V2, "F": F2, "sigma": sigma, "mirror": mirror, "boundary_loops": loops, "half_faces": len(F),
            "on_boundary": on_b}


def cap_holes(V, F, loops):
    """The closed surface of genus g: a fan over each loop from an apex beside its centroid.

    The apex is moved off the loop's plane by a quarter of its mean radius along the cap's
    outward side (opposite the loop's vector area, the loop running with the surface on its
    left), so each cap adds positive volume: a flat sheet with holes is capped into a solid the
    intake keeps as oriented, like the other side of the pair.
    Returns (V (n+b,3), F (m+sum|loop|,3), centres (b,) the new vertices)."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    extra_v, extra_f, centres = [], [], []
    for loop in loops:
        c = len(V) + len(extra_v)
        centres.append(c)
        P = V[loop]
        centroid = P.mean(axis=0)
        area = 0.5 * np.cross(P - centroid, np.roll(P, -1, axis=0) - centroid).sum(axis=0)
        radius = np.linalg.norm(P - centroid, axis=1).mean()
        extra_v.append(centroid - 0.25 * radius * area / max(np.linalg.norm(area), 1e-300))
        # The loop runs with the surface on its left: the cap's faces turn the other way.
        extra_f += [[loop[(i + 1) % len(loop)], loop[i], c] for i in range(len(loop))]
    return np.vstack([V, extra_v]), np.vstack([F, np.array(extra_f, dtype=np.int64)]), np.array(centres)


def _nearest(points, candidates_xyz, chunk=1024):
    """Index into candidates_xyz of the nearest candidate of each point (brute force in chunks)."""
    out = np.empty(len(points), dtype=np.int64)
    c2 = np.einsum("ij,ij->i", candidates_xyz, candidates_xyz)
    for s in range(0, len(points), chunk):
        p = points[s:s + chunk]
        d = c2[None, :] - 2 * p @ candidates_xyz.T
        out[s:s + chunk] = np.argmin(d, axis=1)
    return out


class _Side:
    """One open surface: intake, chords split, the double, the capped surface."""

    def __init__(self, V, F, name, refine_rings=0, refine_levels=0):
        self.name = name
        try:
            it = _core.intake(V, F, allow_boundary=True)
        except _core.InputError as e:
            raise _core.InputError(f"{name}: {e}") from None
        self.V = np.asarray(it["V"], dtype=np.float64)
        self.F = np.asarray(it["F"], dtype=np.int64)
        self.genus = int(it["info"]["genus"])
        self.loops = [np.asarray(l, dtype=np.int64) for l in it["boundary_loops"]]
        self.half_loops = self.loops  # the split half's loops (open_reflection.RefinedHalf adds vertices)
        self.b = len(self.loops)
        self.describe = it["info"].get("topology", f"genus {self.genus} with {self.b} boundary loops")
        if self.b == 0:
            return
        self.V2, self.F2, self.parent, self.mid_of = split_boundary_chords(self.V, self.F, self.loops)
        self.n = len(self.V)
        self.diag = float(np.linalg.norm(self.V.max(axis=0) - self.V.min(axis=0)))
        # Each split face's corners as barycentrics of its parent (input) face.
        self.corner_in_parent = np.zeros((len(self.F2), 3, 3))
        for k in range(3):
            v = self.F2[:, k]
            pf = self.F[self.parent]
            orig = v < self.n
            for j in range(3):
                self.corner_in_parent[orig, k, j] = (pf[orig, j] == v[orig])
                if np.any(~orig):
                    ends = self.mid_of[v[~orig] - self.n]
                    self.corner_in_parent[~orig, k, j] = 0.5 * ((pf[~orig, j] == ends[:, 0]) + (pf[~orig, j] == ends[:, 1]))
        halves = []
        for _ in range(refine_levels):
            # Faces near the boundary split (refine_near_boundary), each new face's corners carried
            # to its input face through the chord-split face it lies in; each level within
            # `refine_rings` rings of the previous level's (finer) faces.
            self.V2, self.F2, within, corners, ends = refine_near_boundary(self.V2, self.F2, self.loops, refine_rings)
            self.corner_in_parent = np.einsum("fkl,flj->fkj", corners, self.corner_in_parent[within])
            self.parent = self.parent[within]
            halves.append(ends)
        self.refined_from = np.vstack(halves) if halves else np.zeros((0, 2), dtype=np.int64)
        self.D = double_surface(self.V2, self.F2, self.loops)
        self.n2 = len(self.V2)

    def to_input_faces(self, face2, bary2):
        """Points on the split half (face of F2, barycentrics) on the input faces."""
        bary = np.einsum("ik,ikj->ij", bary2, self.corner_in_parent[face2])
        return self.parent[face2], bary

    def half_points(self, face, bary):
        """Points on the double (face, barycentrics) reflected onto the half; also whether each
        was on the mirror sheet."""
        face = np.asarray(face, dtype=np.int64).copy()
        bary = np.asarray(bary, dtype=np.float64).copy()
        m = face >= self.D["half_faces"]
        face[m] -= self.D["half_faces"]
        bary[m] = bary[m][:, ::-1]  # the mirror face lists the corners in reverse order
        return face, bary, m

    def snap_to_loops(self, P, loop_of_point):
        """Nearest point of the given boundary loop (polyline) of each point: (face, bary, position)
        on the input faces."""
        edge_face = {}
        for f, tri in enumerate(self.F):
            for k in range(3):
                edge_face[(tri[k], tri[(k + 1) % 3])] = f
        out_f = np.empty(len(P), dtype=np.int64)
        out_b = np.zeros((len(P), 3))
        out_p = np.empty((len(P), 3))
        for li, loop in enumerate(self.loops):
            sel = np.flatnonzero(loop_of_point == li)
            if len(sel) == 0:
                continue
            A, B = self.V[loop], self.V[np.roll(loop, -1)]
            d = B - A
            dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
            for p in sel:
                t = np.clip(np.einsum("ij,ij->i", P[p] - A, d) / dd, 0, 1)
                q = A + t[:, None] * d
                j = int(np.argmin(np.linalg.norm(q - P[p], axis=1)))
                u, w = loop[j], loop[(j + 1) % len(loop)]
                f = edge_face[(u, w)] if (u, w) in edge_face else edge_face[(w, u)]
                tri = list(self.F[f])
                out_b[p, tri.index(u)] += 1 - t[j]
                out_b[p, tri.index(w)] += t[j]
                out_f[p], out_p[p] = f, q[j]
        return out_f, out_b, out_p

    def loop_of_vertex(self):
        """Per vertex of the split half the loop it lies on (-1: interior)."""
        lo = -np.ones(self.n2, dtype=np.int64)
        for i, loop in enumerate(self.half_loops):
            lo[loop] = i
        return lo


def _capped_map(S, T, pairing, options, mirrored=False, tie_tolerance=1e-6, landmarks=None, reverse=False):
    """The capped source onto the capped target (closed, genus g) with loop i's centre held on
    target loop pairing[i]'s: a list of rough maps, each (per split-source vertex its image
    (position) on the capped target, the capped target face it lies in, the target's split
    vertices in the frame of those positions, the capped map's class description). `mirrored`:
    onto the target's mirror image (x -> -x, faces reversed), i.e. an orientation-reversing map
    onto the target.

    Genus 1: the flat torus's classes M and -M are both candidates (`homotopy_both_signs`, the
    closed pipeline's default with landmarks; with the canonical sign alone, holding two or more cap
    centres forced a twisted class: a torus with two holes onto its bend 0.3 swapped the holes).
    Usually one map. More when the capped map's classes tie: genus 1 with one hole has one
    landmark, and the half turn about it (the hyperelliptic involution z -> 2 z_c - z of the
    flat torus) holds it as well, so the classes M and -M hold it with the same energy and the
    capped map cannot tell them apart (one of them maps the half onto itself rotated by 180°:
    the punctured torus onto its bend-0.5 copy moved by 31% of the diagonal). Each class within
    `tie_tolerance` (relative) of the chosen one's held energy is returned; the doubles' energy
    (the hole is not exactly symmetric) or the alignment then chooses (surface_map_open).

    reverse: the capped target mapped onto the capped source (mirrored: the source's mirror image)
    with target loop pairing[i]'s centre held on source loop i's, bijectively only (no plain pins),
    and its inverse taken (per split-source vertex a point on the capped target): the same held
    class when both directions hold, and a bijective one where the source -> target direction can
    hold its centres only by folding (_reverse_capped_class)."""
    Vs, Fs, cs = cap_holes(S.V2, S.F2, S.loops)
    Vt, Ft, ct = cap_holes(T.V2, T.F2, T.loops)
    if mirrored and reverse:
        Vs = Vs * np.array([-1.0, 1.0, 1.0])
        Fs = Fs[:, ::-1]
    elif mirrored:
        Vt = Vt * np.array([-1.0, 1.0, 1.0])
        Ft = Ft[:, ::-1]
    # The cap centres, then the user's landmarks (input vertices keep their indices).
    landmarks = np.vstack([np.array([[cs[i], ct[pairing[i]]] for i in range(S.b)], dtype=np.int64),
                           np.zeros((0, 2), dtype=np.int64) if landmarks is None else landmarks])
    kw = {k: v for k, v in options.items() if k in ("threads", "tolerance", "max_iterations", "target_metric")}
    if options.get("inner_progress") is not None:   # (surface_map_open: a cancel seen mid-candidate)
        kw["progress"] = options["inner_progress"]

    def solve(**extra):
        if reverse:
            r = _solve_closed(lambda **metric: _core.surface_map(Vt, Ft, Vs, Fs, landmarks=landmarks[:, ::-1].copy(),
                                                                 two_way=False, homotopy_both_signs=True, **kw,
                                                                 **extra, **metric), kw)
        else:
            r = _solve_closed(lambda **metric: _core.surface_map(Vs, Fs, Vt, Ft, landmarks=landmarks, two_way=False,
                                                                 homotopy_both_signs=True, **kw, **extra, **metric), kw)
        if bool(r["source_flipped"]) != bool(r["target_flipped"]):
            raise _core.SolveError("the capped surfaces came out oriented differently (the source's faces "
                                   f"{'reversed' if r['source_flipped'] else 'kept'}, the target's "
                                   f"{'reversed' if r['target_flipped'] else 'kept'}): the open meshes' orientations "
                                   "differ")
        fw = r["inverse"] if reverse else r["forward"]   # reverse: per capped-source vertex, on the capped target
        hom = r.get("homotopy", {})
        cands = hom.get("candidates", [])
        chosen = int(hom.get("chosen", -1))
        desc = cands[chosen].get("description", "") if 0 <= chosen < len(cands) else ""
        if extra.get("landmarks_may_fold") and int(r.get("flipped_triangles", 0)):
            desc += f" [cap centres held by plain pins: {int(r['flipped_triangles'])} folded faces]"
        if reverse:
            desc += " [the target -> source capped map, inverted]"
        return (np.asarray(fw["position"])[:S.n2], np.asarray(fw["face"])[:S.n2], Vt[:T.n2], desc), cands, chosen

    # The capped map is used for its class only (_symmetric_images carries it to the doubles, whose
    # own solve gives the map). The class with the cap centres held is defined whether or not its
    # held map folds (each centre at the lift nearest its free image), so when the centres cannot
    # be held bijectively in any class (a cap centre far from where the free map puts it: the
    # double torus with a hole onto the eight with a hole folded 575-643 faces carrying 201
    # vertices along, in all 15 / 14 classes), the classes are ranked by their plain pins' energy
    # and the chosen one's folded images are taken (landmarks_may_fold;
    # docs/history/open_surfaces.md "Capped maps that fold").
    fold = {}
    try:
        first, cands, chosen = solve()
    except _core.Cancelled:
        raise
    except _core.SolveError as e:
        if "landmark" not in str(e) or reverse:
            raise
        fold = {"landmarks_may_fold": True}
        first, cands, chosen = solve(**fold)
    out = [first]
    if 0 <= chosen < len(cands):
        held = cands[chosen].get("landmark_energy", float("nan"))
        for k, c in enumerate(cands):
            bound = c.get("landmark_lower_bound", float("nan"))
            if k != chosen and np.isfinite(held) and np.isfinite(bound) and bound <= held * (1 + tie_tolerance):
                out.append(solve(homotopy=k, **fold)[0])
    return out


def _capped_sphere(side, options):
    """Genus 0: the capped surface conformally on the unit sphere (uniformize/spherical.h), in the
    input's orientation: (positions (n2+b, 3), centres (b,)). Cached on the side."""
    if getattr(side, "sphere", None) is None:
        V, F, centres = cap_holes(side.V2, side.F2, side.loops)
        kw = {k: v for k, v in options.items() if k in ("tolerance",)}
        u = _core.uniformize(V, F, **kw)
        P = np.asarray(u["sphere_positions"], dtype=np.float64)
        if u["flipped_on_input"]:
            P = P * np.array([1.0, 1.0, -1.0])  # the intake turned the faces: turn the sphere back
        side.sphere = (P, centres)
    return side.sphere


def _to_homogeneous(P):
    """Unit-sphere points as homogeneous stereographic coordinates [u : v] (z = u / v), from
    whichever chart is better conditioned at each point."""
    z = P[:, 0] + 1j * P[:, 1]
    north = P[:, 2] > 0
    u = np.where(north, 1 + P[:, 2], z)
    v = np.where(north, np.conj(z), 1 - P[:, 2])
    return u, v


def _from_homogeneous(u, v):
    n = np.abs(u) ** 2 + np.abs(v) ** 2
    w = u * np.conj(v)
    return np.stack([2 * w.real / n, 2 * w.imag / n, (np.abs(u) ** 2 - np.abs(v) ** 2) / n], axis=1)


def _three_point_matrix(z):
    """2x2 matrix of the Möbius map sending the homogeneous points z[0], z[1], z[2] to 0, 1, inf."""
    (u1, v1), (u2, v2), (u3, v3) = z
    # w = (z - z1)(z2 - z3) / ((z - z3)(z2 - z1)) in homogeneous form
    a = (u2 * v3 - u3 * v2)
    b = (u2 * v1 - u1 * v2)
    return np.array([[a * v1, -a * u1], [b * v3, -b * u3]])


def _sphere_rough_map(S, T, pairing, options, mirrored=False, landmarks=None):
    """Genus 0: the Möbius map of the capped spheres sending source cap centre i onto target cap
    centre pairing[i] (exact for the first three loops, the longest; with mirrored, composed with
    a reflection of the sphere: orientation reversing). A homeomorphism of the spheres whatever
    it stretches, which is all the class needs (the closed pipeline's genus-0 map refuses
    stretched Möbius maps by their flipped triangles). Landmarks are not used here (the images
    of landmark vertices are set by _symmetric_images). Returns [(images on the target sphere,
    None, the target's split vertices on its sphere, '')] (the form of _capped_map)."""
    Ps, cs = _capped_sphere(S, options)
    Pt, ct = _capped_sphere(T, options)
    if mirrored:
        Ps = Ps * np.array([1.0, -1.0, 1.0])
    k = min(3, S.b)
    src = [_to_homogeneous(Ps[[cs[i]]]) for i in range(k)]
    dst = [_to_homogeneous(Pt[[ct[pairing[i]]]]) for i in range(k)]
    if k < 3:
        raise _core.SolveError("the sphere map needs three boundary loops")
    A = _three_point_matrix([(u[0], v[0]) for u, v in src])
    B = _three_point_matrix([(u[0], v[0]) for u, v in dst])
    M = np.linalg.inv(B) @ A
    u, v = _to_homogeneous(Ps[:S.n2])
    images = _from_homogeneous(M[0, 0] * u + M[0, 1] * v, M[1, 0] * u + M[1, 1] * v)
    return [(images, None, Pt[:T.n2], "")]


def _chains(S, T, pairing, count):
    """The orders in which to chain the loops for the cut disks (open_cut_disk): 0, 1, ..., b - 1
    first, then the `count` - 1 other chains (a chain and its reverse cut alike) of shortest
    total length, source and target together (_loop_distances: the paths' lengths; with b >= 4
    another chain can give another class of the same pairing). Chains are listed for b <= 7 only."""
    default = list(range(S.b))
    if count <= 1 or S.b > 7:
        return [default]
    try:
        Ds, Dt = _loop_distances(S), _loop_distances(T)
    except ImportError:
        return [default]
    p = list(pairing)

    def length(c):
        return sum(Ds[c[k], c[k + 1]] + Dt[p[c[k]], p[c[k + 1]]] for k in range(len(c) - 1))
    others = sorted((c for c in itertools.permutations(range(S.b)) if c[0] < c[-1] and list(c) != default),
                    key=length)
    return [default] + [list(c) for c in others[:count - 1]]


def _other_chains(S, T, pairing, reversed_orientation, options, lm, twist, error):
    """Genus 0 with b <= 3: one class per pairing and orientation, which the cut disks along any
    chain of the loops give. When the doubles' solve refuses the class carried by the chain
    0, 1, ..., b - 1's images (the carried loops not an isomorphism: the artery onto its decimated
    copy of 30-degree tilts, preserving, slivers to 177 degrees; why was not isolated), the same class is asked
    again from the cut disks along the other chains. Returns (the doubles' map, the images, the
    chain as text); raises the first error when every chain fails."""
    for chain in itertools.permutations(range(S.b)):
        if chain[0] > chain[-1] or list(chain) == list(range(S.b)):
            continue                                      # a chain and its reverse cut alike
        try:
            target_vertex = open_cut_disk.cut_disk_class_images(S, T, pairing, mirrored=reversed_orientation,
                                                                chain=chain)
            images = _symmetric_images(S, T, pairing, reversed_orientation, T.V2[target_vertex], None, T.V2,
                                       landmarks=lm, twist=twist)
            return (_double_map(S, T, images, options, _landmark_pairs(S, T, lm, reversed_orientation)), images,
                    "-".join(map(str, chain)))
        except _core.Cancelled:
            raise
        except _core.Error:
            continue
    raise error


def _reverse_capped_class(S, T, pairing, reversed_orientation, options, lm, twist, error):
    """Genus >= 1: when the doubles' solve refuses the class carried by the capped source -> target
    map's images (the carried loops not an isomorphism), the class of the capped target -> source
    map holding the same centres, inverted (_capped_map's reverse): each of its tied classes solved
    on the doubles, the lowest energy kept (then the alignment). Why: where the source -> target
    map can hold the cap centres only by plain pins, each pin is a spike and the loops around it
    stay where the free map put them (the raw cup with two holes onto the jittered torus with two
    holes: 1,012 folded faces, each source loop's images snapped onto one vertex of its target loop,
    winding 0, so no degree-one map of the doubles), while the other direction held them
    bijectively. Returns (the doubles' map, the images, the class's description); a SolveError
    naming `error` and why when the other direction cannot hold its centres either or none of its
    classes maps."""
    try:
        roughs = _capped_map(S, T, pairing, options, mirrored=reversed_orientation, landmarks=lm, reverse=True)
    except _core.Cancelled:
        raise
    except _core.Error as e:
        raise _core.SolveError(f"{error}; the target -> source capped map: {e}") from None
    solved, failed = [], []
    for pos, face, target_xyz, desc in roughs:
        try:
            images = _symmetric_images(S, T, pairing, reversed_orientation, pos, face, target_xyz, landmarks=lm,
                                       twist=twist)
            r = _double_map(S, T, images, options, _landmark_pairs(S, T, lm, reversed_orientation))
        except _core.Cancelled:
            raise
        except _core.Error as e:
            failed.append(f"{desc}: {e}")
            continue
        solved.append((float(r["energy"]["final"]), _alignment(S, T, np.asarray(r["forward"]["position"])[:S.n]),
                       len(solved), r, images, desc))
    if not solved:
        raise _core.SolveError(f"{error}; the target -> source capped map, inverted: " + "; ".join(failed))
    _, _, _, r, images, desc = min(solved, key=lambda x: x[:3])
    return r, images, desc


def _rough_maps(S, T, pairing, options, mirrored, landmarks, classes_per_pairing=1):
    """The rough maps of the halves for one pairing and orientation (_capped_map's form). Genus 0:
    the homeomorphism of the halves cut into disks along chains of shortest paths between the
    paired loops (open_cut_disk: the class from the pairing and the orientation alone, exact
    target vertices). Only when a half cannot be cut so: with at most three loops the Möbius map of
    the capped spheres (_sphere_rough_map; exact at the three cap centres), with four or more the
    closed pipeline's map of the capped spheres holding every cap centre, then the Möbius map (both
    rough geometric maps whose images, moved onto the target's vertices, carried loops that were not
    an isomorphism on the poncho onto its bend 0.3 and the artery onto its bend 0.2). With four or
    more loops and landmarks, the capped map holding them comes first (the landmarks choose among
    the pairing's classes). Genus >= 1: _capped_map. Returns (the rough maps, how they were made: the candidates' 'rough_map')."""
    if S.genus >= 1:
        try:
            return _capped_map(S, T, pairing, options, mirrored=mirrored, landmarks=landmarks), "capped map"
        except _core.Cancelled:
            raise
        except _core.Error as e:
            # The other direction's capped map, inverted (_reverse_capped_class says why).
            try:
                return _capped_map(S, T, pairing, options, mirrored=mirrored, landmarks=landmarks,
                                   reverse=True), "capped map"
            except _core.Cancelled:
                raise
            except _core.Error:
                raise e from None
    cut_failed = ""
    if S.b >= 4 and landmarks is not None and len(landmarks):
        # With four or more loops the pairing leaves infinitely many classes, and landmarks pick
        # one: the capped map that holds them first, as before the cut disks.
        try:
            return _capped_map(S, T, pairing, options, mirrored=mirrored, landmarks=landmarks), "capped map"
        except _core.Cancelled:
            raise
        except _core.Error as e:
            cut_failed = f" (capped map: {e})"
    if S.b >= 2:
        chains = _chains(S, T, pairing, classes_per_pairing if S.b >= 4 else 1)
        roughs, failed = [], []
        for chain in chains:
            try:
                target_vertex = open_cut_disk.cut_disk_class_images(S, T, pairing, mirrored=mirrored, chain=chain)
                roughs.append((T.V2[target_vertex], None, T.V2, f"chain {'-'.join(map(str, chain))}"
                               if len(chains) > 1 else ""))
            except _core.SolveError as e:
                failed.append(str(e))
        if roughs:
            return roughs, "cut disks"
        cut_failed += f" (cut disks: {failed[0]})"
    if S.b <= 3 or cut_failed.startswith(" (capped map"):
        return (_sphere_rough_map(S, T, pairing, options, mirrored=mirrored, landmarks=landmarks),
                "Möbius map of the capped spheres" + cut_failed)
    try:
        return _capped_map(S, T, pairing, options, mirrored=mirrored, landmarks=landmarks), "capped map" + cut_failed
    except _core.Cancelled:
        raise
    except _core.Error:
        return (_sphere_rough_map(S, T, pairing, options, mirrored=mirrored, landmarks=landmarks),
                "Möbius map of the capped spheres" + cut_failed)


def _collar_twist(T, loop, turns, rings=None, max_ring_growth=1.25):
    """A discrete Dehn twist of the target's split half about a curve parallel to boundary loop
    `loop`, `turns` full turns (sign: the direction along the loop), as a map of its vertices
    (n2,) -> vertex. The collar: the vertices within `rings` edge rings of the loop (default a third
    of the ring depth of the whole half, at least 3); a vertex at depth d whose nearest loop vertex
    (its foot, carried along the breadth-first tree) sits at arc position s in [0, 1) goes to the
    vertex of the same depth whose foot is nearest s + turns (1 - d / rings): the loop itself turns
    by whole turns (fixed), the collar's edge by none, so the map is the identity outside the collar
    and on the boundary. The collar ends at the first ring that with the next is not one connected
    band (a branch point: past it a ring runs around several loops, and turning it would not be a twist
    about a curve parallel to this one), or, on a tube (rings 1-5 within `max_ring_growth` times the
    loop's vertices), at half the depth of the first ring wider than that (the tube opening towards a
    branch point). Not a bijection of the vertices (it only has to carry loops)."""
    V, F, L = T.V2, T.F2, T.loops[loop]
    n = len(V)
    nbr = [[] for _ in range(n)]
    for a, b in np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]):
        nbr[a].append(b)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(V[L] - V[np.roll(L, -1)], axis=1))])
    depth = -np.ones(n, dtype=np.int64)
    foot = np.zeros(n)
    depth[L] = 0
    foot[L] = arc[:-1] / arc[-1]
    frontier = list(L)
    while frontier:
        nxt = []
        for u in frontier:
            for w in nbr[u]:
                if depth[w] < 0:
                    depth[w], foot[w] = depth[u] + 1, foot[u]
                    nxt.append(w)
        frontier = nxt
    if rings is None:
        rings = max(3, int(depth.max()) // 3)
        ring_sizes = np.bincount(depth[depth >= 0])
        tube = bool(np.all(ring_sizes[1:6] <= max_ring_growth * len(L)))
        for d in range(1, rings):
            # The band of rings d and d + 1 (a ring alone need not be connected by its own edges).
            ring = set(np.flatnonzero((depth == d) | (depth == d + 1)).tolist())
            if not ring:
                rings = d
                break
            if tube and ring_sizes[d] > max_ring_growth * len(L):
                # A tube (its first 5 rings the loop's size) widens: it opens towards a branch
                # point, long before the band splits. The artery's branch loops of 18 and 16
                # vertices have rings of 14-23 / 16-17 up to depth ~52 / ~35, then up to 77 / 38,
                # and split only at 65 / 69. Collars of a third of the depth (51 / 54 rings, up to
                # or past the widening) made starts that, +1 and -1 turns alike, carried one other,
                # non-symmetric class (E +0.19% / +0.26%, symmetry 0.04 of the diagonal; how the
                # collar's last rings change the class was not isolated); with 30 or 12 / 18 rings
                # every start came back to the untwisted map. A hole in a round body (the rings
                # widen from the first: the test pants' loops of 54 vertices have rings of 68 at
                # depth 4) keeps the third of the depth, which came back there.
                rings = max(d // 2, 3)
                break
            seen, stack = set(), [next(iter(ring))]
            while stack:
                u = stack.pop()
                if u in seen:
                    continue
                seen.add(u)
                stack.extend(w for w in nbr[u] if w in ring and w not in seen)
            if len(seen) < len(ring):
                rings = max(d, 2)
                break
    tau = np.arange(n)
    for d in range(1, rings):
        ring = np.flatnonzero(depth == d)
        if len(ring) == 0:
            continue
        want = (foot[ring] + turns * (1 - d / rings)) % 1.0
        gap = np.abs(want[:, None] - foot[ring][None, :])
        gap = np.minimum(gap, 1 - gap)
        tau[ring] = ring[np.argmin(gap, axis=1)]
    return tau


def _symmetric_images(S, T, pairing, reversed_orientation, pos, face, target_xyz, landmarks=None, twist=None):
    """Per vertex of the source's double a target double vertex position: the capped map's image
    moved onto the nearest target vertex (source boundary vertices onto the nearest vertex of
    the paired target loop; images inside a target cap onto that cap's loop, at a corner of the cap
    face holding them), the mirror
    vertices onto the mirror of their twin's image. Exact target vertex positions, so the
    pipeline's loop projection (ProjectedLoopsOptions::source_on_target) lands on them.
    reversed_orientation: the capped map was onto the target's mirror image (orientation
    reversing); its double composed with the target's reflection (the source's half onto the
    target's mirror sheet) preserves the doubles' orientation, as the closed pipeline needs.
    pos, face: the capped map's images; target_xyz: the target's split vertices in their frame.
    twist: {target loop: turns}, the images composed with _collar_twist (a twisted start)."""
    n_target_half_faces = len(T.F2)
    DT = T.D
    target_vertex = np.empty(S.n2, dtype=np.int64)
    s_loop = S.loop_of_vertex()
    # Which target cap a capped-target face belongs to (-1: the half).
    cap_of_face = -np.ones(n_target_half_faces + sum(len(l) for l in T.loops), dtype=np.int64)
    cap_start, start = [], n_target_half_faces
    for i, loop in enumerate(T.loops):
        cap_of_face[start:start + len(loop)] = i
        cap_start.append(start)
        start += len(loop)
    cap = cap_of_face[face] if face is not None else np.full(S.n2, -1)
    free = (s_loop < 0) & (cap < 0)
    target_vertex[free] = _nearest(pos[free], target_xyz)
    for i, loop in enumerate(T.loops):
        # Source boundary vertices of the loop paired with i, and images inside cap i.
        src_loop = [k for k in range(S.b) if pairing[k] == i]
        sel = np.flatnonzero(np.isin(s_loop, src_loop) | ((s_loop < 0) & (cap == i)))
        if len(sel):
            target_vertex[sel] = loop[_nearest(pos[sel], target_xyz[loop])]
            # An image inside the cap goes to a corner of its cap face, the nearer of the face's
            # two loop vertices (cap face k lies on loop edge k, k + 1: cap_holes), not to the
            # loop vertex nearest in space: that one is arbitrary near the cap's centre, and a
            # source loop whose images circle the centre inside the cap (a source hole
            # conformally smaller than the target's: the raw cup's onto the jittered torus's, 430
            # of 2,289 images inside the caps) snapped onto 3-4 target loop vertices with winding 0.
            in_cap = sel[cap[sel] == i]
            if len(in_cap):
                k = face[in_cap] - cap_start[i]
                a, b = loop[k], loop[(k + 1) % len(loop)]
                nearer_b = (np.linalg.norm(pos[in_cap] - target_xyz[b], axis=1)
                            < np.linalg.norm(pos[in_cap] - target_xyz[a], axis=1))
                target_vertex[in_cap] = np.where(nearer_b, b, a)
    for loop, turns in (twist or {}).items():
        # A rough map twisted about target loop `loop` (surface_map_open's boundary_twists).
        target_vertex = _collar_twist(T, loop, turns)[target_vertex]
    if landmarks is not None and len(landmarks):
        target_vertex[landmarks[:, 0]] = landmarks[:, 1]   # landmarks onto their target vertices
    sheet1 = DT["V"][target_vertex]
    sheet2 = DT["V"][DT["mirror"][target_vertex]]
    if reversed_orientation:
        sheet1, sheet2 = sheet2, sheet1
    images = np.empty((len(S.D["V"]), 3))
    images[:S.n2] = sheet1
    interior = np.flatnonzero(~S.D["on_boundary"])
    images[S.D["mirror"][interior]] = sheet2[interior]
    return images


def _solve_closed(solve, kw):
    """solve(**extra): one call of the closed pipeline (the capped map, the doubles' map) with the
    caller's target metric if given, else the core's 'fixed-first' policy (the fixed-connectivity
    metric, the flip-based one only when that does not exist: docs/uniformization.md). Why not the
    core's default (flips first): a double's two sheets lie 1e-6 of the diagonal apart, and the
    flip-based metric on the artery's 1-to-4 subdivided double (46,506 vertices) grew past 10 GB and
    ended in std::bad_alloc before any fallback could run (flip cycling on overflowed Penner
    coordinates, since fixed: that double now uniformizes with flips in 101 MB, but the doubles'
    maps were measured on this policy and not again on flips). The one place where the doubles
    choose the metric. (The 31% displacement once blamed on the flip-based metric was the capped torus's
    tie of M and -M, _capped_map; docs/open_surfaces.md.)"""
    return solve() if "target_metric" in kw else solve(target_metric="fixed-first")


def _check_landmarks(S, T, landmarks):
    """Landmarks as a (k, 2) int array of input vertex pairs; InputError naming the bad one."""
    if landmarks is None:
        return np.zeros((0, 2), dtype=np.int64)
    lm = np.asarray(landmarks, dtype=np.int64).reshape(-1, 2)
    s_on, t_on = S.loop_of_vertex(), T.loop_of_vertex()
    for k, (p, q) in enumerate(lm):
        name = f"landmark {k} ({p} {q})"
        if not 0 <= p < S.n:
            raise _core.InputError(f"{name}: source vertex out of range ({S.n} vertices)")
        if not 0 <= q < T.n:
            raise _core.InputError(f"{name}: target vertex out of range ({T.n} vertices)")
        if (s_on[p] < 0) != (t_on[q] < 0):
            which = ("source", "target") if s_on[p] >= 0 else ("target", "source")
            raise _core.InputError(f"{name}: the {which[0]} vertex is on the boundary but the {which[1]} vertex is "
                                   f"not (boundary maps onto boundary)")
    return lm


def _landmarks_allow(S, T, lm, pairing):
    """Whether each boundary landmark's source loop is paired with its target vertex's loop."""
    s_on, t_on = S.loop_of_vertex(), T.loop_of_vertex()
    return all(s_on[p] < 0 or pairing[s_on[p]] == t_on[q] for p, q in lm)


def _landmark_pairs(S, T, lm, reversed_orientation):
    """The doubles' landmarks: each (p, q) with its mirror pair (sigma_S p, sigma_T q); orientation
    reversing: p onto the target's mirror sheet (sigma_T q) and its mirror onto q. Boundary
    vertices are their own mirrors (one pair)."""
    if len(lm) == 0:
        return None
    ms, mt = S.D["mirror"], T.D["mirror"]
    out = []
    for p, q in lm:
        a, b = (q, mt[q]) if not reversed_orientation else (mt[q], q)
        out.append((p, a))
        if ms[p] != p:
            out.append((ms[p], b))
    return np.array(out, dtype=np.int64)


def _refined_images(S, T, S2, T2, images):
    """The rough map `images` (per vertex of S's double a vertex position of T's double, symmetric:
    _symmetric_images) carried onto the doubles of S2, T2, the same surfaces refined near their
    boundary (_Side refine_levels): each half vertex keeps its target vertex (on the same sheet), a
    new source vertex takes that of an end of the edge it halves (one not on the boundary: the
    chords were split first, so one is not), and the mirror vertices the reflection of their
    twin's. (len(S2.D["V"]), 3)."""
    target_vertex = _nearest(images[:S.n2], T.D["V"])
    half_of = np.arange(len(T.D["V"]))
    half_of[T.D["mirror"]] = np.arange(T.n2)  # the mirror sheet's vertices to their twins
    on_mirror = target_vertex >= T.n2
    out = np.empty(S2.n2, dtype=np.int64)
    out[:S.n2] = np.where(on_mirror, T2.D["mirror"][half_of[target_vertex]], target_vertex)
    on_b = S2.D["on_boundary"]
    for k, (a, b) in enumerate(S2.refined_from):   # in order: an end may be an earlier new vertex
        out[S.n2 + k] = out[b if on_b[a] else a]
    full = np.empty(len(S2.D["V"]), dtype=np.int64)
    full[:S2.n2] = out
    interior = np.flatnonzero(~on_b)
    full[S2.D["mirror"][interior]] = T2.D["sigma"][out[interior]]
    return T2.D["V"][full]


def _own_images(S, T, r, pairing, reversed_orientation, landmarks):
    """The doubles' map r's images of the source half's vertices as a rough map's images
    (_symmetric_images: each on the nearest target vertex, the boundary on its paired loop of
    `pairing`): the start of a re-solve of r's own class (_chosen_class_again)."""
    pos = np.asarray(r["forward"]["position"])[:S.n2]
    return _symmetric_images(S, T, pairing, reversed_orientation, pos, None, T.D["V"][:T.n2], landmarks=landmarks)


def _double_map(S, T, images, options, landmarks=None, homotopy=None):
    """The doubles' map of the class of `images` (the closed pipeline's images_only run: that class,
    and, the doubles having no coarse copy, the snapped overlay's own class ranked beside it;
    _keep_requested_pairing). homotopy: the index of the class to solve in that list (None: the
    lower energy)."""
    kw = {k: v for k, v in options.items() if k in ("threads", "tolerance", "max_iterations", "method",
                                                    "source_weights", "solve_progress",
                                                    "target_metric")}
    if options.get("inner_progress") is not None:   # (surface_map_open: a cancel seen mid-candidate)
        kw["progress"] = options["inner_progress"]
    if homotopy is not None:
        kw["homotopy"] = int(homotopy)

    def solve(**extra):
        return _core.surface_map(S.D["V"], S.D["F"], T.D["V"], T.D["F"], homotopy_images=images,
                                 two_way=False, homotopy_search=False, landmarks=landmarks, **kw, **extra)

    return _solve_closed(solve, kw)


def _symmetry(res, S, T, reversed_orientation):
    """(largest |f(sigma x) - sigma f(x)| over the diagonal, fraction of interior source vertices
    whose image lies on the expected sheet) of a map between doubles."""
    pos = np.asarray(res["forward"]["position"])
    face = np.asarray(res["forward"]["face"])
    sig = S.D["sigma"]
    err = float(np.linalg.norm(pos[sig] - pos, axis=1).max()) / T.diag  # sigma_T moves points by 1e-6 only
    interior = np.flatnonzero(~S.D["on_boundary"])
    on_first = face[interior] < T.D["half_faces"]
    return err, float(np.mean(~on_first if reversed_orientation else on_first))


def _dilatation(P, Q, F):
    """D' (ratio of singular values) of the affine maps taking triangles P[F] onto Q[F] (3D)."""
    def frame(X):
        e1 = X[:, 1] - X[:, 0]
        e2 = X[:, 2] - X[:, 0]
        l1 = np.linalg.norm(e1, axis=1)
        x = e1 / np.maximum(l1, 1e-300)[:, None]
        n = np.cross(e1, e2)
        y = np.cross(n, e1)
        y /= np.maximum(np.linalg.norm(y, axis=1), 1e-300)[:, None]
        J = np.zeros((len(X), 2, 2))
        J[:, 0, 0] = l1
        J[:, 0, 1] = np.einsum("ij,ij->i", e2, x)
        J[:, 1, 1] = np.einsum("ij,ij->i", e2, y)
        return J
    Js, Jt = frame(P[F]), frame(Q[F])
    det_s = Js[:, 0, 0] * Js[:, 1, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.zeros_like(Js)
        inv[:, 0, 0] = Js[:, 1, 1] / det_s
        inv[:, 0, 1] = -Js[:, 0, 1] / det_s
        inv[:, 1, 1] = Js[:, 0, 0] / det_s
        A = Jt @ inv
        det = np.abs(A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0])
        s = np.einsum("ijk,ijk->i", A, A) / det  # D' + 1/D'
        d = 0.5 * (s + np.sqrt(np.maximum(s * s - 4, 0)))
    d[~np.isfinite(d)] = np.inf
    return d


def _half_correspondence(res_map, S, T):
    """From the doubles' map: per input source vertex (face, bary, position) on the target's input
    faces, boundary vertices snapped onto their paired target loop; per input target vertex the
    same on the source. Returns (forward, inverse, pairing, back_pairing, snap_distance)."""
    def on_half(A, B, points):
        n = A.n
        f2, b2, _ = B.half_points(np.asarray(points["face"])[:n], np.asarray(points["barycentric"])[:n])
        return f2, b2
    return _split_half_correspondence(S, T, on_half(S, T, res_map["forward"]), on_half(T, S, res_map["inverse"]))


def _reflected_correspondence(sym, S, T):
    """_half_correspondence of the reflection-aware solve (open_reflection.solve_half: points on
    the split halves' faces already)."""
    fw, inv = sym["forward"], sym["inverse"]
    return _split_half_correspondence(S, T, (fw["face"][:S.n], fw["barycentric"][:S.n]),
                                      (inv["face"][:T.n], inv["barycentric"][:T.n]))


def _split_half_correspondence(S, T, forward, inverse):
    """forward: (face, bary) on T's split half faces per input source vertex; inverse the same on
    S's per input target vertex. On the input faces, boundary vertices snapped onto their paired
    loop: (forward, inverse, pairing, back_pairing, snap_distance)."""
    def one_way(A, B, points):
        f2, b2 = points
        face, bary = B.to_input_faces(np.asarray(f2), np.asarray(b2))
        pos = np.einsum("ij,ijk->ik", bary, B.V[B.F[face]])
        on_b = np.concatenate(A.loops)
        # Which B loop each A loop lands on: the loop nearest to most of its vertices.
        loop_of = np.empty(len(on_b), dtype=np.int64)
        pairing, start = [], 0
        b_loop_vertices = np.concatenate(B.loops)
        b_loop_index = np.concatenate([np.full(len(l), i) for i, l in enumerate(B.loops)])
        nearest_loop = b_loop_index[_nearest(pos[on_b], B.V[b_loop_vertices])]
        for li, l in enumerate(A.loops):
            votes = nearest_loop[start:start + len(l)]
            pairing.append(int(np.bincount(votes, minlength=B.b).argmax()))
            loop_of[start:start + len(l)] = pairing[-1]
            start += len(l)
        sf, sb, sp = B.snap_to_loops(pos[on_b], loop_of)
        snap = float(np.linalg.norm(sp - pos[on_b], axis=1).max()) if len(on_b) else 0.0
        face[on_b], bary[on_b], pos[on_b] = sf, sb, sp
        return {"face": face, "barycentric": bary, "position": pos}, pairing, snap
    fw, pairing, snap = one_way(S, T, forward)
    inv, back_pairing, snap_back = one_way(T, S, inverse)
    return fw, inv, pairing, back_pairing, max(snap, snap_back)


def _face_neighbours(F):
    """Per face the faces across its three edges (-1 on the boundary): (m, 3), column k across the
    edge from corner k to corner k + 1."""
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    a, b = F.reshape(-1), np.roll(F, -1, axis=1).reshape(-1)
    key = {(int(u), int(w)): i for i, (u, w) in enumerate(zip(a, b))}
    out = -np.ones(3 * m, dtype=np.int64)
    for i, (u, w) in enumerate(zip(a, b)):
        j = key.get((int(w), int(u)))
        if j is not None:
            out[i] = j // 3
    return out.reshape(m, 3)


def _unfold(V, F, neighbours, root, wanted, max_faces=400):
    """The faces of a breadth-first tree from face `root` until every face of `wanted` is reached,
    unfolded isometrically into the plane of `root` (its own orientation counter-clockwise): a dict
    face -> (3, 2) planar corners, in the order the faces were reached. None when some wanted face
    is more than max_faces away. (Per face in plain floats: the fold test calls it per star, and
    numpy's per-call cost on 2- and 3-vectors was most of the untangling's time.)"""
    root = int(root)
    P0 = V[F[root]]
    e1 = P0[1] - P0[0]
    x = e1 / np.linalg.norm(e1)
    nrm = np.cross(e1, P0[2] - P0[0])
    y = np.cross(nrm / np.linalg.norm(nrm), x)
    corners = {root: [(0.0, 0.0), (float(np.linalg.norm(e1)), 0.0),
                      (float((P0[2] - P0[0]) @ x), float((P0[2] - P0[0]) @ y))]}
    wanted = {int(f) for f in wanted} - {root}
    queue, head = [root], 0
    sqrt = math.sqrt
    while wanted and head < len(queue) and len(queue) <= max_faces:
        f = queue[head]
        head += 1
        Ff, nf, qf = F[f].tolist(), neighbours[f].tolist(), corners[f]
        for k in range(3):
            g = nf[k]
            if g < 0 or g in corners:
                continue
            # The shared edge (u, w) runs u -> w in f and w -> u in g; g's third corner lies on the
            # other side of it from f's, at its 3D distances from u and w.
            u, w = Ff[k], Ff[(k + 1) % 3]
            (pux, puy), (pwx, pwy) = qf[k], qf[(k + 1) % 3]
            Fg = F[g].tolist()
            kg = Fg.index(w)   # g lists w, u, c
            c = Fg[(kg + 2) % 3]
            dx, dy = pwx - pux, pwy - puy
            L = sqrt(dx * dx + dy * dy)
            vc, vu, vw = V[c].tolist(), V[u].tolist(), V[w].tolist()
            ru2 = (vc[0] - vu[0]) ** 2 + (vc[1] - vu[1]) ** 2 + (vc[2] - vu[2]) ** 2
            rw2 = (vc[0] - vw[0]) ** 2 + (vc[1] - vw[1]) ** 2 + (vc[2] - vw[2]) ** 2
            t = (ru2 - rw2 + L * L) / (2 * L)
            h = sqrt(max(ru2 - t * t, 0.0))
            ex, ey = dx / L, dy / L             # left of u -> w (f's side): (-ey, ex)
            q = [None, None, None]
            q[kg], q[(kg + 1) % 3] = (pwx, pwy), (pux, puy)
            q[(kg + 2) % 3] = (pux + t * ex + h * ey, puy + t * ey - h * ex)
            corners[g] = q
            queue.append(g)
            wanted.discard(g)
    if wanted:
        return None
    return {f: np.array(q) for f, q in corners.items()}


def _unfolded_signed_area(V, F, neighbours, faces, bary, max_faces=400):
    """Signed area of the triangle of three points on a triangle mesh (faces (3,), bary (3,3)),
    measured intrinsically: the faces of a breadth-first tree from faces[0] reaching the other two
    are unfolded isometrically into the plane of faces[0] (_unfold), and the points' planar
    positions give the area; also the planar triangle's perimeter. None when the faces are more
    than max_faces apart. This is what the chord triangle in a tangent plane cannot tell where the
    surface folds sharply between the corners' faces (a garment's crease: adjacent faces turned by
    90° or more)."""
    planar = _unfold(V, F, neighbours, faces[0], faces[1:], max_faces)
    if planar is None:
        return None
    pts = [bary[k] @ planar[int(faces[k])] for k in range(3)]
    a, b = pts[1] - pts[0], pts[2] - pts[0]
    perimeter = sum(np.linalg.norm(pts[k] - pts[(k + 1) % 3]) for k in range(3))
    return 0.5 * (a[0] * b[1] - a[1] * b[0]), perimeter


def _flips(S, T, fw, reversing=False, resolved_angle=np.pi / 3):
    """Source faces (ears apart) whose image turns against the target (with `reversing`, an
    orientation-reversing map: whose image does not); ears (faces with three boundary corners,
    fixed by their boundary points alone) and how many of them turn: (flipped, ears, ears turned,
    ear mask). The test of each face: _turned."""
    turned = _turned(S, T, fw, reversing, resolved_angle=resolved_angle)
    ear = _flips_ear(S)
    return int(np.sum(turned & ~ear)), int(ear.sum()), int(np.sum(turned & ear)), ear


def _flips_ear(S):
    """Per face of S whether it is an ear (three boundary corners), as _flips counts them."""
    on_b = np.zeros(S.n, dtype=bool)
    on_b[np.concatenate(S.loops)] = True
    return np.all(on_b[S.F], axis=1)


def _turned(S, T, fw, reversing=False, faces=None, resolved_angle=np.pi / 3):
    """Per source face (or per face of `faces`, an index array), whether its image turns against
    the target (with `reversing`: does not).

    Where the target's normals at the corners' faces agree (pairwise within `resolved_angle`, the
    certificate's resolved images, verify/map_certificate.h), the chord triangle of the images
    against the sum of those normals decides; elsewhere the chord triangle means nothing (a
    correct near-identity image of a face next to a sharp crease of the poncho tested 'turned'
    against faces folded by 100°+, docs/open_surfaces.md) and the triangle is measured in the
    target's faces unfolded into one plane (_unfolded_signed_area): from each corner's face along a
    breadth-first tree, the shortest valid unfolding deciding; where none reaches or they disagree,
    also along the shortest paths between the corners' faces (_path_unfolded_signed_area), the
    majority of the valid unfoldings deciding (docs/history/open_surfaces.md "Session 27 (open27)")."""
    Vt, Ft = T.V, T.F
    if getattr(T, "face_normals", None) is None:
        T.face_normals = np.cross(Vt[Ft[:, 1]] - Vt[Ft[:, 0]], Vt[Ft[:, 2]] - Vt[Ft[:, 0]])
    nt = T.face_normals
    SF = S.F if faces is None else S.F[np.asarray(faces, dtype=np.int64)]
    q = fw["position"][SF]
    img_n = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    corner_faces = np.asarray(fw["face"])[SF]
    # The target's normal at the face holding each corner's image, summed over the corners.
    normal = sum(nt[corner_faces[:, k]] for k in range(3))
    sign = -1 if reversing else 1
    turned = sign * np.einsum("ij,ij->i", img_n, normal) <= 0
    unit = nt / np.maximum(np.linalg.norm(nt, axis=1), 1e-300)[:, None]
    cos_min = np.min([np.einsum("ij,ij->i", unit[corner_faces[:, a]], unit[corner_faces[:, b]])
                      for a, b in ((0, 1), (1, 2), (0, 2))], axis=0)
    unresolved = cos_min < np.cos(resolved_angle)
    if np.any(unresolved):
        if getattr(T, "face_neighbours", None) is None:
            T.face_neighbours = _face_neighbours(Ft)
        bary = np.asarray(fw["barycentric"])
        for f in np.flatnonzero(unresolved):
            # Unfolded from each corner's face; an unfolding is a chart of the surface along the
            # triangle's sides only if its perimeter is at least the 3D chords' (paths on the surface
            # are no shorter; a strip unfolded around a saddle vertex, angle sum > 2 pi, overlaps
            # itself and its straight sides cut across nothing: measured on the poncho, a face whose
            # image keeps its shape came out negative that way from one corner and positive from the
            # other two). The shortest valid one (nearest the geodesic triangle) decides; none: the
            # chord test stays.
            chord = np.linalg.norm(q[f] - np.roll(q[f], -1, axis=0), axis=1).sum()
            got = []
            for r in range(3):
                order = [r, (r + 1) % 3, (r + 2) % 3]
                got.append(_unfolded_signed_area(Vt, Ft, T.face_neighbours, corner_faces[f][order], bary[SF[f]][order]))
            valid = [g for g in got if g is not None and g[1] >= chord * (1 - 1e-9)]
            if not valid or len({g[0] > 0 for g in valid}) > 1:
                # No tree reaches the other corners' faces within its 400 faces (an image many faces
                # across), or the trees' unfoldings disagree (a fewest-faces tree far from the
                # shortest paths; docs/history/open_surfaces.md "Session 27 (open27)": poncho -> spot's inverse, faces 3025
                # and 455, both read turned here and positive along the shortest paths): the faces
                # on the shortest paths between the corners' faces unfolded too, from each corner,
                # and the majority of the valid unfoldings decides (a tie: the shortest).
                for r in range(3):
                    order = [r, (r + 1) % 3, (r + 2) % 3]
                    g = _path_unfolded_signed_area(T, corner_faces[f][order], bary[SF[f]][order], 10 * chord)
                    if g is not None and g[1] >= chord * (1 - 1e-9):
                        valid.append(g)
            if valid:
                positive = sum(g[0] > 0 for g in valid)
                if 2 * positive == len(valid):
                    turned[f] = sign * min(valid, key=lambda g: g[1])[0] <= 0
                else:
                    turned[f] = (sign > 0) != (2 * positive > len(valid))
    return turned


def _path_unfolded_signed_area(T, faces, bary, reach):
    """_unfolded_signed_area along the shortest paths only: the faces on the shortest paths of T's
    face graph (_face_graph) from faces[0] to faces[1] and to faces[2], unfolded into faces[0]'s
    plane along those paths, however many faces apart. None when a face is farther than `reach`
    along the surface."""
    from scipy.sparse.csgraph import dijkstra
    graph = _face_graph(T)
    dist, pred = dijkstra(graph, indices=int(faces[0]), limit=reach, return_predecessors=True)
    keep = {int(faces[0])}
    for target in faces[1:]:
        g = int(target)
        if not np.isfinite(dist[g]):
            return None
        while g not in keep:
            keep.add(g)
            g = int(pred[g])
    nb = np.where(np.isin(T.face_neighbours, list(keep)), T.face_neighbours, -1)
    return _unfolded_signed_area(T.V, T.F, nb, faces, bary, max_faces=len(keep) + 1)


def _face_graph(T):
    """T's faces as a graph (scipy sparse, cached on T): neighbours across an edge, weighted by the
    path from one centroid to the other through the shared edge's midpoint."""
    if getattr(T, "face_graph", None) is None:
        from scipy.sparse import coo_matrix
        if getattr(T, "face_neighbours", None) is None:
            T.face_neighbours = _face_neighbours(T.F)
        c = T.V[T.F].mean(axis=1)
        rows, cols, w = [], [], []
        for k in range(3):
            g = T.face_neighbours[:, k]
            f = np.flatnonzero(g >= 0)
            mid = 0.5 * (T.V[T.F[f, k]] + T.V[T.F[f, (k + 1) % 3]])
            rows.append(f)
            cols.append(g[f])
            w.append(np.linalg.norm(c[f] - mid, axis=1) + np.linalg.norm(mid - c[g[f]], axis=1) + 1e-300)
        T.face_graph = coo_matrix((np.concatenate(w), (np.concatenate(rows), np.concatenate(cols))),
                                  shape=(len(T.F), len(T.F))).tocsr()
    return T.face_graph


def _slide_ears(A, B, points, reversing, keep):
    """_core.slide_ear_images on a half's map of A onto B ({face, barycentric, position}, changed in
    place), the vertices `keep` (landmarks) held where they are. Returns its counts."""
    got = _core.slide_ear_images(A.V, A.F, B.V, B.F, np.asarray(points["face"]), np.asarray(points["barycentric"]),
                                 reversing=reversing, held=[int(v) for v in np.asarray(keep, dtype=np.int64)])
    for k in ("face", "barycentric", "position"):
        points[k][:] = np.asarray(got[k])
    return {k: int(got[k]) for k in ("ears", "turned", "moved", "moved_with_neighbours", "turned_after")}


#: Reflex-corner slides (docs/open_surfaces.md "The half's solve"): in _finish_half, a boundary image
#: next to a reflex corner of the other side's loop slid onto it; False: not (to compare).
REFLEX_CORNER_SLIDES = True

#: The 3D face-angle sum at a boundary vertex from which the slides call it a reflex corner (the
#: punched holes' staircase corners: up to 312 degrees on double_torus_1 A).
REFLEX_CORNER_ANGLE = np.radians(240.0)


def _boundary_angle_sums(side):
    """Per vertex of side's input mesh the sum of its faces' 3D angles there (n,)."""
    V, F = side.V, side.F
    total = np.zeros(len(V))
    for k in range(3):
        u = V[F[:, (k + 1) % 3]] - V[F[:, k]]
        w = V[F[:, (k + 2) % 3]] - V[F[:, k]]
        c = np.einsum("ij,ij->i", u, w) / np.maximum(np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1), 1e-300)
        np.add.at(total, F[:, k], np.arccos(np.clip(c, -1, 1)))
    return total


def _slide_to_reflex_corners(A, B, points, reversing, keep):
    """A half's map of A onto B ({face, barycentric, position} per input vertex of A, boundary
    vertices on B's loops; changed in place): where two consecutive boundary vertices of an A loop
    have their images on the two B loop edges of a reflex corner c of B (face angles summing to
    REFLEX_CORNER_ANGLE or more), one on each side, the face of A on their edge has its two
    boundary corners' images cutting across the corner, squeezed (double_torus_1 B -> A: D' 10.6 on
    the corner of 312 degrees, the next face 8.1). The one of the two whose image slid onto c gives
    its star's faces the smaller largest D' is slid, when that is smaller than before and no face
    of the star turns over (_turned); `keep` (landmarks) stay. Returns the number of vertices slid."""
    on_b = {}
    for li, loop in enumerate(B.loops):
        for j, v in enumerate(loop):
            on_b[int(v)] = (li, j)
    reflex = _boundary_angle_sums(B) >= REFLEX_CORNER_ANGLE
    face, bary = points["face"], points["barycentric"]
    held = set(int(v) for v in np.asarray(keep).ravel())
    stars = {}

    def star(v):
        if v not in stars:
            stars[v] = np.flatnonzero((A.F == v).any(axis=1))
        return stars[v]

    def loop_edge(v):
        # (loop, index of the edge's first vertex) of the B loop edge v's image lies on, or None
        corners = [int(x) for x, t in zip(B.F[face[v]], bary[v]) if t > 1e-12]
        if len(corners) != 2 or any(c not in on_b for c in corners):
            return None
        (l0, j0), (l1, j1) = on_b[corners[0]], on_b[corners[1]]
        n = len(B.loops[l0])
        if l0 != l1 or (j1 - j0) % n not in (1, n - 1):
            return None
        return l0, j0 if (j1 - j0) % n == 1 else j1

    a_on_b = np.zeros(len(A.V), dtype=bool)
    a_on_b[np.concatenate(A.loops)] = True

    def worst(faces):
        # the largest D' of the faces, ears apart (as the report measures it)
        faces = faces[~a_on_b[A.F[faces]].all(axis=1)]
        return float(np.nanmax(_dilatation(A.V, points["position"], A.F[faces]), initial=0.0))

    moved = 0
    for loop in A.loops:
        for k in range(len(loop)):
            u, w = int(loop[k]), int(loop[(k + 1) % len(loop)])
            eu, ew = loop_edge(u), loop_edge(w)
            if eu is None or ew is None or eu[0] != ew[0]:
                continue
            n = len(B.loops[eu[0]])
            if (ew[1] - eu[1]) % n == 1:
                c = int(B.loops[eu[0]][ew[1]])          # the corner between u's edge and w's
            elif (eu[1] - ew[1]) % n == 1:
                c = int(B.loops[eu[0]][eu[1]])
            else:
                continue
            if not reflex[c]:
                continue
            c_face = int(np.flatnonzero((B.F == c).any(axis=1))[0])
            c_bary = (B.F[c_face] == c).astype(float)
            best = None
            for v in (u, w):
                if v in held:
                    continue
                faces = star(v)
                before = worst(faces)
                saved = face[v], bary[v].copy(), points["position"][v].copy()
                face[v], bary[v], points["position"][v] = c_face, c_bary, B.V[c]
                after = worst(faces)
                turned = _turned(A, B, points, reversing, faces=faces).any()
                face[v], bary[v], points["position"][v] = saved
                if after < before and not turned and (best is None or after < best[0]):
                    best = (after, v)
            if best is not None:
                v = best[1]
                face[v], bary[v], points["position"][v] = c_face, c_bary, B.V[c]
                moved += 1
    return moved


def _alignment(S, T, images):
    """Mean squared distance between the source's vertices and their images, both shapes moved
    to centroid 0 and scaled to unit area (the disk map's alignment measure, map/open_map.h)."""
    def frame(V, F):
        a = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
        c = (a[:, None] * V[F].mean(axis=1)).sum(axis=0) / a.sum()
        return c, np.sqrt(a.sum())
    cs, ss = frame(S.V, S.F)
    ct, st = frame(T.V, T.F)
    return float(np.mean(np.sum(((S.V - cs) / ss - (images - ct) / st) ** 2, axis=1)))


def _has_arrays(x):
    if isinstance(x, np.ndarray):
        return x.ndim > 0
    if isinstance(x, dict):
        return any(_has_arrays(v) for v in x.values())
    return False


def _loop_lengths(side):
    return np.array([np.linalg.norm(side.V[l] - side.V[np.roll(l, -1)], axis=1).sum() for l in side.loops])


def _loop_distances(side):
    """(b, b) shortest distances along the input's edges between the boundary loops (0 on the
    diagonal), over the square root of the surface's area: unchanged by bending (an isometry) and
    by remeshing up to the edge paths' discretization, whatever the genus. Cached on the side."""
    if getattr(side, "loop_distances", None) is None:
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import dijkstra
        E = np.concatenate([side.F[:, [0, 1]], side.F[:, [1, 2]], side.F[:, [2, 0]]])
        w = np.linalg.norm(side.V[E[:, 0]] - side.V[E[:, 1]], axis=1)
        G = coo_matrix((w, (E[:, 0], E[:, 1])), shape=(side.n, side.n)).tocsr()
        area = 0.5 * np.linalg.norm(np.cross(side.V[side.F[:, 1]] - side.V[side.F[:, 0]],
                                             side.V[side.F[:, 2]] - side.V[side.F[:, 0]]), axis=1).sum()
        D = np.zeros((side.b, side.b))
        for i, loop in enumerate(side.loops):
            d = dijkstra(G, directed=False, indices=loop, min_only=True)
            D[i] = [d[l].min() for l in side.loops]
        side.loop_distances = 0.5 * (D + D.T) / np.sqrt(area)
    return side.loop_distances


class _PairingScore:
    """A cheap measure of how well source loop i matches target loop pairing[i] (smaller is
    better), for ranking the b! pairings when there are too many to solve (b >= 4), as a sum of
    non-negative terms each known once loops 0..m are paired (`step`), so that a best-first search
    finds the best pairings without listing all b! (_best_pairings). The terms: the squared
    differences of the loops' log relative lengths; the squared differences of the distances
    between the loops (_loop_distances: loop i to loop j against pairing[i] to pairing[j], each
    pair once; without scipy left out); for genus 0 the squared chordal distances between the
    target's cap centres 3.. and the images of the source's under the Möbius map of the capped
    spheres that sends the first three onto theirs exactly (_sphere_rough_map). Lengths and
    distances do not see the orientation: for genus >= 1 both orientations of a pairing tie."""

    def __init__(self, S, T, options):
        ls, lt = _loop_lengths(S), _loop_lengths(T)
        self.length = (np.log(ls / ls.sum())[:, None] - np.log(lt / lt.sum())[None, :]) ** 2   # (b, b)
        try:
            self.Ds, self.Dt = _loop_distances(S), _loop_distances(T)
        except ImportError:     # scipy missing: lengths (and for genus 0 the cap centres) alone
            self.Ds = self.Dt = None
        self.spheres = None
        if S.genus == 0 and S.b > 3:
            try:
                self.spheres = (_capped_sphere(S, options), _capped_sphere(T, options))
            except _core.SolveError:
                # A capped long thin tube need not uniformize (docs/open_surfaces.md: the artery's
                # bent copy); lengths and distances alone rank the pairings then.
                pass
        self._images = {}

    def _cap_images(self, triple, mirrored):
        """The source cap centres 3.. under the Möbius map sending source centres 0, 1, 2 onto the
        target centres `triple` (on the mirrored source sphere when mirrored); cached."""
        key = (triple, mirrored)
        if key not in self._images:
            (Ps, cs), (Pt, ct) = self.spheres
            if mirrored:
                Ps = Ps * np.array([1.0, -1.0, 1.0])
            src = [_to_homogeneous(Ps[[cs[i]]]) for i in range(3)]
            dst = [_to_homogeneous(Pt[[ct[triple[i]]]]) for i in range(3)]
            M = np.linalg.inv(_three_point_matrix([(u[0], v[0]) for u, v in dst])) @ \
                _three_point_matrix([(u[0], v[0]) for u, v in src])
            u, v = _to_homogeneous(Ps[cs[3:]])
            self._images[key] = _from_homogeneous(M[0, 0] * u + M[0, 1] * v, M[1, 0] * u + M[1, 1] * v)
        return self._images[key]

    def step(self, partial, j, mirrored):
        """The terms added when loop m = len(partial) goes onto target loop j, loops 0..m-1 onto
        `partial`."""
        m = len(partial)
        c = float(self.length[m, j])
        if self.Ds is not None and m:
            c += float(np.sum((self.Ds[:m, m] - self.Dt[list(partial), j]) ** 2))
        if self.spheres is not None and m >= 3:
            (_, _), (Pt, ct) = self.spheres
            c += float(np.sum((self._cap_images(tuple(partial[:3]), mirrored)[m - 3] - Pt[ct[j]]) ** 2))
        return c

    def score(self, pairing, mirrored):
        return sum(self.step(tuple(pairing[:m]), pairing[m], mirrored) for m in range(len(pairing)))


def _pairing_score(S, T, pairing, mirrored, options):
    """_PairingScore of one pairing."""
    return _PairingScore(S, T, options).score(list(pairing), mirrored)


def _best_pairings(terms, b, orientations, count, allow=lambda p: True, max_expansions=200000):
    """The `count` (pairing, orientation, score) of lowest terms.score, best first: a best-first
    search over partial pairings (loops 0..m paired), each scored by the sum of its terms so far;
    the terms are non-negative, so a complete pairing popped from the queue scores no more than
    any not yet popped (exact, without listing the b! pairings). Only pairings `allow` accepts.
    Stops after max_expansions partial pairings (then fewer may come back)."""
    heap = [(0.0, o, ()) for o in orientations]
    out, expanded = [], 0
    while heap and len(out) < count:
        score, o, partial = heapq.heappop(heap)
        if len(partial) == b:
            if allow(list(partial)):
                out.append((partial, o, score))
            continue
        expanded += 1
        if expanded > max_expansions:
            break
        for j in range(b):
            if j not in partial:
                heapq.heappush(heap, (score + terms.step(partial, j, o == "reversing"), o, partial + (j,)))
    return out


def _candidate_tasks(S, T, boundary_pairing, orientations, max_pairings, options, allow=lambda p: True):
    """The (pairing, orientation) pairs to solve and how they were chosen. A given pairing: it, in
    each orientation. Else every pairing in each orientation when there are at most max_pairings
    pairings (b <= 3), else the max_pairings (pairing, orientation) pairs of lowest
    _PairingScore (one uniformization per side for genus 0, a shortest-path search per loop;
    _best_pairings finds them without scoring all b!) with the scores. Only pairings `allow`
    accepts (the boundary landmarks' loops)."""
    b = S.b
    if boundary_pairing is not None:
        p = [int(x) for x in boundary_pairing]
        if sorted(p) != list(range(b)):
            raise _core.InputError(f"boundary_pairing {p}: must be a permutation of 0..{b - 1} (the target loop "
                                   f"of each source loop)")
        if not allow(p):
            raise _core.InputError(f"boundary_pairing {p}: a landmark on a source boundary loop names a vertex of "
                                   f"another target loop")
        return [(tuple(p), o, None) for o in orientations], "given"
    if math.factorial(b) <= max_pairings:
        perms = [p for p in itertools.permutations(range(b)) if allow(p)]
        if not perms:
            raise _core.InputError("landmarks: the boundary landmarks pair one source loop with two target loops")
        return [(p, o, None) for p in perms for o in orientations], "ranked by energy"
    best = _best_pairings(_PairingScore(S, T, options), b, orientations, max_pairings, allow)
    if not best:
        raise _core.InputError("landmarks: the boundary landmarks pair one source loop with two target loops")
    return [(p, o, sc) for p, o, sc in best], (
        f"ranked by energy among the {len(best)} of {math.factorial(b) * len(orientations)} pairings and "
        f"orientations of best loop lengths, distances{' and cap centres' if S.genus == 0 else ''}")


#: The half's solve on the halves refined at their boundary (open_reflection.RefinedHalf), then on
#: the target's refined only, then on the unrefined ones, where each fails (docs/open_surfaces.md
#: "The half's solve"); False: the unrefined ones only (to compare).
REFINE_HALF = True

#: Which of the set-ups that succeed is kept (_reflection_candidate): "ranked" (default) every one
#: solved and measured before the untangling (_setup_quality with untangle=False), then finished with
#: the untangling in that rank's order until one comes out without folds both ways (at most
#: SETUP_FINISHED_AT_MOST of them), the best finished kept; "measured" every one finished with the
#: untangling and the best kept (session 24's rule, to compare); "first" the first in the order above
#: (session 23's rule; docs/open_surfaces.md "The half's solve").
SETUP_CHOICE = "ranked"

#: With SETUP_CHOICE "ranked": how many set-ups of a group at most are finished with the untangling
#: (the next in rank is finished only while every one finished so far leaves folds).
SETUP_FINISHED_AT_MOST = 2


def _setup_quality(S, T, r, sym, reversing, untangle):
    """The delivered map of a set-up's half solve, measured as the report measures it: the half's
    maps (_half: the untangling when `untangle`) finished (_finish_half: the ear slides, the
    inverse's untangling), then the folded faces left forward and in the inverse and the largest and
    the area-weighted mean D' of the forward map's chord triangles, ears left out. Returns (the
    measures, the finished half's dict, which surface_map_open then delivers as it is)."""
    h = _half(S, T, r, reversing, untangle, sym)
    _finish_half(S, T, h, reversing, np.zeros((0, 2), dtype=np.int64), untangle)
    dil = _dilatation(S.V, h["fw"]["position"], S.F)
    keep = ~h["ear"] & np.isfinite(dil)
    P = S.V[S.F]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)[keep]
    # The largest D' away from the folds (faces sharing no corner with a folded one, ears apart): what
    # the untangling, which moves the folds' corners and their neighbours, leaves about as it is;
    # ranks the set-ups before the untangling (_finish_ranked_setups).
    # (The folds as the untangling would find them, before the ear and corner slides, and as left.)
    away = keep.copy()
    if h["flipped"] or h.get("before_faces") is not None:
        folded = (_turned(S, T, h["fw"], reversing) if h["flipped"] else np.zeros(len(S.F), dtype=bool)) & ~h["ear"]
        if h.get("before_faces") is not None:
            folded[h["before_faces"]] = True
        near = np.zeros(S.n, dtype=bool)
        near[S.F[folded].reshape(-1)] = True
        away &= ~np.any(near[S.F], axis=1)
    return {"flipped": int(h["flipped"]), "inverse_flipped": int(h["inv_flipped"]),
            "flipped_before_untangling": int(h["before"]),
            "max_distortion": float(dil[keep].max()) if keep.any() else float("nan"),
            "mean_distortion": float(np.dot(area, dil[keep]) / area.sum()) if area.sum() > 0 else float("nan"),
            "max_distortion_away_from_folds": float(dil[away].max()) if away.any() else float("nan")}, h


def _voted_pairing(S, T, r):
    """The target loop of each source loop as the doubles' map r puts it: the loop of T nearest to
    most of the source loop's images (r's forward positions of the input vertices); not always a
    permutation. (The delivered pairing is the same vote on the half's map: _split_half_correspondence.)"""
    pos = np.asarray(r["forward"]["position"])[:S.n]
    t_vertices = np.concatenate(T.loops)
    t_loop = np.concatenate([np.full(len(l), i) for i, l in enumerate(T.loops)])
    got = []
    for loop in S.loops:
        votes = t_loop[_nearest(pos[loop], T.V[t_vertices])]
        got.append(int(np.bincount(votes, minlength=T.b).argmax()))
    return got


def _realized_pairing(S, T, r, requested):
    """_voted_pairing, or `requested` when that is not a permutation."""
    got = _voted_pairing(S, T, r)
    return got if sorted(got) == list(range(T.b)) else list(requested)


def _chosen_class_again(S, T, images, options, landmarks, keep, whose="the requested", own_images=None):
    """The chosen class's doubles' map solved again (other weights, doubles refined near the
    boundary): (r, note, ''), note _keep_requested_pairing's when the class ranked beside the
    chosen one keeps the pairing `keep` and the winner does not; (None, '', why) when neither keeps
    it. `keep`: the requested pairing, or with an automatic pairing the one the chosen candidate's
    map realized (`whose` then "the chosen candidate's"); None: not checked. own_images: when
    given (a function returning images), tried as the start when `images`' classes do not keep it
    (the note then says so)."""
    r = _double_map(S, T, images, options, landmarks)
    if keep is None:
        return r, "", ""
    try:
        return (*_keep_requested_pairing(S, T, r, images, options, landmarks, keep, whose), "")
    except PairingNotKept as e:
        why = str(e)
    if own_images is None:
        return None, "", why
    # The chosen map's own class: its images (snapped to target vertices as a rough map's are)
    # as the start. Its class is the snapped overlay's when that won on the unrefined doubles,
    # which the refined doubles may not list (the fold test's pair: "not an isomorphism").
    images = own_images()
    try:
        r, note = _keep_requested_pairing(S, T, _double_map(S, T, images, options, landmarks), images, options,
                                          landmarks, keep, whose)
    except _core.Cancelled:
        raise
    except _core.Error as e:
        return None, "", f"{why}; from the chosen map's own images: {e}"
    return r, (f"from the chosen map's own images ({why})" + (f"; {note}" if note else "")), ""


class PairingNotKept(_core.SolveError):
    """A requested boundary pairing that the doubles' map of its class does not keep."""


def _keep_requested_pairing(S, T, r, images, options, landmarks, requested, whose="the requested"):
    """The doubles' map r of a requested pairing's class (`images`), kept to that pairing: returns
    (r or its replacement, a note for the candidate's 'snapped_class', '' when nothing was done).

    The doubles' solve asks for the class of `images` alone (images_only), but the doubles have no
    coarse copy, so the closed pipeline also ranks the snapped overlay's own class beside it
    (hyperbolic_map.cpp add_snapped_class) and the lower energy wins. That class is kept (it brings
    a start twisted about a loop back to the untwisted class: test_open_double.py twisted starts),
    but it may pair the loops otherwise (the fold test's pair, [0, 1, 2] requested: the snapped
    class puts them on [1, 2, 0], 61.00 against 62.70 on the doubles). So when the map does not put
    the source loops on the requested target loops, the other classes of the list (in order of
    energy: the images' own when the snapped class won, the snapped class when the images' class
    won) are solved alone (`homotopy` index) and the first whose map keeps the pairing is taken.
    When none does, PairingNotKept (a SolveError, one line) (docs/open_surfaces.md "The half's solve").
    The chosen class's re-solves call it with an automatic pairing too, `requested` then the
    pairing the chosen candidate's map realized and `whose` "the chosen candidate's"
    (docs/open_surfaces.md "The half's solve")."""
    requested = [int(x) for x in requested]
    got = _voted_pairing(S, T, r)
    if got == requested:
        return r, ""
    hom = r.get("homotopy", {})
    cands = hom.get("candidates", [])
    chosen = int(hom.get("chosen", -1))
    snapped = int(hom.get("snapped_class", {}).get("index", -1))
    energy = lambda k: float(cands[k].get("energy", np.inf))
    name = lambda k: ("the snapped overlay's class" if k == snapped else "the images' class" if snapped >= 0 and
                      len(cands) == 2 else f"class {k}")
    others = sorted((k for k in range(len(cands)) if k != chosen and np.isfinite(energy(k))), key=energy)
    paired = {chosen: got}
    for k in others:
        r2 = _double_map(S, T, images, options, landmarks, homotopy=k)
        paired[k] = _voted_pairing(S, T, r2)
        if paired[k] != requested:
            continue
        if chosen == snapped:
            return r2, (f"not ranked: its doubles' map puts the source loops on target loops {got}, not {whose} "
                        f"{requested} (energy {energy(chosen) / 2:.6g} against the images' class's "
                        f"{energy(k) / 2:.6g}, halved)")
        return r2, (f"taken instead of {name(chosen)}, whose doubles' map puts the source loops on target loops "
                    f"{got}, not {whose} {requested}: {name(k)} (energy {energy(k) / 2:.6g} against "
                    f"{energy(chosen) / 2:.6g}, halved)")
    # The images' class's pairing first (the class asked for), the snapped overlay's beside it.
    own = [k for k in paired if k != snapped]
    first = paired[own[0]] if own else got
    note = (f" (nor does the snapped overlay's class ranked beside it: {paired[snapped]})"
            if snapped in paired and own else "")
    raise PairingNotKept(f"the doubles' map of this class puts the source loops on target loops {first}, not "
                         f"{whose} {requested}{note}")


def _reflection_candidate(S, T, r, pairing, reversing, layouts, cand, untangle=True):
    """The reflection-aware solve (open_reflection.solve_half) of the class of the doubles' map r:
    its result when it converged with every face positively oriented in the metric and every point
    located, cand updated (reflection_energy: the half's with its own weights; symmetry_error 0:
    exact by construction, the doubles' kept as doubles_symmetry_error; status ok, since the
    doubles' symmetry no longer matters; 'energy' stays the doubles' halved, which ranks the
    candidates); else None, the reason in cand['reflection_solve']. layouts: per pair of sides (the
    halves refined at their boundary, RefinedHalf, and the unrefined ones) the target half's metric
    and HalfLayout per orientation, filled on first use. The result's 'sides' are the pair it was
    solved on (_half maps it back through them), 'half' its map finished (_setup_quality), which
    surface_map_open delivers. Every set-up is solved and measured before the untangling, the first
    by that rank finished with it (the next only while folds are left) and the best finished kept
    (SETUP_CHOICE, _finish_ranked_setups); cand['reflection_setups'] lists them. The boundary loops are paired as r's images pair them
    (_realized_pairing), whatever `pairing` requested (docs/open_surfaces.md "The half's solve")."""
    def sides(refined):
        # refined: 2 both halves refined at their boundary, 1 the target's only, 0 neither.
        if not refined:
            return S, T
        if "refined" not in layouts:
            layouts["refined"] = (open_reflection.RefinedHalf(S, split_boundary=False),
                                  open_reflection.RefinedHalf(S, split_boundary=False, rings=0),
                                  open_reflection.RefinedHalf(T, split_boundary=True))
        return layouts["refined"][2 - refined], layouts["refined"][2]

    def cached(key, make):
        # (a failure kept too: the metric is one Ricci flow per pair of sides, not one per attempt)
        if key not in layouts:
            try:
                layouts[key] = make()
            except _core.Cancelled:
                raise
            except _core.Error as e:
                layouts[key] = e
        if isinstance(layouts[key], Exception):
            raise layouts[key]
        return layouts[key]

    def layout(refined, A, B):
        metric = cached((refined > 0, "metric"), lambda: open_reflection.symmetric_metric(B.D))
        return cached((refined > 0, reversing), lambda: open_reflection.HalfLayout(
            B.F2[:, ::-1] if reversing else B.F2, B.D, metric))

    # The half's intrinsic Delaunay weights (the doubles' own) on three set-ups: both halves
    # refined at their boundary, the target's only, neither; where none succeeds, the source's own
    # cotangents floored at 0.1 of the mean (a convex energy on the mesh's own edges, as the closed
    # pipeline's fallback) on the same three. Within a group every set-up is solved and measured
    # before the untangling; in the order of their largest D' away from the folds they are finished
    # with the untangling until one leaves no fold (at most SETUP_FINISHED_AT_MOST), and of those
    # the one whose delivered map measures best is kept (_setup_rank: fewest folded faces both ways,
    # then the smallest largest D'); SETUP_CHOICE "measured": every set-up finished before the
    # choice (session 24's rule); "first": the first that succeeds, in that order
    # (session 23's rule: double_torus_1 A -> B 9.73 where the unrefined halves give 8.63,
    # docs/history/open_surfaces.md "Session 24").
    # The boundary loops as the doubles' map r pairs them (its class is what the half's solve
    # solves): each source loop onto the target loop nearest most of its images. The candidate's
    # pairing may differ (the fold test's pair, [0, 1, 2] asked: the snapped overlay's class's images
    # on [1, 2, 0]; a requested pairing no longer does, _keep_requested_pairing, but an automatic
    # pairing's candidate still can), and a boundary vertex sliding on another loop's geodesic than
    # its image's stalls the solve (docs/open_surfaces.md "The half's solve").
    requested = [int(x) for x in pairing]
    pairing = _realized_pairing(S, T, r, requested)
    groups = [[(refined, weights, floor) for refined in ((2, 1, 0) if REFINE_HALF else (0,))]
              for weights, floor in (("delaunay", None), ("own", 0.1))]
    why, sym, setups = [], None, []
    for group in groups:
        done = []
        for refined, weights, floor in group:
            label = (("both halves refined, " if refined == 2 else "the target's half refined, " if refined else "") +
                     ("intrinsic Delaunay weights" if weights == "delaunay" else "own cotangents floored at 0.1"))
            try:
                A, B = sides(refined)
                forward = open_reflection.refined_forward(A, B, r["forward"]) if refined else r["forward"]
                got = open_reflection.solve_half(A, B, forward, pairing, reversing, layout(refined, A, B),
                                                 weights=weights, weight_floor=floor)
            except _core.Cancelled:
                raise
            except _core.Error as e:
                # (open_reflection.ReflectionSolveError: e.g. an intrinsic Delaunay edge of the double
                # that the half cannot express; the next attempt)
                why.append(f"{label}: {e}")
                setups.append({"setup": label, "status": f"failed: {e}"})
                continue
            bad = [w for w, b in (
                ("not converged (gradient %.3g)" % got["gradient"], not got["converged"]),
                (f"{got['intrinsic_flipped']} faces turned in the metric", got["intrinsic_flipped"]),
                (f"{got['escaped']} interior images beyond the boundary", got["escaped"]),
                (f"{len(got['inverse_unlocated'])} target vertices not located", len(got["inverse_unlocated"])))
                if b]
            if bad:
                why.append(f"{label}: " + ", ".join(bad))
                setups.append({"setup": label, "status": "failed: " + ", ".join(bad)})
                continue
            got["sides"] = (A, B)
            got["refined"] = refined
            # "ranked": measured before the untangling only (finished below, in rank order)
            measured_now = SETUP_CHOICE != "ranked" or not untangle
            quality, got["half"] = _setup_quality(S, T, r, got, reversing, untangle and measured_now)
            setups.append(dict({"setup": label, "status": "ok"}, **quality))
            if not measured_now:
                setups[-1].update(finished=False, before_untangling=dict(quality))
            done.append((quality, label, got, len(setups) - 1))
            if SETUP_CHOICE == "first":
                break
        if done and SETUP_CHOICE == "ranked" and untangle:
            done = _finish_ranked_setups(S, T, r, reversing, done, setups)
        if done:
            quality, label, sym, chosen = min(done, key=lambda x: _setup_rank(x[0]))
            setups[chosen]["chosen"] = True
            others = [f"{lab}: max D' {q['max_distortion']:.3g}" + (
                f", {q['flipped']} / {q['inverse_flipped']} folded" if q["flipped"] + q["inverse_flipped"] else "")
                for q, lab, _, _ in done if lab != label]
            if others:
                why.append("also solved, measured worse: " + "; ".join(others))
            unfinished = [f"{s['setup']}: max D' {s['max_distortion']:.3g} ({s['max_distortion_away_from_folds']:.3g} "
                          f"away from the folds), {s['flipped_before_untangling']} / {s['inverse_flipped']} folded "
                          f"before the untangling" for s in setups if s.get("finished") is False]
            if unfinished:
                why.append("also solved, ranked below and not untangled: " + "; ".join(unfinished))
            break
    cand["reflection_setups"] = setups
    if pairing != requested:
        why.insert(0, f"the loops paired as the doubles' map's images lie, {pairing} (requested {requested})")
    if sym is None:
        cand["reflection_solve"] = "not used: " + "; ".join(why)
        return None
    cand["doubles_symmetry_error"], cand["doubles_status"] = cand.get("symmetry_error"), cand.get("status")
    cand.update(reflection_energy=sym["energy"], symmetry_error=0.0, same_sheet=1.0, status="ok")
    A, B = sym["sides"]
    cand["reflection_solve"] = (f"used: {sym['iterations']} Newton steps, {sym['weights']} weights"
                                + (f", on the {'halves' if sym['refined'] == 2 else 'target half'} refined at "
                                   f"the boundary ({A.n2} / {B.n2} vertices)" if sym["refined"] else "")
                                + f", gradient {sym['gradient']:.2g}, boundary "
                                f"{sym['boundary_off_geodesic']:.2g} off the geodesic, metric asymmetry "
                                f"{sym['metric_error']:.2g} averaged out"
                                + ("" if sym["metric_scheme"] == "vertex scaling" else
                                   f", the target's metric by {sym['metric_scheme']}")
                                + (" (" + "; ".join(why) + ")" if why else ""))
    return sym


def _setup_rank(quality):
    """The order in which set-ups are kept or finished: fewest folded faces (forward plus inverse),
    then the smallest largest D'."""
    return quality["flipped"] + quality["inverse_flipped"], quality["max_distortion"]


def _finish_ranked_setups(S, T, r, reversing, done, setups):
    """SETUP_CHOICE "ranked": done lists (quality before the untangling, label, solve, index in
    setups) of the set-ups that succeeded. In the order of their largest D' away from the folds, then
    the fewest folds (what the untangling leaves about as it is; the folds are what it clears), each is
    finished as the delivered map is (_setup_quality with the untangling both ways: the map made
    again from its solve) until one leaves no folded face either way, at most
    SETUP_FINISHED_AT_MOST; setups[index] then holds the finished measures ('finished' True, the
    earlier ones in 'before_untangling'). A set-up without folds where the untangling would start
    (forward before the ear and corner slides, the inverse after them: _half, _finish_half) needs
    none, so it is finished as measured. Returns the finished ones, as done, to choose from."""
    finished = []
    def rank(x):
        away = x[0]["max_distortion_away_from_folds"]
        return (away if np.isfinite(away) else np.inf), x[0]["flipped"] + x[0]["inverse_flipped"]
    for quality, label, got, index in sorted(done, key=rank):
        if len(finished) >= max(1, SETUP_FINISHED_AT_MOST):
            break
        if quality["flipped_before_untangling"] + quality["inverse_flipped"]:
            quality, got["half"] = _setup_quality(S, T, r, got, reversing, True)
        setups[index].update(quality, finished=True)
        finished.append((quality, label, got, index))
        if quality["flipped"] + quality["inverse_flipped"] == 0:
            break
    return finished


def _half(S, T, r, reversing, untangle, sym=None):
    """The half's maps from the doubles' map r (_half_correspondence), or from the reflection-aware
    solve `sym` when given (_reflected_correspondence), the forward map's folded
    faces untangled (open_untangle) when `untangle`: a dict of fw, inv, pairing, back_pairing,
    snap, before (folded faces before the untangling), untangled (vertices moved), flipped, ears,
    ears_turned, ear (_flips)."""
    fw, inv, pairing, back_pairing, snap = (_half_correspondence(r, S, T) if sym is None else
                                            _reflected_correspondence(sym, *sym.get("sides", (S, T))))
    before = _flips(S, T, fw, reversing)[0]
    # (where the untangling is not made, the folded faces it would start from: _setup_quality's
    # measures away from them)
    before_faces = None
    if before and not untangle:
        before_faces = np.flatnonzero(_turned(S, T, fw, reversing) & ~_flips_ear(S))
    untangled = []
    if before and untangle:
        # The few folds of strongly compressed faces (open_untangle): their interior corners moved
        # within their stars, before the costlier solves below.
        untangled = open_untangle.untangle_half(S, T, fw, lambda f: _turned(S, T, fw, reversing, faces=f), reversing)
    flipped, ears, ears_turned, ear = _flips(S, T, fw, reversing)
    return {"fw": fw, "inv": inv, "pairing": pairing, "back_pairing": back_pairing, "snap": snap, "before": before,
            "untangled": untangled, "flipped": flipped, "ears": ears, "ears_turned": ears_turned, "ear": ear,
            "before_faces": before_faces}


def _finish_half(S, T, h, reversing, lm, untangle):
    """Completes _half's dict h: ears whose chord images turn over slid (both directions,
    landmarks held: ears_fw, ears_inv), the forward counts again, and the inverse (per target
    vertex a point of the source's faces: what the add-on's UVs, colours and bakes read, so a fold
    there is a flipped transferred UV triangle; the doubles' own inverse, with the same kind of
    folds where the inverse map compresses) counted and untangled the same way with the sides
    swapped: inv_before, inv_untangled (target vertices moved), inv_flipped, inv_ears,
    inv_ears_turned."""
    fw, inv = h["fw"], h["inv"]
    # Ears whose chord images turn over (three points of a concave or jagged stretch of the other
    # boundary): the middle corner's image slid along the other boundary (map/ear_images.h).
    h["ears_fw"] = _slide_ears(S, T, fw, reversing, lm[:, 0])
    h["ears_inv"] = _slide_ears(T, S, inv, reversing, lm[:, 1])
    if REFLEX_CORNER_SLIDES:
        h["corners_fw"] = _slide_to_reflex_corners(S, T, fw, reversing, lm[:, 0])
        h["corners_inv"] = _slide_to_reflex_corners(T, S, inv, reversing, lm[:, 1])
    h["flipped"], h["ears"], h["ears_turned"], h["ear"] = _flips(S, T, fw, reversing)
    inv_flipped, inv_ears, inv_ears_turned, _ = _flips(T, S, inv, reversing)
    h["inv_before"], h["inv_untangled"] = inv_flipped, []
    if inv_flipped and untangle:
        h["inv_untangled"] = open_untangle.untangle_half(T, S, inv, lambda f: _turned(T, S, inv, reversing, faces=f),
                                                         reversing)
        inv_flipped, inv_ears, inv_ears_turned, _ = _flips(T, S, inv, reversing)
    h["inv_flipped"], h["inv_ears"], h["inv_ears_turned"] = inv_flipped, inv_ears, inv_ears_turned


def _moved_text(side, moved, whose):
    """The report's words for the untangling's moved vertices of `side`: interior ones moved within
    their stars, boundary ones slid along the other rim (open_untangle._slide_boundary_corners)."""
    on_b = np.zeros(side.n, dtype=bool)
    on_b[np.concatenate(side.loops)] = True
    slid = int(on_b[np.asarray(moved, dtype=np.int64)].sum())
    text = f"{len(moved) - slid} interior {whose}vertices moved within their stars"
    return text + (f" and {slid} boundary {whose}vertices slid along the other rim" if slid else "")


def surface_map_open(Vs, Fs, Vt, Ft, boundary_pairing=None, orientations=("preserving", "reversing"),
                     max_pairings=6, symmetry_tolerance=0.05, tie_tolerance=1e-3, progress=None, landmarks=None,
                     classes_per_pairing=2, boundary_twists=0,
                     untangle=True, refine_rings=4, refine_levels=2, reflection_solve=True, **options):
    """Map between two open surfaces of equal (g, b) through their doubles (module docstring).

    Vs (n_s,3), Fs (m_s,3), Vt, Ft: the meshes (input faces are triangles). boundary_pairing: None
    (b >= 2: every pairing tried when there are at most `max_pairings`, else the `max_pairings`
    (pairing, orientation) pairs of best _pairing_score) or the
    target loop of each source loop; 'swap' for two loops. A given pairing is delivered as given or
    refused: a candidate whose doubles' map puts the source loops on other target loops fails
    ("the doubles' map of this class puts the source loops on target loops [...], not the requested
    [...]"), after the snapped overlay's class, when it won and pairs them otherwise, was replaced by
    the images' class (_keep_requested_pairing; the candidate's 'snapped_class' says so). With the
    automatic pairing each candidate's map is ranked on whatever pairing it realizes (the
    candidate's 'realized_pairing'; its 'pairing' is where its rough map started), and the chosen
    class's re-solves (own-edge weights, doubles refined near the boundary) keep the chosen map's:
    one that pairs otherwise, also from the chosen map's own images, is not used (its
    'source_weights_fallback' / 'refined_near_boundary' says why). orientations: which of 'preserving'
    (the halves onto the halves) and 'reversing' (the source's half onto the target's mirror
    half: an orientation-reversing map of the open surfaces) are tried. The lowest energy wins;
    candidates within `tie_tolerance` (relative, default 1e-3) of it are told apart by the
    alignment of the shapes (`alignment`: mean squared distance of the vertices to their images,
    both shapes at centroid 0 and unit area): exact ties (each pairing's two orientations on a pair
    of pants) and near ties, a near mirror-symmetric shape's mirror image against the identity
    (the artery's decimated copy onto the artery: 12.831174 reversing against 12.833028 preserving,
    1.4e-4 apart; the next classes 0.3% and more above). A candidate counts when its largest |f(sigma x) - sigma f(x)| is
    at most `symmetry_tolerance` of the target's diagonal (default 0.05: the artery's correct
    maps measured 0.033-0.040; the test shapes 0.002-0.006) and 90% of its interior lies on the
    expected half. classes_per_pairing (default 2; genus 0 with b >= 4, the cut disks): the
    classes solved per (pairing, orientation): the cut disks along the chain 0, 1, ..., b - 1 and
    along the other chains of shortest total length (_chains); each is its own candidate
    ('chain' in the candidates), the energy ranks them all (the generated shirt A -> B, loops
    0,1,2,3 preserving: chain 0-1-2-3 E 125.92, chains 0-3-1-2, 1-3-0-2, 0-2-1-3 34.895). options: threads,
    tolerance, max_iterations, method, source_weights, solve_progress (the doubles' solves).
    landmarks: (k, 2) (source vertex, target vertex) pairs of the input meshes, held by the
    capped map and, each with its mirror pair, by the doubles' map (_landmark_pairs); a boundary
    vertex only onto a boundary vertex. 'open' then has 'landmarks' and 'landmark_error'.
    boundary_twists (default 0): also solve each rough map composed with 1..boundary_twists turns,
    both ways, of a Dehn twist about a curve parallel to each target boundary loop (_collar_twist;
    the candidates' 'twist', e.g. 'loop 1: -1'), ranked by energy with the rest. Such a twist T_c
    doubles to T_c T_sigma(c)^-1, and sigma(c) is isotopic to c in the double (both parallel to the
    fixed loop), so it is the doubles' own class: on the pants onto its subdivision every twisted
    start comes back to the untwisted map; on the artery onto its bend the starts twisted about
    the branch loops end 0.2% higher, less symmetric, and the energy keeps the untwisted one
    (docs/open_surfaces.md "Twists about the boundary loops"). Kept to check that.

    Returns the result dict of surfmap.surface_map with 'forward' / 'inverse' (per input vertex
    face, barycentric, position on the other input mesh; boundary onto boundary), 'genus' g,
    'boundary_loops' b, 'source_topology' / 'target_topology', 'flipped_triangles',
    'distortion' {mean, max, per_face} of the morph (ears left out of mean and max), 'energy'
    {'final': the half's energy}, and 'open' {domain 'double', method, boundary_pairing,
    orientation, pairing_choice, candidates [{pairing, orientation, energy, symmetry_error,
    same_sheet, alignment, status, chosen, realized_pairing (the loops as its doubles' map pairs
    them), snapped_class (a given pairing only, when set)}], tied_candidates, symmetry_error, same_sheet,
    snap_distance, double_genus, ear_triangles, ear_triangles_turned, source_weights_fallback,
    untangled_vertices, untangled, inverse_flipped_triangles, inverse_ear_triangles,
    inverse_ear_triangles_turned, inverse_untangled_vertices, inverse_untangled, reflex_corner_slides,
    inverse_reflex_corner_slides (vertices slid, REFLEX_CORNER_SLIDES)}. untangle (default
    True): the interior corners of the half's folded faces are moved within their stars
    (open_untangle.untangle_half) before the own-edge weights' solve is tried; 'untangled' says how
    many faces were folded and how many vertices moved. The inverse (per target vertex a point of
    the source: what the add-on's UVs and colours read) is counted and untangled the same way with
    the sides swapped ('inverse_*': target faces, target vertices moved). refine_rings (default
    4), refine_levels (default 2; 0: not tried): where folds are left after all that (forward or
    in the inverse), the chosen class is solved again on doubles whose faces within refine_rings
    rings of the boundary are split refine_levels times (refine_near_boundary; the images onto
    the input faces as before) and kept when fewer faces fold both ways together
    ('refined_near_boundary' says the counts). Only maps with folds left pay for it (poncho ->
    spot: 6 / 2 folded -> 1 / 2, 240 s more; docs/history/open_surfaces.md "Session 19").
    reflection_solve (default True; CLI --no-reflection-solve): the chosen candidate's class solved
    again on the source's half alone, the mirror half given by the reflections
    (open_reflection.solve_half: symmetric to round-off, the boundary on the target's geodesic
    boundary exactly, own-edge cotangent weights), and, when every candidate was refused as not
    symmetric, theirs (ranked by their doubles' energy like the rest); used when it converges bijective in
    the metric, else the doubles' own half (the reason in the candidate's 'reflection_solve'); not
    with landmarks (the doubles hold them). 'open' 'reflection_solve' says what the chosen map used (docs/open_surfaces.md
    "The half's solve").
    Raises InputError for different (g, b) or a bad pairing, SolveError when no candidate
    maps."""
    S = _Side(Vs, Fs, "source")
    T = _Side(Vt, Ft, "target")
    if (S.genus, S.b) != (T.genus, T.b) or S.b == 0:
        raise _core.InputError(f"the source has {S.describe} but the target has {T.describe}; both must be open "
                               f"with the same genus and number of boundary loops (docs/open_surfaces.md)")
    if isinstance(boundary_pairing, str):
        if boundary_pairing != "swap" or S.b != 2:
            raise _core.InputError(f"boundary_pairing '{boundary_pairing}': 'swap' is for two boundary loops only")
        boundary_pairing = [1, 0]
    orientations = tuple(orientations)
    if not orientations or any(o not in ("preserving", "reversing") for o in orientations):
        raise _core.InputError(f"orientations {orientations}: give 'preserving' and/or 'reversing'")
    lm = _check_landmarks(S, T, landmarks)
    tasks, choice = _candidate_tasks(S, T, boundary_pairing, orientations, max_pairings, options,
                                     allow=lambda p: _landmarks_allow(S, T, lm, p))

    current = {"stage": "doubles", "fraction": 0.0}

    def report(stage, fraction):
        current["stage"], current["fraction"] = stage, fraction
        if progress is not None:
            r = progress(stage, fraction)
            if r is not None and not r:
                raise _core.Cancelled("cancelled by the progress callback")

    if progress is not None:
        # The closed solves inside a candidate (its capped map, its doubles' map) report their
        # stage ends through this, so that a cancel is seen at their next stage instead of after
        # the whole candidate (over 4 minutes for a 30k-vertex genus-2 pair with one hole each:
        # Esc in Blender's Compute Map; docs/addon.md "The solve's thread").
        def inner_progress(stage, fraction):
            r = progress(f"{current['stage']} ({stage})", current["fraction"])
            return r is None or bool(r)
        options = dict(options, inner_progress=inner_progress)

    candidates, solved, refused = [], [], []
    layouts = {}  # the target half laid out for the reflection-aware solve, per orientation
    for ti, (pairing, o, score) in enumerate(tasks):
        report(f"doubles: pairing {list(pairing)}, {o}", ti / max(len(tasks), 1))
        rev = o == "reversing"
        try:
            roughs, rough_method = _rough_maps(S, T, pairing, options, rev, lm, classes_per_pairing)
        except _core.Cancelled:
            raise
        except _core.Error as e:
            candidates.append({"pairing": list(pairing), "orientation": o, "energy": float("inf"),
                               "status": f"failed: the capped map: {e}"})
            continue
        twists = [None] + [{j: s * k} for j in range(T.b) for k in range(1, int(boundary_twists) + 1) for s in (1, -1)]
        for (pos, face, target_xyz, capped_class), twist in itertools.product(roughs, twists):
            cand = {"pairing": list(pairing), "orientation": o, "rough_map": rough_method}
            if score is not None:
                cand["pairing_score"] = score
            if capped_class:
                cand["chain" if rough_method == "cut disks" else "capped_class"] = capped_class
            if twist:
                cand["twist"] = ", ".join(f"loop {j}: {t:+d}" for j, t in twist.items())
            try:
                images = _symmetric_images(S, T, pairing, rev, pos, face, target_xyz, landmarks=lm, twist=twist)
                try:
                    r = _double_map(S, T, images, options, _landmark_pairs(S, T, lm, rev))
                except _core.SolveError as e:
                    if rough_method == "cut disks" and S.b <= 3 and "isomorphism" in str(e):
                        r, images, chain = _other_chains(S, T, pairing, rev, options, lm, twist, e)
                        cand["chain"] = f"chain {chain} (chain {'-'.join(map(str, range(S.b)))}: {e})"
                    elif rough_method == "capped map" and "inverted" not in capped_class and "isomorphism" in str(e):
                        r, images, desc = _reverse_capped_class(S, T, pairing, rev, options, lm, twist, e)
                        cand["capped_class"] = f"{desc} (source -> target: {capped_class}: {e})"
                    else:
                        raise
                if boundary_pairing is not None:
                    # A requested pairing is kept or the candidate fails (one line), never swapped
                    # for the snapped overlay's class's pairing (docs/open_surfaces.md "The half's solve").
                    r, note = _keep_requested_pairing(S, T, r, images, options, _landmark_pairs(S, T, lm, rev),
                                                      pairing)
                    if note:
                        cand["snapped_class"] = note
                # The loops as this candidate's doubles' map pairs them (its 'pairing' is where its
                # rough map started; with an automatic pairing the two may differ, and the chosen
                # candidate's realized pairing is what its re-solves keep below).
                cand["realized_pairing"] = _voted_pairing(S, T, r)
                err, sheet = _symmetry(r, S, T, rev)
                cand.update(energy=float(r["energy"]["final"]) / 2, symmetry_error=err, same_sheet=sheet,
                            status="ok" if err <= symmetry_tolerance and sheet >= 0.9 else
                            f"not symmetric (error {err:.3g} of the diagonal, {sheet:.2f} on the expected half)")
                cand["alignment"] = _alignment(S, T, np.asarray(r["forward"]["position"])[:S.n])
                if cand["status"] == "ok":
                    solved.append((cand, r, rev, images, None))
                else:
                    refused.append((cand, r, rev, images))
            except _core.Cancelled:
                raise
            except _core.Error as e:
                cand.update(energy=float("inf"), status=f"failed: {e}")
            candidates.append(cand)
    if not solved and reflection_solve and not len(lm):
        # Every candidate asymmetric beyond the tolerance (the artery onto the cow's small holes):
        # their classes solved on the half alone, ranked by the doubles' energy as before. (Not
        # when some candidate is symmetric: a class of another pairing costs its walks for nothing;
        # the pants A -> remeshed A went 18 -> 62 s.)
        # In order of that energy, and only until one maps and the next lies beyond its ties: the
        # choice below takes the lowest energy and, within tie_tolerance of it, the best alignment,
        # so a candidate above those cannot be chosen and its solves (each set-up finished and
        # measured, the untangling both ways) are not made (artery -> spot with three holes: 12
        # candidates, every one refused; docs/open_surfaces.md "The half's solve").
        first = None
        for cand, r, rev, images in sorted(refused, key=lambda x: x[0]["energy"]):
            if first is not None and cand["energy"] > first * (1 + tie_tolerance):
                cand["reflection_solve"] = (f"not tried: a candidate of lower energy ({first:.6g}) maps on the "
                                            f"half; this one ({cand['energy']:.6g}) is beyond its ties")
                continue
            sym = _reflection_candidate(S, T, r, cand["pairing"], rev, layouts, cand, untangle)
            if sym is not None:
                solved.append((cand, r, rev, images, sym))
                first = cand["energy"] if first is None else first
    if not solved:
        raise _core.SolveError("open surfaces through their doubles: no candidate mapped: " + "; ".join(
            f"pairing {c['pairing']} {c['orientation']}: {c['status']}"
            + (f" (reflection-aware solve {c['reflection_solve']})" if c.get("reflection_solve") else "")
            for c in candidates))
    # Lowest energy; ties (within tie_tolerance, relative) by the alignment of the shapes: every
    # pair of pants has an anticonformal involution (the reflection swapping its two hexagons),
    # so for (0, 3) each pairing's preserving and reversing maps have the same energy, as the
    # disk's rotations do (map/open_map.h). A near mirror-symmetric shape (the artery: two
    # branches alike) has a mirror class whose energy differs from the identity's by less than
    # two triangulations of the same surface differ (the artery onto its decimated copy: the
    # identity 12.626 one way, 12.833 the other), so the energy alone cannot tell them apart
    # and, within 1e-3, the alignment decides.
    lowest = min(x[0]["energy"] for x in solved)
    tied = [x for x in solved if x[0]["energy"] <= lowest * (1 + tie_tolerance)]
    cand, r, rev, chosen_images, sym = min(tied, key=lambda x: x[0]["alignment"])
    for c in candidates:
        c["chosen"] = c is cand
    report("doubles: the half", 0.95)
    if sym is None and reflection_solve and not len(lm):
        sym = _reflection_candidate(S, T, r, cand["pairing"], rev, layouts, cand, untangle)
    # (the half's solve's map was finished when its set-up was measured: _setup_quality)
    h = sym["half"] if sym is not None else _half(S, T, r, rev, untangle)
    chosen_options = options
    # The chosen class's re-solves below (the own-edge weights, the doubles refined near the
    # boundary) keep the pairing of the map that was ranked and chosen: the requested one, or with
    # an automatic pairing the one the chosen candidate's doubles' map realized (its half's solve
    # slid the boundary on those loops, _reflection_candidate); a re-solve that pairs otherwise,
    # even with the class ranked beside it solved alone, is not used (docs/open_surfaces.md
    # "The half's solve").
    if boundary_pairing is not None:
        requested, whose = cand["pairing"], "the requested"
    else:
        requested, whose = _realized_pairing(S, T, r, cand["pairing"]), "the chosen candidate's"
    chosen_pairing = list(h["pairing"])

    def own_images(r=r):
        return _own_images(S, T, r, requested, rev, lm)
    if h["flipped"] and "source_weights" not in options and sym is None:
        # As the closed pipeline's automatic weights (SourceWeights::Automatic): the intrinsic
        # Delaunay weights' straight images of the user's faces fold (here next to the boundary,
        # where the half is cut out of a map symmetric only up to the discretization), so the
        # chosen class is solved again with positive weights on the source's own edges.
        own = dict(options, source_weights="own")
        r2, kept_by, not_kept = _chosen_class_again(S, T, chosen_images, own, _landmark_pairs(S, T, lm, rev),
                                                    requested, whose, own_images)
        h2 = None if not_kept else _half(S, T, r2, rev, untangle)
        if h2 is not None and list(h2["pairing"]) != chosen_pairing:
            not_kept = (f"its half puts the source loops on target loops {list(h2['pairing'])}, not {chosen_pairing} "
                        f"as the chosen map's")
        if not_kept:
            h["weights_fallback"] = (f"{h['flipped']} flipped with the intrinsic Delaunay weights; solved again on "
                                     f"the source's own edges: not used, {not_kept}")
        else:
            h2["weights_fallback"] = (f"{h['flipped']} flipped with the intrinsic Delaunay weights"
                                      f"{' after untangling' if h['untangled'] else ''}; solved again on the source's "
                                      f"own edges: {h2['flipped']} flipped{' after untangling' if h2['untangled'] else ''}"
                                      + (f" ({kept_by})" if kept_by else ""))
            if h2["flipped"] < h["flipped"]:
                r, chosen_options = r2, own
                cand = dict(cand, energy=float(r2["energy"]["final"]) / 2)
                cand["symmetry_error"], cand["same_sheet"] = _symmetry(r2, S, T, rev)
                h = h2
            else:
                h["weights_fallback"] = h2["weights_fallback"]
    if sym is None:
        _finish_half(S, T, h, rev, lm, untangle)
    refined = ""
    if (h["flipped"] or h["inv_flipped"]) and refine_levels > 0:
        # Folds left next to the boundary: the chosen class solved again on doubles refined near
        # their boundaries (refine_near_boundary), where the images of a strongly compressed
        # collar crowd into the first ring of faces of the other side's loop.
        S2 = _Side(S.V, S.F, "source", refine_rings=refine_rings, refine_levels=refine_levels)
        T2 = _Side(T.V, T.F, "target", refine_rings=refine_rings, refine_levels=refine_levels)
        images3 = _refined_images(S, T, S2, T2, chosen_images)
        r3, kept_by, not_kept = _chosen_class_again(S2, T2, images3, chosen_options,
                                                    _landmark_pairs(S2, T2, lm, rev), requested, whose,
                                                    lambda: _refined_images(S, T, S2, T2, own_images(r)))
        if not_kept:
            refined = (f"{h['flipped']} flipped / {h['inv_flipped']} in the inverse; solved again on the doubles "
                       f"refined within {refine_rings} rings of the boundary {refine_levels} times: not used, "
                       f"{not_kept}")
        else:
            # The half's maps through the refined sides' faces (their input meshes are S's and T's).
            sym3, refined_reflection = None, ""
            if sym is not None:
                c3 = {}
                sym3 = _reflection_candidate(S2, T2, r3, cand["pairing"], rev, {}, c3, untangle)
                if sym3 is None:
                    refined_reflection = c3.get("reflection_solve", "")
            h3 = sym3["half"] if sym3 is not None else _half(S2, T2, r3, rev, untangle)
            if sym3 is None:
                _finish_half(S2, T2, h3, rev, lm, untangle)
            refined = (f"{h['flipped']} flipped / {h['inv_flipped']} in the inverse; solved again on the doubles refined "
                       f"within {refine_rings} rings of the boundary {refine_levels} times ({S2.n2} / {T2.n2} vertices "
                       f"on the halves): {h3['flipped']} / {h3['inv_flipped']}")
            if sym is not None:
                refined += (" (reflection-aware solve)" if sym3 is not None else
                            f" (the doubles' half: {refined_reflection})")
            if kept_by:
                refined += f" ({kept_by})"
            moved_loops = list(h3["pairing"]) != chosen_pairing
            if moved_loops:
                refined += (f": not used, its half puts the source loops on target loops {list(h3['pairing'])}, "
                            f"not {chosen_pairing} as the chosen map's")
            if not moved_loops and h3["flipped"] + h3["inv_flipped"] < h["flipped"] + h["inv_flipped"]:
                h3["weights_fallback"] = h.get("weights_fallback", "")
                r, h, sym = r3, h3, sym3
                cand = dict(cand, energy=float(r3["energy"]["final"]) / 2)
                cand["symmetry_error"], cand["same_sheet"] = (_symmetry(r3, S2, T2, rev) if sym3 is None else
                                                              (0.0, 1.0))
                if sym3 is not None:
                    cand["reflection_setups"] = c3.get("reflection_setups", [])
    fw, inv, pairing, back_pairing, snap = h["fw"], h["inv"], h["pairing"], h["back_pairing"], h["snap"]
    if boundary_pairing is not None and list(pairing) != list(cand["pairing"]):
        # (The half's loops by the same vote as _keep_requested_pairing's: not expected to differ.)
        raise PairingNotKept(f"boundary_pairing {cand['pairing']}: the map found puts the source loops on target "
                             f"loops {list(pairing)} ({cand['orientation']}), not the requested pairing")
    flipped, ears, ears_turned, ear = h["flipped"], h["ears"], h["ears_turned"], h["ear"]
    untangled, flipped_before_untangling = h["untangled"], h["before"]
    weights_fallback, ears_fw, ears_inv = h.get("weights_fallback", ""), h["ears_fw"], h["ears_inv"]
    inv_flipped, inv_ears, inv_ears_turned = h["inv_flipped"], h["inv_ears"], h["inv_ears_turned"]
    inv_untangled, inv_flipped_before = h["inv_untangled"], h["inv_before"]
    dil = _dilatation(S.V, fw["position"], S.F)
    finite = dil[~ear & np.isfinite(dil)]
    # The doubles' report, less what is per vertex or per face of the doubles (the initial map,
    # landmarks, per-polygon figures): the half's arrays replace them.
    out = {k: v for k, v in r.items() if not _has_arrays(v)}
    out["forward"], out["inverse"] = fw, inv
    out["genus"] = S.genus
    out["boundary_loops"] = S.b
    for key, side in (("source_topology", S), ("target_topology", T)):
        out[key] = {"genus": side.genus, "boundary_loops": side.b, "description": side.describe}
    out["flipped_triangles"] = flipped
    # Weighted by the source faces' 3D areas, as every other map's mean D' (map/map_report.cpp
    # distortion_measure); the plain mean beside it.
    keep = ~ear & np.isfinite(dil)
    P = S.V[S.F]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)[keep]
    mean = float(np.dot(area, finite) / area.sum()) if len(finite) and area.sum() > 0 else float("nan")
    out["distortion"] = {"mean": mean, "max": float(finite.max()) if len(finite) else float("nan"),
                         "unweighted_mean": float(finite.mean()) if len(finite) else float("nan"),
                         "measure": "D' = ratio of the singular values of the affine map from each source "
                                    "face onto the triangle of its corners' images on the target in 3D (the "
                                    "morph's triangles); mean weighted by the source faces' 3D areas "
                                    "(unweighted_mean: every face alike), max over the faces; ear triangles "
                                    "left out (open.ear_triangles)",
                         "per_face": dil}
    out["mean_dilatation"], out["max_dilatation"] = out["distortion"]["mean"], out["distortion"]["max"]
    # The half's energies: half the doubles' (the map is symmetric).
    out["energy"] = {k: (v / 2 if isinstance(v, (int, float)) and not isinstance(v, bool) else v)
                     for k, v in r["energy"].items() if not _has_arrays(v)}
    # energy.ranking: the doubles' halved, which ranked the candidates (always present; equal to
    # energy.final unless the half's solve delivered the map).
    out["energy"]["ranking"] = out["energy"].get("final")
    if sym is not None:
        # The delivered map is the half's solve: energy.final is its energy (the half's, in the
        # same units as the doubles' halved: half the energy of the symmetric doubles' map on the
        # doubles' unrefined intrinsic Delaunay weights; = open.reflection_energy)
        # (docs/open_surfaces.md "The half's solve").
        out["energy"]["final"] = float(sym["energy"])
        out["converged"] = bool(out.get("converged", True)) and sym["converged"]
    out["source_flipped"] = out["target_flipped"] = False
    out["open"] = {"domain": "double", "method": f"doubling (symmetric class from the {cand.get('rough_map', 'capped map')})",
                   "boundary_pairing": pairing, "requested_pairing": cand["pairing"],
                   "inverse_pairing": back_pairing, "orientation": cand["orientation"], "pairing_choice": choice,
                   "candidates": candidates, "tied_candidates": len(tied), "symmetry_error": cand["symmetry_error"],
                   "same_sheet": cand["same_sheet"], "snap_distance": snap, "double_genus": int(r["genus"]),
                   "ear_triangles": ears, "ear_triangles_turned": ears_turned,
                   "source_weights_fallback": weights_fallback, "refined_near_boundary": refined,
                   "reflection_solve": cand.get("reflection_solve", "off" if not reflection_solve else
                                                "not with landmarks" if len(lm) else ""),
                   "reflection_energy": sym["energy"] if sym is not None else float("nan"),
                   "reflection_iterations": sym["iterations"] if sym is not None else 0,
                   # each set-up of the half's solve tried: its words, status, and the measures it
                   # was ranked and chosen by (flipped, inverse_flipped, flipped_before_untangling,
                   # max / mean_distortion, max_distortion_away_from_folds; finished,
                   # before_untangling: docs/open_surfaces.md "The half's solve")
                   "reflection_setups": cand.get("reflection_setups", []) if sym is not None else [],
                   # the vertices of the source's and the target's halves it was solved on (the
                   # halves refined at their boundary: more than the split halves'; Session 23)
                   "reflection_half_vertices": [int(x.n2) for x in sym["sides"]] if sym is not None else [],
                   "untangled_vertices": len(untangled),
                   "untangled": (f"{flipped_before_untangling} folded faces; {_moved_text(S, untangled, '')}, "
                                 f"{flipped} folded left" if untangled else ""),
                   "ears_turned": ears_fw["turned"], "ears_slid": ears_fw["moved"],
                   "ears_slid_with_neighbours": ears_fw["moved_with_neighbours"],
                   "inverse_ears_turned": ears_inv["turned"], "inverse_ears_slid": ears_inv["moved"],
                   "inverse_ears_slid_with_neighbours": ears_inv["moved_with_neighbours"],
                   # boundary images slid onto a reflex corner of the other side's loop
                   # (REFLEX_CORNER_SLIDES; Session 25)
                   "reflex_corner_slides": h.get("corners_fw", 0),
                   "inverse_reflex_corner_slides": h.get("corners_inv", 0),
                   "inverse_flipped_triangles": inv_flipped, "inverse_ear_triangles": inv_ears,
                   "inverse_ear_triangles_turned": inv_ears_turned, "inverse_untangled_vertices": len(inv_untangled),
                   "inverse_untangled": (f"{inv_flipped_before} folded faces; {_moved_text(T, inv_untangled, 'target ')}, "
                                         f"{inv_flipped} folded left" if inv_untangled else ""),
                   "landmarks": len(lm),
                   "landmark_error": float(np.max(np.linalg.norm(fw["position"][lm[:, 0]] - T.V[lm[:, 1]], axis=1),
                                                  initial=0.0))}
    return out


def map_by_doubling(Vs, Fs, Vt, Ft, **kw):
    """Earlier name of surface_map_open (kept for scripts)."""
    return surface_map_open(Vs, Fs, Vt, Ft, **kw)


# -- `surfmap map` for open pairs beyond disks and annuli (cli/cmd_map_open.cpp runs this module) --

INVERSE_SECTION_MARKER = "# inverse: one line per target vertex, 'source_face b0 b1 b2'"  # verify/correspondence_file.h


def correspondence_text(forward, inverse):
    """The correspondence file of `surfmap map --correspondence` (verify/correspondence_file.h):
    one 'face b0 b1 b2' line per source vertex, the inverse section's marker, one per target vertex."""
    lines = []
    for pts in (forward, inverse):
        for f, b in zip(pts["face"], pts["barycentric"]):
            lines.append(f"{int(f)} {b[0]:.17g} {b[1]:.17g} {b[2]:.17g}")
        if pts is forward:
            lines.append(INVERSE_SECTION_MARKER)
    return "\n".join(lines) + "\n"


def report_json(r):
    """The --report of an open map through the doubles: the closed report's main keys plus the
    open block (JSON-ready; per-face and per-vertex arrays left out)."""
    def clean(x):
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items() if not isinstance(v, np.ndarray)}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if isinstance(x, (np.integer,)):
            return int(x)
        if isinstance(x, (np.floating, float)):
            return float(x) if np.isfinite(x) else None
        return x
    keys = ("genus", "boundary_loops", "source_topology", "target_topology", "flipped_triangles", "open")
    out = {"method": "open", **{k: clean(r[k]) for k in keys}}
    out["distortion"] = {"mean": clean(r["distortion"]["mean"]), "max": clean(r["distortion"]["max"])}
    out["energy"] = {"final": clean(r["energy"]["final"])}
    out["double"] = {k: clean(r[k]) for k in ("homotopy", "two_way_status", "energy_ratio", "target_metric",
                                              "target_metric_choice") if k in r}
    return out


def _atomic_write(path, text):
    import os
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def _read_landmarks(path):
    """The --landmarks file (the closed maps' format): (k, 2) source / target vertex pairs."""
    pairs = []
    try:
        lines = open(path).read().splitlines()
    except OSError:
        raise _core.InputError(f"cannot read landmarks file {path}") from None
    for number, line in enumerate(lines, 1):
        words = line.split("#")[0].split()
        if not words:
            continue
        if len(words) != 2 or not all(w.isdigit() for w in words):
            raise _core.InputError(f"{path}:{number}: expected two vertex indices, got '{line}'")
        pairs.append([int(words[0]), int(words[1])])
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def main(argv=None):
    import argparse
    ap = argparse.ArgumentParser(prog="surfmap map", description="Open surfaces through their doubles "
                                 "(docs/open_surfaces.md); run by `surfmap map` for open pairs beyond disks and annuli")
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--out", required=True)
    ap.add_argument("--report", required=True)
    ap.add_argument("--correspondence", default="")
    ap.add_argument("--boundary-pairing", default="")
    ap.add_argument("--boundary-swap", action="store_true")
    ap.add_argument("--landmarks", default="", help="'source_vertex target_vertex' lines ('#' comments)")
    ap.add_argument("--refine-rings", type=int, default=4)
    ap.add_argument("--refine-levels", type=int, default=2)
    ap.add_argument("--no-reflection-solve", action="store_true")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    try:
        meshes = []
        for path in (a.src, a.dst):
            V, polys = _core.read_polygon_soup(path)
            try:
                it = _core.intake(V, polys, allow_boundary=True)
            except _core.InputError as e:
                raise _core.InputError(f"'{path}': {e}") from None
            meshes.append((np.asarray(it["V"]), np.asarray(it["F"])))
        pairing = None
        if a.boundary_swap:
            pairing = "swap"
        elif a.boundary_pairing:
            try:
                pairing = [int(x) for x in a.boundary_pairing.replace(",", " ").split()]
            except ValueError:
                raise _core.InputError(f"--boundary-pairing '{a.boundary_pairing}': give loop indices such as 1,0,2") from None
        progress = None
        if not a.quiet:
            def progress(stage, fraction):
                print(f"surfmap: {stage}", file=sys.stderr, flush=True)
        landmarks = _read_landmarks(a.landmarks) if a.landmarks else None
        r = surface_map_open(*meshes[0], *meshes[1], boundary_pairing=pairing, progress=progress, landmarks=landmarks,
                             refine_rings=a.refine_rings, refine_levels=a.refine_levels,
                             reflection_solve=not a.no_reflection_solve)
        rep = report_json(r)
        rep["source"], rep["target"] = a.src, a.dst
        text = {a.report: json.dumps(rep, indent=2) + "\n"}
        if a.correspondence:
            text[a.correspondence] = correspondence_text(r["forward"], r["inverse"])
        _core.write_obj(a.out, r["forward"]["position"], meshes[0][1])
        for path, t in text.items():
            _atomic_write(path, t)
    except _core.Cancelled as e:
        print(f"surfmap: cancelled: {e}", file=sys.stderr)
        return 1
    except _core.Error as e:
        print(f"surfmap: error: {e}", file=sys.stderr)
        return 1
    if not a.quiet:
        o = r["open"]
        print(f"surfmap: through the doubles (genus {o['double_genus']}), boundary loops {o['boundary_pairing']} "
              f"({o['orientation']}, {o['pairing_choice']}), mean dilatation {r['distortion']['mean']:.6g}, "
              f"max {r['distortion']['max']:.6g}, flipped triangles {r['flipped_triangles']}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
