#include "face_chart_elements.h"

#include <functional>
#include <limits>
#include <string>
#include <utility>

#include "surfmap/error.h"

#include "../mesh/dijkstra.h"

namespace surfmap::detail {

using hyperbolic::Mobius;

Mobius around_vertex(const Connectivity& conn, const FaceAtlas& atlas, int a, int stop) {
  Mobius x;
  for (int current = a, guard = 0; current != stop; ++guard) {
    if (guard > conn.num_halfedges()) throw SolveError("per-face charts: a vertex star does not close");
    const int into = Connectivity::prev(current);
    x = (x * atlas.transition[into]).normalized();
    current = conn.twin(into);
  }
  return x;
}

OpenFaceRepair rederive_open_faces(const Connectivity& conn, const std::vector<char>& exact,
                                   std::vector<WeightedEdge>& edges) {
  OpenFaceRepair r;
  // Element of halfedge h: its head's coordinates -> its tail's.
  auto halfedge_rho = [&](int h) {
    const int e = conn.edge(h);
    return conn.edge_halfedge(e) == h ? edges[e].rho : edges[e].rho.inverse();
  };
  auto closes = [&](int f) {
    const Mobius p = halfedge_rho(3 * f) * halfedge_rho(3 * f + 1) * halfedge_rho(3 * f + 2);
    return hyperbolic::distance_from_identity(p.normalized()) < kClosingTolerance;
  };
  for (int f = 0; f < conn.num_faces(); ++f) r.open_before += !closes(f);
  for (bool progress = r.open_before > 0; progress;) {
    progress = false;
    for (int e = 0; e < conn.num_edges(); ++e) {
      if (exact[e]) continue;
      const int h = conn.edge_halfedge(e), tw = conn.twin(h);
      const int f = Connectivity::face(h), g = Connectivity::face(tw);
      const int open = !closes(f) + !closes(g);
      if (open == 0) continue;
      for (int side : {h, tw}) {
        const int h1 = Connectivity::next(side), h2 = Connectivity::next(h1);
        const Mobius rho_side = (halfedge_rho(h1) * halfedge_rho(h2)).inverse().normalized();
        const Mobius old_rho = edges[e].rho;
        edges[e].rho = side == h ? rho_side : rho_side.inverse();
        if (!closes(f) + !closes(g) < open) {
          ++r.repaired, progress = true;
          break;
        }
        edges[e].rho = old_rho;
      }
    }
  }
  for (int f = 0; f < conn.num_faces(); ++f) r.open_after += !closes(f);
  return r;
}

std::vector<int> shortest_edge_path_back(const Connectivity& conn, const Eigen::VectorXd& lengths, int a, int b,
                                         const char* what) {
  DijkstraOptions to_b;
  to_b.target = b;
  to_b.want_parent_nodes = true;
  DijkstraResult search;
  dijkstra(conn.num_vertices(), rotation_arcs(conn, [&](int h) { return lengths[conn.edge(h)]; }), {a}, to_b, search);
  if (a != b && search.parent_arc[b] < 0)
    throw SolveError(std::string("per-face charts: no edge path of ") + what + " between vertices " +
                     std::to_string(a) + " and " + std::to_string(b));
  return arcs_back_to_source(search, b);
}

}  // namespace surfmap::detail
