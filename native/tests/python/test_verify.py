"""`surfmap verify` and surfmap.verify: the independent certificate of a stored map
(docs/verification.md), on a map written by `surfmap map --correspondence`."""
import numpy as np
import pytest

import surfmap
from mesh_helpers import torus


@pytest.fixture(scope="module")
def mapped(tmp_path_factory):
    """A genus-1 pair mapped by the CLI: (src path, dst path, CORR.txt path, Vs, Fs, Vt, Ft)."""
    d = tmp_path_factory.mktemp("verify")
    (Vs, Fs), (Vt, Ft) = torus(1.0, 0.45, 40, 20), torus(1.4, 0.5, 36, 18)  # target: mirror symmetric in z
    src, dst, corr = d / "a.obj", d / "b.obj", d / "corr.txt"
    surfmap.write_obj(str(src), Vs, Fs)
    surfmap.write_obj(str(dst), Vt, Ft)
    return src, dst, corr, Vs, Fs, Vt, Ft


def test_cli_round_trip_and_a_fold(tmp_path, cli, mapped):
    src, dst, corr, Vs, Fs, Vt, Ft = mapped
    r = cli("map", src, dst, "--out", tmp_path / "m.obj", "--report", tmp_path / "r.json",
            "--correspondence", corr, "--quiet")
    assert r.returncode == 0, r.stderr
    cert = tmp_path / "cert.json"
    v = cli("verify", src, dst, "--correspondence", corr, "--json", cert)
    assert v.returncode == 0, v.stdout + v.stderr
    assert "\nCERTIFIED:" in v.stdout and "0 negative, 0 degenerate" in v.stdout, v.stdout
    import json
    c = json.loads(cert.read_text())
    assert c["certified"] and c["degree"] == 1 and abs(c["area_ratio"] - 1) < 0.05
    # The file read back from Python certifies the same way.
    f = surfmap.read_correspondence(str(corr))
    assert f["has_inverse"] and len(f["forward"]["face"]) == len(Vs) and len(f["inverse"]["face"]) == len(Vt)
    assert surfmap.verify(Vs, Fs, Vt, Ft, f["forward"], f["inverse"])["certified"]

    # One source vertex, (i, j) = (10, 5) of the 40 x 20 grid, moved onto the image of
    # (12, 5), across its neighbour (11, 5): refused, naming the negative triangles.
    lines = corr.read_text().splitlines()
    lines[10 * 20 + 5] = lines[12 * 20 + 5]
    folded = tmp_path / "folded.txt"
    folded.write_text("\n".join(lines) + "\n")
    v = cli("verify", src, dst, "--correspondence", folded)
    assert v.returncode == 1, v.stdout + v.stderr
    assert "NOT CERTIFIED" in v.stdout and "negatively oriented" in v.stdout, v.stdout
    assert "not certified" in v.stderr
    f = surfmap.read_correspondence(str(folded))
    res = surfmap.verify(Vs, Fs, Vt, Ft, f["forward"], f["inverse"])
    assert not res["certified"] and res["negative_triangles"] > 0 and res["winding_failures"] > 0

    # The original (forward-only) format is refused with a message, a bad line names its line.
    old = tmp_path / "old.txt"
    old.write_text("\n".join(corr.read_text().splitlines()[:len(Vs)]) + "\n")
    v = cli("verify", src, dst, "--correspondence", old)
    assert v.returncode == 1 and "no inverse section" in v.stderr, v.stderr
    bad = tmp_path / "bad.txt"
    bad.write_text("0 1 0\n")
    v = cli("verify", src, dst, "--correspondence", bad)
    assert v.returncode == 1 and "bad.txt:1:" in v.stderr, v.stderr


def test_python_verify_rejects_a_reflection(mapped):
    # The map composed with the mirror z -> -z of the target (a symmetry of its vertices):
    # the reversed map's forward points are the mirrored points, its inverse the inverse at the
    # mirrored vertices. Consistent, but every image triangle is negative and the degree is -1.
    _, _, _, Vs, Fs, Vt, Ft = mapped
    r = surfmap.surface_map(Vs, Fs, Vt, Ft)
    assert surfmap.verify(Vs, Fs, Vt, Ft, r)["certified"]
    mirror = Vt * np.array([1.0, 1.0, -1.0])
    vperm = np.array([np.linalg.norm(Vt - p, axis=1).argmin() for p in mirror])
    assert np.abs(Vt[vperm] - mirror).max() < 1e-9
    faces = {tuple(sorted(f)): i for i, f in enumerate(Ft.tolist())}
    fperm = np.array([faces[tuple(sorted(vperm[f]))] for f in Ft])
    fw_face = fperm[r["forward"]["face"]]
    fw_bary = np.zeros_like(r["forward"]["barycentric"])
    for i, (f, b) in enumerate(zip(r["forward"]["face"], r["forward"]["barycentric"])):
        for k in range(3):
            fw_bary[i, list(Ft[fperm[f]]).index(vperm[Ft[f, k]])] = b[k]
    inverse = {"face": r["inverse"]["face"][vperm], "barycentric": r["inverse"]["barycentric"][vperm]}
    res = surfmap.verify(Vs, Fs, Vt, Ft, {"face": fw_face, "barycentric": fw_bary}, inverse)
    assert not res["certified"]
    assert res["negative_triangles"] == len(Fs) and res["degree"] == -1
    assert res["inverse_failures"] == 0 and res["forward_failures"] == 0, res["summary"]
    with pytest.raises(surfmap.InputError, match="forward"):
        surfmap.verify(Vs, Fs, Vt, Ft, {"face": fw_face}, inverse)


def test_unresolved_images_are_undecided_unless_strict():
    # A coarse genus-2 source onto the vase (mean D' ~1.6): one source vertex's star wraps around
    # a thin part of the vase (its neighbours' images lie where the vase's normal has turned by
    # more than 60 degrees), so its winding cannot be measured in one tangent plane. That check
    # is undecided (listed, not failed); strict=True fails it. Everything resolved passes.
    # (The map of one canonical basis's class, lifted from the loops at source vertex 218, 27.37744:
    # with both bases listed, the default since session 25, the near-mirror class listed in the
    # short basis, 27.37818, ties with it within choose_class's 1e-4 and is listed first, and its
    # map has every star resolved and winding once. Which of two tied classes is chosen is not what
    # this test is about; docs/history/handle_classes.md "Session 25".)
    a = surfmap.shapes.n_hole_torus(2, 14, True)
    b = surfmap.shapes.vase(18, True)
    r = surfmap.surface_map(*a, *b, both_canonical_bases=False)
    c = surfmap.verify(*a, *b, r)
    assert c["certified"] and not c["failures"], c["summary"]
    assert c["undecided"] and c["unresolved_triangles"] > 0, c["summary"]
    assert "CERTIFIED where resolved" in c["summary"]
    assert c["winding_failures"] == c["winding_failures_unresolved"] > 0
    s = surfmap.verify(*a, *b, r, strict=True)
    assert not s["certified"] and s["failures"] == c["undecided"]
