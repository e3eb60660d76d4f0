#pragma once
// Hooks into the surface-map pipeline for tests and benchmarks, kept out of
// the public options (map/surface_map.h): they expose intermediate problems
// and steer internal choices, which applications have no use for.
#include <functional>
#include <string>
#include <vector>

#include "surfmap/map/surface_map.h"

namespace surfmap {
struct HarmonicProblem;       // map/harmonic_relaxation.h
struct InitialMapInspection;  // map/initial_map.h
}  // namespace surfmap

namespace surfmap::testing {

struct MapHooks {
  /// Called once with the harmonic-map problem just before it is solved
  /// (genus >= 1; map/harmonic_relaxation.h, HarmonicProblem), e.g. to run
  /// another solver on exactly the same input.
  std::function<void(const HarmonicProblem&)> inspect_problem;
  /// Genus >= 2: called with the initial map and its inputs
  /// (map/initial_map.h, InitialMapInspection) once it is built.
  std::function<void(const InitialMapInspection&)> inspect_initial_map;
  /// Genus >= 2, default class: start the class search
  /// (SurfaceMapOptions::homotopy.search) from this candidate (-1: the best
  /// on the coarse copy) composed on the source side with the named moves
  /// of topology/mapping_class_search.h twist_moves, in order (e.g.
  /// {"T(a1)", "T(a1)"}; an unknown name is an InputError). A start given
  /// here skips stage 1 (more cuts) of the search.
  int homotopy_search_start = -1;
  /// Genus >= 2: locate the optimum's inverse without the waves (issue 19):
  /// every target vertex with no copy inside an image triangle by the walk
  /// from the nearest corner 0 over all source faces (the reference search).
  bool inverse_full_search = false;
  /// Genus >= 2: called with how the optimum's inverse location found the
  /// target vertices: by the grid alone, by a walk from a located
  /// neighbour (waves), from a grid candidate, after the scan over all faces.
  std::function<void(int in_frame, int from_neighbour, int from_grid, int full_scan)> inverse_location_counts;
  /// Genus >= 2: walk the optimum's forward location from the previous
  /// source vertex's face towards the point itself (the start before issue
  /// 19's neighbour starts and side-map lifts; the reference of a test).
  bool forward_index_order = false;
  /// Genus >= 2: called with the faces crossed by the optimum's forward and
  /// inverse location walks (issue 19: their cost, independent of load).
  std::function<void(long forward_steps, long inverse_steps)> location_walk_steps;
  /// Genus >= 2: the fallback loop maps every fallback class as before
  /// issue 13's session 25, none refused on its full-resolution solve
  /// without its initial map (the reference of a test).
  bool map_every_fallback = false;
  std::vector<std::string> homotopy_search_start_twists;
  /// Called with the options of each run surface_map makes of the pair, the
  /// first and the automatic retries' (LoopOptions::short_generators_fallback,
  /// fold_fallback), before it starts; what it throws ends that run as the
  /// run's own failure would (a test's way to fail one run and not its retry).
  std::function<void(const SurfaceMapOptions&)> before_run;
  /// Genus >= 2, the one Poincare chart's path: called with the run's
  /// options just before its one-way map; what it throws ends that map as
  /// its own failure would, where the two-way run's rescue reads it (a
  /// test's way to give that failure a chosen reason and words).
  std::function<void(const SurfaceMapOptions&)> before_one_way_map;
  /// Makes the maps of the runs a genus >= 2 run makes of other settings in
  /// its rescue by the other direction (two_way_run.h
  /// rescue_by_the_other_direction: the other direction, the cuts at another
  /// vertex), in place of the public surface_map, which the hook may call (a
  /// test's way to record them or fail one).
  std::function<SurfaceMapResult(const TriMesh&, const TriMesh&, const SurfaceMapOptions&)> rescue_run;
};

/// surface_map (map/surface_map.h) with the hooks.
SurfaceMapResult surface_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                             const MapHooks& hooks);

}  // namespace surfmap::testing
