#include "harmonic_solve.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "surfmap/error.h"
#include "surfmap/map/harmonic_relaxation.h"

namespace surfmap::detail {

using hyperbolic::Mobius;
using Complex = std::complex<double>;

SolveProgress chosen_solve_progress(const SurfaceMapOptions& options) {
  // Progress fraction: Newton by iterations; the relaxation (thousands of
  // sweeps) by how many of the decades from its first gradient down to the
  // tolerance are done.
  auto first_gradient = std::make_shared<double>(-1);
  return [&options, first_gradient](int it, double E, double g) {
    if (options.solve_progress && !options.solve_progress(it, E, g)) return false;
    if (*first_gradient < 0) *first_gradient = g;
    double done = std::min(1.0, it / 50.0);
    if (options.solve.method == MapMethod::Relaxation && *first_gradient > 0 && g > 0) {
      const double decades = std::log(*first_gradient / std::max(options.solve.tolerance, 1e-300));
      done = decades > 0 ? std::clamp(std::log(*first_gradient / g) / decades, 0.0, 1.0) : 1.0;
    }
    return !options.progress || options.progress("harmonic solve", 0.7 + 0.1 * done);
  };
}

ChosenSolve solve_chosen_class(int num_vertices, const std::vector<WeightedEdge>& edges,
                               const HyperbolicInitialMapResult& init, const DeckGroup& group,
                               const FundamentalPolygon& polygon, const SurfaceMapOptions& options,
                               std::unique_ptr<HyperbolicHarmonicResult> ranked, const SolveProgress& progress,
                               PatternSolver* solver, const std::function<void(const HarmonicProblem&)>& inspect_problem,
                               const HyperbolicInitialMapResult* start_map, double max_start_edge_size) {
  ChosenSolve solved;
  // The solve runs on the edges expressed in the initial map's charts
  // (effective elements), its vertex decks are composed back afterwards.
  // Conjugated as reduced side words (the initial map's decks are side
  // words too), never as products of the deck matrices.
  std::vector<WeightedEdge> start_edges = edges;
  for (auto& e : start_edges) {
    e.rho_word = group.reduce(
        concat({init.vertex_deck_word[e.i], e.rho_word, inverse(init.vertex_deck_word[e.j])}));
    e.rho = group.evaluate_side_word(e.rho_word);
  }
  std::vector<Complex> start = init.z;
  std::vector<Mobius> start_deck = init.vertex_deck;
  std::vector<Word> start_deck_word = init.vertex_deck_word;
  solved.initial_energy = hyperbolic_energy(start_edges, start, std::vector<Mobius>(start.size()));
  if (start_map) {
    // (The same conjugation, by the given start's decks.)
    start_edges = edges;
    for (auto& e : start_edges) {
      e.rho_word = group.reduce(
          concat({start_map->vertex_deck_word[e.i], e.rho_word, inverse(start_map->vertex_deck_word[e.j])}));
      e.rho = group.evaluate_side_word(e.rho_word);
    }
    start = start_map->z;
    start_deck = start_map->vertex_deck;
    start_deck_word = start_map->vertex_deck_word;
  }
  if (options.solve.start_seed != 0) {
    std::mt19937 rng(options.solve.start_seed);
    std::uniform_real_distribution<double> U(-0.35, 0.35);
    for (Complex& z : start) z = Complex(U(rng), U(rng));
    start_edges = edges;
    start_deck.assign(start.size(), Mobius());
    start_deck_word.assign(start.size(), Word{});
  }
  if (inspect_problem) {
    HarmonicProblem p;
    p.num_vertices = num_vertices;
    p.edges = start_edges;
    p.generators = group.side_pairings();
    p.start = start;
    p.relator = group.side_relator();
    p.reduce_point = [&](Complex& z) { return polygon.reduce(z); };
    inspect_problem(p);
  }
  HyperbolicHarmonicResult& hr = solved.result;
  // The class's full-resolution Newton solve from the ranking is its
  // optimum (convex energy): kept, unless another start or method is asked
  // for (uniqueness checks, the relaxation for comparison).
  const bool reuse = ranked && options.solve.method == MapMethod::Newton && options.solve.start_seed == 0;
  solved.reused = reuse;
  if (reuse) {
    hr = std::move(*ranked);
    // solve_progress saw the requested class's solve live; otherwise (the
    // default class is known only after the ranking) its iterations are
    // reported now.
    if (options.homotopy.class_index < 0 && options.solve_progress)
      for (size_t it = 0; it < hr.gradient_history.size(); ++it)
        if (!options.solve_progress(static_cast<int>(it), hr.energy_history[std::min(it, hr.energy_history.size() - 1)],
                                    hr.gradient_history[it]))
          throw Cancelled("harmonic map solve cancelled");
  } else if (options.solve.method == MapMethod::Relaxation) {
    HarmonicRelaxationOptions ro;
    ro.tolerance = options.solve.tolerance;
    ro.max_iterations = options.solve.max_iterations;
    ro.check_every = 10;  // the evaluation pass costs about a sweep
    ro.progress = progress;
    hr = as_harmonic_result(harmonic_relaxation(num_vertices, start_edges, group.side_pairings(), start, ro));
  } else {
    HyperbolicHarmonicOptions ho;
    ho.tolerance = options.solve.tolerance;
    ho.max_iterations = options.solve.max_iterations;
    ho.progress = progress;
    ho.relator = group.side_relator();
    ho.reduce_point = [&](Complex& z) { return polygon.reduce(z); };
    ho.max_start_edge_size = max_start_edge_size;
    hr = solver->solve(num_vertices, start_edges, group.side_pairings(), start, ho);
  }
  if (!reuse) {
    for (size_t i = 0; i < hr.vertex_deck.size(); ++i) hr.vertex_deck[i] = (hr.vertex_deck[i] * start_deck[i]).normalized();
    if (hr.vertex_deck_word.size() == hr.vertex_deck.size())
      for (size_t i = 0; i < hr.vertex_deck_word.size(); ++i)
        hr.vertex_deck_word[i] = group.reduce(concat(hr.vertex_deck_word[i], start_deck_word[i]));
  }
  if (!hr.converged)
    throw SolveError(std::string("the harmonic map solve (") +
                     (options.solve.method == MapMethod::Relaxation ? "relaxation" : "Newton") + ") did not converge in " +
                     std::to_string(hr.iterations) + " iterations (gradient " +
                     std::to_string(hr.gradient_history.back()) + "); raise max_iterations or the tolerance");
  return solved;
}

}  // namespace surfmap::detail
