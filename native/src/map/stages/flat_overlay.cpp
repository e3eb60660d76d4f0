#include "flat_overlay.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <Eigen/Core>

#include "surfmap/geometry/nearest_point.h"
#include "surfmap/topology/projected_loops.h"

namespace surfmap::detail {
namespace {

using Complex = std::complex<double>;

// Points T p, centred on their bounding box and divided by its diagonal:
// the same frame for a copy however it is translated or scaled, with the
// shape's proportions kept (a per-axis box would stretch a flat torus's
// thickness to its width and send points across the tube).
std::vector<Eigen::Vector3d> normalised(const TriMesh& m, const Eigen::Matrix3d& T) {
  std::vector<Eigen::Vector3d> p(m.num_vertices());
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int v = 0; v < m.num_vertices(); ++v) {
    p[v] = T * m.V.row(v).transpose();
    lo = lo.cwiseMin(p[v]), hi = hi.cwiseMax(p[v]);
  }
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double diagonal = std::max((hi - lo).norm(), std::numeric_limits<double>::min());
  for (Eigen::Vector3d& q : p) q = (q - centre) / diagonal;
  return p;
}

double cross(Complex a, Complex b) { return a.real() * b.imag() - a.imag() * b.real(); }

}  // namespace

FlatOverlay::FlatOverlay(const TriMesh& source, const TriMesh& target, const std::vector<Complex>& target_flat,
                         Complex w1, Complex w2, const FlatOverlayOptions& options)
    : target_flat_(target_flat.begin(), target_flat.begin() + std::min<size_t>(target_flat.size(), target.num_vertices())),
      w1_(w1), w2_(w2), options_(options) {
  const int n = source.num_vertices();
  const int step = std::max(1, (n + std::max(1, options.max_samples) - 1) / std::max(1, options.max_samples));
  for (int v = 0; v < n; v += step) samples_.push_back(v);
  std::vector<OverlayPose> poses{{Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity(), "as posed"}};
  for (OverlayPose& p : rotation_overlay_poses(source, target)) poses.push_back(std::move(p));
  // One k-d tree per target frame (the world-axis poses share the target's).
  std::unique_ptr<NearestPointIndex> index;
  Eigen::Matrix3d indexed_transform = Eigen::Matrix3d::Zero();
  for (const OverlayPose& pose : poses) {
    if (!index || pose.target_transform != indexed_transform) {
      std::vector<Eigen::Vector3d> tp = normalised(target, pose.target_transform);
      tp.resize(target_flat_.size());  // (only vertices with a flat position)
      index = std::make_unique<NearestPointIndex>(std::move(tp));
      indexed_transform = pose.target_transform;
    }
    const std::vector<Eigen::Vector3d> sp = normalised(source, pose.source_transform);
    Pose p{pose.description, {}};
    for (int v : samples_) p.nearest.push_back(index->nearest(sp[v]));
    poses_.push_back(std::move(p));
  }
}

FlatOverlayFit FlatOverlay::fit(const std::vector<Complex>& z) const {
  FlatOverlayFit best;
  best.residual = std::numeric_limits<double>::infinity();
  const double det = cross(w1_, w2_);
  if (!(std::abs(det) > 0) || samples_.empty()) return best;
  const double two_pi = 2 * std::acos(-1.0);
  // The lattice representative of d nearest 0.
  auto wrapped = [&](Complex d) {
    Complex r = d - std::round(cross(d, w2_) / det) * w1_ - std::round(cross(w1_, d) / det) * w2_;
    Complex shortest = r;
    for (int m = -1; m <= 1; ++m)
      for (int k = -1; k <= 1; ++k) {
        const Complex c = r + double(m) * w1_ + double(k) * w2_;
        if (std::abs(c) < std::abs(shortest)) shortest = c;
      }
    return shortest;
  };
  for (const Pose& pose : poses_) {
    if (static_cast<int>(pose.nearest.size()) != static_cast<int>(samples_.size())) continue;
    // Offsets d_i = (flat position of the overlay's target vertex) - z_i,
    // each defined modulo the lattice: their circular mean in lattice
    // coordinates, then the mean of the wrapped residuals about it.
    std::vector<Complex> d(samples_.size());
    Complex ea = 0, eb = 0;
    for (size_t i = 0; i < samples_.size(); ++i) {
      const int j = pose.nearest[i];
      if (j < 0) continue;
      d[i] = target_flat_[j] - z[samples_[i]];
      ea += std::polar(1.0, two_pi * cross(d[i], w2_) / det);
      eb += std::polar(1.0, two_pi * cross(w1_, d[i]) / det);
    }
    Complex shift = std::arg(ea) / two_pi * w1_ + std::arg(eb) / two_pi * w2_;
    for (int round = 0; round < 2; ++round) {
      Complex mean = 0;
      for (const Complex& di : d) mean += wrapped(di - shift);
      shift += mean / double(d.size());
    }
    double residual = 0;
    for (const Complex& di : d) residual += std::abs(wrapped(di - shift));
    residual /= double(d.size()) * std::sqrt(std::abs(det));
    if (residual < best.residual) best.residual = residual, best.shift = shift, best.pose = pose.description;
    // As posed first: a rotation is tried only when the shapes do not
    // overlap as posed. (A symmetric shape overlaps itself after some
    // rotations too, a torus of revolution after a half turn about a
    // horizontal axis, within the same noise: the map would be the symmetry.)
    if (&pose == &poses_.front() && residual <= options_.max_residual) break;
  }
  best.overlaps = best.residual <= options_.max_residual;
  best.as_posed = best.overlaps && best.pose == poses_.front().description;
  return best;
}

}  // namespace surfmap::detail
