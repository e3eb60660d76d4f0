// TriangleGrid (map/point_location.h): its dense cells are refined (issue
// 19), so a triangulation graded like the Klein images of a fundamental
// polygon's corner (triangles 1e4 times smaller near one point) is located
// from short candidate lists, and every point is found in the triangle that
// a search over all triangles finds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <random>

#include "surfmap/map/point_location.h"

namespace surfmap {
namespace {

using Complex = std::complex<double>;

// A triangulated square [0,1]^2 whose grid lines accumulate at the corner
// (1, 1): coordinates 1 - s^4 for s uniform in [0, 1] (cells 1e-8 small there).
PlaneTriangles graded_square(int n) {
  auto coord = [n](int i) { return 1.0 - std::pow(1.0 - static_cast<double>(i) / n, 4.0); };
  PlaneTriangles tris;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const Complex a(coord(i), coord(j)), b(coord(i + 1), coord(j)), c(coord(i + 1), coord(j + 1)),
          d(coord(i), coord(j + 1));
      tris.push_back({a, b, c});
      tris.push_back({a, c, d});
    }
  return tris;
}

TEST(TriangleGrid, GradedTriangulationIsLocatedFromShortListsLikeAFullSearch) {
  const PlaneTriangles tris = graded_square(200);  // 80k triangles
  const TriangleGrid grid(tris, 1e-12);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  size_t longest = 0, total = 0;
  const int samples = 1000;
  for (int k = 0; k < samples; ++k) {
    // Half the points in the dense corner (within 1e-3 of (1, 1)).
    const double s = k % 2 ? 1e-3 : 1.0;
    const Complex p(1.0 - s * u(rng), 1.0 - s * u(rng));
    const std::vector<int>& cand = grid.candidates(p);
    longest = std::max(longest, cand.size()), total += cand.size();
    Eigen::Vector3d b;
    const int f = grid.locate(p, &b);
    // The full search: the triangle with the largest smallest barycentric.
    int best = -1;
    double best_min = -1e300;
    for (int t = 0; t < static_cast<int>(tris.size()); ++t) {
      const double m = TriangleGrid::barycentric(tris[t], p).minCoeff();
      if (m > best_min) best_min = m, best = t;
    }
    ASSERT_GE(best_min, -1e-9);
    ASSERT_GE(f, 0) << p;
    EXPECT_GE(b.minCoeff(), -1e-9);
    // The same triangle, or (a point on a shared edge) one as good.
    if (f != best) EXPECT_NEAR(b.minCoeff(), best_min, 1e-9) << p;
    // Barycentrics reproduce p.
    const Complex q = b[0] * tris[f][0] + b[1] * tris[f][1] + b[2] * tris[f][2];
    EXPECT_LT(std::abs(q - p), 1e-9);
  }
  // Without the refinement the corner cells held ~2000 triangles each.
  EXPECT_LE(longest, 200u);
  EXPECT_LT(static_cast<double>(total) / samples, 40.0);
  // Outside the triangles: nothing.
  Eigen::Vector3d b;
  EXPECT_EQ(grid.locate(Complex(1.5, 0.5), &b), -1);
  EXPECT_TRUE(grid.candidates(Complex(-0.5, 0.5)).empty());
}

}  // namespace
}  // namespace surfmap
