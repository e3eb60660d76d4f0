"""How far a landmark can be moved from where the map without landmarks puts it before the
map is refused (docs/method.md §2.10 landmarks; src/map/landmarks.h). One table row per distance.

  SURFMAP_PYTHONPATH=build/python /usr/bin/python3 bench/bench_landmark_reach.py g1|g2|real [HOPS,...]

g1: torus_of_revolution-like grid tori (1, .45, 64x34) -> (1.4, .5, 64x34), with an anchor landmark
at vertex 0's free image (one genus-1 landmark alone is only a translation); g2:
n_hole_torus(2, 20) -> vase(24); real: g2_double-torus_gpjs -> g2_eight_summer from shared/meshes
(development only; SURFMAP_MESHES=/path/to/shared/meshes, default <repo>/../shared/meshes). The moved landmark's target walks along a shortest edge path towards the target
vertex farthest from its free image; 'dist' is the 3D distance of the target vertex from the free
image in mean target edge lengths and as a fraction of the target's bounding-box diagonal.
"""
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.environ.get("SURFMAP_PYTHONPATH", os.path.join(os.path.dirname(__file__), "..", "build", "python")))
# the Python tests' mesh helpers (torus grids, adjacency, shortest paths), shared
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "native", "tests", "python"))
import surfmap as sm  # noqa: E402
from mesh_helpers import adjacency, mean_edge_length, nearest_vertex, shortest_path, torus  # noqa: E402


def load(p):
    m = sm.load_mesh(p)
    return np.asarray(m["V"]), np.asarray(m["F"])


which = sys.argv[1]
if which == "g1":
    (Va, Fa), (Vb, Fb) = torus(1.0, 0.45, 64, 34), torus(1.4, 0.5, 64, 34, 2)
    s_list = [34 * 20 + 5]; anchor = True
elif which == "g2":
    (Va, Fa), (Vb, Fb) = sm.shapes.n_hole_torus(2, 20, True), sm.shapes.vase(24, True)
    s_list = [len(Va) // 3]; anchor = False
else:
    meshes = os.environ.get("SURFMAP_MESHES", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "meshes"))
    (Va, Fa), (Vb, Fb) = (load(os.path.join(meshes, "g2_double-torus_gpjs.obj")),
                          load(os.path.join(meshes, "g2_eight_summer.off")))
    s_list = [len(Va) // 3]; anchor = False
print(which, len(Va), len(Vb))
free = sm.surface_map(Va, Fa, Vb, Fb)
pos = free["forward"]["position"]
h = mean_edge_length(Vb, Fb)
diag = np.linalg.norm(Vb.max(0) - Vb.min(0))
nb = adjacency(Fb, len(Vb))
s = s_list[0]
t0 = nearest_vertex(Vb, pos[s])
far = int(np.argmax(((Vb - Vb[t0]) ** 2).sum(1)))   # walk towards the farthest vertex
pth = shortest_path(nb, t0, far)
steps = [int(x) for x in sys.argv[2].split(",")] if len(sys.argv) > 2 else [1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40]
print(f"mean target edge {h:.4g}, diagonal {diag:.4g}, free E {free['energy']['final']:.6g}, path length {len(pth)}")
for k in steps:
    if k >= len(pth): break
    t = pth[k]
    lm = ([(0, nearest_vertex(Vb, pos[0]))] if anchor else []) + [(s, t)]
    d = np.linalg.norm(Vb[t] - pos[s])
    t1 = time.time()
    try:
        r = sm.surface_map(Va, Fa, Vb, Fb, landmarks=lm)
        hit = max(np.linalg.norm(r["forward"]["position"][a] - Vb[b]) for a, b in lm)
        msg = (f"OK E {r['energy']['final']:.6g} flips {r['flipped_triangles']} hit {hit:.1e} D' {r['distortion']['mean']:.4g}/{r['distortion']['max']:.4g}"
               + (f" {r.get('landmark_method', '')}; steps {r.get('landmark_steps')} rings {r.get('landmark_rings')} solves {r.get('landmark_solves')} held {r.get('landmark_held_vertices')}" if 'landmark_rings' in r else ""))
    except sm.Error as e:
        msg = f"FAIL {type(e).__name__}: {str(e)[:300]}"
    print(f"hops {k:3d}  dist {d / h:6.2f} edges = {d / diag:.3f} diag  {time.time() - t1:5.1f}s  {msg}", flush=True)
