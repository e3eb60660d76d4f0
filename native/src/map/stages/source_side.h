#pragma once
// The source's side of the genus >= 2 homotopy data (docs/method.md §2.6), which
// needs no target: built on the second thread while the target is
// uniformized. Internal to src/map/hyperbolic_map.cpp.
#include <functional>
#include <vector>

#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/coarse_source.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/system_of_loops.h"

namespace surfmap::detail {

struct SourceSide {
  SystemOfLoops sl;             ///< the source's (unrefined) system of loops
  CanonicalSchema scs;          ///< its canonical schema
  std::vector<Word> edge_word;  ///< #E each edge's element as a word in the loop letters
  IntrinsicDelaunayResult idt;  ///< the energy's triangulation and weights
  HandleBasis shb;              ///< meridian/longitude basis (topology/handle_basis.h)
  CoarseSource cs;              ///< the coarse copy for the ranking (ok = false: rank at full resolution)
};

/// `own_weights`: positive weights on the source's own edges instead of
/// intrinsic Delaunay cotangents (SourceWeights). The coarse copy is built
/// when options.homotopy.coarse_vertices > 0 and min(that, #V / 4) >= 500.
/// Throws SolveError when the intrinsic Delaunay flips do not finish.
/// `graph`: the source's greedy graph when the caller has one (SourceCuts).
/// `step` (optional): called between the side's parts and inside the coarse
/// copy's sampling with the fraction of the side done (about its share of
/// the time at 50k vertices); false stops the side with Cancelled.
SourceSide build_source_side(const TriMesh& source, const Connectivity& sc, const SurfaceMapOptions& options,
                             bool own_weights, const GreedyGraph* graph = nullptr,
                             const std::function<bool(double)>& step = nullptr);

}  // namespace surfmap::detail
