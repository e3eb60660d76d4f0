"""surfmap._core.shapes from Python and the `surfmap generate` contract."""
import numpy as np
import pytest

import surfmap
from surfmap import _core

shapes = _core.shapes


def euler_genus(F):
    edges = {tuple(sorted(e)) for f in F for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    nv = len(np.unique(F))
    return (2 - (nv - len(edges) + len(F))) // 2


def signed_volume(V, F):
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0


@pytest.mark.parametrize(
    "make, genus",
    [
        (lambda: shapes.torus_of_revolution(1.0, 0.5, 32, 16, 1), 1),
        (lambda: shapes.n_hole_torus(3, 32), 3),
        (lambda: shapes.vase(32, smooth=False), 2),
        (lambda: shapes.amphora(32), 2),
        (lambda: shapes.cup(2, 32), 2),
        (lambda: shapes.polycube(holes=4, resolution=40), 4),
        (lambda: shapes.sphere(2), 0),
    ],
)
def test_shapes_are_numpy_closed_surfaces(make, genus):
    V, F = make()
    assert V.dtype == np.float64 and V.ndim == 2 and V.shape[1] == 3
    assert F.dtype == np.int32 and F.ndim == 2 and F.shape[1] == 3
    assert F.min() == 0 and F.max() == len(V) - 1
    # Closed: every directed edge appears once and its reverse once.
    directed = {(int(f[i]), int(f[(i + 1) % 3])) for f in F for i in range(3)}
    assert len(directed) == 3 * len(F)
    assert all((b, a) in directed for a, b in directed)
    assert euler_genus(F) == genus
    assert signed_volume(V, F) > 0


def test_jitter_and_inversion_keep_connectivity():
    V, F = shapes.n_hole_torus(2, 32)
    Vj, Fj = shapes.jitter(V, F, 0.2, seed=5)
    assert np.array_equal(Fj, F) and not np.array_equal(Vj, V)
    Vi, Fi = shapes.sphere_inversion(V, F, [0.0, 0.0, 3.0], 2.0)
    assert euler_genus(Fi) == 2 and signed_volume(Vi, Fi) > 0


def test_errors_are_surfmap_errors():
    with pytest.raises(surfmap.InputError):
        shapes.n_hole_torus(9)
    with pytest.raises(ValueError):
        shapes.torus_of_revolution(0.5, 1.0, 8, 8)
    with pytest.raises(surfmap.Error):
        shapes.amphora(12)


def test_cli_generate_writes_a_valid_obj(cli, tmp_path):
    out = tmp_path / "cup.obj"
    r = cli("generate", "cup", "--genus", "3", "--resolution", "32", "--jitter", "0.1", "--seed", "2", "--out", out)
    assert r.returncode == 0, r.stderr
    info = cli("info", out)
    assert info.returncode == 0, info.stdout + info.stderr
    assert "genus 3" in info.stdout
    bad = cli("generate", "vase", "--resolution", "5", "--out", tmp_path / "bad.obj")
    assert bad.returncode == 1 and "resolution" in bad.stderr
    assert not (tmp_path / "bad.obj").exists()
    assert cli("generate", "teapot", "--out", out).returncode == 2


def test_cli_generate_bent_sphere_then_uniformize(cli, tmp_path):
    """`surfmap generate bent-sphere` (samples::bent_tapered_sphere) and the genus-0 CLI path on it:
    a closed genus-0 mesh whose spherical uniformization embeds (no flipped intrinsic or input
    face) and is Moebius-centred."""
    import json
    out = tmp_path / "bent.obj"
    r = cli("generate", "bent-sphere", "--rings", "20", "--segments", "80", "--stretch", "10", "--out", out)
    assert r.returncode == 0, r.stderr
    assert "genus 0, 1522 vertices" in r.stdout
    report = tmp_path / "u.json"
    u = cli("uniformize", out, "--report", report, "--quiet")
    assert u.returncode == 0, u.stderr
    j = json.loads(report.read_text())
    assert j["genus"] == 0 and j["converged"]
    assert j["flipped_faces"] == 0 and j["input_flipped_faces"] == 0
    assert j["centre_of_mass_norm"] <= 1e-10
    bad = cli("generate", "bent-sphere", "--stretch", "0.5", "--out", tmp_path / "bad.obj")
    assert bad.returncode == 1 and "stretch" in bad.stderr
