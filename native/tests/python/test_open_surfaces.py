"""`surfmap map` on open surfaces (issue 16, docs/open_surfaces.md): disks and
annuli are mapped and written like closed maps; other open pairs and mixed
open/closed pairs are refused with one line naming (g, b) of both."""
import json

import numpy as np
import pytest

import surfmap


def grid(n, m, x_of, holes=()):
    """(n+1) x (m+1) vertex grid placed by x_of(s, t) (s, t in [0, 1]),
    quads split along alternating diagonals; quads (i, j) in `holes` dropped."""
    V = np.array([x_of(j / m, i / n) for i in range(n + 1) for j in range(m + 1)], float)
    F = []
    for i in range(n):
        for j in range(m):
            if (i, j) in holes:
                continue
            a = i * (m + 1) + j
            b, c, d = a + 1, a + m + 1, a + m + 2
            F += [[a, b, d], [a, d, c]] if (i + j) % 2 else [[a, b, c], [b, d, c]]
    return V, np.array(F, int)


def cap(n):
    """A spherical cap (hemisphere, rim at z = 0) as a polar grid with a centre vertex
    (samples/shapes.h spherical_cap)."""
    return surfmap.shapes.spherical_cap(n)


def tube(height, around=32, rows=8):
    """Open cylinder: a grid wrapped around (the seam column merged)."""
    V, F = grid(rows, around, lambda s, t: (np.cos(2 * np.pi * s), np.sin(2 * np.pi * s), height * t))
    m = around + 1
    keep = np.array([idx for idx in range(len(V)) if idx % m != around])
    remap = {old: new for new, old in enumerate(keep)}
    F = np.vectorize(lambda v: remap[v - around if v % m == around else v])(F)
    return V[keep], F


def run_map(cli, tmp_path, src, dst):
    paths = []
    for name, (V, F) in (("src.obj", src), ("dst.obj", dst)):
        surfmap.write_obj(str(tmp_path / name), V, F)
        paths.append(tmp_path / name)
    out, rep, corr = tmp_path / "morph.obj", tmp_path / "report.json", tmp_path / "corr.txt"
    r = cli("map", *paths, "--out", out, "--report", rep, "--correspondence", corr, "--quiet")
    return r, out, rep, corr


def test_disk_to_square_writes_closed_map_outputs(tmp_path, cli):
    src = cap(10)
    dst = grid(20, 20, lambda s, t: (2 * s - 1, 2 * t - 1, 0.0))
    r, out, rep, corr = run_map(cli, tmp_path, src, dst)
    assert r.returncode == 0, r.stderr
    report = json.loads(rep.read_text())
    assert report["genus"] == 0 and report["boundary_loops"] == 1 and report["open"]["domain"] == "disk"
    assert report["flipped_triangles"] == 0
    assert 1.0 <= report["distortion"]["mean"] < 1.15
    lines = corr.read_text().split("\n")[:-1]
    # Forward lines, then the inverse section (verify/correspondence_file.h), as closed maps write.
    k = lines.index("# inverse: one line per target vertex, 'source_face b0 b1 b2'")
    assert k == len(src[0]) and len(lines) - k - 1 == len(dst[0])
    for i, line in enumerate(lines[:k] + lines[k + 1:]):
        face, *bary = line.split()
        assert 0 <= int(face) < len(dst[1] if i < k else src[1])
        assert abs(sum(map(float, bary)) - 1) < 1e-9 and min(map(float, bary)) >= 0
    # The morph lies on the flat square.
    morph = [l.split()[1:] for l in out.read_text().splitlines() if l.startswith("v ")]
    assert len(morph) == len(src[0])
    assert max(abs(float(v[2])) for v in morph) < 1e-12
    assert max(max(abs(float(v[0])), abs(float(v[1]))) for v in morph) <= 1 + 1e-12


def test_annuli_map_with_the_ratio_of_moduli(tmp_path, cli):
    r, _, rep, _ = run_map(cli, tmp_path, tube(1.0), tube(2.0, around=28, rows=12))
    assert r.returncode == 0, r.stderr
    report = json.loads(rep.read_text())
    o = report["open"]
    assert o["domain"] == "annulus"
    ratio = o["target"]["modulus"] / o["source"]["modulus"]
    assert abs(ratio / 2.0 - 1) < 0.01  # both tubes have radius 1, heights 1 and 2
    assert abs(report["distortion"]["mean"] / ratio - 1) < 0.01
    assert report["flipped_triangles"] == 0


def test_mismatched_open_pairs_are_refused(tmp_path, cli):
    square = lambda s, t: (s, t, 0.0)
    three_loops = grid(12, 12, square, holes={(3, 3), (8, 8)})  # genus 0, 3 boundary loops
    # (0, 3) is mapped through the doubles now (test_open_double.py); against a disk it is refused.
    r, out, _, _ = run_map(cli, tmp_path, three_loops, grid(6, 6, square))
    assert r.returncode == 1
    assert "genus 0 with 3 boundary loops" in r.stderr and "genus 0 with 1 boundary loop" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not out.exists()
    r, _, _, _ = run_map(cli, tmp_path, grid(6, 6, square), tube(1.0))
    assert r.returncode == 1
    assert "genus 0 with 1 boundary loop" in r.stderr and "genus 0 with 2 boundary loops" in r.stderr
    # An octahedron: a closed genus-0 surface.
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    r, _, _, _ = run_map(cli, tmp_path, grid(6, 6, square), (V, F))
    assert r.returncode == 1
    assert "genus 0 with 1 boundary loop" in r.stderr and "genus 0 (closed)" in r.stderr


def test_bowtie_boundary_vertex_refused_by_name(tmp_path, cli):
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 2, 0], [3, 2, 0], [3, 3, 0]], float)
    F = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 4], [4, 5, 6]])
    r, _, _, _ = run_map(cli, tmp_path, (V, F), (V, F))
    assert r.returncode == 1
    assert "vertex 4" in r.stderr and len(r.stderr.strip().splitlines()) == 1


# ---- surfmap.surface_map on open surfaces (the Python entry point) ----

def frustum(height, r0, r1, around=32, rows=8):
    """Open truncated cone: radius r0 at z = 0, r1 at z = height (loops of different length)."""
    V, F = tube(height, around, rows)
    t = V[:, 2] / height
    V = V.copy()
    V[:, :2] *= (r0 + (r1 - r0) * t)[:, None]
    return V, F


def signed_areas_xy(P, F):
    a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def test_python_hemisphere_to_square_disk():
    Vs, Fs = cap(10)  # hemisphere: rim at z = 0
    Vt, Ft = grid(20, 20, lambda s, t: (2 * s - 1, 2 * t - 1, 0.0))
    r = surfmap.surface_map(Vs, Fs, Vt, Ft)
    assert r["genus"] == 0 and r["boundary_loops"] == 1 and r["open"]["domain"] == "disk"
    for side in ("source_topology", "target_topology"):
        assert (r[side]["genus"], r[side]["boundary_loops"]) == (0, 1)
    assert r["flipped_triangles"] == 0
    assert 1.0 <= r["distortion"]["mean"] < 1.15
    assert r["distortion"]["per_face"].shape == (len(Fs),)
    pos = r["forward"]["position"]
    assert pos.shape == (len(Vs), 3) and r["inverse"]["position"].shape == (len(Vt), 3)
    # Flips counted independently: the morph's triangles on the flat square
    # all turn the way the square's own faces do.
    target_sign = np.sign(signed_areas_xy(Vt, Ft))
    assert abs(target_sign.sum()) == len(Ft)
    assert np.all(signed_areas_xy(pos, Fs) * target_sign[0] > 0)
    # Boundary onto boundary, interior into the interior, both directions.
    rim = np.abs(Vs[:, 2]) < 1e-9
    on_square_boundary = lambda P: np.abs(np.max(np.abs(P[:, :2]), axis=1) - 1) < 1e-9
    assert np.all(on_square_boundary(pos[rim])) and not np.any(on_square_boundary(pos[~rim]))
    square_rim = np.max(np.abs(Vt[:, :2]), axis=1) > 1 - 1e-12
    inv = r["inverse"]["position"]
    assert np.all(np.abs(inv[square_rim, 2]) < 1e-9) and np.all(inv[~square_rim, 2] > 1e-9)
    # The report is JSON-able like the closed map's (nan/inf aside).
    json.dumps({k: v for k, v in r.items() if k in ("open", "source_topology", "target_topology", "energy")})


def square_from_disk(zeta):
    """The Riemann map of the unit disk onto the square [-1, 1]^2 fixing 0 (Schwarz-Christoffel:
    w = C * integral of (1 + zeta^4)^(-1/2), the corners the images of the 8th roots e^(i pi/4) i^k);
    in closed form zeta 2F1(1/4, 1/2; 5/4; -zeta^4), scaled so that the corner is 1 + i."""
    from math import gamma, pi, sqrt
    from scipy.special import hyp2f1
    half_side = gamma(0.25) ** 2 / (4 * sqrt(2 * pi)) / sqrt(2)    # |w(e^(i pi/4))| / sqrt(2)
    return zeta * hyp2f1(0.25, 0.5, 1.25, -zeta ** 4) / half_side


def test_hemisphere_to_square_is_the_riemann_maps_composed():
    """The disk case is the classic free-boundary harmonic disk map: source and target each onto
    the unit disk conformally, composed with a disk automorphism. Checked against conformal maps
    computed here independently of the solver: the hemisphere's stereographic projection onto the
    unit disk and the square's Schwarz-Christoffel map. The area centring fixes the Möbius part
    (both shapes are symmetric about their centres, so the pole goes to the square's centre); the
    rotation, which no energy selects (every automorphism gives a conformal map of energy = the
    square's area), is fitted here, and nothing else is free. Measured (mean / max distance over
    the diagonal): rings 8: 0.11% / 0.29%, 16: 0.038% / 0.16%, 32: ~0.012% / ~0.08%; the
    orientation-reversing composition is 22% off."""
    pytest.importorskip("scipy")
    from scipy.optimize import minimize_scalar
    previous = np.inf
    for rings in (8, 16, 32):
        Vs, Fs = cap(rings)
        n = 2 * rings
        Vt, Ft = grid(n, n, lambda s, t: (2 * s - 1, 2 * t - 1, 0.0))
        r = surfmap.surface_map(Vs, Fs, Vt, Ft)
        assert r["open"]["domain"] == "disk" and r["flipped_triangles"] == 0
        got = r["forward"]["position"][:, 0] + 1j * r["forward"]["position"][:, 1]
        P = Vs / np.linalg.norm(Vs, axis=1)[:, None]
        zeta = (P[:, 0] + 1j * P[:, 1]) / (1 + P[:, 2])     # stereographic from the south pole: rim -> |zeta| = 1
        error = lambda a: np.abs(got - square_from_disk(np.exp(1j * a) * zeta))
        angles = np.linspace(0, 2 * np.pi, 720, endpoint=False)
        a0 = angles[np.argmin([error(a).mean() for a in angles])]
        a = minimize_scalar(lambda a: error(a).mean(), bounds=(a0 - 0.01, a0 + 0.01), method="bounded").x
        e = error(a)
        diag = 2 * np.sqrt(2)
        print(f"hemisphere rings {rings} -> square {n}x{n}: rotation {a:.4f}, mean distance to the composed "
              f"Riemann maps {100 * e.mean() / diag:.4f}% of the diagonal, max {100 * e.max() / diag:.4f}%")
        assert e.mean() < 0.002 * diag and e.max() < 0.005 * diag
        assert e.mean() < previous           # converges under refinement
        previous = e.mean()
        assert abs(got[np.argmax(Vs[:, 2])]) < 1e-3 * diag    # the pole onto the centre
        # Orientation: the mirror composition is far off (measured 22%), so the fit means something.
        mirror = lambda a: np.abs(got - square_from_disk(np.exp(1j * a) * np.conj(zeta))).mean()
        assert min(mirror(x) for x in angles) > 0.1 * diag


def test_python_annuli_dilatation_is_the_ratio_of_moduli():
    # Tubes of radius 1, heights 1 and 2: moduli h / 2π, analytic ratio 2.
    r = surfmap.surface_map(*tube(1.0), *tube(2.0, around=28, rows=12))
    assert r["open"]["domain"] == "annulus" and r["flipped_triangles"] == 0
    assert (r["target_topology"]["genus"], r["target_topology"]["boundary_loops"]) == (0, 2)
    assert abs(r["distortion"]["mean"] / 2.0 - 1) < 0.01
    assert abs(r["open"]["extremal_dilatation"] / 2.0 - 1) < 0.01
    assert r["open"]["boundary_pairing"] == [0, 1]


def test_python_annulus_boundary_pairing_swaps_the_loops():
    # Loop 0 is the longer loop: the top (radius 1.5 at z = h) on both.
    src, dst = frustum(1.0, 1.0, 1.5), frustum(2.0, 1.0, 1.5, around=28, rows=12)
    plain = surfmap.surface_map(*src, *dst)
    top = np.abs(src[0][:, 2] - 1.0) < 1e-12
    bottom = np.abs(src[0][:, 2]) < 1e-12
    assert np.allclose(plain["forward"]["position"][top, 2], 2.0, atol=1e-9)
    assert np.allclose(plain["forward"]["position"][bottom, 2], 0.0, atol=1e-9)
    for pairing in ("swap", [1, 0]):
        r = surfmap.surface_map(*src, *dst, boundary_pairing=pairing)
        assert r["open"]["boundary_pairing"] == [1, 0]
        assert r["flipped_triangles"] == 0
        pos = r["forward"]["position"]
        assert np.allclose(pos[top, 2], 0.0, atol=1e-9) and np.allclose(pos[bottom, 2], 2.0, atol=1e-9)
        assert np.all((pos[~(top | bottom), 2] > 1e-9) & (pos[~(top | bottom), 2] < 2 - 1e-9))
    for bad in ([0, 0], [0, 1, 2], [2, 0], "reverse"):
        with pytest.raises(surfmap.InputError, match="boundary_pairing|boundary pairing"):
            surfmap.surface_map(*src, *dst, boundary_pairing=bad)
    octahedron = (np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float),
                  np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]))
    with pytest.raises(surfmap.InputError, match="only for open surfaces"):
        surfmap.surface_map(*octahedron, *octahedron, boundary_pairing="swap")


def test_python_mismatched_open_topology_is_one_line_naming_both():
    square = grid(6, 6, lambda s, t: (s, t, 0.0))
    with pytest.raises(surfmap.InputError) as e:
        surfmap.surface_map(*square, *tube(1.0))
    msg = str(e.value)
    assert "genus 0 with 1 boundary loop" in msg and "genus 0 with 2 boundary loops" in msg and "\n" not in msg
    octahedron = (np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float),
                  np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]))
    with pytest.raises(surfmap.InputError, match=r"genus 0 \(closed\)"):
        surfmap.surface_map(*square, *octahedron)
    # Landmarks are held on open pairs (test_open_landmarks.py); a corner (boundary) onto the
    # centre (interior) is refused naming the landmark.
    with pytest.raises(surfmap.InputError, match="landmark 0 .*boundary"):
        surfmap.surface_map(*square, *square, landmarks=[[0, 3 * 7 + 3]])


def test_cli_boundary_swap_and_pairing(tmp_path, cli):
    src, dst = frustum(1.0, 1.0, 1.5), frustum(2.0, 1.0, 1.5, around=28, rows=12)
    top = np.abs(src[0][:, 2] - 1.0) < 1e-12
    for flag in (("--boundary-swap",), ("--boundary-pairing", "1,0")):
        paths = []
        for name, (V, F) in (("src.obj", src), ("dst.obj", dst)):
            surfmap.write_obj(str(tmp_path / name), V, F)
            paths.append(tmp_path / name)
        out, rep = tmp_path / "morph.obj", tmp_path / "report.json"
        r = cli("map", *paths, "--out", out, "--report", rep, "--quiet", *flag)
        assert r.returncode == 0, r.stderr
        report = json.loads(rep.read_text())
        assert report["open"]["boundary_pairing"] == [1, 0] and report["flipped_triangles"] == 0
        assert report["source_topology"]["boundary_loops"] == report["target_topology"]["boundary_loops"] == 2
        morph = np.array([[float(x) for x in l.split()[1:4]] for l in out.read_text().splitlines() if l.startswith("v ")])
        assert np.allclose(morph[top, 2], 0.0, atol=1e-9)
    r = cli("map", *paths, "--out", out, "--report", rep, "--quiet", "--boundary-pairing", "1,1")
    assert r.returncode == 1 and "boundary pairing [1, 1]" in r.stderr


def test_intake_allow_boundary_lists_the_loops():
    V, F = frustum(1.0, 1.0, 1.5)
    with pytest.raises(surfmap.InputError, match="open"):
        surfmap.intake(V, F)
    it = surfmap.intake(V, F, allow_boundary=True)
    assert it["info"]["genus"] == 0 and it["info"]["num_boundary_loops"] == 2 and not it["flipped"]
    loops = it["boundary_loops"]
    assert [len(l) for l in loops] == [32, 32]
    assert np.allclose(V[loops[0], 2], 1.0) and np.allclose(V[loops[1], 2], 0.0)  # longest first
    # Every boundary edge (an edge of one face only) joins consecutive loop vertices.
    edges = {}
    for f in F:
        for k in range(3):
            e = tuple(sorted((f[k], f[(k + 1) % 3])))
            edges[e] = edges.get(e, 0) + 1
    boundary = {e for e, n in edges.items() if n == 1}
    along = {tuple(sorted((l[i], l[(i + 1) % len(l)]))) for l in loops for i in range(len(l))}
    assert boundary == along
    octahedron = (np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float),
                  np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]))
    closed = surfmap.intake(*octahedron, allow_boundary=True)
    assert closed["boundary_loops"] == [] and closed["info"]["genus"] == 0
