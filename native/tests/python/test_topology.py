"""System of loops from Python and the `surfmap loops` contract."""
import json

import numpy as np
import pytest

import surfmap
from mesh_helpers import torus


def tri_torus(n=16, m=9, R=1.0, r=0.35):
    return torus(R, r, n, m, alternate=False)


def check_loops(r, n_input):
    g = r["genus"]
    x = r["base_vertex"]
    F = r["F"]
    edges = {tuple(sorted(e)) for f in F for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    assert len(r["loops"]) == 2 * g
    seen = set()
    for L in r["loops"]:
        assert L[0] == x and L[-1] == x
        for a, b in zip(L[:-1], L[1:]):
            assert tuple(sorted((int(a), int(b)))) in edges
        inner = [int(v) for v in L[1:-1]]
        assert x not in inner and len(set(inner)) == len(inner) and not seen & set(inner)
        seen |= set(inner)
    assert sorted(r["word"]) == sorted([k for k in range(1, 2 * g + 1)] + [-k for k in range(1, 2 * g + 1)])
    # Refined vertices lie where their origin says.
    assert r["origin_barycentric"].shape == (len(r["V"]), 3)


def test_torus_loops_and_origin():
    V, F = tri_torus()
    r = surfmap.system_of_loops(V, F)
    assert r["genus"] == 1
    check_loops(r, len(V))
    P = np.einsum("ik,ikj->ij", r["origin_barycentric"], V[F[r["origin_face"]]])
    assert np.allclose(P, r["V"], atol=1e-12)
    assert np.array_equal(r["V"][: len(V)], V)


def test_genus_zero_is_input_error():
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    with pytest.raises(surfmap.InputError):
        surfmap.system_of_loops(V, F)


def test_cli_loops(cli, tmp_path):
    V, F = tri_torus()
    mesh = tmp_path / "torus.obj"
    mesh.write_text("".join(f"v {a} {b} {c}\n" for a, b, c in V) + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in F))
    out, refined = tmp_path / "loops.json", tmp_path / "refined.obj"
    p = cli("loops", mesh, "--out", out, "--mesh-out", refined, "--base-vertex", 5)
    assert p.returncode == 0, p.stderr
    j = json.loads(out.read_text())
    assert j["genus"] == 1 and j["base_vertex"] == 5 and len(j["loops"]) == 2
    assert len(j["word"].split()) == 4 and len(j["word_letters"]) == 4
    nv = sum(1 for line in refined.read_text().splitlines() if line.startswith("v "))
    assert nv == j["num_vertices"]
    assert all(max(L) < nv for L in j["loops"])
    octa = tmp_path / "octa.obj"
    octa.write_text("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
                    "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n")
    p = cli("loops", octa, "--out", out, "--mesh-out", refined)
    assert p.returncode == 1 and "genus 0" in p.stderr
