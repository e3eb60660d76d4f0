#pragma once
// Intrinsic Delaunay triangulation by edge flips on edge lengths alone
// (Bobenko–Springborn; docs/method.md §2.8). Its cotangent weights are >= 0 and
// still reproduce affine functions exactly, which is what the harmonic-map
// energy needs on irregular meshes (clamping negative cotangents does not).
// The vertex set is unchanged; each intrinsic edge remembers the path of
// original halfedges it was made from, so per-edge data that multiplies along
// paths (deck elements, translations) can be carried over.
#include <vector>

#include <Eigen/Core>

#include "surfmap/mesh/connectivity.h"

namespace surfmap {

struct IntrinsicDelaunayOptions {
  /// An edge is flipped when cot(alpha) + cot(beta) < -tolerance. Default 1e-12.
  double tolerance = 1e-12;
  /// Stop after this many flips (0: 100 x #E). Reaching it leaves
  /// `delaunay` false.
  int max_flips = 0;
};

/// One edge of the intrinsic triangulation, from vertex i to vertex j.
struct IntrinsicEdge {
  int i = -1, j = -1;
  double length = 0.0;
  /// (cot alpha + cot beta) / 2, alpha and beta the angles opposite the edge.
  double cot_weight = 0.0;
  /// Original halfedges (Connectivity numbering of the input) walked from i
  /// to j; a single halfedge for an edge that was never flipped.
  std::vector<int> path;
};

struct IntrinsicDelaunayResult {
  /// #F x 3 faces of the intrinsic triangulation (may contain two edges
  /// between the same vertices, so do not build a Connectivity from it).
  RowMatrixX3i F;
  /// #E edges; edges[e] for the original edge e when it was not flipped.
  std::vector<IntrinsicEdge> edges;
  /// For each face, the edge index of its corner-k side (from F(f,k) to F(f,k+1)).
  RowMatrixX3i face_edges;
  int flips = 0;
  bool delaunay = false;
  /// Smallest cot_weight after flipping (>= -tolerance when delaunay).
  double min_cot_weight = 0.0;
};

/// `edge_lengths`: #E lengths in the edge order of `mesh` (any metric that
/// satisfies the triangle inequality in every face).
IntrinsicDelaunayResult intrinsic_delaunay(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                           const IntrinsicDelaunayOptions& options = {});

}  // namespace surfmap
