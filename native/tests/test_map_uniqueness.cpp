// Uniqueness across different cuts (docs/method.md §3): the
// harmonic energy is strictly convex in a homotopy class, so the optimal map
// must not depend on where the systems of loops are rooted. Different base
// vertices give different loops, different canonical schemata, different
// candidate lists and different deck data on every edge; only the map itself
// has to come out the same, vertex by vertex.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"
#include "certify_helpers.h"

namespace surfmap {
namespace {

double bbox_diagonal(const TriMesh& m) { return (m.V.colwise().maxCoeff() - m.V.colwise().minCoeff()).norm(); }

// A non-conformal deformation (anisotropic stretch) of a jittered, remeshed
// copy: the optimum is not the identity, but its class is unambiguous (no
// symmetric ties between candidates).
TriMesh stretched(const TriMesh& mesh, double sx, double sz) {
  TriMesh out = mesh;
  out.V.col(0) *= sx;
  out.V.col(2) *= sz;
  return out;
}

// Farthest vertex from vertex 0 in 3D: a base vertex on the other side of the
// shape, so the two systems of loops share nothing.
int far_vertex(const TriMesh& mesh) {
  int best = 0;
  double d = -1;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    const double dv = (mesh.V.row(v) - mesh.V.row(0)).norm();
    if (dv > d) d = dv, best = v;
  }
  return best;
}

void expect_same_map_from_different_cuts(const TriMesh& a, const TriMesh& b) {
  SurfaceMapOptions o1, o2;
  o1.loops.source_base_vertex = 0;
  o1.loops.target_base_vertex = 0;
  o2.loops.source_base_vertex = far_vertex(a);
  o2.loops.target_base_vertex = far_vertex(b);
  const SurfaceMapResult m1 = surface_map(a, b, o1), m2 = surface_map(a, b, o2);
  ASSERT_TRUE(m1.converged);
  ASSERT_TRUE(m2.converged);
  EXPECT_EQ(m1.flipped_triangles, 0);
  EXPECT_EQ(m2.flipped_triangles, 0);
  EXPECT_CERTIFIED_MAP(a, b, m1);
  EXPECT_CERTIFIED_MAP(a, b, m2);
  // The target's loops are refined (edges split where loops meet), so each
  // cut uniformizes a slightly different triangulation of the target: the
  // optima agree to discretisation (measured ~2e-6..7e-6 relative), not to
  // round-off as two starts on the same cut do.
  EXPECT_NEAR(m1.final_energy, m2.final_energy, 1e-4 * m1.final_energy);
  const double tol = 1e-3 * bbox_diagonal(b);
  double worst = 0;
  for (int i = 0; i < a.num_vertices(); ++i)
    worst = std::max(worst, (m1.forward[i].position - m2.forward[i].position).norm());
  EXPECT_LT(worst, tol) << "forward maps from two cuts differ by " << worst / bbox_diagonal(b)
                        << " of the target's diagonal";
  // The inverse maps too (each target vertex located in the source).
  const double tol_a = 1e-3 * bbox_diagonal(a);
  double worst_inv = 0;
  for (int j = 0; j < b.num_vertices(); ++j)
    worst_inv = std::max(worst_inv, (m1.inverse[j].position - m2.inverse[j].position).norm());
  EXPECT_LT(worst_inv, tol_a);
  std::printf("forward maps from two cuts: worst %.2e, inverse %.2e of the diagonal; energies %.9g / %.9g\n",
              worst / bbox_diagonal(b), worst_inv / bbox_diagonal(a), m1.final_energy, m2.final_energy);
}

TEST(MapUniqueness, GenusTwoStretchedCopyFromDifferentBaseVertices) {
  const TriMesh a = samples::n_hole_torus(2, 24, true);
  const TriMesh b = stretched(samples::jitter(samples::n_hole_torus(2, 28, true), 0.15, 3), 1.25, 1.6);
  expect_same_map_from_different_cuts(a, b);
}

TEST(MapUniqueness, GenusThreeSliverSourceFromDifferentBaseVertices) {
  // Raw marching-tetrahedra source (slivers, obtuse triangles).
  const TriMesh a = samples::n_hole_torus(3, 22, false);
  const TriMesh b = stretched(samples::jitter(samples::n_hole_torus(3, 26, true), 0.1, 9), 0.8, 1.4);
  expect_same_map_from_different_cuts(a, b);
}

}  // namespace
}  // namespace surfmap

namespace surfmap {
namespace {

// Raw marching-tetrahedra sources (slivers, needles, obtuse triangles) of
// genus 4 and 5 onto jittered smooth copies: zero flipped image triangles,
// converged, every forward point on the target. (Genus 5 used to take more
// than 5 minutes in the handle classes' word arithmetic.)
TEST(MapSlivers, GenusFourAndFiveSliverSourcesHaveNoFlips) {
  for (int g : {4, 5}) {
    const TriMesh a = samples::n_hole_torus(g, 22, false);
    const TriMesh b = samples::jitter(samples::n_hole_torus(g, 26, true), 0.1, g);
    const SurfaceMapResult m = surface_map(a, b);
    EXPECT_TRUE(m.converged) << "genus " << g;
    EXPECT_EQ(m.flipped_triangles, 0) << "genus " << g;
    EXPECT_EQ(m.degenerate_triangles, 0) << "genus " << g;
    EXPECT_CERTIFIED_MAP(a, b, m);
    EXPECT_LT(m.mean_dilatation, 1.5) << "genus " << g;
    for (const auto& p : m.forward) {
      ASSERT_GE(p.face, 0);
      Eigen::Vector3d q = Eigen::Vector3d::Zero();
      for (int k = 0; k < 3; ++k) q += p.barycentric[k] * b.V.row(b.F(p.face, k)).transpose();
      EXPECT_LT((q - p.position).norm(), 1e-6);
    }
  }
}

}  // namespace
}  // namespace surfmap
