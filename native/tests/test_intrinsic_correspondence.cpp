// Points of the flip-based metric carried back to the input faces
// (uniformize/intrinsic_correspondence.h, docs/uniformization.md), and maps
// onto targets whose fixed-connectivity metric does not exist, computed on
// the flipped triangulation and delivered on the user's own faces.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "certify_helpers.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/uniformize/intrinsic_correspondence.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {
namespace {

Eigen::Vector3d position(const TriMesh& m, const FacePoint& p) {
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) q += p.barycentric[k] * m.V.row(m.F(p.face, k)).transpose();
  return q;
}

double diagonal(const TriMesh& m) { return (m.V.colwise().maxCoeff() - m.V.colwise().minCoeff()).norm(); }

// The flow with its own curvatures as targets: u = 0 is the solution, so the
// only flips are the exact (metric-preserving) flips of the input metric.
RicciFlowResult exact_flips_only(const TriMesh& m) {
  const Connectivity c(m.F, m.num_vertices());
  const Eigen::VectorXd l = edge_lengths(m, c);
  const Eigen::VectorXd K =
      ricci_linearization(c, l, Background::Euclidean, RicciScheme::VertexScaling, Eigen::VectorXd::Zero(m.num_vertices()))
          .curvature;
  RicciFlowOptions o;
  o.intrinsic_delaunay = true;
  return ricci_flow(c, l, Background::Euclidean, o, K);
}

// Without flips, and with u = 0, the correspondence is the identity.
TEST(IntrinsicCorrespondence, IdentityWithoutFlips) {
  const TriMesh m = samples::sphere(2);  // a regular subdivided icosahedron: Delaunay
  const RicciFlowResult flow = exact_flips_only(m);
  ASSERT_TRUE(flow.converged) << flow.message;
  ASSERT_EQ(flow.flips, 0);
  EXPECT_LT(flow.u.cwiseAbs().maxCoeff(), 1e-12);
  const IntrinsicCorrespondence corr(flow);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (int f = 0; f < m.num_faces(); ++f) {
    Eigen::Vector3d b(U(rng), U(rng), U(rng));
    b /= b.sum();
    const FacePoint p = corr.to_input(f, b);
    EXPECT_EQ(p.face, f);
    EXPECT_LT((p.barycentric - b).cwiseAbs().maxCoeff(), 1e-12);
    const FacePoint q = corr.undo_flips(f, b);
    EXPECT_EQ(q.face, f);
    EXPECT_LT((q.barycentric - b).cwiseAbs().maxCoeff(), 1e-15);
  }
}

// One flip of a quad of explicit vectors in R^{2,1} (slots k, s, m, t =
// vertices 0..3): null vectors for a Ptolemy flip, hyperboloid points for an
// exact hyperbolic flip. A point of a new triangle, taken at the final
// metric's scale u (vectors e^{u_i} v_i, the vertex scaling
// l = e^{(u_i+u_j)/2} l⁰), must come back as old-triangle weights c with
// Σ c_i v_i on the same ray, c >= 0.
double minkowski(const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return -a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

void expect_rays_kept(bool hyperboloid, const Eigen::Vector4d& u) {
  const double theta[4] = {0.3, 1.9, 2.6, 4.4}, r[4] = {0.7, 1.3, 0.4, 2.1};
  Eigen::Vector3d v[4];
  for (int i = 0; i < 4; ++i)
    v[i] = hyperboloid ? Eigen::Vector3d(std::cosh(r[i]), std::sinh(r[i]) * std::cos(theta[i]), std::sinh(r[i]) * std::sin(theta[i]))
                       : Eigen::Vector3d(r[i], r[i] * std::cos(theta[i]), r[i] * std::sin(theta[i]));
  auto chord = [&](int i, int j) { return std::sqrt(minkowski(v[i] - v[j], v[i] - v[j])); };
  RicciFlowResult fr;
  fr.background = hyperboloid ? Background::Hyperbolic : Background::Euclidean;
  fr.faces.resize(2, 3);
  fr.faces << 0, 1, 2, 2, 3, 0;  // after: (k, s, m), (m, t, k)
  fr.u = u;
  EdgeFlip fl;
  fl.face0 = 0, fl.face1 = 1, fl.corner0 = 1, fl.corner1 = 2;  // before: rows (t, k, s), (t, s, m)
  fl.base_lengths = {chord(0, 1), chord(1, 2), chord(2, 3), chord(3, 0), chord(1, 3), chord(0, 2)};
  fl.exact = hyperboloid;
  fr.flip_history = {fl};
  fr.flips = 1;
  if (!hyperboloid)  // Ptolemy: the new diagonal of four null vectors
    EXPECT_NEAR(fl.base_lengths[5] * fl.base_lengths[4],
                fl.base_lengths[0] * fl.base_lengths[2] + fl.base_lengths[1] * fl.base_lengths[3], 1e-12);
  const int old_rows[2][3] = {{3, 0, 1}, {3, 1, 2}};
  const IntrinsicCorrespondence corr(fr);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int in_old[2] = {0, 0};
  for (int trial = 0; trial < 200; ++trial) {
    const int f = trial % 2;
    Eigen::Vector3d b(U(rng), U(rng), U(rng));
    b /= b.sum();
    Eigen::Vector3d ray = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      const int i = fr.faces(f, k);
      ray += b[k] * (hyperboloid ? v[i] : Eigen::Vector3d(std::exp(u[i]) * v[i]));
    }
    const FacePoint p = corr.to_input(f, b);
    ASSERT_TRUE(p.face == 0 || p.face == 1);
    ++in_old[p.face];
    Eigen::Vector3d back = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) back += p.barycentric[k] * v[old_rows[p.face][k]];
    EXPECT_LT((back / back[0] - ray / ray[0]).norm(), 1e-12) << "trial " << trial;
  }
  EXPECT_GT(in_old[0], 0);  // both old triangles are reached
  EXPECT_GT(in_old[1], 0);
}

TEST(IntrinsicCorrespondence, PtolemyFlipKeepsRaysOfNullVectors) {
  expect_rays_kept(false, Eigen::Vector4d::Zero());
  expect_rays_kept(false, Eigen::Vector4d(0.4, -1.2, 2.0, 0.3));
}

TEST(IntrinsicCorrespondence, ExactHyperbolicFlipKeepsPointsOfTheHyperboloid) {
  expect_rays_kept(true, Eigen::Vector4d::Zero());
}

// Exact flips on the planar fans of a CAD plate: an intrinsic triangle whose
// corners lie on one face plane of the plate, with its 3D chords as its
// lengths, is that 3D triangle, so a point of it must come back to the same
// 3D point on the input faces.
TEST(IntrinsicCorrespondence, ExactFlipsKeepPointsInPlaceOnPlanarFaces) {
  const TriMesh m = samples::cad_plate(2, 32, 0.1);
  const RicciFlowResult flow = exact_flips_only(m);
  ASSERT_TRUE(flow.converged) << flow.message;
  ASSERT_GT(flow.flips, 50);  // the fans are far from Delaunay
  EXPECT_LT(flow.u.cwiseAbs().maxCoeff(), 1e-9);
  const IntrinsicCorrespondence corr(flow);
  const double tol = 1e-9 * diagonal(m);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int checked = 0, moved = 0;
  for (int f = 0; f < flow.faces.rows(); ++f) {
    Eigen::Vector3d X[3];
    for (int k = 0; k < 3; ++k) X[k] = m.V.row(flow.faces(f, k)).transpose();
    if (std::abs(X[0].z() - X[1].z()) > 0 || std::abs(X[0].z() - X[2].z()) > 0) continue;
    bool straight = true;
    for (int k = 0; k < 3; ++k) {
      const double chord = (X[(k + 1) % 3] - X[(k + 2) % 3]).norm();
      straight = straight && std::abs(flow.edge_lengths[flow.face_edges(f, k)] - chord) <= 1e-12 * chord;
    }
    if (!straight) continue;
    for (int trial = 0; trial < 4; ++trial) {
      Eigen::Vector3d b(U(rng), U(rng), U(rng));
      b /= b.sum();
      const FacePoint p = corr.to_input(f, b);
      ASSERT_GE(p.face, 0);
      EXPECT_GE(p.barycentric.minCoeff(), 0.0);
      EXPECT_NEAR(p.barycentric.sum(), 1.0, 1e-12);
      const Eigen::Vector3d want = b[0] * X[0] + b[1] * X[1] + b[2] * X[2];
      EXPECT_LT((position(m, p) - want).norm(), tol) << "face " << f;
      moved += p.face != f;
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
  EXPECT_GT(moved, 10);  // the points really crossed flips
}

// Continuity and vertices after Ptolemy flips and a non-trivial u (hyperbolic
// and flat flows on meshes far from Delaunay): a point on an edge of T'
// comes back to the same input point from both faces, and a corner of T'
// comes back to its input vertex.
void expect_continuous(const TriMesh& m, Background bg) {
  const Connectivity c(m.F, m.num_vertices());
  RicciFlowOptions o;
  o.intrinsic_delaunay = true;
  const RicciFlowResult flow = ricci_flow(c, edge_lengths(m, c), bg, o);
  ASSERT_TRUE(flow.converged) << flow.message;
  ASSERT_GT(flow.flips, 20);
  EXPECT_GT(flow.u.cwiseAbs().maxCoeff(), 0.1);
  const IntrinsicCorrespondence corr(flow);
  const double tol = 1e-8 * diagonal(m);
  // The two (face, side) of every edge of T' (face_edges: T' need not be simplicial).
  std::vector<std::vector<std::pair<int, int>>> sides(flow.edge_vertices.rows());
  for (int f = 0; f < flow.faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) sides[flow.face_edges(f, k)].push_back({f, k});
  int edges = 0;
  for (const auto& es : sides) {
    ASSERT_EQ(es.size(), 2u);
    const auto [f0, k0] = es[0];
    const auto [f1, k1] = es[1];
    // Side k joins corners k+1 -> k+2; the other face runs it the other way.
    const int a = flow.faces(f0, (k0 + 1) % 3);
    ASSERT_EQ(flow.faces(f1, (k1 + 2) % 3), a);
    for (double s : {0.0, 0.3, 0.5, 0.9}) {
      Eigen::Vector3d b0 = Eigen::Vector3d::Zero(), b1 = Eigen::Vector3d::Zero();
      b0[(k0 + 1) % 3] = 1 - s, b0[(k0 + 2) % 3] = s;
      b1[(k1 + 2) % 3] = 1 - s, b1[(k1 + 1) % 3] = s;
      const Eigen::Vector3d p0 = position(m, corr.to_input(f0, b0)), p1 = position(m, corr.to_input(f1, b1));
      EXPECT_LT((p0 - p1).norm(), tol) << "edge at faces " << f0 << ", " << f1 << ", s = " << s;
      if (s == 0.0) EXPECT_LT((p0 - m.V.row(a).transpose()).norm(), tol) << "vertex " << a;
    }
    ++edges;
  }
  EXPECT_EQ(edges, flow.edge_vertices.rows());
}

TEST(IntrinsicCorrespondence, ContinuousAcrossEdgesHyperbolic) {
  expect_continuous(samples::cad_plate(2, 32, 0.1), Background::Hyperbolic);
}

TEST(IntrinsicCorrespondence, ContinuousAcrossEdgesFlat) {
  expect_continuous(samples::cad_plate(1, 32, 0.5), Background::Euclidean);
}

// Every located point is on the user's target: its face, barycentrics >= 0
// summing to 1, and the 3D position they give.
void expect_on_users_mesh(const TriMesh& t, const std::vector<PointOnSurface>& points) {
  for (const auto& p : points) {
    ASSERT_GE(p.face, 0);
    ASSERT_LT(p.face, t.num_faces());
    EXPECT_GE(p.barycentric.minCoeff(), 0.0);
    EXPECT_NEAR(p.barycentric.sum(), 1, 1e-12);
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) q += p.barycentric[k] * t.V.row(t.F(p.face, k)).transpose();
    EXPECT_LT((q - p.position).norm(), 1e-9);
  }
}

// A genus-3 target with flat caps whose fixed-connectivity metric does not
// exist (it needs exact refinement: test_exact_refinement.cpp) maps through
// the flip-based metric: no refinement, flips counted, a certified bijection
// on the user's own faces.
TEST(IntrinsicTargetMap, TargetWithoutFixedMetricMapsOnItsOwnFaces) {
  const TriMesh s = samples::n_hole_torus(3, 32, true);
  const TriMesh t = samples::n_hole_torus(3, 32, false);
  SurfaceMapOptions o;
  o.homotopy.candidates = 1;  // the overlay class (more candidates cost minutes at genus 3)
  o.uniformization.target_metric = UniformizationMetric::IntrinsicDelaunay;
  o.initial.locate = true;  // (initial_forward checked below)
  const SurfaceMapResult m = surface_map(s, t, o);
  EXPECT_TRUE(m.converged);
  EXPECT_EQ(m.target_metric, "intrinsic Delaunay");
  EXPECT_EQ(m.target_metric_choice, "requested");
  EXPECT_GT(m.target_flips, 0);
  EXPECT_EQ(m.target_refinement_splits, 0);
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_EQ(m.degenerate_triangles, 0);
  ASSERT_EQ(static_cast<int>(m.forward.size()), s.num_vertices());
  expect_on_users_mesh(t, m.forward);
  expect_on_users_mesh(t, m.initial_forward);
  EXPECT_CERTIFIED_MAP(s, t, m);
}

// The default (automatic) target metric is the flip path, with results
// identical to requesting it; the fixed-connectivity metric with its exact
// refinement stays available on request (docs/uniformization.md "Which
// target metric runs").
TEST(IntrinsicTargetMap, AutomaticMetricIsTheFlipPath) {
  const TriMesh s = samples::n_hole_torus(3, 32, true);
  const TriMesh t = samples::n_hole_torus(3, 32, false);
  SurfaceMapOptions o;
  o.homotopy.candidates = 1;
  ASSERT_EQ(o.uniformization.target_metric, UniformizationMetric::Automatic);
  const SurfaceMapResult automatic = surface_map(s, t, o);
  o.uniformization.target_metric = UniformizationMetric::IntrinsicDelaunay;
  const SurfaceMapResult flips = surface_map(s, t, o);
  o.uniformization.target_metric = UniformizationMetric::FixedConnectivity;
  const SurfaceMapResult fixed = surface_map(s, t, o);
  EXPECT_EQ(automatic.target_metric, "intrinsic Delaunay");
  EXPECT_EQ(automatic.target_metric_choice, "automatic: the flip-based metric");
  EXPECT_EQ(automatic.target_class_loops.rfind("the target's own loops", 0), 0u) << automatic.target_class_loops;
  EXPECT_EQ(flips.target_metric_choice, "requested");
  EXPECT_EQ(fixed.target_metric_choice, "requested");
  EXPECT_GT(automatic.target_flips, 0);
  EXPECT_EQ(automatic.target_refinement_splits, 0);
  EXPECT_EQ(automatic.target_flips, flips.target_flips);
  EXPECT_EQ(automatic.final_energy, flips.final_energy);
  ASSERT_EQ(automatic.forward.size(), flips.forward.size());
  for (size_t v = 0; v < flips.forward.size(); ++v) {
    EXPECT_EQ(automatic.forward[v].face, flips.forward[v].face);
    EXPECT_EQ(automatic.forward[v].position, flips.forward[v].position);
  }
  // The fixed path on request: refined exactly (this target has no
  // unrefined metric), and the same conformal structure, so the same
  // extremal energy up to discretization.
  EXPECT_EQ(fixed.target_flips, 0);
  EXPECT_GT(fixed.target_refinement_splits, 0);
  EXPECT_TRUE(fixed.converged);
  EXPECT_NEAR(automatic.final_energy / fixed.final_energy, 1.0, 0.02);
}

// Genus 1: a CAD block with one hole (long fans of slivers) as the target.
TEST(IntrinsicTargetMap, FlatCadTargetMapsOnItsOwnFaces) {
  const TriMesh s = samples::torus_of_revolution(2.0, 0.8, 40, 20);
  const TriMesh t = samples::cad_plate(1, 32, 0.5);
  SurfaceMapOptions o;
  o.uniformization.target_metric = UniformizationMetric::IntrinsicDelaunay;  // the flip path, requested
  const SurfaceMapResult m = surface_map(s, t, o);
  EXPECT_TRUE(m.converged);
  EXPECT_EQ(m.target_metric, "intrinsic Delaunay");
  EXPECT_GT(m.target_flips, 0);
  EXPECT_EQ(m.target_refinement_splits, 0);
  EXPECT_EQ(m.flipped_triangles, 0);
  expect_on_users_mesh(t, m.forward);
  EXPECT_CERTIFIED_MAP(s, t, m);
}

// The named policy for callers measured on the fixed metric: fixed-first
// runs the fixed connectivity whenever it can be delivered (here it exists),
// giving exactly the requested fixed path's map, reported as such.
TEST(IntrinsicTargetMap, FixedFirstIsTheFixedPathWhenItExists) {
  const TriMesh s = samples::torus_of_revolution(2.0, 0.8, 32, 16);
  const TriMesh t = samples::torus_of_revolution(3.0, 1.0, 28, 14);
  SurfaceMapOptions o;
  o.uniformization.target_metric = UniformizationMetric::FixedConnectivity;
  const SurfaceMapResult fixed = surface_map(s, t, o);
  o.uniformization.target_metric = UniformizationMetric::FixedFirst;
  const SurfaceMapResult first = surface_map(s, t, o);
  EXPECT_EQ(first.target_metric, "fixed connectivity");
  EXPECT_EQ(first.target_metric_choice, "fixed first: the fixed-connectivity metric");
  EXPECT_EQ(first.target_flips, 0);
  EXPECT_EQ(first.final_energy, fixed.final_energy);
  ASSERT_EQ(first.forward.size(), fixed.forward.size());
  for (size_t v = 0; v < first.forward.size(); ++v) EXPECT_EQ(first.forward[v].position, fixed.forward[v].position);
}

}  // namespace
}  // namespace surfmap
