// Genus 0: maps through the unit sphere (docs/method.md §2.4, §2.10). See
// map/spherical_map.h for the choice of the Möbius map.
#include "surfmap/map/spherical_map.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <memory>
#include <string>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <Eigen/SparseLU>
#include <Eigen/SparseCore>

#include "map_support.h"
#include "surfmap/error.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/distortion.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/uniformize/spherical.h"
#include "surfmap/uniformize/spherical_correspondence.h"
#include "surfmap/uniformize/spherical_subdivision.h"

namespace surfmap {
namespace {

using Complex = std::complex<double>;
using Hom = Eigen::Vector2cd;  // homogeneous coordinates [w1 : w2] of z = w1 / w2

// Stereographic projection from the north pole in homogeneous coordinates,
// using whichever of the two equivalent forms avoids the division by ~0.
Hom to_hom(const Eigen::Vector3d& p) {
  if (p.z() <= 0) return Hom(Complex(p.x(), p.y()), Complex(1.0 - p.z(), 0.0));
  return Hom(Complex(1.0 + p.z(), 0.0), Complex(p.x(), -p.y()));
}

Eigen::Vector3d from_hom(const Hom& w) {
  const double a = std::norm(w[0]), b = std::norm(w[1]), s = a + b;
  const Complex c = w[0] * std::conj(w[1]);
  return Eigen::Vector3d(2 * c.real() / s, 2 * c.imag() / s, (a - b) / s);
}

Eigen::Matrix2cd normalized(Eigen::Matrix2cd m) {
  const Complex d = m.determinant();
  return m / std::sqrt(d);
}

// |det(u, v)| relative to |u| |v|: 0 when the two points coincide.
double separation(const Hom& u, const Hom& v) {
  return std::abs(u[0] * v[1] - u[1] * v[0]) / (u.norm() * v.norm());
}

// The Möbius map sending u1 -> 0, u2 -> 1, u3 -> ∞.
Eigen::Matrix2cd to_standard(const Hom& u1, const Hom& u2, const Hom& u3) {
  const Complex lambda = u3[1] * u2[0] - u3[0] * u2[1], mu = u1[1] * u2[0] - u1[0] * u2[1];
  Eigen::Matrix2cd s;
  s << lambda * u1[1], -lambda * u1[0], mu * u3[1], -mu * u3[0];
  return s;
}

Eigen::Matrix3d rotation_between(const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
  Eigen::Vector3d axis = p.cross(q);
  const double s = axis.norm(), c = p.dot(q);
  if (s < 1e-15) {
    if (c > 0) return Eigen::Matrix3d::Identity();
    // Antipodal: half turn about any axis perpendicular to p.
    axis = p.unitOrthogonal();
    return Eigen::AngleAxisd(M_PI, axis).toRotationMatrix();
  }
  return Eigen::AngleAxisd(std::atan2(s, c), axis / s).toRotationMatrix();
}

double squared_residual(const SphereMobius& m, const std::vector<Eigen::Vector3d>& from,
                        const std::vector<Eigen::Vector3d>& to) {
  double r = 0;
  for (size_t k = 0; k < from.size(); ++k) r += (m.apply(from[k]) - to[k]).squaredNorm();
  return r;
}

// M · (I + X(θ)) for the six real parameters of X ∈ sl(2, C).
SphereMobius perturbed(const SphereMobius& m, const Eigen::Matrix<double, 6, 1>& t) {
  Eigen::Matrix2cd x;
  x << Complex(t[0], t[1]), Complex(t[2], t[3]), Complex(t[4], t[5]), -Complex(t[0], t[1]);
  SphereMobius out;
  out.m = normalized(m.m * (Eigen::Matrix2cd::Identity() + x));
  return out;
}

// Levenberg–Marquardt on Σ |M(from_k) − to_k|² over the 6 real dimensions of
// PSL(2, C), from `start`.
SphereMobius least_squares_mobius(SphereMobius m, const std::vector<Eigen::Vector3d>& from,
                                  const std::vector<Eigen::Vector3d>& to) {
  const int k = static_cast<int>(from.size());
  auto residual = [&](const SphereMobius& mm) {
    Eigen::VectorXd r(3 * k);
    for (int i = 0; i < k; ++i) r.segment<3>(3 * i) = mm.apply(from[i]) - to[i];
    return r;
  };
  Eigen::VectorXd r = residual(m);
  double cost = r.squaredNorm(), lambda = 1e-3;
  for (int it = 0; it < 200 && cost > 1e-30; ++it) {
    Eigen::MatrixXd J(3 * k, 6);
    const double h = 1e-7;
    for (int c = 0; c < 6; ++c) {
      Eigen::Matrix<double, 6, 1> t = Eigen::Matrix<double, 6, 1>::Zero();
      t[c] = h;
      const Eigen::VectorXd rp = residual(perturbed(m, t));
      t[c] = -h;
      J.col(c) = (rp - residual(perturbed(m, t))) / (2 * h);
    }
    const Eigen::Matrix<double, 6, 6> JtJ = J.transpose() * J;
    const Eigen::Matrix<double, 6, 1> g = J.transpose() * r;
    bool accepted = false;
    for (int tries = 0; tries < 30 && !accepted; ++tries) {
      Eigen::Matrix<double, 6, 6> A = JtJ;
      for (int c = 0; c < 6; ++c) A(c, c) += lambda * std::max(JtJ(c, c), 1e-12);
      const Eigen::Matrix<double, 6, 1> step = A.ldlt().solve(-g);
      const SphereMobius trial = perturbed(m, step);
      const Eigen::VectorXd rt = residual(trial);
      if (rt.squaredNorm() < cost) {
        const double gain = cost - rt.squaredNorm();
        m = trial, r = rt, cost = rt.squaredNorm();
        lambda = std::max(lambda / 3, 1e-12);
        accepted = true;
        if (step.norm() < 1e-13 || gain < 1e-15 * cost) return m;
      } else {
        lambda *= 4;
      }
    }
    if (!accepted) break;
  }
  return m;
}

RowMatrixX3d normalised_shape(const RowMatrixX3d& V, const RowMatrixX3i& F, Eigen::VectorXd* vertex_area);

// The shape mismatch J (spherical_map.h) of a map of the source's sphere
// image, over an evenly strided sample of source vertices; remembers each
// sample's last face so that nearby maps locate quickly.
class ShapeMismatch {
 public:
  ShapeMismatch(const RowMatrixX3d& source_V, const RowMatrixX3i& source_F, const RowMatrixX3d& source_sphere,
                const RowMatrixX3d& target_V, const RowMatrixX3i& target_F, const SphereLocator& locator,
                int max_samples)
      : sphere_(source_sphere), target_F_(target_F), locator_(locator) {
    Ys_ = normalised_shape(source_V, source_F, &a_s_);
    Eigen::VectorXd a_t;
    Zt_ = normalised_shape(target_V, target_F, &a_t);
    const int ns = static_cast<int>(source_V.rows());
    const int stride = std::max(1, (ns + max_samples - 1) / std::max(max_samples, 1));
    for (int i = 0; i < ns; i += stride) samples_.push_back(i), weight_ += a_s_[i];
    weight_ = std::max(weight_, 1e-300);
    hint_.assign(samples_.size(), -1);
  }
  template <class Map>
  double operator()(const Map& map) {
    ++evaluations;
    double sum = 0;
    for (size_t k = 0; k < samples_.size(); ++k) {
      const int i = samples_[k];
      Eigen::Vector3d b;
      const int f = locator_.locate(map(Eigen::Vector3d(sphere_.row(i).transpose())), &b, hint_[k]);
      hint_[k] = f;
      Eigen::Vector3d z = Eigen::Vector3d::Zero();
      for (int c = 0; c < 3; ++c) z += b[c] * Zt_.row(target_F_(f, c)).transpose();
      sum += a_s_[i] * (Ys_.row(i).transpose() - z).squaredNorm();
    }
    return sum / weight_;
  }
  int evaluations = 0;

 private:
  const RowMatrixX3d& sphere_;
  const RowMatrixX3i& target_F_;
  const SphereLocator& locator_;
  RowMatrixX3d Ys_, Zt_;
  Eigen::VectorXd a_s_;
  std::vector<int> samples_, hint_;
  double weight_ = 0;
};

// The 24 rotations of the cube (signed permutation matrices of det +1).
std::vector<Eigen::Matrix3d> cube_rotations() {
  std::vector<Eigen::Matrix3d> out;
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& p : perms)
    for (int signs = 0; signs < 8; ++signs) {
      Eigen::Matrix3d R = Eigen::Matrix3d::Zero();
      for (int r = 0; r < 3; ++r) R(r, p[r]) = (signs >> r & 1) ? -1.0 : 1.0;
      if (R.determinant() > 0) out.push_back(R);
    }
  return out;
}

// Area-weighted normalisation: centroid of the surface at 0, total area 1.
RowMatrixX3d normalised_shape(const RowMatrixX3d& V, const RowMatrixX3i& F, Eigen::VectorXd* vertex_area) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  double total = 0;
  vertex_area->setZero(V.rows());
  for (int f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), d = V.row(F(f, 2));
    const double A = 0.5 * (b - a).cross(d - a).norm();
    c += A * (a + b + d) / 3.0;
    total += A;
    for (int k = 0; k < 3; ++k) (*vertex_area)[F(f, k)] += A / 3.0;
  }
  total = std::max(total, 1e-300);
  c /= total;
  RowMatrixX3d out = (V.rowwise() - c.transpose()) / std::sqrt(total);
  *vertex_area /= total;
  return out;
}


// Positive orientation of the chordal triangle (a, b, c) seen from outside.
double orientation(const RowMatrixX3d& P, const RowMatrixX3i& F, int f) {
  const Eigen::Vector3d a = P.row(F(f, 0)), b = P.row(F(f, 1)), c = P.row(F(f, 2));
  return a.dot(b.cross(c));
}

bool bad_face(const RowMatrixX3d& P, const RowMatrixX3i& F, int f) {
  const Eigen::Vector3d a = P.row(F(f, 0)), b = P.row(F(f, 1)), c = P.row(F(f, 2));
  const double scale = std::max({(b - a).squaredNorm(), (c - a).squaredNorm(), (c - b).squaredNorm()});
  return !(orientation(P, F, f) > 1e-12 * scale);
}

}  // namespace

namespace {

/// untangle_sphere_image on one cluster of bad faces: the patch around
/// `bad`, grown ring by ring, re-placed until its own faces are clean.
/// Returns the moved vertices, or -1 with P unchanged.
int untangle_patch(RowMatrixX3d& P, const RowMatrixX3d& V, const RowMatrixX3i& F, const Connectivity& conn,
                   const std::vector<int>& bad, int max_vertices) {
  const int nv = static_cast<int>(P.rows()), nf = static_cast<int>(F.rows());
  std::vector<char> in(nv, 0);
  std::vector<int> region;
  auto add = [&](int v) {
    if (!in[v]) in[v] = 1, region.push_back(v);
  };
  for (int f : bad)
    for (int k = 0; k < 3; ++k) add(F(f, k));
  const RowMatrixX3d original = P;
  for (int grow = 0; grow < 64; ++grow) {
    // One more ring: the region's boundary gets rounder, and Floater's theorem
    // needs a convex one.
    const std::vector<int> current = region;
    for (int v : current)
      for (int h : conn.outgoing(v)) add(conn.head(h));
    if (static_cast<int>(region.size()) > max_vertices) break;
    // Gnomonic chart at the region's mean direction: great circles become
    // lines, so planar orientation there is the chordal orientation on the
    // sphere.
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    for (int v : region) n += original.row(v).transpose();
    if (n.norm() < 1e-12) break;
    n.normalize();
    const Eigen::Vector3d e1 = n.unitOrthogonal(), e2 = n.cross(e1);
    std::vector<int> index(nv, -1), boundary_of;
    int ni = 0;
    // Interior unknowns: region vertices all of whose neighbours are in the
    // region; the rest of the region plus its outer ring stay fixed.
    std::vector<int> interior;
    for (int v : region) {
      bool all = true;
      for (int h : conn.outgoing(v)) all = all && in[conn.head(h)];
      if (all) index[v] = ni++, interior.push_back(v);
    }
    if (ni == 0) continue;
    auto chart = [&](int v, Eigen::Vector2d* x) {
      const Eigen::Vector3d p = original.row(v).transpose();
      const double d = p.dot(n);
      if (!(d > 1e-3)) return false;
      *x = Eigen::Vector2d((p / d).dot(e1), (p / d).dot(e2));
      return true;
    };
    // Floater's mean value weights of the 3D mesh (positive, so with a
    // convex boundary the patch is embedded; and close to conformal, so the
    // patch keeps the shape of its triangles far better than uniform
    // weights, which gave D' ~150 on a jittered bunny).
    bool ok = true;
    std::vector<Eigen::Triplet<double>> trip;
    Eigen::MatrixX2d rhs = Eigen::MatrixX2d::Zero(ni, 2);
    for (int v : interior) {
      const int i = index[v];
      const Eigen::Vector3d xv = V.row(v).transpose();
      for (int h : conn.outgoing(v)) {
        const int b = conn.head(h), c = conn.opposite_vertex(h);
        const Eigen::Vector3d eb = V.row(b).transpose() - xv, ec = V.row(c).transpose() - xv;
        const double lb = eb.norm(), lc = ec.norm();
        const double theta = std::atan2(eb.cross(ec).norm(), eb.dot(ec));
        const double t = std::tan(0.5 * theta);
        for (const auto& [u, w] : {std::pair{b, t / std::max(lb, 1e-300)}, std::pair{c, t / std::max(lc, 1e-300)}}) {
          trip.emplace_back(i, i, w);
          if (index[u] >= 0) {
            trip.emplace_back(i, index[u], -w);
          } else {
            Eigen::Vector2d x;
            ok = ok && chart(u, &x);
            rhs.row(i) += w * x.transpose();
          }
        }
      }
    }
    if (!ok) break;
    Eigen::SparseMatrix<double> L(ni, ni);
    L.setFromTriplets(trip.begin(), trip.end());
    L.makeCompressed();
    Eigen::SparseLU<Eigen::SparseMatrix<double>> solver;
    solver.compute(L);
    if (solver.info() != Eigen::Success) break;
    const Eigen::MatrixX2d X = solver.solve(rhs);
    P = original;
    for (int v : interior)
      P.row(v) = (n + X(index[v], 0) * e1 + X(index[v], 1) * e2).normalized().transpose();
    bool clean = true;
    // This patch's faces: those with a moved vertex, and its bad faces (other
    // clusters' bad faces may touch its fixed ring; they get their own patch).
    for (int f = 0; f < nf && clean; ++f)
      if ((index[F(f, 0)] >= 0 || index[F(f, 1)] >= 0 || index[F(f, 2)] >= 0) && bad_face(P, F, f)) clean = false;
    for (int f : bad) clean = clean && !bad_face(P, F, f);
    if (clean) return ni;
  }
  P = original;
  return -1;
}

}  // namespace

int untangle_sphere_image(RowMatrixX3d& P, const RowMatrixX3d& V, const RowMatrixX3i& F, int max_vertices) {
  const int nv = static_cast<int>(P.rows()), nf = static_cast<int>(F.rows());
  const Connectivity conn(F, nv);
  std::vector<int> bad;
  for (int f = 0; f < nf; ++f)
    if (bad_face(P, F, f)) bad.push_back(f);
  if (bad.empty()) return 0;
  // Clusters of bad faces (sharing a vertex) are re-placed one patch each:
  // one patch over bad faces on opposite sides of the sphere has no
  // gnomonic chart (its mean direction is meaningless), which refused
  // OpenMesh-decimated 500-vertex bunnies with 4 inverted faces apart.
  std::vector<int> cluster_of(nv, -1);
  std::vector<std::vector<int>> clusters;
  for (int f : bad) {
    int c = -1;
    for (int k = 0; k < 3 && c < 0; ++k) c = cluster_of[F(f, k)];
    if (c < 0) c = static_cast<int>(clusters.size()), clusters.emplace_back();
    clusters[c].push_back(f);
    for (int k = 0; k < 3; ++k) cluster_of[F(f, k)] = c;
  }
  const RowMatrixX3d original = P;
  int moved = 0;
  for (const std::vector<int>& cluster : clusters) {
    std::vector<int> still;
    for (int f : cluster)
      if (bad_face(P, F, f)) still.push_back(f);
    if (still.empty()) continue;
    const int m = untangle_patch(P, V, F, conn, still, max_vertices);
    if (m < 0) {
      P = original;
      return -1;
    }
    moved += m;
  }
  for (int f = 0; f < nf; ++f)
    if (bad_face(P, F, f)) {
      P = original;
      return -1;
    }
  return moved;
}

namespace {

// A spherical uniformization usable for the map: converged, or converged in
// its angle sums with a few input faces flipped on the sphere (or one
// degenerate intrinsic face at the fixed ring), which are then untangled
// locally. Tries the same removed vertices as spherical_uniformization.
SphericalUniformization usable_sphere(const TriMesh& mesh, const SphericalUniformizationOptions& uo,
                                      const std::string& which, int* repaired) {
  *repaired = 0;
  const int nv = mesh.num_vertices();
  const int limit = std::max(200, nv / 20);
  auto usable = [&](SphericalUniformization& u) {
    if (u.positions.rows() != nv || !u.positions.allFinite() || !(u.max_curvature_error <= std::max(1e3 * uo.flow.tolerance, 1e-8)) ||
        !(u.centre_of_mass_norm <= 1e-6))
      return false;
    const int moved = untangle_sphere_image(u.positions, mesh.V, mesh.F, limit);
    if (moved < 0) return false;
    *repaired = moved;
    u.converged = true;
    return true;
  };
  // The removed vertices spherical_uniformization tries by default, each
  // accepted as soon as it converged or is repairable.
  const Connectivity conn(mesh.F, nv);
  int best_v = 0;
  for (int v = 1; v < nv; ++v)
    if (conn.valence(v) > conn.valence(best_v)) best_v = v;
  std::vector<int> candidates{best_v};
  for (int k = 1; k <= 6; ++k) candidates.push_back(static_cast<int>((static_cast<long long>(nv) * k) / 7));
  std::string first_message;
  for (int v0 : candidates) {
    SphericalUniformizationOptions o = uo;
    o.removed_vertex = v0;
    SphericalUniformization a;
    try {
      a = spherical_uniformization(mesh, o);
    } catch (const InputError& e) {  // e.g. a link that is not a simple cycle: try the next vertex
      first_message += (first_message.empty() ? "" : "; ") + std::to_string(v0) + ": " + e.what();
      continue;
    }
    // Converged means the intrinsic triangulation embeds. With its flip log
    // the map locates points in it and carries them back to the input faces
    // (SphereSide); without one (no flips) the input faces are the chords,
    // which may need the local untangling.
    if ((a.converged && (a.input_flipped_faces == 0 || !a.frame_log.empty())) || usable(a)) return a;
    first_message += (first_message.empty() ? "" : "; ") + std::to_string(v0) + ": " + a.message;
  }
  throw UniformizationError(which + " spherical uniformization failed: " + first_message);
}

}  // namespace

// ---------------------------------------------------------------------------
// SphereMobius

Eigen::Vector3d SphereMobius::apply(const Eigen::Vector3d& p) const { return from_hom(m * to_hom(p)); }

SphereMobius SphereMobius::operator*(const SphereMobius& other) const {
  SphereMobius out;
  out.m = normalized(m * other.m);
  return out;
}

SphereMobius SphereMobius::inverse() const {
  SphereMobius out;
  out.m << m(1, 1), -m(0, 1), -m(1, 0), m(0, 0);
  out.m = normalized(out.m);
  return out;
}

SphereMobius SphereMobius::from_three_points(const std::array<Eigen::Vector3d, 3>& from,
                                             const std::array<Eigen::Vector3d, 3>& to) {
  std::array<Hom, 3> u, v;
  for (int k = 0; k < 3; ++k) u[k] = to_hom(from[k].normalized()), v[k] = to_hom(to[k].normalized());
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b) {
      if (separation(u[a], u[b]) < 1e-12)
        throw InputError("Möbius map from three points: source points " + std::to_string(a) + " and " +
                         std::to_string(b) + " coincide");
      if (separation(v[a], v[b]) < 1e-12)
        throw InputError("Möbius map from three points: target points " + std::to_string(a) + " and " +
                         std::to_string(b) + " coincide");
    }
  const Eigen::Matrix2cd S = to_standard(u[0], u[1], u[2]), T = to_standard(v[0], v[1], v[2]);
  SphereMobius out;
  out.m = normalized(T.inverse() * S);
  return out;
}

SphereMobius SphereMobius::from_rotation(const Eigen::Matrix3d& R) {
  const std::array<Eigen::Vector3d, 3> e = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(),
                                            Eigen::Vector3d::UnitZ()};
  return from_three_points(e, {R * e[0], R * e[1], R * e[2]});
}

SphereMobius fit_sphere_mobius(const std::vector<Eigen::Vector3d>& from_in, const std::vector<Eigen::Vector3d>& to_in,
                               double* rms) {
  if (from_in.size() != to_in.size() || from_in.empty())
    throw InputError("fit_sphere_mobius: needs the same number (>= 1) of source and target points");
  std::vector<Eigen::Vector3d> from, to;
  for (size_t k = 0; k < from_in.size(); ++k) from.push_back(from_in[k].normalized()), to.push_back(to_in[k].normalized());
  const int k = static_cast<int>(from.size());
  for (int a = 0; a < k; ++a)
    for (int b = a + 1; b < k; ++b) {
      if ((from[a] - from[b]).norm() < 1e-12)
        throw InputError("landmarks " + std::to_string(a) + " and " + std::to_string(b) +
                         " coincide on the source's sphere");
      if ((to[a] - to[b]).norm() < 1e-12)
        throw InputError("landmarks " + std::to_string(a) + " and " + std::to_string(b) +
                         " coincide on the target's sphere");
    }
  SphereMobius m;
  if (k == 1) {
    m = SphereMobius::from_rotation(rotation_between(from[0], to[0]));
  } else if (k == 2) {
    // A third, fixed point as far as possible from the four given ones keeps
    // the map close to the identity where nothing was asked for.
    const Eigen::Vector3d candidates[] = {-(from[0] + from[1] + to[0] + to[1]), from[0].cross(from[1]),
                                          to[0].cross(to[1]), Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(),
                                          Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitX(),
                                          -Eigen::Vector3d::UnitY(), -Eigen::Vector3d::UnitZ()};
    Eigen::Vector3d best(0, 0, 1);
    double best_d = -1;
    for (const Eigen::Vector3d& c : candidates) {
      if (c.norm() < 1e-6) continue;
      const Eigen::Vector3d r = c.normalized();
      const double d = std::min({(r - from[0]).norm(), (r - from[1]).norm(), (r - to[0]).norm(), (r - to[1]).norm()});
      if (d > best_d) best_d = d, best = r;
    }
    m = SphereMobius::from_three_points({from[0], from[1], best}, {to[0], to[1], best});
  } else if (k == 3) {
    m = SphereMobius::from_three_points({from[0], from[1], from[2]}, {to[0], to[1], to[2]});
  } else {
    // Start from the best exact fit of a triple (all triples for few
    // landmarks, a deterministic sample otherwise), then least squares.
    double best = squared_residual(m, from, to);
    auto try_triple = [&](int a, int b, int c) {
      try {
        const SphereMobius t = SphereMobius::from_three_points({from[a], from[b], from[c]}, {to[a], to[b], to[c]});
        const double r = squared_residual(t, from, to);
        if (r < best) best = r, m = t;
      } catch (const InputError&) {
      }
    };
    if (k <= 12) {
      for (int a = 0; a < k; ++a)
        for (int b = a + 1; b < k; ++b)
          for (int c = b + 1; c < k; ++c) try_triple(a, b, c);
    } else {
      unsigned state = 12345u;
      auto next = [&]() { return static_cast<int>((state = state * 1664525u + 1013904223u) >> 8) % k; };
      for (int s = 0; s < 300; ++s) {
        const int a = next(), b = next(), c = next();
        if (a != b && b != c && a != c) try_triple(a, b, c);
      }
    }
    m = least_squares_mobius(m, from, to);
  }
  if (rms) *rms = std::sqrt(squared_residual(m, from, to) / k);
  return m;
}

// ---------------------------------------------------------------------------
// SphereLocator

SphereLocator::SphereLocator(const RowMatrixX3d& positions, const RowMatrixX3i& F) : P_(positions), F_(F) {
  const Connectivity c(F, static_cast<int>(positions.rows()));
  const int nf = static_cast<int>(F.rows()), nv = static_cast<int>(positions.rows());
  neighbour_.assign(3 * nf, -1);
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) neighbour_[3 * f + k] = Connectivity::face(c.twin(3 * f + (k + 1) % 3));
  vertex_face_.assign(nv, 0);
  for (int f = nf - 1; f >= 0; --f)
    for (int k = 0; k < 3; ++k) vertex_face_[F(f, k)] = f;
  // About two vertices per occupied cell (the sphere meets ~π res² cells).
  res_ = std::clamp(static_cast<int>(std::sqrt(nv / (2.0 * M_PI))), 1, 128);
  auto cell_of = [&](const Eigen::Vector3d& p) {
    int idx[3];
    for (int a = 0; a < 3; ++a) idx[a] = std::clamp(static_cast<int>((p[a] + 1.0) * 0.5 * res_), 0, res_ - 1);
    return (static_cast<size_t>(idx[2]) * res_ + idx[1]) * res_ + idx[0];
  };
  const size_t ncells = static_cast<size_t>(res_) * res_ * res_;
  cell_start_.assign(ncells + 1, 0);
  for (int v = 0; v < nv; ++v) ++cell_start_[cell_of(P_.row(v).transpose()) + 1];
  for (size_t i = 0; i < ncells; ++i) cell_start_[i + 1] += cell_start_[i];
  cell_vertices_.assign(nv, -1);
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (int v = 0; v < nv; ++v) cell_vertices_[fill[cell_of(P_.row(v).transpose())]++] = v;
}

Eigen::Vector3d SphereLocator::cone_barycentric(int f, const Eigen::Vector3d& p) const {
  const Eigen::Vector3d a = P_.row(F_(f, 0)), b = P_.row(F_(f, 1)), c = P_.row(F_(f, 2));
  // det(p, b, c) etc.: proportional to the barycentrics of the point where
  // the ray through p meets the plane of (a, b, c); all >= 0 iff p lies in
  // the face's cone.
  return Eigen::Vector3d(p.dot(b.cross(c)), p.dot(c.cross(a)), p.dot(a.cross(b)));
}

int SphereLocator::start_face(const Eigen::Vector3d& p) const {
  int idx[3];
  for (int a = 0; a < 3; ++a) idx[a] = std::clamp(static_cast<int>((p[a] + 1.0) * 0.5 * res_), 0, res_ - 1);
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  for (int ring = 0; ring < res_ && (best < 0 || ring <= 1); ++ring) {
    for (int z = idx[2] - ring; z <= idx[2] + ring; ++z)
      for (int y = idx[1] - ring; y <= idx[1] + ring; ++y)
        for (int x = idx[0] - ring; x <= idx[0] + ring; ++x) {
          if (x < 0 || y < 0 || z < 0 || x >= res_ || y >= res_ || z >= res_) continue;
          if (std::max({std::abs(x - idx[0]), std::abs(y - idx[1]), std::abs(z - idx[2])}) != ring) continue;
          const size_t cell = (static_cast<size_t>(z) * res_ + y) * res_ + x;
          // A start for the walk need not be the nearest vertex: cap the scan
          // in crowded cells (conformal factors cluster vertices).
          const int end = std::min(cell_start_[cell + 1], cell_start_[cell] + 32);
          for (int i = cell_start_[cell]; i < end; ++i) {
            const int v = cell_vertices_[i];
            const double d = (P_.row(v).transpose() - p).squaredNorm();
            if (d < best_d) best_d = d, best = v;
          }
        }
  }
  return best < 0 ? 0 : vertex_face_[best];
}

int SphereLocator::locate(const Eigen::Vector3d& p, Eigen::Vector3d* bary, int hint) const {
  const int nf = static_cast<int>(F_.rows());
  auto walk = [&](int f, int budget) {
    for (int step = 0; step < budget; ++step) {
      const Eigen::Vector3d b = cone_barycentric(f, p);
      const double s = b.sum();
      int k;
      const double worst = b.minCoeff(&k);
      if (s > 0 && worst >= -1e-13 * s) {
        *bary = b.cwiseMax(0.0) / b.cwiseMax(0.0).sum();
        return f;
      }
      f = neighbour_[3 * f + k];
      if (f < 0) return -1;
    }
    return -1;
  };
  int f = -1;
  if (hint >= 0 && hint < nf) f = walk(hint, 64);
  if (f < 0) f = walk(start_face(p), 4 * static_cast<int>(std::sqrt(static_cast<double>(nf))) + 256);
  if (f >= 0) return f;
  // Walks can cycle on non-Delaunay triangulations: exhaustive search for the
  // face whose cone holds p best.
  ++fallbacks;
  int best = 0;
  double best_score = -std::numeric_limits<double>::infinity();
  for (int g = 0; g < nf; ++g) {
    const Eigen::Vector3d b = cone_barycentric(g, p);
    const double s = b.sum();
    if (!(s > 0)) continue;
    const double score = b.minCoeff() / s;
    if (score > best_score) best_score = score, best = g;
  }
  const Eigen::Vector3d b = cone_barycentric(best, p).cwiseMax(0.0);
  *bary = b.sum() > 0 ? Eigen::Vector3d(b / b.sum()) : Eigen::Vector3d(1.0 / 3, 1.0 / 3, 1.0 / 3);
  return best;
}

// ---------------------------------------------------------------------------
// Rotation alignment

SphereAlignmentResult align_sphere_rotation(const RowMatrixX3d& source_V, const RowMatrixX3i& source_F,
                                            const RowMatrixX3d& source_sphere, const RowMatrixX3d& target_V,
                                            const RowMatrixX3i& target_F, const RowMatrixX3d& target_sphere,
                                            const SphereLocator& target_locator,
                                            const SphereAlignmentOptions& options) {
  ShapeMismatch mismatch(source_V, source_F, source_sphere, target_V, target_F, target_locator, options.max_samples);
  SphereAlignmentResult out;
  auto J = [&](const Eigen::Matrix3d& R) { return mismatch([&](const Eigen::Vector3d& x) { return Eigen::Vector3d(R * x); }); };
  auto refine = [&](Eigen::Matrix3d R, double value, double final_step) {
    for (double step = options.initial_step; step >= final_step; step *= 0.5) {
      for (bool improved = true; improved;) {
        improved = false;
        for (int axis = 0; axis < 3; ++axis)
          for (double sign : {1.0, -1.0}) {
            const Eigen::Matrix3d Rt =
                Eigen::AngleAxisd(sign * step, Eigen::Vector3d::Unit(axis)).toRotationMatrix() * R;
            const double v = J(Rt);
            if (v < value) value = v, R = Rt, improved = true;
          }
      }
    }
    return std::make_pair(R, value);
  };
  std::vector<std::pair<double, Eigen::Matrix3d>> starts;
  for (const Eigen::Matrix3d& R : cube_rotations()) {
    const double v = J(R);
    if (R.isIdentity()) out.identity_mismatch = v;
    starts.emplace_back(v, R);
  }
  std::sort(starts.begin(), starts.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  // The three best starts to a coarse level, the best of those to the end.
  std::pair<Eigen::Matrix3d, double> best(Eigen::Matrix3d::Identity(), std::numeric_limits<double>::infinity());
  for (size_t s = 0; s < std::min<size_t>(3, starts.size()); ++s) {
    const auto r = refine(starts[s].second, starts[s].first, 0.03);
    if (r.second < best.second) best = r;
  }
  best = refine(best.first, best.second, options.final_step);
  out.rotation = best.first;
  out.mismatch = best.second;
  out.evaluations = mismatch.evaluations;
  return out;
}

SphereMobius refine_two_landmark_mobius(const SphereMobius& M, const Eigen::Vector3d& q0, const Eigen::Vector3d& q1,
                                        const RowMatrixX3d& source_V, const RowMatrixX3i& source_F,
                                        const RowMatrixX3d& source_sphere, const RowMatrixX3d& target_V,
                                        const RowMatrixX3i& target_F, const SphereLocator& target_locator,
                                        const SphereAlignmentOptions& options, int* evaluations,
                                        double* mismatch_before, double* mismatch_after) {
  // C sends q0 -> 0 (south pole), q1 -> ∞ (north pole); z -> λ z then fixes
  // both, so C⁻¹ D_λ C M (λ = e^(a + i b)) are all the Möbius maps taking
  // the two landmarks where M takes them.
  Eigen::Vector3d r = (q0 + q1).norm() > 1e-6 ? Eigen::Vector3d(-(q0 + q1).normalized()) : q0.unitOrthogonal();
  if ((r - q0).norm() < 1e-6 || (r - q1).norm() < 1e-6) r = q0.cross(q1).normalized();
  const SphereMobius C = SphereMobius::from_three_points({q0, r, q1}, {-Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX(),
                                                                       Eigen::Vector3d::UnitZ()});
  const SphereMobius Ci = C.inverse(), CM = C * M;
  auto family = [&](double a, double b) {
    SphereMobius D;
    const std::complex<double> h = std::exp(0.5 * std::complex<double>(a, b));
    D.m << h, 0, 0, 1.0 / h;
    return Ci * D * CM;
  };
  ShapeMismatch mismatch(source_V, source_F, source_sphere, target_V, target_F, target_locator, options.max_samples);
  auto J = [&](double a, double b) {
    const SphereMobius F = family(a, b);
    return mismatch([&](const Eigen::Vector3d& x) { return F.apply(x); });
  };
  double a = 0, b = 0, value = J(0, 0);
  if (mismatch_before) *mismatch_before = value;
  for (double step = 0.5; step >= 1e-3; step *= 0.5)
    for (bool improved = true; improved;) {
      improved = false;
      for (const auto& [da, db] : {std::pair{step, 0.0}, std::pair{-step, 0.0}, std::pair{0.0, step}, std::pair{0.0, -step}}) {
        const double v = J(a + da, b + db);
        if (v < value) value = v, a += da, b += db, improved = true;
      }
    }
  if (evaluations) *evaluations = mismatch.evaluations;
  if (mismatch_after) *mismatch_after = value;
  return family(a, b);
}

// ---------------------------------------------------------------------------
// The genus-0 path of surface_map()

namespace detail {
namespace {

/// One side's sphere as the map reads it: the triangulation that embeds
/// (the intrinsic faces when the uniformization's flip log carries points
/// back to the input faces, else the input faces) and the way back.
struct SphereSide {
  const TriMesh& mesh;
  const SphericalUniformization& u;
  RowMatrixX3i faces;
  std::unique_ptr<SphericalCorrespondence> carry;

  SphereSide(const TriMesh& m, const SphericalUniformization& s) : mesh(m), u(s), faces(m.F) {
    if (s.frame_log.empty()) return;
    carry = std::make_unique<SphericalCorrespondence>(s, m.F);  // throws on a log that does not match
    faces = s.intrinsic_faces;
  }
  /// The point with barycentrics b (central projection) in face f of `faces`.
  PointOnSurface point(int f, const Eigen::Vector3d& b) const {
    if (!carry) return point_in_face(mesh, f, b);
    const FacePoint q = carry->to_input(f, b);
    return point_in_face(mesh, q.face, q.barycentric);
  }
};

/// The shortest edge chord of a triangulation on the unit sphere.
double smallest_chord(const RowMatrixX3d& P, const RowMatrixX3i& F) {
  double best = std::numeric_limits<double>::infinity();
  for (int f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) best = std::min(best, (P.row(F(f, k)) - P.row(F(f, (k + 1) % 3))).norm());
  return best;
}

/// The source's sphere positions (#Vs x 3) aligned to the target's
/// (ut.positions): the best rotation of us.positions, then with landmarks
/// the Möbius map fitting them (over the two-parameter family of maps
/// keeping two pairs, refined on the shapes' mismatch). Adds the mismatch
/// evaluations to out.iterations.
/// The alignment as a map of the source's sphere: the rotation, then the
/// landmarks' Möbius map when there is one.
struct SourceAlignment {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  bool has_mobius = false;
  SphereMobius mobius;
  Eigen::Vector3d operator()(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d r = rotation * p;
    return has_mobius ? mobius.apply(r) : r;
  }
};

RowMatrixX3d aligned_source_sphere(const TriMesh& source, const TriMesh& target,
                                   const SphericalUniformization& us, const SphericalUniformization& ut,
                                   const SphereLocator& tloc, const SurfaceMapOptions& options,
                                   SurfaceMapResult& out, SourceAlignment* alignment) {
  const SphereAlignmentResult al =
      align_sphere_rotation(source.V, source.F, us.positions, target.V, target.F, ut.positions, tloc);
  const int ns = source.num_vertices();
  RowMatrixX3d X(ns, 3);
  for (int i = 0; i < ns; ++i) X.row(i) = (al.rotation * us.positions.row(i).transpose()).transpose();
  alignment->rotation = al.rotation;
  if (!options.landmarks.empty()) {
    std::vector<Eigen::Vector3d> from, to;
    for (const auto& [s, t] : options.landmarks)
      from.push_back(X.row(s).transpose()), to.push_back(ut.positions.row(t).transpose());
    double rms = 0;
    SphereMobius M = fit_sphere_mobius(from, to, &rms);
    if (options.landmarks.size() == 2) {
      int evaluations = 0;
      M = refine_two_landmark_mobius(M, to[0], to[1], source.V, source.F, X, target.V, target.F, tloc, {}, &evaluations);
      out.iterations += evaluations;
    }
    for (int i = 0; i < ns; ++i) X.row(i) = M.apply(X.row(i).transpose()).transpose();
    alignment->has_mobius = true, alignment->mobius = M;
    // Exact fits (<= 3 landmarks) hit their targets to round-off; put them
    // exactly there so the forward point is the target vertex itself.
    if (options.landmarks.size() <= 3)
      for (const auto& [s, t] : options.landmarks) X.row(s) = ut.positions.row(t);
  }
  out.iterations += al.evaluations;
  return X;
}

/// Orientation of every image triangle on the sphere: a Möbius map keeps
/// small triangles positive, but one whose circle it turns inside out would
/// wrap the sphere. Counts them in out and throws SolveError if any.
void check_sphere_image_orientation(const RowMatrixX3i& F, const RowMatrixX3d& X, const std::vector<int>* origin,
                                    const SurfaceMapOptions& options, SurfaceMapResult& out) {
  int first_bad = -1;
  for (int f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = X.row(F(f, 0)), b = X.row(F(f, 1)), c = X.row(F(f, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const double scale = std::max({(b - a).squaredNorm(), (c - a).squaredNorm(), (c - b).squaredNorm()});
    const double vol = n.dot(a + b + c);
    const int named = origin ? (*origin)[f] : f;
    if (std::abs(vol) <= 1e-12 * scale)
      ++out.degenerate_triangles, first_bad = first_bad < 0 ? named : first_bad;
    else if (vol < 0)
      ++out.flipped_triangles, first_bad = first_bad < 0 ? named : first_bad;
  }
  if (out.flipped_triangles || out.degenerate_triangles)
    throw SolveError("the genus-0 map has " + std::to_string(out.flipped_triangles) + " flipped and " +
                     std::to_string(out.degenerate_triangles) + " degenerate image triangles on the sphere (first: source face " +
                     std::to_string(first_bad) + ")" +
                     (options.landmarks.empty() ? std::string()
                                                : std::string("; the Möbius map fixed by the landmarks stretches the sphere "
                                                              "too much for this mesh: check the landmark pairs")) +
                     "; it is not returned");
}

/// The target point (face, barycentrics) of every row of Y (#Vs x 3 on the
/// target's sphere).
std::vector<PointOnSurface> located_on_target(const SphereSide& target, const SphereLocator& tloc,
                                              const RowMatrixX3d& Y) {
  const int ns = static_cast<int>(Y.rows());
  std::vector<PointOnSurface> fw(ns);
  int hint = -1;
  for (int i = 0; i < ns; ++i) {
    Eigen::Vector3d b;
    hint = tloc.locate(Y.row(i).transpose(), &b, hint);
    fw[i] = target.point(hint, b);
  }
  return fw;
}

struct SphereMapQuality {
  std::vector<double> per_face;
  double mean = 0, max = 0;
  int degenerate = 0;
  std::vector<int> thin_source;  ///< left out of mean and max (DistortionStats::thin_source)
  double thin_source_max = 0;
};

/// D' of each source triangle onto the triangle of its corners' 3D images
/// fw on the target (the morph's triangles: what the user sees, and it
/// carries the discretisation error of both uniformizations): per face
/// (#Fs, infinite where degenerate), area-weighted mean and max.
SphereMapQuality sphere_map_quality(const TriMesh& source, const Connectivity& sc,
                                    const Eigen::VectorXd& source_lengths,
                                    const std::vector<PointOnSurface>& fw) {
  SphereMapQuality q;
  q.per_face.assign(source.num_faces(), std::numeric_limits<double>::infinity());
  // Thin source faces (zero-area ones among them) keep the D' of their
  // mollified lengths per face but stay out of mean and max: that D'
  // measures the mollification's reshaping (a zero-area face at D' 360 on
  // the zero-area sphere onto a bunny, whose other faces reach 4.4), not
  // the map.
  const std::vector<char> thin = thin_source_faces(source.V, source.F);
  double weighted = 0, total = 0;
  for (int f = 0; f < source.num_faces(); ++f) {
    const Eigen::Vector3d p0 = source.V.row(source.F(f, 0)), p1 = source.V.row(source.F(f, 1)),
                          p2 = source.V.row(source.F(f, 2));
    const Eigen::Vector3d i0 = fw[source.F(f, 0)].position, i1 = fw[source.F(f, 1)].position,
                          i2 = fw[source.F(f, 2)].position;
    const double d = triangle_dilatation(Eigen::Vector3d(source_lengths[sc.edge(3 * f)], source_lengths[sc.edge(3 * f + 1)],
                                                         source_lengths[sc.edge(3 * f + 2)]),
                                         Eigen::Vector3d((i1 - i0).norm(), (i2 - i1).norm(), (i0 - i2).norm()));
    if (!std::isfinite(d)) {
      ++q.degenerate;
      continue;
    }
    q.per_face[f] = d;
    if (thin[f]) {
      q.thin_source.push_back(f);
      q.thin_source_max = std::max(q.thin_source_max, d);
      continue;
    }
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    weighted += area * d, total += area;
    q.max = std::max(q.max, d);
  }
  q.mean = weighted / std::max(total, 1e-300);
  return q;
}

/// The forward map of X (aligned source sphere, located by tloc) and its
/// quality, and the quality of the "initial" map (both centred images, no
/// alignment and no landmarks: us.positions located by initial_tloc on the
/// target's own sphere). Throws SolveError when an image triangle is
/// degenerate.
void forward_map_and_quality(const TriMesh& source, const SphereSide& target, const Connectivity& sc,
                             const SphericalUniformization& us, const SphereLocator& tloc,
                             const SphereLocator& initial_tloc, const RowMatrixX3d& X, SurfaceMapResult& out) {
  // The source's side of D' uses its mollified lengths (the metric both
  // uniformizations run on): an exactly zero-area input face then has a
  // finite D' instead of an infinite one that would refuse the whole map.
  const Eigen::VectorXd source_lengths = edge_lengths(source, sc);
  out.forward = located_on_target(target, tloc, X);
  const SphereMapQuality q = sphere_map_quality(source, sc, source_lengths, out.forward);
  out.dilatation = q.per_face;
  out.mean_dilatation = q.mean;
  out.max_dilatation = q.max;
  out.thin_source_faces = q.thin_source;
  out.thin_source_max_dilatation = q.thin_source_max;
  out.degenerate_triangles = q.degenerate;
  if (q.degenerate)
    throw SolveError("the genus-0 map has " + std::to_string(q.degenerate) +
                     " source triangles whose image on the target is degenerate; it is not returned");
  const SphereMapQuality q0 = sphere_map_quality(source, sc, source_lengths, located_on_target(target, initial_tloc, us.positions));
  out.initial_dilatation = q0.per_face;
  out.initial_mean_dilatation = q0.mean;
  out.initial_max_dilatation = q0.max;
  out.initial_flipped_triangles = 0;  // Möbius-centred uniformizations are checked for flips
}

/// The map on the common subdivision over the source faces whose chord
/// triangle is inverted (SurfaceMapResult::SourceSubdivision).
struct PiecewiseSource {
  RowMatrixX3i faces;           ///< over source vertices, then the new ones
  std::vector<int> origin;      ///< source face of each row
  RowMatrixX3d sphere;          ///< aligned sphere point of every vertex
  std::vector<PointOnSurface> source_points;  ///< the new vertices on the source
  std::vector<char> replaced;   ///< per source face: delivered piecewise
  double cover = 0;             ///< Σ spherical areas / 4π
  int bends = 0;                ///< new vertices inside an intrinsic face
};

/// Builds it: the inverted faces, grown across every input edge that an
/// intrinsic edge crosses (so the region's boundary edges are intrinsic
/// edges and the faces outside keep their chord triangles), replaced by
/// their pieces; checks that every triangle is positive on the sphere and
/// that together they cover it once. Throws SolveError otherwise.
PiecewiseSource piecewise_source(const TriMesh& source, const Connectivity& sc, const SphericalUniformization& us,
                                 const SourceAlignment& alignment, const RowMatrixX3d& X,
                                 const std::vector<int>& inverted) {
  const int nv = source.num_vertices(), nf = source.num_faces();
  const SphericalSubdivision sub = spherical_common_subdivision(us, source.F);
  PiecewiseSource pw;
  pw.replaced.assign(nf, 0);
  std::vector<int> queue;
  for (int f : inverted) pw.replaced[f] = 1, queue.push_back(f);
  while (!queue.empty()) {
    const int f = queue.back();
    queue.pop_back();
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * f + k;
      if (sub.crossings_of_edge[sc.edge(h)].empty()) continue;
      const int g = Connectivity::face(sc.twin(h));
      if (!pw.replaced[g]) pw.replaced[g] = 1, queue.push_back(g);
    }
  }
  const std::vector<SubdivisionPiece> pieces = subdivision_pieces(sub, us.intrinsic_faces, source.F, nv);
  std::vector<int> new_id(sub.crossings.size(), -1);
  std::vector<std::array<int, 3>> tris;
  for (int f = 0; f < nf; ++f)
    if (!pw.replaced[f]) tris.push_back({source.F(f, 0), source.F(f, 1), source.F(f, 2)}), pw.origin.push_back(f);
  std::vector<int> crossing_of_new;
  auto id_of = [&](const SubdivisionEnd& e) {
    if (e.vertex >= 0) return e.vertex;
    if (new_id[e.crossing] < 0) new_id[e.crossing] = nv + static_cast<int>(crossing_of_new.size()), crossing_of_new.push_back(e.crossing);
    return new_id[e.crossing];
  };
  // A new vertex's ray on the uniformization's own sphere (w_a x_a + w_b x_b,
  // + w_c x_c for a bend), and its point on its source edge.
  auto own_sphere = [&](const SubdivisionCrossing& c) -> Eigen::Vector3d {
    Eigen::Vector3d chord = c.wa * us.positions.row(c.a).transpose() + c.wb * us.positions.row(c.b).transpose();
    if (c.bend()) chord += c.wc * us.positions.row(c.c).transpose();
    return chord.normalized();
  };
  auto on_source = [&](const SubdivisionEnd& e) -> Eigen::Vector3d {
    if (e.vertex >= 0) return source.V.row(e.vertex).transpose();
    const SubdivisionCrossing& c = sub.crossings[e.crossing];
    return (1 - c.t) * source.V.row(c.A).transpose() + c.t * source.V.row(c.B).transpose();
  };
  std::vector<int> pieces_of(nf, 0);
  for (const SubdivisionPiece& p : pieces) {
    if (!pw.replaced[p.input_face]) continue;
    ++pieces_of[p.input_face];
    // A piece is convex on the sphere unless it has a bend; ears positive
    // on the sphere with no other corner inside, preferring those with area
    // on the source (three corners on one source edge have none there).
    std::vector<int> poly(p.corners.size());
    std::vector<Eigen::Vector3d> on_sphere, src;
    for (size_t i = 0; i < p.corners.size(); ++i) {
      poly[i] = static_cast<int>(i);
      const SubdivisionEnd& e = p.corners[i];
      on_sphere.push_back(e.vertex >= 0 ? Eigen::Vector3d(us.positions.row(e.vertex).transpose())
                                        : own_sphere(sub.crossings[e.crossing]));
      src.push_back(on_source(e));
    }
    const Eigen::Vector3d fa = source.V.row(source.F(p.input_face, 0)), fb = source.V.row(source.F(p.input_face, 1)),
                          fc = source.V.row(source.F(p.input_face, 2));
    const Eigen::Vector3d normal = (fb - fa).cross(fc - fa);
    auto det = [&](int a, int b, int c) { return on_sphere[a].dot(on_sphere[b].cross(on_sphere[c])); };
    while (poly.size() > 3) {
      const int m = static_cast<int>(poly.size());
      int best = -1, fallback = -1;
      for (int i = 0; i < m && best < 0; ++i) {
        const int a = poly[(i + m - 1) % m], b = poly[i], c = poly[(i + 1) % m];
        const double scale = (on_sphere[a] - on_sphere[b]).norm() * (on_sphere[b] - on_sphere[c]).norm() *
                             (on_sphere[c] - on_sphere[a]).norm();
        if (!(det(a, b, c) > 1e-12 * scale)) continue;
        bool empty = true;
        for (int x : poly)
          if (x != a && x != b && x != c && det(a, b, x) >= 0 && det(b, c, x) >= 0 && det(c, a, x) >= 0) empty = false;
        if (!empty) continue;
        if ((src[b] - src[a]).cross(src[c] - src[a]).dot(normal) > 1e-9 * normal.squaredNorm()) best = i;
        else if (fallback < 0) fallback = i;
      }
      const int i = best >= 0 ? best : fallback >= 0 ? fallback : 0;  // none: left to the positivity check below
      tris.push_back({id_of(p.corners[poly[(i + m - 1) % m]]), id_of(p.corners[poly[i]]), id_of(p.corners[poly[(i + 1) % m]])});
      pw.origin.push_back(p.input_face);
      poly.erase(poly.begin() + i);
    }
    tris.push_back({id_of(p.corners[poly[0]]), id_of(p.corners[poly[1]]), id_of(p.corners[poly[2]])});
    pw.origin.push_back(p.input_face);
  }
  for (int f = 0; f < nf; ++f)
    if (pw.replaced[f] && pieces_of[f] == 0)
      throw SolveError("common subdivision: source face " + std::to_string(f) + " has no pieces");
  const int nn = static_cast<int>(crossing_of_new.size());
  pw.faces.resize(static_cast<int>(tris.size()), 3);
  for (int i = 0; i < static_cast<int>(tris.size()); ++i)
    for (int k = 0; k < 3; ++k) pw.faces(i, k) = tris[i][k];
  pw.sphere.resize(nv + nn, 3);
  pw.sphere.topRows(nv) = X;
  for (int k = 0; k < nn; ++k) {
    const SubdivisionCrossing& c = sub.crossings[crossing_of_new[k]];
    // On the uniformization's own sphere, then the alignment (a rotation
    // and the landmarks' Möbius map).
    pw.sphere.row(nv + k) = alignment(own_sphere(c)).transpose();
    pw.bends += c.bend();
    const int h = sc.find_halfedge(c.A, c.B);
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    b[h % 3] = 1 - c.t, b[(h % 3 + 1) % 3] = c.t;
    pw.source_points.push_back(point_in_face(source, Connectivity::face(h), b));
  }
  // Positive triangles covering the sphere once: Σ spherical areas = 4π.
  double area = 0;
  int bad = 0, first_bad = -1;
  for (int i = 0; i < pw.faces.rows(); ++i) {
    const Eigen::Vector3d a = pw.sphere.row(pw.faces(i, 0)), b = pw.sphere.row(pw.faces(i, 1)), c = pw.sphere.row(pw.faces(i, 2));
    const double det = a.dot(b.cross(c));
    if (!(det > 0)) ++bad, first_bad = first_bad < 0 ? pw.origin[i] : first_bad;
    area += 2 * std::atan2(det, 1 + a.dot(b) + b.dot(c) + c.dot(a));
  }
  if (bad)
    throw SolveError("the common subdivision has " + std::to_string(bad) +
                     " triangles not positive on the sphere (first in source face " + std::to_string(first_bad) + ")");
  const double cover = area / (4 * M_PI);
  pw.cover = cover;
  if (!(std::abs(cover - 1) <= 1e-6))
    throw SolveError("the common subdivision covers the sphere " + std::to_string(cover) + " times");
  return pw;
}

/// The new vertices located on the target, the subdivision stored in
/// out.source_subdivision, and D' of the replaced source faces over their
/// pieces (max per face; the mean area-weighted over the pieces).
void piecewise_quality(const TriMesh& source, const SphereSide& target, const SphereLocator& tloc,
                       const PiecewiseSource& pw, SurfaceMapResult& out) {
  const int nv = source.num_vertices();
  auto& sub = out.source_subdivision;
  sub.faces = pw.faces;
  sub.face_origin = pw.origin;
  sub.source_points = pw.source_points;
  sub.forward = located_on_target(target, tloc, pw.sphere.bottomRows(pw.sphere.rows() - nv));
  sub.subdivided_faces = static_cast<int>(std::count(pw.replaced.begin(), pw.replaced.end(), 1));
  sub.bends = pw.bends;
  sub.sphere_cover = pw.cover;
  auto src = [&](int v) -> Eigen::Vector3d { return v < nv ? Eigen::Vector3d(source.V.row(v)) : sub.source_points[v - nv].position; };
  auto img = [&](int v) -> Eigen::Vector3d { return v < nv ? out.forward[v].position : sub.forward[v - nv].position; };
  auto area_of = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
    return 0.5 * (b - a).cross(c - a).norm();
  };
  double weighted = 0, total = 0, mx = 0;
  std::vector<double> piece_max(source.num_faces(), 0);
  // A thin input face (thin_source_faces: zero-area ones among them,
  // accepted through mollification) has pieces with no reliable 3D shape:
  // their D' is undefined or meaningless, not a degenerate image. They stay
  // out of the mean and max (as in sphere_map_quality), and the face keeps
  // the D' of its mollified lengths from sphere_map_quality.
  const std::vector<char> thin = thin_source_faces(source.V, source.F);
  for (int f = 0; f < source.num_faces(); ++f) {
    if (pw.replaced[f] || thin[f]) continue;
    const double a = area_of(source.V.row(source.F(f, 0)), source.V.row(source.F(f, 1)), source.V.row(source.F(f, 2)));
    if (std::isfinite(out.dilatation[f])) weighted += a * out.dilatation[f], total += a, mx = std::max(mx, out.dilatation[f]);
  }
  for (int i = 0; i < pw.faces.rows(); ++i) {
    const int f = pw.origin[i];
    if (!pw.replaced[f] || thin[f]) continue;
    const Eigen::Vector3d p0 = src(pw.faces(i, 0)), p1 = src(pw.faces(i, 1)), p2 = src(pw.faces(i, 2));
    const Eigen::Vector3d i0 = img(pw.faces(i, 0)), i1 = img(pw.faces(i, 1)), i2 = img(pw.faces(i, 2));
    const double a = area_of(p0, p1, p2);
    // Slivers of the fan (a crossing next to a corner) carry no area; their
    // D' says nothing about the map.
    const double face_area = area_of(source.V.row(source.F(f, 0)), source.V.row(source.F(f, 1)), source.V.row(source.F(f, 2)));
    if (!(a > 1e-9 * face_area)) continue;
    const double d = triangle_dilatation(Eigen::Vector3d((p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm()),
                                         Eigen::Vector3d((i1 - i0).norm(), (i2 - i1).norm(), (i0 - i2).norm()));
    if (!std::isfinite(d)) {
      ++out.degenerate_triangles;
      continue;
    }
    piece_max[f] = std::max(piece_max[f], d);
    weighted += a * d, total += a, mx = std::max(mx, d);
  }
  for (int f = 0; f < source.num_faces(); ++f)
    if (pw.replaced[f] && !thin[f]) out.dilatation[f] = piece_max[f];
  out.mean_dilatation = weighted / std::max(total, 1e-300);
  out.max_dilatation = mx;
  if (out.degenerate_triangles)
    throw SolveError("the genus-0 map has " + std::to_string(out.degenerate_triangles) +
                     " pieces of source triangles whose image on the target is degenerate; it is not returned");
}

}  // namespace

void map_spherical(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                   const SurfaceMapOptions& options, SurfaceMapResult& out, const StageDone& stage_done) {
  if (options.homotopy.class_index > 0)
    throw InputError("homotopy class " + std::to_string(options.homotopy.class_index) +
                     " does not exist; a genus-0 surface has one class (0)");
  SphericalUniformizationOptions uo;
  uo.flow.tolerance = options.uniformization.tolerance;
  int repaired_t = 0, repaired_s = 0;
  const SphericalUniformization ut = usable_sphere(target, uo, "target", &repaired_t);
  stage_done("target uniformization", 0.3);
  const SphericalUniformization us = usable_sphere(source, uo, "source", &repaired_s);
  stage_done("source uniformization", 0.45);

  // Points on the target's sphere are located in the triangulation that
  // embeds there and carried back to the target's faces (SphereSide): no
  // target vertex is re-placed.
  const SphereSide tside(target, ut), sside(source, us);
  const SphereLocator tloc(ut.positions, tside.faces);
  TriMesh target_as_located = target;
  target_as_located.F = tside.faces;  // the alignment's mismatch interpolates over the located faces
  SourceAlignment alignment;
  RowMatrixX3d X = aligned_source_sphere(source, target_as_located, us, ut, tloc, options, out, &alignment);
  const int nt = target.num_vertices();
  // A rotation costs every point 1e-16 absolute. A source whose sphere is
  // crowded far below that (a 40:1 tube's ends: chords of 3e-19 near a
  // pole, where the coordinates still resolve them) loses those faces to
  // round-off once rotated (flipped and degenerate image triangles). Then
  // the target's sphere, the better resolved one, is turned back instead:
  // the same map (only the relative rotation matters), the source's points
  // untouched. Landmarks' Möbius maps stay on the source's side.
  RowMatrixX3d target_sphere = ut.positions;
  std::unique_ptr<SphereLocator> turned_tloc;
  if (options.landmarks.empty() && !alignment.rotation.isIdentity(0)) {
    const double source_chord = smallest_chord(us.positions, sside.faces);
    if (source_chord < 1e-9 && source_chord < smallest_chord(ut.positions, tside.faces)) {
      target_sphere = ut.positions * alignment.rotation;  // rows: R^T p
      X = us.positions;
      alignment.rotation.setIdentity();
      turned_tloc = std::make_unique<SphereLocator>(target_sphere, tside.faces);
    }
  }
  const SphereLocator& aligned_tloc = turned_tloc ? *turned_tloc : tloc;
  out.converged = true;
  stage_done("alignment", 0.55);

  // The forward map is linear over the source's own faces between its
  // vertices' images, so a source face whose chord triangle is inverted on
  // the sphere (its image under the discrete conformal map is a curved
  // union of pieces of intrinsic triangles) would be a flipped triangle of
  // the map: only those vertices are still re-placed (untangle_sphere_image),
  // counted in repaired_vertices.
  RowMatrixX3d Xf = X;
  PiecewiseSource pw;
  bool piecewise = false;
  if (sside.carry) {
    std::vector<int> inverted;
    for (int f = 0; f < source.num_faces(); ++f)
      if (bad_face(X, source.F, f)) inverted.push_back(f);
    if (!inverted.empty()) {
      try {
        pw = piecewise_source(source, sc, us, alignment, X, inverted);
        piecewise = true;
        out.source_subdivision.status = "common subdivision";
      } catch (const SolveError& e) {
        out.source_subdivision.status = std::string("not built: ") + e.what();
      }
      out.source_subdivision.inverted_faces = static_cast<int>(inverted.size());
    }
    if (!piecewise) {
      const int moved = untangle_sphere_image(Xf, source.V, source.F, std::max(200, source.num_vertices() / 20));
      if (moved > 0) repaired_s += moved;
    }
  }
  out.repaired_vertices = repaired_s + repaired_t;
  if (piecewise) {
    check_sphere_image_orientation(pw.faces, pw.sphere, &pw.origin, options, out);
  } else {
    check_sphere_image_orientation(source.F, Xf, nullptr, options, out);
  }
  forward_map_and_quality(source, tside, sc, us, aligned_tloc, tloc, Xf, out);
  if (piecewise) piecewise_quality(source, tside, aligned_tloc, pw, out);
  stage_done("forward location", 0.75);

  // Harmonic energy of the sphere-valued map, Σ w_ij |X_i − X_j|² with the
  // source's intrinsic Delaunay cotangent weights (chordal distances): a
  // rotation leaves it unchanged, landmarks' Möbius maps change it.
  const IntrinsicDelaunayResult idt = intrinsic_delaunay(sc, edge_lengths(source, sc));
  auto energy = [&](const RowMatrixX3d& Y) {
    double e = 0;
    for (const auto& ie : idt.edges) e += ie.cot_weight * (Y.row(ie.i) - Y.row(ie.j)).squaredNorm();
    return e;
  };
  out.initial_energy = energy(us.positions);
  out.final_energy = energy(Xf);
  out.energy_history = {out.initial_energy, out.final_energy};
  HomotopyCandidate c;
  c.description = "genus 0: the only class (the sphere is simply connected)";
  c.energy = out.final_energy;
  out.candidates = {c};
  out.chosen_candidate = 0;
  stage_done("energy", 0.8);

  // Inverse map: every target vertex located in the source's aligned image
  // (its embedded triangulation, carried back to the source's faces).
  const SphereLocator sloc(sside.carry ? X : Xf, sside.faces);
  out.inverse.resize(nt);
  int hint = -1;
  for (int v = 0; v < nt; ++v) {
    Eigen::Vector3d b;
    hint = sloc.locate(target_sphere.row(v).transpose(), &b, hint);
    out.inverse[v] = sside.point(hint, b);
  }
  stage_done("inverse location", 1.0);
}

}  // namespace detail
}  // namespace surfmap
