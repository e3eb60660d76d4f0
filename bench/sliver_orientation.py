"""Where `surfmap verify` finds negative images (docs/verification.md, "Sliver images"):

    python3 bench/sliver_orientation.py SRC.off|obj DST.off|obj CORR.txt

For each source triangle whose chord image is negative (the certificate's orientation test:
the signed area of the chord triangle of its corners' images against the mean of the target's
interpolated area-weighted vertex normals there), the faces holding the three image points are
developed isometrically into one plane (breadth-first over the target's faces from one corner's
face, each face unfolded across the shared edge with its 3D edge lengths) and the orientation of
the three points measured there, from each corner's face in turn. Negative from every root:
the images are reversed on the target surface itself, not only in the chord. Prints one line per
triangle (its smallest source angle, the developed relative area from the first corner) and the
counts by the three roots' signs. Reads the meshes as given (no intake: give closed, outward
oriented, triangulated meshes, as `surfmap map` read them)."""
import collections
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import perturb_mesh  # noqa: E402  (its mesh reader)


def read_mesh(path):
    """Vertices and triangles as arrays (perturb_mesh.read, beside this file)."""
    V, F = perturb_mesh.read(path)
    if any(len(f) != 3 for f in F): sys.exit(f'{path}: only triangle meshes are read here')
    return np.array(V), np.array(F)


def main(src, dst, corr):
    S, SF = read_mesh(src)
    T, TF = read_mesh(dst)
    rows = [l.split() for l in open(corr) if l.strip() and not l.startswith('#')]
    face = np.array([int(r[0]) for r in rows[:len(S)]])
    bary = np.array([[float(x) for x in r[1:4]] for r in rows[:len(S)]])
    P = np.einsum('vk,vkd->vd', bary, T[TF[face]])
    fn = np.cross(T[TF[:, 1]] - T[TF[:, 0]], T[TF[:, 2]] - T[TF[:, 0]])
    vn = np.zeros_like(T)
    for k in range(3): np.add.at(vn, TF[:, k], fn)
    n = np.einsum('vk,vkd->vd', bary, vn[TF[face]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    across = collections.defaultdict(list)  # directed edge -> the face holding it
    for f, (a, b, c) in enumerate(TF):
        for u, v in ((a, b), (b, c), (c, a)): across[(u, v)].append(f)

    def develop(root, wanted, max_depth=12):
        a, b, c = TF[root]
        e1 = (T[b] - T[a]) / np.linalg.norm(T[b] - T[a])
        nn = np.cross(T[b] - T[a], T[c] - T[a])
        e2 = np.cross(nn / np.linalg.norm(nn), e1)
        pos = {root: {v: np.array([(T[v] - T[a]) @ e1, (T[v] - T[a]) @ e2]) for v in (a, b, c)}}
        queue, need = collections.deque([(root, 0)]), set(wanted) - {root}
        while queue and need:
            f, depth = queue.popleft()
            if depth >= max_depth: continue
            a, b, c = TF[f]
            for u, v in ((a, b), (b, c), (c, a)):
                for g in across[(v, u)]:
                    if g in pos: continue
                    w = [x for x in TF[g] if x != u and x != v][0]
                    pu, pv = pos[f][u], pos[f][v]
                    L = np.linalg.norm(T[v] - T[u])
                    du, dv = np.linalg.norm(T[w] - T[u]), np.linalg.norm(T[w] - T[v])
                    x = (du * du - dv * dv + L * L) / (2 * L)
                    y = np.sqrt(max(du * du - x * x, 0.0))
                    ex = (pv - pu) / np.linalg.norm(pv - pu)
                    pos[g] = {u: pu, v: pv, w: pu + x * ex - y * np.array([-ex[1], ex[0]])}
                    need.discard(g)
                    queue.append((g, depth + 1))
        return pos

    def smallest_angle(X):
        out = []
        for k in range(3):
            u, v = X[(k + 1) % 3] - X[k], X[(k + 2) % 3] - X[k]
            out.append(np.degrees(np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v), -1, 1))))
        return min(out)

    counts, negative = collections.Counter(), 0
    for t, (i, j, k) in enumerate(SF):
        nb = n[i] + n[j] + n[k]
        h = max(np.linalg.norm(P[j] - P[i]), np.linalg.norm(P[k] - P[j]), np.linalg.norm(P[i] - P[k]))
        if 0.5 * (nb / np.linalg.norm(nb)) @ np.cross(P[j] - P[i], P[k] - P[i]) >= -1e-12 * h * h: continue
        negative += 1
        signs, first = '', float('nan')
        for r in (i, j, k):
            pos = develop(face[r], [face[i], face[j], face[k]])
            if not all(face[x] in pos for x in (i, j, k)):
                signs += '?'
                continue
            A, B, C = (sum(bary[x][m] * pos[face[x]][TF[face[x]][m]] for m in range(3)) for x in (i, j, k))
            area = 0.5 * np.cross(B - A, C - A)
            if r == i: first = area / (h * h)
            signs += '+' if area > 0 else '-'
        counts[signs] += 1
        print(f'triangle {t}: smallest source angle {smallest_angle(S[[i, j, k]]):.3f} deg, '
              f'developed relative area {first:.3e}, signs by root {signs}')
    print(f'{negative} negative chord images; developed signs from the three roots: {dict(counts)}')


if __name__ == '__main__':
    if len(sys.argv) != 4: sys.exit(__doc__)
    main(*sys.argv[1:])
