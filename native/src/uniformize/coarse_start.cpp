// Multilevel start of the Ricci flow (uniformize/coarse_start.h).
#include "surfmap/uniformize/coarse_start.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "../mesh/dijkstra.h"
#include "../mesh/region_dual.h"
#include "../seconds_since.h"
#include "surfmap/error.h"

namespace surfmap {

namespace {

using detail::seconds_since;

/// The mesh's vertex graph once, as offsets into one array (CSR), with the
/// 3D lengths of its edges.
struct VertexGraph {
  std::vector<int> start, next;
  std::vector<double> length;
  VertexGraph(const TriMesh& mesh, const Connectivity& conn) {
    const int nv = conn.num_vertices();
    start.assign(nv + 1, 0);
    next.reserve(static_cast<size_t>(conn.num_halfedges()));
    length.reserve(static_cast<size_t>(conn.num_halfedges()));
    for (int v = 0; v < nv; ++v) {
      // The outgoing halfedges in Connectivity::outgoing's order, walked in
      // place (no list per vertex).
      const int first = conn.vertex_halfedge(v);
      int h = first;
      do {
        const int w = conn.head(h);
        next.push_back(w);
        length.push_back((mesh.V.row(w) - mesh.V.row(v)).norm());
        h = conn.rotate_ccw(h);
      } while (h != first);
      start[v + 1] = static_cast<int>(next.size());
    }
  }
};

/// A coarse copy for the start. Seeds: vertices in index order that are
/// more than `radius` edges from every earlier seed (breadth-first balls);
/// regions: one multi-source Dijkstra over the 3D edge lengths; the coarse
/// faces: the regions' dual (mesh/region_dual.h, shared with the ranking's
/// copy), sorted, used only when that is a closed oriented manifold of the
/// mesh's Euler characteristic (coarse_copy returns false when not).
/// Not the ranking's copy (map/coarse_source.h), which is the same dual of
/// other regions: its seeds are farthest-point samples, each region grown by
/// its own Dijkstra as its seed is added, with every fine vertex's tree
/// parent, and every coarse edge gets a path of fine halfedges (homotopy data
/// is carried along them); its faces stay in the order of their first fine
/// face, and a failed dual is retried once at twice the samples (this copy
/// retries at a smaller radius). That costs ~0.3 s of CPU on a 56k mesh, a
/// third of the flow this start shortens; the start needs no paths and no
/// parents.
struct CoarseCopy {
  std::vector<int> seeds;   // coarse vertex -> fine vertex
  std::vector<int> region;  // fine vertex -> coarse vertex
  TriMesh mesh;
  std::unique_ptr<Connectivity> conn;  // of mesh
};

bool coarse_copy(const TriMesh& mesh, const Connectivity& conn, const VertexGraph& graph, int radius, CoarseCopy& out) {
  const int nv = conn.num_vertices();
  out.seeds.clear();
  std::vector<int> hops(nv, -1), touched, queue;
  for (int v = 0; v < nv; ++v) {
    if (hops[v] >= 0) continue;
    out.seeds.push_back(v);
    // Every vertex within `radius` edges of the new seed is covered.
    queue.assign(1, v);
    hops[v] = 0;
    for (size_t q = 0; q < queue.size(); ++q) {
      const int a = queue[q];
      if (hops[a] >= radius) continue;
      for (int k = graph.start[a]; k < graph.start[a + 1]; ++k) {
        const int b = graph.next[k];
        if (hops[b] < 0 || hops[b] > hops[a] + 1) {
          if (hops[b] < 0) queue.push_back(b);
          hops[b] = hops[a] + 1;
        }
      }
    }
  }
  const int nc = static_cast<int>(out.seeds.size());
  if (nc < 4 || 2 * nc > nv) return false;
  // Regions: nearest seed over the 3D edge lengths.
  out.region.assign(nv, -1);
  auto graph_arcs = [&](int a, auto&& visit) {
    for (int k = graph.start[a]; k < graph.start[a + 1]; ++k) visit(k, graph.next[k], graph.length[k]);
  };
  detail::DijkstraOptions tails;  // each vertex's region is its parent's
  tails.want_parents = false;
  tails.want_parent_nodes = true;
  detail::DijkstraResult nearest;
  detail::dijkstra(nv, graph_arcs, out.seeds, tails, nearest);
  for (int c = 0; c < nc; ++c) out.region[out.seeds[c]] = c;
  for (int b : nearest.settled)  // a parent before its children
    if (nearest.parent_node[b] >= 0) out.region[b] = out.region[nearest.parent_node[b]];
  // The dual faces, sorted (region_dual_faces lists them in the order of
  // their first fine face).
  std::vector<std::array<int, 3>> faces;
  if (!detail::region_dual_faces(mesh.F, out.region, nc, faces)) return false;
  std::sort(faces.begin(), faces.end());
  out.conn = detail::region_dual_surface(faces, nc, conn.euler_characteristic());
  if (!out.conn) return false;
  out.mesh = detail::region_dual_mesh(mesh, out.seeds, *out.conn);
  return true;
}

/// u on every fine vertex: the coarse value at the seeds (held), the
/// region's value elsewhere, then `sweeps` Gauss–Seidel sweeps of the graph
/// Laplacian (each free vertex to the mean of its neighbours), in vertex
/// order: deterministic.
Eigen::VectorXd prolonged(const VertexGraph& graph, const CoarseCopy& copy, const Eigen::VectorXd& coarse_u,
                          int sweeps) {
  const int nv = static_cast<int>(copy.region.size());
  Eigen::VectorXd u(nv);
  std::vector<char> held(nv, 0);
  for (int v = 0; v < nv; ++v) u[v] = coarse_u[copy.region[v]];
  for (int s : copy.seeds) held[s] = 1;
  for (int s = 0; s < sweeps; ++s)
    for (int v = 0; v < nv; ++v) {
      if (held[v] || graph.start[v + 1] == graph.start[v]) continue;
      double sum = 0.0;
      for (int q = graph.start[v]; q < graph.start[v + 1]; ++q) sum += u[graph.next[q]];
      u[v] = sum / (graph.start[v + 1] - graph.start[v]);
    }
  return u;
}

}  // namespace

CoarseStart coarse_conformal_start(const TriMesh& mesh, const Connectivity& conn, Background background,
                                   const CoarseStartOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  CoarseStart r;
  const int nv = conn.num_vertices();
  if (options.coarse_vertices <= 0) {
    r.why = "the coarse start is off";
    return r;
  }
  if (nv < options.min_vertices || nv < 4 * options.coarse_vertices) {
    r.why = "the mesh has " + std::to_string(nv) + " vertices, fewer than the coarse start needs";
    return r;
  }
  const VertexGraph graph(mesh, conn);
  // A breadth-first ball of radius R on a mesh of valence ~6 holds 3R² + 3R + 1
  // vertices; seeds more than R apart come out at about nv / (0.45 (3R² + 3R + 1))
  // (measured: 6674 seeds at R = 2 on the 55886-vertex n-hole torus, 8742 on
  // the 72848-vertex vase). The largest R with at least coarse_vertices seeds.
  auto seeds_at = [nv](int R) { return nv / (0.45 * (3.0 * R * R + 3.0 * R + 1.0)); };
  int radius = 1;
  while (seeds_at(radius + 1) >= options.coarse_vertices) ++radius;
  CoarseCopy copy;
  bool ok = false;
  for (int R = radius; R >= 1 && !ok; --R) ok = coarse_copy(mesh, conn, graph, R, copy);  // denser on failure
  r.copy_seconds = seconds_since(t0);
  if (!ok) {
    r.why = "no coarse copy of the mesh's genus from breadth-first seeds";
    return r;
  }
  r.coarse_vertices = copy.mesh.num_vertices();
  const auto t1 = std::chrono::steady_clock::now();
  RicciFlowResult flow;
  try {
    RicciFlowOptions fo;
    fo.tolerance = options.coarse_tolerance;
    fo.intrinsic_delaunay = true;
    fo.threads = options.threads;
    flow = ricci_flow(*copy.conn, edge_lengths(copy.mesh, *copy.conn), background, fo);
  } catch (const Error& e) {
    r.why = std::string("the coarse copy's flow failed: ") + e.what();
    return r;
  }
  r.flow_seconds = seconds_since(t1);
  r.coarse_iterations = flow.iterations;
  r.coarse_flips = flow.flips;
  if (!flow.converged || !flow.u.allFinite()) {
    r.why = "the coarse copy's flow did not converge: " + flow.message;
    return r;
  }
  const auto t2 = std::chrono::steady_clock::now();
  r.u = prolonged(graph, copy, flow.u, options.smoothing_sweeps);
  r.prolong_seconds = seconds_since(t2);
  r.ok = true;
  r.seconds = seconds_since(t0);
  return r;
}

}  // namespace surfmap
