#pragma once
// Landmarks for genus >= 1 (paper §VII-C; DESIGN.md §2.10): each landmark
// source vertex s is held at a lift of its target vertex t's position in the
// universal cover of the target. Not part of the public API.
//
// Which lift matters: two lifts differ by a deck element, and holding s at
// another lift changes the homotopy class of the map relative to the other
// landmarks (the image of a path between two landmarks winds differently).
// The rule used by both the flat and the hyperbolic path: solve without
// landmarks first, then hold each s at the lift of t nearest (in the cover)
// to where s landed. So landmarks never add winding that the optimum did not
// already have; for genus 1 the optimum is first translated (it is unique
// only up to a translation) to fit the landmarks best in least squares.
#include <complex>
#include <memory>
#include <utility>
#include <vector>

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/harmonic_relaxation.h"
#include "surfmap/map/hyperbolic_harmonic.h"

namespace surfmap::detail {

using Complex = std::complex<double>;

/// The translate p + m w1 + n w2 (m, n integers) nearest to z.
Complex nearest_lattice_translate(Complex z, Complex p, Complex w1, Complex w2);

/// Lifts of the landmarks' target positions for an unconstrained flat
/// optimum z: translates z to fit them best (least squares over the nearest
/// translates, iterated to a fixed point) and returns, per landmark, the
/// translate of target_position[k] nearest to z[source[k]] + shift.
std::vector<Complex> flat_landmark_lifts(const std::vector<Complex>& z, const std::vector<int>& source,
                                         const std::vector<Complex>& target_position, Complex w1, Complex w2);

/// The minimiser of E(z) = Σ_e w_e |z_j + t_e − z_i|² (edge e from i to j,
/// w_e its cotangent weight, or 1 when `uniform`) with z fixed at the pinned
/// vertices (at least one): the free block of the weighted Laplacian is
/// factorised once, and solve() takes each homotopy class's translations.
class PinnedFlatHarmonic {
 public:
  PinnedFlatHarmonic(int num_vertices, const std::vector<IntrinsicEdge>& edges, const std::vector<int>& pinned,
                     bool uniform);
  /// t: #E translations; values: one position per pinned vertex (in the
  /// constructor's order). Returns #V positions and E (cotangent weights).
  std::pair<std::vector<Complex>, double> solve(const std::vector<Complex>& t, const std::vector<Complex>& values) const;

 private:
  int n_;
  const std::vector<IntrinsicEdge>& edges_;
  std::vector<int> pinned_, free_index_;
  bool uniform_;
  Eigen::SparseMatrix<double> coupling_;  ///< #free x #pinned block of L
  std::unique_ptr<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>> llt_;
};

/// Hyperbolic case: re-solves the harmonic map (Riemannian Newton,
/// map/hyperbolic_harmonic.h) from the free optimum `free` (its vertex decks
/// relative to `edges`) with each source[k] held at the deck image of
/// target_position[k] (a point of the target's layout) nearest, in
/// hyperbolic distance, to where `free` put it; images are searched breadth
/// first over words in the layout's side pairings and their inverses (which
/// move the cut disk to its neighbours), pruned to those within reach of the
/// free position. `generators` are the solve's chart moves. The
/// returned vertex decks are again relative to `edges`. With `relaxation`
/// the held problem is solved by the paper's per-vertex relaxation
/// (map/harmonic_relaxation.h, the held vertices skipped) with
/// `relaxation_options` instead of Newton with `options`.
HyperbolicHarmonicResult hold_hyperbolic_landmarks(int num_vertices, const std::vector<WeightedEdge>& edges,
                                                   const std::vector<hyperbolic::Mobius>& generators,
                                                   const std::vector<hyperbolic::Mobius>& side_pairings,
                                                   const HyperbolicHarmonicResult& free, const std::vector<int>& source,
                                                   const std::vector<Complex>& target_position,
                                                   HyperbolicHarmonicOptions options, bool relaxation = false,
                                                   HarmonicRelaxationOptions relaxation_options = {});

}  // namespace surfmap::detail
