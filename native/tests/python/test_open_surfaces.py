"""`surfmap map` on open surfaces (issue 16, docs/open_surfaces.md): disks and
annuli are mapped and written like closed maps; other open pairs and mixed
open/closed pairs are refused with one line naming (g, b) of both."""
import json

import numpy as np

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
    """A spherical cap (disk) as a polar grid with a centre vertex."""
    V = [[0.0, 0.0, 1.0]]
    F = []
    for k in range(1, n + 1):
        phi = 0.5 * np.pi * k / n
        for j in range(6 * n):
            t = 2 * np.pi * j / (6 * n)
            V.append([np.sin(phi) * np.cos(t), np.sin(phi) * np.sin(t), np.cos(phi)])
    ring = lambda k, j: 1 + (k - 1) * 6 * n + j % (6 * n)
    for j in range(6 * n):
        F.append([0, ring(1, j), ring(1, j + 1)])
    for k in range(1, n):
        for j in range(6 * n):
            F += [[ring(k, j), ring(k + 1, j), ring(k + 1, j + 1)], [ring(k, j), ring(k + 1, j + 1), ring(k, j + 1)]]
    return np.array(V), np.array(F, int)


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
    assert len(lines) == len(src[0])
    for line in lines:
        face, *bary = line.split()
        assert 0 <= int(face) < len(dst[1])
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


def test_unsupported_and_mismatched_open_pairs_are_refused(tmp_path, cli):
    square = lambda s, t: (s, t, 0.0)
    three_loops = grid(12, 12, square, holes={(3, 3), (8, 8)})  # genus 0, 3 boundary loops
    r, out, _, _ = run_map(cli, tmp_path, three_loops, three_loops)
    assert r.returncode == 1
    assert "genus 0 with 3 boundary loops are not supported yet" in r.stderr
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
