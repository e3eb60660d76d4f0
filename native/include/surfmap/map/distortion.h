#pragma once
// Quality measures of a piecewise-linear map (docs/method.md §2.11):
// per-triangle dilatation D' = Γ/γ (ratio of the singular values of the
// affine map from a source triangle to its image), its area-weighted mean and
// max, and flipped / degenerate image triangles.
#include <complex>
#include <functional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

/// D' of the affine map taking the triangle with side lengths `source`
/// (opposite-corner order does not matter as long as both use the same
/// order: side k runs from corner k to corner k+1) onto the one with
/// side lengths `image`. Returns +inf for a degenerate image.
double triangle_dilatation(const Eigen::Vector3d& source_sides, const Eigen::Vector3d& image_sides);

/// An image triangle 0, b, c is flat (degenerate) when |b x c| is not above
/// this times max(|b|², |c|²): its D' would be about 1/this or more. 1e-9,
/// not the round-off of the chart (1e-16): a converged map can leave a face
/// of an ordinary source triangle at the edge of a fold with |b x c| ~ 8e-11
/// max(|b|², |c|²) and D' 7e9 (docs/robustness.md, held-out sweep, "D' of
/// jittered and collinear sources"); counted as flat, the fold repair moves
/// it like a folded one. The fold repair's own "positive with a margin" is
/// the same bound, so that what it accepts is not flat here.
///
/// Flat is not folded: a flat image whose |b x c| is still above
/// kRoundOffRelativeCross max(|b|², |c|²) is positively oriented beyond the
/// chart's round-off, so the map is one-to-one there, only extremely
/// stretched (DistortionStats::flat). Such faces start the fold repair but
/// never reject a class: far-from-conformal maps (a 532-vertex CAD plate onto
/// the fertility, mean D' ~150) can leave a few of them in every class, and
/// counting them as folds had sent all of that pair's classes to the rescue
/// (docs/handle_classes.md, "Flat images, folds and the own-edge retry").
constexpr double kFlatImageRelativeCross = 1e-9;

/// Below this |b x c| / max(|b|², |c|²) an image triangle's orientation is
/// round-off (chart coordinates carry ~1e-16 relative error): degenerate,
/// the map is not known to be one-to-one there. The planar measure's
/// degenerate bound too.
constexpr double kRoundOffRelativeCross = 1e-14;

/// Orientation of the triangle with corners 0, b, c: +1, -1 (flipped) or 0
/// (degenerate: |cross| not above kFlatImageRelativeCross max(|b|², |c|²),
/// non-finite included). For a hyperbolic image seen in a chart centring its
/// corner 0 (Möbius maps preserve orientation) as for a planar one.
int image_orientation(std::complex<double> b, std::complex<double> c);

/// D' of one source face (3D corners p0, p1, p2) onto a positively oriented
/// geodesic triangle of the Poincaré disk with corners 0, b, c in a chart and
/// hyperbolic side lengths `image_sides` (side k from corner k to k+1): from
/// the side lengths (docs/method.md §2.11). With `thin_images`, a needle-thin image
/// (a + b - c below 1e-4 of the perimeter: the lengths' round-off, ~1e-9
/// relative after a long solve, leaves the frame built from them
/// meaningless, although the orientation was resolved) is measured by the
/// affine map to the image seen from the chart centring its centroid (D' is
/// scale-free, so the conformal factor there does not matter), with the
/// source frame from the 3D corners: D' + 1/D' = |A|_F²/|det A|. The
/// optimum's figures use it; the initial map's do not (yet), so that their
/// printed values stay those of before.
double hyperbolic_face_dilatation(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                                  std::complex<double> b, std::complex<double> c, const Eigen::Vector3d& image_sides,
                                  bool thin_images);

struct DistortionStats {
  std::vector<double> per_face;  ///< #F dilatation D' (inf for degenerate or flipped images)
  double mean = 0;               ///< area-weighted by the source areas
  double max = 0;
  int flipped = 0;     ///< image triangles with negative orientation
  int degenerate = 0;  ///< image triangles with (near) zero area (image_orientation 0)
  /// Of the degenerate ones: flat but positively oriented beyond round-off
  /// (|b x c| above kRoundOffRelativeCross max(|b|², |c|²)): D' ~1e9 or
  /// more, left out of mean and max like the others, but not folded (the map
  /// is one-to-one there). degenerate - flat are the truly degenerate ones.
  int flat = 0;
  /// Source triangles of (near) zero area (D' undefined: infinite, left out
  /// of mean and max, which they would not weigh in anyway).
  int degenerate_source = 0;
  /// Thin source triangles (thin_source_faces; the zero-area ones among
  /// them): their D' is kept in per_face but left out of mean and max (it
  /// measures the 3D triangle's last digits, not the map); listed here, with
  /// the largest finite D' among them. Flipped or degenerate images of thin
  /// faces are still counted in flipped / degenerate.
  std::vector<int> thin_source;
  double thin_source_max = 0;
};

/// Per face of (V, F): 1 where the source triangle is thinner than the
/// solvers resolve, so that its D' says nothing about the map and stays out
/// of the D' mean and max: its smallest triangle-inequality margin
/// min(l_a + l_b - l_c) (3D side lengths) is below relative_margin x the mean
/// side length, the faces the intrinsic mollification of the edge lengths
/// (geometry/mollify.h, the same default margin) reshapes before any
/// solver sees them. Exactly zero-area faces are among them. A corner of
/// 179.99 degrees or a side 1e-5 of the mean is thin; a 1-degree needle of
/// ordinary sides is not.
std::vector<char> thin_source_faces(const RowMatrixX3d& V, const RowMatrixX3i& F, double relative_margin = 1e-4);

/// The figures of hyperbolic image triangles of the source's faces (paper
/// docs/method.md §2.11): `image_in_chart(f)` gives face f's image seen in a chart
/// centring its corner 0 (corners 0, b, c), `image_sides(f)` its hyperbolic
/// side lengths (asked for positively oriented images only); D' per face by
/// hyperbolic_face_dilatation, the area-weighted (3D areas) mean and the
/// max over the faces with a D', flipped and degenerate counts as in
/// image_orientation; zero-area source faces are left out and counted in
/// degenerate_source (as planar_distortion does). The one loop behind every hyperbolic D' figure
/// (initial map, optimum, landmark folds).
///
/// `image_in_corner_chart(f, k)` (optional; issue 13, session 26): the image
/// seen in the chart centring corner k (corners k + 1 and k + 2 as b and c).
/// Seen from a corner of a long thin image its other corners lie near the
/// same point of the chart's boundary circle: the angle there is about
/// e^-(side length), so at 30-odd units |b x c| is below round-off whatever
/// the triangle's area. When it is given, a face whose orientation from
/// corner 0 is not clearly positive is read again from the corner opposite
/// its longest image side (its largest angle, where the chart resolves it),
/// and that reading (orientation and D') is the face's. Faces positive from
/// corner 0 are read as before.
DistortionStats hyperbolic_image_distortion(
    const TriMesh& source,
    const std::function<std::pair<std::complex<double>, std::complex<double>>(int f)>& image_in_chart,
    const std::function<Eigen::Vector3d(int f)>& image_sides, bool thin_images,
    const std::function<std::pair<std::complex<double>, std::complex<double>>(int f, int corner)>&
        image_in_corner_chart = {});

/// The corner opposite the longest of the three sides (side k joins corners
/// k and k + 1): the largest angle, from which a long thin hyperbolic image's
/// orientation is resolved. 0 when a side is not finite.
int widest_corner(const Eigen::Vector3d& sides);

/// Source triangles in 3D, images as #F x 3 planar corner positions (complex
/// numbers; corner k of face f is the image of F(f,k)). Flipped and
/// degenerate image triangles are counted; their D' is infinite and they are
/// left out of mean and max (which are then meaningless: check the counts).
DistortionStats planar_distortion(const RowMatrixX3d& V, const RowMatrixX3i& F,
                                  const Eigen::Matrix<std::complex<double>, Eigen::Dynamic, 3, Eigen::RowMajor>& image);

}  // namespace surfmap
