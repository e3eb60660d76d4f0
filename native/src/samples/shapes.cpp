#include "surfmap/samples/shapes.h"

#include <algorithm>
#include <array>
#include <numeric>
#include <cmath>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "implicit_mesher.h"
#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"

namespace surfmap::samples {

using Eigen::Vector3d;
using detail::Implicit;

namespace {

// ---- implicit building blocks (distance-like, negative inside) -----------

// Polynomial smooth minimum: equals min(a, b) when |a - b| >= k, blends
// within k, and keeps the Lipschitz constant of its arguments.
double smin(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}
double smax(double a, double b, double k) { return -smin(-a, -b, k); }
double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3 - 2 * x);
}

/// Distance to the circle of radius R around c in the plane with unit normal n.
double circle_distance(const Vector3d& p, const Vector3d& c, const Vector3d& n, double R) {
  const Vector3d q = p - c;
  const double z = q.dot(n);
  const double radial = (q - z * n).norm();
  return std::hypot(radial - R, z);
}

/// Tube of radius r around the arc {c + R(cos t u + sin t w) : |t| <= half_angle}
/// (half_angle > 90 degrees), precomputed so evaluation needs no
/// trigonometry: the sample functions are evaluated millions of times.
struct ArcTube {
  Vector3d c, u, w, n, e1, e2;
  double R, r, cos_gap;
  ArcTube(const Vector3d& c_, const Vector3d& u_, const Vector3d& w_, double R_, double half_angle,
          double r_)
      : c(c_), u(u_), w(w_), n(u_.cross(w_)), R(R_), r(r_) {
    e1 = c + R * (std::cos(half_angle) * u + std::sin(half_angle) * w);
    e2 = c + R * (std::cos(half_angle) * u - std::sin(half_angle) * w);
    cos_gap = std::cos(M_PI - half_angle);
  }
  /// A lower bound of the tube's value at p (cheap).
  double lower_bound(const Vector3d& p) const { return (p - c).norm() - R - r; }
  double operator()(const Vector3d& p) const {
    const Vector3d q = p - c;
    const double x = q.dot(u), y = q.dot(w);
    // Outside the arc's range iff the in-plane direction lies in the gap
    // wedge around -u.
    const double rho = std::hypot(x, y);
    if (-x >= rho * cos_gap) return std::min((p - e1).norm(), (p - e2).norm()) - r;
    return std::hypot(rho - R, q.dot(n)) - r;
  }
};

/// smin(d, tube(p), k), skipping the exact evaluation when the tube's lower
/// bound shows it cannot change the result (smin = min when |a - b| >= k).
double smin_tube(double d, const ArcTube& tube, const Vector3d& p, double k) {
  if (tube.lower_bound(p) >= d + k) return d;
  return smin(d, tube(p), k);
}

double segment_distance(const Vector3d& p, const Vector3d& a, const Vector3d& b) {
  const Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - a - t * ab).norm();
}

/// Closed solid of revolution around z: radius rho(z) for z0 <= z <= z1, the
/// rims rounded by a smooth maximum of width k.
template <class Rho>
double revolution(const Vector3d& p, Rho rho, double z0, double z1, double k) {
  const double radial = std::hypot(p.x(), p.y()) - rho(p.z());
  return smax(radial, smax(z0 - p.z(), p.z() - z1, k), k);
}

/// Handle: a tube of radius r around an arc in the vertical plane through the
/// z axis at azimuth phi, centred at radial distance cx and height cz; the
/// arc's ends (|t| > half_angle) are buried inside the body.
ArcTube handle(double phi, double cx, double cz, double R, double half_angle, double r) {
  const Vector3d u(std::cos(phi), std::sin(phi), 0.0), w(0, 0, 1);
  return ArcTube(cx * u + cz * w, u, w, R, half_angle, r);
}

struct Shape {
  Implicit f;
  Vector3d lo, hi;
  int genus;
  std::string name;
};

TriMesh mesh_shape(const Shape& s, int resolution, bool smooth) {
  if (resolution < 8)
    throw InputError(s.name + ": resolution " + std::to_string(resolution) + " is too low (need >= 8)");
  TriMesh mesh = detail::marching_tetrahedra(s.f, s.lo, s.hi, resolution);
  const double h = (s.hi - s.lo).maxCoeff() / resolution;
  const std::string what = s.name + " at resolution " + std::to_string(resolution);
  // The smoothed mesh is checked after smoothing (which preserves topology);
  // checking both would only repeat the work.
  if (!smooth) detail::check_closed_surface(mesh, s.genus, what);
  if (smooth) {
    detail::improve_on_level_set(mesh, s.f, h, 8);
    detail::check_closed_surface(mesh, s.genus, what + " (smoothed)");
  }
  return mesh;
}

void check_genus_arg(int g, const std::string& what) {
  if (g < 1 || g > 8)
    throw InputError(what + ": genus " + std::to_string(g) + " is out of range (1..8)");
}

/// A wheel: a rim and n spokes of radius 0.3 meeting at the hub; each sector
/// is one hole (genus n). The rim has radius 3 up to 8 spokes and grows like
/// 3 n / 8 beyond, so every sector keeps a hole of about the same width; from
/// 9 spokes on, a flat hub of radius n / (2 pi) fills the centre, where the
/// spokes would otherwise come closer than the grid resolves (spurious holes).
Shape wheel_shape(int n) {
  Shape s;
  s.genus = n;
  s.name = "wheel(" + std::to_string(n) + ")";
  const double Rw = 3.0 * std::max(1.0, n / 8.0), r = 0.3;
  const double hub = n > 8 ? n / (2 * M_PI) : 0.0;
  std::vector<Vector3d> rim_points;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n + 0.3;
    rim_points.emplace_back(Rw * std::cos(a), Rw * std::sin(a), 0);
  }
  s.f = [=](const Vector3d& p) {
    double d = circle_distance(p, Vector3d::Zero(), Vector3d::UnitZ(), Rw);
    for (const Vector3d& e : rim_points) d = smin(d, segment_distance(p, Vector3d::Zero(), e), 0.25);
    if (hub > 0) d = smin(d, std::hypot(std::max(std::hypot(p.x(), p.y()) - hub, 0.0), p.z()), 0.25);
    return d - r;
  };
  const double m = r + 0.05;
  s.lo = Vector3d(-Rw - m, -Rw - m, -m);
  s.hi = Vector3d(Rw + m, Rw + m, m);
  return s;
}

Shape n_hole_torus_shape(int n) {
  Shape s;
  s.genus = n;
  s.name = "n_hole_torus(" + std::to_string(n) + ")";
  if (n <= 4) {
    // Circles of radius 1 in a row, 0.3 apart; tubes of radius 0.4 merge
    // between neighbours without closing the holes.
    const double Rc = 1.0, r = 0.4, spacing = 2 * Rc + 0.3;
    const double x0 = -0.5 * (n - 1) * spacing;
    s.f = [=](const Vector3d& p) {
      double d = 1e30;
      for (int i = 0; i < n; ++i) {
        const Vector3d c(x0 + i * spacing, 0, 0);
        // Exact skip: the circle's distance is >= |p - c| - Rc, and smin is
        // plain min once its arguments differ by more than k.
        if ((p - c).norm() - Rc >= d + 0.3) continue;
        d = smin(d, circle_distance(p, c, Vector3d::UnitZ(), Rc), 0.3);
      }
      return d - r;
    };
    const double m = r + 0.05;
    s.lo = Vector3d(x0 - Rc - m, -Rc - m, -m);
    s.hi = Vector3d(-x0 + Rc + m, Rc + m, m);
  } else {
    s = wheel_shape(n);
    s.name = "n_hole_torus(" + std::to_string(n) + ")";
  }
  return s;
}

Shape vase_shape() {
  Shape s;
  s.genus = 2;
  s.name = "vase";
  auto rho = [](double z) {
    return 0.3 + 0.6 * std::exp(-std::pow((z - 1.0) / 0.65, 2)) + 0.22 * smoothstep((z - 2.2) / 0.8);
  };
  const std::vector<ArcTube> handles = {handle(0, 0.55, 2.15, 0.45, 150 * M_PI / 180, 0.11),
                                         handle(M_PI, 0.55, 2.15, 0.45, 150 * M_PI / 180, 0.11)};
  s.f = [=](const Vector3d& p) {
    double d = revolution(p, rho, 0.0, 3.0, 0.12);
    for (const auto& hd : handles) d = smin_tube(d, hd, p, 0.08);
    return d;
  };
  s.lo = Vector3d(-1.15, -1.0, -0.05);
  s.hi = Vector3d(1.15, 1.0, 3.05);
  return s;
}

Shape amphora_shape() {
  Shape s;
  s.genus = 2;
  s.name = "amphora";
  auto rho = [](double z) {
    return 0.2 + 0.7 * std::exp(-std::pow((z - 1.5) / 0.8, 2)) + 0.12 * smoothstep((z - 3.6) / 0.4) -
           0.07 * (1 - smoothstep(z / 0.5));
  };
  const std::vector<ArcTube> handles = {handle(0, 0.45, 2.85, 0.55, 150 * M_PI / 180, 0.1),
                                         handle(M_PI, 0.45, 2.85, 0.55, 150 * M_PI / 180, 0.1)};
  s.f = [=](const Vector3d& p) {
    double d = revolution(p, rho, 0.0, 4.0, 0.06);
    for (const auto& hd : handles) d = smin_tube(d, hd, p, 0.07);
    return d;
  };
  s.lo = Vector3d(-1.1, -0.95, -0.05);
  s.hi = Vector3d(1.1, 0.95, 4.05);
  return s;
}

Shape cup_shape(int handles) {
  Shape s;
  s.genus = handles;
  s.name = "cup(" + std::to_string(handles) + ")";
  auto rho = [](double z) { return 0.85 + 0.15 * std::sin(M_PI * z / 1.6); };
  std::vector<ArcTube> tubes;
  for (int i = 0; i < handles; ++i)
    tubes.push_back(handle(2 * M_PI * i / handles, 1.0, 0.8, 0.45, 140 * M_PI / 180, 0.12));
  s.f = [=](const Vector3d& p) {
    double d = revolution(p, rho, 0.0, 1.6, 0.15);
    for (const auto& hd : tubes) d = smin_tube(d, hd, p, 0.08);
    return d;
  };
  const double e = handles == 1 ? 1.0 : 1.6;
  s.lo = Vector3d(-(handles == 1 ? 1.05 : e), -(handles <= 2 ? 1.05 : e), -0.05);
  s.hi = Vector3d(1.6, handles <= 2 ? 1.05 : e, 1.65);
  return s;
}

Shape polycube_shape(int holes) {
  Shape s;
  s.genus = holes;
  s.name = "polycube(" + std::to_string(holes) + ")";
  const double spacing = 1.6, hole = 0.45;
  const double Lx = 0.8 * (holes - 1) + 1.05, Ly = 1.0, Lz = 0.6;
  auto rounded_box = [](const Vector3d& p, const Vector3d& b, double rr) {
    const Vector3d q = p.cwiseAbs() - (b - Vector3d::Constant(rr));
    return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0) - rr;
  };
  s.f = [=](const Vector3d& p) {
    double d = rounded_box(p, Vector3d(Lx, Ly, Lz), 0.15);
    for (int i = 0; i < holes; ++i) {
      const double cx = (i - 0.5 * (holes - 1)) * spacing;
      // Square prism along z with rounded vertical edges.
      const double qx = std::abs(p.x() - cx) - (hole - 0.1), qy = std::abs(p.y()) - (hole - 0.1);
      const double prism = std::hypot(std::max(qx, 0.0), std::max(qy, 0.0)) + std::min(std::max(qx, qy), 0.0) - 0.1;
      d = smax(d, -prism, 0.12);
    }
    return d;
  };
  s.lo = Vector3d(-Lx, -Ly, -Lz);
  s.hi = Vector3d(Lx, Ly, Lz);
  return s;
}

double signed_volume(const TriMesh& m) {
  double vol = 0;
  for (int t = 0; t < m.num_faces(); ++t) {
    const Vector3d a = m.V.row(m.F(t, 0)), b = m.V.row(m.F(t, 1)), c = m.V.row(m.F(t, 2));
    vol += a.dot(b.cross(c)) / 6.0;
  }
  return vol;
}

}  // namespace

TriMesh torus_of_revolution(double R, double r, int n_major, int n_minor, int connectivity_variant) {
  if (!(r > 0) || !(R > r))
    throw InputError("torus_of_revolution: need R > r > 0 (got R = " + std::to_string(R) +
                     ", r = " + std::to_string(r) + ")");
  if (n_major < 3 || n_minor < 3)
    throw InputError("torus_of_revolution: need n_major, n_minor >= 3 (got " + std::to_string(n_major) +
                     ", " + std::to_string(n_minor) + ")");
  // Variant 2 offsets every odd ring by half a cell along the minor circle.
  auto shift = [&](int i) { return connectivity_variant == 2 && (i % 2 == 1) ? 0.5 : 0.0; };
  TriMesh m;
  m.V.resize(n_major * n_minor, 3);
  auto id = [&](int i, int j) { return ((i % n_major) * n_minor) + ((j % n_minor + n_minor) % n_minor); };
  for (int i = 0; i < n_major; ++i)
    for (int j = 0; j < n_minor; ++j) {
      const double th = 2 * M_PI * i / n_major, ph = 2 * M_PI * (j + shift(i)) / n_minor;
      m.V.row(id(i, j)) << (R + r * std::cos(ph)) * std::cos(th), (R + r * std::cos(ph)) * std::sin(th),
          r * std::sin(ph);
    }
  m.F.resize(2 * n_major * n_minor, 3);
  std::mt19937 rng(connectivity_variant);
  int t = 0;
  // Counter-clockwise in the (theta, phi) parameter plane is outward.
  for (int i = 0; i < n_major; ++i)
    for (int j = 0; j < n_minor; ++j) {
      const double s0 = shift(i), s1 = shift((i + 1) % n_major);
      const int a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      if (s1 > s0) {  // ring i+1 sits half a cell higher: b lies between a and d
        m.F.row(t++) << a, b, d;
        m.F.row(t++) << d, b, c;
      } else if (s1 < s0) {  // c lies between a and d
        m.F.row(t++) << a, b, c;
        m.F.row(t++) << a, c, d;
      } else {
        bool other_diagonal = false;
        if (connectivity_variant == 1) other_diagonal = (i + j) % 2 == 1;
        else if (connectivity_variant >= 3 || connectivity_variant < 0) other_diagonal = rng() & 1u;
        if (other_diagonal) {
          m.F.row(t++) << a, b, d;
          m.F.row(t++) << b, c, d;
        } else {
          m.F.row(t++) << a, b, c;
          m.F.row(t++) << a, c, d;
        }
      }
    }
  return m;
}

TriMesh n_hole_torus(int n, int resolution, bool smooth) {
  check_genus_arg(n, "n_hole_torus");
  return mesh_shape(n_hole_torus_shape(n), resolution, smooth);
}
TriMesh wheel(int spokes, int resolution, bool smooth) {
  if (spokes < 3 || spokes > 32)
    throw InputError("wheel: spokes " + std::to_string(spokes) + " is out of range (3..32)");
  return mesh_shape(wheel_shape(spokes), resolution, smooth);
}
TriMesh vase(int resolution, bool smooth) { return mesh_shape(vase_shape(), resolution, smooth); }
TriMesh amphora(int resolution, bool smooth) { return mesh_shape(amphora_shape(), resolution, smooth); }
TriMesh cup(int handles, int resolution, bool smooth) {
  check_genus_arg(handles, "cup");
  return mesh_shape(cup_shape(handles), resolution, smooth);
}
TriMesh polycube(int holes, int resolution, bool smooth) {
  check_genus_arg(holes, "polycube");
  return mesh_shape(polycube_shape(holes), resolution, smooth);
}

TriMesh needle(const TriMesh& mesh, int v, double height, double gap) {
  if (v < 0 || v >= mesh.num_vertices()) throw InputError("needle: vertex " + std::to_string(v) + " does not exist");
  if (!(height > 0)) throw InputError("needle: height must be positive");
  if (!(gap > 0 && gap < 1)) throw InputError("needle: gap must lie in (0, 1)");
  TriMesh out = mesh;
  Vector3d normal = Vector3d::Zero();
  int n = -1;
  for (int t = 0; t < mesh.num_faces(); ++t)
    for (int c = 0; c < 3; ++c) {
      if (mesh.F(t, c) != v) continue;
      const Vector3d a = mesh.V.row(v), b = mesh.V.row(mesh.F(t, (c + 1) % 3)), d = mesh.V.row(mesh.F(t, (c + 2) % 3));
      normal += (b - a).cross(d - a);
      for (int w : {mesh.F(t, (c + 1) % 3), mesh.F(t, (c + 2) % 3)}) n = n < 0 ? w : std::min(n, w);
    }
  if (n < 0 || !(normal.norm() > 0)) throw InputError("needle: vertex " + std::to_string(v) + " has no faces");
  const Vector3d tip = mesh.V.row(v).transpose() + height * normal.normalized();
  out.V.row(v) = tip;
  out.V.row(n) = tip + gap * (mesh.V.row(n).transpose() - tip);
  return out;
}

TriMesh finger(const TriMesh& mesh, int v, double length, int segments) {
  if (v < 0 || v >= mesh.num_vertices()) throw InputError("finger: vertex " + std::to_string(v) + " does not exist");
  if (!(length > 0)) throw InputError("finger: length must be positive");
  if (segments < 1) throw InputError("finger: segments must be at least 1");
  // v's link in face order: next[a] = b for every face (v, a, b).
  std::map<int, int> next;
  Vector3d normal = Vector3d::Zero();
  for (int t = 0; t < mesh.num_faces(); ++t)
    for (int c = 0; c < 3; ++c) {
      if (mesh.F(t, c) != v) continue;
      const int a = mesh.F(t, (c + 1) % 3), b = mesh.F(t, (c + 2) % 3);
      next[a] = b;
      normal += (mesh.V.row(a) - mesh.V.row(v)).cross(mesh.V.row(b) - mesh.V.row(v)).transpose();
    }
  if (next.size() < 3 || !(normal.norm() > 0)) throw InputError("finger: vertex " + std::to_string(v) + " has no proper star");
  std::vector<int> link{next.begin()->first};
  while (static_cast<int>(link.size()) <= static_cast<int>(next.size())) {
    const auto it = next.find(link.back());
    if (it == next.end()) throw InputError("finger: the link of vertex " + std::to_string(v) + " is not a cycle");
    if (it->second == link.front()) break;
    link.push_back(it->second);
  }
  const int m = static_cast<int>(link.size());
  if (m != static_cast<int>(next.size())) throw InputError("finger: the link of vertex " + std::to_string(v) + " is not one cycle");
  normal.normalize();
  Vector3d centre = Vector3d::Zero();
  for (int a : link) centre += mesh.V.row(a).transpose();
  centre /= m;
  double radius = 0;
  for (int a : link) radius += (mesh.V.row(a).transpose() - centre).norm() / m;
  const int nv = mesh.num_vertices();
  TriMesh out;
  out.V.resize(nv + segments * m, 3);
  out.V.topRows(nv) = mesh.V;
  // ring[k][i]: the k-th copy of link vertex i (ring 0: the link itself).
  auto ring = [&](int k, int i) { return k == 0 ? link[i % m] : nv + (k - 1) * m + i % m; };
  for (int k = 1; k <= segments; ++k)
    for (int i = 0; i < m; ++i)
      out.V.row(ring(k, i)) = mesh.V.row(link[i]) + (length * k / segments) * normal.transpose();
  out.V.row(v) = (centre + (length + 0.5 * radius) * normal).transpose();
  std::vector<Eigen::Vector3i> faces;
  for (int t = 0; t < mesh.num_faces(); ++t)
    if (mesh.F(t, 0) != v && mesh.F(t, 1) != v && mesh.F(t, 2) != v) faces.emplace_back(mesh.F.row(t).transpose());
  for (int k = 0; k < segments; ++k)
    for (int i = 0; i < m; ++i) {
      faces.emplace_back(ring(k, i), ring(k, i + 1), ring(k + 1, i + 1));
      faces.emplace_back(ring(k, i), ring(k + 1, i + 1), ring(k + 1, i));
    }
  for (int i = 0; i < m; ++i) faces.emplace_back(v, ring(segments, i), ring(segments, i + 1));
  out.F.resize(static_cast<int>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) out.F.row(static_cast<int>(f)) = faces[f].transpose();
  return out;
}

TriMesh jitter(const TriMesh& mesh, double amplitude, unsigned seed) {
  if (!(amplitude >= 0 && amplitude < 0.3))
    throw InputError("jitter: amplitude " + std::to_string(amplitude) + " is out of range [0, 0.3)");
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  TriMesh out = mesh;
  std::vector<std::vector<int>> vf(nv);
  for (int t = 0; t < nf; ++t)
    for (int c = 0; c < 3; ++c) vf[mesh.F(t, c)].push_back(t);
  auto normal = [&](int t) {
    const Vector3d a = out.V.row(out.F(t, 0)), b = out.V.row(out.F(t, 1)), c = out.V.row(out.F(t, 2));
    return Vector3d((b - a).cross(c - a));
  };
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> angle(0.0, 2 * M_PI);
  for (int v = 0; v < nv; ++v) {
    // Local mean edge length and area-weighted vertex normal.
    double len = 0;
    int cnt = 0;
    Vector3d nrm = Vector3d::Zero();
    std::vector<Vector3d> before;
    for (int t : vf[v]) {
      for (int c = 0; c < 3; ++c) {
        len += (out.V.row(out.F(t, c)) - out.V.row(out.F(t, (c + 1) % 3))).norm();
        ++cnt;
      }
      before.push_back(normal(t));
      nrm += before.back();
    }
    const double theta = angle(rng);
    if (cnt == 0 || nrm.norm() == 0) continue;
    nrm.normalize();
    const Vector3d u = nrm.unitOrthogonal(), w = nrm.cross(u);
    const Vector3d offset = amplitude * (len / cnt) * (std::cos(theta) * u + std::sin(theta) * w);
    const Vector3d p0 = out.V.row(v);
    // Shrink the move until no incident face flips or loses most of its area.
    for (double scale = 1.0; scale > 1e-3; scale *= 0.5) {
      out.V.row(v) = (p0 + scale * offset).transpose();
      bool ok = true;
      for (size_t q = 0; q < vf[v].size() && ok; ++q) {
        const Vector3d nn = normal(vf[v][q]);
        ok = nn.dot(before[q]) > 0.2 * before[q].squaredNorm();
      }
      if (ok) break;
      out.V.row(v) = p0.transpose();
    }
  }
  return out;
}

TriMesh sphere_inversion(const TriMesh& mesh, const Vector3d& c, double rho) {
  if (!(rho > 0)) throw InputError("sphere_inversion: radius must be positive (got " + std::to_string(rho) + ")");
  TriMesh out = mesh;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    const Vector3d d = mesh.V.row(v).transpose() - c;
    const double d2 = d.squaredNorm();
    if (!(d2 > 1e-24))
      throw InputError("sphere_inversion: vertex " + std::to_string(v) + " coincides with the centre");
    out.V.row(v) = (c + rho * rho * d / d2).transpose();
  }
  // Inversion reverses orientation; whether the enclosed solid maps to the
  // enclosed solid depends on where c is, so decide by the signed volume.
  if (signed_volume(out) < 0) out.F.col(1).swap(out.F.col(2));
  return out;
}

TriMesh sphere(int subdivisions) {
  if (subdivisions < 0 || subdivisions > 9)
    throw InputError("sphere: subdivisions " + std::to_string(subdivisions) + " out of range (0..9)");
  const double t = (1 + std::sqrt(5.0)) / 2;
  std::vector<Vector3d> P = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                             {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<int, 3>> F = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (auto& p : P) p.normalize();
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      P.push_back((P[a] + P[b]).normalized());
      mid[key] = static_cast<int>(P.size()) - 1;
      return static_cast<int>(P.size()) - 1;
    };
    std::vector<std::array<int, 3>> G;
    G.reserve(4 * F.size());
    for (const auto& f : F) {
      const int ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]), ca = midpoint(f[2], f[0]);
      G.push_back({f[0], ab, ca});
      G.push_back({f[1], bc, ab});
      G.push_back({f[2], ca, bc});
      G.push_back({ab, bc, ca});
    }
    F.swap(G);
  }
  TriMesh m;
  m.V.resize(static_cast<int>(P.size()), 3);
  for (size_t v = 0; v < P.size(); ++v) m.V.row(static_cast<int>(v)) = P[v].transpose();
  m.F.resize(static_cast<int>(F.size()), 3);
  for (size_t f = 0; f < F.size(); ++f)
    for (int c = 0; c < 3; ++c) m.F(static_cast<int>(f), c) = F[f][c];
  if (signed_volume(m) < 0) m.F.col(1).swap(m.F.col(2));
  return m;
}

TriMesh spherical_cap(int rings, double bump) {
  if (rings < 1 || rings > 1000)
    throw InputError("spherical_cap: rings " + std::to_string(rings) + " out of range (1..1000)");
  const int around = 6 * rings;
  TriMesh m;
  m.V.resize(1 + rings * around, 3);
  m.V.row(0) << 0.0, 0.0, 1.0;
  for (int k = 1; k <= rings; ++k) {
    const double phi = 0.5 * M_PI * k / rings;
    for (int j = 0; j < around; ++j) {
      const double t = 2 * M_PI * j / around;
      m.V.row(1 + (k - 1) * around + j) << std::sin(phi) * std::cos(t), std::sin(phi) * std::sin(t), std::cos(phi);
    }
  }
  m.V.col(2) += bump * m.V.col(0).cwiseProduct(m.V.col(2));
  auto ring = [&](int k, int j) { return 1 + (k - 1) * around + j % around; };
  m.F.resize(around * (2 * rings - 1), 3);
  int f = 0;
  for (int j = 0; j < around; ++j) m.F.row(f++) << 0, ring(1, j), ring(1, j + 1);
  for (int k = 1; k < rings; ++k)
    for (int j = 0; j < around; ++j) {
      m.F.row(f++) << ring(k, j), ring(k + 1, j), ring(k + 1, j + 1);
      m.F.row(f++) << ring(k, j), ring(k + 1, j + 1), ring(k, j + 1);
    }
  return m;
}

TriMesh stretched_uv_sphere(int rings, int segments, double stretch) {
  if (rings < 2 || segments < 3 || !(stretch > 0))
    throw InputError("stretched_uv_sphere: needs rings >= 2, segments >= 3 and stretch > 0 (got " +
                     std::to_string(rings) + ", " + std::to_string(segments) + ", " + std::to_string(stretch) + ")");
  TriMesh m;
  const int nv = 2 + (rings - 1) * segments;
  m.V.resize(nv, 3);
  m.V.row(0) << 0, 0, stretch;
  for (int i = 1; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const double th = M_PI * i / rings, ph = 2 * M_PI * j / segments;
      m.V.row(1 + (i - 1) * segments + j) << std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph),
          stretch * std::cos(th);
    }
  m.V.row(nv - 1) << 0, 0, -stretch;
  auto id = [&](int i, int j) { return 1 + (i - 1) * segments + (j % segments); };
  std::vector<std::array<int, 3>> F;
  for (int j = 0; j < segments; ++j) F.push_back({0, id(1, j), id(1, j + 1)});
  for (int i = 1; i < rings - 1; ++i)
    for (int j = 0; j < segments; ++j) {
      F.push_back({id(i, j), id(i + 1, j), id(i, j + 1)});
      F.push_back({id(i, j + 1), id(i + 1, j), id(i + 1, j + 1)});
    }
  for (int j = 0; j < segments; ++j) F.push_back({nv - 1, id(rings - 1, j + 1), id(rings - 1, j)});
  m.F.resize(static_cast<int>(F.size()), 3);
  for (size_t f = 0; f < F.size(); ++f) m.F.row(static_cast<int>(f)) << F[f][0], F[f][1], F[f][2];
  return m;
}

TriMesh bent_tapered_sphere(int rings, int segments, double stretch, double bend) {
  if (rings < 2 || segments < 3 || !(stretch >= 1) || !(bend >= 0 && bend <= 1))
    throw InputError("bent_tapered_sphere: needs rings >= 2, segments >= 3, stretch >= 1 and bend in [0, 1] (got " +
                     std::to_string(rings) + ", " + std::to_string(segments) + ", " + std::to_string(stretch) + ", " +
                     std::to_string(bend) + ")");
  TriMesh m = stretched_uv_sphere(rings, segments, stretch);
  for (int v = 0; v < m.num_vertices(); ++v) {
    const double z = m.V(v, 2);
    m.V(v, 0) += bend * z * z / stretch;
    m.V(v, 1) *= 1.0 + z / (2.0 * stretch);  // in [0.5, 1.5]: never pinches
  }
  return m;
}

TriMesh peanut(int resolution, bool smooth) {
  Shape s;
  s.f = [](const Vector3d& p) {
    const double a = (p - Vector3d(-0.6, 0, 0)).norm() - 0.8, b = (p - Vector3d(0.6, 0.1, 0)).norm() - 0.7;
    return smin(a, b, 0.4);
  };
  s.lo = Vector3d(-1.45, -0.85, -0.85);
  s.hi = Vector3d(1.35, 0.85, 0.85);
  s.genus = 0;
  s.name = "peanut";
  return mesh_shape(s, resolution, smooth);
}

namespace {

// Builds faces of a polyhedral part with each face's required outward
// direction, so every triangle is oriented by its own normal (CAD faces are
// planar, never degenerate here).
struct PartBuilder {
  std::vector<Vector3d> V;
  std::vector<Eigen::Vector3i> F;
  int add(const Vector3d& p) {
    V.push_back(p);
    return static_cast<int>(V.size()) - 1;
  }
  void tri(int a, int b, int c, const Vector3d& outward) {
    const Vector3d n = (V[b] - V[a]).cross(V[c] - V[a]);
    if (n.dot(outward) >= 0)
      F.emplace_back(a, b, c);
    else
      F.emplace_back(a, c, b);
  }
  TriMesh mesh() const {
    TriMesh m;
    m.V.resize(static_cast<int>(V.size()), 3);
    m.F.resize(static_cast<int>(F.size()), 3);
    for (size_t i = 0; i < V.size(); ++i) m.V.row(i) = V[i].transpose();
    for (size_t i = 0; i < F.size(); ++i) m.F.row(i) = F[i].transpose();
    return m;
  }
};

}  // namespace

TriMesh cad_plate(int holes, int segments, double thickness) {
  if (holes < 1 || holes > 64) throw InputError("cad_plate: holes " + std::to_string(holes) + " is out of range (1..64)");
  if (segments < 8 || segments % 4 != 0)
    throw InputError("cad_plate: segments " + std::to_string(segments) + " must be a multiple of 4, >= 8");
  if (!(thickness > 0)) throw InputError("cad_plate: thickness must be positive");
  const double radius = 0.3;
  PartBuilder b;
  // corner[s][i][j]: layer s (0 bottom, 1 top), x = i, y = j.
  std::array<std::vector<std::array<int, 2>>, 2> corner;
  for (int s = 0; s < 2; ++s) {
    corner[s].resize(holes + 1);
    for (int i = 0; i <= holes; ++i)
      for (int j = 0; j < 2; ++j) corner[s][i][j] = b.add(Vector3d(i, j, s * thickness));
  }
  const Vector3d up(0, 0, 1);
  for (int h = 0; h < holes; ++h) {
    const Vector3d centre(h + 0.5, 0.5, 0);
    std::array<std::vector<int>, 2> rim;
    for (int s = 0; s < 2; ++s)
      for (int q = 0; q < segments; ++q) {
        const double a = 2 * M_PI * q / segments;
        rim[s].push_back(b.add(centre + Vector3d(radius * std::cos(a), radius * std::sin(a), s * thickness)));
      }
    for (int s = 0; s < 2; ++s) {
      const Vector3d out = s ? up : Vector3d(-up);
      // Corners at 45, 135, 225, 315 degrees around the hole's centre.
      const int quad_corner[4] = {corner[s][h + 1][1], corner[s][h][1], corner[s][h][0], corner[s][h + 1][0]};
      const int quarter = segments / 4;
      for (int q = 0; q < segments; ++q)  // the fans: long thin triangles
        b.tri(quad_corner[q / quarter], rim[s][q], rim[s][(q + 1) % segments], out);
      for (int k = 0; k < 4; ++k)  // between two fans, at 90 k + 90 degrees
        b.tri(quad_corner[k], quad_corner[(k + 1) % 4], rim[s][((k + 1) * quarter) % segments], out);
    }
    for (int q = 0; q < segments; ++q) {  // the hole's wall, facing its axis
      const int q1 = (q + 1) % segments;
      const Vector3d mid = 0.5 * (b.V[rim[0][q]] + b.V[rim[0][q1]]);
      const Vector3d inward(centre.x() - mid.x(), centre.y() - mid.y(), 0);
      b.tri(rim[0][q], rim[0][q1], rim[1][q1], inward);
      b.tri(rim[0][q], rim[1][q1], rim[1][q], inward);
    }
  }
  // Outer walls: one quad (two triangles) per side of each cell.
  auto wall = [&](int i0, int j0, int i1, int j1, const Vector3d& out) {
    b.tri(corner[0][i0][j0], corner[0][i1][j1], corner[1][i1][j1], out);
    b.tri(corner[0][i0][j0], corner[1][i1][j1], corner[1][i0][j0], out);
  };
  for (int i = 0; i < holes; ++i) {
    wall(i, 0, i + 1, 0, Vector3d(0, -1, 0));
    wall(i, 1, i + 1, 1, Vector3d(0, 1, 0));
  }
  wall(0, 0, 0, 1, Vector3d(-1, 0, 0));
  wall(holes, 0, holes, 1, Vector3d(1, 0, 0));
  TriMesh m = b.mesh();
  detail::check_closed_surface(m, holes, "cad_plate");
  return m;
}

TriMesh insert_degenerate_faces(const TriMesh& mesh, int count, double t, unsigned seed) {
  if (!(t >= 0 && t < 1)) throw InputError("insert_degenerate_faces: t must be in [0, 1)");
  const int nf = mesh.num_faces();
  if (count < 0 || count > nf / 8)
    throw InputError("insert_degenerate_faces: count " + std::to_string(count) + " is out of range (0.." +
                     std::to_string(nf / 8) + ")");
  const Connectivity conn(mesh.F, mesh.num_vertices());
  std::vector<char> used(nf, 0);
  std::vector<int> halfedges(3 * nf);
  std::iota(halfedges.begin(), halfedges.end(), 0);
  std::shuffle(halfedges.begin(), halfedges.end(), std::mt19937(seed));
  TriMesh out;
  std::vector<Vector3d> V;
  for (int v = 0; v < mesh.num_vertices(); ++v) V.push_back(mesh.V.row(v).transpose());
  std::vector<Eigen::Vector3i> F;
  for (int f = 0; f < nf; ++f) F.push_back(mesh.F.row(f).transpose());
  int done = 0;
  for (int h : halfedges) {
    if (done == count) break;
    const int f0 = h / 3, f1 = conn.twin(h) / 3;
    if (used[f0] || used[f1]) continue;
    used[f0] = used[f1] = 1;
    const int a = conn.tail(h), bv = conn.head(h), c = conn.opposite_vertex(h);
    const int m = static_cast<int>(V.size());
    V.push_back(V[a] + t * (V[bv] - V[a]));
    F[f0] = Eigen::Vector3i(a, m, c);
    F.emplace_back(m, bv, c);
    F.emplace_back(m, a, bv);  // zero area: m lies on the segment a-b
    ++done;
  }
  if (done < count)
    throw InputError("insert_degenerate_faces: found only " + std::to_string(done) + " separate edges");
  out.V.resize(static_cast<int>(V.size()), 3);
  out.F.resize(static_cast<int>(F.size()), 3);
  for (size_t i = 0; i < V.size(); ++i) out.V.row(i) = V[i].transpose();
  for (size_t i = 0; i < F.size(); ++i) out.F.row(i) = F[i].transpose();
  return out;
}

}  // namespace surfmap::samples
