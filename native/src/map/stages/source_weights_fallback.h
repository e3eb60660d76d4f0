#pragma once
// The automatic source weights' fallback and the map's quality record,
// shared by genus 1 (flat_map.cpp) and genus >= 2 (hyperbolic_map.cpp):
// with intrinsic Delaunay cotangent weights the intrinsic triangulation's
// image is an embedding, but straight images of the user's own faces can
// fold (slivers, caps); positive weights on the source's own edges embed
// those faces (the Tutte-type theorem on the torus and beyond). With
// SourceWeights::Automatic the chosen class is then solved again with them;
// the class stays (docs/method.md §2.8). Internal to the pipeline.
#include <string>

#include "surfmap/map/distortion.h"
#include "surfmap/map/surface_map.h"

namespace surfmap::detail {

/// The report's name of the weights in use (SurfaceMapResult::source_weights).
/// `raised`: edges of the intrinsic triangulation whose weight was raised
/// (delaunay_energy_weights, tips of cone angle < pi).
std::string source_weights_name(bool own_weights, int raised = 0);

/// D' of the initial map (`q0`, per source face) into out.initial_*.
void store_initial_distortion(const DistortionStats& q0, SurfaceMapResult& out);

/// D' of the optimised map (`q`, per source face) with its flipped and
/// degenerate counts into `out`; degenerate_triangles counts only the truly
/// degenerate images (q.degenerate - q.flat: orientation round-off), not the
/// flat but positive ones (one-to-one; their D' is +inf in `dilatation`),
/// which are flat_triangles.
void store_distortion(const DistortionStats& q, SurfaceMapResult& out);

/// What becomes of the optimised map recorded in `out` (store_distortion and
/// out.intrinsic_flipped_triangles set): true when its source faces fold and
/// the automatic fallback applies (weights not yet `own_weights`): the caller
/// switches to own-edge weights and maps the chosen class again. False when
/// no face folds (flat but positive faces, DistortionStats::flat, do not
/// fold: a class is not rejected for them). SolveError naming the counts when faces fold and the
/// fallback does not apply: a folded map is not returned.
bool retry_with_own_weights(const SurfaceMapOptions& options, bool own_weights, const SurfaceMapResult& out);

}  // namespace surfmap::detail
