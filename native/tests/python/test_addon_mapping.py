"""The add-on's bpy-free modules (addon/surface_map: geometry, distortion, colours, uv_transfer,
landmarks, morph, side, map_job), imported as a package outside Blender (its __init__ skips the
bpy half when bpy is missing): UV transfer across seams, distortion measures, colour scales,
landmarks, fingerprints, the map job's options and its sliced outputs."""
import importlib
import json
import math
import pathlib
import sys
import types

import numpy as np
import pytest

import surfmap

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "addon"))
_MODULES = ("geometry", "distortion", "colours", "uv_transfer", "landmarks", "morph", "side",
            "map_job")
_mods = {name: importlib.import_module(f"surface_map.{name}") for name in _MODULES}
# One namespace with every name of the bpy-free modules (the tests below predate the split).
M = types.SimpleNamespace(**{k: v for m in _mods.values() for k, v in vars(m).items()
                             if not k.startswith("__")})


def torus(R, r, n, m):
    V, F = surfmap.shapes.torus_of_revolution(R, r, n, m)
    return np.asarray(V, dtype=float), np.asarray(F)


def torus_corner_uv(V, F, R):
    """(u, v) angles per triangle corner, unwrapped per triangle: one island, seams at 0."""
    P = V[F]
    u = np.arctan2(P[..., 1], P[..., 0]) / (2 * np.pi) % 1.0
    v = np.arctan2(P[..., 2], np.hypot(P[..., 0], P[..., 1]) - R) / (2 * np.pi) % 1.0
    for a in (u, v):
        a[:] = np.where(a.max(axis=1, keepdims=True) - a > 0.5, a + 1.0, a)
    return np.stack([u, v], -1)


@pytest.fixture(scope="module", params=["auto", "fixed"])
def tori(request):
    """The pair on the default target metric (the flip-based one: the map is piecewise
    projective on the target's faces) and on the fixed connectivity (piecewise linear): the
    add-on's outputs read the map only at the per-vertex images, which both deliver on the
    user's own faces (docs/addon.md "Outputs on the flip-based metric")."""
    Vs, Fs = torus(1.0, 0.5, 48, 24)
    Vt, Ft = torus(1.5, 0.5, 40, 20)
    m = surfmap.surface_map(Vs, Fs, Vt, Ft, target_metric=request.param)
    return Vs, Fs, Vt, Ft, m


def _transfer(Vs, Fs, Ft, m, uv):
    X = M.UVTransfer(Fs, uv, Vs)
    lv = Ft.reshape(-1)
    f, b = m["inverse"]["face"][lv], m["inverse"]["barycentric"][lv]
    out, strad = X.polygon_uvs(f, b, np.arange(len(Ft)) * 3, np.full(len(Ft), 3))
    pre = M.points_at(Vs, Fs, m["inverse"]["face"], m["inverse"]["barycentric"])[Ft]
    return X, out.reshape(-1, 3, 2), X.naive(f, b).reshape(-1, 3, 2), strad, pre


@pytest.mark.parametrize("layout", ["one island", "four rotated islands"])
def test_uv_transfer_has_no_flips_or_seam_straddling(tori, layout):
    Vs, Fs, Vt, Ft, m = tori
    uv = torus_corner_uv(Vs, Fs, 1.0)
    if layout != "one island":  # quadrants, each rotated, scaled and moved in the layout
        isl = (uv[:, :, 0].mean(1) % 1 < 0.5).astype(int) * 2 + (uv[:, :, 1].mean(1) % 1 < 0.5)
        z = uv[..., 0] + 1j * uv[..., 1]
        z = z * (np.exp(1j * np.pi / 2 * isl) * (0.5 + 0.2 * isl))[:, None] \
            + (isl * (1.7 + 0.9j))[:, None]
        uv = np.stack([z.real, z.imag], -1)
    assert M.uv_quality(uv, Vs[Fs])[0] == 0
    X, ours, naive, strad, pre = _transfer(Vs, Fs, Ft, m, uv)
    assert X.island.max() + 1 == (1 if layout == "one island" else 4)
    assert np.sum(M.signed_uv_areas(ours) <= 0) == 0
    assert M.seam_straddling(ours, pre, uv, Vs[Fs]) == 0
    # the naive per-vertex transfer straddles every seam crossing, and those are the
    # triangles the transfer unfolded; elsewhere both agree exactly
    n_naive = M.seam_straddling(naive, pre, uv, Vs[Fs])
    assert n_naive > 50
    assert strad.sum() >= n_naive
    assert np.allclose(ours[~strad], naive[~strad])
    # the unfolded UVs are continuous across the seam: each target edge has the same UV
    # length (up to the map's smoothness) as its neighbours, nothing spans the layout
    assert np.max(M.uv_stretch(ours, Vt[Ft])) < 3 * np.median(M.uv_stretch(ours, Vt[Ft]))


def test_uv_transfer_self_map_reproduces_the_uvs():
    # identity correspondence (a torus onto itself): every corner's preimage is its own vertex
    V, F = torus(1.0, 0.5, 24, 12)
    uv = torus_corner_uv(V, F, 1.0)
    X = M.UVTransfer(F, uv, V)
    # the preimage of vertex v: some triangle containing it, barycentric 1 there
    face = np.zeros(len(V), dtype=int)
    bary = np.zeros((len(V), 3))
    for f in range(len(F) - 1, -1, -1):
        for k in range(3):
            face[F[f, k]] = f
    for v in range(len(V)):
        bary[v, list(F[face[v]]).index(v)] = 1.0
    lv = F.reshape(-1)
    out, _ = X.polygon_uvs(face[lv], bary[lv], np.arange(len(F)) * 3, np.full(len(F), 3))
    out = out.reshape(-1, 3, 2)
    # each triangle's UVs equal the original up to a whole-period shift of the layout
    d = out - uv
    assert np.allclose(d, np.round(d), atol=1e-9)
    assert np.allclose(d - d[:, :1], 0, atol=1e-9)


def test_dilatation_and_conformal_factor_of_known_maps():
    V, F = torus(1.0, 0.5, 24, 12)
    # a uniform scaling is conformal: D' = 1, λ = 1 (areas normalised)
    D, flipped = M.dilatation(V, F, 3.0 * V, M.face_normals(V, F))
    assert np.allclose(D, 1.0) and not flipped.any()
    assert np.allclose(M.conformal_factor(V, F, 3.0 * V), 1.0)
    # stretching a flat triangle by 2 in x: D' = 2
    Vp = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    Fp = np.array([[0, 1, 2]])
    D, _ = M.dilatation(Vp, Fp, Vp * [2, 1, 1])
    assert abs(D[0] - 2.0) < 1e-12
    # a mirror image is flipped relative to the normal
    D, fl = M.dilatation(Vp, Fp, Vp * [-1, 1, 1], np.array([[0, 0, 1.0]]))
    assert fl[0] and np.isinf(D[0])


def test_mean_curvature_sphere_and_torus():
    V, F = surfmap.shapes.sphere(4)
    H = M.mean_curvature(np.asarray(V, float) * 7.0, np.asarray(F))   # scale-free: 1 on any sphere
    # barycentric areas are off at the 12 valence-5 vertices; elsewhere H is 1 to 1%
    assert abs(np.median(H) - 1.0) < 0.01 and np.all(np.abs(H - 1.0) < 0.16), (H.min(), H.max())
    R, r = 1.0, 0.4
    V, F = torus(R, r, 96, 48)
    H = M.mean_curvature(V, F) / math.sqrt(4 * math.pi ** 2 * R * r / (4 * math.pi))
    # analytic: H = (R + 2 r cos v) / (2 r (R + r cos v)) (outer equator: (R+2r)/(2r(R+r)))
    outer = int(np.argmax(np.hypot(V[:, 0], V[:, 1])))
    assert abs(H[outer] - (R + 2 * r) / (2 * r * (R + r))) < 0.02 * H[outer]


def test_colour_scale_ranges_and_invalid():
    rgba = M.colour_scale(np.array([1.0, 2.0, 3.0, np.inf]), 1.0, 3.0)
    assert rgba.shape == (4, 4) and np.allclose(rgba[:, 3], 1.0)
    assert np.allclose(rgba[0, :3], M._srgb_to_linear(M.SEQUENTIAL[0]))
    assert np.allclose(rgba[2, :3], M._srgb_to_linear(M.SEQUENTIAL[-1]))
    assert np.allclose(rgba[3, :3], M.INVALID)
    lo, hi = M.symmetric_range(np.array([-0.5, 0.1, 0.2]), q=1.0)
    assert lo == -0.5 and hi == 0.5


def test_landmark_summary_says_how_they_were_held():
    # The report fields of surface_map (landmark_method, _steps, _solves, _rings) in one line.
    assert M.landmark_summary({"genus": 2}, 0) is None
    assert M.landmark_summary({"genus": 0, "landmark_error": 0.0}, 3).endswith("they fix (exact)")
    assert "largest miss 0.012" in M.landmark_summary({"genus": 0, "landmark_error": 0.012}, 5)
    pinned = {"genus": 1, "landmark_method": "pinned", "landmark_steps": 0, "landmark_solves": 1}
    assert M.landmark_summary(pinned, 2).startswith("2 landmark(s) held by plain pins")
    barrier = {"genus": 2, "landmark_method": "barrier continuation", "landmark_steps": 7,
               "landmark_solves": 8}
    assert M.landmark_summary(barrier, 1).startswith("1 landmark(s) held by barrier continuation in 7 step(s)")
    carried = {"genus": 2, "landmark_method": "carried neighbourhoods", "landmark_steps": 3,
               "landmark_solves": 6, "landmark_rings": [2, 0], "landmark_held_vertices": 20}
    line = M.landmark_summary(carried, 2)
    assert "rings [2, 0], 20 vertices held rigidly" in line and "stalled after 3 step(s)" in line


def test_landmarks_and_fingerprints():
    pairs, names, problems = M.landmark_pairs(
        {"lm_a": ([3, 4], [0.2, 0.9]), "lm_b": ([1], [1.0]), "other": ([0], [1.0])},
        {"lm_a": ([7], [1.0]), "lm_c": ([2], [1.0])})
    assert pairs.tolist() == [[4, 7]] and names == ["lm_a"]
    assert any("lm_b" in p and "source" in p for p in problems)
    assert any("lm_c" in p and "target" in p for p in problems)
    with pytest.raises(ValueError, match="out of range"):
        M.check_landmarks([[0, 9]], 5, 5)
    with pytest.raises(ValueError, match="two landmarks"):
        M.check_landmarks([[1, 2], [1, 3]], 5, 5)
    V, F = torus(1.0, 0.5, 12, 6)
    fp = M.fingerprint(V, F)
    assert fp == M.fingerprint(V.copy(), F.copy())
    V2 = V.copy()
    V2[3, 0] += 1e-3
    assert M.fingerprint(V2, F) != fp
    assert M.fingerprint(V, F[:, [0, 2, 1]]) != fp


def test_refinement_follows_the_target():
    Vs, Fs = torus(1.0, 0.5, 24, 12)       # a coarse source
    Vt, Ft = torus(1.5, 0.5, 96, 48)       # a fine target
    m = surfmap.surface_map(Vs, Fs, Vt, Ft)
    img = m["forward"]["position"]
    R, r = 1.5, 0.5

    def project(P):  # closest point on the torus of revolution and its normal (analytic)
        rho = np.hypot(P[:, 0], P[:, 1])
        c = np.stack([P[:, 0] / rho * R, P[:, 1] / rho * R, np.zeros(len(P))], 1)
        d = P - c
        n = d / np.linalg.norm(d, axis=1)[:, None]
        return c + r * n, n
    _, n0 = project(img)
    L = 0.05
    out = M.refine_for_morph(Vs, Fs, img, n0, project, max_length=L, rounds=3)
    V, F, I = out["V"], out["F"], out["image"]
    assert out["rounds"] >= 2 and len(V) > 3 * len(Vs)
    # the original vertices and their images are kept; new vertices lie on the source's
    # triangles (given by origin face + barycentrics) and their images on the target
    assert np.array_equal(V[:len(Vs)], Vs) and np.array_equal(I[:len(Vs)], img)
    P = np.einsum("tkj,tjx->tkx", out["origin_bary"], Vs[Fs[out["origin_face"]]])
    assert np.allclose(P, V[F], atol=1e-12)
    assert np.allclose(project(I[len(Vs):])[0], I[len(Vs):], atol=1e-12)
    # still a closed manifold surface (no T-junctions): every edge in exactly two triangles,
    # each way once, and the Euler characteristic of a torus
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert np.all(counts == 1)
    und = np.unique(np.sort(e, axis=1), axis=0)
    assert len(und) * 2 == len(e) and len(V) - len(und) + len(F) == 0
    # image edges got much shorter than the coarse source's
    def longest(Vx, Fx):
        ee = np.concatenate([Fx[:, [0, 1]], Fx[:, [1, 2]], Fx[:, [2, 0]]])
        return np.linalg.norm(Vx[ee[:, 0]] - Vx[ee[:, 1]], axis=1).max()
    assert longest(I, F) < 0.5 * longest(img, Fs)
    # the morph target (images) is on the target surface, where the coarse morph's flat
    # triangles cut through it: their midpoints are off the surface, the refined ones close
    def mid_off(Vx, Fx):
        c = Vx[Fx].mean(axis=1)
        return np.abs(np.linalg.norm(c - project(c)[0], axis=1)).max()
    assert mid_off(I, F) < 0.3 * mid_off(img, Fs)


def test_box_projection_has_islands_and_no_flips():
    V, F = surfmap.shapes.n_hole_torus(2)
    V, F = np.asarray(V, dtype=float), np.asarray(F)
    uv = M.box_projection(V, F.reshape(-1), np.arange(len(F)) * 3, np.full(len(F), 3))
    uv = uv.reshape(-1, 3, 2)
    assert np.all(M.signed_uv_areas(uv) > 0)
    assert M.uv_islands(F, uv).max() + 1 >= 6
    assert uv.min() >= 0 and uv.max() <= 1


def test_map_options_spell_the_core_names_in_one_place():
    """The panel's enum values become the core's keywords once (MapOptions.from_settings)."""
    settings = types.SimpleNamespace(homotopy=3, method='RELAXATION', tolerance=1e-9,
                                     source_weights='OWN', write_uvs_before=True,
                                     morph_space='WORLD', colour_percentile=95.0)
    o = M.MapOptions.from_settings(settings, landmarks=np.array([[1, 2]]), outputs={"UV"})
    kw = o.native_kwargs()
    assert kw["homotopy"] == 3 and kw["method"] == "relaxation" and kw["source_weights"] == "own"
    assert kw["tolerance"] == 1e-9 and kw["landmarks"].dtype == np.int32
    assert o.outputs == {"UV"} and o.morph_space == "WORLD" and o.colour_percentile == 95.0
    default = M.MapOptions().native_kwargs()
    assert default == {"homotopy": -1}          # the core's own defaults otherwise


def test_a_listed_pairing_is_asked_for_by_its_words():
    """A pairing picked from the last run's list goes to the core by its words (class_words),
    which name it in the next run too; its list number may name another pairing there. Not
    listed, or listed without words (genus 1): the number, as before."""
    words = [[1, 2, -1], [2], [3], [4]]
    listed = [types.SimpleNamespace(index=0, words="[]"),
              types.SimpleNamespace(index=3, words=json.dumps(words))]
    settings = types.SimpleNamespace(homotopy=3, candidates=listed, method='NEWTON', tolerance=0.0,
                                     source_weights='AUTO', write_uvs_before=False,
                                     morph_space='IN_PLACE', colour_percentile=99.0)
    assert M.listed_class_words(settings) == words
    kw = M.MapOptions.from_settings(settings).native_kwargs()
    assert kw == {"homotopy": -1, "class_words": words}
    settings.homotopy = 0                       # listed without words (a torus): its number
    assert M.MapOptions.from_settings(settings).native_kwargs() == {"homotopy": 0}
    settings.homotopy = 5                       # not listed: its number
    assert M.MapOptions.from_settings(settings).native_kwargs() == {"homotopy": 5}
    settings.homotopy = -1                      # automatic
    assert M.MapOptions.from_settings(settings).native_kwargs() == {"homotopy": -1}
    assert M.MapOptions(class_words=words).unsupported(types.SimpleNamespace(
        surface_map=lambda: None, CAPABILITIES={"homotopy"})) is None


def test_core_supports_prefers_the_capabilities_attribute():
    def surface_map():
        """Globally optimal map ... `landmarks`: ..."""
    old = types.SimpleNamespace(surface_map=surface_map)
    assert M.core_supports(old, "landmarks") and not M.core_supports(old, "method")
    new = types.SimpleNamespace(surface_map=surface_map, CAPABILITIES={"method", "landmarks"})
    assert M.core_supports(new, "method")
    flags = types.SimpleNamespace(surface_map=surface_map,
                                  _core=types.SimpleNamespace(CAPABILITIES={"method": False}))
    assert not M.core_supports(flags, "method")
    nested = types.SimpleNamespace(surface_map=surface_map,
                                   CAPABILITIES={"surface_map": ["tolerance"]})
    assert M.core_supports(nested, "tolerance") and not M.core_supports(nested, "method")
    unsupported = M.MapOptions(method="relaxation").unsupported(old)
    assert unsupported == "method"
    assert M.core_supports(surfmap, "landmarks")   # the real module, whichever way it says


def test_sliced_outputs_equal_the_whole_and_colour_both_sides(tori):
    Vs, Fs, Vt, Ft, m = tori

    def side(name, V, F, uv=None):
        L = len(F) * 3
        d = dict(V=V, F=F, tri_loops=np.arange(L).reshape(-1, 3), tri_polygon=np.arange(len(F)),
                 num_polygons=len(F), loop_start=np.arange(0, L, 3),
                 loop_total=np.full(len(F), 3), loop_vertex=np.asarray(F).reshape(-1))
        s = M.MeshSide.from_mesh_data(name, np.eye(4), d).orient(False)
        if uv is not None:
            s.uv_layers["uv"] = uv.reshape(-1, 2)
        return s
    src = side("s", Vs, Fs, torus_corner_uv(Vs, Fs, 1.0))
    tgt = side("t", Vt, Ft)
    c = M.OutputComputation(src, tgt, m, M.MapOptions())
    n = 0
    while c.step():
        n += 1
    out = c.out
    whole = M.compute_outputs(src, tgt, m, M.MapOptions())
    assert n >= 5 and np.array_equal(out["uv"]["uv"], whole["uv"]["uv"])
    for name in (M.DILATATION_COLOURS, M.CONFORMAL_COLOURS, M.CURVATURE_COLOURS):
        assert name in out["colours"] and name in out["target_colours"]
    # D' is the same stretch seen from either side (up to the piecewise-linear inverse)
    Ds, Dt = out["raw"][M.DILATATION_COLOURS], out["target_raw"][M.DILATATION_COLOURS]
    assert np.all(Dt[np.isfinite(Dt)] >= 1 - 1e-9)
    # the colour range is the final map's (both objects): its top is their 99th percentile,
    # not pulled up by the initial map's larger D' (the mesh would be almost one colour)
    both = np.concatenate([Ds, Dt])
    both = both[np.isfinite(both)]
    lo, hi = out["ranges"][M.DILATATION_COLOURS]
    assert lo == 1.0 and hi == pytest.approx(np.quantile(both, 0.99), rel=1e-12)
    D0 = out["dilatation_initial"]   # (genus 1: the initial map is located too)
    assert np.quantile(D0[np.isfinite(D0)], 0.99) > hi   # (the old range, with it, was wider)
    assert abs(np.median(Ds) - np.median(Dt)) < 0.05 * np.median(Ds)
    # the area ratio on the target (through the inverse map, same sign convention) agrees
    # with the source's at each target vertex's preimage
    lam_s, lam_t = out["raw"][M.CONFORMAL_COLOURS], out["target_raw"][M.CONFORMAL_COLOURS]
    face, bary = out["inverse"]
    lam_s_at = np.einsum("ik,ik->i", bary, lam_s[np.asarray(Fs)[face]])
    r = np.corrcoef(lam_s_at, lam_t)[0, 1]
    assert r > 0.9, r
    assert np.abs(lam_s_at - lam_t).mean() < 0.2 * np.abs(lam_s).max()


def test_outputs_read_the_map_at_the_vertices(tori):
    """On either target metric the per-vertex images are points of the user's own faces (the
    positions are the barycentric combinations of the face's corners), and the outputs use
    exactly those: the morph puts each source vertex at its image, and the target's UVs are
    the source's UVs at the target vertices' preimages wherever no seam is crossed."""
    Vs, Fs, Vt, Ft, m = tori
    for side, (V, F) in (("forward", (Vt, Ft)), ("inverse", (Vs, Fs))):
        f, b = m[side]["face"], m[side]["barycentric"]
        assert np.all(b >= 0) and np.allclose(b.sum(axis=1), 1.0)
        assert np.abs(M.points_at(V, F, f, b) - m[side]["position"]).max() < 1e-12
    L = len(Fs) * 3
    src = M.MeshSide.from_mesh_data("s", np.eye(4), dict(
        V=Vs, F=Fs, tri_loops=np.arange(L).reshape(-1, 3), tri_polygon=np.arange(len(Fs)),
        num_polygons=len(Fs), loop_start=np.arange(0, L, 3), loop_total=np.full(len(Fs), 3),
        loop_vertex=np.asarray(Fs).reshape(-1))).orient(False)
    src.uv_layers["uv"] = torus_corner_uv(Vs, Fs, 1.0).reshape(-1, 2)
    Lt = len(Ft) * 3
    tgt = M.MeshSide.from_mesh_data("t", np.eye(4), dict(
        V=Vt, F=Ft, tri_loops=np.arange(Lt).reshape(-1, 3), tri_polygon=np.arange(len(Ft)),
        num_polygons=len(Ft), loop_start=np.arange(0, Lt, 3), loop_total=np.full(len(Ft), 3),
        loop_vertex=np.asarray(Ft).reshape(-1))).orient(False)
    out = M.compute_outputs(src, tgt, m, M.MapOptions(outputs={"UV", "MORPH"}))
    assert np.abs(out["image_of_source"] - m["forward"]["position"]).max() < 1e-12
    uv = out["uv"]["uv"].reshape(-1, 3, 2)
    _, _, naive, strad, _ = _transfer(Vs, Fs, Ft, m, torus_corner_uv(Vs, Fs, 1.0))
    assert np.sum(M.signed_uv_areas(uv) <= 0) == 0
    assert np.allclose(uv[~strad], naive[~strad], rtol=0, atol=1e-6)   # (float32 UVs)


def _quad_mesh(quads):
    """(V, F, edge vertex pairs, each corner's edge) of a quad mesh, as Blender stores it."""
    edges, corner_edges = {}, []
    for q in quads:
        for k in range(4):
            e = tuple(sorted((q[k], q[(k + 1) % 4])))
            corner_edges.append(edges.setdefault(e, len(edges)))
    return len({v for q in quads for v in q}), len(quads), np.array(list(edges)), np.array(corner_edges)


def test_mesh_topology_counts_genus_and_boundary_loops():
    # The panel's one-line summary (side.mesh_topology): a torus of 6 x 4 quads is closed of
    # genus 1; a 5 x 5 grid is a disk; the grid with its middle 3 x 3 cut out an annulus; two
    # disjoint grids are not one surface (V - E + F = 2 with 2 loops: no genus).
    from surface_map.side import describe_counts, mesh_topology
    n, m = 6, 4
    torus = [(i * m + j, ((i + 1) % n) * m + j, ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m)
             for i in range(n) for j in range(m)]
    assert mesh_topology(*_quad_mesh(torus)) == (1, 0)
    grid = [(j * 6 + i, j * 6 + i + 1, (j + 1) * 6 + i + 1, (j + 1) * 6 + i) for j in range(5) for i in range(5)]
    assert mesh_topology(*_quad_mesh(grid)) == (0, 1)
    ring = [q for k, q in enumerate(grid) if not (1 <= k % 5 <= 3 and 1 <= k // 5 <= 3)]
    assert mesh_topology(*_quad_mesh(ring)) == (0, 2)
    two = grid + [tuple(v + 36 for v in q) for q in grid]
    assert mesh_topology(*_quad_mesh(two)) == (None, 2)
    assert [describe_counts(1, 0), describe_counts(0, 2), describe_counts(None, 2)] == \
        ["closed, genus 1", "genus 0, 2 boundary loops", "not one surface"]
