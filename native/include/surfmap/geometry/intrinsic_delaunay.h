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
  /// No flip leaves a vertex with fewer than this many edge ends (a loop
  /// counts twice). 1 is Bobenko–Springborn's algorithm, which always ends
  /// Delaunay but may leave a vertex of cone angle < pi with one edge inside
  /// a face whose two sides are one edge; with 2 (the default) such an edge
  /// stays unflipped, and with 3 every vertex keeps a fan of >= 3 triangles.
  /// Edges left non-Delaunay for this reason are counted in `degree_limited`.
  int min_degree = 2;
  /// Keep every flip in IntrinsicDelaunayResult::flip_history (default
  /// false): the genus-0 uniformization carries points back through them.
  bool record_flips = false;
  /// #E (edge order of the input's Connectivity) or empty: nonzero for edges
  /// never flipped (issue 16: the boundary of an open surface's half inside
  /// its double, so that the half's intrinsic triangulation stays a half;
  /// docs/open_surfaces.md "The half's solve"). Such an edge may end non-Delaunay
  /// (it is then not counted in `degree_limited`, and `delaunay` is false).
  std::vector<char> keep;
};

/// One flip of intrinsic_delaunay (options.record_flips): the quad
/// (k, i, l, j) counter-clockwise, diagonal i–j replaced by k–l. Before:
/// face0 = (i, j, k) with i in column column0, face1 = (j, i, l) with j in
/// column column1; after: face0 = (k, i, l), face1 = (l, j, k).
struct IntrinsicFlip {
  int face0 = -1, face1 = -1, column0 = 0, column1 = 0;
  int i = -1, j = -1, k = -1, l = -1;
  /// Lengths of k–i, i–l, l–j, j–k, the old diagonal i–j, the new k–l.
  double lengths[6] = {};
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
  /// #F x 3: 1 when face f's corner-k side runs along edges[face_edges(f, k)]
  /// (from i to j), 0 when against it. Needed for loop edges (i == j),
  /// whose direction the vertex numbers do not tell.
  RowMatrixX3i face_edge_forward;
  int flips = 0;
  /// With options.record_flips: the flips in the order made.
  std::vector<IntrinsicFlip> flip_history;
  /// Non-Delaunay edges left unflipped because of `min_degree` at the end.
  int degree_limited = 0;
  /// Edges whose weight was raised to a positive floor afterwards
  /// (delaunay_energy_weights); 0 from intrinsic_delaunay itself.
  int raised_weights = 0;
  bool delaunay = false;
  /// Smallest cot_weight after flipping (>= -tolerance when delaunay).
  double min_cot_weight = 0.0;
};

/// `edge_lengths`: #E lengths in the edge order of `mesh` (any metric that
/// satisfies the triangle inequality in every face).
IntrinsicDelaunayResult intrinsic_delaunay(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                           const IntrinsicDelaunayOptions& options = {});

}  // namespace surfmap
