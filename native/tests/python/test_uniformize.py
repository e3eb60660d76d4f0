"""Uniformization from Python (_core.uniformize / ricci_flow / Poincaré-disk
helpers) and the `surfmap uniformize` CLI contract."""
import json
import math

import numpy as np
import pytest

import surfmap
from surfmap import _core
from mesh_helpers import torus as grid_torus


def torus(R, r, n, m):
    return grid_torus(R, r, n, m, alternate=False)


def su11(g):
    a, b = complex(g[0], g[1]), complex(g[2], g[3])
    return np.array([[a, b], [b.conjugate(), a.conjugate()]])


def centring(p):
    s = 1 / math.sqrt(1 - abs(p) ** 2)
    return np.array([[s, -p * s], [-(p.conjugate()) * s, s]])


def reduce_tau(t):
    for _ in range(100):
        t -= round(t.real)
        if abs(t) < 1:
            t = -1 / t
        else:
            return t
    return t


def orientation_ok(corners, hyperbolic):
    z = corners
    if hyperbolic:  # Klein model: geodesics straight
        z = 2 * z / (1 + np.abs(z) ** 2)
    a, b, c = z[:, 0], z[:, 1], z[:, 2]
    return np.all(np.imag(np.conj(b - a) * (c - a)) > 0)


@pytest.mark.parametrize("R,r", [(2.0, 1.0), (1.4, 1.0)])
def test_torus_modulus(R, r):
    V, F = torus(R, r, 100, int(100 * r / R) + 20)
    res = _core.uniformize(V, F)
    assert res["genus"] == 1 and res["kind"] == "flat" and res["converged"]
    assert res["max_curvature_error"] < 1e-9
    expected = reduce_tau(1j * math.sqrt(R * R - r * r) / r)
    assert abs(res["tau_reduced"] - expected) / abs(expected) < 5e-3
    assert res["tau"].imag > 0
    # tau_reduced is the SL(2,Z) image of tau.
    a, b, c, d = res["sl2z"]
    assert a * d - b * c == 1
    assert abs((a * res["tau"] + b) / (c * res["tau"] + d) - res["tau_reduced"]) < 1e-9
    L = res["layout"]
    assert L["corners"].shape == (len(res["refined_F"]), 3) and L["corners"].dtype == np.complex128
    assert L["num_flipped"] == 0 and orientation_ok(L["corners"], False)
    # The lattice vectors are the generator translations; area = |ω1 × ω2|.
    w1, w2 = res["lattice"]
    assert abs(res["area"] - abs((np.conj(w1) * w2).imag)) < 1e-8 * res["area"]


def test_genus2_generators_and_relation():
    V, F = _core.shapes.n_hole_torus(2, 28, True)
    res = _core.uniformize(V, F)
    g = res["genus"]
    assert g == 2 and res["kind"] == "hyperbolic"
    assert abs(res["area"] - 4 * math.pi * (g - 1)) < 1e-6
    gens = res["generators"]
    assert gens.shape == (2 * g, 4)
    mats = [su11(x) for x in gens]
    for M in mats:
        assert abs(np.linalg.det(M) - 1) < 1e-6 * np.abs(M).max() ** 2
    L = res["layout"]
    assert orientation_ok(L["corners"], True)
    assert np.all(np.abs(L["corners"]) < 1)
    # The word relation, multiplied out in the chart centring the base corner.
    T = centring(L["base_corner"])
    Ti = np.linalg.inv(T)

    def product(flip=0):
        P = np.eye(2, dtype=complex)
        for s in L["word"]:
            M = T @ mats[abs(s) - 1] @ Ti
            if s < 0:
                M = np.linalg.inv(M)
            if abs(s) == flip:
                M = np.linalg.inv(M)
            P = P @ M
        return min(np.abs(P - np.eye(2)).max(), np.abs(P + np.eye(2)).max())

    assert product() < 1e-6
    assert product(flip=1) > 1e-2  # the check can fail
    assert abs(product() - res["product_relation_error"]) < 1e-8
    # Each generator maps the base corner to another copy of the base vertex.
    base_copies = L["disk_positions"][L["disk_vertex_origin"] == res["base_vertex"]]
    assert len(base_copies) == 4 * g
    for x in gens:
        img = _core.mobius_apply(x, np.array([L["base_corner"]]))[0]
        d = _core.hyperbolic_distance(np.full(len(base_copies), img), base_copies)
        # lifted loops end at g(c0), a copy of x in a neighbouring tile: at a
        # positive distance from c0 and never NaN
        assert np.isfinite(d).all()
    # ... and that end is a copy of the base vertex: carried back towards the layout by
    # the generators and their inverses (greedily, while the distance to the layout's
    # centre drops) it lands on one of the layout's copies of the base vertex.
    mats = [su11(x) for x in gens]
    moves = mats + [np.linalg.inv(M) for M in mats]
    centre = L["disk_positions"].mean()

    def mob(M, z):
        return (M[0, 0] * z + M[0, 1]) / (M[1, 0] * z + M[1, 1])

    def hd(z, w):
        return _core.hyperbolic_distance(np.array([z]), np.array([w]))[0]

    def reduced_distance_to_base_copies(p):
        for _ in range(200):
            q = min((mob(h, p) for h in moves), key=lambda z: hd(z, centre))
            if not hd(q, centre) < hd(p, centre) - 1e-12:
                break
            p = q
        return min(hd(p, c) for c in base_copies)

    c0 = L["base_corner"]
    for M in mats:
        assert hd(mob(M, c0), c0) > 0.1
        assert reduced_distance_to_base_copies(mob(M, c0)) < 1e-6
    # the check can fail: the image of another vertex's copy is not a copy of the base vertex
    other = L["disk_positions"][L["disk_vertex_origin"] != res["base_vertex"]][0]
    assert reduced_distance_to_base_copies(mob(mats[0], other)) > 1e-3


def test_hyperbolic_helpers():
    rng = np.random.default_rng(1)
    z = 0.9 * np.sqrt(rng.random(50)) * np.exp(2j * math.pi * rng.random(50))
    w = 0.9 * np.sqrt(rng.random(50)) * np.exp(2j * math.pi * rng.random(50))
    p = 0.5 + 0.3j
    s = 1 / math.sqrt(1 - abs(p) ** 2)
    m = np.array([s, 0, -p.real * s, -p.imag * s])  # centring chart T_p
    assert abs(_core.mobius_apply(m, np.array([p]))[0]) < 1e-14
    d = _core.hyperbolic_distance(z, w)
    d2 = _core.hyperbolic_distance(_core.mobius_apply(m, z), _core.mobius_apply(m, w))
    assert np.allclose(d, d2, rtol=1e-9)
    assert np.allclose(d, 2 * np.arctanh(np.abs(z - w) / np.abs(1 - np.conj(w) * z)), rtol=1e-9)
    mm = _core.mobius_compose(m, m)[0]
    assert np.allclose(_core.mobius_apply(mm, z), _core.mobius_apply(m, _core.mobius_apply(m, z)))
    with pytest.raises(surfmap.InputError):
        _core.hyperbolic_distance(np.array([1.5 + 0j]), np.array([0j]))
    with pytest.raises(surfmap.InputError):
        _core.mobius_apply([0, 0, 1, 0], z)


def test_progress_cancel_and_errors():
    V, F = torus(2.0, 1.0, 40, 20)
    calls = []
    res = _core.uniformize(V, F, progress=lambda it, res: calls.append((it, res)))
    # One call per iteration, with the residual before that iteration.
    assert len(calls) == res["iterations"] and calls[0][0] == 0
    assert calls[-1][1] < calls[0][1] and res["max_curvature_error"] < 1e-9
    with pytest.raises(surfmap.Cancelled):
        _core.uniformize(V, F, progress=lambda it, res: False)

    def boom(it, res):
        raise KeyError("from the callback")

    with pytest.raises(KeyError):
        _core.uniformize(V, F, progress=boom)
    # An unreachable tolerance is a failed solve, never a success, unless the
    # floating-point floor band accepts it (then it says so).
    with pytest.raises(surfmap.SolveError):
        _core.uniformize(V, F, tolerance=1e-30, floor_tolerance=0)
    floor = _core.uniformize(V, F, tolerance=1e-30)
    assert floor["converged"] and floor["stopped_at_floor"] and floor["max_curvature_error"] <= 1e-7
    with pytest.raises(surfmap.InputError):
        _core.uniformize(V, F, scheme="nonsense")
    with pytest.raises(surfmap.InputError):
        _core.uniformize(V, F, base_vertex=10**6)


def test_ricci_flow_binding():
    V, F = torus(2.0, 1.0, 30, 15)
    r = _core.ricci_flow(V, F, background="euclidean")
    assert r["converged"] and r["max_curvature_error"] < 1e-9
    assert r["u"].shape == (len(V),)
    assert r["edge_lengths"].shape == (len(r["edge_vertices"]),)
    # The final metric is a conformal change: l' = exp((u_i + u_j)/2) l.
    e = r["edge_vertices"]
    l0 = np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)
    assert np.allclose(r["edge_lengths"], np.exp((r["u"][e[:, 0]] + r["u"][e[:, 1]]) / 2) * l0, rtol=1e-9)


def test_sphere():
    V, F = _core.shapes.sphere(2)
    V = V * np.array([1.0, 1.5, 0.7])  # an ellipsoid
    res = _core.uniformize(V, F)
    assert res["genus"] == 0 and res["kind"] == "spherical" and res["converged"]
    P = res["sphere_positions"]
    assert P.shape == V.shape
    assert np.allclose(np.linalg.norm(P, axis=1), 1, atol=1e-9)
    assert res["flipped_faces"] == 0
    # Outward orientation kept: every face's normal points away from the centre.
    a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    assert np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) > 0)


def test_cli_report_and_layout(cli, tmp_path):
    V, F = torus(2.0, 1.0, 60, 30)
    mesh = tmp_path / "torus.obj"
    _core.write_obj(str(mesh), V, F)
    rep, lay = tmp_path / "rep.json", tmp_path / "lay.obj"
    p = cli("uniformize", mesh, "--report", rep, "--layout", lay, "--quiet")
    assert p.returncode == 0, p.stderr
    j = json.loads(rep.read_text())
    for k in ["genus", "kind", "converged", "iterations", "max_curvature_error", "area", "time_s",
              "residual_history", "tau", "tau_reduced"]:
        assert k in j
    assert j["genus"] == 1 and j["converged"] is True
    t = complex(*j["tau_reduced"])
    assert abs(t - 1j * math.sqrt(3)) / math.sqrt(3) < 5e-3
    text = lay.read_text().split("\n")
    zs = [float(l.split()[3]) for l in text if l.startswith("v ")]
    assert zs and all(z == 0 for z in zs)

    V2, F2 = _core.shapes.n_hole_torus(2, 24, True)
    mesh2 = tmp_path / "g2.obj"
    _core.write_obj(str(mesh2), V2, F2)
    p = cli("uniformize", mesh2, "--report", rep, "--quiet")
    assert p.returncode == 0, p.stderr
    j = json.loads(rep.read_text())
    assert j["genus"] == 2 and len(j["generators"]) == 4 and all(len(g) == 4 for g in j["generators"])
    assert j["product_relation_error"] < 1e-6
    assert abs(j["area"] - 4 * math.pi) < 1e-6
    # Failure: exit status 1 and a one-line message, no report claiming success.
    rep_bad = tmp_path / "bad.json"
    p = cli("uniformize", mesh2, "--report", rep_bad, "--tolerance", "1e-30", "--floor-tolerance", "0", "--quiet")
    assert p.returncode == 1 and "error" in p.stderr and not rep_bad.exists()
    p = cli("uniformize", mesh2, "--report", rep_bad, "--scheme", "bogus")
    assert p.returncode == 2



def test_refine_keyword_refines_the_fixed_metric_exactly_as_the_clis_refine(cli, tmp_path):
    # The generated genus-3 torus whose fixed-connectivity metric does not exist
    # (test_exact_refinement.cpp): without `refine` the fixed metric is a UniformizationError; with
    # it the mesh is refined by altitude-foot splits and the metric meets Gauss-Bonnet, with the
    # same split count as the CLI's `--refine`.
    V, F = surfmap.shapes.n_hole_torus(3, 32, False)
    with pytest.raises(surfmap.UniformizationError):
        surfmap.uniformize(V, F, metric="fixed")
    u = surfmap.uniformize(V, F, metric="fixed", refine=True)
    assert u["converged"] and u["genus"] == 3
    assert u["refinement_splits"] > 0 and len(u["refined_V"]) > len(V)
    assert abs(u["area"] - 4 * math.pi * 2) < 1e-6
    assert u["layout"]["num_flipped"] == 0
    mesh, rep = tmp_path / "g3.obj", tmp_path / "g3.json"
    _core.write_obj(str(mesh), V, F)
    p = cli("uniformize", mesh, "--metric", "fixed", "--refine", "--report", rep, "--quiet")
    assert p.returncode == 0, p.stderr
    assert json.loads(rep.read_text())["refinement_splits"] == u["refinement_splits"]
