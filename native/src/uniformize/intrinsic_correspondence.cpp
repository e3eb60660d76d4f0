// Points of the flip-based metric on the input faces
// (uniformize/intrinsic_correspondence.h; docs/uniformization.md).
#include "surfmap/uniformize/intrinsic_correspondence.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "surfmap/error.h"

namespace surfmap {
namespace {

// Quad slots (k, s, m, t) = 0..3; EdgeFlip::base_lengths order of the pairs.
constexpr int kPairs[6][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {1, 3}, {0, 2}};
// Old triangles: face0's row from corner0 on holds slots k, s, t; face1's
// from corner1 on m, t, s. New: face0 = (k, s, m), face1 = (m, t, k).
constexpr int kOld[2][3] = {{0, 1, 3}, {2, 3, 1}};
constexpr int kNew[2][3] = {{0, 1, 2}, {2, 3, 0}};

using Quad = Eigen::Matrix4d;

/// Gram matrix of the quad's corner vectors in R^{2,1}: null vectors
/// (Ptolemy flips) or hyperboloid points (exact hyperbolic flips).
Quad gram(const EdgeFlip& fl, bool hyperboloid) {
  Quad G = Quad::Constant(hyperboloid ? -1.0 : 0.0);
  for (int p = 0; p < 6; ++p) {
    const double x = fl.base_lengths[p];
    const double g = (hyperboloid ? -1.0 : 0.0) - 0.5 * x * x;
    G(kPairs[p][0], kPairs[p][1]) = G(kPairs[p][1], kPairs[p][0]) = g;
  }
  return G;
}

/// Barycentrics (over the triangle's three slots, summing to 1) of the
/// point with slot weights w, through the Gram matrix: Σ c_i v_i ∥ Σ w_j v_j.
Eigen::Vector3d weights_by_gram(const Quad& G, const int tri[3], const Eigen::Vector4d& w) {
  Eigen::Matrix3d A;
  Eigen::Vector3d rhs;
  const Eigen::Vector4d Gw = G * w;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) A(a, b) = G(tri[a], tri[b]);
    rhs[a] = Gw[tri[a]];
  }
  Eigen::Vector3d c = A.fullPivLu().solve(rhs);
  return c / c.sum();
}

/// The same for a Euclidean quad unfolded in the plane (exact flips).
Eigen::Vector3d weights_in_plane(const EdgeFlip& fl, const int tri[3], const Eigen::Vector4d& w) {
  const auto& L = fl.base_lengths;
  std::array<Eigen::Vector2d, 4> q;
  const double st = L[4];
  q[1] = {0, 0};
  q[3] = {st, 0};
  const double kx = (L[0] * L[0] - L[3] * L[3] + st * st) / (2 * st);
  q[0] = {kx, std::sqrt(std::max(0.0, L[0] * L[0] - kx * kx))};  // (k, s, t) counter-clockwise
  const double mx = (L[1] * L[1] - L[2] * L[2] + st * st) / (2 * st);
  q[2] = {mx, -std::sqrt(std::max(0.0, L[1] * L[1] - mx * mx))};  // (m, t, s) counter-clockwise
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  for (int j = 0; j < 4; ++j) p += w[j] * q[j];
  auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); };
  Eigen::Vector3d c;
  for (int a = 0; a < 3; ++a) c[a] = cross(q[tri[(a + 1) % 3]] - p, q[tri[(a + 2) % 3]] - p);
  return c / c.sum();
}

Eigen::Vector3d clamped(Eigen::Vector3d b) {
  b = b.cwiseMax(0.0);
  const double s = b.sum();
  return s > 0 ? Eigen::Vector3d(b / s) : Eigen::Vector3d::Constant(1.0 / 3.0);
}

}  // namespace

namespace detail {
Eigen::Vector3d old_triangle_weights(const EdgeFlip& fl, bool plane, int side, const Eigen::Vector4d& w) {
  return plane ? weights_in_plane(fl, kOld[side], w) : weights_by_gram(gram(fl, fl.exact), kOld[side], w);
}
}  // namespace detail

IntrinsicCorrespondence::IntrinsicCorrespondence(const RicciFlowResult& flow)
    : flips_(flow.flip_history), faces_(flow.faces), u_(flow.u), background_(flow.background) {
  if (static_cast<int>(flips_.size()) != flow.flips)
    throw InputError("intrinsic correspondence: the flow made " + std::to_string(flow.flips) + " flips but recorded " +
                     std::to_string(flips_.size()));
  flips_of_face_.resize(faces_.rows());
  for (int j = 0; j < static_cast<int>(flips_.size()); ++j) {
    const EdgeFlip& fl = flips_[j];
    if (fl.face0 < 0 || fl.face1 < 0 || fl.face0 >= faces_.rows() || fl.face1 >= faces_.rows())
      throw InputError("intrinsic correspondence: flip " + std::to_string(j) + " names a face out of range");
    flips_of_face_[fl.face0].push_back(j);
    flips_of_face_[fl.face1].push_back(j);
  }
  // The final-frame flips come last; the faces before them, by undoing
  // their rows (after: face0 = (k, s, m), face1 = (m, t, k)).
  solve_flips_ = static_cast<int>(flips_.size());
  while (solve_flips_ > 0 && flips_[solve_flips_ - 1].final_frame) --solve_flips_;
  for (int j = 0; j < solve_flips_; ++j)
    if (flips_[j].final_frame)
      throw InputError("intrinsic correspondence: final-frame flip " + std::to_string(j) + " before a flip of the solve");
  solve_faces_ = faces_;
  for (int j = static_cast<int>(flips_.size()) - 1; j >= solve_flips_; --j) {
    const EdgeFlip& fl = flips_[j];
    const int k = solve_faces_(fl.face0, 0), s = solve_faces_(fl.face0, 1), m = solve_faces_(fl.face0, 2),
              t = solve_faces_(fl.face1, 1);
    solve_faces_(fl.face0, fl.corner0) = k, solve_faces_(fl.face0, (fl.corner0 + 1) % 3) = s,
                               solve_faces_(fl.face0, (fl.corner0 + 2) % 3) = t;
    solve_faces_(fl.face1, fl.corner1) = m, solve_faces_(fl.face1, (fl.corner1 + 1) % 3) = t,
                               solve_faces_(fl.face1, (fl.corner1 + 2) % 3) = s;
  }
}

FacePoint IntrinsicCorrespondence::to_input(int f, const Eigen::Vector3d& b) const {
  if (f < 0 || f >= faces_.rows()) throw InputError("intrinsic correspondence: face " + std::to_string(f) + " out of range");
  // The final-frame flips, in the final metric.
  const FacePoint q = undo_range(FacePoint{f, clamped(b)}, solve_flips_, static_cast<int>(flips_.size()));
  // b⁰_i ∝ b_i e^{u_i}, scaled by the largest factor of the face against overflow.
  double umax = -INFINITY;
  for (int k = 0; k < 3; ++k) umax = std::max(umax, u_[solve_faces_(q.face, k)]);
  Eigen::Vector3d b0;
  for (int k = 0; k < 3; ++k) b0[k] = std::max(0.0, q.barycentric[k]) * std::exp(u_[solve_faces_(q.face, k)] - umax);
  return undo_flips(q.face, clamped(b0));
}

FacePoint IntrinsicCorrespondence::undo_flips(int f, const Eigen::Vector3d& b) const {
  if (f < 0 || f >= faces_.rows()) throw InputError("intrinsic correspondence: face " + std::to_string(f) + " out of range");
  return undo_range(FacePoint{f, clamped(b)}, 0, solve_flips_);
}

FacePoint IntrinsicCorrespondence::undo_range(FacePoint p, int stop, int time) const {
  for (;;) {
    const std::vector<int>& list = flips_of_face_[p.face];
    const auto it = std::lower_bound(list.begin(), list.end(), time);
    if (it == list.begin() || *(it - 1) < stop) break;
    const int j = *(it - 1);
    const EdgeFlip& fl = flips_[j];
    // The point's weights on the quad's slots (it is in one of the new faces).
    const int side = p.face == fl.face0 ? 0 : 1;
    Eigen::Vector4d w = Eigen::Vector4d::Zero();
    for (int a = 0; a < 3; ++a) w[kNew[side][a]] += p.barycentric[a];
    // Written in both old triangles; the one with no (or the least) negative
    // weight contains it (both agree on the old diagonal).
    Eigen::Vector3d c[2];
    const bool plane = fl.exact && background_ == Background::Euclidean;
    const Quad G = plane ? Quad() : gram(fl, fl.exact);
    for (int o = 0; o < 2; ++o) c[o] = plane ? weights_in_plane(fl, kOld[o], w) : weights_by_gram(G, kOld[o], w);
    auto worst = [](const Eigen::Vector3d& x) { return x.allFinite() ? x.minCoeff() : -INFINITY; };
    const int o = worst(c[0]) >= worst(c[1]) ? 0 : 1;
    const int face = o == 0 ? fl.face0 : fl.face1, corner = o == 0 ? fl.corner0 : fl.corner1;
    Eigen::Vector3d bary;
    for (int a = 0; a < 3; ++a) bary[(corner + a) % 3] = c[o][a];
    p.face = face;
    p.barycentric = clamped(bary);
    time = j;
  }
  return p;
}

}  // namespace surfmap
