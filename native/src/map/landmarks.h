#pragma once
// Landmarks for genus >= 1 (docs/method.md §2.10): each landmark
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
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/harmonic_relaxation.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/mesh/tri_mesh.h"

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

/// A landmark's carried neighbourhood: the source vertices within `rings`
/// hops of it on the energy's edge graph, breadth first (vertex[0] is the
/// landmark); parent[q] is the position of q's BFS parent in the list (-1
/// for the landmark), edge[q] the edge joining them and head[q] whether q is
/// that edge's j end.
struct LandmarkPatch {
  std::vector<int> vertex, parent, edge;
  std::vector<char> head;
};

/// Far landmarks (docs/method.md §2.10 asks for a bijective map): a source vertex
/// pinned far from where the free optimum puts it makes the held optimum
/// fold around it — the held problem is convex (flat: strictly; hyperbolic:
/// a non-positively curved target), so its minimiser is unique and no
/// continuation or warm start changes it (measured: plain pins fold beyond
/// ~5 edge lengths). What does change it is what is held. A held disk of
/// radius r carried rigidly by d keeps its harmonic surround unfolded about
/// while d < r log(R/r) (radial harmonic annulus: det = 1 − d/(r log(R/r))
/// on the inner circle), so each landmark carries a neighbourhood of its
/// free image, moved by the isometry taking its free image to its lift, and
/// the rest of the map is the harmonic map with those vertices held.
///
/// The driver: every landmark starts with 0 rings (the plain pin, the exact
/// held optimum when it does not fold). `solve(patches)` solves the held
/// problem and returns the source faces whose images flip or degenerate;
/// the landmarks nearest (in hops) to those faces grow their neighbourhood
/// (0, 1, 2, 3, 5, 8, 12, ... rings) and the problem is solved again.
/// Throws SolveError naming the landmarks when two neighbourhoods meet, the
/// held vertices would exceed half the source, or growing them adds folds
/// three rounds running: those landmarks cannot be held bijectively this
/// way in this class.
struct LandmarkPatchSearch {
  std::vector<int> rings;  ///< per landmark, the rings of the accepted solve
  int solves = 0;          ///< held solves done
  int held_vertices = 0;   ///< source vertices held in the accepted solve
};
LandmarkPatchSearch grow_landmark_patches(
    int num_vertices, const std::vector<std::pair<int, int>>& edge_ends, const RowMatrixX3i& faces,
    const std::vector<std::pair<int, int>>& landmarks,
    const std::function<std::vector<int>(const std::vector<LandmarkPatch>&)>& solve);

/// Genus 1, landmarks whose plain pins fold the map: the landmarked map of
/// lowest harmonic energy among bijective ones, approached by an interior
/// point continuation. Minimises E(z) + μ Σ_f φ(A_f(z) / c_f) with the
/// landmarks held, where A_f is the signed area of source face f's image,
/// c_f = 1/4 of its area in the free optimum, φ(x) = x − 1 − log x below 1
/// and 0 above (C¹; inactive where a face keeps a quarter of its free
/// area), μ = E(free) / #F. The landmarks move from their free images to
/// their lifts in steps; each step is predicted by the harmonic extension of
/// the landmarks' move and corrected by Newton (Gauss–Newton barrier
/// Hessian, line search keeping every A_f > 0), so the map is bijective at
/// every step. A step whose prediction folds, or whose correction stalls, is
/// halved; success doubles the next. The hyperbolic counterpart is
/// hyperbolic_barrier_landmarks.
struct FlatBarrierResult {
  bool ok = false;
  std::vector<Complex> z;  ///< #V cover positions (valid when ok)
  double energy = 0;       ///< E(z), the harmonic part only
  int steps = 0, newton_iterations = 0;
  double reached = 0;  ///< fraction of the way the landmarks got (1 when ok)
  /// The paths of the last continuation run: 0 the geodesics, else how far
  /// each landmark stepped aside to its left (> 0) or right (< 0), a
  /// fraction of its geodesic's length, after the geodesics stalled.
  double bend = 0;
};
FlatBarrierResult flat_barrier_landmarks(int num_vertices, const std::vector<IntrinsicEdge>& edges,
                                         const std::vector<Complex>& translations,
                                         const RowMatrixX3i& faces,
                                         const Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>& face_offsets,
                                         const std::vector<Complex>& free, const std::vector<int>& source,
                                         const std::vector<Complex>& lifts);

/// Genus >= 2, landmarks whose plain pins fold the map: the hyperbolic
/// counterpart of flat_barrier_landmarks. Minimises E(z) + μ Σ_f φ(A_f(z) /
/// c_f) with the landmarks held, where E = Σ w d(z_i, ρ z_j)² (hyperbolic
/// distance), A_f is twice the Euclidean area of source face f's image
/// triangle in the Klein model seen from the chart centring its corner 0
/// (geodesics are straight there, so the sign of A_f is the orientation of
/// the geodesic triangle), c_f = 1/4 of it in the free optimum, φ and μ as
/// in the flat case. The landmarks walk the geodesics from their free
/// images to their lifts in steps; each step is predicted by the free
/// points' response −H⁻¹ ∂g/∂s and corrected by Newton in the points'
/// Poincaré coordinates (exact Hessian by forward differentiation of the
/// edge and face terms when it is positive definite, else every term's
/// block projected onto PSD), with a line search that rejects any point
/// outside the disk and any face with A_f ≤ 0, so the map is bijective at
/// every step. A step that cannot be taken is halved; success doubles the
/// next. No chart moves: the points stay in the free optimum's charts
/// (`free`, `edges` with their effective elements), where the landmarks'
/// lifts are at most the target's diameter away from the domain.
/// `face_elements`: 3 x #F, the element of source halfedge (F(f,k) ->
/// F(f,k+1)) in those charts, so face f's image corners are z[F(f,0)],
/// face_elements[3f](z[F(f,1)]) and face_elements[3f+2]⁻¹(z[F(f,2)]).
struct HyperbolicBarrierResult {
  bool ok = false;
  std::vector<Complex> z;  ///< #V points in the free optimum's charts (valid when ok)
  double energy = 0;       ///< E(z), the harmonic part only
  int steps = 0, newton_iterations = 0;
  double reached = 0;  ///< fraction of the way the landmarks got (1 when ok)
  /// The paths of the last continuation run: 0 the geodesics, else how far
  /// each landmark stepped aside to its left (> 0) or right (< 0), a
  /// fraction of its geodesic's length, after the geodesics stalled.
  double bend = 0;
};
/// `progress` (optional, as HyperbolicHarmonicOptions::progress): called
/// every Newton iteration with (iterations so far, objective, gradient);
/// false cancels (Cancelled).
HyperbolicBarrierResult hyperbolic_barrier_landmarks(int num_vertices, const std::vector<WeightedEdge>& edges,
                                                     const RowMatrixX3i& faces,
                                                     const std::vector<hyperbolic::Mobius>& face_elements,
                                                     const std::vector<Complex>& free, const std::vector<int>& source,
                                                     const std::vector<Complex>& lifts,
                                                     const std::function<bool(int, double, double)>& progress = {});

/// How hold_hyperbolic_landmarks held the landmarks: `method` is "pinned"
/// (the exact held optimum), "barrier continuation" or "carried
/// neighbourhoods"; `rings` per landmark (all 0 unless carried), `solves`
/// the held solves (plain pins, continuation steps, carried rounds),
/// `held_vertices` those held in the accepted solve; the continuation's
/// steps, Newton iterations and how far it got (1 when it arrived, also
/// when its result was not used).
struct LandmarkHold {
  std::string method;
  std::vector<int> rings;
  int solves = 0, held_vertices = 0;
  int barrier_steps = 0, barrier_newton_iterations = 0;
  double barrier_reached = 0;
};

/// Hyperbolic case: re-solves the harmonic map (Riemannian Newton,
/// map/hyperbolic_harmonic.h) from the free optimum `free` (its vertex decks
/// relative to `edges`) with each source[k] held at the deck image of
/// target_position[k] (a point of the target's layout) nearest, in
/// hyperbolic distance, to where `free` put it; images are searched breadth
/// first over words in the layout's side pairings and their inverses (which
/// move the cut disk to its neighbours), pruned to those within reach of the
/// free position. With `faces` and `bad_faces` (the source faces a held
/// result folds; vertex decks relative to `edges`), landmarks whose plain
/// pins fold are moved there by hyperbolic_barrier_landmarks when
/// `face_elements` (as there, in the free optimum's charts) is given, and
/// when that does not arrive (or without it) carry their neighbourhoods
/// (grow_landmark_patches); `hold` receives the record. `generators` are
/// the solve's chart moves. The returned vertex decks are again relative to
/// `edges`. With `relaxation` the plain and carried held problems are solved
/// by the paper's per-vertex relaxation (map/harmonic_relaxation.h, the held
/// vertices skipped) with `relaxation_options` instead of Newton with
/// `options`; the continuation is Newton's in either case.
HyperbolicHarmonicResult hold_hyperbolic_landmarks(int num_vertices, const std::vector<WeightedEdge>& edges,
                                                   const std::vector<hyperbolic::Mobius>& generators,
                                                   const std::vector<hyperbolic::Mobius>& side_pairings,
                                                   const HyperbolicHarmonicResult& free, const std::vector<int>& source,
                                                   const std::vector<Complex>& target_position,
                                                   const std::vector<int>& target_vertex,
                                                   HyperbolicHarmonicOptions options, bool relaxation = false,
                                                   HarmonicRelaxationOptions relaxation_options = {},
                                                   const RowMatrixX3i* faces = nullptr,
                                                   const std::function<std::vector<int>(const HyperbolicHarmonicResult&)>&
                                                       bad_faces = {},
                                                   LandmarkHold* hold = nullptr,
                                                   const std::vector<hyperbolic::Mobius>* face_elements = nullptr);

}  // namespace surfmap::detail
