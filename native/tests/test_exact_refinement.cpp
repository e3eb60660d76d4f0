// Exact refinement of infeasible targets (mesh/exact_refinement.h,
// uniformize/feasible_metric.h) and maps onto such targets.
#include "surfmap/mesh/exact_refinement.h"

#include <gtest/gtest.h>

#include <cmath>

#include <Eigen/Geometry>

#include "surfmap/error.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/feasible_metric.h"
#include "surfmap/uniformize/uniformize.h"
#include "certify_helpers.h"
#include "sliver_caps.h"

namespace surfmap {
namespace {

double face_area(const TriMesh& m, int f) {
  const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
  return 0.5 * (b - a).cross(c - a).norm();
}

double max_angle_deg(const TriMesh& m) {
  double best = 0;
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = m.V.row(m.F(f, k)), q = m.V.row(m.F(f, (k + 1) % 3)), r = m.V.row(m.F(f, (k + 2) % 3));
      best = std::max(best, std::atan2((q - p).cross(r - p).norm(), (q - p).dot(r - p)) * 180 / M_PI);
    }
  return best;
}

TEST(ExactRefinement, RefinedMeshIsTheSameSurfaceFaceByFace) {
  const TriMesh in = testing_support::with_caps(samples::n_hole_torus(2, 32, true), 7, 0.01);
  ASSERT_GT(max_angle_deg(in), 170);
  ExactRefinementOptions o;
  o.max_angle_deg = 150;
  const ExactRefinementResult r = refine_obtuse_triangles(in, o);
  EXPECT_GT(r.splits, 0);
  EXPECT_EQ(r.obtuse_after, 0);
  EXPECT_LE(max_angle_deg(r.mesh), 150 + 1e-9);
  EXPECT_EQ(Connectivity(r.mesh.F, r.mesh.num_vertices()).genus(), Connectivity(in.F, in.num_vertices()).genus());
  const double scale = (in.V.colwise().maxCoeff() - in.V.colwise().minCoeff()).norm();
  ASSERT_EQ(r.mesh.V.topRows(in.num_vertices()), in.V);  // input vertices first, unmoved
  // Every refined vertex is its origin face's barycentric combination.
  for (int v = 0; v < r.mesh.num_vertices(); ++v) {
    const int f = r.origin_face[v];
    ASSERT_GE(f, 0);
    EXPECT_GE(r.origin_barycentric.row(v).minCoeff(), 0);
    EXPECT_NEAR(r.origin_barycentric.row(v).sum(), 1, 1e-12);
    Eigen::RowVector3d q = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k) q += r.origin_barycentric(v, k) * in.V.row(in.F(f, k));
    EXPECT_LT((q - r.mesh.V.row(v)).norm(), 1e-12 * scale) << "vertex " << v;
  }
  // Every refined face lies in its origin face (corners on its plane, inside
  // it), and the pieces of each input face tile it: areas add up exactly.
  std::vector<double> area(in.num_faces(), 0);
  for (int f = 0; f < r.mesh.num_faces(); ++f) {
    const int o = r.face_origin[f];
    const Eigen::Vector3d p0 = in.V.row(in.F(o, 0)), p1 = in.V.row(in.F(o, 1)), p2 = in.V.row(in.F(o, 2));
    const Eigen::Vector3d n = (p1 - p0).cross(p2 - p0);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = r.mesh.V.row(r.mesh.F(f, k));
      EXPECT_LT(std::abs((p - p0).dot(n.normalized())), 1e-12 * scale);
      const Eigen::Vector3d b = Eigen::Vector3d((p1 - p).cross(p2 - p).dot(n), (p2 - p).cross(p0 - p).dot(n),
                                                (p0 - p).cross(p1 - p).dot(n)) / n.squaredNorm();
      EXPECT_GE(b.minCoeff(), -1e-9) << "refined face " << f << " leaves input face " << o;
    }
    area[o] += face_area(r.mesh, f);
  }
  for (int f = 0; f < in.num_faces(); ++f) EXPECT_NEAR(area[f], face_area(in, f), 1e-9 * face_area(in, f)) << f;
}

// Raw marching tetrahedra (genus 3): the fixed-connectivity hyperbolic
// metric does not exist; after the exact refinement it does, the loops
// still cut a disk and the layout glues (uniformize checks it).
TEST(ExactRefinement, InfeasibleSliverTargetGetsAHyperbolicMetric) {
  const TriMesh m = samples::n_hole_torus(3, 32, false);
  const SystemOfLoops loops = system_of_loops(m);
  FeasibleMetricOptions plain;
  plain.refine_max_angles.clear();
  EXPECT_FALSE(feasible_metric(m, loops, Background::Hyperbolic, plain).flow.converged);
  const FeasibleMetricResult fm = feasible_metric(m, loops, Background::Hyperbolic);
  ASSERT_TRUE(fm.flow.converged) << fm.flow.message;
  EXPECT_GT(fm.refinement_splits, 0);
  EXPECT_FALSE(fm.unrefined_failure.empty());
  // Origins stay exact on the input through both refinements.
  const double scale = (m.V.colwise().maxCoeff() - m.V.colwise().minCoeff()).norm();
  const TriMesh& rm = fm.loops.mesh;
  ASSERT_EQ(rm.V.topRows(m.num_vertices()), m.V);
  for (int v = 0; v < rm.num_vertices(); ++v) {
    Eigen::RowVector3d q = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k) q += fm.loops.origin_barycentric(v, k) * m.V.row(m.F(fm.loops.origin_face[v], k));
    EXPECT_LT((q - rm.V.row(v)).norm(), 1e-12 * scale) << "vertex " << v;
  }
  // Every refined face lies in its recorded input face.
  ASSERT_EQ(static_cast<int>(fm.loops.face_origin.size()), rm.num_faces());
  for (int f = 0; f < rm.num_faces(); ++f) {
    const int o = fm.loops.face_origin[f];
    const Eigen::Vector3d p0 = m.V.row(m.F(o, 0)), p1 = m.V.row(m.F(o, 1)), p2 = m.V.row(m.F(o, 2));
    const Eigen::Vector3d n = (p1 - p0).cross(p2 - p0);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = rm.V.row(rm.F(f, k));
      EXPECT_LT(std::abs((p - p0).dot(n.normalized())), 1e-12 * scale);
      const Eigen::Vector3d b = Eigen::Vector3d((p1 - p).cross(p2 - p).dot(n), (p2 - p).cross(p0 - p).dot(n),
                                                (p0 - p).cross(p1 - p).dot(n)) / n.squaredNorm();
      EXPECT_GE(b.minCoeff(), -1e-9) << "refined face " << f << " leaves input face " << o;
    }
  }
  EXPECT_EQ(Connectivity(rm.F, rm.num_vertices()).genus(), 3);
  UniformizeOptions fixed;
  fixed.metric = UniformizationMetric::FixedConnectivity;
  fixed.fixed_connectivity_refinement = true;
  const UniformizeResult u = uniformize(m, fixed);
  EXPECT_TRUE(u.converged);
  EXPECT_GT(u.refinement_splits, 0);
  EXPECT_EQ(u.layout.num_flipped, 0);
  EXPECT_NEAR(u.area, 4 * M_PI * 2, 1e-6);  // 4π(g − 1)
}

// The failure of a metric is a type, not a message: on that target the
// fixed-connectivity metric without refinement throws UniformizationError
// (which callers catch to try another metric); fixed-first then runs the
// flip path and says so, with the flip path's own area 4π(g − 1).
TEST(ExactRefinement, MissingFixedMetricIsAUniformizationErrorAndFixedFirstRunsFlips) {
  const TriMesh m = samples::n_hole_torus(3, 32, false);
  UniformizeOptions fixed;
  fixed.metric = UniformizationMetric::FixedConnectivity;
  EXPECT_THROW(uniformize(m, fixed), UniformizationError);
  try {
    uniformize(m, fixed);
  } catch (const SolveError& e) {  // still a SolveError for callers that catch that
    EXPECT_NE(dynamic_cast<const UniformizationError*>(&e), nullptr);
  }
  UniformizeOptions fixed_first;
  fixed_first.metric = UniformizationMetric::FixedFirst;
  const UniformizeResult u = uniformize(m, fixed_first);
  EXPECT_TRUE(u.converged);
  EXPECT_EQ(u.metric.rfind("intrinsic Delaunay (fixed connectivity failed: uniformize: Ricci flow", 0), 0u) << u.metric;
  EXPECT_GT(u.edge_flips, 0);
  EXPECT_EQ(u.refinement_splits, 0);
  EXPECT_NEAR(u.area, 4 * M_PI * 2, 1e-6);
}

// A map onto that target: no flips, and every forward point is on the
// user's (unrefined) target: face index and barycentrics of its own faces.
TEST(ExactRefinement, MapOntoAnInfeasibleTargetStaysOnTheUsersMesh) {
  const TriMesh s = samples::n_hole_torus(3, 32, true);
  const TriMesh t = samples::n_hole_torus(3, 32, false);
  SurfaceMapOptions o;
  o.homotopy.candidates = 1;  // the overlay class (more candidates cost minutes at genus 3 in the twist reduction)
  o.uniformization.target_metric = UniformizationMetric::FixedConnectivity;  // the refinement path (an option; the default runs flips)
  const SurfaceMapResult m = surface_map(s, t, o);
  EXPECT_EQ(m.target_metric, "fixed connectivity");
  EXPECT_EQ(m.target_flips, 0);
  EXPECT_GT(m.target_refinement_splits, 0);
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_EQ(m.degenerate_triangles, 0);
  // Unflipped in the domain, but the caps' needle triangles have thin, bent
  // images: 140 of 13676 chord triangles fold in R^3 (docs/verification.md).
  EXPECT_CERTIFIED_MAP_UP_TO_CHORD_FOLDS(s, t, m, 0.03);
  ASSERT_EQ(static_cast<int>(m.forward.size()), s.num_vertices());
  ASSERT_EQ(static_cast<int>(m.inverse.size()), t.num_vertices());
  for (const auto& p : m.forward) {
    ASSERT_GE(p.face, 0);
    ASSERT_LT(p.face, t.num_faces());
    EXPECT_GE(p.barycentric.minCoeff(), -1e-12);
    EXPECT_NEAR(p.barycentric.sum(), 1, 1e-12);
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) q += p.barycentric[k] * t.V.row(t.F(p.face, k)).transpose();
    EXPECT_LT((q - p.position).norm(), 1e-9);
  }
  for (const auto& p : m.inverse) {
    ASSERT_GE(p.face, 0);
    ASSERT_LT(p.face, s.num_faces());
  }
  EXPECT_LT(m.mean_dilatation, 3);
}

}  // namespace
}  // namespace surfmap

namespace surfmap {
namespace {

// A source with caps (CAD-like): the intrinsic Delaunay weights embed its
// intrinsic triangulation, but straight images of its own caps fold; the
// automatic fallback solves with positive weights on its own edges, which
// embed the user's faces (Tutte-type theorem).
TEST(SourceWeights, FoldingSourceFallsBackToPositiveOwnEdgeWeights) {
  const TriMesh s = testing_support::with_caps(samples::n_hole_torus(2, 32, true), 5, 0.002);
  const TriMesh t = samples::amphora(36, true);
  SurfaceMapOptions o;
  o.homotopy.candidates = 1;
  o.solve.source_weights = SourceWeights::IntrinsicDelaunay;
  try {
    surface_map(s, t, o);
    ADD_FAILURE() << "the fixture should fold with the intrinsic weights";
  } catch (const SolveError& e) {
    EXPECT_NE(std::string(e.what()).find("flipped"), std::string::npos) << e.what();
  }
  o.solve.source_weights = SourceWeights::Automatic;
  // The global fallback itself (the local repair first is FoldRepair.*).
  o.solve.local_fold_repair = false;
  const SurfaceMapResult m = surface_map(s, t, o);
  EXPECT_EQ(m.source_weights, "positive on the source's own edges");
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_EQ(m.degenerate_triangles, 0);
  // Unflipped in the domain, but the caps' needle triangles have thin, bent
  // images: 140 of 13676 chord triangles fold in R^3 (docs/verification.md).
  EXPECT_CERTIFIED_MAP_UP_TO_CHORD_FOLDS(s, t, m, 0.03);
  ASSERT_EQ(static_cast<int>(m.forward.size()), s.num_vertices());
  for (double d : m.dilatation) EXPECT_TRUE(std::isfinite(d));
  // The same as asking for the own-edge weights directly.
  o.solve.source_weights = SourceWeights::OwnEdges;
  const SurfaceMapResult m2 = surface_map(s, t, o);
  // Same weights, same convex problem: equal optima to the solve tolerance
  // (other weights differ by percents).
  EXPECT_NEAR(m2.final_energy, m.final_energy, 1e-7 * m.final_energy);
  EXPECT_NEAR(m2.mean_dilatation, m.mean_dilatation, 1e-6);
}

// On a clean mesh the automatic choice keeps the intrinsic weights.
TEST(SourceWeights, CleanSourceKeepsIntrinsicDelaunayWeights) {
  const TriMesh s = samples::n_hole_torus(2, 32, true);
  const TriMesh t = samples::amphora(36, true);
  SurfaceMapOptions o;
  o.homotopy.candidates = 1;
  const SurfaceMapResult m = surface_map(s, t, o);
  EXPECT_EQ(m.source_weights, "intrinsic Delaunay cotangent");
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_CERTIFIED_MAP(s, t, m);
}

}  // namespace
}  // namespace surfmap
