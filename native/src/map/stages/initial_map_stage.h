#pragma once
// Stage "initial map" of the genus >= 2 map (docs/method.md §2.7 as adapted in
// map/initial_map.h): the chosen class's "before" map and the default start
// of its harmonic solve. Internal to src/map/hyperbolic_map.cpp.
#include <atomic>
#include <optional>
#include <vector>

#include "class_data.h"
#include "surfmap/map/distortion.h"
#include "surfmap/map/fundamental_polygon.h"
#include "surfmap/map/initial_map.h"

namespace surfmap::detail {

/// A class's initial map with the #3F halfedge elements it is expressed in.
struct ClassInitialMap {
  std::vector<hyperbolic::Mobius> halfedge_rho;
  std::vector<Word> halfedge_word;
  HyperbolicInitialMapResult init;
  /// Its D' (initial_map_distortion) when computed ahead, next to the
  /// full-resolution solves (issue 19); empty: computed when needed.
  std::optional<DistortionStats> distortion;
};

/// The initial map of the class with data `cd` (map/initial_map.h, by
/// options.initial.method: the cut-graph polygon, the loops' polygon, the
/// uniform-weight map; `start_z`/`start_word` (#V, or empty): the
/// uniform-weight solve's start). When every construction fails, every
/// vertex at the origin (its degenerate triangles are then reported).
/// `stop` (another thread's task, concurrency.h): gives up (Cancelled) when raised.
ClassInitialMap class_initial_map(const ClassData& cd, const TriMesh& source, const Connectivity& sc,
                                  const SystemOfLoops& sl, const DeckGroup& group, const FundamentalPolygon& polygon,
                                  const SurfaceMapOptions& options, const std::atomic<bool>* stop,
                                  std::vector<std::complex<double>> start_z = {}, std::vector<Word> start_word = {});

/// D' of the initial map (from reduced words when it has them:
/// initial_map.h, the matrix products lose digits for large decks).
DistortionStats initial_map_distortion(const TriMesh& source, const DeckGroup& group, const ClassInitialMap& initial);

}  // namespace surfmap::detail
