"""EXPERIMENTAL doubling for open surfaces of any (g, b) (surfmap.open_double; docs/open_surfaces.md):
a pair of pants (genus 0, 3 boundary loops; the double has genus 2) and a posed copy map near the
identity, symmetric under the reflections, boundary loop i onto loop i, no flipped triangle."""
import numpy as np
import pytest

import surfmap
from surfmap import open_double


def compact(V, F):
    used = np.unique(F)
    remap = -np.ones(len(V), int)
    remap[used] = np.arange(len(used))
    return V[used], remap[F]


def pants(level=4):
    """A sphere with three caps of different sizes removed around non-coplanar directions
    (no mirror symmetry)."""
    V, F = surfmap.shapes.sphere(level)
    V, F = np.asarray(V, float), np.asarray(F)
    dirs = np.array([[1, 0, 0.3], [-0.5, 0.866, -0.2], [-0.4, -0.8, 0.5]])
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    c = V[F].mean(axis=1)
    c /= np.linalg.norm(c, axis=1)[:, None]
    return compact(V, F[np.all(c @ dirs.T < np.array([0.8, 0.85, 0.75]), axis=1)])


def test_split_and_double_have_the_right_topology():
    V, F = pants()
    V2, F2, parent = open_double.split_boundary_chords(V, F)
    assert np.allclose(V2[:len(V)], V) and len(parent) == len(F2)
    it = surfmap.intake(V2, F2, allow_boundary=True)
    assert it["info"]["genus"] == 0 and len(it["boundary_loops"]) == 3
    D = open_double.double_surface(V2, F2)
    info = surfmap.inspect(D["V"], D["F"])
    assert info["valid"] and info["genus"] == 2          # 2g + b - 1
    sig = D["sigma"]
    assert np.array_equal(sig[sig], np.arange(len(sig)))
    fixed = np.flatnonzero(sig == np.arange(len(sig)))
    assert np.array_equal(np.sort(fixed), np.sort(np.concatenate(D["boundary_loops"])))


def test_pants_and_posed_copy_map_near_the_identity():
    Vs, Fs = pants()
    Vt = Vs.copy()
    Vt[:, 0] += 0.1 * Vt[:, 1] ** 2                        # a bend
    r = open_double.map_by_doubling(Vs, Fs, Vt, Fs)
    diag = np.linalg.norm(Vt.max(axis=0) - Vt.min(axis=0))
    assert r["double_genus"] == 2 and (r["genus"], r["boundary_loops"]) == (0, 3)
    assert r["symmetry_error"] < 0.02 and r["same_sheet"] > 0.9
    assert r["boundary_pairing"] == [0, 1, 2]
    assert r["flipped_triangles"] == 0
    assert r["snap_distance"] < 0.01 * diag
    d = np.linalg.norm(r["forward"]["position"] - Vt, axis=1)
    assert d.mean() < 0.02 * diag, d.mean() / diag
    # Boundary onto boundary: each source loop's vertices on the same target loop's polyline.
    for loop in open_double.boundary_loops(Vs, Fs):
        P = r["forward"]["position"][loop]
        A, B = Vt[loop], Vt[np.roll(loop, -1)]
        t = np.clip(np.einsum("pij,ij->pi", P[:, None] - A[None], B - A) / np.einsum("ij,ij->i", B - A, B - A), 0, 1)
        Q = A[None] + t[..., None] * (B - A)[None]
        assert np.linalg.norm(Q - P[:, None], axis=2).min(axis=1).max() < 1e-9


def test_doubling_refuses_different_topology():
    Vs, Fs = pants(3)
    V, F = surfmap.shapes.sphere(3)
    V, F = np.asarray(V, float), np.asarray(F)
    keep = np.asarray(V)[F].mean(axis=1)[:, 2] < 0.8    # one cap removed: a disk
    with pytest.raises(surfmap.InputError, match="genus 0 with 3 .*genus 0 with 1"):
        open_double.map_by_doubling(Vs, Fs, *compact(V, F[keep]))


def test_punctured_torus_and_posed_copy_map_near_the_identity():
    """Genus 1 with one boundary loop (the double has genus 2)."""
    V, F = surfmap.shapes.torus_of_revolution(1.0, 0.45, 48, 24)
    V, F = np.asarray(V, float), np.asarray(F)
    hole = np.linalg.norm(V[F].mean(axis=1) - np.array([1.0, 0, 0.45]), axis=1) < 0.3
    Vs, Fs = compact(V, F[~hole])
    Vt = Vs.copy()
    Vt[:, 2] *= 1.1
    r = open_double.map_by_doubling(Vs, Fs, Vt, Fs)
    diag = np.linalg.norm(Vt.max(axis=0) - Vt.min(axis=0))
    assert (r["genus"], r["boundary_loops"], r["double_genus"]) == (1, 1, 2)
    assert r["symmetry_error"] < 0.02 and r["flipped_triangles"] == 0 and r["boundary_pairing"] == [0]
    assert np.linalg.norm(r["forward"]["position"] - Vt, axis=1).mean() < 0.02 * diag
