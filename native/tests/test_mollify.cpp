// Intrinsic mollification (geometry/mollify.h) and the acceptance of
// degenerate faces through it (intake, the solvers' edge lengths).
#include "surfmap/geometry/mollify.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/distortion.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/uniformize/ricci_flow.h"
#include "surfmap/uniformize/uniformize.h"

namespace surfmap {
namespace {

Eigen::VectorXd euclidean_lengths(const TriMesh& m, const Connectivity& c) {
  Eigen::VectorXd l(c.num_edges());
  for (int e = 0; e < c.num_edges(); ++e) l[e] = (m.V.row(c.edge_vertex(e, 0)) - m.V.row(c.edge_vertex(e, 1))).norm();
  return l;
}

double min_face_margin(const Eigen::VectorXd& l, const Connectivity& c, int* below = nullptr, double delta = 0) {
  double worst = INFINITY;
  for (int f = 0; f < c.num_faces(); ++f) {
    const double a = l[c.edge(3 * f)], b = l[c.edge(3 * f + 1)], d = l[c.edge(3 * f + 2)];
    const double m = std::min({a + b - d, b + d - a, a + d - b});
    if (below && m < delta) ++*below;
    worst = std::min(worst, m);
  }
  return worst;
}

TEST(Mollify, WellShapedMeshIsUnchanged) {
  const TriMesh m = samples::torus_of_revolution(1.0, 0.4, 24, 12);
  const Connectivity c(m.F, m.num_vertices());
  const Eigen::VectorXd l = euclidean_lengths(m, c);
  const MollifyResult r = mollify_edge_lengths(l, c);
  EXPECT_EQ(r.epsilon, 0.0);
  EXPECT_EQ(r.faces_touched, 0);
  EXPECT_EQ((r.lengths - l).cwiseAbs().maxCoeff(), 0.0);
}

class DegenerateTorus : public ::testing::TestWithParam<double> {};

TEST_P(DegenerateTorus, EveryFaceGetsTheMarginWithTheSmallestEpsilon) {
  const double t = GetParam();  // 0: coincident vertices, 0.5: collinear
  const TriMesh m = samples::insert_degenerate_faces(samples::torus_of_revolution(1.0, 0.4, 24, 12), 20, t, 7);
  const Connectivity c(m.F, m.num_vertices());
  const Eigen::VectorXd l = euclidean_lengths(m, c);
  const double rel = 1e-4, delta0 = rel * l.mean();
  int below = 0;
  EXPECT_LE(min_face_margin(l, c, &below, delta0), 1e-12);  // really degenerate
  const MollifyResult r = mollify_edge_lengths(l, c, rel);
  EXPECT_EQ(r.faces_touched, below);
  EXPECT_GE(r.faces_touched, 20);  // at least the inserted faces
  // Uniform shift, margin reached against the mollified mean...
  EXPECT_NEAR((r.lengths - l).maxCoeff(), r.epsilon, 1e-15);
  EXPECT_NEAR((r.lengths - l).minCoeff(), r.epsilon, 1e-15);
  EXPECT_GE(min_face_margin(r.lengths, c), rel * r.lengths.mean() * (1 - 1e-9));
  // ...and nothing smaller would do: 1% less epsilon misses it.
  const Eigen::VectorXd less = l.array() + 0.99 * r.epsilon;
  EXPECT_LT(min_face_margin(less, c), rel * less.mean());
  // Idempotent: mollifying again changes nothing.
  const MollifyResult again = mollify_edge_lengths(r.lengths, c, rel);
  EXPECT_EQ(again.epsilon, 0.0);
  EXPECT_EQ(again.faces_touched, 0);
  // The solvers' lengths are the mollified ones, and the intrinsic Delaunay
  // triangulation of them has finite, non-negative weights.
  EXPECT_LE((edge_lengths(m, c) - r.lengths).cwiseAbs().maxCoeff(), 0.0);
  const IntrinsicDelaunayResult idt = intrinsic_delaunay(c, r.lengths);
  EXPECT_TRUE(idt.delaunay);
  for (const auto& e : idt.edges) EXPECT_TRUE(std::isfinite(e.cot_weight));
}

INSTANTIATE_TEST_SUITE_P(CoincidentAndCollinear, DegenerateTorus, ::testing::Values(0.0, 0.5));

TEST(Mollify, BadLengthsNameTheEdge) {
  const TriMesh m = samples::torus_of_revolution(1.0, 0.4, 8, 6);
  const Connectivity c(m.F, m.num_vertices());
  Eigen::VectorXd l = euclidean_lengths(m, c);
  l[5] = NAN;
  try {
    mollify_edge_lengths(l, c);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("edge 5"), std::string::npos) << e.what();
  }
  EXPECT_THROW(mollify_edge_lengths(l.head(3), c), InputError);
  EXPECT_THROW(mollify_edge_lengths(euclidean_lengths(m, c), c, 0.7), InputError);
}

TEST(Mollify, IntakeAcceptsZeroAreaFacesWithANote) {
  const TriMesh m = samples::insert_degenerate_faces(samples::torus_of_revolution(1.0, 0.4, 24, 12), 5, 0.5, 3);
  const IntakeResult r = intake(m.V, m.F);
  EXPECT_TRUE(r.info.valid);
  EXPECT_EQ(r.info.genus, 1);
  EXPECT_GE(r.info.zero_area_faces, 5);
  EXPECT_GE(r.info.mollified_faces, 5);
  EXPECT_GT(r.info.mollify_epsilon, 0.0);
  ASSERT_FALSE(r.info.notes.empty());
  EXPECT_EQ(r.info.notes.back().rfind("mollified: ", 0), 0u) << r.info.notes.back();
  // What intake reports is what the solvers use.
  const Connectivity c(r.mesh.F, r.mesh.num_vertices());
  const MollifyResult mr = mollify_edge_lengths(euclidean_lengths(r.mesh, c), c);
  EXPECT_EQ(mr.faces_touched, r.info.mollified_faces);
  EXPECT_DOUBLE_EQ(mr.epsilon, r.info.mollify_epsilon);
}

TEST(Mollify, FlatMetricOfExactlyDegenerateTorusExists) {
  // A torus with zero-area faces (coincident vertices: zero-length edges)
  // has mollified lengths that are a valid metric, so the flip-based Ricci
  // flow finds its flat metric: curvature 0 at every vertex, the total angle
  // defect (Gauss-Bonnet, 2 pi chi = 0) checked independently of the solver.
  const TriMesh m =
      samples::insert_degenerate_faces(samples::torus_of_revolution(1.0, 0.4, 32, 16), 12, 0.0, 11);
  const Connectivity c(m.F, m.num_vertices());
  const Eigen::VectorXd raw = euclidean_lengths(m, c);
  EXPECT_EQ(raw.minCoeff(), 0.0);  // really degenerate input
  RicciFlowOptions opt;
  opt.intrinsic_delaunay = true;
  const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Euclidean, opt);
  ASSERT_TRUE(r.converged) << r.message;
  std::vector<double> angle_sum(m.num_vertices(), 0.0);
  for (int f = 0; f < r.faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const double a = r.edge_lengths[r.face_edges(f, k)], b = r.edge_lengths[r.face_edges(f, (k + 1) % 3)],
                   d = r.edge_lengths[r.face_edges(f, (k + 2) % 3)];
      angle_sum[r.faces(f, k)] += std::acos(std::clamp((b * b + d * d - a * a) / (2 * b * d), -1.0, 1.0));
    }
  for (int v = 0; v < m.num_vertices(); ++v) EXPECT_NEAR(angle_sum[v], 2 * M_PI, 1e-7) << "vertex " << v;
}

TEST(Mollify, CoincidentVerticesOnlyAreRefused) {
  TriMesh m = samples::torus_of_revolution(1.0, 0.4, 8, 6);
  m.V.setZero();
  try {
    intake(m.V, m.F);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("same position"), std::string::npos) << e.what();
  }
}

TEST(Distortion, ZeroAreaSourceFacesAreLeftOutOfMeanAndMax) {
  // The identity map of a planar strip with one collinear (0 area) and one
  // coincident-corner face: D' = 1 on the others, the two are counted apart.
  RowMatrixX3d V(5, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0.5, 0, 0, 1, 0, 0;
  RowMatrixX3i F(3, 3);
  F << 0, 1, 2, 0, 3, 1, 1, 4, 2;  // (0, 0.5, 1) collinear; corners 1 and 4 coincide
  Eigen::Matrix<std::complex<double>, Eigen::Dynamic, 3, Eigen::RowMajor> img(3, 3);
  for (int f = 0; f < 3; ++f)
    for (int k = 0; k < 3; ++k) img(f, k) = {V(F(f, k), 0), V(F(f, k), 1)};
  img(1, 1) += std::complex<double>(0, 0.1);  // images of the flat faces are proper triangles
  img(2, 1) += std::complex<double>(0.1, 0.1);
  const DistortionStats q = planar_distortion(V, F, img);
  EXPECT_EQ(q.degenerate_source, 2);
  EXPECT_NEAR(q.mean, 1.0, 1e-12);
  EXPECT_NEAR(q.max, 1.0, 1e-12);
  EXPECT_TRUE(std::isinf(q.per_face[1]) && std::isinf(q.per_face[2]));
}

TEST(Shapes, CadPlateAndPeanutAreClosedWithTheirGenus) {
  for (int holes : {1, 3}) {
    const TriMesh m = samples::cad_plate(holes, 32, holes == 1 ? 1.5 : 0.1);
    const IntakeResult r = intake(m.V, m.F);
    EXPECT_EQ(r.info.genus, holes);
    EXPECT_FALSE(r.flipped);
    EXPECT_EQ(m.num_vertices(), 4 * (holes + 1) + 2 * holes * 32);
  }
  const IntakeResult p = intake(samples::peanut(32, false).V, samples::peanut(32, false).F);
  EXPECT_EQ(p.info.genus, 0);
  EXPECT_THROW(samples::cad_plate(0), InputError);
  EXPECT_THROW(samples::cad_plate(2, 30), InputError);
}

}  // namespace
}  // namespace surfmap
