#pragma once
// Genus-0 surface maps (docs/method.md §2.4, §2.10): the pieces
// of the spherical path of surface_map().
//
// For genus 0 every harmonic map between the uniformized surfaces is
// conformal, and the conformal maps of the sphere are the Möbius
// transformations: the optimum is fixed only up to that six-dimensional
// group. Both surfaces are uniformized onto the unit sphere
// (uniformize/spherical.h), each Möbius-centred (area centroid at the
// origin), which leaves a rotation; the map is then
//
//   source vertex i  ->  M(x_i) on the target's sphere  ->  target face +
//   barycentrics (central projection onto the chordal triangle) -> 3D point
//
// with M chosen as follows.
//   * No landmarks: M is the rotation R minimising the shape mismatch
//     J(R) = Σ_i a_i |Ŷ_i − Ẑ(R x_i)|² (align_sphere_rotation), where Ŷ are
//     the source's 3D positions and Ẑ(p) the target's 3D point at sphere
//     point p, both normalised (area centroid at 0, total area 1), a_i the
//     source vertex areas. Because both images are centred, a rotation is
//     all the freedom that is left; J compares the shapes in the poses they
//     were given (up to translation and scale), the "objects side by side"
//     habit of Blender users, and is minimised globally over the 24
//     rotations of the cube group before a local pattern search refines the
//     best start. Principal axes were not used: their signs and their order
//     are ambiguous exactly on the near-symmetric shapes that are common.
//   * Landmarks (docs/method.md §2.10): after that rotation, 1 pair is hit by the
//     smallest rotation taking one point to the other (an isometry: centring
//     kept); 2 pairs by the Möbius map taking both points to their targets
//     that minimises the same shape mismatch J over the two real parameters
//     left (refine_two_landmark_mobius, started from the one fixing a third
//     point far from all four); 3 pairs by the unique
//     Möbius map taking the three points to the three targets (exact);
//     more than 3 by the Möbius map closest to them in least squares
//     (Levenberg–Marquardt on the sphere, started from the best exact
//     3-point fit): a conformal map cannot hit four arbitrary points, and a
//     non-conformal one would not be harmonic.
//
// Robustness: on real meshes the discrete conformal metric often exists only
// on the intrinsic Delaunay triangulation (uniformize/spherical.h), so a few
// input faces, drawn as chords between their vertices' sphere points, can
// come out flipped (g0_bunny: one face). Points on either sphere are
// therefore located in that side's intrinsic triangulation, which embeds,
// and carried back to its input faces through the uniformization's flip log
// (uniformize/spherical_correspondence.h): no target vertex is moved. The
// forward map is linear over the source's own faces, so a source face whose
// chord triangle is inverted cannot be one triangle of the map: those faces
// (grown until their region's boundary edges are intrinsic edges too) are
// delivered on their pieces of the common subdivision with the intrinsic
// triangulation (uniformize/spherical_subdivision.h;
// SurfaceMapResult::source_subdivision), every source vertex keeping its
// harmonic image; every triangle positive on the sphere and their spherical
// areas summing to 4π certify the bijection. Only when that subdivision
// cannot be built (a Δ-complex quad in the log) are vertices re-placed as
// before, by a Tutte-type embedding with mean value weights in the gnomonic
// chart of a patch (untangle_sphere_image; Floater's theorem);
// SurfaceMapResult::repaired_vertices counts the moved vertices.
#include <array>
#include <vector>

#include <Eigen/Core>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

/// A Möbius transformation of the unit sphere S² ⊂ R³: an SL(2, C) matrix
/// acting on the Riemann sphere, identified with S² by stereographic
/// projection from the north pole (z = (x + iy) / (1 − h) for (x, y, h)).
/// Points are handled in homogeneous coordinates, so the pole is not special.
struct SphereMobius {
  Eigen::Matrix2cd m = Eigen::Matrix2cd::Identity();

  /// Image of the unit vector p (the result is a unit vector).
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const;
  SphereMobius operator*(const SphereMobius& other) const;  ///< this ∘ other
  SphereMobius inverse() const;
  /// The unique Möbius map with from[k] -> to[k] (k = 0, 1, 2); each triple
  /// must consist of distinct unit vectors (InputError otherwise).
  static SphereMobius from_three_points(const std::array<Eigen::Vector3d, 3>& from,
                                        const std::array<Eigen::Vector3d, 3>& to);
  /// The rotation R as a Möbius map (exact: R is the Möbius map of three points).
  static SphereMobius from_rotation(const Eigen::Matrix3d& R);
};

/// Fits a Möbius map to k >= 1 point pairs on the unit sphere as described in
/// the header comment (1: smallest rotation, 2: fixes a far third point, 3:
/// exact, > 3: least squares). `rms` (optional) receives the root mean square
/// chordal residual, 0 up to round-off for k <= 3. Throws InputError when
/// points of `from` or of `to` coincide.
SphereMobius fit_sphere_mobius(const std::vector<Eigen::Vector3d>& from, const std::vector<Eigen::Vector3d>& to,
                               double* rms = nullptr);

/// Point location in a triangulation of the unit sphere whose vertices lie on
/// it (positions #V x 3, faces #F x 3, outward oriented, no flipped
/// triangles): the face whose cone from the origin contains p, and the
/// barycentrics of p's central projection onto that face's chordal triangle.
class SphereLocator {
 public:
  SphereLocator(const RowMatrixX3d& positions, const RowMatrixX3i& F);
  /// Face containing unit vector p (barycentrics >= 0 up to round-off,
  /// summing to 1). `hint`: a face to start walking from (-1: from the
  /// nearest vertex found in a grid). Never fails on a valid triangulation:
  /// a walk that does not arrive falls back to a search over all faces.
  int locate(const Eigen::Vector3d& p, Eigen::Vector3d* bary, int hint = -1) const;
  /// Walks that ended in the exhaustive fallback (diagnostics).
  mutable int fallbacks = 0;

 private:
  Eigen::Vector3d cone_barycentric(int f, const Eigen::Vector3d& p) const;
  int start_face(const Eigen::Vector3d& p) const;
  const RowMatrixX3d& P_;
  const RowMatrixX3i& F_;
  std::vector<int> neighbour_;   ///< 3F: face across the side opposite corner k
  std::vector<int> vertex_face_; ///< a face incident to each vertex
  int res_ = 1;                  ///< grid cells per axis over [-1, 1]^3
  std::vector<int> cell_start_, cell_vertices_;
};

/// Re-places vertices so that no face of the sphere image P (#V x 3 unit
/// vectors, faces F) is flipped or degenerate: a Tutte-type embedding with
/// Floater's mean value weights of the 3D mesh V (#V x 3), in the gnomonic
/// chart, of the patch around the bad faces, grown ring by ring up to
/// `max_vertices` vertices. Returns the number of moved vertices (0 when
/// nothing was flipped) or -1 (P unchanged) when no patch worked.
int untangle_sphere_image(RowMatrixX3d& P, const RowMatrixX3d& V, const RowMatrixX3i& F, int max_vertices);

struct SphereAlignmentOptions {
  /// Source vertices used in J (an evenly strided subset above this count;
  /// default 1500): the rotation has three degrees of freedom.
  int max_samples = 1500;
  /// Pattern-search steps (radians): from `initial_step` halving down to
  /// `final_step` (defaults 0.25 and 1e-4).
  double initial_step = 0.25, final_step = 1e-4;
};

struct SphereAlignmentResult {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  double mismatch = 0;          ///< J(R) / Σ a_i: mean squared distance of normalised shapes
  double identity_mismatch = 0; ///< the same for R = I
  int evaluations = 0;
};

/// Rotation R of the source's sphere minimising J(R) (header comment).
/// source_V, source_F: the source in 3D; source_sphere: its centred sphere
/// image (#V_s x 3); target_V, target_F, target_sphere likewise, with
/// `target_locator` built on target_sphere.
SphereAlignmentResult align_sphere_rotation(const RowMatrixX3d& source_V, const RowMatrixX3i& source_F,
                                            const RowMatrixX3d& source_sphere, const RowMatrixX3d& target_V,
                                            const RowMatrixX3i& target_F, const RowMatrixX3d& target_sphere,
                                            const SphereLocator& target_locator,
                                            const SphereAlignmentOptions& options = {});

/// Two landmarks leave two real parameters of the Möbius map: the maps
/// C⁻¹ ∘ (z ↦ λz) ∘ C ∘ M (C sending q0, q1 to 0, ∞) all take the landmarks
/// where M takes them (onto q0, q1). Picks λ minimising the shape mismatch J
/// of the source image `source_sphere` (already rotated) mapped by the
/// family, by pattern search on log λ. evaluations, mismatch_before (λ = 1)
/// and mismatch_after are optional outputs.
SphereMobius refine_two_landmark_mobius(const SphereMobius& M, const Eigen::Vector3d& q0, const Eigen::Vector3d& q1,
                                        const RowMatrixX3d& source_V, const RowMatrixX3i& source_F,
                                        const RowMatrixX3d& source_sphere, const RowMatrixX3d& target_V,
                                        const RowMatrixX3i& target_F, const SphereLocator& target_locator,
                                        const SphereAlignmentOptions& options = {}, int* evaluations = nullptr,
                                        double* mismatch_before = nullptr, double* mismatch_after = nullptr);

}  // namespace surfmap
