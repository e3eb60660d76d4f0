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


namespace surfmap {
std::vector<int> path_from_region_centre(const CoarseSource& cs, const Connectivity& fc, int v) {
  std::vector<int> path;
  for (int h = cs.parent_halfedge[v]; h >= 0; h = cs.parent_halfedge[fc.tail(h)]) path.push_back(h);
  std::reverse(path.begin(), path.end());
  return path;
}

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
  auto length = [&](int h) { return (fine.V.row(fc.head(h)) - fine.V.row(fc.tail(h))).norm(); };
  std::vector<double> dist(nv, std::numeric_limits<double>::infinity());
  std::vector<int> region(nv, -1), parent(nv, -1);
  using Item = std::pair<double, int>;
  std::vector<int> seeds;
  std::vector<int> taken;  // the vertices the last grow() took
  auto grow = [&](int seed) {
    taken.clear();
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> pq;
    const int c = static_cast<int>(seeds.size());
    seeds.push_back(seed);
    dist[seed] = 0, region[seed] = c, parent[seed] = -1;
    pq.push({0.0, seed});
    while (!pq.empty()) {
      const auto [d, v] = pq.top();
      pq.pop();
      if (d > dist[v]) continue;
      taken.push_back(v);
      for (int h : fc.outgoing(v)) {
        const int w = fc.head(h);
        const double dw = d + length(h);
        if (dw < dist[w]) {
          dist[w] = dw, region[w] = c, parent[w] = h;
          pq.push({dw, w});
        }
      }
    }
  };
  std::unique_ptr<Connectivity> cc;
  std::vector<std::array<int, 3>> faces;
  for (int want = goal, round = 0;; want *= 2, ++round) {
    if (want * 2 > nv) {
      cs.why = "no valid coarse copy below half the source's vertices";
      return cs;
    }
    if (seeds.empty()) grow(0);
    // Farthest point first: a max-heap of (distance, vertex), stale entries skipped.
    std::priority_queue<Item> far;
    for (int v = 0; v < nv; ++v) far.push({dist[v], v});
    while (static_cast<int>(seeds.size()) < want && !far.empty()) {
      const auto [d, v] = far.top();
      far.pop();
      if (d != dist[v] || d == 0) continue;
      grow(v);
      // Vertices whose distance dropped are re-queued lazily: push the
      // current value of every vertex the new region took.
      if (far.size() > static_cast<size_t>(4 * nv)) {
        far = {};
        for (int u = 0; u < nv; ++u) far.push({dist[u], u});
      } else {
        for (int u : taken) far.push({dist[u], u});
      }
    }
    // Dual faces (one per distinct triple; a triple seen twice with the same
    // orientation is the same face).
    faces.clear();
    std::unordered_map<long long, int> seen;
    const long long ns = static_cast<long long>(seeds.size());
    bool bad = false;
    for (int f = 0; f < fine.num_faces() && !bad; ++f) {
      std::array<int, 3> t{region[fine.F(f, 0)], region[fine.F(f, 1)], region[fine.F(f, 2)]};
      if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) continue;
      const int m = static_cast<int>(std::min_element(t.begin(), t.end()) - t.begin());
      std::rotate(t.begin(), t.begin() + m, t.end());  // smallest first, orientation kept
      const long long key = (t[0] * ns + t[1]) * ns + t[2];
      const long long flipped = (t[0] * ns + t[2]) * ns + t[1];
      if (seen.count(flipped)) bad = true;
      if (seen.emplace(key, f).second) faces.push_back(t);
    }
    if (!bad) {
      RowMatrixX3i F(static_cast<int>(faces.size()), 3);
      for (size_t f = 0; f < faces.size(); ++f)
        for (int k = 0; k < 3; ++k) F(static_cast<int>(f), k) = faces[f][k];
      try {
        cc = std::make_unique<Connectivity>(F, static_cast<int>(seeds.size()));
        if (cc->euler_characteristic() != fc.euler_characteristic()) cc.reset();
      } catch (const std::exception&) {
        cc.reset();
      }
    }
    if (cc) break;
    if (round >= 1) {
      cs.why = "the Voronoi dual of " + std::to_string(seeds.size()) + " samples is not a surface of the source's genus";
      return cs;
    }
  }
  const int nc = static_cast<int>(seeds.size());
  cs.fine_vertex = seeds;
  cs.mesh.V.resize(nc, 3);
  for (int c = 0; c < nc; ++c) cs.mesh.V.row(c) = fine.V.row(seeds[c]);
  cs.mesh.F = cc->faces();
  cs.region = region;
  cs.parent_halfedge = parent;

  // Paths of the coarse edges: through the shortest fine edge joining the
  // two regions (tree path, edge, tree path), else a Dijkstra search.
  std::unordered_map<long long, std::pair<double, int>> bridge;  // (region a, region b) -> (cost, fine halfedge a->b)
  for (int h = 0; h < fc.num_halfedges(); ++h) {
    const int a = cs.region[fc.tail(h)], b = cs.region[fc.head(h)];
    if (a == b) continue;
    const double cost = dist[fc.tail(h)] + length(h) + dist[fc.head(h)];
    const long long key = static_cast<long long>(a) * nc + b;
    auto it = bridge.find(key);
    if (it == bridge.end() || cost < it->second.first) bridge[key] = {cost, h};
  }
  cs.edge_path.resize(cc->num_edges());
  for (int e = 0; e < cc->num_edges(); ++e) {
    const int h = cc->edge_halfedge(e);
    const int a = cc->tail(h), b = cc->head(h);
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
    // Regions not adjacent (rare): shortest fine path between the two vertices.
    const int s = cs.fine_vertex[a], t = cs.fine_vertex[b];
    std::unordered_map<int, double> dd{{s, 0.0}};
    std::unordered_map<int, int> via;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> q;
    q.push({0.0, s});
    bool found = false;
    while (!q.empty()) {
      const auto [d, v] = q.top();
      q.pop();
      if (d > dd[v]) continue;
      if (v == t) {
        found = true;
        break;
      }
      if (dd.size() > 20000) break;
      for (int g : fc.outgoing(v)) {
        const int w = fc.head(g);
        const double dw = d + length(g);
        auto f = dd.find(w);
        if (f == dd.end() || dw < f->second) dd[w] = dw, via[w] = g, q.push({dw, w});
      }
    }
    if (!found) {
      cs.why = "no fine path found for coarse edge " + std::to_string(e);
      return cs;
    }
    for (int v = t; v != s; v = fc.tail(via[v])) path.push_back(via[v]);
    std::reverse(path.begin(), path.end());
  }
  cs.ok = true;
  cs.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return cs;
}

}  // namespace surfmap
