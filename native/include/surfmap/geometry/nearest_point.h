#pragma once
// Nearest point among a fixed set of 3D points (a k-d tree), for the loop
// overlay (topology/projected_loops.h, docs/method.md §2.6: a source loop's vertices
// are sent to the nearest target vertex). Issue 19 (docs/benchmarks.md): the
// overlay used a uniform grid searched ring by ring, whose cost grows like
// (distance / cell)^3 when the query lies off the point set; cells shrink
// with the mesh, so the overlay of two different shapes grew like V^1.5 per
// query. The tree's query cost depends on the number of points near the
// query's distance shell, not on how far the query lies from them.
#include <vector>

#include <Eigen/Core>

namespace surfmap {

struct NearestPointOptions {
  /// Points per leaf (>= 1); 8 is a good trade-off between tree depth and
  /// brute-force work in the leaves.
  int leaf_size = 8;
};

/// A static k-d tree over `points` (N points, any N >= 0).
/// Built in O(N log N), O(N) memory; each query is exact.
class NearestPointIndex {
 public:
  explicit NearestPointIndex(std::vector<Eigen::Vector3d> points, const NearestPointOptions& options = {});
  /// The index (into the constructor's points) of the point nearest `q` in
  /// Euclidean distance; among equally near points the smallest index.
  /// -1 when there are no points.
  int nearest(const Eigen::Vector3d& q) const;
  int size() const { return static_cast<int>(points_.size()); }

 private:
  struct Node {
    int begin, end;      // range of order_ (leaf) or of the subtree
    int axis = -1;       // split axis, -1 for a leaf
    double split = 0;    // coordinate of the split
    int left = -1, right = -1;
  };
  int build(int begin, int end, int depth);
  void search(int node, const Eigen::Vector3d& q, int& best, double& best_d2) const;
  std::vector<Eigen::Vector3d> points_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
  int leaf_size_;
};

}  // namespace surfmap
