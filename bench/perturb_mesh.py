"""Used by the held-out sweep (docs/history/robustness.md, "Held-out sweep, 2026-12-03"):

    python3 bench/perturb_mesh.py IN.obj|IN.off OUT.obj NOISE K SEED

Perturbed copies of the closed real meshes: vertex noise (uniform in a ball of radius
NOISE x mean edge length) plus K collapsed edges (one end moved onto the other: two zero-area
faces each) and K faces made collinear (a corner moved onto the midpoint of its opposite side)."""
import random, sys, math, os
def read(path):
    V, F = [], []
    if path.endswith('.obj'):
        for line in open(path):
            t = line.split()
            if not t: continue
            if t[0] == 'v': V.append([float(x) for x in t[1:4]])
            elif t[0] == 'f': F.append([int(x.split('/')[0]) - 1 for x in t[1:]])
    else:
        toks = [l.split('#')[0].split() for l in open(path)]
        toks = [t for t in toks if t]
        i = 1 if toks[0][0].upper() == 'OFF' and len(toks[0]) == 1 else 0
        if i == 0: toks[0] = toks[0][1:]
        nv, nf = int(toks[i][0]), int(toks[i][1]); i += 1
        for k in range(nv): V.append([float(x) for x in toks[i + k][:3]])
        i += nv
        for k in range(nf): n = int(toks[i + k][0]); F.append([int(x) for x in toks[i + k][1:1 + n]])
    return V, F
def main(src, dst, noise, k, seed):
    rnd = random.Random(seed)
    V, F = read(src)
    edges = set()
    for f in F:
        for a in range(len(f)):
            u, v = f[a], f[(a + 1) % len(f)]
            edges.add((min(u, v), max(u, v)))
    mean = sum(math.dist(V[u], V[v]) for u, v in edges) / len(edges)
    for p in V:
        while True:
            d = [rnd.uniform(-1, 1) for _ in range(3)]
            if sum(x * x for x in d) <= 1: break
        for c in range(3): p[c] += noise * mean * d[c]
    touched = set()
    el = sorted(edges)
    n = 0
    while n < k:
        u, v = rnd.choice(el)
        if u in touched or v in touched: continue
        V[v] = list(V[u]); touched |= {u, v}; n += 1
    n = 0
    while n < k:
        f = rnd.choice(F)
        if len(f) != 3 or any(x in touched for x in f): continue
        a, b, c = f
        V[c] = [(V[a][i] + V[b][i]) / 2 for i in range(3)]; touched |= {a, b, c}; n += 1
    with open(dst, 'w') as out:
        for p in V: out.write('v %.17g %.17g %.17g\n' % tuple(p))
        for f in F: out.write('f ' + ' '.join(str(x + 1) for x in f) + '\n')
if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]))
