"""The optimal map from Python and the `surfmap map` contract (genus 1)."""
import json
import math
import re
import threading
import time

import numpy as np
import pytest

import surfmap
from mesh_helpers import nearest_vertex, torus


def modulus(R, r):
    return r / math.sqrt(R * R - r * r)


@pytest.fixture(scope="module")
def pair():
    return torus(1.0, 0.5, 120, 60), torus(1.5, 0.5, 150, 60, 1)


def cli_map(cli, tmp_path, *flags, pair=None):
    """`surfmap map s.obj t.obj --out o.obj --report r.json --quiet *flags` in tmp_path, the pair
    ((V, F) source, (V, F) target) written there first when given: (the finished process, the
    report as a dict, or None when the map failed)."""
    if pair is not None:
        for name, (V, F) in zip(("s.obj", "t.obj"), pair):
            surfmap.write_obj(str(tmp_path / name), V, F)
    p = cli("map", tmp_path / "s.obj", tmp_path / "t.obj", "--out", tmp_path / "o.obj", "--report",
            tmp_path / "r.json", "--quiet", *flags)
    return p, (json.loads((tmp_path / "r.json").read_text()) if p.returncode == 0 else None)


def test_extremal_map_between_tori(pair):
    (Vs, Fs), (Vt, Ft) = pair
    r = surfmap.surface_map(Vs, Fs, Vt, Ft)
    K = modulus(1.0, 0.5) / modulus(1.5, 0.5)
    assert r["flipped_triangles"] == 0 and r["converged"]
    assert surfmap.verify(Vs, Fs, Vt, Ft, r)["certified"]
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


def test_target_metric_automatic_by_default_flips_and_fixed_on_request():
    # Genus 1: the target's flip-based metric by default and on request
    # (flips counted, no refinement), the fixed-connectivity one on request
    # (a torus of revolution, where it exists unrefined); all certified.
    Vs, Fs = torus(1.0, 0.5, 40, 20)
    Vt, Ft = torus(1.5, 0.5, 50, 20, 1)
    auto = surfmap.surface_map(Vs, Fs, Vt, Ft)
    flips = surfmap.surface_map(Vs, Fs, Vt, Ft, target_metric="flips")
    fixed = surfmap.surface_map(Vs, Fs, Vt, Ft, target_metric="fixed")
    assert flips["target_metric"] == "intrinsic Delaunay" and flips["target_refinement_splits"] == 0
    assert flips["target_metric_choice"] == "requested"
    assert fixed["target_metric"] == "fixed connectivity" and fixed["target_flips"] == 0
    assert fixed["target_metric_choice"] == "requested"
    assert auto["target_metric"] == "intrinsic Delaunay" and auto["target_flips"] == flips["target_flips"]
    assert auto["target_refinement_splits"] == 0 and auto["target_metric_choice"].startswith("automatic")
    # The automatic choice is the flip path itself: the same map.
    assert np.array_equal(np.asarray(auto["forward"]["position"]), np.asarray(flips["forward"]["position"]))
    for r in (flips, fixed):
        assert r["converged"] and r["flipped_triangles"] == 0
        assert surfmap.verify(Vs, Fs, Vt, Ft, r)["certified"]
    # The same conformal structure computed two ways: the same extremal map.
    assert abs(flips["distortion"]["mean"] / fixed["distortion"]["mean"] - 1) < 1e-3
    with pytest.raises(surfmap.InputError, match="'auto', 'flips', 'fixed' or 'fixed-first'"):
        surfmap.surface_map(Vs, Fs, Vt, Ft, target_metric="nope")
    # The report repeats the option in the same spelling.
    assert [r["target_metric_requested"] for r in (auto, flips, fixed)] == ["auto", "flips", "fixed"]
    # fixed-first: the fixed metric exists here, so it is the fixed path's map.
    first = surfmap.surface_map(Vs, Fs, Vt, Ft, target_metric="fixed-first")
    assert first["target_metric_requested"] == "fixed-first"
    assert first["target_metric"] == "fixed connectivity" and first["target_flips"] == 0
    assert first["target_metric_choice"] == "fixed first: the fixed-connectivity metric"
    assert np.array_equal(np.asarray(first["forward"]["position"]), np.asarray(fixed["forward"]["position"]))


def test_a_missing_metric_is_a_uniformization_error():
    # One exception hierarchy: a metric that cannot be delivered is a type (a
    # SolveError, so older callers still catch it), never a message to match.
    assert issubclass(surfmap.UniformizationError, surfmap.SolveError)
    assert issubclass(surfmap.UniformizationError, RuntimeError)
    # A torus whose fixed-connectivity flat metric does not exist unrefined: every
    # 4th face split at a point just above an edge's midpoint (an angle near 180
    # degrees); the flip path and fixed-first deliver one.
    V, F = torus(1.0, 0.5, 24, 12)
    V, F = list(map(list, V)), [list(f) for f in F]
    for i in range(0, len(F), 4):
        a, b, c = F[i]
        p = [(V[a][k] + V[b][k]) / 2 + 1e-4 * (V[c][k] - (V[a][k] + V[b][k]) / 2) for k in range(3)]
        V.append(p)
        m = len(V) - 1
        F[i] = [a, b, m]
        F += [[b, c, m], [c, a, m]]
    V, F = np.asarray(V), np.asarray(F)
    with pytest.raises(surfmap.UniformizationError):
        surfmap.uniformize(V, F, metric="fixed")
    u = surfmap.uniformize(V, F, metric="fixed-first")
    assert u["metric"].startswith("intrinsic Delaunay (fixed connectivity failed: uniformize:")
    flips = surfmap.uniformize(V, F)
    assert abs(u["tau_reduced"] - flips["tau_reduced"]) < 1e-9


def test_capabilities_name_keywords_surface_map_accepts():
    # The add-on tests membership here (no docstring search): every name
    # must be a keyword argument of surface_map, and the ones the add-on
    # asks for must be there.
    caps = surfmap.capabilities
    assert isinstance(caps, frozenset) and caps is surfmap._core.CAPABILITIES
    assert {"landmarks", "method", "tolerance", "source_weights", "solve_progress"} <= caps
    signature = surfmap.surface_map.__doc__.splitlines()[0]
    params = {part.strip().split(":")[0] for part in signature[signature.index("(") + 1:signature.rindex(")")].split(",")}
    assert caps <= params, caps - params
    Vs, Fs = torus(1.0, 0.5, 12, 6)
    with pytest.raises(TypeError):
        surfmap.surface_map(Vs, Fs, Vs, Fs, no_such_keyword=1)


def test_features_name_what_the_module_does_beyond_keywords():
    # The add-on allows landmarks on open pairs only when "open_landmarks" is listed.
    assert surfmap.features is surfmap._core.FEATURES and "open_landmarks" in surfmap.features
    assert not (surfmap.features & surfmap.capabilities)


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
                "flipped_triangles", "degenerate_triangles", "flat_triangles", "homotopy", "time_s"):
        assert key in report
    assert report["flipped_triangles"] == 0 and report["genus"] == 1
    v = cli("verify", src, dst, "--correspondence", corr)
    assert v.returncode == 0 and "\nCERTIFIED:" in v.stdout, v.stdout + v.stderr
    assert {"initial", "final", "history"} <= set(report["energy"])
    lines = corr.read_text().splitlines()
    # forward lines first (the original format), then the inverse section (docs/verification.md)
    assert len(lines) == len(Vs) + 1 + len(Vt) and lines[len(Vs)].startswith("# inverse")
    face, *bary = lines[0].split()
    assert 0 <= int(face) < len(Ft) and abs(sum(map(float, bary)) - 1) < 1e-9
    morph = surfmap.load_mesh(str(out))
    assert morph["V"].shape == Vs.shape


def test_cli_map_timings_print_the_report_stage_table(tmp_path, cli, pair):
    # Issue 19: --timings prints the report's stage table (one line per stage, then total).
    (Vs, Fs), (Vt, Ft) = pair
    src, dst = tmp_path / "a.obj", tmp_path / "b.obj"
    surfmap.write_obj(str(src), Vs, Fs)
    surfmap.write_obj(str(dst), Vt, Ft)
    out, rep = tmp_path / "morph.obj", tmp_path / "report.json"
    r = cli("map", src, dst, "--out", out, "--report", rep, "--quiet", "--timings", "--threads", "1")
    assert r.returncode == 0, r.stderr
    stages = json.loads(rep.read_text())["stages"]
    lines = r.stderr.strip().splitlines()
    assert lines[0].split()[:3] == ["stage", "time_s", "analyses"]
    assert len(lines) == 1 + len(stages) and lines[-1].startswith("total")
    assert {s["name"] for s in stages} == set(json.loads(rep.read_text())["time_s"])
    for line, s in zip(lines[1:], stages):
        assert line.startswith(s["name"]) and line.split()[-4:-1] == [str(s["analyses"]), str(s["factorisations"]),
                                                                      str(s["newton_iterations"])]
    # genus 1: one factorisation of the source Laplacian at least, counted in the total
    assert stages[-1]["factorisations"] >= 1 and stages[-1]["peak_memory_mb"] > 0
    bad = cli("map", src, dst, "--out", out, "--report", rep, "--threads", "-1")
    assert bad.returncode != 0


def test_python_threads_option_gives_the_same_map(pair):
    (Vs, Fs), (Vt, Ft) = pair
    assert "threads" in surfmap.CAPABILITIES
    one = surfmap.surface_map(Vs, Fs, Vt, Ft, threads=1)
    two = surfmap.surface_map(Vs, Fs, Vt, Ft, threads=2)
    assert one["energy"]["final"] == pytest.approx(two["energy"]["final"], rel=1e-12)
    assert np.array_equal(one["forward"]["face"], two["forward"]["face"])
    assert [s["name"] for s in one["stages"]][-1] == "total"
    with pytest.raises(surfmap.InputError, match="threads"):
        surfmap.surface_map(Vs, Fs, Vt, Ft, threads=-1)


def test_cli_map_says_how_landmarks_were_held(tmp_path, cli):
    # A far genus-1 landmark pair (a quarter turn: the plain pins fold): the report and the
    # summary line say it was held by the barrier continuation, with its steps.
    (Vs, Fs), (Vt, Ft) = torus(1.0, 0.45, 64, 34), torus(1.4, 0.5, 64, 34, 2)
    free = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=[(0, 0)])
    s = 34 * 20 + 5
    t = nearest_vertex(Vt, free["forward"]["position"][s])
    t = 34 * ((t // 34 + 16) % 64) + t % 34
    src, dst, lm = tmp_path / "a.obj", tmp_path / "b.obj", tmp_path / "lm.txt"
    surfmap.write_obj(str(src), Vs, Fs)
    surfmap.write_obj(str(dst), Vt, Ft)
    lm.write_text(f"0 0\n{s} {t}\n")
    out, rep = tmp_path / "morph.obj", tmp_path / "report.json"
    r = cli("map", src, dst, "--out", out, "--report", rep, "--landmarks", lm)
    assert r.returncode == 0, r.stderr
    report = json.loads(rep.read_text())
    assert report["landmark_method"] == "barrier continuation" and report["landmark_steps"] > 0
    assert report["landmark_solves"] == 1 + report["landmark_steps"] and report["flipped_triangles"] == 0
    assert (f"2 landmark(s) held by barrier continuation ({report['landmark_steps']} continuation steps)"
            in r.stderr), r.stderr


def test_genus1_landmarks_rank_both_signs_by_default():
    # Two landmarks on a torus pair (HomotopyOptions::flat_both_signs, default on): every
    # class M is listed with -M; the held map is no worse than with the canonical signs
    # alone (homotopy_both_signs=False), holds both pairs exactly and has no flips.
    (Vs, Fs), (Vt, Ft) = torus(1.0, 0.45, 48, 24), torus(1.4, 0.5, 48, 24, 2)
    pairs = [(0, 0), (24 * 20 + 5, 24 * 30 + 17)]
    one = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=pairs, homotopy_both_signs=False)
    both = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=pairs)
    signed = lambda r: {tuple(c["matrix"]) for c in r["homotopy"]["candidates"]}
    assert signed(both) == signed(one) | {tuple(-k for k in m) for m in signed(one)}
    assert len(signed(both)) == 2 * len(signed(one))
    assert both["energy"]["final"] <= one["energy"]["final"] * (1 + 1e-9)
    assert both["flipped_triangles"] == 0 and both["landmark_error"] < 1e-9
    for s, t in pairs:
        assert np.linalg.norm(both["forward"]["position"][s] - Vt[t]) < 1e-12
    # Without landmarks the list stays up to the sign (M and -M: the same energy).
    free = surfmap.surface_map(Vs, Fs, Vt, Ft)
    assert signed(free) == signed(one)


def test_cli_homotopy_both_signs_mirrors_python(tmp_path, cli):
    # --homotopy-both-signs (the default) / --no-homotopy-both-signs are Python's
    # homotopy_both_signs=True / False: the report lists each flat class M with -M, or the
    # canonical signs alone, and the two lists differ exactly by the sign.
    (Vs, Fs), (Vt, Ft) = torus(1.0, 0.45, 24, 12), torus(1.4, 0.5, 24, 12, 2)
    src, dst, lm = tmp_path / "a.obj", tmp_path / "b.obj", tmp_path / "pairs.txt"
    surfmap.write_obj(str(src), Vs, Fs)
    surfmap.write_obj(str(dst), Vt, Ft)
    pairs = [(0, 0), (12 * 10 + 3, 12 * 15 + 8)]
    lm.write_text("".join(f"{s} {t}\n" for s, t in pairs))
    signed = {}
    for flag in ("", "--homotopy-both-signs", "--no-homotopy-both-signs"):
        rep = tmp_path / f"report{len(signed)}.json"
        r = cli("map", src, dst, "--out", tmp_path / "m.obj", "--report", rep, "--quiet", "--landmarks", lm,
                *([flag] if flag else []))
        assert r.returncode == 0, r.stderr
        report = json.loads(rep.read_text())
        signed[flag] = {tuple(c["matrix"]) for c in report["homotopy"]["candidates"]}
        assert report["flipped_triangles"] == 0
    one = signed["--no-homotopy-both-signs"]
    assert signed[""] == signed["--homotopy-both-signs"]
    assert signed[""] == one | {tuple(-k for k in m) for m in one} and len(signed[""]) == 2 * len(one)
    py = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=pairs, homotopy_both_signs=False)
    assert {tuple(c["matrix"]) for c in py["homotopy"]["candidates"]} == one


def test_cli_target_metric_has_the_python_spelling(tmp_path, cli):
    # One spelling: --target-metric takes the names of target_metric=, the report repeats it,
    # and anything else is refused with the list.
    Vs, Fs = torus(1.0, 0.5, 24, 12)
    Vt, Ft = torus(1.5, 0.5, 20, 10, 1)
    src, dst = tmp_path / "a.obj", tmp_path / "b.obj"
    surfmap.write_obj(str(src), Vs, Fs)
    surfmap.write_obj(str(dst), Vt, Ft)
    rep = tmp_path / "report.json"
    r = cli("map", src, dst, "--out", tmp_path / "m.obj", "--report", rep, "--quiet",
            "--target-metric", "fixed-first")
    assert r.returncode == 0, r.stderr
    report = json.loads(rep.read_text())
    assert report["target_metric_requested"] == "fixed-first"
    assert report["target_metric_choice"] == "fixed first: the fixed-connectivity metric"
    bad = cli("map", src, dst, "--out", tmp_path / "n.obj", "--target-metric", "fixed_first")
    assert bad.returncode != 0 and "fixed-first" in bad.stderr + bad.stdout


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


# Genus 0: through the unit sphere (map/spherical_map.h).

def blob(subdivisions):
    """An asymmetric genus-0 shape: a scaled, bulged icosphere."""
    V, F = surfmap.shapes.sphere(subdivisions)
    V = V / np.linalg.norm(V, axis=1, keepdims=True)
    bulge = 1.0 + 0.25 * V[:, 0] + 0.1 * V[:, 1] * V[:, 2]
    return V * np.array([1.6, 1.0, 0.7]) * bulge[:, None], F


def test_genus0_conformal_copy_and_landmarks():
    Vs, Fs = blob(3)
    Vt, Ft = surfmap.shapes.sphere_inversion(Vs, Fs, np.array([3.0, 0.5, -0.4]), 2.5)
    r = surfmap.surface_map(Vs, Fs, Vt, Ft)
    assert r["genus"] == 0 and r["converged"] and r["flipped_triangles"] == 0
    assert surfmap.verify(Vs, Fs, Vt, Ft, r)["certified"]
    # Conformally equivalent copies: D' close to 1 (first-order discretisation error at 642 vertices).
    assert 1.0 <= r["distortion"]["mean"] < 1.08
    fwd = r["forward"]
    recon = np.einsum("ik,ikj->ij", fwd["barycentric"], Vt[Ft[fwd["face"]]])
    assert np.abs(recon - fwd["position"]).max() < 1e-9
    assert r["inverse"]["face"].shape == (len(Vt),)
    # Three landmarks are hit exactly; more are fitted in least squares and the residual is reported.
    pairs = np.array([[0, 40], [111, 300], [500, 20]])
    r3 = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=pairs)
    assert r3["flipped_triangles"] == 0
    assert surfmap.verify(Vs, Fs, Vt, Ft, r3)["certified"]
    assert np.abs(r3["forward"]["position"][pairs[:, 0]] - Vt[pairs[:, 1]]).max() < 1e-9
    assert r3["landmark_error"] < 1e-9
    # Four landmarks that agree with the free map (each source vertex to the target vertex nearest its image).
    src = np.array([0, 111, 500, 250])
    dst = np.array([np.linalg.norm(Vt - fwd["position"][i], axis=1).argmin() for i in src])
    r4 = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=np.stack([src, dst], 1))
    worst = np.linalg.norm(r4["forward"]["position"][src] - Vt[dst], axis=1).max()
    assert r4["flipped_triangles"] == 0
    assert surfmap.verify(Vs, Fs, Vt, Ft, r4)["certified"]
    # The least-squares fit does about as well as the free map already did on these pairs.
    free_error = np.linalg.norm(fwd["position"][src] - Vt[dst], axis=1).max()
    assert r4["landmark_error"] == pytest.approx(worst) and 0 < worst < 1.5 * free_error
    with pytest.raises(surfmap.InputError, match="out of range"):
        surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=[[0, len(Vt)]])


def test_genus0_cli(tmp_path, cli):
    Vs, Fs = blob(2)
    Vt, Ft = surfmap.shapes.jitter(Vs * 2.0 + 1.0, Fs, 0.2, 4)
    src, dst = tmp_path / "a.obj", tmp_path / "b.obj"
    surfmap.write_obj(str(src), Vs, Fs)
    surfmap.write_obj(str(dst), Vt, Ft)
    lm = tmp_path / "pairs.txt"
    lm.write_text("0 0\n10 10\n")
    out, rep = tmp_path / "morph.obj", tmp_path / "report.json"
    r = cli("map", src, dst, "--out", out, "--report", rep, "--landmarks", lm, "--quiet")
    assert r.returncode == 0, r.stderr
    report = json.loads(rep.read_text())
    assert report["genus"] == 0 and report["flipped_triangles"] == 0 and report["landmark_error"] < 1e-9
    morph = surfmap.load_mesh(str(out))["V"]
    # A jittered copy of the same shape: the map is close to the identity.
    assert np.abs(morph - (Vs * 2.0 + 1.0)).max() < 0.05 * np.ptp(Vt, axis=0).max()


def test_landmarks_genus1_hit_exactly(pair):
    (Vs, Fs), (Vt, Ft) = pair
    free = surfmap.surface_map(Vs, Fs, Vt, Ft)
    # Landmarks where the free map (nearly) sends them: held exactly, no flips, no lower energy.
    src = np.array([5, 2000, 5000])
    dst = np.array([np.linalg.norm(Vt - free["forward"]["position"][i], axis=1).argmin() for i in src])
    r = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=np.stack([src, dst], 1))
    assert r["flipped_triangles"] == 0 and r["landmark_error"] < 1e-9
    assert surfmap.verify(Vs, Fs, Vt, Ft, r)["certified"]
    assert np.abs(r["forward"]["position"][src] - Vt[dst]).max() < 1e-9
    assert r["energy"]["final"] >= free["energy"]["final"] * (1 - 1e-12)
    with pytest.raises(surfmap.InputError, match="already landmark"):
        surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=[[1, 2], [1, 3]])


def test_genus2_candidates_are_described_and_the_overlay_class_wins():
    a = surfmap.shapes.n_hole_torus(2, 30, True)
    b = surfmap.shapes.jitter(*surfmap.shapes.n_hole_torus(2, 34, True), 0.2, 4)
    r = surfmap.surface_map(*a, *b)
    cands = r["homotopy"]["candidates"]
    assert len(cands) >= 8
    for c in cands:
        assert set(c) >= {"description", "energy", "solved"}
        assert "handle 1 -> handle" in c["description"] or "mixes handles" in c["description"]
    chosen = cands[r["homotopy"]["chosen"]]
    assert chosen["solved"] and "as the shapes overlap" in chosen["description"]
    assert r["distortion"]["mean"] < 1.08


def test_genus2_quality_signal_and_class_bounds_are_in_the_result():
    # Issue 14: the energy over 8 pi (g - 1), a warning only when far above
    # it, and what the two-way run did (not run: a copy is nearly conformal).
    a = surfmap.shapes.n_hole_torus(2, 30, True)
    b = surfmap.shapes.jitter(*surfmap.shapes.n_hole_torus(2, 34, True), 0.2, 4)
    r = surfmap.surface_map(*a, *b)
    q = r["quality"]
    assert set(q) >= {"energy_ratio", "warning", "reverse_candidates", "reverse_status", "reverse_check",
                      "two_way_status", "two_way_time_s"}
    chosen = r["homotopy"]["candidates"][r["homotopy"]["chosen"]]
    assert abs(q["energy_ratio"] - chosen["energy"] / (8 * np.pi)) < 1e-12
    assert 1.0 <= q["energy_ratio"] < 1.1 and q["warning"] == ""
    assert q["two_way_status"].startswith("not run")
    # No base vertex given: the class is chosen in the cuts it is written in.
    assert q["class_cuts_status"] == "" and q["class_cuts_time_s"] == 0
    # Per-candidate lower bounds (no solve): a copy's ranking stops at the
    # overlay class (within 2% of 8 pi (g - 1)), where no bound can change
    # the choice, so the source is not uniformized for them (issue 19) and
    # the status says why; where they are computed they never exceed the
    # solved energies (test_class_lower_bound.cpp NeverAboveTheSolvedEnergies).
    assert r["homotopy"]["ranking"]["status"].startswith("stopped")
    assert q["class_bound_status"].startswith("not computed: no decision needed them")
    for c in r["homotopy"]["candidates"]:
        assert c["class_lower_bound"] is None or np.isnan(c["class_lower_bound"])


def test_two_way_keyword_and_the_directions_comparison_are_in_the_result():
    # Issue 14: `two_way` (options.homotopy.two_way) turns the other direction
    # off; the result says whether the two directions' classes were compared.
    a = surfmap.shapes.n_hole_torus(2, 30, True)
    b = surfmap.shapes.jitter(*surfmap.shapes.n_hole_torus(2, 34, True), 0.2, 4)
    assert "two_way" in surfmap._core.CAPABILITIES
    on = surfmap.surface_map(*a, *b)
    off = surfmap.surface_map(*a, *b, two_way=False)
    assert off["quality"]["two_way_status"] == "not run (off)"
    assert on["quality"]["two_way_status"].startswith("not run: energy ratio below")
    for r in (on, off):
        assert r["quality"]["reverse_inverse"] == -1
    assert on["quality"]["reverse_inverse_reason"].startswith("not compared")
    # The algebraic comparison (quality.directions): not run below the ratio,
    # but the chosen class's words (2g) and the source's letters as a target
    # are reported for callers that compose two directions themselves.
    d = on["quality"]["directions"]
    assert d["outcome"] == "" and d["reason"].startswith("not compared")
    assert len(d["chosen_class_words"]) == 4 and len(d["source_as_target"]) == 4, d["source_as_target_status"]
    assert abs(on["energy"]["final"] - off["energy"]["final"]) < 1e-9 * on["energy"]["final"]
    s = on["homotopy"]["search"]
    assert set(s) >= {"geometric_classes", "coarse_solves", "starts", "source_marking", "target_marking",
                      "source_geodesics", "target_geodesics", "source_greedy_pants", "target_greedy_pants",
                      "greedy_pants_time_s"}
    # Below the ratio the geometric stage (and with it the greedy pants) does not run.
    assert s["source_greedy_pants"] == "" and s["greedy_pants_time_s"] == 0


def test_genus2_class_search_is_reported_and_skipped_near_the_conformal_bound():
    a = surfmap.shapes.n_hole_torus(2, 30, True)
    b = surfmap.shapes.jitter(*surfmap.shapes.n_hole_torus(2, 34, True), 0.2, 4)
    r = surfmap.surface_map(*a, *b)
    s = r["homotopy"]["search"]
    assert set(s) >= {"run", "moves", "energies", "evaluations", "evaluated", "stop_reason", "time_s", "found_candidate"}
    # A jittered copy's identity class is nearly conformal: E within 10% of
    # 8 pi (g - 1), so there is nothing for the search to find.
    assert r["energy"]["final"] < 1.1 * 8 * np.pi
    assert not s["run"] and "conformal bound" in s["stop_reason"] and s["evaluations"] == 0
    off = surfmap.surface_map(*a, *b, homotopy_search=False)
    assert not off["homotopy"]["search"]["run"] and off["homotopy"]["search"]["stop_reason"] == ""
    assert abs(off["energy"]["final"] - r["energy"]["final"]) < 1e-9 * r["energy"]["final"]
    with pytest.raises(surfmap.InputError, match="homotopy_search_evaluations"):
        surfmap.surface_map(*a, *b, homotopy_search_evaluations=0)


def test_genus2_solve_progress_reports_energies_and_cancels():
    a = surfmap.shapes.n_hole_torus(2, 24, True)
    b = surfmap.shapes.vase(28, True)
    seen = []
    r = surfmap.surface_map(*a, *b, homotopy=0,
                            solve_progress=lambda it, e, g: seen.append((it, e, g)) or True)
    assert seen, "solve_progress was never called"
    energies = [e for _, e, _ in seen]
    # Newton decreases the energy at every accepted step and ends at the reported optimum.
    assert all(e2 <= e1 * (1 + 1e-12) for e1, e2 in zip(energies, energies[1:]))
    assert abs(energies[-1] - r["energy"]["final"]) <= 1e-9 * r["energy"]["final"]
    with pytest.raises(surfmap.Cancelled):
        surfmap.surface_map(*a, *b, homotopy=0, solve_progress=lambda it, e, g: it < 1)
    with pytest.raises(ZeroDivisionError):
        surfmap.surface_map(*a, *b, homotopy=0, solve_progress=lambda it, e, g: 1 / 0)


def test_polygon_flattening_with_a_fold_is_repaired_locally():
    # Raw marching-tets source: the flattening folds one face where the
    # loops cross; the rings around it are re-solved (the rest held) instead
    # of the whole uniform-weight map, and the repaired map has no folds.
    a = surfmap.shapes.n_hole_torus(2, 30, False)
    b = surfmap.shapes.vase(30, True)
    r = surfmap.surface_map(*a, *b, initial_map="polygon")
    im = r["initial_map"]
    assert im["construction"] == "polygon" and im["polygon"]["status"] == "used"
    assert im["cut_graph"]["status"] == "not tried"
    assert im["polygon"]["flipped"] > 0 and 0 < im["polygon"]["repaired_vertices"] < len(a[0]) // 4
    assert im["iterations"] == 0
    assert r["initial_flipped_triangles"] == 0
    assert r["flipped_triangles"] == 0
    assert surfmap.verify(*a, *b, r)["certified"]


def test_genus2_initial_map_construction_and_location(tmp_path, cli):
    a = surfmap.shapes.n_hole_torus(2, 32, True)
    b = surfmap.shapes.n_hole_torus(2, 40, True)
    r = surfmap.surface_map(*a, *b, homotopy=0, locate_initial_map=True)
    im = r["initial_map"]
    assert im["located"] and im["location_requested"]
    # The default: the source cut along its own cut graph onto a convex polygon.
    assert im["construction"] == "cut-graph polygon" and im["cut_graph"]["status"] == "used"
    assert im["cut_graph"]["min_turn"] > 0 and im["cut_graph"]["flipped"] == 0 and im["iterations"] == 0
    assert im["polygon"]["status"] == "not tried"
    assert r["initial_flipped_triangles"] == 0
    p = surfmap.surface_map(*a, *b, homotopy=0, initial_map="polygon")
    assert p["initial_map"]["construction"] == "polygon" and p["initial_map"]["polygon"]["convex"]
    # Not requested (the default): no location, said so; the same map.
    assert p["initial_forward"] is None and p["initial_inverse"] is None
    assert not p["initial_map"]["located"] and not p["initial_map"]["location_requested"]
    init = r["initial_forward"]
    Vt, Ft = b
    assert init["position"].shape == a[0].shape
    # Located initial points lie on the target's faces.
    q = np.einsum("ik,ikj->ij", init["barycentric"], Vt[Ft[init["face"]]])
    assert np.abs(q - init["position"]).max() < 1e-9 and init["barycentric"].min() >= -1e-9
    u = surfmap.surface_map(*a, *b, homotopy=0, initial_map="uniform")
    assert u["initial_map"]["construction"] == "uniform harmonic" and u["initial_map"]["iterations"] > 0
    # One optimum from either start (docs/method.md §3).
    assert abs(u["energy"]["final"] - r["energy"]["final"]) <= 1e-8 * r["energy"]["final"]
    diag = np.linalg.norm(Vt.max(0) - Vt.min(0))
    assert np.abs(u["forward"]["position"] - r["forward"]["position"]).max() < 1e-3 * diag
    with pytest.raises(surfmap.InputError):
        surfmap.surface_map(*a, *b, homotopy=0, initial_map="canonical")
    # CLI: the report says which construction, --initial-out writes the "before" morph.
    src, dst = tmp_path / "a.obj", tmp_path / "b.obj"
    surfmap.write_obj(str(src), *a)
    surfmap.write_obj(str(dst), *b)
    out, rep, ini = tmp_path / "m.obj", tmp_path / "r.json", tmp_path / "i.obj"
    p = cli("map", src, dst, "--out", out, "--report", rep, "--initial-out", ini, "--homotopy", "0", "--quiet")
    assert p.returncode == 0, p.stderr
    report = json.loads(rep.read_text())
    assert report["initial_map"]["construction"] == "cut-graph polygon" and report["initial_map"]["located"]
    assert report["initial_map"]["location_requested"]  # (implied by --initial-out)
    assert report["initial_map"]["cut_graph"]["status"] == "used"
    before = surfmap.load_mesh(str(ini))
    assert np.abs(before["V"] - init["position"]).max() < 1e-6


@pytest.mark.parametrize("genus", [1, 2])
def test_initial_inverse_inverts_the_initial_map(genus):
    # 'initial_inverse' (the "before" UV transfer): each target vertex located on the source
    # through the initial map. Pushing it forward again with the initial map's own images
    # of that source face lands on the target vertex, up to the chord of the image triangle.
    if genus == 1:
        a, b = torus(1.0, 0.5, 40, 20), torus(1.5, 0.5, 50, 20, 1)
    else:
        a, b = surfmap.shapes.n_hole_torus(2, 18, True), surfmap.shapes.vase(22, True)
    (Vs, Fs), (Vt, Ft) = a, b
    r = surfmap.surface_map(Vs, Fs, Vt, Ft, locate_initial_map=True)
    fw, iv = r["initial_forward"], r["initial_inverse"]
    assert fw is not None and iv is not None and r["initial_flipped_triangles"] == 0
    assert iv["face"].shape == (len(Vt),) and iv["barycentric"].min() >= -1e-9
    assert np.allclose(iv["barycentric"].sum(1), 1)
    q = np.einsum("ik,ikj->ij", iv["barycentric"], Vs[Fs[iv["face"]]])
    assert np.abs(q - iv["position"]).max() < 1e-9
    img = fw["position"]
    back = np.einsum("ik,ikj->ij", iv["barycentric"], img[Fs[iv["face"]]])
    edge = max(np.linalg.norm(img[Fs[:, k]] - img[Fs[:, (k + 1) % 3]], axis=1).max() for k in range(3))
    err = np.linalg.norm(back - Vt, axis=1)
    assert err.max() < 0.5 * edge, (err.max(), edge)
    # ... and it is the initial map's inverse, not the optimum's.
    fin = r["inverse"]["position"]
    assert np.abs(fin - iv["position"]).max() > 1e-3 * np.linalg.norm(Vs.max(0) - Vs.min(0))


def test_source_weights_kwarg():
    a = surfmap.shapes.n_hole_torus(2, 14, True)
    b = surfmap.shapes.vase(18, True)
    auto = surfmap.surface_map(*a, *b)
    own = surfmap.surface_map(*a, *b, source_weights="own")
    intrinsic = surfmap.surface_map(*a, *b, source_weights="intrinsic")
    assert auto["source_weights"] == intrinsic["source_weights"] != own["source_weights"]
    assert own["flipped_triangles"] == 0
    assert surfmap.verify(*a, *b, own)["certified"]
    assert abs(auto["energy"]["final"] - intrinsic["energy"]["final"]) <= 1e-9 * auto["energy"]["final"]
    assert abs(own["energy"]["final"] - auto["energy"]["final"]) > 1e-6 * auto["energy"]["final"]
    with pytest.raises(surfmap.InputError, match="source_weights"):
        surfmap.surface_map(*a, *b, source_weights="uniform")


def _with_caps(V, F, stride, eps):
    """Every `stride`-th face (a, b, c) split at a point just above the midpoint of ab (`eps` of
    the way to c): CAD-like caps, an angle near 180 degrees, which fold the intrinsic map (the
    fixture of native/tests/sliver_caps.h)."""
    V = [np.asarray(v, dtype=float) for v in np.asarray(V, dtype=float)]
    out = []
    for f, t in enumerate(np.asarray(F)):
        if f % stride:
            out.append(t)
            continue
        mid = 0.5 * (V[t[0]] + V[t[1]])
        p = len(V)
        V.append(mid + eps * (V[t[2]] - mid))
        out += [(t[0], t[1], p), (t[1], t[2], p), (t[2], t[0], p)]
    return np.array(V), np.array(out, dtype=np.int32)


def _signature_defaults(fn):
    """{keyword: default} from a pybind11 signature line ('name: type = value, ...')."""
    line = fn.__doc__.splitlines()[0]
    return {m.group(1): m.group(2) for m in re.finditer(r"(\w+): [\w.]+ = ([^,)]+)", line)}


def test_default_map_is_the_same_on_every_path(tmp_path, cli):
    # Issue 14 (docs/handle_classes.md "Quality signal"): a reviewer's figures for a pair must
    # not depend on the path taken. With no options, the CLI, the Python module, the many-shape
    # tools' call and the add-on's default panel settings must run the same options and report
    # the same class, ratio and D'. The source has caps that fold the intrinsic map, so the
    # automatic weights and the local fold repair (whose defaults decide the figures: own-edge
    # weights give another energy and another D') are exercised.
    a = _with_caps(*surfmap.shapes.n_hole_torus(2, 24, True), 37, 0.002)
    b = surfmap.shapes.amphora(30, True)
    src, dst, rep = tmp_path / "a.obj", tmp_path / "b.obj", tmp_path / "r.json"
    surfmap.write_obj(str(src), *a)
    surfmap.write_obj(str(dst), *b)
    a, b = [(m["V"], m["F"]) for m in (surfmap.load_mesh(str(src)), surfmap.load_mesh(str(dst)))]
    r = surfmap.surface_map(*a, *b)
    assert r["converged"] and r["flipped_triangles"] == 0
    assert r["fold_repair"]["status"] == "repaired", r["fold_repair"]
    assert r["source_weights"].startswith("intrinsic Delaunay cotangent; "), r["source_weights"]
    p = cli("map", src, dst, "--out", tmp_path / "m.obj", "--report", rep, "--quiet")
    assert p.returncode == 0, p.stderr
    _same_report(r, json.loads(rep.read_text()))   # every key and value, the class words too
    # The many-shape tools (surfmap.compare, surfmap.batch, the add-on's batch operators) call
    # through mapcall.run_map, and their summary carries the same quality signal.
    from surfmap import mapcall
    summary = mapcall.map_report(r)
    assert summary["quality"]["energy_ratio"] == r["quality"]["energy_ratio"]
    assert summary["distortion"]["mean"] == r["distortion"]["mean"]
    assert summary["source_weights"] == r["source_weights"]
    # The add-on's default panel settings pass nothing that differs from the core's defaults.
    import pathlib
    import sys
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "addon"))
    from surface_map import map_job
    defaults = _signature_defaults(surfmap.surface_map)
    assert {"two_way", "local_fold_repair", "source_weights", "two_way_ratio"} <= set(defaults), defaults
    for key, value in map_job.MapOptions().native_kwargs().items():
        assert repr(value) == defaults[key], (key, value, defaults[key])
    # What the figures are: the ratio names its energy, D' its measure; with own-edge weights
    # (2.29 against 1.55 on g3_block -> g3_3holes) the report says the ratio is not comparable.
    q = r["quality"]
    assert q["energy_ratio_basis"].startswith("the chosen class's free optimum") and \
        "intrinsic Delaunay" in q["energy_ratio_basis"] and "fold repair" in q["energy_ratio_basis"]
    assert "hyperbolic uniformization metric" in r["distortion"]["measure"]
    assert "3D areas" in r["distortion"]["measure"]
    # Thin source faces (the ones mollification reshapes) are left out of the summary, listed.
    assert "left out" in r["distortion"]["measure"]
    counted = np.isfinite(r["distortion"]["per_face"])
    counted[np.asarray(r["distortion"]["left_out_face_ids"], dtype=int)] = False
    assert len(r["distortion"]["left_out_face_ids"]) == r["distortion"]["left_out_faces"]
    assert r["distortion"]["unweighted_mean"] == pytest.approx(r["distortion"]["per_face"][counted].mean())
    own = surfmap.surface_map(*a, *b, source_weights="own", two_way=False)
    assert own["source_weights"].startswith("positive on the source's own edges")
    assert "NOT comparable" in own["quality"]["energy_ratio_basis"]
    assert own["quality"]["energy_ratio"] > q["energy_ratio"]   # the same pair, another energy


def test_genus2_barrier_continuation_reports_progress_and_cancels():
    # A far genus-2 landmark (its plain pin folds): the continuation's Newton iterations are
    # reported through solve_progress after the free and the pinned solves (a third run of
    # iteration counts), and a False from the callback there cancels the map.
    from mesh_helpers import adjacency, nearest_vertex, shortest_path
    a = surfmap.shapes.n_hole_torus(2, 14, True)
    b = surfmap.shapes.vase(18, True)
    free = surfmap.surface_map(*a, *b)
    s = len(a[0]) // 3
    t0 = nearest_vertex(b[0], free["forward"]["position"][s])
    far = int(np.argmax(((b[0] - b[0][t0]) ** 2).sum(1)))
    t = shortest_path(adjacency(b[1], len(b[0])), t0, far)[6]
    kw = dict(class_words=free["homotopy"]["chosen_words"])   # (by its name, not another run's index)

    def runs(lm):
        calls = []
        r = surfmap.surface_map(*a, *b, landmarks=lm, solve_progress=lambda i, e, g: calls.append(i) or True, **kw)
        starts = [k for k in range(len(calls)) if k == 0 or calls[k] < calls[k - 1]]
        return r, starts

    near, near_starts = runs([(s, t0)])
    r, starts = runs([(s, t)])
    assert near["landmark_method"] == "pinned" and r["landmark_method"] == "barrier continuation"
    assert len(starts) == len(near_starts) + 1
    seen = []

    def stop_in_the_continuation(i, e, g):
        seen.append(i)
        return len(seen) <= starts[-1]

    with pytest.raises(surfmap.Cancelled):
        surfmap.surface_map(*a, *b, landmarks=[(s, t)], solve_progress=stop_in_the_continuation, **kw)
    assert len(seen) == starts[-1] + 1


def test_genus2_classes_are_ranked_with_the_landmarks_held():
    # With landmarks, the classes solved at full resolution are ranked by their energy with
    # the landmarks held the way the returned map holds them (plain pins, else the barrier
    # continuation, else carried rings; inf where they cannot be held bijectively), by branch
    # and bound: the plain pins' energy is a lower bound, and a class whose bound is not below
    # the best held energy is not held (NaN). The chosen class is the lowest, its final energy
    # exactly that held energy.
    a = surfmap.shapes.n_hole_torus(2, 14, True)
    b = surfmap.shapes.vase(18, True)
    Vb, n = b[0], len(a[0])
    other = surfmap.surface_map(*a, *b, homotopy=0)      # a near-symmetric class of the best
    lm = [(s, nearest_vertex(Vb, other["forward"]["position"][s])) for s in range(0, n, n // 6)]
    r = surfmap.surface_map(*a, *b, landmarks=lm, homotopy_full_solves=8)
    cands = r["homotopy"]["candidates"]
    solved = [i for i, c in enumerate(cands) if c["solved"] and math.isfinite(c["energy"])]
    assert len(solved) >= 2
    assert all(math.isfinite(cands[i]["landmark_lower_bound"]) for i in solved)
    assert all(math.isnan(c["landmark_lower_bound"]) and math.isnan(c["landmark_energy"])
               for i, c in enumerate(cands) if i not in solved)
    for i in solved:    # bound <= held; the free optimum is below both
        c = cands[i]
        assert c["landmark_lower_bound"] >= c["energy"] * (1 - 1e-9)
        assert math.isnan(c["landmark_energy"]) or c["landmark_energy"] >= c["landmark_lower_bound"] * (1 - 1e-9)
    held = {i: cands[i]["landmark_energy"] for i in solved if math.isfinite(cands[i]["landmark_energy"])}
    chosen = r["homotopy"]["chosen"]
    assert chosen == min(held, key=held.get)
    # Pruned classes could not have won.
    assert all(cands[i]["landmark_lower_bound"] >= held[chosen] for i in solved if math.isnan(cands[i]["landmark_energy"]))
    assert r["flipped_triangles"] == 0 and r["landmark_method"] in ("pinned", "barrier continuation")
    assert surfmap.verify(*a, *b, r)["certified"]
    assert r["landmark_solves"] == 1 + r["landmark_steps"] and r["landmark_rings"] == [0] * len(lm)
    assert abs(r["energy"]["final"] - held[chosen]) <= 1e-8 * held[chosen]
    # Genus 1 ranks the same way (every class has a bound: the plain pins of its optimum).
    (Vs, Fs), (Vt, Ft) = torus(1.0, 0.5, 30, 15), torus(1.5, 0.5, 36, 15, 1)
    g1 = surfmap.surface_map(Vs, Fs, Vt, Ft, landmarks=[(0, 0), (200, 300)])
    c1 = g1["homotopy"]["candidates"]
    assert all(c["landmark_lower_bound"] >= c["energy"] * (1 - 1e-12) for c in c1)
    held1 = {i: c["landmark_energy"] for i, c in enumerate(c1) if math.isfinite(c["landmark_energy"])}
    k1 = g1["homotopy"]["chosen"]
    assert k1 == min(held1, key=held1.get) and g1["energy"]["final"] == held1[k1]
    assert all(c["landmark_lower_bound"] >= held1[k1] for i, c in enumerate(c1) if math.isnan(c["landmark_energy"]))


# Keys only one side has: the arrays (Python: numpy) and the intake's flips; the file names and
# intake notes (CLI). Everything else comes from one serializer (map/map_report.h).
_PYTHON_ONLY = {"forward", "inverse", "initial_forward", "initial_inverse", "source_flipped", "target_flipped",
                "per_face"}
_CLI_ONLY = {"source", "target", "notes"}


def _same_report(py, js, path="result"):
    """Asserts the Python result `py` and the CLI's JSON report `js` agree key by key (times excepted;
    the JSON writes nan and inf as null)."""
    if isinstance(js, dict):
        assert isinstance(py, dict), path
        keys_py = {k for k in py if k not in _PYTHON_ONLY}
        keys_js = {k for k in js if k not in _CLI_ONLY}
        assert keys_py == keys_js, (path, keys_py ^ keys_js)
        for k in keys_js:
            # (the stage table is measurements too: seconds, peak memory, and counts
            # that depend on which stage the second thread's work fell into)
            if k not in ("time_s", "stages") and not k.endswith("_time_s"):
                _same_report(py[k], js[k], f"{path}[{k!r}]")
    elif isinstance(js, list):
        assert isinstance(py, list) and len(py) == len(js), path
        for i, (p, j) in enumerate(zip(py, js)):
            _same_report(p, j, f"{path}[{i}]")
    elif js is None:
        assert isinstance(py, float) and not math.isfinite(py), (path, py)
    elif isinstance(js, (bool, str)):
        assert py == js and type(py) is type(js), (path, py, js)
    else:
        assert isinstance(py, (int, float)) and not isinstance(py, bool), (path, py)
        assert abs(py - js) <= 1e-9 * max(1.0, abs(js)), (path, py, js)


@pytest.mark.parametrize("genus", [1, 2])
def test_python_result_and_cli_report_carry_the_same_keys_and_values(tmp_path, cli, genus):
    if genus == 1:
        a, b = torus(1.0, 0.5, 30, 15), torus(1.5, 0.5, 36, 15, 1)
        landmarks, kwargs, flags = [(0, 0)], {"initial_map": "uniform"}, ["--initial-map", "uniform"]
    else:
        a, b = surfmap.shapes.n_hole_torus(2, 14, True), surfmap.shapes.vase(18, True)
        landmarks, kwargs, flags = None, {"method": "newton", "source_weights": "intrinsic"}, [
            "--method", "newton", "--source-weights", "intrinsic"]
    src, dst, rep = tmp_path / "a.obj", tmp_path / "b.obj", tmp_path / "r.json"
    surfmap.write_obj(str(src), *a)
    surfmap.write_obj(str(dst), *b)
    # Both sides map the meshes as read back (the OBJ rounds the coordinates).
    a, b = [(m["V"], m["F"]) for m in (surfmap.load_mesh(str(src)), surfmap.load_mesh(str(dst)))]
    r = surfmap.surface_map(*a, *b, landmarks=landmarks, **kwargs)
    if landmarks:
        (tmp_path / "l.txt").write_text("0 0\n")
        flags += ["--landmarks", tmp_path / "l.txt"]
    p = cli("map", src, dst, "--out", tmp_path / "m.obj", "--report", rep, "--quiet", *flags)
    assert p.returncode == 0, p.stderr
    report = json.loads(rep.read_text())
    _same_report(r, report)
    assert report["method"] == r["method"] == "newton" and r["landmarks"] == len(landmarks or [])
    assert len(r["homotopy"]["candidates"]) > 1 and r["homotopy"]["candidates"][1]["index"] == 1
    assert r["distortion"]["per_face"].shape == (len(a[1]),)
    if genus == 1:
        assert r["landmark_method"] != "" and r["landmark_error"] < 1e-6
    # One spelling per enum: the CLI refuses the other one, Python names the allowed ones.
    bad = cli("map", src, dst, "--out", tmp_path / "m.obj", "--report", rep, "--initial-map", "cut-graph")
    assert bad.returncode != 0 and "cut_graph" in bad.stderr + bad.stdout
    with pytest.raises(surfmap.InputError, match="'cut_graph', 'polygon' or 'uniform', not 'cut-graph'"):
        surfmap.surface_map(*a, *b, initial_map="cut-graph")


def test_flat_map_of_a_turned_remeshed_torus_is_placed_by_the_overlay(tmp_path, cli):
    # Genus 1 (docs/handle_classes.md "Genus 1: placement by the overlay"): a torus of
    # revolution onto a remeshing of itself turned 0.7 rad about its axis (the same surface).
    # The flat map is unique only up to the torus's translations; the 3D overlay places it so
    # that every vertex lands next to itself (before: by the base vertices, half the diagonal
    # off). flat_overlay=False (CLI --no-flat-overlay) keeps the base vertex rule.
    Vs, Fs = torus(1.2, 0.4, 60, 24)
    Vt, Ft = torus(1.2, 0.4, 50, 28, 1)
    c, s = math.cos(0.7), math.sin(0.7)
    Vt = Vt @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T
    diagonal = np.linalg.norm(Vs.max(0) - Vs.min(0))
    r = surfmap.surface_map(Vs, Fs, Vt, Ft)
    assert r["converged"] and r["flipped_triangles"] == 0
    assert r["flat_placement"].startswith("3D overlay (as posed)")
    d = np.linalg.norm(np.asarray(r["forward"]["position"]) - Vs, axis=1) / diagonal
    assert d.mean() < 0.005 and d.max() < 0.02
    off = surfmap.surface_map(Vs, Fs, Vt, Ft, flat_overlay=False)
    assert off["flat_placement"].startswith("base vertex")
    assert off["energy"]["final"] == pytest.approx(r["energy"]["final"], rel=1e-9)
    # The CLI: the same placement and the flag.
    for flag, start in (([], "3D overlay (as posed)"), (["--no-flat-overlay"], "base vertex")):
        p, report = cli_map(cli, tmp_path, *flag, pair=((Vs, Fs), (Vt, Ft)))
        assert p.returncode == 0, p.stderr
        assert report["flat_placement"].startswith(start)


def test_every_cli_map_option_has_a_python_keyword(cli):
    # The CLI's `map` flags and surface_map's keywords are one list of options: each flag
    # (--no-x: keyword x=False) names a keyword in CAPABILITIES, except the ones about files
    # and the console.
    help_text = cli("map", "--help").stdout
    # Each option line starts with its flags ("  --x,--no-x{false}", "  --x TEXT"); a flag
    # named inside a description ("as uniformize --loops") is not one of map's.
    flags = set()
    for line in help_text.splitlines():
        head = re.match(r"  (-\S+)", line)
        if head:
            flags |= set(re.findall(r"--([a-z][a-z-]*)", head.group(1)))
    assert {"no-cheap-direction-check", "compare-directions", "target-loops"} <= flags, flags
    not_options = {"help", "out", "report", "correspondence", "initial-out", "quiet", "timings"}
    # (--classical-canonical-generators: short_canonical_generators=False, the default said aloud;
    # --one-canonical-basis: both_canonical_bases=False)
    renamed = {"base_vertex": "source_base_vertex", "boundary_swap": "boundary_pairing",
               "classical_canonical_generators": "short_canonical_generators",
               "one_canonical_basis": "both_canonical_bases"}
    missing = set()
    for flag in flags - not_options:
        name = flag[3:] if flag.startswith("no-") else flag
        name = name.replace("-", "_")
        if renamed.get(name, name) not in surfmap.CAPABILITIES:
            missing.add(flag)
    assert not missing, missing


def test_a_class_is_asked_for_by_its_words_in_another_run(tmp_path, cli):
    # Issue 14, session 24: a class of one run named in another by its words (class_words=,
    # --class-words), as the report gives them (homotopy.chosen_words, each candidate's words):
    # the one candidate, the same class (words, energy) in Python and the CLI; an index names a
    # class only within one run's list. Bad names are InputErrors.
    a = surfmap.shapes.n_hole_torus(2, 14, True)
    b = surfmap.shapes.vase(18, True)
    free = surfmap.surface_map(*a, *b)
    h = free["homotopy"]
    words = h["chosen_words"]
    assert len(words) == 4 and words == h["candidates"][h["chosen"]]["words"]
    r = surfmap.surface_map(*a, *b, class_words=words)
    assert len(r["homotopy"]["candidates"]) == 1 and r["homotopy"]["chosen_words"] == words
    assert r["energy"]["final"] == pytest.approx(free["energy"]["final"], rel=1e-6)
    src, dst, out, rep = (tmp_path / n for n in ("a.obj", "b.obj", "m.obj", "r.json"))
    surfmap.write_obj(str(src), *a)
    surfmap.write_obj(str(dst), *b)
    c = cli("map", src, dst, "--out", out, "--report", rep, "--quiet", "--class-words", json.dumps(words))
    assert c.returncode == 0, c.stderr
    report = json.loads(rep.read_text())
    assert report["homotopy"]["chosen_words"] == words
    assert report["energy"]["final"] == pytest.approx(free["energy"]["final"], rel=1e-6)
    bad = cli("map", src, dst, "--out", out, "--report", rep, "--class-words", "[[1],[2]")
    assert bad.returncode != 0 and "--class-words" in bad.stderr
    with pytest.raises(surfmap.InputError, match="class_words"):
        surfmap.surface_map(*a, *b, class_words=words[:3])
    with pytest.raises(surfmap.InputError, match="class_words"):
        surfmap.surface_map(*a, *b, class_words=words, homotopy=0)
    with pytest.raises(surfmap.InputError, match="class_words"):
        surfmap.surface_map(*a, *b, class_words="1 2 3 4")


def test_both_canonical_bases_is_the_default_and_one_basis_is_asked_for(tmp_path, cli):
    # Session 25 (docs/handle_classes.md "Classes named by words"): the candidate classes are listed in both
    # canonical bases by default (some listed "in the short canonical basis"); both_canonical_bases=
    # False and the CLI's --one-canonical-basis list the run's basis only, the same list; the two
    # flags together are refused in one line.
    a = surfmap.shapes.n_hole_torus(2, 14, True)
    b = surfmap.shapes.vase(18, True)

    def short_listed(candidates):
        return sum("in the short canonical basis" in c["description"] for c in candidates)

    both = surfmap.surface_map(*a, *b, two_way=False, agreement_ratio=2)
    one = surfmap.surface_map(*a, *b, two_way=False, agreement_ratio=2, both_canonical_bases=False)
    assert short_listed(both["homotopy"]["candidates"]) > 0
    assert short_listed(one["homotopy"]["candidates"]) == 0
    assert len(one["homotopy"]["candidates"]) < len(both["homotopy"]["candidates"])
    src, dst, out, rep = (tmp_path / n for n in ("a.obj", "b.obj", "m.obj", "r.json"))
    surfmap.write_obj(str(src), *a)
    surfmap.write_obj(str(dst), *b)
    c = cli("map", src, dst, "--out", out, "--report", rep, "--quiet", "--no-two-way", "--agreement-ratio", "2",
            "--one-canonical-basis")
    assert c.returncode == 0, c.stderr
    listed = json.loads(rep.read_text())["homotopy"]["candidates"]
    assert short_listed(listed) == 0
    assert [x["words"] for x in listed] == [x["words"] for x in one["homotopy"]["candidates"]]
    bad = cli("map", src, dst, "--out", out, "--report", rep, "--both-canonical-bases", "--one-canonical-basis")
    assert bad.returncode != 0 and "exclude each other" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1, bad.stderr


def test_face_charts_keyword_maps_in_per_face_charts():
    # face_charts='always' (CLI --face-charts always): the genus >= 2 map in per-face charts
    # of the target (issue 13; by default only where one chart cannot hold the target), the
    # snapped class of a jittered copy, converged with 0 flipped, said so in the report; a
    # bad name is refused naming the keyword.
    plate = surfmap.shapes.cad_plate(3, 16, 0.1)
    copy = surfmap.shapes.jitter(*plate, 0.2, 1)
    r = surfmap.surface_map(*copy, *plate, face_charts="always")
    assert r["converged"]
    assert r["flipped_triangles"] == 0 and r["degenerate_triangles"] == 0
    assert r["face_charts"].startswith("per-face charts (requested)"), r["face_charts"]
    assert r["face_charts_requested"] == "always"
    with pytest.raises(surfmap.InputError, match="face_charts"):
        surfmap.surface_map(*copy, *plate, face_charts="sometimes")


def test_cli_option_keywords_are_checked_and_reach_the_map():
    a = surfmap.shapes.n_hole_torus(2, 30, True)
    b = surfmap.shapes.jitter(*surfmap.shapes.n_hole_torus(2, 34, True), 0.2, 4)
    for bad, match in (({"homotopy_extra_cuts": -1}, "homotopy_extra_cuts"),
                       ({"own_weights_floor": 0.0}, "own_weights_floor"),
                       ({"target_loops": "straight"}, "target_loops")):
        with pytest.raises(surfmap.InputError, match=match):
            surfmap.surface_map(*a, *b, **bad)
    # compare_directions (CLI --compare-directions): the other direction is mapped even for
    # this nearly conformal copy, where the default skips it (ratio below 2), and the two
    # directions' classes are compared.
    r = surfmap.surface_map(*a, *b, compare_directions=True, cheap_direction_check=False)
    q = r["quality"]
    assert not q["two_way_status"].startswith("not run"), q["two_way_status"]
    assert q["two_way_status"].startswith("target -> source energy ratio"), q["two_way_status"]
    assert not q["reverse_inverse_reason"].startswith("not compared: the two-way run did not run")
    # The one serializer (map/map_report.cpp to_json, the CLI's --report too) gives this
    # session's report fields here as well.
    assert set(q["directions"]) >= {"outcome", "reason", "inverted_candidate", "chosen_class_words"}
    assert "long_starts" in r["homotopy"]["ranking"] and "status" in r["source_subdivision"]
    # (session 25: no class failed here, so no fallback was refused on its solve)
    assert r["homotopy"]["fallbacks"]["refused_unmapped"] == 0


def test_short_curve_twists_and_generators_fallback_keywords_reach_the_map():
    # Issue 13, session 27: short_curve_twists=True (--short-curve-twists) gives the class
    # search the twists along both surfaces' short curves, listed in the report;
    # short_generators_fallback (--no-short-generators-fallback) is a keyword, and a map
    # that needs no retry says nothing of one. The genus-3 plate -> n-hole torus maps at
    # about 1.2 x the conformal bound, above the search's gap, so the search runs.
    a = surfmap.shapes.cad_plate(3)
    b = surfmap.shapes.n_hole_torus(3, 26, True)
    r = surfmap.surface_map(*a, *b, short_curve_twists=True, two_way=False, through_shape=False,
                            short_generators_fallback=False, fold_fallback=False)
    s = r["homotopy"]["search"]
    assert s["run"], s["stop_reason"]
    assert " source curves " in s["curve_twists"] and " target curves " in s["curve_twists"], s["curve_twists"]
    assert int(s["curve_twists"].split()[0]) >= 6  # (2g marking curves at least)
    assert r["canonical_generators_fallback"] == ""
    assert {"short_curve_twists", "short_generators_fallback"} <= surfmap.CAPABILITIES


def test_fold_fallback_keyword_and_flag_reach_the_map(cli, tmp_path):
    # Issue 13, session 28: fold_fallback (--no-fold-fallback) is a keyword and a flag, the
    # report has the key, empty for a map that needed no retry, and the flag's run writes
    # it too; a keyword of the wrong type is refused. (What the retry does is checked in
    # C++: SurfaceMapHandles.FoldFailuresAreRetriedWithTheShortGeneratorsOneWay and
    # SurfaceMapFallbacks.FoldedFallbacksAreRefusedOnTheirSolveAsMappingThemWould.)
    a = surfmap.shapes.n_hole_torus(2, 18, True)
    b = surfmap.shapes.n_hole_torus(2, 22, True)
    r = surfmap.surface_map(*a, *b, two_way=False, homotopy_search=False, fold_fallback=False)
    assert r["converged"] and r["fold_fallback"] == ""
    assert "fold_fallback" in surfmap.CAPABILITIES
    with pytest.raises(TypeError):
        surfmap.surface_map(*a, *b, fold_fallback="no")
    p, q = cli_map(cli, tmp_path, "--no-two-way", "--no-fold-fallback", pair=(a, b))
    assert p.returncode == 0, p.stderr
    assert q["fold_fallback"] == "" and not any("made with the short" in n for n in q["notes"])


def test_high_kicks_keyword_and_flag_reach_the_map(cli, tmp_path):
    # Issue 14, session 28: high_kicks= (--high-kicks N, 0: none) reaches the class
    # search, and the report says what was done. The genus-3 plate -> n-hole torus maps at
    # about 1.2 x the conformal bound: the search runs and ends below 2 x, so no kick is made
    # by default; with high_kicks=0 the step is off. A negative count is an InputError.
    a = surfmap.shapes.cad_plate(3)
    b = surfmap.shapes.n_hole_torus(3, 26, True)
    r = surfmap.surface_map(*a, *b, two_way=False, through_shape=False)
    s = r["homotopy"]["search"]
    assert s["run"], s["stop_reason"]
    assert s["high_kicks_status"].startswith("not run: the search ended at "), s["high_kicks_status"]
    assert s["high_kicks_status"].endswith("below 2 x"), s["high_kicks_status"]
    assert s["kicks"] == 0 and s["lower_kicks"] == 0
    off = surfmap.surface_map(*a, *b, two_way=False, through_shape=False, high_kicks=0)
    assert off["homotopy"]["search"]["high_kicks_status"] == "off"
    assert off["energy"]["final"] == pytest.approx(r["energy"]["final"], rel=1e-9)
    with pytest.raises(surfmap.InputError, match="high_kicks must be at least 0"):
        surfmap.surface_map(*a, *b, high_kicks=-1)
    assert "high_kicks" in surfmap.CAPABILITIES
    p, report = cli_map(cli, tmp_path, "--no-two-way", "--no-through-shape", "--high-kicks", "0", pair=(a, b))
    assert p.returncode == 0, p.stderr
    assert report["homotopy"]["search"]["high_kicks_status"] == "off"
    # One spelling, as the other counts (--refine-levels 0): no --no-high-kicks beside it (session 28 review).
    p, _ = cli_map(cli, tmp_path, "--no-high-kicks")
    assert p.returncode != 0 and "--no-high-kicks" in p.stderr, p.stderr
    p, _ = cli_map(cli, tmp_path, "--high-kicks", "-1")
    assert p.returncode != 0 and "high-kicks" in p.stderr, p.stderr


def test_through_shape_ratio_keyword_and_flag_reach_the_map(cli, tmp_path):
    # Issue 14, session 28 (branch class29): through_shape_ratio= (CLI --through-shape-ratio R)
    # is the energy ratio from which the through-shape step runs. The genus-2 CAD plate -> n-hole
    # torus maps at about 1.1 x the conformal bound: below the default 3 and below 2, the step
    # does not run and says below what; from ratio 1 it runs and names the shapes it went
    # through. A negative ratio is refused (InputError; the CLI's own check).
    a = surfmap.shapes.cad_plate(2)
    b = surfmap.shapes.n_hole_torus(2, 26, True)
    r = surfmap.surface_map(*a, *b, two_way=False)
    assert r["quality"]["through_shape_status"] == "not run: energy ratio below 3"
    low = surfmap.surface_map(*a, *b, two_way=False, through_shape_ratio=2)
    assert low["quality"]["through_shape_status"] == "not run: energy ratio below 2"
    ran = surfmap.surface_map(*a, *b, two_way=False, through_shape_ratio=1)
    assert "through the genus-2 n-hole torus" in ran["quality"]["through_shape_status"], \
        ran["quality"]["through_shape_status"]
    assert ran["quality"]["energy_ratio"] <= r["quality"]["energy_ratio"] * (1 + 1e-6)
    with pytest.raises(surfmap.InputError, match="through_shape_ratio must be 0 or more"):
        surfmap.surface_map(*a, *b, through_shape_ratio=-1)
    assert "through_shape_ratio" in surfmap.CAPABILITIES
    p, report = cli_map(cli, tmp_path, "--no-two-way", "--through-shape-ratio", "2", pair=(a, b))
    assert p.returncode == 0, p.stderr
    status = report["quality"]["through_shape_status"]
    assert status == "not run: energy ratio below 2", status
    p, _ = cli_map(cli, tmp_path, "--through-shape-ratio", "-1")
    assert p.returncode != 0 and "through-shape-ratio" in p.stderr, p.stderr


def test_agreement_ratio_keyword_and_flag_reach_the_map(cli, tmp_path):
    # Issue 14 below the two-way run (docs/handle_classes.md "The two directions today"): the generated
    # genus-3 CAD plate -> n-hole torus maps at about 1.2 x the conformal bound, between
    # agreement_ratio (default 1.1) and two_way_ratio (2), so by default the other direction
    # is mapped too and quality.directions.agreement says what was done (here the two
    # directions' classes are already inverse: nothing else solved, the map unchanged);
    # agreement_ratio=2 (CLI --agreement-ratio 2) turns it off; a negative ratio is refused.
    a = surfmap.shapes.cad_plate(3)
    b = surfmap.shapes.n_hole_torus(3, 26, True)
    on = surfmap.surface_map(*a, *b)
    off = surfmap.surface_map(*a, *b, agreement_ratio=2.0)
    assert 1.1 <= off["quality"]["energy_ratio"] < 2, off["quality"]["energy_ratio"]
    d_on, d_off = on["quality"]["directions"], off["quality"]["directions"]
    assert d_off["agreement"] == "" and off["quality"]["two_way_status"] == "not run: energy ratio below 2"
    assert d_on["agreement"] != "", on["quality"]["two_way_status"]
    assert "both directions agree" in on["quality"]["two_way_status"]
    assert d_on["outcome"] in ("inverse", "symmetric: both optimal"), d_on
    if d_on["agreement"].startswith(("inverse", "inverse up to")):
        # Nothing solved: the first run's map and class are returned.
        assert on["quality"]["energy_ratio"] == off["quality"]["energy_ratio"]
        assert d_on["chosen_class_words"] == d_off["chosen_class_words"]
    with pytest.raises(surfmap.InputError, match="agreement_ratio"):
        surfmap.surface_map(*a, *b, agreement_ratio=-1.0)
    assert "agreement_ratio" in surfmap.CAPABILITIES
    from surfmap import mapcall
    assert "agreement_ratio" in mapcall.MAP_OPTION_NAMES
    # The CLI flag reaches the same option.
    p, report = cli_map(cli, tmp_path, "--agreement-ratio", "2", pair=(a, b))
    assert p.returncode == 0, p.stderr
    q = report["quality"]
    assert q["directions"]["agreement"] == "" and q["two_way_status"] == "not run: energy ratio below 2"
    bad, _ = cli_map(cli, tmp_path, "--agreement-ratio", "-1")
    assert bad.returncode != 0 and "agreement-ratio" in bad.stderr, bad.stderr


def test_cheap_direction_check_keyword_changes_the_two_way_verdict():
    # Issue 14 (docs/handle_classes.md "The two directions today"), as
    # SurfaceMapHandles.ReverseClassOnlySolvesTheOtherDirectionsClassAlone: with the two-way
    # run forced (two_way_ratio=0), the direction whose other direction's ratio is not lower
    # checks its class against the other's (a verdict in quality.directions);
    # cheap_direction_check=False (CLI --no-cheap-direction-check) keeps it unchecked.
    a = surfmap.shapes.n_hole_torus(2, 26, True)
    b = surfmap.shapes.vase(30, True)
    f = surfmap.surface_map(*a, *b, two_way_ratio=0)
    r = surfmap.surface_map(*b, *a, two_way_ratio=0)
    statuses = (f["quality"]["two_way_status"], r["quality"]["two_way_status"])
    pair = (a, b) if "not lower" in statuses[0] else (b, a)
    checked = f if pair[0] is a else r
    q = checked["quality"]
    assert "not lower; " in q["two_way_status"], statuses
    assert q["directions"]["outcome"] in ("inverse", "symmetric: both optimal"), q["directions"]
    off = surfmap.surface_map(*pair[0], *pair[1], two_way_ratio=0, cheap_direction_check=False)
    assert off["quality"]["two_way_status"].endswith("not lower: kept"), off["quality"]["two_way_status"]
    assert off["quality"]["directions"]["outcome"] == ""
    with pytest.raises(surfmap.InputError, match="two_way_ratio"):
        surfmap.surface_map(*a, *b, two_way_ratio=-1.0)
