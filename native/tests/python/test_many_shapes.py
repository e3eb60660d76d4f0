"""Many shapes (docs/many_shapes.md): canonical domains, the comparison table through a common
domain or pairwise maps, and `surfmap batch` on a 2-worker Dask LocalCluster (resumable)."""
import csv
import json
import math
import os
import pathlib

import numpy as np
import pytest

import surfmap
from surfmap import batch as B
from surfmap import compare as C

_repo = pathlib.Path(__file__).resolve().parents[3]


def rotation(a=0.7, b=1.1):
    Rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
    return Rx @ Rz


def euler_genus(V, F):
    F = np.asarray(F)
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    edges = np.unique(e, axis=0)
    assert 2 * len(edges) == 3 * len(F)  # closed: every edge in two faces
    return (2 - (len(V) - len(edges) + len(F))) // 2


# ---- canonical domains ----------------------------------------------------------------------


@pytest.mark.parametrize("genus,kind,layout", [(2, "n-torus", "row"), (4, "n-torus", "row"),
                                               (3, "n-torus", "ring"), (2, "polycube", "row")])
def test_canonical_domain_is_clean(genus, kind, layout):
    V, F, q = surfmap.shapes.canonical_domain(genus, kind, layout, resolution=32)
    assert euler_genus(V, F) == genus == q["genus"]
    info = surfmap.inspect(V, F)
    assert info["valid"] and info["genus"] == genus and info["num_components"] == 1
    P = V[F]
    assert np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() / 6 > 0  # outward
    assert C.face_areas(V, F).sum() == pytest.approx(1.0, rel=1e-9)
    assert q["min_angle_deg"] > 5 and q["mean_min_angle_deg"] > 40 and q["fraction_below_20_deg"] < 0.02


def test_domain_cli(cli, tmp_path):
    out, rep = tmp_path / "D.obj", tmp_path / "D.json"
    r = cli("domain", "--genus", 3, "--kind", "n-torus", "--layout", "ring", "--resolution", 32, "--out", out,
            "--report", rep)
    assert r.returncode == 0, r.stderr
    info = json.loads(cli("info", out, "--json").stdout)
    assert info["genus"] == 3 and info["valid"]
    assert json.loads(rep.read_text())["genus"] == 3
    bad = cli("domain", "--genus", 9, "--out", tmp_path / "x.obj")
    assert bad.returncode == 1 and bad.stderr.count("\n") == 1 and "genus 9" in bad.stderr
    bad = cli("domain", "--genus", 2, "--kind", "polycube", "--layout", "ring", "--out", tmp_path / "x.obj")
    assert bad.returncode == 1 and "ring" in bad.stderr


# ---- λ and H ------------------------------------------------------------------------------


def test_mean_curvature_is_the_addons_and_scale_free():
    import sys
    sys.path.insert(0, str(_repo / "addon"))
    from surface_map import distortion as M   # the add-on's bpy-free colour code
    V, F = surfmap.shapes.vase(32)
    H = C.mean_curvature(V, F)
    np.testing.assert_allclose(H, M.mean_curvature(V, F), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(C.mean_curvature(3.5 * V @ rotation().T + 2, F), H, rtol=1e-9, atol=1e-9)
    Vs, Fs = surfmap.shapes.sphere(4)
    assert np.median(C.mean_curvature(Vs, Fs)) == pytest.approx(1.0, abs=0.01)  # round sphere: 1


def test_lambda_of_the_identity_is_zero_and_integrates_to_one():
    V, F = surfmap.shapes.torus_of_revolution(1.5, 0.5, 30, 15)
    lam, _ = C.pulled_back_fields(V, F, V, F, np.zeros(len(V), int), np.zeros((len(V), 3)), 2.0 * V)
    np.testing.assert_allclose(lam, 0, atol=1e-12)
    # A map that doubles one half's area: ∫ e^λ over the unit-area domain is 1 by normalisation.
    W = V.copy()
    W[V[:, 0] > 0] *= math.sqrt(2)
    lam, _ = C.pulled_back_fields(V, F, V, F, np.zeros(len(V), int), np.zeros((len(V), 3)), W)
    w = C.domain_weights(V, F)
    assert np.dot(w, np.exp(lam)) == pytest.approx(1.0, abs=0.02)
    assert lam.std() > 0.2


# ---- comparison ---------------------------------------------------------------------------


def genus1_shapes():
    # Genus 1: the map onto a torus is unique only up to the target's translations (chosen
    # through the base vertices), so the copy keeps the mesh (the genus-2 test remeshes).
    base = surfmap.shapes.torus_of_revolution(1.6, 0.5, 48, 20)
    V, F = base
    copy = (2.5 * V @ rotation().T + np.array([1.0, -2.0, 0.5]), F)  # scaled, rotated, moved
    return {"base": base, "fat": surfmap.shapes.torus_of_revolution(1.2, 0.7, 48, 24),
            "thin": surfmap.shapes.torus_of_revolution(2.5, 0.4, 60, 14), "copy": copy,
            "mid": surfmap.shapes.torus_of_revolution(2.0, 0.5, 48, 18)}


@pytest.mark.parametrize("mode", ["domain", "direct"])
def test_compare_genus1_invariance(mode, tmp_path):
    S = genus1_shapes()
    dom = surfmap.shapes.canonical_domain(1, resolution=32)[:2] if mode == "domain" else None
    r = C.compare(list(S.values()), dom, beta=1.0, names=list(S))
    E = r["matrix"]
    assert E.shape == (5, 5) and r["mode"] == mode
    np.testing.assert_array_equal(E, E.T)
    np.testing.assert_array_equal(np.diag(E), 0)
    names = r["names"]
    b, c = names.index("base"), names.index("copy")
    assert C.nearest(E, b) == c and C.nearest(E, c) == b
    others = [E[b, k] for k in range(5) if k not in (b, c)]
    assert E[b, c] < 1e-3 * min(others)
    # Scale invariance exactly where nothing else changes: the same mesh scaled by 7.
    V, F = S["fat"]
    r2 = C.compare([(V, F), (7.0 * V, F), S["base"]], dom, beta=1.0)
    assert r2["matrix"][0, 1] < 1e-4 * r2["matrix"][0, 2]
    np.testing.assert_allclose(r2["matrix"][0, 2], r2["matrix"][1, 2], rtol=1e-5)


def genus2_shapes():
    V, F = surfmap.shapes.vase(40)
    dt = surfmap.shapes.n_hole_torus(2, 36)
    inverted = surfmap.shapes.sphere_inversion(*dt, np.array([0.5, 0.3, 2.5]), 2.0)  # conformal, not isometric
    return {"vase": surfmap.shapes.vase(32), "amphora": surfmap.shapes.amphora(32),
            "double_torus": dt, "polycube": surfmap.shapes.polycube(2, 32),
            "inverted_torus": inverted, "vase_copy": (3.0 * V @ rotation().T + 5.0, F)}


def test_compare_six_genus2_shapes(tmp_path):
    S = genus2_shapes()
    dom_path = tmp_path / "D.obj"
    Vd, Fd, _ = surfmap.shapes.canonical_domain(2, resolution=32)
    surfmap.write_obj(str(dom_path), Vd, Fd)
    r = C.compare(list(S.values()), str(dom_path), names=list(S))
    E, names = r["matrix"], r["names"]
    np.testing.assert_array_equal(E, E.T)
    np.testing.assert_array_equal(np.diag(E), 0)
    assert (E[~np.eye(6, dtype=bool)] > 0).all()
    v, c = names.index("vase"), names.index("vase_copy")
    assert C.nearest(E, v) == c and C.nearest(E, c) == v
    assert E[v, c] < 0.3 * min(E[v, k] for k in range(6) if k not in (v, c))
    assert r["symmetries"] >= 2  # the row of two tori has its half-turns
    assert all(rep["flipped_triangles"] == 0 for rep in r["reports"])
    png = tmp_path / "matrix.png"
    C.plot(str(png), names, E)
    import matplotlib.image
    img = matplotlib.image.imread(str(png))
    assert img.shape[0] > 200 and img.shape[1] > 400 and img[..., :3].std() > 0.05  # not blank
    X = C.classical_mds(E)
    assert X.shape == (6, 2)


def test_compare_cli_and_errors(cli, tmp_path):
    paths = []
    for k, (R, r) in enumerate([(1.5, 0.5), (2.0, 0.5), (1.2, 0.6)]):
        V, F = surfmap.shapes.torus_of_revolution(R, r, 36, 16)
        paths.append(tmp_path / f"t{k}.obj")
        surfmap.write_obj(str(paths[-1]), V, F)
    out, png = tmp_path / "table.csv", tmp_path / "m.png"
    res = cli("compare", *paths, "--out", out, "--plot", png, "--beta", 0.5)
    assert res.returncode == 0, res.stderr
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["shape", "t0", "t1", "t2"] and len(rows) == 4
    E = np.array([[float(x) for x in row[1:]] for row in rows[1:]])
    np.testing.assert_allclose(E, E.T)
    np.testing.assert_array_equal(np.diag(E), 0)
    doc = json.loads((tmp_path / "table.json").read_text())
    assert doc["beta"] == 0.5 and doc["mode"] == "direct" and len(doc["reports"]) == 3
    assert png.stat().st_size > 10000
    sphere = tmp_path / "s.obj"
    surfmap.write_obj(str(sphere), *surfmap.shapes.sphere(2))
    bad = cli("compare", paths[0], sphere, "--out", tmp_path / "bad.csv")
    assert bad.returncode == 1 and "genus" in bad.stderr and bad.stderr.count("\n") == 1
    assert not (tmp_path / "bad.csv").exists()


# ---- batch on a Dask LocalCluster --------------------------------------------------------


def torus_files(folder, count=13):
    folder.mkdir(exist_ok=True)
    paths = []
    for k in range(count):
        R = 1.2 + 0.15 * k
        r = 0.3 + 0.04 * (k % 7)
        V, F = surfmap.shapes.torus_of_revolution(R, r, 24 + 2 * (k % 3), 12, k % 3)
        paths.append(str(folder / f"t{k:02d}.obj"))
        surfmap.write_obj(paths[-1], V, F)
    return paths


def strip_times(rep):
    # (the stage table holds measurements too: seconds, peak memory)
    return {k: v for k, v in rep.items() if k not in ("time_s", "wall_time_s", "stages")}


def test_batch_cluster_equals_serial_and_resumes(tmp_path):
    paths = torus_files(tmp_path / "meshes")
    jobs = B.make_jobs("template", paths)  # t00 onto the 12 others
    assert len(jobs) == 12
    out = tmp_path / "cluster"
    res = B.run_jobs(jobs, str(out), workers=2, quiet=True)
    assert [r["status"] for r in res] == ["done"] * 12
    ser = B.run_serial(jobs, str(tmp_path / "serial"))
    for a, b, job in zip(res, ser, jobs):
        assert strip_times(a["report"]) == strip_times(b["report"])
        ma = (out / "jobs" / job["id"] / "morph.obj").read_text()
        assert ma == (tmp_path / "serial" / "jobs" / job["id"] / "morph.obj").read_text()
    # Resumable: three results lost (as if their worker died); a re-run does only those.
    lost = [jobs[k]["id"] for k in (2, 5, 11)]
    for job_id in lost:
        (out / "jobs" / job_id / "report.json").unlink()
    kept = {j["id"]: (out / "jobs" / j["id"] / "report.json").stat().st_mtime_ns for j in jobs if j["id"] not in lost}
    # A failing job among them (genus 1 onto genus 0) is recorded and does not stop the others.
    sphere = tmp_path / "meshes" / "sphere.obj"
    surfmap.write_obj(str(sphere), *surfmap.shapes.sphere(2))
    jobs2 = jobs + [{"id": "bad", "source": paths[0], "target": str(sphere)}]
    # This time on an existing cluster, reached through its scheduler's address.
    from distributed import LocalCluster
    B._ensure_worker_path()
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster:
        res2 = B.run_jobs(jobs2, str(out), scheduler=cluster.scheduler_address, quiet=True)
    status = {r["id"]: r["status"] for r in res2}
    assert {k for k, s in status.items() if s == "done"} == set(lost)
    assert {k for k, s in status.items() if s == "skipped"} == set(kept)
    assert status["bad"] == "failed" and "genus" in json.loads((out / "jobs" / "bad" / "error.json").read_text())["error"]
    for job_id, mtime in kept.items():
        assert (out / "jobs" / job_id / "report.json").stat().st_mtime_ns == mtime
    for a, job in zip(res2, jobs):
        assert strip_times(a["report"]) == strip_times(ser[jobs.index(job)]["report"])
    rows = B.write_summary(str(out), jobs2, res2)
    assert [r["status"] for r in rows].count("done") == 12 and rows[-1]["status"] == "failed"
    assert not list(out.rglob("*.tmp*"))  # every file renamed into place


def test_batch_cli_domain_table(cli, tmp_path):
    paths = torus_files(tmp_path / "meshes", count=4)
    dom = tmp_path / "D.obj"
    assert cli("domain", "--genus", 1, "--resolution", 32, "--out", dom).returncode == 0
    out = tmp_path / "out"
    r = cli("batch", "domain", dom, *paths, "--out", out, "--workers", 2, "--table", "--plot", tmp_path / "m.png")
    assert r.returncode == 0, r.stderr
    assert "4/4" in r.stderr
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert [x["status"] for x in rows] == ["done"] * 4
    E = np.array([[float(x) for x in row[1:]] for row in list(csv.reader((out / "table.csv").open()))[1:]])
    # The same table as surfmap.compare in one process.
    ref = C.compare(paths, str(dom))["matrix"]
    np.testing.assert_allclose(E, ref, rtol=1e-6, atol=1e-12)  # other processes: round-off
    assert (tmp_path / "m.png").exists()
    assert cli("batch", "--help").returncode == 0
