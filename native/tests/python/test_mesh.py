"""Mesh intake from Python and the `surfmap info` contract."""
import json
import math

import numpy as np
import pytest

import surfmap

OCTA_V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
OCTA_F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])


def quad_torus(n=12, m=8, R=1.0, r=0.4):
    u, v = np.meshgrid(np.arange(n) * 2 * math.pi / n, np.arange(m) * 2 * math.pi / m, indexing="ij")
    V = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u), r * np.sin(v)], -1).reshape(-1, 3)
    quads = [[i * m + j, ((i + 1) % n) * m + j, ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m]
             for i in range(n) for j in range(m)]
    return V, quads


def test_exception_hierarchy():
    assert issubclass(surfmap.InputError, surfmap.Error)
    assert issubclass(surfmap.InputError, ValueError)
    assert issubclass(surfmap.SolveError, RuntimeError)
    assert issubclass(surfmap.Cancelled, surfmap.Error)


def test_inspect_counts_and_genus():
    info = surfmap.inspect(OCTA_V, OCTA_F)
    assert info["valid"] and info["genus"] == 0 and info["num_edges"] == 12
    V, quads = quad_torus()
    info = surfmap.inspect(V, quads)
    assert info["valid"] and info["genus"] == 1 and info["euler_characteristic"] == 0


def test_intake_triangulates_polygons_and_keeps_corner_map():
    V, quads = quad_torus(9, 7)
    r = surfmap.intake(V, quads)
    assert r["F"].shape == (2 * 9 * 7, 3)
    for t, tri in enumerate(r["F"]):
        assert set(tri) <= set(quads[r["source_polygon"][t]])


def test_intake_orients_outward():
    V, quads = quad_torus()
    r = surfmap.intake(V, [q[::-1] for q in quads])
    assert r["flipped"]
    a, b, c = (r["V"][r["F"][:, k]] for k in range(3))
    assert np.einsum("ij,ij->i", a, np.cross(b, c)).sum() > 0


@pytest.mark.parametrize(
    "mutate, expected",
    [
        (lambda V, F: (np.where(np.arange(18).reshape(6, 3) == 7, np.nan, V), F), "vertex 2"),
        (lambda V, F: (V, np.where(F == 5, 9, F)), "out of range"),
        (lambda V, F: (V, F[:-1]), "open"),
        (lambda V, F: (V, np.vstack([F[:-1], F[-1][::-1]])), "inconsistently oriented"),
    ],
)
def test_bad_input_raises_input_error_naming_the_problem(mutate, expected):
    V, F = mutate(OCTA_V.copy(), OCTA_F.copy())
    with pytest.raises(surfmap.InputError, match=expected):
        surfmap.intake(V, F)


def test_bad_shapes_of_arrays():
    with pytest.raises(surfmap.InputError):
        surfmap.intake(np.zeros((4, 2)), OCTA_F)
    with pytest.raises(surfmap.InputError):
        surfmap.intake(OCTA_V, np.zeros((3, 4, 1), int))


def test_cli_info_exit_status(tmp_path, cli):
    good = tmp_path / "octa.obj"
    surfmap.write_obj(str(good), OCTA_V, OCTA_F)
    r = cli("info", good)
    assert r.returncode == 0, r.stderr
    assert "genus 0" in r.stdout
    bad = tmp_path / "bad.obj"
    surfmap.write_obj(str(bad), OCTA_V, np.vstack([OCTA_F, OCTA_F[:1]]))
    r = cli("info", bad)
    assert r.returncode == 1
    assert "non-manifold" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = cli("info", tmp_path / "missing.obj")
    assert r.returncode == 1 and "does not exist" in r.stderr
    r = cli("info", "--json", good)
    assert '"genus": 0' in r.stdout


def test_cli_info_accepts_a_valid_open_surface(tmp_path, cli):
    # Issue 16: `surfmap map` takes open surfaces, so `info` says what one is (genus, loops)
    # and exits 0, where it said "not supported yet" and exited 1; an open mesh with another
    # problem (a bowtie vertex) still exits 1 naming it, and the closed-only commands say
    # which command takes open surfaces.
    disk = tmp_path / "disk.obj"
    surfmap.write_obj(str(disk), OCTA_V, OCTA_F[:-1])
    r = cli("info", disk)
    assert r.returncode == 0, r.stderr
    assert "valid open manifold surface: genus 0 with 1 boundary loop" in r.stdout
    assert "not supported" not in r.stdout
    j = json.loads(cli("info", "--json", disk).stdout)
    assert j["open"]["genus"] == 0 and j["open"]["boundary_loops"] == 1
    assert j["open"]["boundary_lengths"][0] == pytest.approx(3 * np.sqrt(2))
    assert j["problems"] == [] and j["valid"] is False
    bowtie = tmp_path / "bowtie.obj"
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 2, 0], [3, 2, 0], [3, 3, 0]], float)
    surfmap.write_obj(str(bowtie), V, np.array([[0, 1, 4], [0, 4, 3], [1, 2, 4], [4, 5, 6]]))
    r = cli("info", bowtie)
    assert r.returncode == 1
    assert "vertex 4" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = cli("uniformize", disk, "--report", tmp_path / "u.json")
    assert r.returncode == 1
    assert "needs a closed surface" in r.stderr and "surfmap map" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_zero_area_faces_are_mollified_with_a_note():
    # Issue 13: a vertex placed exactly on edge (0, 2) makes face (0, 2, 4)
    # flat; intake accepts it and reports the intrinsic mollification.
    V = OCTA_V.copy()
    V[4] = [0.5, 0.5, 0.0]
    info = surfmap.inspect(V, OCTA_F)
    assert info["valid"], info["problems"]
    assert info["zero_area_faces"] == 1
    assert info["mollified_faces"] >= 1 and info["mollify_epsilon"] > 0
    assert info["notes"][-1].startswith("mollified: ")
    r = surfmap.intake(V, OCTA_F)
    assert r["info"]["mollified_faces"] == info["mollified_faces"]
    clean = surfmap.inspect(OCTA_V, OCTA_F)
    assert clean["mollified_faces"] == 0 and clean["mollify_epsilon"] == 0 and clean["notes"] == []


def test_generated_degenerate_and_cad_meshes_are_accepted():
    V, F = surfmap._core.shapes.cad_plate(2, 32, 1.0)
    assert surfmap.inspect(V, F)["genus"] == 2
    V, F = surfmap._core.shapes.torus_of_revolution(1.0, 0.4, 16, 8)
    V2, F2 = surfmap._core.shapes.insert_degenerate_faces(V, F, 4, 0.0, 1)
    info = surfmap.inspect(V2, F2)
    assert info["valid"] and info["genus"] == 1 and info["zero_area_faces"] >= 4


@pytest.mark.parametrize("name,text", [
    ("huge.off", "OFF\n2000000000 2000000000 0\n0 0 0\n"),
    ("face.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n999999999 0 1 2\n"),
    ("header.ply", "ply\nformat ascii 1.0\nelement ve"),
    ("face.obj", "v 0 0 0\nv 1 0 0\nf\nf 1 2 x\n"),
])
def test_corrupt_files_give_one_line_input_errors(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(surfmap.InputError) as e:
        surfmap.load_mesh(str(path))
    assert "\n" not in str(e.value) and name in str(e.value)
