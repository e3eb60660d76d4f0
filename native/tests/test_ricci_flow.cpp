// Tests of the discrete Ricci flow (uniformize/ricci_flow.h): derivatives by
// finite differences, flat tori, hyperbolic metrics of genus 2..6 checked
// against Gauss–Bonnet with an independent law-of-cosines computation, ugly
// (jittered, sliver) meshes, flow vs Newton, and honest failure reports.
#include "surfmap/uniformize/ricci_flow.h"

#include <cmath>
#include <array>
#include <map>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <limits>

#include "surfmap/error.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/mesh/connectivity.h"
#include "holed_plate.h"

namespace surfmap {
namespace {

constexpr double kPi = 3.14159265358979323846;

// ---- local shape generators (independent of samples/) ----------------------

TriMesh torus(double R, double r, int n, int m) {
  TriMesh t;
  t.V.resize(n * m, 3);
  t.F.resize(2 * n * m, 3);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double a = 2 * kPi * i / n, b = 2 * kPi * j / m;
      t.V.row(i * m + j) << (R + r * std::cos(b)) * std::cos(a), (R + r * std::cos(b)) * std::sin(a),
          r * std::sin(b);
      const int v00 = i * m + j, v10 = ((i + 1) % n) * m + j, v01 = i * m + (j + 1) % m,
                v11 = ((i + 1) % n) * m + (j + 1) % m;
      t.F.row(2 * (i * m + j)) << v00, v10, v11;
      t.F.row(2 * (i * m + j) + 1) << v00, v11, v01;
    }
  return t;
}

using testing_support::holed_plate;

// Random 3D displacement of every vertex by up to `amp` (absolute): obtuse
// triangles and, for large amp, slivers. Lengths stay a valid metric as long
// as no triangle becomes exactly flat.
TriMesh jitter3d(TriMesh t, double amp, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-amp, amp);
  for (int v = 0; v < t.V.rows(); ++v)
    for (int k = 0; k < 3; ++k) t.V(v, k) += U(rng);
  return t;
}

// ---- independent metric checks ----------------------------------------------

// Angle at the corner between sides a and b, opposite side c.
double corner_angle(double a, double b, double c, Background bg) {
  double cs;
  if (bg == Background::Euclidean)
    cs = (a * a + b * b - c * c) / (2 * a * b);
  else
    cs = (std::cosh(a) * std::cosh(b) - std::cosh(c)) / (std::sinh(a) * std::sinh(b));
  return std::acos(std::max(-1.0, std::min(1.0, cs)));
}

struct AngleCheck {
  Eigen::VectorXd angle_sum;  // per vertex
  double area = 0;            // hyperbolic: Σ (π − angle sum of the triangle)
  double min_angle = 10;
};

AngleCheck check_angles(const Connectivity& c, const Eigen::VectorXd& l, Background bg) {
  AngleCheck out;
  out.angle_sum = Eigen::VectorXd::Zero(c.num_vertices());
  for (int f = 0; f < c.num_faces(); ++f) {
    double tsum = 0;
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * f + k;  // corner at tail(h): sides h and prev(h), opposite next(h)
      const double a = l[c.edge(h)], b = l[c.edge(Connectivity::prev(h))],
                   cc = l[c.edge(Connectivity::next(h))];
      EXPECT_LT(cc, a + b) << "face " << f << " violates the triangle inequality";
      const double th = corner_angle(a, b, cc, bg);
      out.angle_sum[c.tail(h)] += th;
      out.min_angle = std::min(out.min_angle, th);
      tsum += th;
    }
    out.area += kPi - tsum;
  }
  return out;
}

Eigen::VectorXd curvature_fd(const Connectivity& c, const Eigen::VectorXd& l, Background bg,
                             RicciScheme s, const Eigen::VectorXd& u) {
  return ricci_linearization(c, l, bg, s, u).curvature;
}

// ---- tests --------------------------------------------------------------------

TEST(RicciFlow, JacobianMatchesFiniteDifferencesAndIsSymmetric) {
  const TriMesh meshes[2] = {jitter3d(torus(3, 1, 10, 7), 0.05, 1), jitter3d(holed_plate(2, 2), 0.04, 2)};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-0.15, 0.15);
  for (const TriMesh& m : meshes) {
    Connectivity c(m.F);
    const Eigen::VectorXd l = edge_lengths(m, c);
    for (Background bg : {Background::Euclidean, Background::Hyperbolic})
      for (RicciScheme s : {RicciScheme::VertexScaling, RicciScheme::InversiveDistance}) {
        SCOPED_TRACE(::testing::Message() << "bg " << int(bg) << " scheme " << int(s));
        Eigen::VectorXd u(c.num_vertices());
        for (int i = 0; i < u.size(); ++i) u[i] = U(rng);
        const RicciLinearization lin = ricci_linearization(c, l, bg, s, u);
        ASSERT_EQ(lin.degenerate_faces, 0);
        const Eigen::MatrixXd J = Eigen::MatrixXd(lin.jacobian);
        EXPECT_LT((J - J.transpose()).cwiseAbs().maxCoeff(), 1e-9 * (1 + J.cwiseAbs().maxCoeff()));
        const double h = 1e-6;
        double worst = 0, scale = J.cwiseAbs().maxCoeff();
        for (int w = 0; w < c.num_vertices(); w += 5) {
          Eigen::VectorXd up = u, um = u;
          up[w] += h;
          um[w] -= h;
          const Eigen::VectorXd fd =
              (curvature_fd(c, l, bg, s, up) - curvature_fd(c, l, bg, s, um)) / (2 * h);
          worst = std::max(worst, (fd - J.col(w)).cwiseAbs().maxCoeff());
        }
        EXPECT_LT(worst, 1e-6 * (1 + scale));
        // Gauss–Bonnet holds for any metric; flat Jacobian kills constants.
        if (bg == Background::Euclidean) {
          EXPECT_NEAR(lin.curvature.sum(), 2 * kPi * c.euler_characteristic(), 1e-9);
          EXPECT_LT((J * Eigen::VectorXd::Ones(u.size())).cwiseAbs().maxCoeff(), 1e-9);
        }
      }
  }
}

TEST(RicciFlow, EuclideanVertexScalingJacobianIsHalfCotanLaplacian) {
  const TriMesh m = jitter3d(torus(3, 1, 9, 6), 0.1, 3);
  Connectivity c(m.F);
  const RicciLinearization lin = ricci_linearization(
      c, edge_lengths(m, c), Background::Euclidean, RicciScheme::VertexScaling,
      Eigen::VectorXd::Zero(c.num_vertices()));
  const Eigen::MatrixXd J(lin.jacobian);
  for (int e = 0; e < c.num_edges(); ++e) {
    const int h = c.edge_halfedge(e);
    double w = 0;
    for (int hh : {h, c.twin(h)}) {  // cot of the corner opposite hh, from 3D positions
      const Eigen::RowVector3d p = m.V.row(c.opposite_vertex(hh)), a = m.V.row(c.tail(hh)),
                               b = m.V.row(c.head(hh));
      const Eigen::Vector3d x = (a - p).transpose(), y = (b - p).transpose();
      w += x.dot(y) / x.cross(y).norm();
    }
    EXPECT_NEAR(J(c.edge_vertex(e, 0), c.edge_vertex(e, 1)), -w / 2, 1e-10);
  }
}

void expect_flat(const Connectivity& c, const RicciFlowResult& r, double tol) {
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_LT(r.max_curvature_error, tol);
  ASSERT_TRUE(r.u.allFinite());
  ASSERT_TRUE(r.edge_lengths.allFinite());
  const AngleCheck a = check_angles(c, r.edge_lengths, Background::Euclidean);
  EXPECT_LT((a.angle_sum.array() - 2 * kPi).abs().maxCoeff(), tol);
  EXPECT_NEAR(a.angle_sum.sum(), 2 * kPi * c.num_vertices(), 1e-8);  // = π #F on a torus
  EXPECT_GT(a.min_angle, 0);
}

TEST(RicciFlow, TorusBecomesFlat) {
  const TriMesh m = torus(3, 1, 40, 20);
  Connectivity c(m.F);
  const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Euclidean);
  expect_flat(c, r, 1e-9);
  EXPECT_LE(r.iterations, 15);
  EXPECT_EQ(r.u[0], 0.0);  // gauge
  // Residuals decrease monotonically (line search) and fast at the end.
  for (size_t i = 1; i < r.residual_history.size(); ++i)
    EXPECT_LE(r.residual_history[i], r.residual_history[i - 1] * 1.5);
  // On a torus of revolution the flat metric is rotationally symmetric: u
  // depends only on the minor angle (ring j), so all rings agree.
  for (int i = 1; i < 40; ++i)
    for (int j = 0; j < 20; ++j) EXPECT_NEAR(r.u[i * 20 + j], r.u[j], 1e-7);
}

TEST(RicciFlow, JitteredToriBecomeFlat) {
  for (double amp : {0.05, 0.1}) {  // grid spacing ~0.47 major, ~0.31 minor
    SCOPED_TRACE(amp);
    const TriMesh m = jitter3d(torus(3, 1, 40, 20), amp, 11);
    Connectivity c(m.F);
    const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Euclidean);
    expect_flat(c, r, 1e-9);
  }
}

TEST(RicciFlow, SliverMeshEitherFlatOrHonestFailure) {
  // Crumpled slivers: with this fixed triangulation the minimiser of the
  // extended energy may have degenerate triangles (no flat metric exists
  // without edge flips). Then the result must say so, naming a face, and
  // contain no NaNs; a success must be a genuinely flat metric.
  int failures = 0;
  for (unsigned seed : {11u, 12u, 13u}) {
    const TriMesh m = jitter3d(torus(3, 1, 40, 20), 0.3, seed);
    Connectivity c(m.F);
    const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Euclidean);
    EXPECT_TRUE(r.u.allFinite());
    EXPECT_TRUE(r.edge_lengths.allFinite());
    if (r.converged) {
      expect_flat(c, r, 1e-9);
    } else {
      ++failures;
      EXPECT_NE(r.message.find("face"), std::string::npos) << r.message;
      // Honest: the named face really is degenerate in the returned lengths
      // (no triangle-inequality slack beyond round-off of its longest side).
      int face = -1;
      ASSERT_EQ(std::sscanf(r.message.c_str(), "face %d", &face), 1) << r.message;
      ASSERT_GE(face, 0);
      ASSERT_LT(face, r.face_edges.rows());
      double l[3], slack = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) l[k] = r.edge_lengths(r.face_edges(face, k));
      for (int k = 0; k < 3; ++k) slack = std::min(slack, l[(k + 1) % 3] + l[(k + 2) % 3] - l[k]);
      EXPECT_LE(slack, 1e-9 * std::max({l[0], l[1], l[2]})) << r.message;
    }
  }
  RecordProperty("failures", failures);
  // The fixture must exercise the failure path (measured: all three seeds end
  // with a degenerate face on this fixed triangulation); a seed that converges
  // is checked flat above.
  EXPECT_GT(failures, 0);
}

TEST(RicciFlow, InversiveDistanceTorusBecomesFlat) {
  const TriMesh m = torus(3, 1, 30, 15);
  Connectivity c(m.F);
  RicciFlowOptions o;
  o.scheme = RicciScheme::InversiveDistance;
  const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Euclidean, o);
  expect_flat(c, r, 1e-9);
}

void expect_hyperbolic(const Connectivity& c, const RicciFlowResult& r, int max_it) {
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_LT(r.max_curvature_error, 1e-9);
  EXPECT_LE(r.iterations, max_it);
  const AngleCheck a = check_angles(c, r.edge_lengths, Background::Hyperbolic);
  EXPECT_LT((a.angle_sum.array() - 2 * kPi).abs().maxCoeff(), 1e-9);
  const int g = c.genus();
  EXPECT_NEAR(a.area / (4 * kPi * (g - 1)), 1.0, 1e-6);
}

TEST(RicciFlow, HyperbolicGaussBonnetGenus2To6) {
  for (int g = 2; g <= 6; ++g) {
    SCOPED_TRACE(g);
    const TriMesh m = holed_plate(g, g <= 3 ? 4 : 2);
    Connectivity c(m.F);
    ASSERT_EQ(c.genus(), g);
    const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Hyperbolic);
    expect_hyperbolic(c, r, 30);
  }
}

TEST(RicciFlow, HyperbolicOnJitteredSliverMesh) {
  const TriMesh m = jitter3d(holed_plate(3, 4), 0.1, 5);  // cell size 0.25: heavy distortion
  Connectivity c(m.F);
  const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Hyperbolic);
  expect_hyperbolic(c, r, 30);
}

TEST(RicciFlow, HyperbolicInversiveDistance) {
  const TriMesh m = holed_plate(2, 3);
  Connectivity c(m.F);
  RicciFlowOptions o;
  o.scheme = RicciScheme::InversiveDistance;
  const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Hyperbolic, o);
  expect_hyperbolic(c, r, 50);
}

TEST(RicciFlow, FlowAndNewtonReachTheSameMetric) {
  {
    const TriMesh m = jitter3d(torus(3, 1, 12, 8), 0.05, 4);
    Connectivity c(m.F);
    const Eigen::VectorXd l = edge_lengths(m, c);
    RicciFlowOptions o;
    o.method = RicciMethod::GradientFlow;
    o.tolerance = 1e-11;
    const RicciFlowResult rf = ricci_flow(c, l, Background::Euclidean, o);
    const RicciFlowResult rn = ricci_flow(c, l, Background::Euclidean);
    ASSERT_TRUE(rf.converged) << rf.message;
    ASSERT_TRUE(rn.converged) << rn.message;
    EXPECT_GT(rf.iterations, 5 * rn.iterations);
    const Eigen::VectorXd du = (rf.u.array() - rf.u.mean()) - (rn.u.array() - rn.u.mean());
    EXPECT_LT(du.cwiseAbs().maxCoeff(), 1e-8);
  }
  {
    const TriMesh m = holed_plate(2, 2);
    Connectivity c(m.F);
    const Eigen::VectorXd l = edge_lengths(m, c);
    RicciFlowOptions o;
    o.method = RicciMethod::GradientFlow;
    o.tolerance = 1e-11;
    const RicciFlowResult rf = ricci_flow(c, l, Background::Hyperbolic, o);
    const RicciFlowResult rn = ricci_flow(c, l, Background::Hyperbolic);
    ASSERT_TRUE(rf.converged) << rf.message;
    ASSERT_TRUE(rn.converged) << rn.message;
    EXPECT_LT((rf.u - rn.u).cwiseAbs().maxCoeff(), 1e-8);
  }
}

TEST(RicciFlow, PrescribedConeCurvature) {
  // A torus with one cone of +π/2 and one of −π/2: still flat elsewhere.
  const TriMesh m = torus(3, 1, 24, 12);
  Connectivity c(m.F);
  Eigen::VectorXd target = Eigen::VectorXd::Zero(c.num_vertices());
  target[5] = kPi / 2;
  target[150] = -kPi / 2;
  const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Euclidean, {}, target);
  ASSERT_TRUE(r.converged) << r.message;
  const AngleCheck a = check_angles(c, r.edge_lengths, Background::Euclidean);
  for (int v = 0; v < c.num_vertices(); ++v)
    EXPECT_NEAR(2 * kPi - a.angle_sum[v], target[v], 1e-9) << "vertex " << v;
}

TEST(RicciFlow, InfeasibleTargetIsReportedNotFaked) {
  // Angle sums cannot be negative, so K = 2π + 1 at a vertex is unreachable.
  const TriMesh m = torus(3, 1, 16, 8);
  Connectivity c(m.F);
  Eigen::VectorXd target = Eigen::VectorXd::Zero(c.num_vertices());
  target[0] = 2 * kPi + 1;
  target[40] = -(2 * kPi + 1);
  RicciFlowOptions o;
  o.max_iterations = 60;
  const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Euclidean, o, target);
  EXPECT_FALSE(r.converged);
  EXPECT_FALSE(r.message.empty());
  EXPECT_TRUE(r.message.find("face") != std::string::npos ||
              r.message.find("vertex") != std::string::npos)
      << r.message;
  EXPECT_TRUE(r.u.allFinite());
  EXPECT_TRUE(r.edge_lengths.allFinite());
  EXPECT_GT(r.max_curvature_error, 0.5);
}

TEST(RicciFlow, InputErrorsAndCancel) {
  const TriMesh m = torus(3, 1, 10, 6);
  Connectivity c(m.F);
  const Eigen::VectorXd l = edge_lengths(m, c);
  // Gauss–Bonnet violated for a flat target; no hyperbolic metric on a torus.
  EXPECT_THROW(ricci_flow(c, l, Background::Euclidean, {}, Eigen::VectorXd::Ones(c.num_vertices())),
               InputError);
  EXPECT_THROW(ricci_flow(c, l, Background::Hyperbolic), InputError);
  Eigen::VectorXd bad = l;
  bad[3] = -1;
  EXPECT_THROW(ricci_flow(c, bad, Background::Euclidean), InputError);
  EXPECT_THROW(ricci_flow(c, l.head(5), Background::Euclidean), InputError);
  RicciFlowOptions o;
  o.progress = [](int it, double) { return it < 1; };
  EXPECT_THROW(ricci_flow(c, l, Background::Euclidean, o), Cancelled);
}

}  // namespace
}  // namespace surfmap

namespace surfmap {
namespace {

// Angle sums per vertex on the triangulation the result lives on
// (faces / face_edges: side opposite corner k), from the law of cosines.
Eigen::VectorXd angle_sums_on_result(const RicciFlowResult& r, int nv) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(nv);
  for (int f = 0; f < r.faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const double a = r.edge_lengths[r.face_edges(f, k)],  // opposite corner k
          b = r.edge_lengths[r.face_edges(f, (k + 1) % 3)], c = r.edge_lengths[r.face_edges(f, (k + 2) % 3)];
      EXPECT_LT(a, b + c) << "face " << f;
      sum[r.faces(f, k)] += corner_angle(b, c, a, Background::Euclidean);
    }
  return sum;
}

TEST(RicciFlow, WithoutFlipsResultTriangulationIsTheInput) {
  const TriMesh m = torus(3, 1, 12, 8);
  Connectivity c(m.F);
  const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Euclidean);
  ASSERT_TRUE(r.converged);
  EXPECT_EQ(r.flips, 0);
  EXPECT_TRUE(r.faces == m.F);
  EXPECT_TRUE(r.edge_vertices == c.edge_vertices());
  for (int f = 0; f < c.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(r.face_edges(f, k), c.edge(3 * f + (k + 1) % 3));
}

TEST(RicciFlow, IntrinsicDelaunayFlipsMakeSliverToriFlat) {
  // The meshes whose fixed-connectivity solve may degenerate
  // (SliverMeshEitherFlatOrHonestFailure) always get a flat metric with
  // Ptolemy flips (docs/uniformization.md).
  int total_flips = 0;
  for (unsigned seed : {11u, 12u, 13u}) {
    SCOPED_TRACE(seed);
    const TriMesh m = jitter3d(torus(3, 1, 40, 20), 0.3, seed);
    Connectivity c(m.F);
    RicciFlowOptions o;
    o.intrinsic_delaunay = true;
    const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Euclidean, o);
    ASSERT_TRUE(r.converged) << r.message;
    total_flips += r.flips;
    EXPECT_LT(r.max_curvature_error, 1e-9);
    EXPECT_LE(r.iterations, 30);
    const Eigen::VectorXd sums = angle_sums_on_result(r, c.num_vertices());
    EXPECT_LT((sums.array() - 2 * kPi).abs().maxCoeff(), 1e-9);
    // Still a triangulation of the torus: same counts, every edge used twice.
    EXPECT_EQ(r.faces.rows(), c.num_faces());
    std::vector<int> uses(r.edge_vertices.rows(), 0);
    for (int f = 0; f < r.faces.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int e = r.face_edges(f, k);
        ++uses[e];
        const int a = r.faces(f, (k + 1) % 3), b = r.faces(f, (k + 2) % 3);
        EXPECT_EQ(std::min(a, b), r.edge_vertices(e, 0));
        EXPECT_EQ(std::max(a, b), r.edge_vertices(e, 1));
      }
    for (int u : uses) EXPECT_EQ(u, 2);
  }
  EXPECT_GT(total_flips, 0);
}

}  // namespace
}  // namespace surfmap

namespace surfmap {
namespace {

TEST(RicciFlow, IntrinsicDelaunayFlipsHyperbolicSliverMesh) {
  // Heavy 3D jitter of a genus-2/3 plate (cell 0.25, jitter 0.15): slivers and
  // folds. With flips the hyperbolic metric exists and satisfies Gauss–Bonnet
  // on the flipped triangulation (independent hyperbolic law of cosines).
  for (int g : {2, 3}) {
    SCOPED_TRACE(g);
    const TriMesh m = jitter3d(holed_plate(g, 4), 0.15, 20 + g);
    Connectivity c(m.F);
    RicciFlowOptions o;
    o.intrinsic_delaunay = true;
    const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Hyperbolic, o);
    ASSERT_TRUE(r.converged) << r.message;
    EXPECT_LE(r.iterations, 30);
    Eigen::VectorXd sums = Eigen::VectorXd::Zero(c.num_vertices());
    double area = 0;
    for (int f = 0; f < r.faces.rows(); ++f) {
      double tsum = 0;
      for (int k = 0; k < 3; ++k) {
        const double a = r.edge_lengths[r.face_edges(f, k)], b = r.edge_lengths[r.face_edges(f, (k + 1) % 3)],
                     cc = r.edge_lengths[r.face_edges(f, (k + 2) % 3)];
        EXPECT_LT(a, b + cc) << "face " << f;
        const double th = corner_angle(b, cc, a, Background::Hyperbolic);
        sums[r.faces(f, k)] += th;
        tsum += th;
      }
      area += kPi - tsum;
    }
    EXPECT_LT((sums.array() - 2 * kPi).abs().maxCoeff(), 1e-9);
    EXPECT_NEAR(area / (4 * kPi * (g - 1)), 1.0, 1e-6);
  }
}

}  // namespace
}  // namespace surfmap

namespace surfmap {
// Issue 13: extreme hyperbolic targets (cone angle 1e-3 at every vertex of a
// genus-2 mesh) drive the conformal factors past 100, where the flip pass
// used to run on (Delaunay tests of overflowed Penner coordinates are NaN,
// and a NaN test flipped) and the flip history grew without bound. The run
// must end within the flip budget: converged with the Gauss–Bonnet area, or
// a SolveError naming the flips, never exhausted memory.
TEST(RicciFlow, FlipPassesStayWithinTheirBudgetAtExtremeTargets) {
  // Every vertex a cone of angle 0.1 or 1e-3 (near-cusps, hyperbolic sides
  // of 10-20). Before: the first Newton step jumped to where every angle
  // underflows (residual = the cone angles, small; Hessian 0) and stalled
  // there ("line search failed ... error 0.1"), or at 1e-3 the flips ran
  // out of budget. With hyperbolic steps capped (kMaxHyperbolicStep) both
  // converge; the angle sums are checked here with the half-angle formula.
  const TriMesh m = samples::n_hole_torus(2, 16, false);
  const Connectivity conn(m.F, m.num_vertices());
  for (double cone : {1e-1, 1e-3}) {
    SCOPED_TRACE(cone);
    const Eigen::VectorXd target = Eigen::VectorXd::Constant(m.num_vertices(), 2 * M_PI - cone);
    RicciFlowOptions o;
    o.intrinsic_delaunay = true;
    const RicciFlowResult r = ricci_flow(conn, edge_lengths(m, conn), Background::Hyperbolic, o, target);
    EXPECT_LE(r.flips, 50 * (conn.num_edges() + 10));
    EXPECT_LE(static_cast<long long>(r.flip_history.size()), 50LL * (conn.num_edges() + 10));
    ASSERT_TRUE(r.converged) << r.message;
    EXPECT_LE(r.max_curvature_error, 1e-10);
    std::vector<double> angle_sum(m.num_vertices(), 0.0);
    double area = 0;
    for (int f = 0; f < r.faces.rows(); ++f) {
      double l[3];
      for (int k = 0; k < 3; ++k) l[k] = r.edge_lengths[r.face_edges(f, k)];
      const double s = 0.5 * (l[0] + l[1] + l[2]);
      double angles = 0;
      for (int k = 0; k < 3; ++k) {
        const double a = l[k], b = l[(k + 1) % 3], c = l[(k + 2) % 3];
        const double theta = 2 * std::atan(std::sqrt(std::sinh(s - b) * std::sinh(s - c) / (std::sinh(s) * std::sinh(s - a))));
        angle_sum[r.faces(f, k)] += theta;
        angles += theta;
      }
      area += M_PI - angles;
    }
    for (int v = 0; v < m.num_vertices(); ++v) EXPECT_NEAR(angle_sum[v], cone, 2e-10) << "vertex " << v;
    // Gauss-Bonnet with cones: area = sum of curvatures - 2 pi chi (chi = -2).
    EXPECT_NEAR(area, target.sum() + 4 * M_PI, 1e-6 * area);
  }
}

TEST(RicciFlow, LongHyperbolicTrianglesHaveFiniteAnglesAndJacobian) {
  // Hyperbolic sides of ~800: sinh(s) sinh(s - a) overflows, and the
  // half-angle quotients gave NaN angles and Jacobian entries; the long
  // triangle formulas take the products through their logarithms.
  const TriMesh m = samples::n_hole_torus(2, 16, false);
  const Connectivity conn(m.F, m.num_vertices());
  for (double u0 : {150.0, 400.0}) {
    SCOPED_TRACE(u0);
    const Eigen::VectorXd u = Eigen::VectorXd::Constant(m.num_vertices(), u0);
    const RicciLinearization lin = ricci_linearization(conn, edge_lengths(m, conn), Background::Hyperbolic,
                                                       RicciScheme::VertexScaling, u);
    ASSERT_TRUE(lin.edge_lengths.allFinite());
    EXPECT_GT(lin.edge_lengths.minCoeff(), 2 * u0 - 20);
    ASSERT_TRUE(lin.curvature.allFinite());
    // Angles of order exp(-l/2) vanish: every curvature is 2 pi.
    for (int v = 0; v < m.num_vertices(); ++v) EXPECT_NEAR(lin.curvature[v], 2 * M_PI, 1e-12);
    for (int k = 0; k < lin.jacobian.outerSize(); ++k)
      for (Eigen::SparseMatrix<double>::InnerIterator it(lin.jacobian, k); it; ++it)
        ASSERT_TRUE(std::isfinite(it.value())) << it.row() << ", " << it.col();
  }
}
}  // namespace surfmap

#include "surfmap/uniformize/coarse_start.h"

namespace surfmap {
namespace {

// Issue 19: the multilevel start (uniformize/coarse_start.h). From the coarse
// copy's prolonged u, Newton with flips must reach the metric it reaches from
// u = 0 (the same conformal factors within the tolerance's reach, Gauss–Bonnet
// on the flipped triangulation) in fewer Newton steps; a prolongation that
// misplaced the coarse values (wrong regions, wrong vertices) starts further
// away than u = 0 and fails the step count or the distance bound.
/// The coarse start tests' genus-2 n-hole torus (resolution 40, hyperbolic),
/// its flow from u = 0 with flips and its coarse start (~400 coarse vertices).
struct GenusTwoCoarseCase {
  static RicciFlowOptions with_flips() {
    RicciFlowOptions o;
    o.intrinsic_delaunay = true;
    return o;
  }
  static CoarseStartOptions small_copy() {
    CoarseStartOptions so;
    so.coarse_vertices = 400;
    so.min_vertices = 1000;
    return so;
  }
  TriMesh m = samples::n_hole_torus(2, 40, true);
  Connectivity c{m.F, m.num_vertices()};
  Eigen::VectorXd l = edge_lengths(m, c);
  RicciFlowOptions o = with_flips();
  RicciFlowResult zero = ricci_flow(c, l, Background::Hyperbolic, o);
  CoarseStart start = coarse_conformal_start(m, c, Background::Hyperbolic, small_copy());
};

TEST(RicciFlow, CoarseStartReachesTheSameHyperbolicMetricInFewerNewtonSteps) {
  const GenusTwoCoarseCase cs;
  ASSERT_EQ(cs.c.genus(), 2);
  ASSERT_TRUE(cs.zero.converged) << cs.zero.message;
  ASSERT_TRUE(cs.start.ok) << cs.start.why;
  // About the vertices asked for (the seeds' spacing is chosen for them).
  EXPECT_GT(cs.start.coarse_vertices, 200);
  EXPECT_LT(cs.start.coarse_vertices, 1600);
  ASSERT_EQ(cs.start.u.size(), cs.c.num_vertices());
  // The prolonged u is the solution's large-scale part: much nearer to it
  // than u = 0 is.
  const double spread = cs.zero.u.cwiseAbs().maxCoeff();
  ASSERT_GT(spread, 0.1);
  EXPECT_LT((cs.start.u - cs.zero.u).cwiseAbs().maxCoeff(), 0.25 * spread);

  const RicciFlowResult from = ricci_flow_from(cs.c, cs.l, Background::Hyperbolic, cs.o, cs.start.u);
  ASSERT_TRUE(from.converged) << from.message;
  EXPECT_LE(from.max_curvature_error, cs.o.tolerance);
  EXPECT_LT(from.iterations, cs.zero.iterations);
  EXPECT_LT((from.u - cs.zero.u).cwiseAbs().maxCoeff(), 1e-7);
  // Gauss–Bonnet on the flipped triangulation, angles by an independent law of cosines.
  Eigen::VectorXd sums = Eigen::VectorXd::Zero(cs.c.num_vertices());
  double area = 0;
  for (int f = 0; f < from.faces.rows(); ++f) {
    double tsum = 0;
    for (int k = 0; k < 3; ++k) {
      const double a = from.edge_lengths[from.face_edges(f, k)], b = from.edge_lengths[from.face_edges(f, (k + 1) % 3)],
                   cc = from.edge_lengths[from.face_edges(f, (k + 2) % 3)];
      const double th = corner_angle(b, cc, a, Background::Hyperbolic);
      sums[from.faces(f, k)] += th;
      tsum += th;
    }
    area += kPi - tsum;
  }
  EXPECT_LT((sums.array() - 2 * kPi).abs().maxCoeff(), 1e-9);
  EXPECT_NEAR(area / (4 * kPi), 1.0, 1e-6);
}

// The flat case: the torus's flat metric from the coarse start (u up to the
// constant the gauge u_0 = 0 fixes) is the one from u = 0.
TEST(RicciFlow, CoarseStartReachesTheSameFlatTorusMetric) {
  const TriMesh m = jitter3d(torus(3, 1, 80, 40), 0.05, 3);
  const Connectivity c(m.F, m.num_vertices());
  const Eigen::VectorXd l = edge_lengths(m, c);
  RicciFlowOptions o;
  o.intrinsic_delaunay = true;
  const RicciFlowResult zero = ricci_flow(c, l, Background::Euclidean, o);
  ASSERT_TRUE(zero.converged) << zero.message;
  CoarseStartOptions so;
  so.coarse_vertices = 300;
  so.min_vertices = 1000;
  const CoarseStart start = coarse_conformal_start(m, c, Background::Euclidean, so);
  ASSERT_TRUE(start.ok) << start.why;
  const RicciFlowResult from = ricci_flow_from(c, l, Background::Euclidean, o, start.u);
  ASSERT_TRUE(from.converged) << from.message;
  EXPECT_EQ(from.u[0], 0.0);
  EXPECT_LE(from.iterations, zero.iterations);
  EXPECT_LT((from.u - zero.u).cwiseAbs().maxCoeff(), 1e-7);
}

// RicciFlowOptions::threads: the evaluations split over two threads (meshes
// of 20000 faces or more) give the same bits as one thread, flips included.
TEST(RicciFlow, TwoThreadEvaluationsGiveTheSameBits) {
  const TriMesh m = jitter3d(torus(3, 1, 150, 70), 0.05, 4);
  const Connectivity c(m.F, m.num_vertices());
  ASSERT_GE(c.num_faces(), 20000);
  const Eigen::VectorXd l = edge_lengths(m, c);
  RicciFlowOptions o;
  o.intrinsic_delaunay = true;
  const RicciFlowResult one = ricci_flow(c, l, Background::Euclidean, o);
  o.threads = 2;
  const RicciFlowResult two = ricci_flow(c, l, Background::Euclidean, o);
  ASSERT_TRUE(one.converged) << one.message;
  ASSERT_TRUE(two.converged) << two.message;
  EXPECT_EQ(one.iterations, two.iterations);
  EXPECT_EQ(one.flips, two.flips);
  EXPECT_EQ(one.cg_iterations, two.cg_iterations);
  EXPECT_EQ(one.residual_history, two.residual_history);
  EXPECT_TRUE(one.u == two.u);
  EXPECT_TRUE(one.edge_lengths == two.edge_lengths);
  EXPECT_TRUE(one.edge_vertices == two.edge_vertices);
}

// ricci_flow_from_checked (the map's target stage): a start is used only
// when the energy runs downhill to it and not much uphill at it. The coarse
// start does (and saves Newton steps); its negation is uphill from u = 0
// (φ'(0) = g(0)·(−u) > 0) and twice it overshoots; both are declined, after
// which the run is the one from u = 0 bit for bit: the flips undone exactly.
TEST(RicciFlow, CheckedStartIsUsedOnlyWhenDownhillAndNearItsSegmentsMinimum) {
  const GenusTwoCoarseCase cs;
  ASSERT_TRUE(cs.zero.converged) << cs.zero.message;
  ASSERT_TRUE(cs.start.ok) << cs.start.why;

  const CheckedFlow good = ricci_flow_from_checked(cs.c, cs.l, Background::Hyperbolic, cs.o, cs.start.u);
  ASSERT_TRUE(good.flow.converged) << good.flow.message;
  EXPECT_TRUE(good.start.start_used);
  // E convex along the segment: the slope grows; a good start is downhill
  // and near the segment's minimum.
  EXPECT_LT(good.start.slope_at_zero, 0.0);
  EXPECT_LE(good.start.slope_at_zero, good.start.slope_at_start);
  EXPECT_LT(good.start.slope_at_start, 0.05 * -good.start.slope_at_zero);
  EXPECT_EQ(good.start.residual_at_zero, cs.zero.residual_history.front());
  EXPECT_LT(good.flow.iterations, cs.zero.iterations);
  EXPECT_LT((good.flow.u - cs.zero.u).cwiseAbs().maxCoeff(), 1e-7);

  const CheckedFlow bad = ricci_flow_from_checked(cs.c, cs.l, Background::Hyperbolic, cs.o, -cs.start.u);
  const RicciFlowResult& b = bad.flow;
  ASSERT_TRUE(b.converged) << b.message;
  EXPECT_FALSE(bad.start.start_used);
  EXPECT_GT(bad.start.slope_at_zero, 0.0);
  EXPECT_EQ(b.iterations, cs.zero.iterations);
  EXPECT_EQ(b.residual_history, cs.zero.residual_history);
  EXPECT_EQ(b.flips, cs.zero.flips);
  EXPECT_TRUE(b.u == cs.zero.u);
  EXPECT_TRUE(b.edge_lengths == cs.zero.edge_lengths);
  EXPECT_TRUE(b.edge_vertices == cs.zero.edge_vertices);
  EXPECT_TRUE(b.faces == cs.zero.faces);
  ASSERT_EQ(b.flip_history.size(), cs.zero.flip_history.size());
  for (size_t k = 0; k < b.flip_history.size(); ++k) {
    EXPECT_EQ(b.flip_history[k].face0, cs.zero.flip_history[k].face0);
    EXPECT_EQ(b.flip_history[k].corner0, cs.zero.flip_history[k].corner0);
    EXPECT_EQ(b.flip_history[k].base_lengths, cs.zero.flip_history[k].base_lengths);
  }

  // Twice the start overshoots its line's minimum (near t = 1/2: φ'(1) is
  // about |φ'(0)|): declined although it is downhill from u = 0.
  const CheckedFlow twice = ricci_flow_from_checked(cs.c, cs.l, Background::Hyperbolic, cs.o, 2.0 * cs.start.u);
  EXPECT_FALSE(twice.start.start_used);
  EXPECT_LT(twice.start.slope_at_zero, 0.0);
  EXPECT_GT(twice.start.slope_at_start, 0.5 * -twice.start.slope_at_zero);
  EXPECT_TRUE(twice.flow.u == cs.zero.u);
}

TEST(RicciFlow, CoarseStartDeclinesSmallMeshesAndBadStartsAreInputErrors) {
  const TriMesh m = samples::n_hole_torus(2, 26, true);
  const Connectivity c(m.F, m.num_vertices());
  const CoarseStart start = coarse_conformal_start(m, c, Background::Hyperbolic);  // default: >= 20000 vertices
  EXPECT_FALSE(start.ok);
  EXPECT_NE(start.why.find("vertices"), std::string::npos) << start.why;
  CoarseStartOptions off;
  off.coarse_vertices = 0;
  EXPECT_FALSE(coarse_conformal_start(m, c, Background::Hyperbolic, off).ok);
  const Eigen::VectorXd l = edge_lengths(m, c);
  EXPECT_THROW(ricci_flow_from(c, l, Background::Hyperbolic, {}, Eigen::VectorXd::Zero(3)), InputError);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(c.num_vertices());
  u[5] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(ricci_flow_from(c, l, Background::Hyperbolic, {}, u), InputError);
}

}  // namespace
}  // namespace surfmap
