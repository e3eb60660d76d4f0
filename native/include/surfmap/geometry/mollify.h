#pragma once
// Intrinsic mollification of edge lengths: every length raised by one
// common amount, just enough for every triangle inequality to hold with a
// margin (docs/robustness.md).
// Nearly or exactly degenerate triangles (collinear vertices, coincident
// positions, angles of 1e-4 degrees) break cotangent weights, angle sums and
// layouts. Adding one small uniform epsilon to every edge length gives every
// triangle a strict triangle inequality with a set margin, changes a
// well-shaped mesh not at all (epsilon = 0) and perturbs angles only in the
// triangles that were (nearly) degenerate.
#include <Eigen/Core>

#include "surfmap/mesh/connectivity.h"

namespace surfmap {

struct MollifyResult {
  /// #E mollified lengths (input lengths + epsilon), Connectivity edge order.
  Eigen::VectorXd lengths;
  /// The uniform amount added to every edge (0: nothing changed).
  double epsilon = 0;
  /// Faces whose margin l_a + l_b - l_c was below delta before mollification
  /// (0 when epsilon == 0).
  int faces_touched = 0;
};

/// `lengths`: #E non-negative finite edge lengths of `c` (Connectivity edge
/// order). Returns the smallest epsilon >= 0 such that, with every length
/// increased by epsilon, each face satisfies l_a + l_b >= l_c + delta for all
/// three corners, where delta = relative_margin x (mean mollified edge
/// length). Defining delta on the mollified lengths makes the operation
/// idempotent: mollifying the result again gives epsilon = 0.
/// relative_margin must be in [0, 0.5). Throws InputError naming the edge for
/// a negative, NaN or infinite length, or on a size mismatch.
MollifyResult mollify_edge_lengths(const Eigen::VectorXd& lengths, const Connectivity& c,
                                   double relative_margin = 1e-4);

}  // namespace surfmap
