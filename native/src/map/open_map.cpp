// The optimal map between two disks or two annuli (docs/open_surfaces.md).
#include "surfmap/map/open_map.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <functional>
#include <cmath>
#include <set>

#include <Eigen/Geometry>

#include "../seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/map/distortion.h"
#include "surfmap/map/ear_images.h"
#include "surfmap/map/map_report.h"

namespace surfmap {
namespace {

using cd = std::complex<double>;

// Point location in a canonical domain (unit disk, or the cylinder unwrapped
// per face): a uniform grid of face bounding boxes; points outside every
// face (the disk's boundary arcs lie outside the inscribed boundary polygon)
// go to the nearest face touching the boundary. Points on the domain's
// boundary (the unit circle, the cylinder's lines y = 0 and y = modulus) go
// onto the nearest boundary edge of the mesh: on the cylinder an ear's inner
// edge (a chord between two vertices of one loop) lies on the boundary line
// too, and a point located on it would land on the chord in 3D, off the
// target's boundary (measured: 1.8% of the diagonal).
class DomainLocator {
 public:
  DomainLocator(const TriMesh& mesh, const OpenConformalResult& domain)
      : cylinder_(domain.cylinder), modulus_(domain.modulus) {
    const int nf = mesh.num_faces();
    tris_.resize(nf);
    double lo_x = 1e300, hi_x = -1e300, lo_y = 1e300, hi_y = -1e300;
    for (int f = 0; f < nf; ++f) {
      tris_[f] = face_image(domain, mesh, f);
      for (const cd& z : tris_[f])
        lo_x = std::min(lo_x, z.real()), hi_x = std::max(hi_x, z.real()), lo_y = std::min(lo_y, z.imag()),
        hi_y = std::max(hi_y, z.imag());
    }
    // Faces with a vertex on the boundary: the fallback candidates.
    std::vector<char> on_boundary(mesh.num_vertices(), 0);
    for (int v = 0; v < mesh.num_vertices(); ++v) {
      const cd z = domain.uv[v];
      on_boundary[v] = domain.cylinder ? (z.imag() <= 1e-12 || z.imag() >= domain.modulus - 1e-12)
                                       : std::abs(std::abs(z) - 1.0) < 1e-12;
    }
    for (int f = 0; f < nf; ++f)
      if (on_boundary[mesh.F(f, 0)] || on_boundary[mesh.F(f, 1)] || on_boundary[mesh.F(f, 2)]) rim_.push_back(f);
    // The mesh's boundary edges: (face, corner k) for the edge k -> k + 1
    // without a twin.
    std::set<std::pair<int, int>> directed;
    for (int f = 0; f < nf; ++f)
      for (int k = 0; k < 3; ++k) directed.emplace(mesh.F(f, k), mesh.F(f, (k + 1) % 3));
    for (int f = 0; f < nf; ++f)
      for (int k = 0; k < 3; ++k)
        if (!directed.count({mesh.F(f, (k + 1) % 3), mesh.F(f, k)})) boundary_edges_.emplace_back(f, k);
    x0_ = lo_x, y0_ = lo_y;
    const int n = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(nf))));
    cell_ = std::max(std::max(hi_x - lo_x, hi_y - lo_y) / n, 1e-300);
    nx_ = static_cast<int>((hi_x - lo_x) / cell_) + 1, ny_ = static_cast<int>((hi_y - lo_y) / cell_) + 1;
    cells_.assign(static_cast<size_t>(nx_) * ny_, {});
    for (int f = 0; f < nf; ++f) {
      const auto& t = tris_[f];
      const int ix0 = cx(std::min({t[0].real(), t[1].real(), t[2].real()})),
                ix1 = cx(std::max({t[0].real(), t[1].real(), t[2].real()}));
      const int iy0 = cy(std::min({t[0].imag(), t[1].imag(), t[2].imag()})),
                iy1 = cy(std::max({t[0].imag(), t[1].imag(), t[2].imag()}));
      for (int x = ix0; x <= ix1; ++x)
        for (int y = iy0; y <= iy1; ++y) cells_[static_cast<size_t>(y) * nx_ + x].push_back(f);
    }
  }

  /// Face and barycentrics (clamped to the face) of the point z.
  int locate(cd z, Eigen::Vector3d* bary) const {
    if (cylinder_) z = cd(z.real() - std::floor(z.real()), z.imag());
    const double shifts[3] = {0.0, -1.0, 1.0};
    const bool on_domain_boundary = cylinder_ ? (z.imag() <= 1e-12 || z.imag() >= modulus_ - 1e-12)
                                              : std::abs(std::abs(z) - 1.0) < 1e-12;
    if (on_domain_boundary) {
      double best_d = 1e300;
      int best = -1;
      for (int s = 0; s < (cylinder_ ? 3 : 1); ++s) {
        const cd q = z + shifts[s];
        for (const auto& [f, k] : boundary_edges_) {
          const cd a = tris_[f][k], b = tris_[f][(k + 1) % 3];
          const double len2 = std::norm(b - a);
          const double t = len2 > 0 ? std::clamp(std::real(std::conj(b - a) * (q - a)) / len2, 0.0, 1.0) : 0.0;
          const double d = std::abs(a + t * (b - a) - q);
          if (d < best_d) {
            best_d = d, best = f;
            *bary = Eigen::Vector3d::Zero();
            (*bary)[k] = 1 - t, (*bary)[(k + 1) % 3] = t;
          }
        }
      }
      if (best >= 0) return best;
    }
    for (int s = 0; s < (cylinder_ ? 3 : 1); ++s) {
      const cd q = z + shifts[s];
      const double fx = (q.real() - x0_) / cell_, fy = (q.imag() - y0_) / cell_;
      if (fx < 0 || fy < 0 || fx >= nx_ || fy >= ny_) continue;
      int best = -1;
      double best_min = -1e-9;
      for (int f : cells_[static_cast<size_t>(fy) * nx_ + static_cast<int>(fx)]) {
        const Eigen::Vector3d b = barycentric(tris_[f], q);
        if (b.minCoeff() >= best_min) best_min = b.minCoeff(), best = f, *bary = b;
      }
      if (best >= 0) {
        *bary = bary->cwiseMax(0.0);
        *bary /= bary->sum();
        return best;
      }
    }
    // Nearest rim face (closest point on its edges).
    double best_d = 1e300;
    int best = -1;
    for (int s = 0; s < (cylinder_ ? 3 : 1); ++s) {
      const cd q = z + shifts[s];
      for (int f : rim_) {
        const auto& t = tris_[f];
        for (int k = 0; k < 3; ++k) {
          const cd a = t[k], b = t[(k + 1) % 3];
          const double len2 = std::norm(b - a);
          const double s01 = len2 > 0 ? std::clamp(std::real(std::conj(b - a) * (q - a)) / len2, 0.0, 1.0) : 0.0;
          const double d = std::abs(a + s01 * (b - a) - q);
          if (d < best_d) {
            best_d = d, best = f;
            *bary = Eigen::Vector3d::Zero();
            (*bary)[k] = 1 - s01, (*bary)[(k + 1) % 3] = s01;
          }
        }
      }
    }
    if (best < 0) throw SolveError("point location in the canonical domain failed (no boundary faces)");
    return best;
  }

 private:
  static Eigen::Vector3d barycentric(const std::array<cd, 3>& t, cd p) {
    auto cross = [](cd a, cd b) { return a.real() * b.imag() - a.imag() * b.real(); };
    const double area = cross(t[1] - t[0], t[2] - t[0]);
    if (area == 0) return Eigen::Vector3d::Constant(-1e300);
    return Eigen::Vector3d(cross(t[1] - p, t[2] - p), cross(t[2] - p, t[0] - p), cross(t[0] - p, t[1] - p)) / area;
  }
  int cx(double x) const { return std::clamp(static_cast<int>((x - x0_) / cell_), 0, nx_ - 1); }
  int cy(double y) const { return std::clamp(static_cast<int>((y - y0_) / cell_), 0, ny_ - 1); }
  bool cylinder_;
  double modulus_;
  std::vector<std::array<cd, 3>> tris_;
  std::vector<int> rim_;
  std::vector<std::pair<int, int>> boundary_edges_;
  double x0_ = 0, y0_ = 0, cell_ = 1;
  int nx_ = 1, ny_ = 1;
  std::vector<std::vector<int>> cells_;
};

// A Möbius map (a z + b) / (c z + d) as its matrix {a, b, c, d}.
using Mobius = std::array<cd, 4>;
constexpr Mobius kIdentity{cd(1), cd(0), cd(0), cd(1)};
cd mobius_apply(const Mobius& m, cd z) { return (m[0] * z + m[1]) / (m[2] * z + m[3]); }
Mobius inverse_of(const Mobius& m) { return {m[3], -m[1], -m[2], m[0]}; }
Mobius compose(const Mobius& f, const Mobius& g) {  // f ∘ g
  return {f[0] * g[0] + f[1] * g[2], f[0] * g[1] + f[1] * g[3], f[2] * g[0] + f[3] * g[2], f[2] * g[1] + f[3] * g[3]};
}
// The disk automorphism z -> (z - a) / (1 - conj(a) z), sending a to 0.
Mobius to_origin(cd a) { return {cd(1), -a, -std::conj(a), cd(1)}; }
// The Möbius map sending z1, z2, z3 to 0, 1, infinity.
Mobius three_points(cd z1, cd z2, cd z3) { return {z2 - z3, -z1 * (z2 - z3), z2 - z1, -z3 * (z2 - z1)}; }

// The map between the canonical domains and its inverse. Disk:
// post(e^{i rotation} pre(z)), pre and post disk automorphisms (identity
// unless landmarks are held, hold_landmarks).
// Cylinder: x -> x + rotation + twist y / source_height (a Dehn twist about
// the core, `twist` whole turns), y -> y stretch (swap: both reversed).
struct DomainMap {
  bool cylinder = false, swap = false;
  double rotation = 0, stretch = 1, target_height = 0, source_height = 1;
  int twist = 0;
  Mobius pre = kIdentity, post = kIdentity;
  cd forward(cd z) const {
    if (!cylinder) return mobius_apply(post, mobius_apply(pre, z) * std::polar(1.0, rotation));
    const double x = z.real() + twist * z.imag() / source_height;
    if (!swap) return cd(x + rotation, z.imag() * stretch);
    return cd(rotation - x, target_height - z.imag() * stretch);
  }
  cd inverse(cd w) const {
    if (!cylinder) return mobius_apply(inverse_of(pre), mobius_apply(inverse_of(post), w) * std::polar(1.0, -rotation));
    const double y = swap ? (target_height - w.imag()) / stretch : w.imag() / stretch;
    const double x = swap ? rotation - w.real() : w.real() - rotation;
    return cd(x - twist * y / source_height, y);
  }
};

// The morph's Dirichlet energy (1/4) Σ_corners cot(angle) |opposite image
// edge|² with the source's own cotangents, for the images `image`.
double morph_energy(const TriMesh& source, const std::function<Eigen::Vector3d(int)>& image) {
  std::vector<Eigen::Vector3d> q(source.num_vertices());
  for (int i = 0; i < source.num_vertices(); ++i) q[i] = image(i);
  double energy = 0;
  for (int f = 0; f < source.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p0 = source.V.row(source.F(f, k)), p1 = source.V.row(source.F(f, (k + 1) % 3)),
                            p2 = source.V.row(source.F(f, (k + 2) % 3));
      const Eigen::Vector3d u = p1 - p0, v = p2 - p0;
      energy += 0.25 * u.dot(v) / std::max(u.cross(v).norm(), 1e-300) *
                (q[source.F(f, (k + 2) % 3)] - q[source.F(f, (k + 1) % 3)]).squaredNorm();
    }
  return energy;
}

PointOnSurface point_in_face(const TriMesh& mesh, int f, const Eigen::Vector3d& b) {
  PointOnSurface p;
  p.face = f;
  p.barycentric = b;
  p.position = b[0] * mesh.V.row(mesh.F(f, 0)).transpose() + b[1] * mesh.V.row(mesh.F(f, 1)).transpose() +
               b[2] * mesh.V.row(mesh.F(f, 2)).transpose();
  return p;
}

// Positions moved to their area centroid and scaled to unit area.
RowMatrixX3d normalised(const TriMesh& mesh) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  double area = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    const double w = 0.5 * (b - a).cross(c - a).norm();
    centroid += w * (a + b + c) / 3, area += w;
  }
  centroid /= area;
  RowMatrixX3d X = mesh.V.rowwise() - centroid.transpose();
  return X / std::sqrt(area);
}

// Rotation / shift minimising the squared distance between the sampled
// source vertices and their images (normalised shapes).
double align(const TriMesh& source, const TriMesh& target, const OpenConformalResult& sd, const DomainLocator& tloc,
             DomainMap m, int samples) {
  const RowMatrixX3d xs = normalised(source), xt = normalised(target);
  const int ns = source.num_vertices();
  const int step = std::max(1, ns / std::max(samples, 1));
  const double period = m.cylinder ? 1.0 : 2 * M_PI;
  auto cost = [&](double r) {
    m.rotation = r;
    double total = 0;
    for (int i = 0; i < ns; i += step) {
      Eigen::Vector3d b;
      const int f = tloc.locate(m.forward(sd.uv[i]), &b);
      const Eigen::Vector3d y = b[0] * xt.row(target.F(f, 0)).transpose() + b[1] * xt.row(target.F(f, 1)).transpose() +
                                b[2] * xt.row(target.F(f, 2)).transpose();
      total += (y - xs.row(i).transpose()).squaredNorm();
    }
    return total;
  };
  const int coarse = 64;
  int best = 0;
  double best_cost = 1e300;
  for (int k = 0; k < coarse; ++k) {
    const double c = cost(period * k / coarse);
    if (c < best_cost) best_cost = c, best = k;
  }
  // Golden-section search in the bracket around the best sample.
  double a = period * (best - 1) / coarse, b = period * (best + 1) / coarse;
  const double g = (std::sqrt(5.0) - 1) / 2;
  double c1 = b - g * (b - a), c2 = a + g * (b - a), f1 = cost(c1), f2 = cost(c2);
  for (int it = 0; it < 30; ++it) {
    if (f1 < f2)
      b = c2, c2 = c1, f2 = f1, c1 = b - g * (b - a), f1 = cost(c1);
    else
      a = c1, c1 = c2, f1 = f2, c2 = a + g * (b - a), f2 = cost(c2);
  }
  double r = 0.5 * (a + b);
  r -= period * std::floor(r / period);
  return r >= period ? r - period : r;  // round-off of a tiny negative r
}

/// Landmarks of a disk or annulus pair (docs/open_surfaces.md, "Landmarks"):
/// sets the parts of `m` they pin and returns true when they pin the
/// rotation / shift too (no alignment then). Disk (the 3-parameter Möbius
/// group, exactly): one interior point (pre/post send it to the centre, the
/// rotation still aligns the shapes), one interior and one boundary point, or
/// up to three boundary points (two: the third is the midpoint of the arc
/// from the first to the second on each side). Annulus: the shift, the
/// circular mean over the landmarks (exact for one; heights follow the
/// stretch). Boundary landmarks must lie on the paired target loop.
bool hold_landmarks(const std::vector<std::pair<int, int>>& landmarks, const OpenMapResult& r,
                    const TriMesh& source, const TriMesh& target, DomainMap& m) {
  if (landmarks.empty()) return false;
  std::vector<int> s_loop(source.num_vertices(), -1), t_loop(target.num_vertices(), -1);
  for (size_t i = 0; i < r.source_topology.boundary_loops.size(); ++i)
    for (int v : r.source_topology.boundary_loops[i]) s_loop[v] = static_cast<int>(i);
  for (size_t i = 0; i < r.target_topology.boundary_loops.size(); ++i)
    for (int v : r.target_topology.boundary_loops[i]) t_loop[v] = static_cast<int>(i);
  std::vector<cd> zs, zt;
  std::vector<char> rim;
  for (size_t k = 0; k < landmarks.size(); ++k) {
    const auto [p, q] = landmarks[k];
    const std::string name = "landmark " + std::to_string(k) + " (" + std::to_string(p) + " " + std::to_string(q) + ")";
    if (p < 0 || p >= source.num_vertices())
      throw InputError(name + ": source vertex out of range (" + std::to_string(source.num_vertices()) + " vertices)");
    if (q < 0 || q >= target.num_vertices())
      throw InputError(name + ": target vertex out of range (" + std::to_string(target.num_vertices()) + " vertices)");
    if ((s_loop[p] < 0) != (t_loop[q] < 0))
      throw InputError(name + ": the " + (s_loop[p] < 0 ? "target" : "source") + " vertex is on the boundary but the " +
                       (s_loop[p] < 0 ? "source" : "target") + " vertex is not (boundary maps onto boundary)");
    if (s_loop[p] >= 0 && r.boundary_pairing[s_loop[p]] != t_loop[q])
      throw InputError(name + ": source loop " + std::to_string(s_loop[p]) + " maps onto target loop " +
                       std::to_string(r.boundary_pairing[s_loop[p]]) + ", not loop " + std::to_string(t_loop[q]));
    zs.push_back(r.source_domain.uv[p]), zt.push_back(r.target_domain.uv[q]), rim.push_back(s_loop[p] >= 0);
  }
  const int n = static_cast<int>(landmarks.size());
  if (m.cylinder) {
    cd mean = 0;  // the shift on the circle R/Z
    for (int k = 0; k < n; ++k) {
      m.rotation = 0;
      mean += std::polar(1.0, 2 * M_PI * (zt[k].real() - m.forward(zs[k]).real()));
    }
    m.rotation = std::arg(mean) / (2 * M_PI);
    m.rotation -= std::floor(m.rotation);
    return true;
  }
  const int interior = static_cast<int>(std::count(rim.begin(), rim.end(), 0));
  const std::string refuse = "disk landmarks: give up to 3 boundary points, or 1 interior point and at most 1 "
                             "boundary point (the disk's Möbius group has 3 parameters); got " +
                             std::to_string(interior) + " interior and " + std::to_string(n - interior) + " boundary";
  if (n > 3 || interior > 1 || (interior == 1 && n > 2)) throw InputError(refuse);
  if (interior == 1) {
    const int k = rim[0] ? 1 : 0;
    m.pre = to_origin(zs[k]), m.post = inverse_of(to_origin(zt[k]));
    if (n == 1) return false;  // the rotation aligns the shapes
    const int j = 1 - k;
    m.rotation = std::arg(mobius_apply(to_origin(zt[k]), zt[j]) / mobius_apply(m.pre, zs[j]));
    return true;
  }
  if (n == 1) {
    m.rotation = std::arg(zt[0] / zs[0]);
    return true;
  }
  if (n == 2) {  // the midpoint of the arc from the first to the second point
    auto mid = [](cd a, cd b) {
      double t = std::arg(b / a);
      if (t < 0) t += 2 * M_PI;
      return a * std::polar(1.0, t / 2);
    };
    zs.push_back(mid(zs[0], zs[1])), zt.push_back(mid(zt[0], zt[1]));
  }
  // Three boundary points in the same cyclic order on both circles.
  auto turn = [](cd a, cd b, cd c) { return std::imag(std::conj(b - a) * (c - a)) > 0; };
  if (turn(zs[0], zs[1], zs[2]) != turn(zt[0], zt[1], zt[2]))
    throw InputError("disk landmarks: the boundary points run in opposite cyclic orders on the source and the target");
  m.pre = compose(inverse_of(three_points(zt[0], zt[1], zt[2])), three_points(zs[0], zs[1], zs[2]));
  m.rotation = 0;
  return true;
}

/// Throws InputError unless `pairing` is a permutation of 0..b-1.
void check_boundary_pairing(const std::vector<int>& pairing, int b) {
  std::string text;
  for (int t : pairing) text += (text.empty() ? "" : ", ") + std::to_string(t);
  std::vector<char> seen(b, 0);
  bool ok = static_cast<int>(pairing.size()) == b;
  for (int t : pairing) ok = ok && t >= 0 && t < b && !seen[t]++;
  if (!ok)
    throw InputError("boundary pairing [" + text + "]: must give each of the " + std::to_string(b) +
                     " source boundary loops a different target loop 0.." + std::to_string(b - 1));
}

}  // namespace

OpenMapResult open_surface_map(const TriMesh& source, const OpenSurfaceTopology& source_topology,
                               const TriMesh& target, const OpenSurfaceTopology& target_topology,
                               const OpenMapOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  check_same_open_topology(source_topology, target_topology);
  const int g = source_topology.genus, b = source_topology.num_boundary_loops();
  if (g != 0 || (b != 1 && b != 2))
    throw InputError("open surfaces of genus " + std::to_string(g) + " with " + std::to_string(b) +
                     (b == 1 ? " boundary loop" : " boundary loops") +
                     " are not supported yet: the source and the target both have " +
                     source_topology.describe() + " (supported: a disk, genus 0 with 1 loop; an annulus, genus 0 "
                     "with 2 loops; closed surfaces of any genus)");
  OpenMapResult r;
  r.source_topology = source_topology, r.target_topology = target_topology;
  const bool disk = b == 1;
  r.domain = disk ? "disk" : "annulus";
  r.source_domain = disk ? disk_conformal_map(source, source_topology, options.conformal)
                         : annulus_conformal_map(source, source_topology, options.conformal);
  r.target_domain = disk ? disk_conformal_map(target, target_topology, options.conformal)
                         : annulus_conformal_map(target, target_topology, options.conformal);
  DomainMap m;
  m.cylinder = !disk;
  r.boundary_pairing = options.boundary_pairing;
  if (r.boundary_pairing.empty()) {
    for (int i = 0; i < b; ++i) r.boundary_pairing.push_back(i);
    if (!disk && options.swap_annulus_loops) std::swap(r.boundary_pairing[0], r.boundary_pairing[1]);
  }
  check_boundary_pairing(r.boundary_pairing, b);
  m.swap = !disk && r.boundary_pairing[0] == 1;
  if (!disk) {
    m.stretch = r.target_domain.modulus / r.source_domain.modulus;
    m.target_height = r.target_domain.modulus;
    m.source_height = r.source_domain.modulus;
    m.twist = options.twist;
    r.extremal_dilatation = std::max(m.stretch, 1.0 / m.stretch);
  }
  const DomainLocator tloc(target, r.target_domain), sloc(source, r.source_domain);
  const bool pinned = hold_landmarks(options.landmarks, r, source, target, m);
  auto place = [&] {
    if (!pinned)
      m.rotation = std::isnan(options.rotation) ? align(source, target, r.source_domain, tloc, m, options.alignment_samples)
                                                : options.rotation;
  };
  place();
  if (!disk && options.twist_search) {
    // Twists about the core (issue 16): the boundary slides freely, so a
    // twisted map is homotopic to the untwisted one through maps taking
    // boundary to boundary (turn one loop), and the energy ranks them; from
    // the start, step to the lower neighbour while the energy decreases.
    auto energy_at = [&](int k) {
      DomainMap mk = m;
      mk.twist = k;
      const double e = morph_energy(source, [&](int i) {
        Eigen::Vector3d bary;
        const int f = tloc.locate(mk.forward(r.source_domain.uv[i]), &bary);
        return point_in_face(target, f, bary).position;
      });
      r.twist_energies.emplace_back(k, e);
      return e;
    };
    double here = energy_at(m.twist);
    for (int moves = 0; moves < 64; ++moves) {
      const double up = energy_at(m.twist + 1), down = energy_at(m.twist - 1);
      if (std::min(up, down) >= here) break;
      m.twist += up < down ? 1 : -1;
      here = std::min(up, down);
    }
    if (m.twist != options.twist) place();  // the shift aligned for the twist kept
  }
  r.twist = m.twist;
  r.rotation = m.rotation;

  SurfaceMapResult& out = r.map;
  out.genus = 0;
  out.converged = true;
  out.forward.resize(source.num_vertices());
  for (int i = 0; i < source.num_vertices(); ++i) {
    Eigen::Vector3d bary;
    const int f = tloc.locate(m.forward(r.source_domain.uv[i]), &bary);
    out.forward[i] = point_in_face(target, f, bary);
  }
  out.inverse.resize(target.num_vertices());
  for (int j = 0; j < target.num_vertices(); ++j) {
    Eigen::Vector3d bary;
    const int f = sloc.locate(m.inverse(r.target_domain.uv[j]), &bary);
    out.inverse[j] = point_in_face(source, f, bary);
  }
  // Ears whose chord image turns over (three points of a concave or jagged
  // stretch of the other boundary): the middle corner's image slid along the
  // other boundary, else a window of boundary vertices around it
  // (map/ear_images.h), both directions; landmarks keep their images.
  {
    EarImagesOptions fw_options, inv_options;
    for (const auto& [p, q] : options.landmarks) fw_options.held.push_back(p), inv_options.held.push_back(q);
    r.forward_ears = slide_ear_images(source, source_topology, target, target_topology, out.forward, fw_options);
    r.inverse_ears = slide_ear_images(target, target_topology, source, source_topology, out.inverse, inv_options);
  }
  // Ears: source faces with all three corners on the boundary. Their image
  // is fixed by the boundary correspondence alone: on the annulus's straight
  // boundary lines a degenerate triangle by construction, on a disk the
  // chord triangle of three boundary points, which is near-degenerate on
  // the target when the source is much coarser.
  std::vector<char> on_boundary(source.num_vertices(), 0), ear(source.num_faces(), 0);
  for (const auto& loop : source_topology.boundary_loops)
    for (int v : loop) on_boundary[v] = 1;
  for (int f = 0; f < source.num_faces(); ++f)
    ear[f] = on_boundary[source.F(f, 0)] && on_boundary[source.F(f, 1)] && on_boundary[source.F(f, 2)];
  // Flips: source faces whose corners' images in the target's domain turn
  // clockwise (the cylinder unwrapped per face); ears with a zero-area
  // image are degenerate instead.
  for (int f = 0; f < source.num_faces(); ++f) {
    std::array<cd, 3> w = face_image(r.source_domain, source, f);
    for (auto& z : w) z = m.forward(z);
    const double area = std::imag(std::conj(w[1] - w[0]) * (w[2] - w[0]));
    const double scale = std::norm(w[1] - w[0]) + std::norm(w[2] - w[0]);
    if (ear[f] && std::abs(area) <= 1e-12 * scale)
      ++r.ear_triangles_degenerate;
    else if (area <= 0)
      ++out.flipped_triangles;
  }
  // D' on the morph's triangles and the morph's Dirichlet energy
  // (1/4) Σ_corners cot(angle) |opposite image edge|².
  out.dilatation.assign(source.num_faces(), std::numeric_limits<double>::infinity());
  const std::vector<char> thin = thin_source_faces(source.V, source.F);
  double weighted = 0, total = 0, energy = 0;
  for (int f = 0; f < source.num_faces(); ++f) {
    Eigen::Vector3d p[3], q[3];
    for (int k = 0; k < 3; ++k) p[k] = source.V.row(source.F(f, k)), q[k] = out.forward[source.F(f, k)].position;
    const double area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).norm();
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d u = p[(k + 1) % 3] - p[k], v = p[(k + 2) % 3] - p[k];
      energy += 0.25 * u.dot(v) / std::max(u.cross(v).norm(), 1e-300) * (q[(k + 2) % 3] - q[(k + 1) % 3]).squaredNorm();
    }
    const double d = triangle_dilatation(Eigen::Vector3d((p[1] - p[0]).norm(), (p[2] - p[1]).norm(), (p[0] - p[2]).norm()),
                                         Eigen::Vector3d((q[1] - q[0]).norm(), (q[2] - q[1]).norm(), (q[0] - q[2]).norm()));
    if (ear[f]) {  // left out of mean and max, counted (see above)
      out.dilatation[f] = d;
      ++r.ear_triangles;
      continue;
    }
    if (!std::isfinite(d)) {
      ++out.degenerate_triangles;
      continue;
    }
    out.dilatation[f] = d;
    if (thin[f]) {  // D' of digits no solver resolved: kept per face, left out of mean and max
      out.thin_source_faces.push_back(f);
      out.thin_source_max_dilatation = std::max(out.thin_source_max_dilatation, d);
      continue;
    }
    weighted += area * d, total += area;
    out.max_dilatation = std::max(out.max_dilatation, d);
  }
  out.mean_dilatation = weighted / std::max(total, 1e-300);
  for (const auto& [p, q] : options.landmarks)
    r.landmark_error = std::max(r.landmark_error, (out.forward[p].position - target.V.row(q).transpose()).norm());
  out.final_energy = out.initial_energy = energy;
  out.initial_mean_dilatation = out.mean_dilatation, out.initial_max_dilatation = out.max_dilatation;
  out.total_time = detail::seconds_since(start);
  out.candidates.push_back(HomotopyCandidate{});
  out.candidates.back().description = disk ? "disk: conformal, rotation aligning the shapes"
                                           : (m.swap ? "annulus: affine stretch, loop 0 -> loop 1"
                                                     : "annulus: affine stretch, loop i -> loop i");
  out.candidates.back().energy = energy;
  out.chosen_candidate = 0;
  return r;
}

nlohmann::json to_json(const OpenMapResult& r, const OpenMapOptions& options) {
  auto domain_json = [](const OpenConformalResult& d) {
    return nlohmann::json{{"modulus", d.modulus},
                          {"modulus_from_u", d.modulus_from_u},
                          {"modulus_from_theta", d.modulus_from_theta},
                          {"pole", d.pole},
                          {"centring_iterations", d.centring_iterations},
                          {"flipped_faces", d.flipped_faces},
                          {"degenerate_faces", d.degenerate_faces},
                          {"weights", open_conformal_weights_name(d.weights)},
                          {"intrinsic_flips", d.intrinsic_flips},
                          {"intrinsic_flipped_faces", d.intrinsic_flipped_faces},
                          {"kept_rounds", d.kept_rounds},
                          {"kept_faces", d.kept_faces},
                          {"own_negative_weights", d.own_negative_weights},
                          {"negative_weights", d.negative_weights}};
  };
  auto topology_json = [](const OpenSurfaceTopology& t) {
    return nlohmann::json{{"genus", t.genus}, {"boundary_loops", t.num_boundary_loops()}, {"description", t.describe()},
                          {"boundary_lengths", t.boundary_lengths}};
  };
  nlohmann::json report = to_json(r.map, SurfaceMapOptions{});
  report["method"] = "open";
  report["distortion"]["measure"] =
      "D' = ratio of the singular values of the affine map from each source face onto the triangle of its corners' "
      "images on the target in 3D (the morph's triangles); mean weighted by the source faces' 3D areas "
      "(unweighted_mean: every face alike), max over the faces; ear triangles left out (open.ear_triangles)";
  report["boundary_loops"] = r.source_topology.num_boundary_loops();
  report["source_topology"] = topology_json(r.source_topology);
  report["target_topology"] = topology_json(r.target_topology);
  report["open"] = {{"domain", r.domain},
                    {"rotation", r.rotation},
                    {"rotation_requested", !std::isnan(options.rotation)},
                    {"twist", r.twist},
                    {"twist_start", options.twist},
                    {"twist_energies", r.twist_energies},
                    {"extremal_dilatation", r.extremal_dilatation},
                    {"boundary_pairing", r.boundary_pairing},
                    {"landmarks", options.landmarks.size()},
                    {"landmark_error", r.landmark_error},
                    {"ear_triangles", r.ear_triangles},
                    {"ear_triangles_degenerate", r.ear_triangles_degenerate},
                    {"ears_turned", r.forward_ears.turned},
                    {"ears_slid", r.forward_ears.moved},
                    {"ears_slid_with_neighbours", r.forward_ears.moved_with_neighbours},
                    {"ears_turned_after", r.forward_ears.turned_after},
                    {"inverse_ear_triangles", r.inverse_ears.ears},
                    {"inverse_ears_turned", r.inverse_ears.turned},
                    {"inverse_ears_slid", r.inverse_ears.moved},
                    {"inverse_ears_slid_with_neighbours", r.inverse_ears.moved_with_neighbours},
                    {"inverse_ears_turned_after", r.inverse_ears.turned_after},
                    {"source", domain_json(r.source_domain)},
                    {"target", domain_json(r.target_domain)},
                    {"description", r.map.candidates.empty() ? std::string() : r.map.candidates[0].description}};
  return report;
}

}  // namespace surfmap
