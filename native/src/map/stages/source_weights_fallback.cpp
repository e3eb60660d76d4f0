#include "source_weights_fallback.h"

#include "surfmap/error.h"

namespace surfmap::detail {

std::string source_weights_name(bool own_weights, int raised) {
  if (own_weights) return "positive on the source's own edges";
  if (raised == 0) return "intrinsic Delaunay cotangent";
  return "intrinsic Delaunay cotangent, except " + std::to_string(raised) +
         " edge(s) at tips of cone angle < pi kept unflipped with a positive floor weight";
}

void store_initial_distortion(const DistortionStats& q0, SurfaceMapResult& out) {
  out.initial_dilatation = q0.per_face;
  out.initial_mean_dilatation = q0.mean;
  out.initial_max_dilatation = q0.max;
  out.initial_flipped_triangles = q0.flipped;
}

void store_distortion(const DistortionStats& q, SurfaceMapResult& out) {
  out.dilatation = q.per_face;
  out.mean_dilatation = q.mean;
  out.max_dilatation = q.max;
  out.thin_source_faces = q.thin_source;
  out.thin_source_max_dilatation = q.thin_source_max;
  out.flipped_triangles = q.flipped;
  // Flat but positive images (q.flat) are one-to-one: not counted here, so
  // that only truly degenerate ones (orientation round-off) fold a class.
  // Their D' is +inf in `dilatation`, out of mean and max.
  out.degenerate_triangles = q.degenerate - q.flat;
  out.flat_triangles = q.flat;
}

bool retry_with_own_weights(const SurfaceMapOptions& options, bool own_weights, const SurfaceMapResult& out) {
  if (!out.flipped_triangles && !out.degenerate_triangles) return false;
  if (!own_weights && options.solve.source_weights == SourceWeights::Automatic) return true;
  throw SolveError("the optimised map has " + std::to_string(out.flipped_triangles) + " flipped and " +
                   std::to_string(out.degenerate_triangles) + " degenerate image triangles of the source's faces (" +
                   std::to_string(out.intrinsic_flipped_triangles) +
                   " flipped on its intrinsic Delaunay triangulation, where the energy lives); it is not returned",
                   SolveFailure::folds);
}

}  // namespace surfmap::detail
