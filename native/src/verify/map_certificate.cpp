// The independent certificate of a stored map (verify/map_certificate.h,
// docs/verification.md). Written apart from the solver on purpose: nothing
// here calls the map layer; points are evaluated, frames built and
// orientations measured by the code in this file only.
#include "surfmap/verify/map_certificate.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include <Eigen/Geometry>

#include "surfmap/error.h"

namespace surfmap {
namespace {

using Eigen::Vector3d;

Vector3d corner(const TriMesh& m, int f, int k) { return m.V.row(m.F(f, k)).transpose(); }

/// The 3D point of a located point: Σ_k b_k * (corner k of its face).
Vector3d evaluate(const TriMesh& m, const SurfacePoint& p) {
  return p.barycentric[0] * corner(m, p.face, 0) + p.barycentric[1] * corner(m, p.face, 1) +
         p.barycentric[2] * corner(m, p.face, 2);
}

/// Checks one point (face in range, finite barycentrics >= -tol summing to
/// 1 within tol) and updates the worst values seen.
bool check_point(const SurfacePoint& p, int num_faces, double tol, MapCertificate& c) {
  if (p.face < 0 || p.face >= num_faces || !p.barycentric.allFinite()) return false;
  const double lowest = p.barycentric.minCoeff(), sum_error = std::abs(p.barycentric.sum() - 1.0);
  c.min_barycentric = std::min(c.min_barycentric, lowest);
  c.max_barycentric_sum_error = std::max(c.max_barycentric_sum_error, sum_error);
  return lowest >= -tol && sum_error <= tol;
}

/// Unit outward normals at the vertices of `m`: the sum of the incident
/// faces' (corner-ordered, so outward) area vectors, normalised. The
/// target's tangent frame at a located point interpolates these over the
/// point's face.
RowMatrixX3d vertex_normals(const TriMesh& m) {
  RowMatrixX3d N = RowMatrixX3d::Zero(m.num_vertices(), 3);
  for (int f = 0; f < m.num_faces(); ++f) {
    const Vector3d area = (corner(m, f, 1) - corner(m, f, 0)).cross(corner(m, f, 2) - corner(m, f, 0));
    for (int k = 0; k < 3; ++k) N.row(m.F(f, k)) += area.transpose();
  }
  for (int v = 0; v < N.rows(); ++v) {
    const double n = N.row(v).norm();
    if (n > 0) N.row(v) /= n;
  }
  return N;
}

Vector3d normal_at(const TriMesh& m, const RowMatrixX3d& N, const SurfacePoint& p) {
  Vector3d n = Vector3d::Zero();
  for (int k = 0; k < 3; ++k) n += p.barycentric[k] * N.row(m.F(p.face, k)).transpose();
  const double len = n.norm();
  return len > 0 ? Vector3d(n / len) : n;
}

double mean_edge_length(const TriMesh& m) {
  double sum = 0;
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) sum += (corner(m, f, (k + 1) % 3) - corner(m, f, k)).norm();
  return m.num_faces() ? sum / (3.0 * m.num_faces()) : 0.0;
}

double longest_edge(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  return std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
}

/// Checks 2-4: orientation of every source triangle's image in the target's
/// frame, the winding of every vertex star, and the signed area sum.
/// P: #V_source image points; Nf: #V_source target normals at them.
void check_orientation(const TriMesh& source, const TriMesh& target, const std::vector<Vector3d>& P,
                       const std::vector<Vector3d>& Nf, const std::vector<char>& unresolved,
                       const std::vector<char>& star_unresolved, const MapCertificateOptions& opt, MapCertificate& c) {
  const int nv = source.num_vertices();
  std::vector<double> angle_sum(nv, 0.0);
  std::vector<char> unmeasurable(nv, 0);
  c.min_relative_area = std::numeric_limits<double>::infinity();
  for (int f = 0; f < source.num_faces(); ++f) {
    const int v[3] = {source.F(f, 0), source.F(f, 1), source.F(f, 2)};
    const Vector3d& a = P[v[0]];
    const Vector3d& b = P[v[1]];
    const Vector3d& d = P[v[2]];
    // The triangle's frame: the mean of the target's normals at its corners.
    const Vector3d n_sum = Nf[v[0]] + Nf[v[1]] + Nf[v[2]];
    const double h = longest_edge(a, b, d), h2 = h * h;
    double relative = 0;
    if (n_sum.norm() > 1e-3 && h2 > 0) {
      const double signed_area = 0.5 * n_sum.normalized().dot((b - a).cross(d - a));
      c.signed_image_area += signed_area;
      relative = signed_area / h2;
    }
    if (relative < -opt.orientation_tolerance) {
      ++c.negative_triangles;
      c.negative_unresolved += unresolved[f];
    } else if (relative <= opt.orientation_tolerance) {  // also: no frame, collapsed
      ++c.degenerate_triangles;
      c.degenerate_unresolved += unresolved[f];
    }
    if (relative < c.min_relative_area) c.min_relative_area = relative, c.worst_triangle = f;
    // Angle of the image star at each corner, in that corner's own frame.
    for (int k = 0; k < 3; ++k) {
      const int at = v[k];
      const Vector3d& n = Nf[at];
      Vector3d u = P[v[(k + 1) % 3]] - P[at], w = P[v[(k + 2) % 3]] - P[at];
      u -= u.dot(n) * n;
      w -= w.dot(n) * n;
      const double scale = std::max(h, 1e-300);
      if (n.norm() < 0.5 || u.norm() <= 1e-14 * scale || w.norm() <= 1e-14 * scale) {
        unmeasurable[at] = 1;
        continue;
      }
      angle_sum[at] += std::atan2(n.dot(u.cross(w)), u.dot(w));
    }
  }
  for (int v = 0; v < nv; ++v) {
    const double winding = angle_sum[v] / (2 * M_PI);
    if (unmeasurable[v] || std::lround(winding) != 1) {
      if (c.first_winding_failure < 0) c.first_winding_failure = v;
      ++c.winding_failures;
      c.winding_failures_unresolved += star_unresolved[v];
    }
  }
  for (int f = 0; f < target.num_faces(); ++f)
    c.target_area += 0.5 * (corner(target, f, 1) - corner(target, f, 0)).cross(corner(target, f, 2) - corner(target, f, 0)).norm();
  c.area_ratio = c.target_area > 0 ? c.signed_image_area / c.target_area : 0.0;
  c.degree = static_cast<int>(std::lround(c.area_ratio));
}

/// Per source triangle: 1 when the target's normals at its corners' images
/// pairwise make more than `angle` (the image is unresolved); per source
/// vertex: 1 when a triangle of its star is.
void mark_unresolved(const TriMesh& source, const std::vector<Vector3d>& Nf, double angle, std::vector<char>* triangles,
                     std::vector<char>* stars) {
  const double min_dot = std::cos(angle);
  triangles->assign(source.num_faces(), 0);
  stars->assign(source.num_vertices(), 0);
  for (int f = 0; f < source.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k)
      if (!(Nf[source.F(f, k)].dot(Nf[source.F(f, (k + 1) % 3)]) >= min_dot)) (*triangles)[f] = 1;
    if ((*triangles)[f])
      for (int k = 0; k < 3; ++k) (*stars)[source.F(f, k)] = 1;
  }
}

/// Check 5 in one direction: for every vertex x of `mesh_b`, its point on
/// `mesh_a` (back[x]) is carried by the other map, given at mesh_a's vertices
/// as the 3D points `there` (on mesh_b), and compared with x. Returns the
/// largest error relative to the image triangle's longest edge.
void check_composition(const TriMesh& mesh_a, const TriMesh& mesh_b, const std::vector<SurfacePoint>& back,
                       const std::vector<Vector3d>& there, const std::vector<char>& unresolved, double tolerance,
                       double* max_relative, int* worst, int* failures, int* failures_unresolved,
                       double* max_mean_edges) {
  const double mean_edge = mean_edge_length(mesh_b);
  for (int x = 0; x < mesh_b.num_vertices(); ++x) {
    const int g = back[x].face;
    const Vector3d& a = there[mesh_a.F(g, 0)];
    const Vector3d& b = there[mesh_a.F(g, 1)];
    const Vector3d& d = there[mesh_a.F(g, 2)];
    const Vector3d q = back[x].barycentric[0] * a + back[x].barycentric[1] * b + back[x].barycentric[2] * d;
    const double error = (q - mesh_b.V.row(x).transpose()).norm(), scale = longest_edge(a, b, d);
    const double relative = scale > 0 ? error / scale : (error > 0 ? std::numeric_limits<double>::infinity() : 0.0);
    if (!(relative <= tolerance)) ++*failures, *failures_unresolved += unresolved[x];
    if (!(relative <= *max_relative)) *max_relative = relative, *worst = x;
    if (mean_edge > 0) *max_mean_edges = std::max(*max_mean_edges, error / mean_edge);
  }
}

std::string fmt(double x) {
  std::ostringstream s;
  s << std::setprecision(4) << x;
  return s.str();
}

}  // namespace

MapCertificate certify_map(const TriMesh& source, const TriMesh& target, const std::vector<SurfacePoint>& forward,
                           const std::vector<SurfacePoint>& inverse, const MapCertificateOptions& opt) {
  if (!(opt.barycentric_tolerance >= 0) || !(opt.orientation_tolerance >= 0) || !(opt.area_tolerance > 0) ||
      !(opt.inverse_tolerance > 0))
    throw InputError("certify_map: tolerances must be non-negative (area and inverse: positive)");
  MapCertificate c;
  c.source_vertices = source.num_vertices();
  c.source_triangles = source.num_faces();
  c.target_vertices = target.num_vertices();
  c.target_triangles = target.num_faces();
  auto fail = [&c](const std::string& line) { c.failures.push_back(line); };
  // 1. Location.
  if (static_cast<int>(forward.size()) != c.source_vertices)
    fail("forward map has " + std::to_string(forward.size()) + " points for " + std::to_string(c.source_vertices) +
         " source vertices");
  if (static_cast<int>(inverse.size()) != c.target_vertices)
    fail("inverse map has " + std::to_string(inverse.size()) + " points for " + std::to_string(c.target_vertices) +
         " target vertices");
  if (!c.failures.empty()) return c;
  std::string first_invalid;
  c.min_barycentric = std::numeric_limits<double>::infinity();
  for (int s = 0; s < c.source_vertices; ++s)
    if (!check_point(forward[s], c.target_triangles, opt.barycentric_tolerance, c) && c.invalid_forward++ == 0)
      first_invalid = "source vertex " + std::to_string(s);
  for (int t = 0; t < c.target_vertices; ++t)
    if (!check_point(inverse[t], c.source_triangles, opt.barycentric_tolerance, c) && c.invalid_inverse++ == 0 &&
        first_invalid.empty())
      first_invalid = "target vertex " + std::to_string(t);
  if (c.invalid_forward + c.invalid_inverse > 0) {
    fail(std::to_string(c.invalid_forward) + " forward and " + std::to_string(c.invalid_inverse) +
         " inverse points without a valid face and barycentrics (first: " + first_invalid + ")");
    return c;
  }
  // 2-4. Orientation, winding, degree.
  const RowMatrixX3d target_normals = vertex_normals(target);
  std::vector<Vector3d> P(c.source_vertices), Nf(c.source_vertices), Q(c.target_vertices);
  for (int s = 0; s < c.source_vertices; ++s) {
    P[s] = evaluate(target, forward[s]);
    Nf[s] = normal_at(target, target_normals, forward[s]);
  }
  std::vector<char> unresolved, star_unresolved;
  mark_unresolved(source, Nf, opt.resolved_normal_angle, &unresolved, &star_unresolved);
  for (char u : unresolved) c.unresolved_triangles += u;
  check_orientation(source, target, P, Nf, unresolved, star_unresolved, opt, c);
  auto of_them = [](int n) { return n ? " (" + std::to_string(n) + " of them unresolved)" : std::string(); };
  // A check that failed only on unresolved images is undecided (a failure
  // with options.strict); one failure on a resolved image fails it.
  auto judge = [&c, &opt, &fail](int count, int unresolved_count, const std::string& line) {
    if (count == 0) return;
    if (opt.strict || count > unresolved_count) fail(line);
    else c.undecided.push_back(line);
  };
  if (c.negative_triangles > 0)
    judge(c.negative_triangles, c.negative_unresolved, std::to_string(c.negative_triangles) + " source triangles with negatively oriented images" +
         of_them(c.negative_unresolved) + " (worst: triangle " + std::to_string(c.worst_triangle) +
         ", relative area " + fmt(c.min_relative_area) + ")");
  if (c.degenerate_triangles > 0)
    judge(c.degenerate_triangles, c.degenerate_unresolved, std::to_string(c.degenerate_triangles) + " source triangles with degenerate images" +
         of_them(c.degenerate_unresolved));
  if (c.winding_failures > 0)
    judge(c.winding_failures, c.winding_failures_unresolved, std::to_string(c.winding_failures) + " source vertices whose image star does not wind once" +
         of_them(c.winding_failures_unresolved) + " (first: vertex " + std::to_string(c.first_winding_failure) + ")");
  if (!(std::abs(c.area_ratio - 1.0) <= opt.area_tolerance))
    fail("signed image area / target area = " + fmt(c.area_ratio) + " (degree " + std::to_string(c.degree) +
         "), not within " + fmt(opt.area_tolerance) + " of 1");
  // 5. Compositions.
  for (int t = 0; t < c.target_vertices; ++t) Q[t] = evaluate(source, inverse[t]);
  std::vector<char> preimage_unresolved(c.target_vertices);
  for (int t = 0; t < c.target_vertices; ++t) preimage_unresolved[t] = unresolved[inverse[t].face];
  check_composition(source, target, inverse, P, preimage_unresolved, opt.inverse_tolerance, &c.max_inverse_error,
                    &c.worst_inverse_vertex, &c.inverse_failures, &c.inverse_failures_unresolved,
                    &c.max_inverse_error_mean_edges);
  // I(F(s)) interpolates the inverse's image of F(s)'s target face on the
  // source: resolved when the source's normals at its corners' preimages agree.
  const RowMatrixX3d source_normals = vertex_normals(source);
  std::vector<Vector3d> Ns(c.target_vertices);
  for (int t = 0; t < c.target_vertices; ++t) Ns[t] = normal_at(source, source_normals, inverse[t]);
  std::vector<char> target_unresolved, unused;
  mark_unresolved(target, Ns, opt.resolved_normal_angle, &target_unresolved, &unused);
  std::vector<char> image_face_unresolved(c.source_vertices);
  for (int s = 0; s < c.source_vertices; ++s) image_face_unresolved[s] = target_unresolved[forward[s].face];
  check_composition(target, source, forward, Q, image_face_unresolved, opt.inverse_tolerance, &c.max_forward_error,
                    &c.worst_forward_vertex, &c.forward_failures, &c.forward_failures_unresolved,
                    &c.max_forward_error_mean_edges);
  if (c.inverse_failures > 0)
    judge(c.inverse_failures, c.inverse_failures_unresolved, std::to_string(c.inverse_failures) + " target vertices t with |F(I(t)) - t| above " + fmt(opt.inverse_tolerance) +
         " of the image triangle" + of_them(c.inverse_failures_unresolved) + " (worst: vertex " +
         std::to_string(c.worst_inverse_vertex) + ", " + fmt(c.max_inverse_error) + ")");
  if (c.forward_failures > 0)
    judge(c.forward_failures, c.forward_failures_unresolved, std::to_string(c.forward_failures) + " source vertices s with |I(F(s)) - s| above " + fmt(opt.inverse_tolerance) +
         " of the preimage triangle" + of_them(c.forward_failures_unresolved) + " (worst: vertex " +
         std::to_string(c.worst_forward_vertex) + ", " + fmt(c.max_forward_error) + ")");
  c.certified = c.failures.empty();
  return c;
}

std::string MapCertificate::summary() const {
  std::ostringstream s;
  s << "located: " << source_vertices - invalid_forward << "/" << source_vertices << " source vertices on target faces, "
    << target_vertices - invalid_inverse << "/" << target_vertices << " target vertices on source faces (lowest barycentric "
    << fmt(min_barycentric) << ", largest |sum - 1| " << fmt(max_barycentric_sum_error) << ")\n";
  s << "orientation: " << source_triangles << " source triangles, " << negative_triangles << " negative, "
    << degenerate_triangles << " degenerate; smallest signed area / longest edge^2 " << fmt(min_relative_area)
    << " (triangle " << worst_triangle << ")\n";
  s << "resolution: " << unresolved_triangles << " source triangles whose image corners' target normals differ by "
       "more than the resolved angle (unresolved: there the vertex images alone do not pin the map down in R^3)\n";
  s << "winding: " << winding_failures << " source vertex stars not winding once"
    << (first_winding_failure >= 0 ? " (first: vertex " + std::to_string(first_winding_failure) + ")" : std::string())
    << "\n";
  s << "degree: signed image area " << fmt(signed_image_area) << " / target area " << fmt(target_area) << " = "
    << fmt(area_ratio) << " (degree " << degree << ")\n";
  s << "inverse: max |F(I(t)) - t| " << fmt(max_inverse_error) << " of the image triangle (target vertex "
    << worst_inverse_vertex << ", " << fmt(max_inverse_error_mean_edges) << " target mean edges), max |I(F(s)) - s| "
    << fmt(max_forward_error) << " (source vertex " << worst_forward_vertex << ", " << fmt(max_forward_error_mean_edges)
    << " source mean edges); " << inverse_failures + forward_failures << " above the tolerance\n";
  if (certified && undecided.empty())
    s << "CERTIFIED: a bijection (degree 1, locally injective, inverse consistent)";
  else if (certified)
    s << "CERTIFIED where resolved: degree 1, locally injective and inverse consistent on every resolved image; "
      << undecided.size() << " check(s) undecided on unresolved images (--strict fails them):";
  else
    s << "NOT CERTIFIED: " << failures.size() << " check(s) failed";
  for (const auto& f : failures) s << "\n  " << f;
  if (!certified && !undecided.empty()) s << "\n  undecided (unresolved images only):";
  for (const auto& u : undecided) s << "\n  " << u;
  return s.str();
}

}  // namespace surfmap
