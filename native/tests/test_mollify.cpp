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
#include "surfmap/map/map_report.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/uniformize/ricci_flow.h"
#include "surfmap/uniformize/uniformize.h"
#include "../src/map/stages/hyperbolic_quality.h"
#include "../src/map/stages/source_weights_fallback.h"

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

TEST(Distortion, ThinSourceFacesAreTheOnesMollificationReshapes) {
  // A 179.99-degree corner and a side 1e-6 of the others are thin; a
  // 1-degree needle of ordinary sides is not (its D' is a real distortion).
  RowMatrixX3d V(9, 3);
  const double h = std::tan(0.005 * M_PI / 180) * 0.5;  // 179.99 degrees at (0.5, h)
  V << 0, 0, 0, 1, 0, 0, 0.5, h, 0,                      // obtuse sliver
      0, 0, 0, 1, 0, 0, 1, 1e-6, 0,                       // a side of 1e-6
      0, 0, 0, 1, 0, 0, std::cos(M_PI / 180), std::sin(M_PI / 180), 0;  // 1-degree needle
  RowMatrixX3i F(3, 3);
  F << 0, 1, 2, 3, 4, 5, 6, 7, 8;
  const std::vector<char> thin = thin_source_faces(V, F);
  EXPECT_EQ(thin, std::vector<char>({1, 1, 0}));
  // On a closed mesh the flags are the faces mollify_edge_lengths counts:
  // nearly collinear faces (the inserted vertices lifted off their edges by
  // 1e-7 and 1e-2 of the radius: thin, and not thin) on a sphere.
  TriMesh m = samples::insert_degenerate_faces(samples::sphere(2), 6, 0.5, 1);
  const int nv0 = samples::sphere(2).num_vertices();
  for (int v = nv0; v < m.num_vertices(); ++v) m.V.row(v) *= 1 + (v % 2 ? 1e-7 : 1e-2);
  const Connectivity c(m.F, m.num_vertices());
  Eigen::VectorXd raw(c.num_edges());  // the 3D lengths (edge_lengths() would return them mollified)
  for (int e = 0; e < c.num_edges(); ++e) raw[e] = (m.V.row(c.edge_vertex(e, 0)) - m.V.row(c.edge_vertex(e, 1))).norm();
  const MollifyResult r = mollify_edge_lengths(raw, c);
  const std::vector<char> flags = thin_source_faces(m.V, m.F);
  EXPECT_EQ(std::count(flags.begin(), flags.end(), 1), r.faces_touched);
  EXPECT_EQ(r.faces_touched, 3);  // one face per vertex lifted by 1e-7; the 1e-2 lifts are resolved
}

TEST(Distortion, ThinSourceFacesAreLeftOutOfTheSummaryAndListed) {
  // The identity image of a strip whose middle face is nearly collinear
  // (height 1e-8) but whose image is a proper triangle: that face's D' is
  // about 1e7 and would be the max (and dominate the mean); it is kept per
  // face, left out of mean and max, and listed with its D'.
  RowMatrixX3d V(5, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0.5, -1e-8, 0, 1, 1, 0;
  RowMatrixX3i F(3, 3);
  F << 0, 1, 2, 0, 3, 1, 1, 4, 2;
  Eigen::Matrix<std::complex<double>, Eigen::Dynamic, 3, Eigen::RowMajor> img(3, 3);
  for (int f = 0; f < 3; ++f)
    for (int k = 0; k < 3; ++k) img(f, k) = {V(F(f, k), 0), V(F(f, k), 1)};
  img(1, 1) += std::complex<double>(0, -0.1);
  const DistortionStats q = planar_distortion(V, F, img);
  EXPECT_EQ(q.degenerate_source, 0);
  ASSERT_EQ(q.thin_source, std::vector<int>({1}));
  EXPECT_GT(q.per_face[1], 1e6);
  EXPECT_EQ(q.thin_source_max, q.per_face[1]);
  EXPECT_NEAR(q.mean, 1.0, 1e-12);
  EXPECT_NEAR(q.max, 1.0, 1e-12);
  EXPECT_EQ(q.flipped, 0);
  // A thin face with a flipped image is still a flip, not left out.
  img(1, 1) = std::complex<double>(0.5, 0.1);
  const DistortionStats flipped = planar_distortion(V, F, img);
  EXPECT_EQ(flipped.flipped, 1);
  EXPECT_TRUE(flipped.thin_source.empty());
}

TEST(Distortion, NearlyCollinearTorusFacesDoNotMakeTheMapsDistortion) {
  // Before, D' of a nearly (not exactly) collinear source face was measured
  // against its 3D triangle, whose almost-180-degree corner no conformal
  // image matches: D' max 1e10 on genus 3-4 maps whose points were right
  // (docs/robustness.md, "The source side"). Now the
  // faces mollification reshapes are left out of mean and max and listed;
  // their own D' stays per face (here far above the rest).
  const TriMesh clean = samples::torus_of_revolution(1.0, 0.4, 24, 12);
  TriMesh a = samples::insert_degenerate_faces(clean, 8, 0.5, 2);
  const Eigen::RowVector3d off = Eigen::RowVector3d(1, 2, 3).normalized() * 1e-7;
  for (int v = clean.num_vertices(); v < a.num_vertices(); ++v) a.V.row(v) += off;
  const TriMesh b = samples::torus_of_revolution(1.5, 0.5, 24, 12, 1);
  const SurfaceMapResult m = surface_map(a, b), plain = surface_map(clean, b);
  EXPECT_TRUE(m.converged);
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_EQ(m.thin_source_faces.size(), 8u);
  EXPECT_TRUE(plain.thin_source_faces.empty());
  const std::vector<char> thin = thin_source_faces(a.V, a.F);
  for (int f : m.thin_source_faces) EXPECT_TRUE(thin[f]) << "face " << f;
  double mx = 0;
  for (int f = 0; f < a.num_faces(); ++f)
    if (!thin[f] && std::isfinite(m.dilatation[f])) mx = std::max(mx, m.dilatation[f]);
  EXPECT_EQ(m.max_dilatation, mx);
  // Measured: D' max 14.3 over the other faces (the split faces beside the
  // thin ones are distorted too; the clean torus: 1.42), 7.8e5 on the thin
  // faces, which was the max before.
  EXPECT_LT(m.max_dilatation, 50.0);
  EXPECT_GT(m.thin_source_max_dilatation, 1e4);
  EXPECT_LT(m.mean_dilatation, 2 * plain.mean_dilatation);
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


// Two ordinary source faces (equilateral, sharing an edge); face 0's image
// has the source's shape (D' ~1), face 1's has the corners 0, b, c in a
// small chart (nearly Euclidean).
DistortionStats two_face_image_distortion(std::complex<double> b, std::complex<double> c) {
  TriMesh src;
  src.V.resize(4, 3);
  src.V << 0, 0, 0, 1, 0, 0, 0.5, std::sqrt(0.75), 0, 1.5, std::sqrt(0.75), 0;
  src.F.resize(2, 3);
  src.F << 0, 1, 2, 1, 3, 2;
  using Complex = std::complex<double>;
  const double s = 0.05;
  const std::vector<std::pair<Complex, Complex>> chart = {{Complex(s, 0), Complex(0.5 * s, std::sqrt(0.75) * s)},
                                                          {b, c}};
  auto poincare_distance = [](Complex z, Complex w) {
    return 2 * std::atanh(std::abs(z - w) / std::abs(1.0 - std::conj(z) * w));
  };
  auto sides = [&](int f) {
    const Complex p[3] = {0.0, chart[f].first, chart[f].second};
    return Eigen::Vector3d(poincare_distance(p[0], p[1]), poincare_distance(p[1], p[2]),
                           poincare_distance(p[2], p[0]));
  };
  return hyperbolic_image_distortion(src, [&](int f) { return chart[f]; }, sides, true);
}

TEST(Distortion, NearlyFlatImagesOfOrdinaryFacesAreCountedFlat) {
  // A converged genus-3 map of a jittered source once left one ordinary
  // source face (angles 126/21/33 degrees) at the edge of a fold: its image
  // in the chart had |b x c| ~ 1e-11 max(|b|², |c|²), positive, and D' 7.4e9
  // made the map's mean D' 13,113 (docs/robustness.md, held-out sweep).
  // Such an image is flat: counted in `degenerate` (which starts the fold
  // repair), out of mean and max, like a zero-area one.
  using Complex = std::complex<double>;
  const double s = 0.05;
  const Complex b(s, 0), c(0.5 * s, 2e-11 * s);  // |b x c| = 2e-11 |b|²
  EXPECT_EQ(image_orientation(b, c), 0);
  EXPECT_EQ(image_orientation(Complex(s, 0), Complex(0.5 * s, std::sqrt(0.75) * s)), 1);
  EXPECT_EQ(image_orientation(Complex(0.5 * s, std::sqrt(0.75) * s), Complex(s, 0)), -1);
  const DistortionStats q = two_face_image_distortion(b, c);
  EXPECT_EQ(q.degenerate, 1);
  EXPECT_EQ(q.flipped, 0);
  EXPECT_TRUE(q.thin_source.empty());  // the source faces are ordinary
  EXPECT_TRUE(std::isinf(q.per_face[1]));
  EXPECT_LT(q.max, 1.05);
  EXPECT_LT(q.mean, 1.05);
}

TEST(Distortion, FlatButPositiveImagesDoNotFoldTheMap) {
  // A far-from-conformal map (a coarse CAD plate onto the fertility, mean D'
  // 1e4) leaves a few images flatter than kFlatImageRelativeCross in every
  // class, yet positive far beyond round-off: one-to-one there. Counted as
  // folds they sent every class of that pair to the own-edge retry and
  // then out (docs/handle_classes.md, "Flat images, folds and the own-edge retry"). They stay out
  // of the D' mean and max, but only images flat within round-off or
  // negatively oriented fold the map.
  using Complex = std::complex<double>;
  const double s = 0.05;
  SurfaceMapOptions automatic;  // SourceWeights::Automatic
  struct Case {
    Complex c;           // face 1's corner 2 (corner 1 at (s, 0))
    int degenerate, flat;  // DistortionStats
    bool folds;
  };
  const Case cases[] = {
      {Complex(0.5 * s, 2e-11 * s), 1, 1, false},   // flat, positive (|b x c| = 2e-11 |b|²)
      {Complex(0.5 * s, 5e-10 * s), 1, 1, false},   // just under the flat bound
      {Complex(0.5 * s, 1e-16 * s), 1, 0, true},    // orientation round-off
      {Complex(0.5 * s, -2e-11 * s), 1, 0, true},   // flat and negative
      {Complex(0.5 * s, 1e-6 * s), 0, 0, false},    // thin, not flat: D' ~1e6, measured
  };
  for (const Case& k : cases) {
    const DistortionStats q = two_face_image_distortion(Complex(s, 0), k.c);
    SCOPED_TRACE(k.c.imag() / s);
    EXPECT_EQ(q.degenerate, k.degenerate);
    EXPECT_EQ(q.flat, k.flat);
    EXPECT_EQ(q.flipped, 0);
    SurfaceMapResult out;
    detail::store_distortion(q, out);
    EXPECT_EQ(out.degenerate_triangles, k.degenerate - k.flat);
    // The flat but positive ones are counted apart, in the report (CLI and
    // Python) too.
    EXPECT_EQ(out.flat_triangles, k.flat);
    const nlohmann::json report = to_json(out, automatic);
    EXPECT_EQ(report.at("flat_triangles").get<int>(), k.flat);
    EXPECT_EQ(report.at("degenerate_triangles").get<int>(), k.degenerate - k.flat);
    // Automatic weights: a fold sends the class to the own-edge retry; with
    // own-edge weights already, it is refused (the class is not used).
    EXPECT_EQ(detail::retry_with_own_weights(automatic, false, out), k.folds);
    if (k.folds)
      EXPECT_THROW(detail::retry_with_own_weights(automatic, true, out), SolveError);
    else
      EXPECT_FALSE(detail::retry_with_own_weights(automatic, true, out));
    if (k.degenerate) {
      EXPECT_TRUE(std::isinf(q.per_face[1]));
      EXPECT_LT(q.max, 1.05);  // out of the max
    } else {
      EXPECT_GT(q.per_face[1], 1e5);
      EXPECT_EQ(q.max, q.per_face[1]);
    }
  }
}

// An ordinary source triangle (equilateral) and its back (a closed
// two-face sphere), the image of vertex k at g[k](0), each corner in its own
// chart as the solver keeps them: edge (tail, head) carries g[tail]^-1
// g[head] (head's chart -> tail's). Both faces list their corners from
// vertex `first` on; the back's image is the front's mirror.
DistortionStats one_face_chart_distortion(const hyperbolic::Mobius (&g)[3], int first) {
  TriMesh src;
  src.V.resize(3, 3);
  src.V << 0, 0, 0, 1, 0, 0, 0.5, std::sqrt(0.75), 0;
  src.F.resize(2, 3);
  src.F << first, (first + 1) % 3, (first + 2) % 3, first, (first + 2) % 3, (first + 1) % 3;
  const Connectivity sc(src.F, 3);
  detail::SolverEdgeIndex index;
  std::vector<hyperbolic::Mobius> edge_local;
  for (int e = 0; e < sc.num_edges(); ++e) {
    const int h = sc.edge_halfedge(e);
    index.solver_edge.push_back(e);
    index.forward.push_back(1);
    edge_local.push_back(g[sc.tail(h)].inverse() * g[sc.head(h)]);
  }
  return detail::chart_distortion(src, sc, edge_local, index);
}

TEST(Distortion, LongThinImagesAreReadFromTheirWidestCorner) {
  // Issue 13 (block g12 -> raw wheel g12, docs/robustness.md "Fallback classes and reading long images"):
  // a twisted class maps source faces of an ordinary size to hyperbolic
  // triangles 30-56 units long. Seen from the chart centring a sharp corner
  // of such an image, the other two corners lie within e^-(side length) of
  // each other on the chart's boundary circle, so |b x c| is below round-off
  // however large the triangle's area: the face was counted degenerate and
  // refused the class's own-edge map, which had no flipped face. From its
  // widest corner (opposite its longest side) the orientation is resolved.
  using hyperbolic::Mobius;
  const double L = 35, base = 0.5, lean = 0.3;
  for (const int sign : {1, -1}) {
    // Corner 0 (the apex) at distance L from corner 1, corner 2 at `base`
    // from corner 1: positively oriented for sign 1, mirrored for -1.
    const Mobius g[3] = {Mobius::translation(std::polar(L, sign * (M_PI / 2 + lean))), Mobius::identity(),
                         Mobius::translation(std::complex<double>(base, 0))};
    SCOPED_TRACE(sign);
    // Listed from the apex (the old reading's blind corner), from corner 1
    // (the widest) and from corner 2: one orientation, and one D'.
    const DistortionStats apex = one_face_chart_distortion(g, 0);
    const DistortionStats widest = one_face_chart_distortion(g, 1);
    const DistortionStats third = one_face_chart_distortion(g, 2);
    // The front (face 0) is positive for sign 1 and the back flipped, the
    // other way round for -1: one flipped face, none degenerate.
    const int positive = sign > 0 ? 0 : 1;
    for (const DistortionStats* q : {&apex, &widest, &third}) {
      EXPECT_EQ(q->degenerate, 0);
      EXPECT_EQ(q->flipped, 1);
      EXPECT_TRUE(std::isinf(q->per_face[1 - positive]));
      ASSERT_TRUE(std::isfinite(q->per_face[positive]));
      EXPECT_GT(q->per_face[positive], 10);  // stretched (D' ~93), measured
      EXPECT_NEAR(q->per_face[positive], widest.per_face[positive], 1e-6 * widest.per_face[positive]);
    }
    // What refused the class's own-edge map: no face is left degenerate.
    SurfaceMapResult out;
    detail::store_distortion(apex, out);
    EXPECT_EQ(out.degenerate_triangles, 0);
    EXPECT_EQ(out.flipped_triangles, 1);
  }
  // An ordinary image reads the same from every corner, as before.
  const Mobius h[3] = {Mobius::translation(std::complex<double>(0, 0.4)), Mobius::identity(),
                       Mobius::translation(std::complex<double>(0.5, 0))};
  const DistortionStats a = one_face_chart_distortion(h, 0), b = one_face_chart_distortion(h, 1);
  EXPECT_EQ(a.flipped, 1);
  EXPECT_EQ(b.flipped, 1);
  EXPECT_EQ(a.degenerate + b.degenerate, 0);
  EXPECT_NEAR(a.per_face[0], b.per_face[0], 1e-9 * b.per_face[0]);
}

}  // namespace
}  // namespace surfmap
