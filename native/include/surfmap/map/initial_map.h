#pragma once
// The initial ("before") map of the hyperbolic case (genus >= 2; paper §IV-B,
// DESIGN.md §2.7) and the quality of any map given by points and deck
// elements (paper §VII-A).
//
// What is built, and why it is not literally the paper's construction: the
// paper cuts both surfaces along canonical loops, flattens each cut disk
// harmonically onto the same canonical 4g-gon and composes the two. Here the
// source keeps its own connectivity, and its greedy loops are not refined:
// they share tree paths, so the source cut along them is not a 4g-gon (its
// corners are the branch points of the loop graph, up to 12g−6 sides, and a
// 4g-gon side would have to run along both banks of a shared path); and the
// boundary words of the two surfaces differ (canonical generators are words
// in the loops, the mesh is never re-cut: DESIGN.md §2.3), so no side of one
// disk corresponds to a side of the other, and the polygon with corners
// G_i(p) that the source word spells in the target's group is in general not
// simple, so flattening onto it would not in general give an embedding.
// What the composition is for (a map in the chosen homotopy class that is
// an embedding and a sensible start) is obtained instead
// by the Tutte-type map in the same class: the discrete harmonic map with
// uniform weights (every source edge weight 1) into the target's hyperbolic
// surface, i.e. each vertex at the hyperbolic barycentre of its neighbours'
// images. With positive weights this map is an embedding (the hyperbolic
// Tutte theorem; DESIGN.md §2.8), on any triangulation, slivers included,
// and it is the exact counterpart of the genus-1 initial map (flat_map.cpp:
// the uniform-weight Tutte embedding of the flat torus). Its figures
// (energy, D' per source face, flips) are measured on the image triangles in
// the Poincaré disk, where they are intrinsic to the target's metric; only
// the optimum is located on the target's triangles (3D points). Cost: a
// Newton solve from the origin with uniform weights (about 7 iterations on
// the generated shapes), which the main solve earns back: from this start it
// needs about 3 Newton iterations instead of 8–13 from the origin.
#include <complex>
#include <vector>

#include <Eigen/Core>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/map/distortion.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

struct HyperbolicInitialMapOptions {
  /// Gradient tolerance of the uniform-weight solve (default 1e-4; Newton
  /// converges quadratically, so the energy is then exact to ~1e-9 relative
  /// and one factorisation is saved; the map only starts the real solve).
  double tolerance = 1e-4;
  int max_iterations = 100;
};

struct HyperbolicInitialMapResult {
  bool converged = false;
  int iterations = 0;
  /// #V points and per-vertex deck elements (as HyperbolicHarmonicResult).
  std::vector<std::complex<double>> z;
  std::vector<hyperbolic::Mobius> vertex_deck;
  /// The same decks as words in the generators' letters (see
  /// HyperbolicHarmonicResult::vertex_deck_word).
  std::vector<Word> vertex_deck_word;
  double time_s = 0;
};

/// Uniform-weight harmonic map in the class given by `halfedge_rho`
/// (#3F: the deck element of source halfedge h = 3f+k, which runs from
/// F(f,k) to F(f,k+1); the twin's element is the inverse).
/// `generators`: the target's deck group generators (for the dynamic charts).
/// Throws SolveError if the solve breaks down.
HyperbolicInitialMapResult hyperbolic_initial_map(const Connectivity& source, const std::vector<hyperbolic::Mobius>& halfedge_rho,
                                                  const std::vector<hyperbolic::Mobius>& generators,
                                                  const HyperbolicInitialMapOptions& options = {});

/// Quality of the map given by `z` (#V points in the Poincaré disk),
/// `vertex_deck` (#V) and `halfedge_rho` (#3F, as above): the image of face f
/// is the geodesic triangle on z_{F0}, ρ_eff(3f) z_{F1}, ρ_eff(3f+2)⁻¹ z_{F2}
/// with ρ_eff(h) = deck[tail] · ρ(h) · deck[head]⁻¹; D' from the hyperbolic
/// side lengths against the 3D ones (paper §VII-A), orientation tested in
/// the chart centring corner 0. Flipped and degenerate images have D' = +inf
/// and are left out of mean and max. `image` receives the #F x 3 corners.
DistortionStats hyperbolic_distortion(const TriMesh& source, const std::vector<hyperbolic::Mobius>& halfedge_rho,
                                      const std::vector<std::complex<double>>& z,
                                      const std::vector<hyperbolic::Mobius>& vertex_deck,
                                      Eigen::Matrix<std::complex<double>, Eigen::Dynamic, 3, Eigen::RowMajor>* image = nullptr);

}  // namespace surfmap
