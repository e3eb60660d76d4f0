#include "surfmap/mesh/connectivity.h"

#include <algorithm>
#include <array>
#include <string>
#include <unordered_map>

#include "surfmap/error.h"

namespace surfmap {

Connectivity::Connectivity(const RowMatrixX3i& F, int num_vertices) : F_(F) {
  const int nf = static_cast<int>(F.rows());
  num_vertices_ = num_vertices >= 0 ? num_vertices : (nf ? F.maxCoeff() + 1 : 0);
  const int nh = 3 * nf;
  twin_.assign(nh, -1);
  edge_of_.assign(nh, -1);
  vertex_out_.assign(num_vertices_, -1);
  // Order halfedges by (min vertex, max vertex, halfedge) to pair twins
  // without hashing: a counting sort by min vertex (halfedges taken in index
  // order), then each vertex's short run (~6 halfedges) by insertion on
  // (max vertex, halfedge). O(#H) where a comparison sort of the keys was
  // O(#H log #H) and ran for every Connectivity (issue 19: 5% of a 50k map).
  std::vector<int> run_start(num_vertices_ + 1, 0);
  for (int h = 0; h < nh; ++h) {
    const int a = tail(h), b = head(h);
    if (a < 0 || a >= num_vertices_ || b < 0 || b >= num_vertices_)
      throw InputError("face " + std::to_string(h / 3) + " has a vertex index out of range");
    ++run_start[std::min(a, b) + 1];
    vertex_out_[a] = h;
  }
  for (int v = 0; v < num_vertices_; ++v) run_start[v + 1] += run_start[v];
  struct Key {
    int lo, hi, h;  ///< h's edge (smaller, larger vertex), h
    bool operator<(const Key& o) const { return hi != o.hi ? hi < o.hi : h < o.h; }  // within one lo
  };
  std::vector<Key> keys(nh);
  {
    std::vector<int> fill(run_start.begin(), run_start.end() - 1);
    for (int h = 0; h < nh; ++h) {
      const int a = tail(h), b = head(h);
      keys[fill[std::min(a, b)]++] = {std::min(a, b), std::max(a, b), h};
    }
  }
  for (int v = 0; v < num_vertices_; ++v) {
    const auto first = keys.begin() + run_start[v], last = keys.begin() + run_start[v + 1];
    if (last - first > 32) {  // a high-valence vertex: no quadratic insertion
      std::sort(first, last);
      continue;
    }
    for (auto i = first + 1; i < last; ++i)
      for (auto j = i; j > first && *j < *(j - 1); --j) std::iter_swap(j, j - 1);
  }
  edge_halfedge_.reserve(nh / 2);
  std::vector<std::array<int, 2>> ev;
  ev.reserve(nh / 2);
  for (size_t i = 0; i < keys.size();) {
    size_t j = i;
    while (j < keys.size() && keys[j].lo == keys[i].lo && keys[j].hi == keys[i].hi) ++j;
    const int h0 = keys[i].h;
    const int a = std::min(tail(h0), head(h0)), b = std::max(tail(h0), head(h0));
    // Built only on the error paths: this loop runs once per edge.
    auto name = [a, b] { return "edge (" + std::to_string(a) + ", " + std::to_string(b) + ")"; };
    if (j - i == 1)
      throw InputError(name() + " is a boundary edge (only one face, " + std::to_string(h0 / 3) +
                       "); open surfaces are not supported");
    if (j - i > 2)
      throw InputError(name() + " is non-manifold: it has " + std::to_string(j - i) + " faces");
    const int h1 = keys[i + 1].h;
    if (tail(h0) == tail(h1))
      throw InputError("faces " + std::to_string(h0 / 3) + " and " + std::to_string(h1 / 3) +
                       " are inconsistently oriented across " + name());
    const int e = static_cast<int>(ev.size());
    ev.push_back({a, b});
    twin_[h0] = h1;
    twin_[h1] = h0;
    edge_of_[h0] = edge_of_[h1] = e;
    edge_halfedge_.push_back(tail(h0) == a ? h0 : h1);
    i = j;
  }
  edge_vertices_.resize(static_cast<int>(ev.size()), 2);
  for (int e = 0; e < static_cast<int>(ev.size()); ++e) {
    edge_vertices_(e, 0) = ev[e][0];
    edge_vertices_(e, 1) = ev[e][1];
  }
  // Every vertex must be used, and its faces must form one fan (a disk).
  std::vector<int> fan_size(num_vertices_, 0);
  for (int h = 0; h < nh; ++h) ++fan_size[tail(h)];
  for (int v = 0; v < num_vertices_; ++v) {
    if (vertex_out_[v] < 0)
      throw InputError("vertex " + std::to_string(v) + " is not used by any face");
    int count = 0, h = vertex_out_[v];
    do {
      h = rotate_ccw(h);
      ++count;
    } while (h != vertex_out_[v] && count <= fan_size[v]);
    if (count != fan_size[v])
      throw InputError("vertex " + std::to_string(v) +
                       " is non-manifold: its faces form more than one fan");
  }
}

int Connectivity::find_halfedge(int a, int b) const {
  const int start = vertex_out_[a];
  int h = start;
  do {
    if (head(h) == b) return h;
    h = rotate_ccw(h);
  } while (h != start);
  return -1;
}

// Issue 19: counted first, so the vector is allocated once (pushing onto an
// empty one reallocated 4 times for valence 6; half a million calls in a
// 5k map, mostly allocation).
std::vector<int> Connectivity::outgoing(int v) const {
  std::vector<int> out(valence(v));
  int h = vertex_out_[v];
  for (int& o : out) {
    o = h;
    h = rotate_ccw(h);
  }
  return out;
}

int Connectivity::valence(int v) const {
  const int start = vertex_out_[v];
  int count = 0, h = start;
  do {
    ++count;
    h = rotate_ccw(h);
  } while (h != start);
  return count;
}

}  // namespace surfmap
