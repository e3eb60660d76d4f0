#pragma once
// The paper's relaxation for the discrete harmonic map into a hyperbolic
// surface (docs/method.md §2.8, "heat diffusion" in Möbius-centred local charts;
// docs/method.md §2.8), kept beside the Riemannian Newton solver
// (map/hyperbolic_harmonic.h) so the two can be compared on the same input.
//
// Same problem as hyperbolic_harmonic_map: minimise
// E(z) = Σ_e w_e d(z_i, ρ_e z_j)² over one point z_i per vertex in the
// Poincaré disk, with a deck element ρ_e per edge i->j and weights w_e >= 0
// (round-off negatives down to −1e-12 · max w, as intrinsic Delaunay
// cotangents produce, are accepted and used as 0).
//
// Method (Gauss–Seidel sweeps over the vertices in index order): in the chart
// centring z_i the neighbours' images ρ_ij z_j sit at log_{z_i}(ρ_ij z_j);
// their weighted average v_i = Σ w log / Σ w is where the Euclidean heat flow
// would move z_i, and the paper moves half way:
//     z_i <- exp_{z_i}(step · v_i),   step = ½.
// Along that geodesic the vertex's own energy has slope −2 Σw |v_i|² and
// curvature between 2 Σw |v_i|² and 2 Σw |v_i|² · max d coth d (docs/method.md §7),
// so step ½ decreases it whenever the incident image edges are shorter than
// about 3.8; longer ones (far from the optimum, e.g. an all-at-origin start)
// get a backtracking check on the vertex's energy, so E never increases.
// Vertices that wander far from the origin are moved back by deck elements
// after each sweep (the paper's dynamic charts, docs/method.md §2.6), exactly as the Newton
// solver does. Convergence test: the same relative gradient tolerance as
// Newton (largest per-vertex gradient |2 Σ w log| <= tolerance · max w).
//
// A sweep costs O(#E); the number of sweeps per decade of gradient grows
// like the condition number of the weight Laplacian (~ #V on a mesh), which
// is why Newton is the default.
#include <complex>
#include <functional>
#include <string>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/map/hyperbolic_harmonic.h"

namespace surfmap {

struct HarmonicRelaxationOptions {
  /// Stop when the largest per-vertex gradient length is below this times
  /// the largest weight (default 1e-10, as HyperbolicHarmonicOptions).
  double tolerance = 1e-10;
  /// Sweep cap (default 100000). Reaching it is reported as converged=false.
  int max_iterations = 100000;
  /// Fraction of the move to the neighbours' chart-centred average (default
  /// ½, the paper's heat-diffusion step; 1 is the plain Gauss–Seidel
  /// update, which may overshoot on long hyperbolic edges).
  double step = 0.5;
  /// Stop (converged=false) after this many seconds of sweeping; 0 (default)
  /// means no budget. Used by the benchmark to extrapolate slow runs.
  double time_budget_s = 0;
  /// Energy and gradient are evaluated (one extra pass over the edges) every
  /// this many sweeps (default 1); the convergence test runs only then.
  int check_every = 1;
  /// Called at every evaluation with (sweep, energy, gradient norm); return
  /// false to cancel (throws Cancelled).
  std::function<bool(int, double, double)> progress;
  /// #V or empty (default): vertices held at their start point (landmarks,
  /// docs/method.md §2.10), as HyperbolicHarmonicOptions::fixed: never relaxed, and
  /// left out of the convergence test's gradient. A chart move may still
  /// change a held vertex's point by a deck element (same point on the target).
  std::vector<char> fixed;
};

struct HarmonicRelaxationResult {
  bool converged = false;
  /// Sweeps done.
  int iterations = 0;
  /// At every evaluation (the start included): energy, largest per-vertex
  /// gradient length, the sweep count, and the cumulative seconds spent in
  /// sweeps (evaluation passes excluded, so the curve measures the method).
  std::vector<double> energy_history, gradient_history, time_history;
  std::vector<int> sweep_history;
  /// #V points in the Poincaré disk and the deck element applied to each
  /// vertex (effective element of edge i->j: vertex_deck[i] · ρ · vertex_deck[j]⁻¹).
  std::vector<std::complex<double>> z;
  std::vector<hyperbolic::Mobius> vertex_deck;
  /// Hyperbolic only (empty for the flat one): the same decks as freely
  /// reduced words in the generators' letters (+(k+1) = generators[k],
  /// -(k+1) its inverse, product order as written), and per edge its
  /// effective element at the end, kept up to date move by move from small
  /// matrices: as HyperbolicHarmonicResult::vertex_deck_word and
  /// edge_effective. A deck accumulated over a long class's edges has huge
  /// entries and vertex_deck[i] * rho * vertex_deck[j]^-1 keeps no digits;
  /// the held solves after it (landmarks) need these instead
  /// (docs/history/handle_classes.md "Session 25").
  std::vector<Word> vertex_deck_word;
  std::vector<hyperbolic::Mobius> edge_effective;
  double energy = 0;
  /// Wall time of the whole call (sweeps and evaluations).
  double time_s = 0;
  /// "tolerance", "iteration cap" or "time budget".
  std::string stop_reason;
};

/// Same inputs as hyperbolic_harmonic_map: `generators` of the deck group
/// (their inverses are used too) for the dynamic charts, `z0` #V start
/// points inside the disk. Throws InputError on bad sizes or start points,
/// Cancelled from the progress callback.
HarmonicRelaxationResult harmonic_relaxation(int num_vertices, const std::vector<WeightedEdge>& edges,
                                             const std::vector<hyperbolic::Mobius>& generators,
                                             std::vector<std::complex<double>> z0,
                                             const HarmonicRelaxationOptions& options = {});

/// The flat counterpart (genus 1, for comparison with the exact solve):
/// E = Σ w |z_i − z_j − t_ij|² with a lattice translation t per edge i->j,
/// the same Gauss–Seidel sweeps with step `options.step` towards the
/// weighted average of the neighbours' images z_j + t_ij. No deck moves are
/// needed (translations commute). `z0`: #V start points.
HarmonicRelaxationResult flat_harmonic_relaxation(int num_vertices, const std::vector<int>& edge_i,
                                                  const std::vector<int>& edge_j, const std::vector<double>& weight,
                                                  const std::vector<std::complex<double>>& translation,
                                                  std::vector<std::complex<double>> z0,
                                                  const HarmonicRelaxationOptions& options = {});

/// The harmonic-map problem of one surface map as the solvers see it, handed
/// to SurfaceMapOptions::inspect_problem (benchmarks and tests run both
/// solvers on exactly the pipeline's input). Hyperbolic (genus >= 2):
/// `edges` with their deck elements expressed in the start's charts, the
/// target's `generators` and the `start` points. Flat (genus 1): edge ends,
/// weights and lattice translations of the chosen class (energy
/// Σ w |z_j + t − z_i|²) and the start (the initial map).
struct HarmonicProblem {
  bool flat = false;
  int num_vertices = 0;
  std::vector<WeightedEdge> edges;
  std::vector<hyperbolic::Mobius> generators;
  std::vector<int> flat_i, flat_j;
  std::vector<double> flat_weight;
  std::vector<std::complex<double>> flat_translation;
  std::vector<std::complex<double>> start;
  /// Hyperbolic: the group's relator in generator letters and the
  /// pipeline's reduction into the fundamental polygon, as the Newton solve
  /// uses them (HyperbolicHarmonicOptions::relator, reduce_point; the edges
  /// carry their side words). reduce_point is valid only during the call.
  Word relator;
  std::function<Word(std::complex<double>&)> reduce_point;
};

/// The relaxation's outcome in the form of HyperbolicHarmonicResult, for
/// callers that accept either solver (iterations = sweeps; the histories are
/// those of the evaluations).
HyperbolicHarmonicResult as_harmonic_result(HarmonicRelaxationResult r);

}  // namespace surfmap
