// The target in per-face charts (issue 13): CAD plates of genus 13 .. 24 lay
// out 28 .. 55 from the centre of the Poincaré disk, past what one chart
// holds in double precision, so the harmonic map must run with every point
// kept as (target face, point in that face's canonical chart). On a genus-3
// surface, which one chart does hold, the per-face atlas, its location walk
// and the harmonic solve in per-face charts must agree with the single
// chart: the atlas's transitions with the layout's charts, the walk's face
// and barycentrics with where the layout puts the point, and the harmonic
// map's energy, edge lengths and points with the single-chart solve's
// (1e-9).
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "surfmap/error.h"
#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/map/point_location.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/uniformize/layout.h"
#include "surfmap/uniformize/uniformize.h"

namespace surfmap {
namespace {

using hyperbolic::Mobius;
using Complex = std::complex<double>;

// A genus-3 surface uniformized once for the tests below (its layout is
// held by the single chart), its laid-out mesh and the atlas of its metric.
struct Genus3 {
  UniformizeResult u;
  Connectivity conn;
  FaceAtlas atlas;
  Genus3()
      : u(uniformize(samples::n_hole_torus(3, 32, true))),
        conn(u.loops.mesh.F, u.loops.mesh.num_vertices()),
        atlas(hyperbolic_face_atlas(conn, u.edge_lengths)) {}
};

const Genus3& genus3() {
  static const Genus3 g;
  return g;
}

TEST(FaceCharts, TheAtlasIsTheLayoutsChartsSeenFromEachFace) {
  const Genus3& g = genus3();
  ASSERT_TRUE(g.u.converged);
  ASSERT_TRUE(g.u.single_chart);
  const DiskLayout& L = g.u.layout;
  ASSERT_EQ(g.atlas.num_faces(), L.corners.rows());
  // Each face's chart places its canonical triangle at the layout's corners.
  double worst_corner = 0;
  for (int f = 0; f < g.atlas.num_faces(); ++f)
    for (int k = 0; k < 3; ++k)
      worst_corner = std::max(worst_corner, hyperbolic::distance(L.face_charts[f].apply(g.atlas.corners[f][k]), L.corners(f, k)));
  EXPECT_LT(worst_corner, 1e-9);
  // Across an uncut edge the transition is the quotient of the two charts;
  // across a cut edge, of the charts and the edge's deck map.
  double worst_uncut = 0, worst_cut = 0;
  for (int h = 0; h < g.conn.num_halfedges(); ++h) {
    const int f = Connectivity::face(h), t = Connectivity::face(g.conn.twin(h));
    const int e = g.conn.edge(h);
    Mobius other = L.face_charts[t];
    if (L.cut_edge[e]) {
      // edge_deck_mobius[e] takes the copy beside face(edge_halfedge(e))'s
      // neighbour into place (layout.h): seen from h's side, or its inverse.
      const Mobius deck = L.edge_deck_mobius[e];
      other = (g.conn.edge_halfedge(e) == h ? deck.inverse() : deck) * other;
    }
    const double d = hyperbolic::mobius_distance((L.face_charts[f] * g.atlas.transition[h]).normalized(), other.normalized());
    (L.cut_edge[e] ? worst_cut : worst_uncut) = std::max(L.cut_edge[e] ? worst_cut : worst_uncut, d);
  }
  EXPECT_LT(worst_uncut, 1e-9);
  EXPECT_LT(worst_cut, 1e-9);
}

TEST(FaceCharts, TheWalkFindsTheFaceTheLayoutPutsAPointIn) {
  const Genus3& g = genus3();
  const DiskLayout& L = g.u.layout;
  const int nF = g.atlas.num_faces();
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> any_face(0, nF - 1);
  std::uniform_real_distribution<double> U(0.05, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 200; ++trial) {
    // A point inside face g0 (interior barycentrics), seen from a face f0
    // a few faces away: the walk must end in g0 at the same barycentrics,
    // whichever cut edges the walk crosses.
    const int g0 = any_face(rng);
    double b[3] = {U(rng), U(rng), U(rng)};
    const double s = b[0] + b[1] + b[2];
    for (double& x : b) x /= s;
    // The point with these hyperboloid barycentrics: the normalised
    // combination of the corners' hyperboloid points.
    double X = 0, Y = 0, T = 0;
    for (int k = 0; k < 3; ++k) {
      const Complex c = g.atlas.corners[g0][k];
      const double n = 1 - std::norm(c);
      X += b[k] * 2 * c.real() / n, Y += b[k] * 2 * c.imag() / n, T += b[k] * (1 + std::norm(c)) / n;
    }
    const double m = std::sqrt(T * T - X * X - Y * Y);
    X /= m, Y /= m, T /= m;
    const Complex w(X / (1 + T), Y / (1 + T));
    const Complex p = L.face_charts[g0].apply(w);  // in the layout
    // From a face whose chart is within 3 units of the point.
    int f0 = -1;
    for (int tries = 0; tries < 50 && f0 < 0; ++tries) {
      const int f = any_face(rng);
      if (hyperbolic::distance(L.corners(f, 0), p) < 3.0) f0 = f;
    }
    if (f0 < 0) continue;
    const Complex q = L.face_charts[f0].inverse().apply(p);
    Mobius moved;
    Eigen::Vector3d bary;
    const int found = locate_in_face_charts(g.atlas, f0, q, 1000, &moved, &bary);
    ASSERT_EQ(found, g0) << "trial " << trial << " from face " << f0;
    // The same point to 1e-9 in the metric; its barycentrics to 1e-7 (the
    // reference went through two global charts, whose round-off, ~1e-10 in
    // the metric, is 1e-8 of a triangle 0.01 across).
    EXPECT_LT(hyperbolic::distance(moved.apply(q), w), 1e-9) << "trial " << trial;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(bary[k], b[k], 1e-7) << "trial " << trial;
    ++checked;
  }
  EXPECT_GT(checked, 100);
  // A start face out of range is an InputError naming it.
  Mobius moved;
  Eigen::Vector3d bary;
  EXPECT_THROW(locate_in_face_charts(g.atlas, nF, Complex(0.0), 10, &moved, &bary), InputError);
}

// The element taking the canonical coordinates of face(a) to those of
// face(stop) (both outgoing from the same vertex), composed face by face
// counter-clockwise around that vertex: the transitions of its star.
Mobius around_vertex(const Genus3& g, int a, int stop) {
  Mobius x;  // face(current) -> face(a)
  for (int current = a, guard = 0; current != stop; ++guard) {
    if (guard > 64) throw SolveError("around_vertex: the star did not close");
    const int prev = Connectivity::next(Connectivity::next(current));
    x = (x * g.atlas.transition[prev]).normalized();
    current = g.conn.twin(prev);
  }
  return x;
}

TEST(FaceCharts, HarmonicMapInFaceChartsIsTheSingleChartsMap) {
  const Genus3& g = genus3();
  const DiskLayout& L = g.u.layout;
  const int n = g.conn.num_vertices();
  // The surface mapped onto itself with random positive weights (the
  // optimum is then not the identity), every vertex starting jittered off
  // its corner of one of its faces.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1.0, 1.0), W(0.5, 1.5);
  std::vector<int> face0(n), out0(n);
  std::vector<Complex> w0(n), z0(n);
  for (int v = 0; v < n; ++v) {
    const int h = g.conn.outgoing(v).front();
    out0[v] = h;
    face0[v] = Connectivity::face(h);
    w0[v] = hyperbolic::exp_map(g.atlas.corners[face0[v]][h % 3], 0.02 * Complex(U(rng), U(rng)));
    z0[v] = L.face_charts[face0[v]].apply(w0[v]);
  }
  std::vector<WeightedEdge> local, single;
  for (int e = 0; e < g.conn.num_edges(); ++e) {
    const int h = g.conn.edge_halfedge(e), i = g.conn.tail(h), j = g.conn.head(h);
    WeightedEdge ed;
    ed.i = i, ed.j = j, ed.w = W(rng);
    // face0[j] -> face(h) around j, then face(h) -> face0[i] around i.
    const Mobius to_h_from_j = around_vertex(g, out0[j], Connectivity::next(h)).inverse();
    const Mobius h_to_i = around_vertex(g, out0[i], h);
    ed.rho = (h_to_i * to_h_from_j).normalized();
    local.push_back(ed);
    ed.rho = (L.face_charts[face0[i]] * ed.rho * L.face_charts[face0[j]].inverse()).normalized();
    single.push_back(ed);
  }
  HyperbolicHarmonicOptions o;
  o.tolerance = 1e-12;
  const HyperbolicHarmonicResult one = hyperbolic_harmonic_map(n, single, L.side_pairings, z0, o);
  const HyperbolicHarmonicResult per_face = hyperbolic_harmonic_map_in_face_charts(n, local, g.atlas, face0, w0, o);
  ASSERT_TRUE(one.converged);
  ASSERT_TRUE(per_face.converged);
  ASSERT_EQ(per_face.face.size(), static_cast<size_t>(n));
  EXPECT_NEAR(per_face.energy, one.energy, 1e-9 * one.energy);
  double worst_length = 0;
  for (size_t e = 0; e < local.size(); ++e)
    worst_length = std::max(worst_length, std::abs(per_face.edge_local[e].displacement_of_origin() -
                                                   one.edge_local[e].displacement_of_origin()));
  EXPECT_LT(worst_length, 1e-9);
  // The start's class is the identity's (every edge's element composed
  // inside the stars of its ends), so the optimum is an embedding: no image
  // triangle turned over, each tested in its first corner's chart (Klein
  // model: straight sides).
  auto head_in_tail_chart = [&](int h) {
    const int e = g.conn.edge(h);
    const Mobius& A = per_face.edge_local[e];
    return hyperbolic::poincare_to_klein((g.conn.edge_halfedge(e) == h ? A : A.inverse()).apply(Complex(0.0)));
  };
  int flipped = 0;
  for (int f = 0; f < g.conn.num_faces(); ++f)
    flipped += !(std::imag(std::conj(head_in_tail_chart(3 * f)) * head_in_tail_chart(g.conn.twin(3 * f + 2))) > 0);
  EXPECT_EQ(flipped, 0);
  // The same points of the surface: the single chart's point brought back
  // to the start's sheet, then located from the start face by the walk,
  // against the per-face solve's face and point, compared in 3D.
  const TriMesh& mesh = g.u.loops.mesh;
  double diag = (mesh.V.colwise().maxCoeff() - mesh.V.colwise().minCoeff()).norm(), worst_point = 0;
  auto position = [&](int f, const Complex& w) {
    double l[3];
    hyperbolic::triangle_barycentric(w, g.atlas.corners[f][0], g.atlas.corners[f][1], g.atlas.corners[f][2], l);
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) p += l[k] * mesh.V.row(mesh.F(f, k)).transpose();
    return p;
  };
  int moved_vertices = 0;
  for (int v = 0; v < n; ++v) {
    const Complex lift = one.vertex_deck[v].inverse().apply(one.z[v]);
    Mobius moved;
    Eigen::Vector3d bary;
    const Complex q = L.face_charts[face0[v]].inverse().apply(lift);
    const int f = locate_in_face_charts(g.atlas, face0[v], q, 1000, &moved, &bary);
    ASSERT_GE(f, 0) << "vertex " << v;
    worst_point = std::max(worst_point, (position(f, moved.apply(q)) - position(per_face.face[v], per_face.z[v])).norm());
    moved_vertices += per_face.face[v] != face0[v];
  }
  EXPECT_LT(worst_point, 1e-9 * diag);
  // The solve did move vertices between faces (the weights pull them off
  // their corners), so the walk and the transitions' conjugations ran.
  EXPECT_GT(moved_vertices, n / 10);
  // Inputs the per-face solve refuses: a start face out of range, a relator.
  std::vector<int> bad = face0;
  bad[0] = g.atlas.num_faces();
  EXPECT_THROW(hyperbolic_harmonic_map_in_face_charts(n, local, g.atlas, bad, w0, o), InputError);
  HyperbolicHarmonicOptions with_relator = o;
  with_relator.relator = L.side_relator;
  EXPECT_THROW(hyperbolic_harmonic_map_in_face_charts(n, local, g.atlas, face0, w0, with_relator), InputError);
}

// surface_map in per-face charts (issue 13), forced on a genus-3 plate that
// one chart holds (the plates that need it, genus >= 13, take 10-25 s): a
// jittered copy onto the plate maps in the snapped class, converged with 0
// flipped, every target vertex found in a source face's image, and its
// harmonic map is the one the single-chart pipeline finds with the same
// weights (same energy to 1e-8: the same class and optimum).
TEST(FaceCharts, SurfaceMapInFaceChartsMapsAJitteredPlateOntoThePlate) {
  const TriMesh target = samples::cad_plate(3, 16);
  const TriMesh source = samples::jitter(target, 0.2, 1);
  SurfaceMapOptions options;
  options.uniformization.face_charts = FaceCharts::Always;
  const SurfaceMapResult r = surface_map(source, target, options);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.flipped_triangles, 0);
  EXPECT_EQ(r.degenerate_triangles, 0);
  EXPECT_EQ(r.face_charts.rfind("per-face charts (requested)", 0), 0u) << r.face_charts;
  EXPECT_EQ(r.snapped_inconsistent_faces, 0);
  // The solve's elements close around every source face (its own edges).
  EXPECT_EQ(r.layout_closure.triangles, source.num_faces());
  EXPECT_EQ(r.layout_closure.open_triangles, 0);
  EXPECT_LT(r.layout_closure.worst_gap, r.layout_closure.tolerance);
  ASSERT_EQ(static_cast<int>(r.forward.size()), source.num_vertices());
  ASSERT_EQ(static_cast<int>(r.inverse.size()), target.num_vertices());
  const double diagonal = (target.V.colwise().maxCoeff() - target.V.colwise().minCoeff()).norm();
  double worst_forward = 0, worst_inverse = 0, mean_forward = 0;
  for (int v = 0; v < source.num_vertices(); ++v) {
    const PointOnSurface& p = r.forward[v];
    Eigen::Vector3d on_face = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) on_face += p.barycentric[k] * target.V.row(target.F(p.face, k)).transpose();
    EXPECT_LT((on_face - p.position).norm(), 1e-12 * diagonal);
    const double d = (p.position - target.V.row(v).transpose()).norm();
    worst_forward = std::max(worst_forward, d), mean_forward += d / source.num_vertices();
  }
  for (int v = 0; v < target.num_vertices(); ++v)
    worst_inverse = std::max(worst_inverse, (r.inverse[v].position - target.V.row(v).transpose()).norm());
  // (Own-edge weights on a coarse plate slide vertices along the surface:
  // mean 2.8%, largest 13% of the diagonal; a map in a twisted class moves
  // whole handles.)
  EXPECT_LT(mean_forward, 0.05 * diagonal);
  EXPECT_LT(worst_forward, 0.2 * diagonal);
  EXPECT_LT(worst_inverse, 0.2 * diagonal);
  // The map in one chart, with the same weights, its class chosen by its
  // own candidates (no search, no other direction): the same class, so the
  // same harmonic map and energy.
  SurfaceMapOptions single;
  single.solve.source_weights = SourceWeights::OwnEdges;
  single.homotopy.search.enabled = false;
  single.homotopy.two_way = false;
  single.homotopy.through_shape = false;
  const SurfaceMapResult one = surface_map(source, target, single);
  ASSERT_TRUE(one.face_charts.empty());
  EXPECT_NEAR(r.final_energy, one.final_energy, 1e-8 * one.final_energy);
  // One class: no class search, nothing to compare.
  ASSERT_EQ(r.candidates.size(), 1u);
  EXPECT_EQ(r.two_way_status.rfind("not run", 0), 0u);
}

// The per-face path maps one class and holds no landmarks: asked for both,
// one line naming what it does not take.
TEST(FaceCharts, SurfaceMapInFaceChartsRefusesLandmarks) {
  const TriMesh target = samples::cad_plate(2, 16);
  SurfaceMapOptions options;
  options.uniformization.face_charts = FaceCharts::Always;
  options.landmarks = {{0, 0}};
  EXPECT_THROW(surface_map(target, target, options), InputError);
}

}  // namespace
}  // namespace surfmap
