#pragma once
// Edge elements in the per-face charts of a FaceAtlas (issue 13): composed
// around a vertex's star, filled from the closing relation of a face,
// re-derived where faces do not close, along shortest edge paths; and the
// flipped images of a mesh's faces from its edges' elements. The steps the
// per-face map (face_chart_map.h) builds its start from, shared with
// bench/bench_face_charts.cpp (which includes this internal header by its
// path). Internal to the core.
#include <complex>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/uniformize/layout.h"

namespace surfmap::detail {

/// A product of transitions closes (is the identity) up to this distance
/// from the identity: the transitions have entries ~1 and round off ~1e-15
/// per product, while a product in a wrong class moves points by a closed
/// geodesic of the surface (the plates' thinnest necks measured: ~0.08).
constexpr double kClosingTolerance = 1e-6;

/// face(stop)'s canonical coordinates -> face(a)'s, for halfedges a and stop
/// outgoing from one vertex, composed across the edges of its star.
/// SolveError when the star does not close.
hyperbolic::Mobius around_vertex(const Connectivity& conn, const FaceAtlas& atlas, int a, int stop);

/// The class is a cocycle: around every face rho_ab rho_bc rho_ca = id. Fills
/// the element of every edge that is a face's only unknown one from the other
/// two, until no face has exactly one unknown edge. rho(e) is edge e's element
/// along its edge_halfedge (a reference into the caller's storage); `known`
/// (#E) is updated. Returns how many edges it filled.
template <class EdgeRho>
int close_faces(const Connectivity& conn, std::vector<char>& known, EdgeRho&& rho) {
  using hyperbolic::Mobius;
  auto halfedge_rho = [&](int h) -> Mobius {
    const int e = conn.edge(h);
    return conn.edge_halfedge(e) == h ? rho(e) : rho(e).inverse();
  };
  int filled = 0;
  for (bool progress = true; progress;) {
    progress = false;
    for (int f = 0; f < conn.num_faces(); ++f) {
      int unknown = -1, count = 0;
      for (int k = 0; k < 3; ++k)
        if (!known[conn.edge(3 * f + k)]) unknown = 3 * f + k, ++count;
      if (count != 1) continue;
      const int h1 = Connectivity::next(unknown), h2 = Connectivity::next(h1);
      const Mobius rho_h = (halfedge_rho(h1) * halfedge_rho(h2)).inverse().normalized();
      const int e = conn.edge(unknown);
      rho(e) = conn.edge_halfedge(e) == unknown ? rho_h : rho_h.inverse();
      known[e] = 1, ++filled, progress = true;
    }
  }
  return filled;
}

/// Faces whose edges' elements do not close (beyond kClosingTolerance)
/// before and after re-deriving, and the edges re-derived.
struct OpenFaceRepair {
  int open_before = 0, repaired = 0, open_after = 0;
};

/// A path in another class shows as its faces not closing: each edge not
/// marked `exact` (#E) whose faces do not all close takes the element one of
/// its two faces' other edges give when that closes more of the two faces
/// (repeated while anything changes; each change closes a face, so this
/// ends). `edges` (#E of conn, along edge_halfedge) hold the elements.
OpenFaceRepair rederive_open_faces(const Connectivity& conn, const std::vector<char>& exact,
                                   std::vector<WeightedEdge>& edges);

/// The halfedges of the shortest edge path from a to b (Dijkstra on
/// `lengths`, #E, stopped at b), listed from b back to a; `what` names the
/// mesh in the SolveError when b cannot be reached.
std::vector<int> shortest_edge_path_back(const Connectivity& conn, const Eigen::VectorXd& lengths, int a, int b,
                                         const char* what);

/// Flipped images of a mesh's faces among edges in their ends' charts
/// (head_in_tail(h): the head of halfedge h in its tail's chart, a Poincaré
/// point), tested in the Klein model.
template <class HeadInTail>
int count_flipped(const Connectivity& conn, const HeadInTail& head_in_tail) {
  int count = 0;
  for (int f = 0; f < conn.num_faces(); ++f) {
    const std::complex<double> p1 = hyperbolic::poincare_to_klein(head_in_tail(3 * f));
    const std::complex<double> p2 = hyperbolic::poincare_to_klein(head_in_tail(conn.twin(3 * f + 2)));
    if (!(std::imag(std::conj(p1) * p2) > 0)) ++count;
  }
  return count;
}

}  // namespace surfmap::detail
