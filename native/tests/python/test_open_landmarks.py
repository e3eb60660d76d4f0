"""Landmarks on open pairs (docs/open_surfaces.md, "Landmarks"): disks hold up to three boundary
points or one interior point (with at most one boundary point) exactly through the disk's Möbius
group, annuli the shift, the doubles each landmark with its mirror image. Checked here: each
landmark's image is its target vertex, flips counted independently, boundary onto boundary."""
import json

import numpy as np
import pytest

import surfmap
from surfmap import open_double
from test_open_double import bend, check_map, pants, punctured_torus
from test_open_surfaces import cap, frustum, grid, signed_areas_xy


def landmark_error(r, Vt, lm):
    return np.linalg.norm(np.asarray(r["forward"]["position"])[lm[:, 0]] - Vt[lm[:, 1]], axis=1).max()


def disk_flips(r, Fs, Vt, Ft):
    sign = np.sign(signed_areas_xy(Vt, Ft))[0]
    return int(np.sum(signed_areas_xy(np.asarray(r["forward"]["position"]), Fs) * sign <= 0))


def square():
    return grid(20, 20, lambda s, t: (2 * s - 1, 2 * t - 1, 0.0))


def test_disk_landmarks_pin_the_mobius_group_exactly():
    Vs, Fs = cap(10)
    Vt, Ft = square()
    rim_s = np.flatnonzero(np.abs(Vs[:, 2]) < 1e-9)
    rim_t = np.flatnonzero(np.max(np.abs(Vt[:, :2]), axis=1) > 1 - 1e-12)
    ang_s = np.arctan2(Vs[rim_s, 1], Vs[rim_s, 0])
    ang_t = np.arctan2(Vt[rim_t, 1], Vt[rim_t, 0])
    def rim_pair(a_s, a_t):   # the rim vertices nearest to the given angles on each side
        d = lambda a, b: np.abs(np.angle(np.exp(1j * (a - b))))
        return [rim_s[np.argmin(d(ang_s, a_s))], rim_t[np.argmin(d(ang_t, a_t))]]
    top = int(np.argmax(Vs[:, 2]))                                    # the pole
    off = int(np.argmin(np.linalg.norm(Vt - np.array([0.4, -0.3, 0]), axis=1)))   # off the square's centre
    free = surfmap.surface_map(Vs, Fs, Vt, Ft)
    cases = {
        "three boundary points (turned)": [rim_pair(0.0, 1.0), rim_pair(2.0, 3.3), rim_pair(4.0, 5.0)],
        "two boundary points": [rim_pair(0.3, 2.0), rim_pair(3.0, 4.0)],
        "one interior point": [[top, off]],
        "one interior and one boundary point": [[top, off], rim_pair(1.0, -2.0)],
        "one boundary point": [rim_pair(0.5, 2.5)],
    }
    diag = np.linalg.norm(Vt.max(axis=0) - Vt.min(axis=0))
    for name, lm in cases.items():
        lm = np.array(lm)
        r = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=lm)
        assert landmark_error(r, Vt, lm) < 1e-9 * diag, name
        assert r["open"]["landmarks"] == len(lm) and r["open"]["landmark_error"] < 1e-9 * diag, name
        assert disk_flips(r, Fs, Vt, Ft) == 0 and r["flipped_triangles"] == 0, name
        assert r["distortion"]["mean"] >= free["distortion"]["mean"] - 1e-9, name   # pinning costs
    with pytest.raises(surfmap.InputError, match="interior"):
        surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=[[top, off], [top + 1, off + 1]])
    with pytest.raises(surfmap.InputError, match="opposite cyclic orders"):
        surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=[rim_pair(0.0, 1.0), rim_pair(2.0, 5.0), rim_pair(4.0, 3.3)])
    with pytest.raises(surfmap.InputError, match="on the boundary but"):
        surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=[[rim_s[0], off]])


def test_annulus_landmark_sets_the_shift():
    Vs, Fs = frustum(1.0, 1.0, 1.5)       # loop 0 (the longer) at the top on both
    Vt, Ft = frustum(2.0, 1.0, 1.5, around=28, rows=12)
    s = int(np.flatnonzero(np.abs(Vs[:, 2]) < 1e-12)[3])         # bottom rim (loop 1)
    bottom_t = np.flatnonzero(np.abs(Vt[:, 2]) < 1e-12)
    t = int(bottom_t[11])
    r = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=[[s, t]])
    diag = np.linalg.norm(Vt.max(axis=0) - Vt.min(axis=0))
    assert r["open"]["domain"] == "annulus" and r["flipped_triangles"] == 0
    assert landmark_error(r, Vt, np.array([[s, t]])) < 1e-9 * diag
    # The shift is a rotation of the frusta: every vertex turned by the landmark's angle (up
    # to the target's 28-gon: its images lie on the polygon's chords).
    P = np.asarray(r["forward"]["position"])
    turn = np.angle(np.exp(1j * (np.arctan2(P[:, 1], P[:, 0]) - np.arctan2(Vs[:, 1], Vs[:, 0]))))
    assert np.abs(turn - turn[s]).max() < 0.01


@pytest.mark.parametrize("shape", ["pants", "punctured_torus"])
def test_doubles_hold_landmarks_and_their_mirrors(shape):
    Vs, Fs = pants(3) if shape == "pants" else punctured_torus(32, 16)
    Vt = bend(Vs, 0.3)
    loops = open_double.boundary_loops(Vs, Fs)
    on_b = np.zeros(len(Vs), bool)
    on_b[np.concatenate(loops)] = True
    # An interior landmark moved a few rings from its own vertex, and a boundary one moved
    # along its loop by two vertices.
    inner = int(np.flatnonzero(~on_b)[len(Vs) // 3])
    near = np.argsort(np.linalg.norm(Vs - Vs[inner], axis=1))
    moved = int(next(v for v in near[8:] if not on_b[v]))
    lm = np.array([[inner, moved], [loops[0][0], loops[0][2]]])
    pairing = list(range(len(loops)))
    r = surfmap.surface_map(Vs, Fs, Vt, Fs, landmarks=lm, boundary_pairing=pairing)
    diag = np.linalg.norm(Vt.max(axis=0) - Vt.min(axis=0))
    assert r["open"]["landmarks"] == 2
    assert landmark_error(r, Vt, lm) < 1e-6 * diag, landmark_error(r, Vt, lm) / diag
    assert check_map(r, Vs, Fs, Vt, Fs) == 0 and r["flipped_triangles"] == 0
    # A boundary landmark onto an interior vertex is refused by name.
    with pytest.raises(surfmap.InputError, match="landmark 0 .*boundary"):
        surfmap.surface_map(Vs, Fs, Vt, Fs, landmarks=[[loops[0][0], moved]])


def test_cli_landmarks_for_open_pairs(tmp_path, cli):
    Vs, Fs = pants(3)
    Vt = bend(Vs, 0.3)
    loops = open_double.boundary_loops(Vs, Fs)
    surfmap.write_obj(str(tmp_path / "s.obj"), Vs, Fs)
    surfmap.write_obj(str(tmp_path / "t.obj"), Vt, Fs)
    (tmp_path / "lm.txt").write_text(f"# boundary landmark\n{loops[1][0]} {loops[1][3]}\n")
    rep = tmp_path / "r.json"
    p = cli("map", tmp_path / "s.obj", tmp_path / "t.obj", "--out", tmp_path / "m.obj", "--report", rep,
            "--landmarks", tmp_path / "lm.txt", "--boundary-pairing", "0,1,2", "--quiet")
    assert p.returncode == 0, p.stderr
    report = json.loads(rep.read_text())
    assert report["open"]["landmarks"] == 1 and report["flipped_triangles"] == 0
    diag = np.linalg.norm(Vt.max(axis=0) - Vt.min(axis=0))
    assert report["open"]["landmark_error"] < 1e-6 * diag
    # The disk path reads the same file.
    Vd, Fd = cap(8)
    Vq, Fq = square()
    surfmap.write_obj(str(tmp_path / "d.obj"), Vd, Fd)
    surfmap.write_obj(str(tmp_path / "q.obj"), Vq, Fq)
    (tmp_path / "lm2.txt").write_text(f"{int(np.argmax(Vd[:, 2]))} {int(np.argmin(np.linalg.norm(Vq - [0.3, 0.2, 0], axis=1)))}\n")
    p = cli("map", tmp_path / "d.obj", tmp_path / "q.obj", "--out", tmp_path / "m2.obj", "--report", rep,
            "--landmarks", tmp_path / "lm2.txt", "--quiet")
    assert p.returncode == 0, p.stderr
    report = json.loads(rep.read_text())
    assert report["open"]["landmarks"] == 1 and report["open"]["landmark_error"] < 1e-9
    (tmp_path / "bad.txt").write_text("3 x\n")
    p = cli("map", tmp_path / "d.obj", tmp_path / "q.obj", "--out", tmp_path / "m2.obj", "--report", rep,
            "--landmarks", tmp_path / "bad.txt", "--quiet")
    assert p.returncode != 0 and "bad.txt:1" in p.stderr
