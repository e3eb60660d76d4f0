// Flip-based uniformization (docs/uniformization.md): Ptolemy flips of the
// hyperbolic metric, Newton stopping at the floating-point floor, and the
// default uniformize path (intrinsic Delaunay metric, loops on the flipped
// triangulation) on meshes where the fixed-connectivity metric does not exist.
#include <cmath>
#include <complex>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "surfmap/error.h"
#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/feasible_metric.h"
#include "surfmap/uniformize/intrinsic_correspondence.h"
#include "surfmap/uniformize/intrinsic_loops.h"
#include "surfmap/uniformize/simplicial_flips.h"
#include "surfmap/uniformize/ricci_flow.h"
#include "surfmap/uniformize/uniformize.h"

namespace surfmap {
namespace {

using C = std::complex<double>;
constexpr double kPi = 3.14159265358979323846;

double hangle(double a, double b, double c) {  // angle opposite c
  return std::acos((std::cosh(a) * std::cosh(b) - std::cosh(c)) / (std::sinh(a) * std::sinh(b)));
}

// Whether the fixed-connectivity hyperbolic metric exists on m as it is (no
// exact refinement): what sends the meshes below past the fixed path.
bool unrefined_fixed_metric_converges(const TriMesh& m) {
  const SystemOfLoops loops = system_of_loops(m);
  FeasibleMetricOptions plain;
  plain.refine_max_angles.clear();
  return feasible_metric(m, loops, Background::Hyperbolic, plain).flow.converged;
}

// The flip formula of the hyperbolic flow: with sinh(l/2) = e^{(u_i+u_j)/2}
// l⁰/2, a flip sets l⁰_new l⁰_e = l⁰_a l⁰_c + l⁰_b l⁰_d, i.e. Ptolemy for
// sinh(l/2). Checked here against geometry: for four points on a hyperbolic
// circle the relation holds for the true diagonals, and the quadrilateral is
// exactly on the Delaunay boundary (opposite angles = angles at the ends).
TEST(IntrinsicUniformization, HyperbolicPtolemyHoldsOnCyclicQuadrilaterals) {
  for (double rho : {0.1, 0.5, 0.9}) {
    const double t[4] = {0.3, 1.9, 2.6, 4.4};
    C p[4];
    // A circle centred at 0 in the Poincaré disk, then moved by an isometry.
    const hyperbolic::Mobius m = hyperbolic::Mobius::translation_to(C(0.3, -0.2));
    for (int k = 0; k < 4; ++k) p[k] = m.apply(rho * std::exp(C(0, t[k])));
    auto d = [&](int i, int j) { return hyperbolic::distance(p[i], p[j]); };
    auto s = [&](int i, int j) { return std::sinh(d(i, j) / 2); };
    const double lhs = s(0, 2) * s(1, 3), rhs = s(0, 1) * s(2, 3) + s(1, 2) * s(3, 0);
    EXPECT_NEAR(lhs / rhs, 1.0, 1e-12) << "rho " << rho;
    // Diagonal 0-2: triangles (0,1,2) and (0,2,3). Opposite corners 1 and 3.
    const double a1 = hangle(d(0, 1), d(1, 2), d(0, 2)), a3 = hangle(d(2, 3), d(3, 0), d(0, 2));
    const double ends = hangle(d(0, 1), d(0, 2), d(1, 2)) + hangle(d(0, 2), d(1, 2), d(0, 1)) +
                        hangle(d(0, 2), d(0, 3), d(2, 3)) + hangle(d(0, 2), d(2, 3), d(0, 3));
    EXPECT_NEAR(a1 + a3, ends, 1e-10);
    // Off the circle the relation fails: the check can tell.
    const C q = m.apply(0.7 * rho * std::exp(C(0, t[3])));
    const double s03 = std::sinh(hyperbolic::distance(q, p[0]) / 2), s13 = std::sinh(hyperbolic::distance(q, p[1]) / 2),
                 s23 = std::sinh(hyperbolic::distance(q, p[2]) / 2);
    EXPECT_GT(std::abs(s(0, 2) * s13 - (s(0, 1) * s23 + s(1, 2) * s03)), 1e-4);
  }
}

// Raw marching tetrahedra: the fixed-connectivity hyperbolic metric does not
// exist (ExactRefinement tests); the default path converges with flips, no
// refinement, Gauss–Bonnet area and a glued layout.
TEST(IntrinsicUniformization, InfeasibleFixedMetricConvergesWithFlips) {
  const TriMesh m = samples::n_hole_torus(3, 32, false);
  ASSERT_FALSE(unrefined_fixed_metric_converges(m));
  const UniformizeResult u = uniformize(m);
  EXPECT_TRUE(u.converged);
  EXPECT_EQ(u.metric, "intrinsic Delaunay");
  EXPECT_GT(u.edge_flips, 0);
  EXPECT_EQ(u.refinement_splits, 0);
  EXPECT_LE(u.max_curvature_error, 1e-10);
  EXPECT_EQ(u.layout.num_flipped, 0);
  EXPECT_NEAR(u.area, 4 * kPi * 2, 1e-6);
  EXPECT_LT(u.layout.max_deck_inconsistency, 1e-6);
  EXPECT_LT(u.layout.max_corner_inconsistency, 1e-6);
  // Independent area: the geodesic triangles of the laid-out corners.
  double area = 0;
  for (int f = 0; f < u.layout.corners.rows(); ++f)
    area += hyperbolic::triangle_area(u.layout.corners(f, 0), u.layout.corners(f, 1), u.layout.corners(f, 2));
  EXPECT_NEAR(area, 4 * kPi * 2, 1e-6);
  // The loops live on a triangulation of the input's vertices.
  ASSERT_GE(u.loops.mesh.num_vertices(), m.num_vertices());
  EXPECT_EQ(static_cast<int>(u.loops.generator_edges.size()), 6);
}

// Issue 13: the genus-3 CAD plate (128 points per rim). The flip-based
// metric converges, but its Delaunay triangulation has two edges between one
// pair of vertices, so the loops cannot be cut on it and uniformize falls
// back to the fixed connectivity, whose unrefined metric has degenerate
// faces. The fallback must refine (it used to refuse the mesh).
TEST(IntrinsicUniformization, NonSimplicialFlippedTriangulationIsMadeSimplicialByExactFlips) {
  // The 128-segment CAD plate: after the Ptolemy flips T' has loop or
  // double edges. It went to the refined fixed-connectivity metric; now
  // exact flips of the final metric make T' simplicial and the flip path
  // delivers it (uniformize/simplicial_flips.h).
  const TriMesh m = samples::cad_plate(3, 128, 0.1);
  RicciFlowOptions flips;
  flips.intrinsic_delaunay = true;
  const Connectivity conn(m.F, m.num_vertices());
  RicciFlowResult flow = ricci_flow(conn, edge_lengths(m, conn), Background::Hyperbolic, flips);
  ASSERT_TRUE(flow.converged) << flow.message;
  // What sent it to the fallback: T' is not simplicial.
  ASSERT_FALSE(is_simplicial(flow));
  EXPECT_THROW(intrinsic_loops(m, flow, Background::Hyperbolic), SolveError);
  ASSERT_FALSE(unrefined_fixed_metric_converges(m));
  const int solve_flips = flow.flips;
  const SimplicialFlipsResult sf = make_simplicial(flow);
  EXPECT_TRUE(sf.simplicial);
  EXPECT_GT(sf.loop_edges + sf.multiple_edges, 0);
  EXPECT_EQ(flow.flips, solve_flips + sf.flips);
  EXPECT_EQ(static_cast<int>(flow.flip_history.size()), flow.flips);
  EXPECT_TRUE(is_simplicial(flow));
  // The metric is unchanged: still curvature 0 at every vertex (angle sums
  // recomputed here with the half-angle formula on the flipped faces).
  std::vector<double> angle_sum(m.num_vertices(), 0.0);
  for (int f = 0; f < flow.faces.rows(); ++f) {
    double l[3];
    for (int k = 0; k < 3; ++k) l[k] = flow.edge_lengths[flow.face_edges(f, k)];
    const double s = 0.5 * (l[0] + l[1] + l[2]);
    for (int k = 0; k < 3; ++k) {
      const double a = l[k], b = l[(k + 1) % 3], c = l[(k + 2) % 3];
      ASSERT_GT(s - a, 0) << "face " << f;
      angle_sum[flow.faces(f, k)] +=
          2 * std::atan(std::sqrt(std::sinh(s - b) * std::sinh(s - c) / (std::sinh(s) * std::sinh(s - a))));
    }
  }
  for (int v = 0; v < m.num_vertices(); ++v) EXPECT_NEAR(angle_sum[v], 2 * kPi, 1e-9) << "vertex " << v;
  EXPECT_NO_THROW(intrinsic_loops(m, flow, Background::Hyperbolic));
  // The default path: the flip-based metric, unrefined.
  const UniformizeResult u = uniformize(m);
  EXPECT_TRUE(u.converged);
  EXPECT_EQ(u.metric.find("fixed connectivity"), std::string::npos) << u.metric;
  EXPECT_NE(u.metric.find("exact flips of the final metric"), std::string::npos) << u.metric;
  EXPECT_EQ(u.refinement_splits, 0);
  EXPECT_LE(u.max_curvature_error, 1e-10);
  EXPECT_EQ(u.layout.num_flipped, 0);
  EXPECT_LT(u.layout.max_deck_inconsistency, 1e-6);
  EXPECT_NEAR(u.area, 4 * kPi * 2, 1e-6);
  double area = 0;
  for (int f = 0; f < u.layout.corners.rows(); ++f)
    area += hyperbolic::triangle_area(u.layout.corners(f, 0), u.layout.corners(f, 1), u.layout.corners(f, 2));
  EXPECT_NEAR(area, 4 * kPi * 2, 1e-6);
  EXPECT_EQ(static_cast<int>(u.loops.generator_edges.size()), 6);
  // Points of T' carried back through the final-frame flips and the solve's
  // flips: every vertex of T' is its own input vertex.
  const IntrinsicCorrespondence corr(flow);
  for (int f = 0; f < flow.faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      b[k] = 1;
      const FacePoint p = corr.to_input(f, b);
      ASSERT_GE(p.face, 0);
      int corner = 0;
      p.barycentric.maxCoeff(&corner);
      EXPECT_EQ(m.F(p.face, corner), flow.faces(f, k)) << "face " << f << " corner " << k;
      EXPECT_NEAR(p.barycentric[corner], 1.0, 1e-9);
    }
  // Continuous across every edge of T' (the final-frame flips' diagonals
  // included): an edge's midpoint carried back from either face is one
  // point of the input.
  auto on_input = [&](int f, const Eigen::Vector3d& b) {
    const FacePoint p = corr.to_input(f, b);
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) x += p.barycentric[k] * m.V.row(m.F(p.face, k)).transpose();
    return x;
  };
  const double diagonal = (m.V.colwise().maxCoeff() - m.V.colwise().minCoeff()).norm();
  std::vector<std::vector<std::pair<int, int>>> sides(flow.edge_vertices.rows());  // (face, corner opposite)
  for (int f = 0; f < flow.faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) sides[flow.face_edges(f, k)].emplace_back(f, k);
  double worst = 0;
  for (const auto& sd : sides) {
    ASSERT_EQ(sd.size(), 2u);
    Eigen::Vector3d x[2];
    for (int j = 0; j < 2; ++j) {
      Eigen::Vector3d b = Eigen::Vector3d::Constant(0.5);
      b[sd[j].second] = 0;
      x[j] = on_input(sd[j].first, b);
    }
    worst = std::max(worst, (x[0] - x[1]).norm());
  }
  EXPECT_LT(worst, 1e-9 * diagonal);
}

// Coarse, very anisotropic, jittered tori (6 segments around the major
// circle with 600 around the minor one; 8 around a fat minor circle with
// random diagonals): many flips, loops cut on the flipped triangulation, a
// layout that glues with no flipped triangle, and a lattice whose cell has
// the metric's area.
TEST(IntrinsicUniformization, AnisotropicToriLayOutOnTheFlippedTriangulation) {
  struct Case { double R, r; int n, m, variant; };
  for (const Case& k : std::vector<Case>{{3.0, 1.0, 6, 600, 2}, {1.2, 1.0, 400, 8, 3}}) {
    SCOPED_TRACE(k.m);
    // A little tangential jitter: no cyclic quadrilaterals (Delaunay ties).
    const TriMesh m = samples::jitter(samples::torus_of_revolution(k.R, k.r, k.n, k.m, k.variant), 0.05, 3);
    const UniformizeResult u = uniformize(m);
    ASSERT_TRUE(u.converged);
    EXPECT_GT(u.edge_flips, 0);
    EXPECT_LE(u.max_curvature_error, 1e-10);
    EXPECT_EQ(u.layout.num_flipped, 0);
    EXPECT_EQ(u.layout.num_unresolved, 0);
    EXPECT_LT(u.layout.max_deck_inconsistency, 1e-8 * std::sqrt(u.area));
    EXPECT_LT(u.layout.max_holonomy_rotation, 1e-8);
    // The lattice spans the fundamental domain: |ω1 × ω2| = its area.
    const C w1 = u.modulus.omega1, w2 = u.modulus.omega2;
    EXPECT_NEAR(std::abs(std::imag(std::conj(w1) * w2)) / u.area, 1.0, 1e-8);
  }
}

// Flat tori through the default path: the analytic modulus of a torus of
// revolution i√(R²−r²)/r within 0.3%, also with long thin triangles
// (anisotropic grid) and random diagonals, where flips happen.
TEST(IntrinsicUniformization, TorusModulusWithFlips) {
  struct Case { double R, r; int n, m, variant; bool flips; };
  // Offset rings on an anisotropic grid: obtuse triangles, thousands of
  // flips. (Random diagonals of the grid's cyclic quads are Delaunay ties:
  // no flips.)
  for (const Case& k : std::vector<Case>{
           {2.0, 1.0, 60, 120, 2, false}, {3.0, 1.0, 300, 60, 2, true}, {1.5, 0.5, 200, 60, 9, false}}) {
    SCOPED_TRACE(k.n);
    const TriMesh m = samples::torus_of_revolution(k.R, k.r, k.n, k.m, k.variant);
    const UniformizeResult u = uniformize(m);
    ASSERT_TRUE(u.converged);
    EXPECT_EQ(u.layout.num_flipped, 0);
    EXPECT_LE(u.max_curvature_error, 1e-10);
    if (k.flips) EXPECT_GT(u.edge_flips, 1000);
    const C expected = reduce_modulus(C(0, std::sqrt(k.R * k.R - k.r * k.r) / k.r));
    EXPECT_LT(std::abs(u.tau_reduced - expected) / std::abs(expected), 3e-3) << u.tau_reduced << " vs " << expected
                                                                              << ", flips " << u.edge_flips;
  }
}

// Part of the contract: a residual the floating-point floor does not allow
// to go below is success with stopped_at_floor; with no floor band it is an
// honest failure, never a fake success.
TEST(IntrinsicUniformization, FloatingPointFloorIsSuccessNotError) {
  const TriMesh m = samples::n_hole_torus(2, 32, false);
  const Connectivity c(m.F, m.num_vertices());
  RicciFlowOptions o;
  o.intrinsic_delaunay = true;
  o.tolerance = 1e-30;  // below any floor
  const RicciFlowResult r = ricci_flow(c, edge_lengths(m, c), Background::Hyperbolic, o);
  EXPECT_TRUE(r.converged) << r.message;
  EXPECT_TRUE(r.stopped_at_floor);
  EXPECT_LE(r.max_curvature_error, 1e-7);
  EXPECT_GT(r.floor_estimate, 0.0);
  o.floor_tolerance = 0;
  const RicciFlowResult strict = ricci_flow(c, edge_lengths(m, c), Background::Hyperbolic, o);
  EXPECT_FALSE(strict.converged);
  EXPECT_FALSE(strict.stopped_at_floor);
  EXPECT_FALSE(strict.message.empty());
}

}  // namespace
}  // namespace surfmap
