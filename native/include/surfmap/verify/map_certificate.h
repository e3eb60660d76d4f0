#pragma once
// An independent certificate that a stored map between two closed surfaces
// is a bijection (docs/verification.md). It reads only the two meshes and the
// located points (per source vertex a target face and barycentrics, per
// target vertex a source face and barycentrics) and shares none of the
// solver's location, orientation or distortion code: its own point-on-face
// evaluation, its own tangent frames and orientation tests.
//
// What it checks (docs/verification.md states what this proves):
//  1. location: every point names an existing face, its barycentrics are
//     finite, >= -barycentric_tolerance and sum to 1 within it;
//  2. orientation: each source triangle's image (the chord triangle between
//     its corners' image points) has a positive signed area measured in the
//     target's tangent frame there (the target's own outward face
//     orientation: area-weighted vertex normals, interpolated over faces);
//     none negative or degenerate beyond round-off;
//  3. local injectivity: the image of every source vertex's star winds once
//     around the vertex's image (rules out branch points, which positive
//     triangles alone allow);
//  4. degree: the signed image areas sum to the target's area within
//     area_tolerance (with 2 and 3 the map is a covering, and its number of
//     sheets is the area ratio: 1);
//  5. inverse: at every target vertex t, the forward map applied to its
//     preimage returns to t, and at every source vertex s the inverse applied
//     to its image returns to s, within inverse_tolerance of the size of the
//     image triangle the composition interpolates in.
// Checks 2, 3 and 5 are decided on *resolved* images, where the target's
// normals at the corners agree within resolved_normal_angle; failures on
// unresolved images only are listed as undecided unless options.strict.
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

/// A point on a triangle mesh: a face index and the weights of its three
/// corners (in the order of F's row).
struct SurfacePoint {
  int face = -1;
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();
};

struct MapCertificateOptions {
  /// Barycentrics may be below 0 by this much, and their sum may differ from
  /// 1 by this much (default 1e-9: location round-off).
  double barycentric_tolerance = 1e-9;
  /// An image triangle is negative when its signed area is below
  /// -orientation_tolerance * (its longest edge)^2, degenerate when its
  /// magnitude is at most that (default 1e-12: round-off).
  double orientation_tolerance = 1e-12;
  /// |signed image area / target area - 1| allowed (default 0.25; any value
  /// below 0.5 makes the nearest integer of the ratio, the covering's number
  /// of sheets, equal to 1).
  double area_tolerance = 0.25;
  /// Largest composition error |F(I(t)) - t| (and |I(F(s)) - s|) allowed,
  /// relative to the longest edge of the image triangle the composition
  /// interpolates in (default 1: within one image triangle of where the
  /// forward map puts the preimage; the map is linear on a source triangle
  /// only in the solver's uniformization domain, and measured in R^3 a
  /// correct map's composition is off by up to ~0.75 of a triangle on
  /// strongly stretched real pairs).
  double inverse_tolerance = 1.0;
  /// An image triangle is *resolved* when the target's normals at its three
  /// corners pairwise make at most this angle (radians, default pi/3); the
  /// chord-and-tangent-plane measures are faithful only there. Unresolved
  /// triangles are still checked (and can fail); the certificate counts them
  /// and says which failures lie on them.
  double resolved_normal_angle = M_PI / 3;
  /// false (default): a check whose failures all lie on unresolved images is
  /// *undecided* (listed, not failed); true: any failure fails.
  bool strict = false;
};

struct MapCertificate {
  /// True when every check below passed.
  bool certified = false;
  /// One line per failed check (empty when certified), and one per check
  /// that failed only on unresolved images (MapCertificateOptions::strict).
  std::vector<std::string> failures, undecided;

  int source_vertices = 0, source_triangles = 0, target_vertices = 0, target_triangles = 0;
  /// 1. Points with an invalid face or barycentrics, and the worst values:
  /// the most negative barycentric and the largest |sum - 1| (both maps).
  int invalid_forward = 0, invalid_inverse = 0;
  double min_barycentric = 0, max_barycentric_sum_error = 0;
  /// 2. Source triangles whose image is negative / degenerate, the smallest
  /// signed area relative to the image's longest edge squared, and where.
  int negative_triangles = 0, degenerate_triangles = 0;
  /// Source triangles whose images are unresolved (resolved_normal_angle),
  /// and how many of the negative / degenerate ones are.
  int unresolved_triangles = 0, negative_unresolved = 0, degenerate_unresolved = 0;
  double min_relative_area = 0;
  int worst_triangle = -1;
  /// 3. Source vertices whose image star does not wind exactly once (or
  /// cannot be measured: coincident images), and the first of them.
  int winding_failures = 0, winding_failures_unresolved = 0;  ///< ... of them at stars with an unresolved image
  int first_winding_failure = -1;
  /// 4. Σ signed image areas, the target's area, their ratio, and the
  /// degree: the ratio's nearest integer (the covering's sheets when 2 and 3 hold).
  double signed_image_area = 0, target_area = 0, area_ratio = 0;
  int degree = 0;
  /// 5. Largest relative composition errors and their vertices, how many
  /// exceed the tolerance; the absolute errors relative to the mean edge
  /// length of the mesh they are measured on.
  double max_inverse_error = 0, max_forward_error = 0;
  int worst_inverse_vertex = -1, worst_forward_vertex = -1;
  int inverse_failures = 0, forward_failures = 0;
  /// ... of them in an unresolved image (target vertex: its preimage's
  /// source triangle's forward image; source vertex: the inverse's image of
  /// the target face its image lies on).
  int inverse_failures_unresolved = 0, forward_failures_unresolved = 0;
  double max_inverse_error_mean_edges = 0, max_forward_error_mean_edges = 0;

  /// A few lines: counts and worst values of every check, then PASS/FAIL.
  std::string summary() const;
};

/// Certifies a map between `source` and `target` (closed, manifold,
/// outward-oriented triangle meshes, e.g. after mesh/intake.h).
/// forward: #V_source points on the target; inverse: #V_target points on the
/// source. Never throws for a bad map (a wrong count, face or barycentric is
/// a failed check); throws InputError only for unusable options.
MapCertificate certify_map(const TriMesh& source, const TriMesh& target, const std::vector<SurfacePoint>& forward,
                           const std::vector<SurfacePoint>& inverse, const MapCertificateOptions& options = {});

}  // namespace surfmap
