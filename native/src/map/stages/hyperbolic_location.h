#pragma once
// Stage "location" of the genus >= 2 map (docs/method.md §2.9: the outputs): every
// source vertex's image as a point on the target's input mesh (forward),
// every target vertex's preimage on the source (inverse), and the same two
// for the initial map (the "before" morph and UV transfer). One straight
// walk over the target's laid-out faces in the universal cover, resp. over
// the map's image triangles, with locate_in_cover (map/point_location.h) as
// the fallback. Internal to the pipeline (src/map/hyperbolic_map.cpp).
#include <memory>
#include <vector>

#include "../map_support.h"
#include "surfmap/map/fundamental_polygon.h"
#include "surfmap/map/initial_map.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap::detail {

struct LocationCover;

/// What the location reads. Sizes: #V / #F of the source, #3F halfedges.
struct HyperbolicLocationInput {
  const TriMesh* source = nullptr;
  const TriMesh* target = nullptr;  ///< the user's target (outputs are on it)
  const Connectivity* sc = nullptr;
  const Connectivity* tc = nullptr;
  const SystemOfLoops* target_loops = nullptr;  ///< the target's refined mesh (the layout's faces)
  const TargetIntrinsic* target_intrinsic = nullptr;  ///< its T' on the flip path (null: fixed connectivity)
  const DiskLayout* layout = nullptr;
  const FundamentalPolygon* polygon = nullptr;
  const DeckGroup* group = nullptr;
  /// The optimum: #V points in P, #E effective element of every source edge
  /// (its edge_halfedge, tail chart to head chart, after the moves into P),
  /// #F x 3 image corners (corner k of face f is the image of F(f, k),
  /// anchored at corner 0: γ_{f,0} = id, γ_{f,1} = eff(3f), γ_{f,2} = eff(3f+2)^-1).
  const std::vector<Complex>* zp = nullptr;
  const std::vector<hyperbolic::Mobius>* eff_edge = nullptr;
  const Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>* image = nullptr;
  /// The initial map and the class's #3F halfedge elements (matrices and
  /// side words) it is expressed in.
  const HyperbolicInitialMapResult* init = nullptr;
  const std::vector<hyperbolic::Mobius>* halfedge_rho = nullptr;
  const std::vector<Word>* halfedge_word = nullptr;
  int threads = 1;
  /// Locate the initial map too (InitialMapOptions::locate); false leaves
  /// initial_forward and initial_inverse empty.
  bool locate_initial = true;
  /// The target's cover (location_cover) when built ahead; nullptr: built
  /// by locate_hyperbolic_map.
  const LocationCover* cover = nullptr;
  /// The optimum's inverse without the waves (testing/map_hooks.h).
  bool inverse_full_search = false;
  /// The optimum's forward walks from the previous vertex's face towards
  /// the point itself, as before issue 19 (testing/map_hooks.h).
  bool forward_index_order = false;
};

/// How the optimum's inverse location found the target vertices (issue 19).
struct InverseLocationCounts {
  int in_frame = 0;        ///< a copy inside an image triangle (grid, no walk)
  int from_neighbour = 0;  ///< waves: walk from a located neighbour's face
  int from_grid = 0;       ///< walk from a grid candidate near a copy
  int full_scan = 0;       ///< reached the scan over all source faces (or the later fallbacks)
};
struct HyperbolicLocationResult {
  std::vector<PointOnSurface> forward;          ///< #V source
  std::vector<PointOnSurface> inverse;          ///< #V target
  std::vector<PointOnSurface> initial_forward;  ///< #V source, or empty when a vertex could not be located
  std::vector<PointOnSurface> initial_inverse;  ///< #V target, or empty likewise
  InverseLocationCounts inverse_counts;         ///< of `inverse`
  long forward_walk_steps = 0;                  ///< faces crossed by the optimum's forward walks
  long inverse_walk_steps = 0;                  ///< faces crossed by the optimum's inverse walks
};

/// The target's laid-out faces as a triangulation of the universal cover,
/// with their grid, and both surfaces' vertex neighbours: what every
/// location of one map walks over, whatever the class (issue 19, session
/// 23: built ahead, next to the full-resolution solves). Reads `source`,
/// `target`, `target_loops`, `layout` and `polygon` of `in`, which it
/// must not outlive.
std::shared_ptr<const LocationCover> location_cover(const HyperbolicLocationInput& in);

/// Locates the optimum, forward on the calling thread (reporting "forward
/// location" to `stage_done` when it is done) and inverse on the second
/// thread when there is one (after the forward with one thread), and the
/// initial map (when `locate_initial`) on whichever thread is free next. A
/// vertex of the optimum that cannot be located is a SolveError (the
/// forward's first); of the initial map, it leaves that output empty. The
/// result does not depend on `threads`.
HyperbolicLocationResult locate_hyperbolic_map(const HyperbolicLocationInput& in, const StageDone& stage_done);

}  // namespace surfmap::detail
