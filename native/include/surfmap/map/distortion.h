#pragma once
// Quality measures of a piecewise-linear map (paper §VII-A; DESIGN.md §2.11):
// per-triangle dilatation D' = Γ/γ (ratio of the singular values of the
// affine map from a source triangle to its image), its area-weighted mean and
// max, and flipped / degenerate image triangles.
#include <complex>
#include <vector>

#include <Eigen/Core>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

/// D' of the affine map taking the triangle with side lengths `source`
/// (opposite-corner order does not matter as long as both use the same
/// order: side k runs from corner k to corner k+1) onto the one with
/// side lengths `image`. Returns +inf for a degenerate image.
double triangle_dilatation(const Eigen::Vector3d& source_sides, const Eigen::Vector3d& image_sides);

struct DistortionStats {
  std::vector<double> per_face;  ///< #F dilatation D' (inf for degenerate or flipped images)
  double mean = 0;               ///< area-weighted by the source areas
  double max = 0;
  int flipped = 0;     ///< image triangles with negative orientation
  int degenerate = 0;  ///< image triangles with (near) zero area
  /// Source triangles of (near) zero area (D' undefined: infinite, left out
  /// of mean and max, which they would not weigh in anyway).
  int degenerate_source = 0;
};

/// Source triangles in 3D, images as #F x 3 planar corner positions (complex
/// numbers; corner k of face f is the image of F(f,k)). Flipped and
/// degenerate image triangles are counted; their D' is infinite and they are
/// left out of mean and max (which are then meaningless: check the counts).
DistortionStats planar_distortion(const RowMatrixX3d& V, const RowMatrixX3i& F,
                                  const Eigen::Matrix<std::complex<double>, Eigen::Dynamic, 3, Eigen::RowMajor>& image);

}  // namespace surfmap
