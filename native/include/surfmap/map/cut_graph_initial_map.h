#pragma once
// A genus >= 2 initial map that embeds the source by construction (paper
// docs/method.md §2.7 in spirit): the source's disk cut along a cut graph
// of its own edges, flattened onto a convex geodesic polygon of the target.
//
//  1. Cut graph G: the union of the source's UNREFINED greedy loops
//     (topology/system_of_loops.h, refine = false), dangling edges pruned.
//     Cut along G the source is a disk D whose faces are the source's own
//     faces, so Floater's theorem (below) speaks about the source's faces
//     directly. The polygon construction of initial_map.h cuts along the
//     REFINED loops instead, whose split and bend points lie inside source
//     faces: those faces, straight between their corners' images, can fold
//     there (1-12 on sliver sources), which is what its local repair and
//     fallback are for.
//  2. D is developed in the class (the deck word c_d of every disk copy d,
//     from the class's halfedge words, as in initial_map.h). The corners of
//     D's boundary are the copies of G's branch vertices (degree >= 3); its
//     sides are the copies of G's chains, paired by deck elements.
//  3. The polygon: one lift p_b per branch vertex b, corner d at c_d(p_b),
//     with the p_b minimising Σ_chains d(ends)² / L_chain (L: the chain's 3D
//     length), the discrete harmonic map of the metric graph G into the
//     target (a convex function; Gauss-Seidel Karcher-mean steps). At the
//     minimum the chain directions at every branch vertex, weighted by
//     length / L, sum to zero, so no two consecutive ones are more than π
//     apart: every corner of the polygon is convex (the single-base-point
//     polygon of initial_map.h has no such property, its 4g corners share
//     one angle sum of 2π). Simplicity and strict convexity are checked in
//     the Klein model; when they fail the map is not built (applied = false).
//     The branch points live in dynamic charts (docs/method.md §2.6 in algebraic
//     form): p_b = H_b(q_b) with q_b kept in the target's domain by
//     reduce_point and H_b a deck word folded into the corners' words, and
//     the whole development is moved by one deck element so that corner 0
//     lies in the domain. In a twisted class the development's words are
//     long (chain elements displacing the origin by 30-38 on the 50k genus-2
//     bench pair); without the charts the branch points drifted to |z| ~ 1
//     and a chain came out with no length.
//  4. Floater's theorem needs no interior edge joining two vertices of one
//     side (its faces would be degenerate): such a chord of D replaces the
//     part of its chain it spans (G stays a cut graph: the chord and that
//     part bound a disk on one bank), and D is cut again.
//  5. Boundary copies on their side at the fraction of the chain's 3D
//     length (the same on both banks, so the pairing carries one copy onto
//     the other); interior vertices by the Klein-model Tutte map with
//     symmetrised mean-value weights and the hyperboloid-barycentre rounds
//     of initial_map.h (positive weights every round). The disk is then
//     embedded in the convex polygon, the sides glue up, and every source
//     face is a positively oriented geodesic triangle: no fold to repair.
//     Round-off can still make a sliver face's image degenerate; the caller
//     checks (hyperbolic_distortion).
// Cost: one cut (the caller's unrefined loops), the development, and
// 1 + hyperboloid_rounds sparse Cholesky factorisations of the source's size
// (no Newton solve): 0.9-1.4 s on the 50k genus-2 bench pair under a load
// of 6 on 2 cores, where the uniform-weight fallback it replaces took
// 4.4-4.7 s (the refined-loop polygon is not convex there).
// Measured where it does not apply: very twisted classes (real
// block -> 3holes, fertility -> generated genus 4: corner elements with
// entries of 1e7) are too large for double precision; the fallbacks run.
// Where it differs from the paper (docs/method.md §2.7): the paper cuts both surfaces
// along canonical loops and composes two flattenings onto one canonical
// 4g-gon; here only the source is cut, along its own cut graph, and the
// target enters through its universal cover (the polygon's corners are deck
// images of points of the target's hyperbolic plane), so no composition
// through barycentric coordinates is needed.
#include <complex>
#include <functional>
#include <string>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap {

struct CutGraphInitialMapOptions {
  /// Base vertex of the source's unrefined loops (-1: automatic, as
  /// system_of_loops), computed here unless `loops` is given.
  int base_vertex = -1;
  /// Optional: the source's unrefined loops (SystemOfLoops::loops, closed
  /// vertex paths along source edges) when the caller has them.
  const std::vector<std::vector<int>>* loops = nullptr;
  /// Gauss-Seidel sweeps of the polygon's corner points at most (default
  /// 20000; each costs O(#chains) Möbius maps) and the step length (in the
  /// target's metric) below which they stop (default 1e-11).
  int network_sweeps = 20000;
  double network_tolerance = 1e-11;
  /// A corner is convex when its exterior angle in the Klein model exceeds
  /// this (radians, default 1e-9).
  double min_turn = 1e-9;
  /// Chord reroutings of the cut graph at most (default 64).
  int max_reroutes = 64;
  /// Hyperboloid-barycentre rounds of the flattening (default 1; 0: the
  /// plain Klein-model Tutte map). Every round is an embedding; the rounds
  /// only make the start closer to the optimum (50k genus-2 bench pair:
  /// initial energy 44.0 / 30.2 / 29.7 after 0 / 1 / 3 rounds, final 25.96),
  /// one sparse factorisation each.
  int hyperboloid_rounds = 1;
  /// Optional: moves a point into the target's fundamental domain and
  /// returns the side word applied (HyperbolicHarmonicOptions::reduce_point).
  std::function<Word(std::complex<double>&)> reduce_point;
};

struct CutGraphInitialMapResult {
  /// True when the polygon was simple and strictly convex and the
  /// flattening was computed; otherwise `reason` says why not and the map
  /// fields are empty.
  bool applied = false;
  std::string reason;
  /// The cut graph: branch vertices (degree >= 3), chains, and the chords
  /// rerouted (step 4); the polygon has 2 x chains sides.
  int branch_vertices = 0, chains = 0, chords_rerouted = 0;
  /// The polygon's corners (Poincaré disk, boundary order), Σ_sides d (its
  /// perimeter), and its smallest and largest exterior angle in the Klein
  /// model (radians; convex when > 0 with total 2π).
  std::vector<std::complex<double>> corners;
  double perimeter = 0, min_turn = 0, max_turn = 0;
  bool convex = false;
  /// Gauss-Seidel sweeps used for the corner points.
  int network_sweeps = 0;
  /// #V_source points and deck elements (HyperbolicHarmonicResult contract:
  /// z_i = vertex_deck_i(lift_i)); words are side words of the group.
  std::vector<std::complex<double>> z;
  std::vector<hyperbolic::Mobius> vertex_deck;
  std::vector<Word> vertex_deck_word;
  double time_s = 0;
};

/// The construction of the file comment. `source`/`sc`: the source mesh;
/// `halfedge_word` (#3F): the class's deck element of every source halfedge
/// as a side word of `group` (its twin carries the inverse), flat around
/// every face. Throws InputError on size mismatches; a polygon that is not
/// convex is not an error (applied = false).
CutGraphInitialMapResult cut_graph_initial_map(const TriMesh& source, const Connectivity& sc,
                                               const std::vector<Word>& halfedge_word, const DeckGroup& group,
                                               const CutGraphInitialMapOptions& options = {});

}  // namespace surfmap
