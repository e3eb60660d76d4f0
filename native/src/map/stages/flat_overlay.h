#pragma once
// The genus-1 map's placement by the 3D overlay (issue 13/14: a remeshed or
// posed copy of a torus must map to itself). The harmonic map into a flat
// torus is unique only up to the torus's translations, and a class M and
// its negative -M (the half turn z -> -z) have the same energy; on a torus
// of revolution both are isometries of the shape (a rotation about its axis,
// a half turn about a horizontal axis), so the energy cannot choose. Here
// the shapes' 3D overlay does: every sampled source vertex is sent to the
// nearest target vertex (as posed, or after a rigid pose of
// rotation_overlay_poses, both shapes centred on their boxes and scaled by
// their diagonals), and the translation s that best carries the flat image
// z_i + s onto that vertex's flat position (modulo the lattice) is fitted.
// Internal to src/map/flat_map.cpp.
#include <complex>
#include <string>
#include <vector>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::detail {

struct FlatOverlayOptions {
  /// Source vertices sampled (evenly along the vertex list; default 4000).
  int max_samples = 4000;
  /// Fits whose mean residual exceeds this fraction of sqrt(area of the
  /// torus) do not overlap (default 0.1; a copy fits within about a mean
  /// edge, 0.01-0.02 at 10k vertices; a wrong sign or translation of a
  /// torus of revolution leaves residuals of 0.2-0.4).
  double max_residual = 0.1;
};

struct FlatOverlayFit {
  /// The best pose fits within FlatOverlayOptions::max_residual.
  bool overlaps = false;
  /// Translation to add to every source image z_i.
  std::complex<double> shift;
  /// Mean flat distance (modulo the lattice) from z_i + shift to the flat
  /// position of the target vertex nearest source vertex i in 3D, over the
  /// samples, divided by sqrt(area of the torus); +inf without a pose.
  double residual = 0;
  /// "as posed" or the pose's description (rotation_overlay_poses).
  std::string pose;
  /// The shapes overlap as posed (then no rotation was tried).
  bool as_posed = false;
};

/// The 3D overlay of a pair, for fitting the flat images of several classes:
/// the nearest target vertex of every sampled source vertex is found once
/// per pose (as posed, then rotation_overlay_poses(source, target)).
class FlatOverlay {
 public:
  /// `target_flat`: the flat position of every target vertex (its first #V
  /// target entries are used), on the torus of lattice (w1, w2).
  FlatOverlay(const TriMesh& source, const TriMesh& target, const std::vector<std::complex<double>>& target_flat,
              std::complex<double> w1, std::complex<double> w2, const FlatOverlayOptions& options = {});
  /// The translation of the flat images `z` (#V source) by the overlay as
  /// posed when it fits within FlatOverlayOptions::max_residual, else by the
  /// best-fitting rotation.
  FlatOverlayFit fit(const std::vector<std::complex<double>>& z) const;

 private:
  struct Pose {
    std::string description;
    std::vector<int> nearest;  ///< per sample, the nearest target vertex
  };
  std::vector<std::complex<double>> target_flat_;
  std::complex<double> w1_, w2_;
  FlatOverlayOptions options_;
  std::vector<int> samples_;  ///< sampled source vertices
  std::vector<Pose> poses_;
};

}  // namespace surfmap::detail
