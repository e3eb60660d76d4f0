#include "surfmap/mesh/open_surface.h"

#include <algorithm>
#include <numeric>
#include <utility>

#include "surfmap/error.h"
#include "surfmap/mesh/mesh_io.h"

namespace surfmap {
namespace {

struct CornerUnion {
  std::vector<int> parent;
  explicit CornerUnion(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

}  // namespace

std::string OpenSurfaceTopology::describe() const {
  const int b = num_boundary_loops();
  if (b == 0) return "genus " + std::to_string(genus) + " (closed)";
  return "genus " + std::to_string(genus) + " with " + std::to_string(b) + " boundary loop" + (b == 1 ? "" : "s");
}

OpenSurfaceTopology open_surface_topology(const TriMesh& mesh) {
  const int nf = mesh.num_faces(), nv = mesh.num_vertices();
  // Directed halfedges (tail, head) -> corner index 3f+k (corner at the tail).
  std::vector<std::pair<long long, int>> directed(3 * nf);
  auto key = [nv](int a, int b) { return static_cast<long long>(a) * nv + b; };
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) directed[3 * f + k] = {key(mesh.F(f, k), mesh.F(f, (k + 1) % 3)), 3 * f + k};
  std::sort(directed.begin(), directed.end());
  auto find_halfedge = [&](int a, int b) {
    auto it = std::lower_bound(directed.begin(), directed.end(), std::make_pair(key(a, b), -1));
    return (it != directed.end() && it->first == key(a, b)) ? it->second : -1;
  };
  // Corners around a vertex are one fan when faces sharing an edge at the
  // vertex are united: corner (f,k) at v = F(f,k) has edges v->F(f,k+1) and
  // F(f,k+2)->v; the twin of v->w is w->v in the neighbouring face, whose
  // corner at v is the next corner of that face.
  CornerUnion fans(3 * nf);
  std::vector<int> boundary_out(nv, -1), boundary_count(nv, 0);
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.F(f, k), w = mesh.F(f, (k + 1) % 3);
      const int twin = find_halfedge(w, v);
      if (twin < 0) {
        boundary_out[v] = 3 * f + k;
        ++boundary_count[v];
      } else {
        fans.unite(3 * f + k, 3 * (twin / 3) + (twin % 3 + 1) % 3);
      }
    }
  std::vector<int> fan_count(nv, 0);
  for (int c = 0; c < 3 * nf; ++c)
    if (fans.find(c) == c) ++fan_count[mesh.F(c / 3, c % 3)];
  for (int v = 0; v < nv; ++v) {
    if (boundary_count[v] > 1)
      throw InputError("non-manifold boundary vertex " + std::to_string(v) + ": it lies on the boundary " +
                       std::to_string(boundary_count[v]) +
                       " times (two boundary loops touch there, a bowtie); split the vertex or fill the gap");
    if (fan_count[v] > 1)
      throw InputError("non-manifold vertex " + std::to_string(v) + ": its faces form " +
                       std::to_string(fan_count[v]) + " separate fans (a bowtie)");
  }

  OpenSurfaceTopology top;
  std::vector<char> visited(nv, 0);
  for (int start = 0; start < nv; ++start) {
    if (boundary_out[start] < 0 || visited[start]) continue;
    std::vector<int> loop;
    double length = 0;
    for (int v = start; !visited[v];) {
      visited[v] = 1;
      loop.push_back(v);
      const int h = boundary_out[v];
      const int w = mesh.F(h / 3, (h % 3 + 1) % 3);
      length += (mesh.V.row(w) - mesh.V.row(v)).norm();
      v = w;
    }
    top.boundary_loops.push_back(std::move(loop));
    top.boundary_lengths.push_back(length);
  }
  std::vector<int> order(top.boundary_loops.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return top.boundary_lengths[a] > top.boundary_lengths[b]; });
  OpenSurfaceTopology sorted;
  for (int i : order) {
    sorted.boundary_loops.push_back(top.boundary_loops[i]);
    sorted.boundary_lengths.push_back(top.boundary_lengths[i]);
  }
  // Edges: interior ones counted twice among the directed halfedges.
  int boundary_edges = 0;
  for (int v = 0; v < nv; ++v) boundary_edges += boundary_count[v];
  const int num_edges = (3 * nf - boundary_edges) / 2 + boundary_edges;
  sorted.euler_characteristic = nv - num_edges + nf;
  sorted.genus = (2 - sorted.euler_characteristic - sorted.num_boundary_loops()) / 2;
  return sorted;
}

OpenIntakeResult intake_open(const PolygonSoup& soup) {
  IntakeOptions options;
  options.allow_boundary = true;
  OpenIntakeResult r;
  r.intake = intake(soup, options);
  r.topology = open_surface_topology(r.intake.mesh);
  return r;
}

OpenIntakeResult load_open_mesh(const std::string& path) {
  const PolygonSoup soup = read_polygon_soup(path);
  try {
    return intake_open(soup);
  } catch (const InputError& e) {
    throw InputError("'" + path + "': " + e.what());
  }
}

void check_same_open_topology(const OpenSurfaceTopology& source, const OpenSurfaceTopology& target) {
  if (source.genus != target.genus || source.num_boundary_loops() != target.num_boundary_loops())
    throw InputError("the source has " + source.describe() + " but the target has " + target.describe() +
                     "; both surfaces must have the same genus and number of boundary loops");
}

}  // namespace surfmap
