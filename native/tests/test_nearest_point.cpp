// NearestPointIndex (geometry/nearest_point.h): exact nearest point, checked
// against brute force and against the uniform-grid ring search the loop
// overlay used before issue 19 (kept here as the reference).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <unordered_map>

#include "surfmap/error.h"
#include "surfmap/geometry/nearest_point.h"
#include "surfmap/samples/shapes.h"

using namespace surfmap;

namespace {

int brute_nearest(const std::vector<Eigen::Vector3d>& p, const Eigen::Vector3d& q) {
  int best = -1;
  double bd = std::numeric_limits<double>::infinity();
  for (int i = 0; i < static_cast<int>(p.size()); ++i) {
    const double d = (p[i] - q).squaredNorm();
    if (d < bd) bd = d, best = i;  // first (smallest) index among ties
  }
  return best;
}

// The overlay's former nearest-vertex search (topology/projected_loops.cpp
// before issue 19), verbatim: cells of side `cell`, rings r = 0..63 around
// the query's cell, stop once the best point is within r cells. Returns the
// point and whether the search stopped by that rule (else it ran out of
// rings and its answer need not be the nearest).
struct OldVertexGrid {
  OldVertexGrid(std::vector<Eigen::Vector3d> p, double cell) : p_(std::move(p)), cell_(cell) {
    for (int i = 0; i < static_cast<int>(p_.size()); ++i) cells_[key(cellof(p_[i]))].push_back(i);
  }
  std::pair<int, bool> nearest(const Eigen::Vector3d& q) const {
    const Eigen::Vector3i c = cellof(q);
    int best = -1;
    double bd = std::numeric_limits<double>::infinity();
    for (int r = 0; r < 64; ++r) {
      for (int x = -r; x <= r; ++x)
        for (int y = -r; y <= r; ++y)
          for (int z = -r; z <= r; ++z) {
            if (std::max({std::abs(x), std::abs(y), std::abs(z)}) != r) continue;
            auto it = cells_.find(key(c + Eigen::Vector3i(x, y, z)));
            if (it == cells_.end()) continue;
            for (int i : it->second) {
              const double d = (p_[i] - q).squaredNorm();
              if (d < bd) bd = d, best = i;
            }
          }
      if (best >= 0 && std::sqrt(bd) <= r * cell_) return {best, true};
    }
    return {best, false};
  }
  Eigen::Vector3i cellof(const Eigen::Vector3d& q) const {
    return Eigen::Vector3i(static_cast<int>(std::floor(q[0] / cell_)), static_cast<int>(std::floor(q[1] / cell_)),
                           static_cast<int>(std::floor(q[2] / cell_)));
  }
  static long long key(const Eigen::Vector3i& c) {
    return ((static_cast<long long>(c[0]) + 1048576) << 42) ^ ((static_cast<long long>(c[1]) + 1048576) << 21) ^
           (static_cast<long long>(c[2]) + 1048576);
  }
  std::vector<Eigen::Vector3d> p_;
  double cell_;
  std::unordered_map<long long, std::vector<int>> cells_;
};

// Vertices scaled per axis into [-1/2, 1/2]^3 (the overlay's box frame).
std::vector<Eigen::Vector3d> in_unit_box(const TriMesh& m) {
  const Eigen::RowVector3d lo = m.V.colwise().minCoeff(), hi = m.V.colwise().maxCoeff();
  std::vector<Eigen::Vector3d> out;
  for (int v = 0; v < m.num_vertices(); ++v)
    out.push_back(((m.V.row(v) - 0.5 * (lo + hi)).array() / (hi - lo).array()).matrix().transpose());
  return out;
}

}  // namespace

TEST(NearestPoint, MatchesBruteForceOnRandomPointsWithDuplicates) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int n : {1, 2, 9, 100, 3000}) {
    std::vector<Eigen::Vector3d> p;
    for (int i = 0; i < n; ++i) p.emplace_back(u(rng), u(rng), 0.1 * u(rng));
    // Exact duplicates and points on a lattice (many equal coordinates and
    // equal distances): the smallest index must win.
    for (int i = 0; i < n / 3; ++i) p.push_back(p[static_cast<size_t>(i * 2) % p.size()]);
    for (int i = 0; i < 27; ++i) p.emplace_back(i % 3 - 1.0, (i / 3) % 3 - 1.0, i / 9 - 1.0);
    const NearestPointIndex index(p, NearestPointOptions{3});
    for (int k = 0; k < 500; ++k) {
      Eigen::Vector3d q(u(rng), u(rng), u(rng));
      if (k % 5 == 0) q *= 10;  // far off the point set
      if (k % 7 == 0) q = p[static_cast<size_t>(k) % p.size()];
      if (k % 11 == 0) q = Eigen::Vector3d(0.5 * (k % 3), 0, 0);  // equidistant from lattice points
      ASSERT_EQ(index.nearest(q), brute_nearest(p, q)) << "n " << n << " query " << k;
    }
  }
}

TEST(NearestPoint, EmptySetAndBadOptions) {
  EXPECT_EQ(NearestPointIndex({}).nearest(Eigen::Vector3d::Zero()), -1);
  EXPECT_THROW(NearestPointIndex({Eigen::Vector3d::Zero()}, NearestPointOptions{0}), InputError);
}

// The loop overlay's query: every vertex of one shape, in its box frame,
// against the other shape's vertices. The old grid's answer is compared
// wherever its ring search stopped by its own rule (then it was exact).
TEST(NearestPoint, SameAnswerAsTheOldGridOnAShapePair) {
  const std::vector<Eigen::Vector3d> target = in_unit_box(samples::vase(40, true));
  const std::vector<Eigen::Vector3d> source = in_unit_box(samples::n_hole_torus(2, 40, true));
  const NearestPointIndex index(target);
  const OldVertexGrid old(target, 0.02);
  int compared = 0, off_surface = 0;
  for (size_t i = 0; i < source.size(); i += 3) {
    const auto [old_answer, old_exact] = old.nearest(source[i]);
    const int now = index.nearest(source[i]);
    ASSERT_EQ(now, brute_nearest(target, source[i]));
    if (!old_exact) continue;
    ++compared;
    EXPECT_EQ(now, old_answer) << "source vertex " << i;
    if ((target[now] - source[i]).norm() > 0.1) ++off_surface;
  }
  EXPECT_GT(compared, static_cast<int>(source.size() / 3) * 9 / 10);
  EXPECT_GT(off_surface, 0);  // the shapes differ: some queries lie far from the target (the old grid's slow case)
}
