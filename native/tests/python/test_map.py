"""The optimal map from Python and the `surfmap map` contract (genus 1)."""
import json
import math
import threading
import time

import numpy as np
import pytest

import surfmap


def torus(R, r, n, m, shift=0):
    """Torus of revolution, n x m grid, quads split along one diagonal (shift varies the connectivity)."""
    u, v = np.meshgrid(np.arange(n) * 2 * math.pi / n, (np.arange(m) + 0.5 * shift) * 2 * math.pi / m, indexing="ij")
    V = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u), r * np.sin(v)], -1).reshape(-1, 3)
    F = []
    for i in range(n):
        for j in range(m):
            a, b = i * m + j, ((i + 1) % n) * m + j
            c, d = ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m
            F += [[a, b, c], [a, c, d]] if (i + j + shift) % 2 == 0 else [[a, b, d], [b, c, d]]
    return V, np.array(F)


def modulus(R, r):
    return r / math.sqrt(R * R - r * r)


@pytest.fixture(scope="module")
def pair():
    return torus(1.0, 0.5, 120, 60), torus(1.5, 0.5, 150, 60, 1)


def test_extremal_map_between_tori(pair):
    (Vs, Fs), (Vt, Ft) = pair
    r = surfmap.surface_map(Vs, Fs, Vt, Ft)
    K = modulus(1.0, 0.5) / modulus(1.5, 0.5)
    assert r["flipped_triangles"] == 0 and r["converged"]
    assert abs(r["distortion"]["mean"] / K - 1) < 0.01
    fwd = r["forward"]
    assert fwd["face"].shape == (len(Vs),) and fwd["barycentric"].shape == (len(Vs), 3)
    # Each forward point is its target face's barycentric combination.
    recon = np.einsum("ik,ikj->ij", fwd["barycentric"], Vt[Ft[fwd["face"]]])
    assert np.abs(recon - fwd["position"]).max() < 1e-9
    # Points on the target torus satisfy its implicit equation.
    rho = np.hypot(fwd["position"][:, 0], fwd["position"][:, 1])
    assert np.abs(np.hypot(rho - 1.5, fwd["position"][:, 2]) - 0.5).max() < 0.01
    assert r["inverse"]["face"].shape == (len(Vt),)
    cands = r["homotopy"]["candidates"]
    assert min(c["energy"] for c in cands) == cands[r["homotopy"]["chosen"]]["energy"]


def test_progress_cancel_and_callback_errors(pair):
    (Vs, Fs), (Vt, Ft) = pair
    stages = []
    surfmap.surface_map(Vs, Fs, Vt, Ft, progress=lambda s, f: stages.append((s, f)) or True)
    assert len(stages) >= 4 and stages[-1][1] == 1.0
    with pytest.raises(surfmap.Cancelled):
        surfmap.surface_map(Vs, Fs, Vt, Ft, progress=lambda s, f: False)

    def boom(stage, fraction):
        raise KeyError("from the callback")

    with pytest.raises(KeyError, match="from the callback"):
        surfmap.surface_map(Vs, Fs, Vt, Ft, progress=boom)


def test_gil_is_released_during_the_solve(pair):
    (Vs, Fs), (Vt, Ft) = pair
    ticks = []
    done = threading.Event()

    def ticker():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.002)

    t = threading.Thread(target=ticker)
    t.start()
    start = time.perf_counter()
    surfmap.surface_map(Vs, Fs, Vt, Ft)
    end = time.perf_counter()
    done.set()
    t.join()
    during = [x for x in ticks if start < x < end]
    assert len(during) >= 5, f"only {len(during)} ticks while the solve ran {end - start:.2f}s"


def test_bad_pairs_are_refused():
    Vs, Fs = torus(1.0, 0.4, 20, 10)
    octa_V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    octa_F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    with pytest.raises(surfmap.InputError, match="genus 1.*genus 0"):
        surfmap.surface_map(Vs, Fs, octa_V, octa_F)
    with pytest.raises(surfmap.InputError, match="target: .*open"):
        surfmap.surface_map(Vs, Fs, Vs, Fs[:-1])


def test_cli_map_writes_outputs(tmp_path, cli, pair):
    (Vs, Fs), (Vt, Ft) = pair
    src, dst = tmp_path / "a.obj", tmp_path / "b.obj"
    surfmap.write_obj(str(src), Vs, Fs)
    surfmap.write_obj(str(dst), Vt, Ft)
    out, rep, corr = tmp_path / "morph.obj", tmp_path / "report.json", tmp_path / "corr.txt"
    r = cli("map", src, dst, "--out", out, "--report", rep, "--correspondence", corr, "--quiet")
    assert r.returncode == 0, r.stderr
    report = json.loads(rep.read_text())
    for key in ("genus", "converged", "iterations", "energy", "distortion", "initial_distortion",
                "flipped_triangles", "homotopy", "time_s"):
        assert key in report
    assert report["flipped_triangles"] == 0 and report["genus"] == 1
    assert {"initial", "final", "history"} <= set(report["energy"])
    lines = corr.read_text().splitlines()
    assert len(lines) == len(Vs)
    face, *bary = lines[0].split()
    assert 0 <= int(face) < len(Ft) and abs(sum(map(float, bary)) - 1) < 1e-9
    morph = surfmap.load_mesh(str(out))
    assert morph["V"].shape == Vs.shape


def test_cli_map_bad_input_writes_nothing(tmp_path, cli):
    Vs, Fs = torus(1.0, 0.4, 20, 10)
    src, bad = tmp_path / "a.obj", tmp_path / "open.obj"
    surfmap.write_obj(str(src), Vs, Fs)
    surfmap.write_obj(str(bad), Vs, Fs[:-2])
    out, rep = tmp_path / "morph.obj", tmp_path / "report.json"
    r = cli("map", src, bad, "--out", out, "--report", rep)
    assert r.returncode == 1
    assert "open" in r.stderr and "open.obj" in r.stderr
    assert not out.exists() and not rep.exists()
