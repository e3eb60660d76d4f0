"""Shape comparison through a common domain (or pairwise maps): the distance table
E(Si, Sj) = ∫_T |λi − λj|² + β |Hi − Hj|² dp and its plots. Definitions: docs/many_shapes.md.

Domain mode: every shape Si is mapped once onto the common domain T (its optimal class,
the native map); through the inverse map g_i: T -> Si (each domain vertex located on Si)

* λi(v) = log( (A_Si(g_i(ring v)) / A_Si(g_i(T))) / (A_T(ring v) / A_T(T)) ): the log of the
  area ratio of v's one-ring (the faces around v) on Si, through g_i, and on T, each
  normalised by its total area;
* Hi(v) = mean curvature of Si at g_i(v), scale-free: H · sqrt(A_Si / 4π) (1 on a round
  sphere; the add-on's mean-curvature colour), interpolated from Si's vertices;
* E(Si, Sj) = Σ_v a_v (|λi(v) − λj(σ v)|² + β |Hi(v) − Hj(σ v)|²), a_v the one-third
  one-ring area of v on T over T's area (so ∫_T dp = 1), minimised over the rotations σ of
  the domain onto itself (detected; the class search cannot tell symmetric classes apart).

Direct mode (no domain): Si is mapped onto Sj for every i < j and the same sum is taken on
T = Sj with λj = 0 and Hj Sj's own curvature. Both modes are scale invariant (every area is
normalised, H is scale-free; shapes are also centred and scaled to unit area before mapping)
and rotation invariant (everything is intrinsic). The table is symmetric with zeros on the
diagonal by construction (E(Si, Sj) is computed for i < j and mirrored).
"""
import argparse
import csv
import json
import math
import os
import sys

import numpy as np

from . import _core
from .mapcall import forward_points, inverse_points, map_report, run_map  # noqa: F401

# ---- meshes ----------------------------------------------------------------------------


def load_shape(shape):
    """A path (OBJ/OFF/PLY/STL, validated and oriented outward) or a (V, F) pair ->
    (V float64 (n,3), F int64 (m,3))."""
    if isinstance(shape, (str, os.PathLike)):
        d = _core.load_mesh(os.fspath(shape))
    else:
        d = _core.intake(np.asarray(shape[0], dtype=np.float64), np.asarray(shape[1]))
    return np.asarray(d["V"], dtype=np.float64), np.asarray(d["F"], dtype=np.int64)


def face_areas(V, F):
    P = V[F]
    return 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)


def normalise(V, F):
    """Centred at the area-weighted centroid and scaled to total area 1."""
    a = face_areas(V, F)
    centroid = (a[:, None] * V[F].mean(axis=1)).sum(axis=0) / a.sum()
    return (V - centroid) / math.sqrt(a.sum())


def vertex_ring_areas(V, F, a=None):
    """Area of the faces around each vertex (n,)."""
    a = face_areas(V, F) if a is None else a
    ring = np.zeros(len(V))
    for k in range(3):
        np.add.at(ring, F[:, k], a)
    return ring


def vertex_normals(V, F):
    P = V[F]
    n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    N = np.zeros_like(V)
    for k in range(3):
        np.add.at(N, F[:, k], n)
    return N / np.maximum(np.linalg.norm(N, axis=1), 1e-300)[:, None]


def mean_curvature(V, F):
    """Signed scale-free mean curvature per vertex, H · sqrt(A / 4π) (A the total area; 1 on
    any round sphere): half the cotangent Laplacian of the position over the barycentric
    one-ring area, positive where the surface is convex along its outward normal. The same
    formula as the add-on's mean-curvature colour (addon mapping.mean_curvature)."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    L = np.zeros((len(V), 3))
    for k in range(3):
        i, j, o = F[:, k], F[:, (k + 1) % 3], F[:, (k + 2) % 3]
        u, w = V[i] - V[o], V[j] - V[o]
        cot = np.einsum("ij,ij->i", u, w) / np.maximum(np.linalg.norm(np.cross(u, w), axis=1), 1e-300)
        d = (V[j] - V[i]) * cot[:, None] * 0.5
        np.add.at(L, i, d)
        np.add.at(L, j, -d)
    a = face_areas(V, F)
    area = vertex_ring_areas(V, F, a) / 3.0
    area[area == 0] = 1e-300
    Hn = L / area[:, None]
    H = 0.5 * np.linalg.norm(Hn, axis=1)
    sign = -np.sign(np.einsum("ij,ij->i", Hn, vertex_normals(V, F)))
    sign[sign == 0] = 1.0
    return H * sign * math.sqrt(a.sum() / (4 * math.pi))


# ---- fields on the domain ---------------------------------------------------------------


def pulled_back_fields(V_shape, F_shape, V_dom, F_dom, inv_face, inv_bary, inv_pos, H_shape=None):
    """λ and H of a shape on the domain's vertices, through the inverse map (each domain
    vertex located on the shape: face (nd,), barycentric (nd,3), position (nd,3)).
    Returns (lam (nd,), H (nd,))."""
    a_dom = face_areas(V_dom, F_dom)
    a_img = face_areas(inv_pos, F_dom)
    ring_dom = vertex_ring_areas(V_dom, F_dom, a_dom) / a_dom.sum()
    ring_img = vertex_ring_areas(inv_pos, F_dom, a_img) / max(a_img.sum(), 1e-300)
    lam = np.log(np.maximum(ring_img, 1e-300) / np.maximum(ring_dom, 1e-300))
    if H_shape is None:
        H_shape = mean_curvature(V_shape, F_shape)
    corners = np.asarray(F_shape, dtype=np.int64)[np.asarray(inv_face, dtype=np.int64)]
    H = np.einsum("ik,ik->i", np.asarray(inv_bary, dtype=np.float64), H_shape[corners])
    return lam, H


def map_normalised(Vs, Fs, Vt, Ft, map_options=None, progress=None):
    """The native map between the two shapes each centred and scaled to unit area (so the
    class search's overlays see them alike). Faces and barycentrics of the result refer to
    the given meshes; its positions are in the normalised coordinates."""
    return run_map(normalise(Vs, Fs), Fs, normalise(Vt, Ft), Ft, map_options, progress=progress)


def domain_fields(shape, domain, map_options=None, progress=None):
    """Maps one shape onto the domain (both normalised to unit area) and returns
    {"lambda": (nd,), "H": (nd,), "report": map_report}."""
    Vs, Fs = load_shape(shape)
    Vd, Fd = load_shape(domain)
    # Genus 1: every shape placed on the domain by the base vertices, not by the 3D overlay,
    # whose placement depends on each shape's pose (docs/handle_classes.md).
    map_options = {"flat_overlay": False, **(map_options or {})}
    m = map_normalised(Vs, Fs, Vd, Fd, map_options, progress=progress)
    face, bary, pos = inverse_points(m)
    lam, H = pulled_back_fields(Vs, Fs, Vd, Fd, face, bary, pos)
    return {"lambda": lam, "H": H, "report": map_report(m)}


def domain_weights(V_dom, F_dom):
    """a_v: one third of the one-ring area over the total area (sums to 1)."""
    a = face_areas(V_dom, F_dom)
    return vertex_ring_areas(V_dom, F_dom, a) / (3.0 * a.sum())


def _rotation(axis_flip, theta):
    c, s = math.cos(theta), math.sin(theta)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    return np.diag([1.0, -1.0, -1.0]) @ Rz if axis_flip else Rz


def domain_symmetries(V_dom, F_dom, max_order=8):
    """Rotations of the (unit-area, centred) domain onto itself, as vertex permutations
    (nearest vertex of the rotated vertex): the identity first. Candidates: rotations about z
    by 2πk/n (n <= max_order) and those composed with the half-turn about x; one is kept when
    every rotated vertex lies within one mean edge length of a domain vertex."""
    from scipy.spatial import cKDTree

    V = normalise(np.asarray(V_dom, dtype=np.float64), F_dom)
    F = np.asarray(F_dom, dtype=np.int64)
    edge = np.linalg.norm(V[F[:, 1]] - V[F[:, 0]], axis=1).mean()
    tree = cKDTree(V)
    angles = sorted({round((2 * math.pi * k / n) % (2 * math.pi), 12)
                     for n in range(1, max_order + 1) for k in range(n)})
    perms, seen = [], set()
    for flip in (False, True):
        for theta in angles:
            dist, idx = tree.query(V @ _rotation(flip, theta).T)
            if dist.max() < edge:
                key = idx.tobytes()
                if key not in seen:
                    seen.add(key)
                    perms.append(idx)
    return perms


def field_distance(lam_i, H_i, lam_j, H_j, weights, beta, symmetries=None):
    """min over σ of Σ_v a_v (|λi(v) − λj(σv)|² + β |Hi(v) − Hj(σv)|²)."""
    best = math.inf
    for p in symmetries if symmetries else [np.arange(len(weights))]:
        e = float(np.dot(weights, (lam_i - lam_j[p]) ** 2 + beta * (H_i - H_j[p]) ** 2))
        best = min(best, e)
    return best


def distance_matrix(fields, V_dom, F_dom, beta=1.0, symmetries=None):
    """Symmetric (n,n) table from per-shape fields [(lam, H), ...] on one domain; E(i,j) for
    i < j is mirrored, the diagonal is 0."""
    w = domain_weights(V_dom, F_dom)
    n = len(fields)
    E = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            E[i, j] = E[j, i] = field_distance(fields[i][0], fields[i][1], fields[j][0], fields[j][1],
                                               w, beta, symmetries)
    return E


def pair_distance(shape_i, shape_j, beta=1.0, map_options=None, progress=None):
    """Direct mode: shape i mapped onto shape j, E integrated over shape j (λj = 0).
    Returns (E, map_report)."""
    Vi, Fi = load_shape(shape_i)
    Vj, Fj = load_shape(shape_j)
    m = map_normalised(Vi, Fi, Vj, Fj, map_options, progress=progress)
    return distance_of_map(Vi, Fi, Vj, Fj, m, beta), map_report(m)


def distance_of_map(Vi, Fi, Vj, Fj, m, beta=1.0):
    """Direct mode's E from a computed map i -> j (the native result dict)."""
    face, bary, pos = inverse_points(m)
    lam, H = pulled_back_fields(Vi, Fi, Vj, Fj, face, bary, pos)
    return field_distance(lam, H, np.zeros_like(lam), mean_curvature(Vj, Fj), domain_weights(Vj, Fj), beta)


def shape_name(shape, k):
    if isinstance(shape, (str, os.PathLike)):
        return os.path.splitext(os.path.basename(os.fspath(shape)))[0]
    return f"shape{k}"


def compare(shapes, domain=None, beta=1.0, names=None, map_options=None, symmetries=True,
            progress=None):
    """Distance table of the shapes (paths or (V, F) pairs).

    domain: a path or (V, F) of the common domain (every shape mapped once onto it), or None
    for the direct pairwise mode (every pair mapped). progress(done, total, name) after each
    map. Returns {"names", "matrix" (numpy (n,n)), "mode", "beta", "reports", "symmetries"}
    (domain mode also "lambda", "H": (n, nd) arrays on the domain's vertices)."""
    n = len(shapes)
    names = list(names) if names else [shape_name(s, k) for k, s in enumerate(shapes)]
    if len(names) != n:
        raise _core.InputError(f"{len(names)} names for {n} shapes")
    if domain is not None:
        Vd, Fd = load_shape(domain)
        fields, reports = [], []
        for k, s in enumerate(shapes):
            try:
                f = domain_fields(s, (Vd, Fd), map_options)
            except _core.Error as e:
                raise type(e)(f"{names[k]}: {e}") from None
            fields.append((f["lambda"], f["H"]))
            reports.append(dict(f["report"], name=names[k]))
            if progress:
                progress(k + 1, n, names[k])
        syms = domain_symmetries(Vd, Fd) if symmetries else None
        E = distance_matrix(fields, Vd, Fd, beta, syms)
        return {"names": names, "matrix": E, "mode": "domain", "beta": beta, "reports": reports,
                "symmetries": len(syms) if syms else 1,
                "lambda": np.array([f[0] for f in fields]), "H": np.array([f[1] for f in fields])}
    E = np.zeros((n, n))
    reports, done, total = [], 0, n * (n - 1) // 2
    for i in range(n):
        for j in range(i + 1, n):
            try:
                e, rep = pair_distance(shapes[i], shapes[j], beta, map_options)
            except _core.Error as err:
                raise type(err)(f"{names[i]} -> {names[j]}: {err}") from None
            E[i, j] = E[j, i] = e
            reports.append(dict(rep, source=names[i], target=names[j], E=e))
            done += 1
            if progress:
                progress(done, total, f"{names[i]} -> {names[j]}")
    return {"names": names, "matrix": E, "mode": "direct", "beta": beta, "reports": reports,
            "symmetries": 1}


# ---- outputs -----------------------------------------------------------------------------


def _atomic_write(path, write):
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "w", newline="") as f:
        write(f)
    os.replace(tmp, path)


def write_csv(path, names, E):
    def w(f):
        out = csv.writer(f)
        out.writerow(["shape", *names])
        for name, row in zip(names, E):
            out.writerow([name, *(f"{x:.9g}" for x in row)])
    _atomic_write(path, w)


def write_json(path, result, extra=None):
    doc = {k: v for k, v in result.items() if k not in ("matrix", "lambda", "H")}
    doc["matrix"] = np.asarray(result["matrix"]).tolist()
    doc.update(extra or {})
    _atomic_write(path, lambda f: json.dump(doc, f, indent=2))


def classical_mds(E, dims=2):
    """Classical MDS of the distances sqrt(E): (n, dims) coordinates."""
    D2 = np.asarray(E, dtype=np.float64)  # E is already a squared (L2) distance
    n = len(D2)
    J = np.eye(n) - np.ones((n, n)) / n
    B = -0.5 * J @ D2 @ J
    w, v = np.linalg.eigh(B)
    order = np.argsort(w)[::-1][:dims]
    return v[:, order] * np.sqrt(np.maximum(w[order], 0.0))


def plot(path, names, E, title="E(Si, Sj)"):
    """Heat map of the table with the shapes' names, and a 2-D classical MDS embedding."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(names)
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(6 + 0.6 * n, 3 + 0.3 * n), constrained_layout=True)
    im = ax.imshow(E, cmap="viridis")
    ax.set_xticks(range(n), names, rotation=60, ha="right")
    ax.set_yticks(range(n), names)
    for i in range(n):
        for j in range(n):
            ax.text(j, i, f"{E[i, j]:.3g}", ha="center", va="center", fontsize=7,
                    color="white" if E[i, j] < 0.5 * np.max(E) else "black")
    ax.set_title(title)
    fig.colorbar(im, ax=ax, shrink=0.8)
    X = classical_mds(E)
    ax2.scatter(X[:, 0], X[:, 1])
    for k, name in enumerate(names):
        ax2.annotate(name, X[k], textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax2.set_title("classical MDS of sqrt(E)")
    ax2.set_aspect("equal", adjustable="datalim")
    tmp = f"{path}.tmp{os.getpid()}.png"
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    os.replace(tmp, path)


def nearest(E, i):
    """Index of the shape nearest to shape i (other than i)."""
    row = np.array(E[i], dtype=np.float64)
    row[i] = np.inf
    return int(np.argmin(row))


# ---- command line ------------------------------------------------------------------------


def parse_map_options(items):
    """['key=value', ...] -> dict of map options (ints, floats, booleans parsed)."""
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep:
            raise _core.InputError(f"--map-option {item!r}: expected key=value")
        low = value.lower()
        if low in ("true", "false"):
            out[key] = low == "true"
        else:
            try:
                out[key] = int(value)
            except ValueError:
                try:
                    out[key] = float(value)
                except ValueError:
                    out[key] = value
    return out


def main(argv=None):
    p = argparse.ArgumentParser(prog="surfmap compare", description=__doc__.split("\n")[0])
    p.add_argument("shapes", nargs="+", metavar="SHAPE", help="mesh files of one genus")
    p.add_argument("--domain", help="common domain D.obj (e.g. from `surfmap domain`); omit for pairwise maps")
    p.add_argument("--out", required=True, help="table.csv (a JSON with the map reports is written beside it)")
    p.add_argument("--json", help="JSON output (default: the CSV's name with .json)")
    p.add_argument("--plot", help="matrix.png: heat map and 2-D MDS embedding")
    p.add_argument("--beta", type=float, default=1.0, help="weight of the mean-curvature term (default 1)")
    p.add_argument("--names", help="comma-separated names (default: the file names)")
    p.add_argument("--no-symmetries", action="store_true", help="do not minimise over the domain's rotations")
    p.add_argument("--map-option", action="append", metavar="KEY=VALUE",
                   help="option of the native map (e.g. homotopy_search=false); repeatable")
    p.add_argument("--quiet", action="store_true")
    a = p.parse_args(argv)
    try:
        names = a.names.split(",") if a.names else None

        def progress(done, total, name):
            if not a.quiet:
                print(f"surfmap compare: {done}/{total} {name}", file=sys.stderr, flush=True)

        r = compare(a.shapes, a.domain, a.beta, names, parse_map_options(a.map_option),
                    symmetries=not a.no_symmetries, progress=progress)
        write_csv(a.out, r["names"], r["matrix"])
        write_json(a.json or os.path.splitext(a.out)[0] + ".json", r,
                   {"shapes": [os.fspath(s) for s in a.shapes], "domain": a.domain})
        if a.plot:
            plot(a.plot, r["names"], r["matrix"])
    except (_core.Error, OSError) as e:
        print(f"surfmap compare: error: {e}", file=sys.stderr)
        return 1
    if not a.quiet:
        print(f"surfmap compare: {len(r['names'])} shapes, mode {r['mode']}, wrote {a.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
