// Genus-0 points back on the input faces (uniformize/spherical_correspondence.h).
#include "surfmap/uniformize/spherical_correspondence.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "surfmap/error.h"
#include "surfmap/uniformize/intrinsic_correspondence.h"

namespace surfmap {
namespace {

Eigen::Vector3d clamped(Eigen::Vector3d b) {
  b = b.cwiseMax(0.0);
  const double s = b.sum();
  return s > 0 ? Eigen::Vector3d(b / s) : Eigen::Vector3d::Constant(1.0 / 3.0);
}

// Vertex id of column c of a row given as slots.
int vertex_at(const SphereFlip& fl, const std::array<int, 3>& slots, int c) { return fl.quad[slots[c]]; }

}  // namespace

SphericalCorrespondence::SphericalCorrespondence(const SphericalUniformization& s, const RowMatrixX3i& input_faces)
    : flips_(s.flip_log), frames_(s.frame_log), final_(s.intrinsic_faces) {
  const int nf = static_cast<int>(final_.rows());
  if (input_faces.rows() != nf || s.frame_log.empty())
    throw InputError("spherical correspondence: no flip log for " + std::to_string(nf) + " intrinsic faces");
  flips_of_face_.resize(nf);
  // Replay the log on the input faces: it must end on intrinsic_faces. A
  // flip's rows may start at another column than the face's row before it
  // (the punctured disk writes star rows from v0 on): the rotation is kept.
  RowMatrixX3i rows = input_faces;
  auto rotation = [&](int f, const SphereFlip& fl, const std::array<int, 3>& slots) {
    for (int r = 0; r < 3; ++r) {
      bool same = true;
      for (int c = 0; c < 3; ++c) same = same && rows(f, (c + r) % 3) == vertex_at(fl, slots, c);
      if (same) return r;
    }
    return -1;
  };
  rot0_.resize(flips_.size());
  rot1_.resize(flips_.size());
  for (int j = 0; j < static_cast<int>(flips_.size()); ++j) {
    const SphereFlip& fl = flips_[j];
    if (fl.face0 < 0 || fl.face1 < 0 || fl.face0 >= nf || fl.face1 >= nf || fl.face0 == fl.face1)
      throw InputError("spherical correspondence: flip " + std::to_string(j) + " names wrong faces");
    rot0_[j] = rotation(fl.face0, fl, fl.before0);
    rot1_[j] = rotation(fl.face1, fl, fl.before1);
    if (rot0_[j] < 0 || rot1_[j] < 0)
      throw InputError("spherical correspondence: flip " + std::to_string(j) + " does not match the faces before it");
    for (int c = 0; c < 3; ++c) {
      rows(fl.face0, c) = vertex_at(fl, fl.after0, c);
      rows(fl.face1, c) = vertex_at(fl, fl.after1, c);
    }
    flips_of_face_[fl.face0].push_back(j);
    flips_of_face_[fl.face1].push_back(j);
  }
  rows_end_ = rows;
  final_rot_.assign(nf, -1);
  for (int f = 0; f < nf; ++f)
    for (int r = 0; r < 3 && final_rot_[f] < 0; ++r)
      if (rows(f, r) == final_(f, 0) && rows(f, (1 + r) % 3) == final_(f, 1) && rows(f, (2 + r) % 3) == final_(f, 2))
        final_rot_[f] = r;
  for (int f = 0; f < nf; ++f)
    if (final_rot_[f] < 0)
      throw InputError("spherical correspondence: the flip log does not end on intrinsic face " + std::to_string(f));
}

FacePoint SphericalCorrespondence::to_input(int f, const Eigen::Vector3d& b) const {
  if (f < 0 || f >= final_.rows())
    throw InputError("spherical correspondence: face " + std::to_string(f) + " out of range");
  FacePoint p{f, Eigen::Vector3d::Zero()};
  const Eigen::Vector3d bc = clamped(b);
  std::array<int, 3> row{};
  for (int c = 0; c < 3; ++c) {
    p.barycentric[(c + final_rot_[f]) % 3] = bc[c];
    row[c] = rows_end_(f, c);
  }
  int frame = static_cast<int>(frames_.size()) - 1;
  // Frames changed after flip j (time > j) are undone before flip j.
  auto undo_frames_after = [&](int j) {
    for (; frame >= 0 && frames_[frame].time > j; --frame) {
      const Eigen::VectorXd& g = frames_[frame].log_scale;
      const double top = std::max({g[row[0]], g[row[1]], g[row[2]]});
      Eigen::Vector3d q;
      for (int c = 0; c < 3; ++c) q[c] = p.barycentric[c] * std::exp(g[row[c]] - top);
      p.barycentric = clamped(q);
    }
  };
  int time = static_cast<int>(flips_.size());
  for (;;) {
    const std::vector<int>& list = flips_of_face_[p.face];
    const auto it = std::lower_bound(list.begin(), list.end(), time);
    if (it == list.begin()) break;
    const int j = *(it - 1);
    undo_frames_after(j);
    const SphereFlip& fl = flips_[j];
    const std::array<int, 3>& now = p.face == fl.face0 ? fl.after0 : fl.after1;
    Eigen::Vector4d w = Eigen::Vector4d::Zero();
    for (int c = 0; c < 3; ++c) w[now[c]] += p.barycentric[c];
    EdgeFlip ef;
    ef.base_lengths = fl.lengths;
    ef.exact = false;  // Ptolemy flips: null vectors; exact flips unfold in the plane
    // Old triangles in slot order: 0 = (k, s, t) is face0's, 1 = (m, t, s) face1's.
    const Eigen::Vector3d c0 = detail::old_triangle_weights(ef, fl.exact, 0, w),
                          c1 = detail::old_triangle_weights(ef, fl.exact, 1, w);
    auto worst = [](const Eigen::Vector3d& x) { return x.allFinite() ? x.minCoeff() : -INFINITY; };
    const int side = worst(c0) >= worst(c1) ? 0 : 1;
    const Eigen::Vector3d& c = side == 0 ? c0 : c1;
    static constexpr int kOldSlots[2][3] = {{0, 1, 3}, {2, 3, 1}};
    Eigen::Vector4d slot_weight = Eigen::Vector4d::Zero();
    for (int a = 0; a < 3; ++a) slot_weight[kOldSlots[side][a]] = c[a];
    const std::array<int, 3>& before = side == 0 ? fl.before0 : fl.before1;
    const int rot = side == 0 ? rot0_[j] : rot1_[j];
    Eigen::Vector3d bary;
    for (int col = 0; col < 3; ++col) {
      bary[(col + rot) % 3] = slot_weight[before[col]];
      row[(col + rot) % 3] = fl.quad[before[col]];
    }
    p.face = side == 0 ? fl.face0 : fl.face1;
    p.barycentric = clamped(bary);
    time = j;
  }
  undo_frames_after(-1);
  return p;
}

}  // namespace surfmap
