#include "surfmap/map/coarse_source.h"

#include <algorithm>
#include <array>
#include <memory>
#include <string>
#include <chrono>
#include <cmath>
#include <limits>
#include <queue>
#include <unordered_map>

#include "../seconds_since.h"
#include "../mesh/dijkstra.h"
#include "../mesh/region_dual.h"
#include "surfmap/error.h"

namespace surfmap {
std::vector<int> path_from_region_centre(const CoarseSource& cs, const Connectivity& fc, int v) {
  std::vector<int> path;
  for (int h = cs.parent_halfedge[v]; h >= 0; h = cs.parent_halfedge[fc.tail(h)]) path.push_back(h);
  std::reverse(path.begin(), path.end());
  return path;
}

namespace {

using Item = std::pair<double, int>;

/// Geodesic Voronoi regions of farthest-point samples (Dijkstra over the
/// fine edges' lengths): per fine vertex (#V) the distance to, the region of
/// and the tree parent halfedge from its nearest seed.
struct VoronoiSampling {
  const TriMesh& fine;
  const Connectivity& fc;
  const int nv;
  detail::DijkstraResult tree;  // distance and parent_arc: from the nearest seed
  std::vector<int> region;
  std::vector<int> seeds;

  VoronoiSampling(const TriMesh& fine_mesh, const Connectivity& fine_conn)
      : fine(fine_mesh), fc(fine_conn), nv(fine_mesh.num_vertices()), region(nv, -1) {}

  double length(int h) const { return (fine.V.row(fc.head(h)) - fine.V.row(fc.tail(h))).norm(); }
  auto arcs() const {
    return detail::rotation_arcs(fc, [this](int h) { return length(h); });
  }
  /// The vertices the last grow() took.
  const std::vector<int>& taken() const { return tree.settled; }

  /// A new seed and its region: the vertices now closer to it than to the
  /// earlier seeds (listed in taken()).
  void grow(int seed) {
    const int c = static_cast<int>(seeds.size());
    seeds.push_back(seed);
    detail::DijkstraOptions nearer;
    nearer.keep_distances = true;
    detail::dijkstra(nv, arcs(), {seed}, nearer, tree);
    for (int v : tree.settled) region[v] = c;
  }

  /// Seeds added farthest point first until there are `want`; `keep_going`
  /// (CoarseSourceOptions) every 64 seeds.
  void sample_up_to(int want, const std::function<bool(double)>& keep_going) {
    if (seeds.empty()) grow(0);
    // Farthest point first: a max-heap of (distance, vertex), stale entries skipped.
    std::priority_queue<Item> far;
    const std::vector<double>& dist = tree.distance;
    for (int v = 0; v < nv; ++v) far.push({dist[v], v});
    while (static_cast<int>(seeds.size()) < want && !far.empty()) {
      const auto [d, v] = far.top();
      far.pop();
      if (d != dist[v] || d == 0) continue;
      grow(v);
      if (keep_going && seeds.size() % 64 == 0 && !keep_going(static_cast<double>(seeds.size()) / want))
        throw Cancelled("the source's coarse copy cancelled");
      // Vertices whose distance dropped are re-queued lazily: push the
      // current value of every vertex the new region took.
      if (far.size() > static_cast<size_t>(4 * nv)) {
        far = {};
        for (int u = 0; u < nv; ++u) far.push({dist[u], u});
      } else {
        for (int u : taken()) far.push({dist[u], u});
      }
    }
  }
};

/// Regions not adjacent (rare): the shortest fine path from vertex s to t
/// (halfedges in order, appended to `path`) by a Dijkstra search of at most
/// ~20000 vertices (in `search`, kept between calls). False when t was not
/// reached.
bool shortest_fine_path(const VoronoiSampling& vs, int s, int t, detail::DijkstraResult& search,
                        std::vector<int>& path) {
  detail::DijkstraOptions nearby;
  nearby.target = t;
  nearby.max_reached = 20000;
  nearby.want_parent_nodes = true;
  detail::dijkstra(vs.nv, vs.arcs(), {s}, nearby, search);
  if (!search.reached_target) return false;
  const std::vector<int> back = detail::arcs_back_to_source(search, t);
  path.insert(path.end(), back.rbegin(), back.rend());
  return true;
}

/// cs.edge_path for the coarse connectivity cc: through the shortest fine
/// edge joining the two regions (tree path, edge, tree path), else a
/// Dijkstra search. False (cs.why set) when that search fails.
bool coarse_edge_paths(const VoronoiSampling& vs, const Connectivity& cc, CoarseSource& cs) {
  const Connectivity& fc = vs.fc;
  const std::vector<double>& dist = vs.tree.distance;
  const int nc = static_cast<int>(vs.seeds.size());
  std::unordered_map<long long, std::pair<double, int>> bridge;  // (region a, region b) -> (cost, fine halfedge a->b)
  for (int h = 0; h < fc.num_halfedges(); ++h) {
    const int a = cs.region[fc.tail(h)], b = cs.region[fc.head(h)];
    if (a == b) continue;
    const double cost = dist[fc.tail(h)] + vs.length(h) + dist[fc.head(h)];
    const long long key = static_cast<long long>(a) * nc + b;
    auto it = bridge.find(key);
    if (it == bridge.end() || cost < it->second.first) bridge[key] = {cost, h};
  }
  cs.edge_path.resize(cc.num_edges());
  detail::DijkstraResult search;  // of shortest_fine_path
  for (int e = 0; e < cc.num_edges(); ++e) {
    const int h = cc.edge_halfedge(e);
    const int a = cc.tail(h), b = cc.head(h);
    auto it = bridge.find(static_cast<long long>(a) * nc + b);
    std::vector<int>& path = cs.edge_path[e];
    if (it != bridge.end()) {
      const int x = it->second.second;
      path = path_from_region_centre(cs, fc, fc.tail(x));
      path.push_back(x);
      std::vector<int> back = path_from_region_centre(cs, fc, fc.head(x));
      for (auto r = back.rbegin(); r != back.rend(); ++r) path.push_back(fc.twin(*r));
      continue;
    }
    if (!shortest_fine_path(vs, cs.fine_vertex[a], cs.fine_vertex[b], search, path)) {
      cs.why = "no fine path found for coarse edge " + std::to_string(e);
      return false;
    }
  }
  return true;
}

}  // namespace

CoarseSource coarse_source(const TriMesh& fine, const Connectivity& fc, const CoarseSourceOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  CoarseSource cs;
  const int nv = fine.num_vertices();
  const int goal = std::max(options.target_vertices, 4);
  if (nv <= goal) {
    cs.why = "the source has no more vertices than the coarse copy would";
    return cs;
  }

  // Seeds by farthest-point sampling over the fine edges' lengths (each new
  // seed's Dijkstra only visits the vertices it is now closest to), then the
  // dual of their geodesic Voronoi regions: a coarse face for every fine
  // triangle whose corners lie in three different regions. For a sampling
  // dense against the surface's features the regions are disks meeting like
  // a triangulation's dual, and the dual is a closed manifold of the same
  // genus; that is checked, never assumed (and a denser sampling tried once).
  // (OpenMesh's Decimater was the first choice: 3.2 s to go from 50k to 3k
  // vertices, 26 s from 174k; this costs a few Dijkstra passes.)
  VoronoiSampling vs(fine, fc);
  std::unique_ptr<Connectivity> cc;
  std::vector<std::array<int, 3>> faces;
  for (int want = goal, round = 0;; want *= 2, ++round) {
    if (want * 2 > nv) {
      cs.why = "no valid coarse copy below half the source's vertices";
      return cs;
    }
    vs.sample_up_to(want, options.keep_going);
    if (detail::region_dual_faces(fine.F, vs.region, static_cast<int>(vs.seeds.size()), faces))
      cc = detail::region_dual_surface(faces, static_cast<int>(vs.seeds.size()), fc.euler_characteristic());
    if (cc) break;
    if (round >= 1) {
      cs.why = "the Voronoi dual of " + std::to_string(vs.seeds.size()) + " samples is not a surface of the source's genus";
      return cs;
    }
  }
  cs.fine_vertex = vs.seeds;
  cs.mesh = detail::region_dual_mesh(fine, vs.seeds, *cc);
  cs.region = vs.region;
  cs.parent_halfedge = vs.tree.parent_arc;

  if (!coarse_edge_paths(vs, *cc, cs)) return cs;
  cs.ok = true;
  cs.seconds = detail::seconds_since(t0);
  return cs;
}

}  // namespace surfmap
