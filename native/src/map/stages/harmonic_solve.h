#pragma once
// Stage "harmonic solve" of the genus >= 2 map (docs/method.md §2.8 and
// its notes): the chosen class's harmonic map, by Riemannian Newton
// (map/hyperbolic_harmonic.h) or the paper's relaxation
// (map/harmonic_relaxation.h), from its initial map. Internal to
// src/map/hyperbolic_map.cpp.
#include <functional>
#include <memory>
#include <vector>

#include "class_data.h"
#include "surfmap/map/harmonic_relaxation.h"
#include "surfmap/map/fundamental_polygon.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/map/initial_map.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap::detail {

using SolveProgress = std::function<bool(int iteration, double energy, double gradient)>;

/// The progress of the chosen class's solves for options.solve_progress and
/// options.progress ("harmonic solve", 0.45 .. 0.7): Newton by iterations,
/// the relaxation (thousands of sweeps) by the decades of gradient done
/// from its first gradient down to the tolerance. One object serves the
/// free solve and the landmark holds (the first gradient is shared).
SolveProgress chosen_solve_progress(const SurfaceMapOptions& options);

struct ChosenSolve {
  /// The optimum: #V points, vertex decks relative to the class's edges
  /// (composed back from the start's), solver charts.
  HyperbolicHarmonicResult result;
  /// Energy of the initial map (the start, before start_seed replaces it).
  double initial_energy = 0;
  /// The ranking's full-resolution solve was kept (Newton from the default start).
  bool reused = false;
};

/// `edges`: the class's solver edges (ClassData::edges); `init`: its
/// initial map (#V z, decks as words). `ranked`: the class's converged
/// full-resolution solve from the ranking (may be null); its optimum
/// (convex energy) is kept unless another start (start_seed) or method is
/// asked for. Calls `inspect_problem` (testing/map_hooks.h) with the
/// problem as solved. `start` (may be null; #V z and decks as words): where
/// the solve starts instead of the initial map (issue 13: the class's
/// optimum with the other source weights); initial_energy stays the
/// initial map's. `max_start_edge_size`: the Newton solve's
/// (HyperbolicHarmonicOptions::max_start_edge_size; the pipeline raises it
/// when every candidate's start was refused).
/// Newton solves run on `solver` (the class level's pattern). Throws
/// SolveError when the solve does not converge, Cancelled.
ChosenSolve solve_chosen_class(int num_vertices, const std::vector<WeightedEdge>& edges,
                               const HyperbolicInitialMapResult& init, const DeckGroup& group,
                               const FundamentalPolygon& polygon, const SurfaceMapOptions& options,
                               std::unique_ptr<HyperbolicHarmonicResult> ranked, const SolveProgress& progress,
                               PatternSolver* solver,
                               const std::function<void(const HarmonicProblem&)>& inspect_problem = {},
                               const HyperbolicInitialMapResult* start = nullptr,
                               double max_start_edge_size = HyperbolicHarmonicOptions().max_start_edge_size);

}  // namespace surfmap::detail
