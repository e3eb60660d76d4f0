"""The reflection-aware solve of the doubles (surfmap.open_reflection; docs/open_surfaces.md
"Session 20"): the target half's metric has a geodesic boundary, the half's harmonic map keeps the
boundary on it to round-off where the doubles' own map is asymmetric (measured here), 0 flipped
both ways by the independent count of test_open_double.check_map; the CLI flags and keywords of
the open options reach the map."""
import json

import numpy as np

import surfmap
from surfmap import open_double, open_reflection
from test_open_double import bend, check_map, pants


def angle_sums(layout, n_vertices):
    """Per vertex the sum of its corners' angles in the laid-out half (hyperbolic law of cosines)."""
    L = layout.lengths
    total = np.zeros(n_vertices)
    for k in range(3):
        a, b, c = L[:, k], L[:, (k + 1) % 3], L[:, (k + 2) % 3]
        cos = (np.cosh(b) * np.cosh(c) - np.cosh(a)) / (np.sinh(b) * np.sinh(c))
        np.add.at(total, layout.F[:, k], np.arccos(np.clip(cos, -1, 1)))
    return total


def test_target_half_is_laid_out_with_a_geodesic_boundary():
    # The double's hyperbolic metric made symmetric: every interior vertex of the half has angle
    # sum 2 pi, every boundary vertex pi (its two boundary edges on one geodesic); the layout's
    # transitions glue each cut edge's two placements exactly.
    Vt, Ft = pants(3)
    T = open_double._Side(bend(Vt, 0.3), Ft, "target")
    layout = open_reflection.HalfLayout(T.F2, T.D)
    assert layout.metric_error < 1e-4  # the mirror sheet's 1e-6 offset, averaged out
    total = angle_sums(layout, T.n2)
    on_b = T.loop_of_vertex() >= 0
    assert np.abs(total[~on_b] - 2 * np.pi).max() < 1e-8
    assert np.abs(total[on_b] - np.pi).max() < 1e-8
    f_idx, k_idx = np.nonzero((layout.neighbour >= 0) & ~layout.tree)
    assert len(f_idx) > 0
    for f, k in zip(f_idx, k_idx):
        g, kg = layout.neighbour[f, k], layout.across[f, k]
        M = layout.transition[f, k]
        for cf, cg in (((k + 1) % 3, (kg + 2) % 3), ((k + 2) % 3, (kg + 1) % 3)):
            assert layout.F[f, cf] == layout.F[g, cg]
            assert abs(open_reflection._apply(M, layout.pos[g, cg]) - layout.pos[f, cf]) < 1e-10


def test_reflection_solve_is_symmetric_where_the_doubles_map_is_not():
    # The test pants onto their bend 0.3, loops 0,1,2 preserving. The doubles' map is symmetric
    # only up to the discretization: |f(sigma x) - sigma f(x)| up to 0.0099 of the diagonal, the
    # source's boundary images up to 0.063 off the target's boundary before the snap. The
    # reflection-aware solve: the half alone, boundary images on the target's geodesic boundary to
    # round-off (hyperbolic distance, and in 3D before any snap), converged in a few Newton steps,
    # every face positive in the metric, 0 flipped forward and inverse.
    Vs, Fs = pants(3)
    Vt = bend(Vs, 0.3)
    diag = np.linalg.norm(Vt.max(axis=0) - Vt.min(axis=0))
    kw = dict(boundary_pairing=[0, 1, 2], orientations=("preserving",))
    doubles = open_double.surface_map_open(Vs, Fs, Vt, Fs, reflection_solve=False, **kw)
    assert doubles["open"]["reflection_solve"] == "off"
    assert doubles["open"]["symmetry_error"] > 1e-3
    assert doubles["open"]["snap_distance"] > 1e-3 * diag
    r = open_double.surface_map_open(Vs, Fs, Vt, Fs, **kw)
    o = r["open"]
    assert o["reflection_solve"].startswith("used"), o["reflection_solve"]
    assert o["symmetry_error"] == 0.0 and o["candidates"][0]["doubles_symmetry_error"] > 1e-3
    assert o["snap_distance"] < 1e-10 * diag
    assert r["converged"] and r["flipped_triangles"] == 0 and o["inverse_flipped_triangles"] == 0
    assert check_map(r, Vs, Fs, Vt, Fs) == 0
    # The same class: the energies differ by the discretization only (the half's intrinsic
    # Delaunay weights with its boundary kept here, the refined doubles' there). energy.final is
    # the delivered map's (the half's solve), energy.ranking the doubles' halved, which ranked it.
    assert r["energy"]["ranking"] == doubles["energy"]["final"]
    assert r["energy"]["final"] == o["reflection_energy"]
    assert abs(o["reflection_energy"] - doubles["energy"]["final"]) < 0.01 * doubles["energy"]["final"]
    assert "intrinsic Delaunay" in o["reflection_solve"], o["reflection_solve"]
    assert np.linalg.norm(r["forward"]["position"] - doubles["forward"]["position"], axis=1).mean() < 0.01 * diag


def test_the_half_solve_is_a_critical_point_with_the_boundary_on_its_geodesic():
    # solve_half directly: the energy decreases from the doubles' images to a point where the
    # gradient (over the largest weighted edge length) is below 1e-9, no boundary image is more
    # than 1e-12 off its geodesic, and a random small move of the interior images (each within its
    # chart) raises the energy.
    Vs, Fs = pants(3)
    S = open_double._Side(Vs, Fs, "source")
    T = open_double._Side(bend(Vs, 0.3), Fs, "target")
    pos, face, target_xyz, _ = open_double._rough_maps(S, T, [0, 1, 2], {}, False, np.zeros((0, 2), int))[0][0]
    images = open_double._symmetric_images(S, T, [0, 1, 2], False, pos, face, target_xyz)
    r = open_double._double_map(S, T, images, {})
    h = open_reflection.solve_half(S, T, r["forward"], [0, 1, 2], False)
    assert h["converged"] and h["gradient"] < 1e-9 and h["iterations"] <= 10
    assert h["boundary_off_geodesic"] < 1e-12
    assert h["intrinsic_flipped"] == 0 and h["escaped"] == 0 and len(h["inverse_unlocated"]) == 0
    hist = np.array(h["energy_history"])
    assert np.all(np.diff(hist) <= 1e-12 * hist[0]) and hist[-1] < hist[0]


def test_cli_flags_and_keywords_of_the_open_options(tmp_path, cli):
    # --no-reflection-solve / reflection_solve=False keep the doubles' half; --refine-levels 0 /
    # refine_levels=0 turn the refinement fallback off; bad values are refused.
    Vs, Fs = pants(3)
    Vt = bend(Vs, 0.3)
    surfmap.write_obj(str(tmp_path / "s.obj"), Vs, Fs)
    surfmap.write_obj(str(tmp_path / "t.obj"), Vt, Fs)
    reports = {}
    for name, flags in (("default", []), ("off", ["--no-reflection-solve", "--refine-levels", "0",
                                                   "--refine-rings", "2"])):
        rep = tmp_path / f"{name}.json"
        p = cli("map", tmp_path / "s.obj", tmp_path / "t.obj", "--out", tmp_path / f"{name}.obj", "--report", rep,
                "--boundary-pairing", "0,1,2", "--quiet", *flags)
        assert p.returncode == 0, p.stderr
        reports[name] = json.loads(rep.read_text())["open"]
    assert reports["default"]["reflection_solve"].startswith("used")
    assert reports["off"]["reflection_solve"] == "off"
    assert reports["off"]["snap_distance"] > 1e3 * reports["default"]["snap_distance"]
    p = cli("map", tmp_path / "s.obj", tmp_path / "t.obj", "--out", tmp_path / "x.obj", "--report",
            tmp_path / "x.json", "--refine-levels", "-1")
    assert p.returncode != 0
    r = surfmap.surface_map(Vs, Fs, Vt, Fs, boundary_pairing=[0, 1, 2], reflection_solve=False, refine_levels=0)
    assert r["open"]["reflection_solve"] == "off"
    for kw in ("refine_rings", "refine_levels", "reflection_solve"):
        assert kw in surfmap.CAPABILITIES
