#include "surfmap/map/coarse_source.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include <Eigen/Geometry>

#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"
#include "certify_helpers.h"

namespace surfmap {
namespace {

// The coarse copy is a closed surface of the same genus whose vertices are
// source vertices, with fine paths that really join the ends of every coarse
// edge and region trees that really lead to every fine vertex.
void expect_valid_coarse_copy(const TriMesh& fine, int target) {
  const Connectivity fc(fine.F, fine.num_vertices());
  CoarseSourceOptions o;
  o.target_vertices = target;
  const CoarseSource cs = coarse_source(fine, fc, o);
  ASSERT_TRUE(cs.ok) << cs.why;
  const int nc = cs.mesh.num_vertices();
  EXPECT_GE(nc, target);
  EXPECT_LE(nc, 2 * target);
  const Connectivity cc(cs.mesh.F, nc);  // throws unless closed, manifold, oriented
  EXPECT_EQ(cc.genus(), fc.genus());
  ASSERT_EQ(static_cast<int>(cs.fine_vertex.size()), nc);
  std::set<int> distinct(cs.fine_vertex.begin(), cs.fine_vertex.end());
  EXPECT_EQ(static_cast<int>(distinct.size()), nc);
  for (int c = 0; c < nc; ++c) {
    EXPECT_EQ(cs.mesh.V.row(c), fine.V.row(cs.fine_vertex[c]));
    EXPECT_EQ(cs.region[cs.fine_vertex[c]], c);
    EXPECT_EQ(cs.parent_halfedge[cs.fine_vertex[c]], -1);
  }
  // Orientation kept: the coarse normals agree with the fine normals around
  // their vertices (signed volume of the same sign).
  auto volume = [](const TriMesh& m) {
    double v = 0;
    for (int f = 0; f < m.num_faces(); ++f)
    {
      const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
      v += a.dot(b.cross(c));
    }
    return v / 6;
  };
  EXPECT_GT(volume(cs.mesh) * volume(fine), 0);
  EXPECT_NEAR(volume(cs.mesh), volume(fine), 0.1 * std::abs(volume(fine)));
  ASSERT_EQ(static_cast<int>(cs.edge_path.size()), cc.num_edges());
  for (int e = 0; e < cc.num_edges(); ++e) {
    const int h = cc.edge_halfedge(e);
    const std::vector<int>& p = cs.edge_path[e];
    ASSERT_FALSE(p.empty());
    EXPECT_EQ(fc.tail(p.front()), cs.fine_vertex[cc.tail(h)]);
    EXPECT_EQ(fc.head(p.back()), cs.fine_vertex[cc.head(h)]);
    for (size_t k = 1; k < p.size(); ++k) EXPECT_EQ(fc.head(p[k - 1]), fc.tail(p[k]));
  }
  for (int v = 0; v < fine.num_vertices(); v += 7) {
    const std::vector<int> p = path_from_region_centre(cs, fc, v);
    int at = cs.fine_vertex[cs.region[v]];
    for (int h : p) {
      EXPECT_EQ(fc.tail(h), at);
      EXPECT_EQ(cs.region[fc.head(h)], cs.region[v]);
      at = fc.head(h);
    }
    EXPECT_EQ(at, v);
  }
}

TEST(CoarseSource, GenusTwoCleanAndSliverCopiesAreValid) {
  expect_valid_coarse_copy(samples::n_hole_torus(2, 40, true), 1000);
  expect_valid_coarse_copy(samples::n_hole_torus(2, 40, false), 1000);  // slivers
}

TEST(CoarseSource, GenusFiveJitteredCopyIsValid) {
  expect_valid_coarse_copy(samples::jitter(samples::n_hole_torus(5, 40, true), 0.2, 3), 1500);
}

TEST(CoarseSource, TooSmallASourceIsRefusedWithAReason) {
  const TriMesh m = samples::n_hole_torus(2, 16, true);
  const Connectivity fc(m.F, m.num_vertices());
  CoarseSourceOptions o;
  o.target_vertices = m.num_vertices();
  const CoarseSource cs = coarse_source(m, fc, o);
  EXPECT_FALSE(cs.ok);
  EXPECT_FALSE(cs.why.empty());
}

// The ranking on the coarse copy (map/hyperbolic_map.cpp) against the
// exhaustive one: every usable class solved at full resolution
// (homotopy.full_solves = 0). The default must pick the same class with the
// same optimum while solving at most two classes at full resolution, and the
// coarse estimates must be close enough to the full-resolution energies for
// the 10% margin to be a real safety factor (measured on the chosen classes:
// within 4%).
void expect_coarse_ranking_matches_exhaustive(const TriMesh& a, const TriMesh& b) {
  SurfaceMapOptions all;
  all.homotopy.full_solves = 0;
  const SurfaceMapResult ex = surface_map(a, b, all);
  const SurfaceMapResult m = surface_map(a, b);
  ASSERT_EQ(m.candidates.size(), ex.candidates.size());
  EXPECT_EQ(m.chosen_candidate, ex.chosen_candidate);
  EXPECT_NEAR(m.final_energy, ex.final_energy, 1e-6 * ex.final_energy);
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_CERTIFIED_MAP(a, b, m);
  int solved = 0, compared = 0, skipped = 0;
  for (size_t k = 0; k < m.candidates.size(); ++k) {
    const HomotopyCandidate &c = m.candidates[k], &e = ex.candidates[k];
    solved += c.solved;
    if (!e.solved) continue;
    const size_t twin_at = c.description.find("[not ranked: the same class as candidate ");
    if (twin_at != std::string::npos) {
      // Issue 19: not solved as an earlier candidate's class up to an
      // isometry of the target. Its exhaustive optimum is that class's.
      const int twin = std::stoi(c.description.substr(twin_at + std::string("[not ranked: the same class as candidate ").size()));
      ASSERT_LT(twin, static_cast<int>(k)) << c.description;
      EXPECT_FALSE(c.solved);
      EXPECT_TRUE(std::isinf(c.energy)) << c.description;
      ASSERT_TRUE(ex.candidates[twin].solved) << c.description;
      EXPECT_NEAR(e.energy, ex.candidates[twin].energy, 1e-6 * e.energy) << c.description;
      ++skipped;
      continue;
    }
    if (c.description.find("[not ranked:") != std::string::npos) {
      // Issue 19 (HomotopyOptions::ranking_gap): not solved on the coarse
      // copy because it could not win. Its exhaustive optimum is indeed above
      // the chosen class's, and its curve bound below that optimum.
      EXPECT_FALSE(c.solved);
      EXPECT_TRUE(std::isinf(c.energy)) << c.description;
      EXPECT_GT(e.energy, ex.final_energy * (1 + 1e-4)) << c.description;
      EXPECT_LE(c.class_curve_bound, e.energy) << c.description;
      ++skipped;
      continue;
    }
    ASSERT_TRUE(std::isfinite(c.coarse_energy)) << c.description;
    // The chosen class's estimate is close; other classes' estimates may be
    // too high (a Newton solve from the all-at-origin start of a twisted
    // class can stop at a folded point: vase -> jittered torus, class 2,
    // 101.7 on the coarse copy and 102.0 at full resolution from the origin,
    // 81.9 from its prolonged coarse solution), never much too low.
    if (static_cast<int>(k) == ex.chosen_candidate) EXPECT_NEAR(c.coarse_energy, e.energy, 0.05 * e.energy) << c.description;
    EXPECT_GT(c.coarse_energy, 0.95 * e.energy) << c.description;
    if (c.solved) EXPECT_NEAR(c.energy, e.energy, 1e-6 * e.energy) << c.description;
    else EXPECT_DOUBLE_EQ(c.energy, c.coarse_energy);  // an unsolved class shows its estimate
    ++compared;
  }
  EXPECT_GE(compared, 1);
  EXPECT_GE(compared + skipped, 2);
  EXPECT_LE(skipped, m.ranking_skipped);
  EXPECT_LE(solved, 2);
  EXPECT_GE(solved, 1);
}

TEST(CoarseRanking, SliverSourcePicksTheClassOfTheExhaustiveRanking) {
  expect_coarse_ranking_matches_exhaustive(samples::n_hole_torus(2, 30, false), samples::vase(30, true));
}

TEST(CoarseRanking, VaseToJitteredTorusPicksTheClassOfTheExhaustiveRanking) {
  expect_coarse_ranking_matches_exhaustive(samples::vase(30, true), samples::jitter(samples::n_hole_torus(2, 30, true), 0.2, 3));
}

// Issue 19: on a genus-2 pair every class has a twin, its composite with the
// hyperelliptic involution (an isometry of every genus-2 surface); the
// ranking does not solve the later of two classes with one fingerprint. The
// skipped class, solved at full resolution on request, must have its
// twin's energy (the isometry carries one class's harmonic maps onto the
// other's), and the chosen class must be the one every class's solve picks.
TEST(CoarseRanking, IsometricTwinIsNotSolvedAndHasItsTwinsEnergy) {
  const TriMesh a = samples::n_hole_torus(2, 32, true), b = samples::vase(32, true);
  const SurfaceMapResult m = surface_map(a, b);
  const std::string tag = "[not ranked: the same class as candidate ";
  int k = -1, twin = -1;
  for (size_t q = 0; q < m.candidates.size() && k < 0; ++q) {
    const size_t at = m.candidates[q].description.find(tag);
    if (at == std::string::npos) continue;
    k = static_cast<int>(q);
    twin = std::stoi(m.candidates[q].description.substr(at + tag.size()));
  }
  ASSERT_GE(k, 0) << "no class skipped as an isometric twin";
  ASSERT_LT(twin, k);
  EXPECT_FALSE(m.candidates[k].solved);
  EXPECT_TRUE(std::isinf(m.candidates[k].energy));
  EXPECT_NE(m.ranking_status.find("up to an isometry of the target"), std::string::npos) << m.ranking_status;
  SurfaceMapOptions ok, otwin;
  // (By their words: an index names a class only within one run's list.)
  ok.homotopy.class_words = m.candidates[k].words;
  otwin.homotopy.class_words = m.candidates[twin].words;
  const SurfaceMapResult mk = surface_map(a, b, ok), mt = surface_map(a, b, otwin);
  ASSERT_TRUE(mk.converged && mt.converged);
  EXPECT_NEAR(mk.final_energy, mt.final_energy, 1e-8 * mt.final_energy);
  // Both above (or at) the chosen class's optimum, which the pair reaches
  // without solving the twin.
  EXPECT_GE(mk.final_energy, m.final_energy * (1 - 1e-9));
  EXPECT_EQ(m.flipped_triangles, 0);
}

}  // namespace
}  // namespace surfmap
