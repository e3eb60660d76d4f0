#include "surfmap/geometry/nearest_point.h"

#include <algorithm>
#include <limits>
#include <numeric>

#include "surfmap/error.h"

namespace surfmap {

NearestPointIndex::NearestPointIndex(std::vector<Eigen::Vector3d> points, const NearestPointOptions& options)
    : points_(std::move(points)), leaf_size_(options.leaf_size) {
  if (leaf_size_ < 1) throw InputError("NearestPointIndex: leaf_size must be >= 1, got " + std::to_string(leaf_size_));
  order_.resize(points_.size());
  std::iota(order_.begin(), order_.end(), 0);
  nodes_.reserve(2 * points_.size() / leaf_size_ + 2);
  if (!points_.empty()) build(0, static_cast<int>(points_.size()), 0);
}

// Splits [begin, end) of order_ at its median along the axis of largest
// extent; returns the node's index. Recursion depth is log2(N / leaf_size).
int NearestPointIndex::build(int begin, int end, int depth) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back(Node{begin, end});
  if (end - begin <= leaf_size_ || depth > 60) return id;
  Eigen::Vector3d lo = points_[order_[begin]], hi = lo;
  for (int i = begin + 1; i < end; ++i) {
    lo = lo.cwiseMin(points_[order_[i]]);
    hi = hi.cwiseMax(points_[order_[i]]);
  }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  if (!(hi[axis] > lo[axis])) return id;  // all points coincide: a leaf
  const int mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](int a, int b) { return points_[a][axis] < points_[b][axis]; });
  const double split = points_[order_[mid]][axis];
  nodes_[id].axis = axis;
  nodes_[id].split = split;
  const int left = build(begin, mid, depth + 1);
  const int right = build(mid, end, depth + 1);
  nodes_[id].left = left;
  nodes_[id].right = right;
  return id;
}

// Left subtree: coordinates <= split; right subtree: >= split. The far side
// is visited when the plane is no farther than the best distance (ties
// included, so that the smallest index among equally near points wins).
void NearestPointIndex::search(int node, const Eigen::Vector3d& q, int& best, double& best_d2) const {
  const Node& n = nodes_[node];
  if (n.axis < 0) {
    for (int i = n.begin; i < n.end; ++i) {
      const int p = order_[i];
      const double d2 = (points_[p] - q).squaredNorm();
      if (d2 < best_d2 || (d2 == best_d2 && p < best)) best_d2 = d2, best = p;
    }
    return;
  }
  const double delta = q[n.axis] - n.split;
  const int near_side = delta <= 0 ? n.left : n.right, far_side = delta <= 0 ? n.right : n.left;
  search(near_side, q, best, best_d2);
  if (delta * delta <= best_d2) search(far_side, q, best, best_d2);
}

int NearestPointIndex::nearest(const Eigen::Vector3d& q) const {
  if (points_.empty()) return -1;
  int best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  search(0, q, best, best_d2);
  return best;
}

}  // namespace surfmap
