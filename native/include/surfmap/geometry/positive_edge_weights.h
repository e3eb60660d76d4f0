#pragma once
// Positive weights on a mesh's OWN edges (docs/method.md §2.8), the fallback of
// the genus >= 2 map when the straight images of the source's faces fold.
// The harmonic map with the intrinsic Delaunay cotangent weights embeds the
// intrinsic triangulation, but on meshes with slivers (g3_block) the
// geodesic images of the user's own triangles can still overlap. With
// positive weights on the mesh's own edges the discrete harmonic map into a
// hyperbolic surface embeds the mesh itself (the Tutte-type theorem for
// hyperbolic targets, Colin de Verdière 1991; docs/method.md §2.8), whatever the
// weights; the price is that they no longer reproduce affine maps (higher
// D' where the cotangents were negative).
//
// Weights: the cotangent weight (cot α + cot β)/2 of each edge, raised to at
// least `floor` times the mean of the positive ones.
#include <Eigen/Core>

#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/mesh/connectivity.h"

namespace surfmap {

struct PositiveEdgeWeightsOptions {
  /// Lower bound of every weight, relative to the mean positive cotangent
  /// weight (default 0.1; must be > 0).
  double floor = 0.1;
};

/// The mesh's own triangulation (no flips: F, face_edges and edges exactly
/// the input's, edges[e] from edge_vertices(e, 0) to (e, 1) along its
/// halfedge) with positive weights, in the IntrinsicDelaunayResult layout so
/// it can stand in for the intrinsic triangulation. `raised` (optional)
/// receives the number of edges whose cotangent weight was below the floor.
IntrinsicDelaunayResult positive_edge_weights(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                              const PositiveEdgeWeightsOptions& options = {}, int* raised = nullptr);

/// The source's harmonic-energy triangulation (docs/robustness.md, "The source side"):
/// the intrinsic Delaunay triangulation (intrinsic_delaunay, default
/// options) when its flips finish. They stop short when Delaunay needs a
/// vertex with a single edge: a tip whose cone angle is below pi (g1_twirl
/// has two). There the harmonic map would put that vertex onto its only
/// neighbour and fold the user's faces around it, so instead the flips run
/// with min_degree = 3 and the few edges they leave non-Delaunay get the
/// floor weight of positive_edge_weights (`raised_weights` counts them,
/// `degree_limited` the edges left unflipped; `delaunay` is true when the
/// result has only positive or Delaunay weights). Every other edge keeps its
/// intrinsic Delaunay cotangent weight.
IntrinsicDelaunayResult delaunay_energy_weights(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                                const PositiveEdgeWeightsOptions& options = {});

}  // namespace surfmap
