#include "surfmap/geometry/intrinsic_delaunay.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include "surfmap/error.h"
#include "surfmap/geometry/positive_edge_weights.h"
#include "surfmap/samples/shapes.h"

namespace surfmap {
namespace {

// A flat torus R^2 / (Z x hZ): an n x m grid, sheared and jittered so that
// many triangles are obtuse, triangulated along the bad diagonal. Each
// halfedge gets its displacement vector in the plane (minimal image).
struct FlatTorus {
  RowMatrixX3i F;
  Eigen::MatrixX2d P;
  double h = 0.7;
  double shear = 0.0;  // lattice vectors (1, 0) and (shear * h, h)
  std::vector<Eigen::Vector2d> displacement;  // per halfedge
  Eigen::VectorXd lengths;                    // per edge
};

FlatTorus flat_torus(int n, int m, double shear, double jitter, unsigned seed) {
  FlatTorus t;
  t.shear = shear;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1);
  t.P.resize(n * m, 2);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double y = t.h * j / m;
      t.P.row(i * m + j) << double(i) / n + shear * y + jitter * U(rng) / n, y + jitter * U(rng) * t.h / m;
    }
  t.F.resize(2 * n * m, 3);
  int f = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const int a = i * m + j, b = ((i + 1) % n) * m + j, c = ((i + 1) % n) * m + (j + 1) % m,
                d = i * m + (j + 1) % m;
      t.F.row(f++) << a, b, d;  // the "wrong" diagonal b-d for a positive shear
      t.F.row(f++) << b, c, d;
    }
  return t;
}

void attach_metric(FlatTorus& t, const Connectivity& c) {
  t.displacement.resize(c.num_halfedges());
  for (int h = 0; h < c.num_halfedges(); ++h) {
    Eigen::Vector2d d = t.P.row(c.head(h)) - t.P.row(c.tail(h));
    // Minimal image in the sheared lattice: reduce y first, then x.
    const double ky = std::round(d.y() / t.h);
    d -= ky * Eigen::Vector2d(t.shear * t.h, t.h);
    d.x() -= std::round(d.x());
    t.displacement[h] = d;
  }
  t.lengths.resize(c.num_edges());
  for (int e = 0; e < c.num_edges(); ++e) t.lengths[e] = t.displacement[c.edge_halfedge(e)].norm();
}

TEST(IntrinsicDelaunay, FlatTorusWeightsAreNonnegativeAndReproduceAffineFunctions) {
  for (unsigned seed : {1u, 2u, 3u}) {
    // A strong shear makes the chosen diagonals give very obtuse triangles.
    FlatTorus t = flat_torus(14, 11, 0.9, 0.35, seed);
    Connectivity c(t.F);
    attach_metric(t, c);
    const auto r = intrinsic_delaunay(c, t.lengths);
    EXPECT_TRUE(r.delaunay);
    EXPECT_GT(r.flips, 0) << "the test mesh should need flips";
    EXPECT_GE(r.min_cot_weight, -1e-12);
    std::vector<Eigen::Vector2d> balance(c.num_vertices(), Eigen::Vector2d::Zero());
    for (const auto& e : r.edges) {
      ASSERT_FALSE(e.path.empty());
      // The path is a chain of original halfedges from i to j.
      EXPECT_EQ(c.tail(e.path.front()), e.i);
      EXPECT_EQ(c.head(e.path.back()), e.j);
      Eigen::Vector2d d = Eigen::Vector2d::Zero();
      for (size_t q = 0; q < e.path.size(); ++q) {
        if (q) EXPECT_EQ(c.tail(e.path[q]), c.head(e.path[q - 1]));
        d += t.displacement[e.path[q]];
      }
      // In a flat metric with trivial holonomy the developed path is the edge.
      EXPECT_NEAR(d.norm(), e.length, 1e-10);
      balance[e.i] += e.cot_weight * d;
      balance[e.j] -= e.cot_weight * d;
    }
    // Cotangent weights reproduce linear functions: sum_j w_ij (x_j - x_i) = 0.
    for (const auto& b : balance) EXPECT_LT(b.norm(), 1e-10);
  }
}

TEST(IntrinsicDelaunay, KeptEdgesAreNeverFlipped) {
  // IntrinsicDelaunayOptions::keep: the edges the free run flips, kept, stay edges of the result
  // (same endpoints, their own halfedge as path) and are the only non-Delaunay ones left.
  FlatTorus t = flat_torus(14, 11, 0.9, 0.35, 1u);
  Connectivity c(t.F);
  attach_metric(t, c);
  const auto free_run = intrinsic_delaunay(c, t.lengths);
  IntrinsicDelaunayOptions o;
  o.keep.assign(c.num_edges(), 0);
  int kept = 0;
  for (int e = 0; e < c.num_edges() && kept < 5; ++e)
    if (free_run.edges[e].path.size() > 1) o.keep[e] = 1, ++kept;
  ASSERT_EQ(kept, 5);
  const auto r = intrinsic_delaunay(c, t.lengths, o);
  EXPECT_FALSE(r.delaunay);
  EXPECT_EQ(r.degree_limited, 0);
  for (int e = 0; e < c.num_edges(); ++e) {
    if (o.keep[e]) {
      EXPECT_EQ(r.edges[e].path, std::vector<int>{c.edge_halfedge(e)}) << e;
    } else {
      EXPECT_GE(r.edges[e].cot_weight, -1e-12) << e;
    }
  }
  o.keep.pop_back();
  EXPECT_THROW(intrinsic_delaunay(c, t.lengths, o), InputError);
}

TEST(IntrinsicDelaunay, PreservesConeAnglesAndAreaOnCurvedSurface) {
  // Torus of revolution with skinny triangles (few segments around the tube).
  const int n = 60, m = 7;
  RowMatrixX3d V(n * m, 3);
  RowMatrixX3i F(2 * n * m, 3);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double u = 2 * M_PI * i / n, v = 2 * M_PI * (j + 0.37 * i) / m;
      V.row(i * m + j) << (1 + 0.3 * std::cos(v)) * std::cos(u), (1 + 0.3 * std::cos(v)) * std::sin(u),
          0.3 * std::sin(v);
    }
  int f = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const int a = i * m + j, b = ((i + 1) % n) * m + j, c2 = ((i + 1) % n) * m + (j + 1) % m,
                d = i * m + (j + 1) % m;
      F.row(f++) << a, b, c2;
      F.row(f++) << a, c2, d;
    }
  Connectivity c(F);
  Eigen::VectorXd L(c.num_edges());
  for (int e = 0; e < c.num_edges(); ++e) L[e] = (V.row(c.edge_vertex(e, 0)) - V.row(c.edge_vertex(e, 1))).norm();
  auto angle_sums_and_area = [&](const RowMatrixX3i& faces, const RowMatrixX3i& face_edges,
                                 const std::function<double(int)>& len) {
    std::vector<double> sums(V.rows(), 0.0);
    double area = 0;
    for (int t = 0; t < faces.rows(); ++t) {
      const double a = len(face_edges(t, 0)), b = len(face_edges(t, 1)), cc = len(face_edges(t, 2));
      // angle at corner k is opposite side k+1
      const double s[3] = {a, b, cc};
      for (int k = 0; k < 3; ++k) {
        const double opp = s[(k + 1) % 3], x = s[k], y = s[(k + 2) % 3];
        sums[faces(t, k)] += std::acos(std::clamp((x * x + y * y - opp * opp) / (2 * x * y), -1.0, 1.0));
      }
      const double p = 0.5 * (a + b + cc);
      area += std::sqrt(std::max(p * (p - a) * (p - b) * (p - cc), 0.0));
    }
    return std::make_pair(sums, area);
  };
  RowMatrixX3i fe(c.num_faces(), 3);
  for (int h = 0; h < c.num_halfedges(); ++h) fe(h / 3, h % 3) = c.edge(h);
  const auto before = angle_sums_and_area(F, fe, [&](int e) { return L[e]; });
  const auto r = intrinsic_delaunay(c, L);
  EXPECT_TRUE(r.delaunay);
  EXPECT_GT(r.flips, 0);
  const auto after = angle_sums_and_area(r.F, r.face_edges, [&](int e) { return r.edges[e].length; });
  for (int v = 0; v < V.rows(); ++v) EXPECT_NEAR(before.first[v], after.first[v], 1e-9);
  EXPECT_NEAR(before.second, after.second, 1e-9 * before.second);
  for (const auto& e : r.edges) EXPECT_GE(e.cot_weight, -1e-12);
}

// Angle sum at every vertex and total area of a triangulation given by its
// faces, face-side edges (corner-k side) and edge lengths.
std::pair<std::vector<double>, double> angle_sums_and_area(int nv, const RowMatrixX3i& faces,
                                                           const RowMatrixX3i& face_edges,
                                                           const std::function<double(int)>& len) {
  std::vector<double> sums(nv, 0.0);
  double area = 0;
  for (int t = 0; t < faces.rows(); ++t) {
    const double s[3] = {len(face_edges(t, 0)), len(face_edges(t, 1)), len(face_edges(t, 2))};
    for (int k = 0; k < 3; ++k) {  // the angle at corner k is opposite side k+1
      const double opp = s[(k + 1) % 3], x = s[k], y = s[(k + 2) % 3];
      sums[faces(t, k)] += std::acos(std::clamp((x * x + y * y - opp * opp) / (2 * x * y), -1.0, 1.0));
    }
    const double p = 0.5 * (s[0] + s[1] + s[2]);
    area += std::sqrt(std::max(p * (p - s[0]) * (p - s[1]) * (p - s[2]), 0.0));
  }
  return {sums, area};
}

// The intrinsic triangulation is a valid one of the same metric: every
// vertex keeps its angle sum, the area is unchanged, every edge's path
// chains original halfedges from i to j, every face side runs along or
// against its edge as face_edge_forward says; returns the edge ends at each vertex.
std::vector<int> expect_same_metric(const Connectivity& c, const Eigen::VectorXd& L, const IntrinsicDelaunayResult& r) {
  RowMatrixX3i fe(c.num_faces(), 3);
  for (int h = 0; h < c.num_halfedges(); ++h) fe(h / 3, h % 3) = c.edge(h);
  const auto before = angle_sums_and_area(c.num_vertices(), c.faces(), fe, [&](int e) { return L[e]; });
  const auto after = angle_sums_and_area(c.num_vertices(), r.F, r.face_edges, [&](int e) { return r.edges[e].length; });
  for (int v = 0; v < c.num_vertices(); ++v) EXPECT_NEAR(before.first[v], after.first[v], 1e-9) << "vertex " << v;
  EXPECT_NEAR(before.second, after.second, 1e-9 * before.second);
  std::vector<int> degree(c.num_vertices(), 0);
  for (const auto& e : r.edges) {
    EXPECT_EQ(c.tail(e.path.front()), e.i);
    EXPECT_EQ(c.head(e.path.back()), e.j);
    for (size_t q = 1; q < e.path.size(); ++q) EXPECT_EQ(c.tail(e.path[q]), c.head(e.path[q - 1]));
    ++degree[e.i], ++degree[e.j];
  }
  for (int f = 0; f < r.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const auto& e = r.edges[r.face_edges(f, k)];
      const int a = r.F(f, k), b = r.F(f, (k + 1) % 3);
      if (r.face_edge_forward(f, k)) EXPECT_TRUE(e.i == a && e.j == b) << "face " << f;
      else EXPECT_TRUE(e.i == b && e.j == a) << "face " << f;
    }
  return degree;
}

TEST(IntrinsicDelaunay, NeedleTipNeedsAVertexWithOneEdge) {
  // g1_twirl's failure: a tip of cone angle < pi whose nearest neighbour is
  // much closer than the rest. Delaunay needs the flip that leaves it a
  // single edge inside a face whose two sides are that edge.
  const TriMesh mesh = samples::needle(samples::torus_of_revolution(1.0, 0.35, 48, 16), 0, 0.8, 0.2);
  const Connectivity c(mesh.F, mesh.num_vertices());
  Eigen::VectorXd L(c.num_edges());
  for (int e = 0; e < c.num_edges(); ++e)
    L[e] = (mesh.V.row(c.edge_vertex(e, 0)) - mesh.V.row(c.edge_vertex(e, 1))).norm();
  RowMatrixX3i fe(c.num_faces(), 3);
  for (int h = 0; h < c.num_halfedges(); ++h) fe(h / 3, h % 3) = c.edge(h);
  const auto input = angle_sums_and_area(c.num_vertices(), c.faces(), fe, [&](int e) { return L[e]; });
  ASSERT_LT(input.first[0], M_PI);

  // Default (min_degree 2): the flip is refused, the edge stays non-Delaunay.
  const auto limited2 = intrinsic_delaunay(c, L);
  EXPECT_FALSE(limited2.delaunay);
  EXPECT_GE(limited2.degree_limited, 1);
  EXPECT_LT(limited2.min_cot_weight, -1e-3);

  // Bobenko–Springborn (min_degree 1): Delaunay, the tip has one edge.
  IntrinsicDelaunayOptions full;
  full.min_degree = 1;
  const auto r1 = intrinsic_delaunay(c, L, full);
  EXPECT_TRUE(r1.delaunay);
  EXPECT_EQ(r1.degree_limited, 0);
  EXPECT_GE(r1.min_cot_weight, -1e-12);
  const std::vector<int> d1 = expect_same_metric(c, L, r1);
  EXPECT_EQ(d1[0], 1);
  // The face holding the tip: two sides are its single edge, one way each.
  int holding = 0;
  for (int f = 0; f < r1.F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (r1.F(f, k) == 0) {
        ++holding;
        EXPECT_EQ(r1.face_edges(f, k), r1.face_edges(f, (k + 2) % 3));
        EXPECT_NE(r1.face_edge_forward(f, k), r1.face_edge_forward(f, (k + 2) % 3));
      }
  EXPECT_EQ(holding, 1);

  // min_degree 3: every vertex keeps >= 3 edges; only the limited edges
  // stay negative.
  IntrinsicDelaunayOptions three;
  three.min_degree = 3;
  const auto r3 = intrinsic_delaunay(c, L, three);
  EXPECT_FALSE(r3.delaunay);
  const std::vector<int> d3 = expect_same_metric(c, L, r3);
  EXPECT_GE(*std::min_element(d3.begin(), d3.end()), 3);
  int negative = 0;
  for (const auto& e : r3.edges) negative += e.cot_weight < -1e-12;
  EXPECT_EQ(negative, r3.degree_limited);
  EXPECT_GE(negative, 1);

  // The source's energy weights: those of r3 with the negative ones raised.
  const auto w = delaunay_energy_weights(c, L);
  EXPECT_TRUE(w.delaunay);
  EXPECT_EQ(w.raised_weights, negative);
  EXPECT_EQ(w.flips, r3.flips);
  ASSERT_EQ(w.edges.size(), r3.edges.size());
  for (size_t e = 0; e < w.edges.size(); ++e) {
    if (r3.edges[e].cot_weight < -1e-12) EXPECT_GT(w.edges[e].cot_weight, 0);
    else EXPECT_EQ(w.edges[e].cot_weight, r3.edges[e].cot_weight);
  }
  // Without the needle nothing changes: the plain Delaunay triangulation.
  const TriMesh plain = samples::torus_of_revolution(1.0, 0.35, 48, 16);
  const Connectivity pc(plain.F, plain.num_vertices());
  Eigen::VectorXd PL(pc.num_edges());
  for (int e = 0; e < pc.num_edges(); ++e)
    PL[e] = (plain.V.row(pc.edge_vertex(e, 0)) - plain.V.row(pc.edge_vertex(e, 1))).norm();
  const auto pw = delaunay_energy_weights(pc, PL), pd = intrinsic_delaunay(pc, PL);
  EXPECT_TRUE(pw.delaunay);
  EXPECT_EQ(pw.raised_weights, 0);
  EXPECT_EQ(pw.flips, pd.flips);
  EXPECT_EQ(pw.F, pd.F);
}

TEST(IntrinsicDelaunay, RejectsBadLengths) {
  RowMatrixX3i F(8, 3);
  F << 0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5;
  Connectivity c(F);
  Eigen::VectorXd L = Eigen::VectorXd::Ones(c.num_edges());
  EXPECT_NO_THROW(intrinsic_delaunay(c, L));
  L[3] = 5.0;
  EXPECT_THROW(intrinsic_delaunay(c, L), InputError);
  EXPECT_THROW(intrinsic_delaunay(c, Eigen::VectorXd::Ones(3)), InputError);
}

}  // namespace
}  // namespace surfmap
