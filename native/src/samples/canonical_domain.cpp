#include "surfmap/samples/canonical_domain.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "implicit_mesher.h"
#include "surfmap/error.h"
#include "surfmap/samples/shapes.h"

namespace surfmap::samples {
namespace {

using Eigen::Vector3d;

double smin(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}
double smax(double a, double b, double k) { return -smin(-a, -b, k); }

struct DomainShape {
  detail::Implicit f;
  Vector3d lo, hi;
  double unit_length;  // extent of one hole's tile along the longest axis
};

// g tori of centre-line radius 1 and tube radius 0.4 side by side along x,
// 0.3 apart, blended where they meet (the holes stay open): the same surface
// as samples::n_hole_torus for g <= 4, for any g.
DomainShape row_of_tori(int g) {
  const double Rc = 1.0, r = 0.4, spacing = 2 * Rc + 0.3, k = 0.3;
  const double x0 = -0.5 * (g - 1) * spacing;
  DomainShape s;
  s.f = [=](const Vector3d& p) {
    double d = 1e30;
    for (int i = 0; i < g; ++i) {
      const Vector3d q = p - Vector3d(x0 + i * spacing, 0, 0);
      if (q.norm() - Rc >= d + k) continue;  // smin is min there: exact skip
      d = smin(d, std::hypot(std::hypot(q.x(), q.y()) - Rc, q.z()), k);
    }
    return d - r;
  };
  const double m = r + 0.05;
  s.lo = Vector3d(x0 - Rc - m, -Rc - m, -m);
  s.hi = Vector3d(-x0 + Rc + m, Rc + m, m);
  s.unit_length = 2 * (Rc + m);
  return s;
}

// A pancake (a disk of radius Rd with a round rim, half thickness t) with g
// round holes of radius rh evenly spaced on the circle of radius Rc (g = 1:
// one central hole, a torus). Walls between holes and to the rim are >= 0.5.
DomainShape ring_of_holes(int g) {
  const double t = 0.35, rh = 0.45, wall = 0.5, k = 0.2;
  const double Rc = g == 1 ? 0.0 : std::max(0.9, (2 * rh + wall) / (2 * std::sin(M_PI / g)));
  const double Rd = Rc + rh + wall + t;
  std::vector<Vector3d> centres;
  for (int i = 0; i < g; ++i)
    centres.emplace_back(Rc * std::cos(2 * M_PI * i / g), Rc * std::sin(2 * M_PI * i / g), 0);
  DomainShape s;
  s.f = [=](const Vector3d& p) {
    const double rho = std::hypot(p.x(), p.y());
    double d = std::hypot(std::max(rho - (Rd - t), 0.0), p.z()) - t;
    for (const Vector3d& c : centres) d = smax(d, rh - std::hypot(p.x() - c.x(), p.y() - c.y()), k);
    return d;
  };
  const double m = 0.05;
  s.lo = Vector3d(-Rd - m, -Rd - m, -t - m);
  s.hi = Vector3d(Rd + m, Rd + m, t + m);
  s.unit_length = 2 * (rh + wall + t + m) + 0.9;
  return s;
}

// Grid cells along the longest axis: `resolution` per hole tile, so the tube
// stays resolved however many holes there are.
int cells_along_longest_axis(const DomainShape& s, int resolution) {
  const double longest = (s.hi - s.lo).maxCoeff();
  return static_cast<int>(std::ceil(resolution * std::max(1.0, longest / s.unit_length)));
}

TriMesh mesh_domain(const DomainShape& s, int resolution, int genus, const std::string& what) {
  const int cells = cells_along_longest_axis(s, resolution);
  TriMesh mesh = detail::marching_tetrahedra(s.f, s.lo, s.hi, cells);
  detail::improve_on_level_set(mesh, s.f, (s.hi - s.lo).maxCoeff() / cells, 8);
  detail::check_closed_surface(mesh, genus, what);
  return mesh;
}

double corner_angle(const TriMesh& m, int t, int c) {
  const Vector3d p = m.V.row(m.F(t, c)), q = m.V.row(m.F(t, (c + 1) % 3)), r = m.V.row(m.F(t, (c + 2) % 3));
  const Vector3d u = q - p, v = r - p;
  return std::atan2(u.cross(v).norm(), u.dot(v));
}

void measure(CanonicalDomainResult& r) {
  const TriMesh& m = r.mesh;
  double area = 0, volume = 0, min_angle = M_PI, sum_min = 0;
  int below = 0;
  for (int t = 0; t < m.num_faces(); ++t) {
    const Vector3d a = m.V.row(m.F(t, 0)), b = m.V.row(m.F(t, 1)), c = m.V.row(m.F(t, 2));
    area += 0.5 * (b - a).cross(c - a).norm();
    volume += a.dot(b.cross(c)) / 6.0;
    const double smallest = std::min({corner_angle(m, t, 0), corner_angle(m, t, 1), corner_angle(m, t, 2)});
    min_angle = std::min(min_angle, smallest);
    sum_min += smallest;
    if (smallest < 20 * M_PI / 180) ++below;
  }
  r.area = area;
  r.signed_volume = volume;
  r.min_angle_deg = min_angle * 180 / M_PI;
  r.mean_min_angle_deg = m.num_faces() ? sum_min / m.num_faces() * 180 / M_PI : 0;
  r.fraction_below_20_deg = m.num_faces() ? static_cast<double>(below) / m.num_faces() : 0;
}

}  // namespace

CanonicalDomainResult canonical_domain(const CanonicalDomainOptions& o) {
  if (o.genus < 0 || o.genus > 8)
    throw InputError("canonical domain: genus " + std::to_string(o.genus) + " is out of range (0..8)");
  if (o.resolution < 16)
    throw InputError("canonical domain: resolution " + std::to_string(o.resolution) + " is too low (need >= 16)");
  if (o.kind == DomainKind::Polycube && o.layout == DomainLayout::Ring)
    throw InputError("canonical domain: the polycube kind has its holes in a row (no ring layout)");
  CanonicalDomainResult r;
  r.genus = o.genus;
  const std::string g = std::to_string(o.genus);
  if (o.genus == 0) {
    // Subdivided icosahedron with about as many vertices as a genus-1 domain.
    r.mesh = sphere(std::clamp(static_cast<int>(std::lround(std::log2(o.resolution / 2.5))), 3, 7));
    r.description = "sphere (genus 0)";
  } else if (o.kind == DomainKind::Polycube) {
    // samples::polycube spaces its holes 1.6 apart: keep ~resolution cells per hole.
    const int cells = static_cast<int>(std::ceil(o.resolution * std::max(1.0, (1.6 * (o.genus - 1) + 2.1) / 2.1)));
    r.mesh = polycube(o.genus, cells, true);
    r.description = "polycube genus " + g;
  } else if (o.layout == DomainLayout::Row) {
    r.mesh = mesh_domain(row_of_tori(o.genus), o.resolution, o.genus, "n-torus row genus " + g);
    r.description = "n-torus (row) genus " + g;
  } else {
    r.mesh = mesh_domain(ring_of_holes(o.genus), o.resolution, o.genus, "n-torus ring genus " + g);
    r.description = "n-torus (ring) genus " + g;
  }
  measure(r);
  if (o.unit_area) {
    const Eigen::RowVector3d centroid = r.mesh.V.colwise().mean();
    const double s = 1.0 / std::sqrt(r.area);
    r.mesh.V = ((r.mesh.V.rowwise() - centroid) * s).eval();
    measure(r);
  }
  return r;
}

}  // namespace surfmap::samples
