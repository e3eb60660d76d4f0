// Positive weights on a mesh's own edges (geometry/positive_edge_weights.h).
#include "surfmap/geometry/positive_edge_weights.h"

#include <algorithm>
#include <cmath>

#include "surfmap/error.h"

namespace surfmap {

IntrinsicDelaunayResult positive_edge_weights(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                              const PositiveEdgeWeightsOptions& options, int* raised) {
  if (!(options.floor > 0)) throw InputError("positive_edge_weights: floor must be positive");
  const int ne = mesh.num_edges(), nf = mesh.num_faces();
  if (edge_lengths.size() != ne) throw InputError("positive_edge_weights: need one length per edge");
  IntrinsicDelaunayResult r;
  r.F = mesh.faces();
  r.face_edges.resize(nf, 3);
  r.face_edge_forward.resize(nf, 3);
  r.edges.resize(ne);
  for (int e = 0; e < ne; ++e) {
    const int h = mesh.edge_halfedge(e);
    r.edges[e].i = mesh.tail(h);
    r.edges[e].j = mesh.head(h);
    r.edges[e].length = edge_lengths[e];
    r.edges[e].path = {h};
  }
  // Half cotangent of the angle opposite each halfedge, from the lengths.
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * f + k;
      r.face_edges(f, k) = mesh.edge(h);
      r.face_edge_forward(f, k) = mesh.edge_halfedge(mesh.edge(h)) == h;
      const double a = edge_lengths[mesh.edge(h)], b = edge_lengths[mesh.edge(Connectivity::next(h))],
                   c = edge_lengths[mesh.edge(Connectivity::prev(h))];
      // Angle opposite side a: cot = (b² + c² − a²) / (4 · area).
      const double s = 0.5 * (a + b + c);
      const double area = std::sqrt(std::max(s * (s - a) * (s - b) * (s - c), 0.0));
      // A zero-area face gives −∞: the edge gets the floor.
      const double cot = area > 0 ? (b * b + c * c - a * a) / (4 * area) : -HUGE_VAL;
      r.edges[mesh.edge(h)].cot_weight += 0.5 * cot;
    }
  double sum = 0;
  int count = 0;
  for (const auto& e : r.edges)
    if (e.cot_weight > 0 && std::isfinite(e.cot_weight)) sum += e.cot_weight, ++count;
  const double floor = options.floor * (count > 0 ? sum / count : 1.0);
  int n = 0;
  for (auto& e : r.edges)
    if (!(e.cot_weight >= floor)) e.cot_weight = floor, ++n;
  if (raised) *raised = n;
  r.flips = 0;
  r.delaunay = true;  // usable in place of the intrinsic triangulation; weights all positive
  r.min_cot_weight = floor;
  for (const auto& e : r.edges) r.min_cot_weight = std::min(r.min_cot_weight, e.cot_weight);
  return r;
}

IntrinsicDelaunayResult delaunay_energy_weights(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                                const PositiveEdgeWeightsOptions& options) {
  if (!(options.floor > 0)) throw InputError("delaunay_energy_weights: floor must be positive");
  IntrinsicDelaunayResult r = intrinsic_delaunay(mesh, edge_lengths);
  if (r.delaunay || r.degree_limited == 0) return r;  // finished, or the flip limit (delaunay false)
  IntrinsicDelaunayOptions limited;
  limited.min_degree = 3;
  r = intrinsic_delaunay(mesh, edge_lengths, limited);
  // Only edges left unflipped because of the degree limit may stay negative.
  int stuck = 0;
  for (const auto& e : r.edges)
    if (e.cot_weight < -limited.tolerance) ++stuck;
  if (stuck != r.degree_limited) return r;  // the flip limit was reached: delaunay stays false
  double sum = 0;
  int count = 0;
  for (const auto& e : r.edges)
    if (e.cot_weight > 0) sum += e.cot_weight, ++count;
  const double floor = options.floor * (count > 0 ? sum / count : 1.0);
  for (auto& e : r.edges)
    if (e.cot_weight < -limited.tolerance) e.cot_weight = floor, ++r.raised_weights;
  r.min_cot_weight = 1e300;
  for (const auto& e : r.edges) r.min_cot_weight = std::min(r.min_cot_weight, e.cot_weight);
  r.delaunay = true;  // usable as the energy's triangulation: no weight below -tolerance
  return r;
}

}  // namespace surfmap
