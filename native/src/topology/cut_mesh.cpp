#include "surfmap/topology/cut_mesh.h"

#include <algorithm>
#include <string>
#include <utility>

#include "surfmap/error.h"

namespace surfmap {

CutMesh cut_mesh_along_edges(const TriMesh& mesh, const Connectivity& conn,
                             const std::vector<char>& cut_edge) {
  const int nv = conn.num_vertices(), nf = conn.num_faces();
  if (static_cast<int>(cut_edge.size()) != conn.num_edges())
    throw InputError("cut_mesh: cut_edge has " + std::to_string(cut_edge.size()) +
                     " entries, the mesh has " + std::to_string(conn.num_edges()) + " edges");
  CutMesh out;
  // corner_vertex[h]: the cut vertex used by face(h) at tail(h).
  std::vector<int> corner_vertex(conn.num_halfedges(), -1);
  for (int v = 0; v < nv; ++v) {
    // Outgoing halfedges counter-clockwise; face(o_i) lies between o_i and
    // o_{i+1}. A new wedge (a new copy of v) starts at every cut edge.
    const std::vector<int> ring = conn.outgoing(v);
    const int d = static_cast<int>(ring.size());
    int start = 0;
    bool any_cut = false;
    for (int i = 0; i < d; ++i)
      if (cut_edge[conn.edge(ring[i])]) {
        start = i;
        any_cut = true;
        break;
      }
    int copy = -1;
    for (int j = 0; j < d; ++j) {
      const int o = ring[(start + j) % d];
      if (j == 0 || (any_cut && cut_edge[conn.edge(o)])) {
        copy = static_cast<int>(out.original_vertex.size());
        out.original_vertex.push_back(v);
      }
      corner_vertex[o] = copy;
    }
  }
  const int ncut = static_cast<int>(out.original_vertex.size());
  out.mesh.V.resize(ncut, 3);
  for (int i = 0; i < ncut; ++i) out.mesh.V.row(i) = mesh.V.row(out.original_vertex[i]);
  out.mesh.F.resize(nf, 3);
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) out.mesh.F(f, k) = corner_vertex[3 * f + k];

  // Count edges and trace the boundary from the cut mesh's own faces (an
  // independent check of the wedge bookkeeping above).
  std::vector<std::pair<long long, int>> keys;
  keys.reserve(3 * nf);
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = out.mesh.F(f, k), b = out.mesh.F(f, (k + 1) % 3);
      keys.push_back({static_cast<long long>(std::min(a, b)) * ncut + std::max(a, b),
                      3 * f + k});
    }
  std::sort(keys.begin(), keys.end());
  std::vector<int> boundary_next(ncut, -1);
  int num_edges = 0, num_boundary = 0;
  for (size_t i = 0; i < keys.size();) {
    size_t j = i;
    while (j < keys.size() && keys[j].first == keys[i].first) ++j;
    ++num_edges;
    if (j - i == 1) {
      const int h = keys[i].second, f = h / 3, k = h % 3;
      const int a = out.mesh.F(f, k), b = out.mesh.F(f, (k + 1) % 3);
      if (boundary_next[a] != -1)
        throw SolveError("cut_mesh: cut vertex " + std::to_string(a) +
                         " has two outgoing boundary edges");
      boundary_next[a] = b;
      ++num_boundary;
    }
    i = j;
  }
  out.num_edges = num_edges;
  out.euler_characteristic = ncut - num_edges + nf;
  std::vector<char> seen(ncut, 0);
  for (int v = 0; v < ncut; ++v) {
    if (boundary_next[v] < 0 || seen[v]) continue;
    std::vector<int> loop;
    int w = v;
    while (!seen[w]) {
      seen[w] = 1;
      loop.push_back(w);
      w = boundary_next[w];
      if (w < 0) throw SolveError("cut_mesh: open boundary chain");
    }
    out.boundary_loops.push_back(std::move(loop));
  }
  return out;
}

CutMesh cut_mesh(const TriMesh& mesh, const std::vector<std::vector<int>>& loops) {
  const Connectivity conn(mesh.F, mesh.num_vertices());
  std::vector<char> cut(conn.num_edges(), 0);
  for (size_t k = 0; k < loops.size(); ++k)
    for (size_t i = 0; i + 1 < loops[k].size(); ++i) {
      const int a = loops[k][i], b = loops[k][i + 1];
      if (a < 0 || a >= conn.num_vertices() || b < 0 || b >= conn.num_vertices())
        throw InputError("cut_mesh: loop " + std::to_string(k) + " has a vertex out of range");
      const int h = conn.find_halfedge(a, b);
      if (h < 0)
        throw InputError("cut_mesh: loop " + std::to_string(k) + " steps from vertex " +
                         std::to_string(a) + " to " + std::to_string(b) + ", which is not an edge");
      cut[conn.edge(h)] = 1;
    }
  return cut_mesh_along_edges(mesh, conn, cut);
}

}  // namespace surfmap
