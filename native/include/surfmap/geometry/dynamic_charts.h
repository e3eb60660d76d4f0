#pragma once
// Bringing a point of the universal cover back towards the origin by deck
// elements (the algebraic form of the paper's dynamic charts, docs/method.md §2.6), shared
// by the Newton solver (map/hyperbolic_harmonic.h) and the relaxation
// (map/harmonic_relaxation.h) when no reduction into the fundamental polygon
// is supplied.
//
// The point is given by an isometry C with C(0) = z (a chart), not by z:
// its distance from the origin is read off the matrix, d(0, z) = 2 asinh|b|,
// which stays exact however far out z is (30 units from the origin |z| is
// 1 − 2e-13, and comparing |z| between candidates there compares round-off).
#include <vector>

#include "surfmap/geometry/hyperbolic.h"

namespace surfmap {

/// Greedy reduction: applies the move of `moves` (group elements, e.g. the
/// side pairings and their inverses) that brings C(0) closest to the origin
/// while that strictly helps. Returns the indices of the moves applied,
/// first applied first, so the element applied is moves[k_last] ··· moves[k_first];
/// at most `max_moves` of them. Only a Dirichlet domain centred at the
/// origin guarantees that some move helps outside the domain: for other
/// polygons the greedy can stall far out (seen: 14.8 units from the origin
/// with the side pairings of a genus-2 vase's polygon, every single move
/// and every product of two making it farther), so callers with the
/// polygon reduce into it instead (HyperbolicHarmonicOptions::reduce_point).
inline std::vector<int> reduce_towards_origin(const hyperbolic::Mobius& chart, const std::vector<hyperbolic::Mobius>& moves,
                                              int max_moves = 64) {
  using hyperbolic::Mobius;
  std::vector<int> applied;
  Mobius c = chart;
  // |b| = sinh(d/2): monotone in the distance; a relative margin keeps
  // round-off from cycling between equidistant tiles.
  auto closer = [](const Mobius& m, double than) { return std::abs(m.b) < than * (1 - 1e-9) - 1e-15; };
  while (static_cast<int>(applied.size()) < max_moves) {
    double best = std::abs(c.b);
    int arg = -1;
    Mobius next;
    for (size_t k = 0; k < moves.size(); ++k) {
      const Mobius m = (moves[k] * c).normalized();
      if (closer(m, best)) best = std::abs(m.b), arg = static_cast<int>(k), next = m;
    }
    if (arg < 0) break;
    c = next;
    applied.push_back(arg);
  }
  return applied;
}

}  // namespace surfmap
