// Properties of the greedy system of loops and its refinement (docs/method.md §2.2):
// 2g simple loops through x, pairwise disjoint except at x, cutting the
// surface into one disk whose boundary reads a 4g-gon word; refined vertices
// lie on the input surface; T and T* are complementary spanning trees.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <Eigen/Geometry>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/topology/cut_mesh.h"
#include "surfmap/topology/system_of_loops.h"

namespace surfmap {
namespace {

double surface_area(const TriMesh& m) {
  double a = 0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d p0 = m.V.row(m.F(f, 0)), p1 = m.V.row(m.F(f, 1)), p2 = m.V.row(m.F(f, 2));
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

bool equal_up_to_rotation(const std::vector<int>& a, const std::vector<int>& b) {
  if (a.size() != b.size()) return false;
  for (size_t r = 0; r < a.size(); ++r) {
    bool ok = true;
    for (size_t i = 0; i < a.size() && ok; ++i) ok = a[(i + r) % a.size()] == b[i];
    if (ok) return true;
  }
  return a.empty();
}

// Reads the word off the cut mesh's boundary independently of the library's
// own boundary walk: sides start at copies of x, and the first step names
// the loop and its direction.
std::vector<int> word_from_cut(const CutMesh& cut, const SystemOfLoops& s) {
  std::map<std::pair<int, int>, int> first_step;
  for (int k = 0; k < static_cast<int>(s.loops.size()); ++k) {
    const auto& L = s.loops[k];
    first_step[{L[0], L[1]}] = k + 1;
    first_step[{L[L.size() - 1], L[L.size() - 2]}] = -(k + 1);
  }
  std::vector<int> word;
  const auto& B = cut.boundary_loops.at(0);
  for (size_t i = 0; i < B.size(); ++i) {
    const int a = cut.original_vertex[B[i]], b = cut.original_vertex[B[(i + 1) % B.size()]];
    if (a != s.base_vertex) continue;
    auto it = first_step.find({a, b});
    EXPECT_NE(it, first_step.end()) << "boundary side starting at x with unknown first step";
    if (it != first_step.end()) word.push_back(it->second);
  }
  return word;
}

void check_word_letters(const std::vector<int>& word, int g) {
  ASSERT_EQ(static_cast<int>(word.size()), 4 * g);
  std::multiset<int> letters(word.begin(), word.end());
  for (int k = 1; k <= 2 * g; ++k) {
    EXPECT_EQ(letters.count(k), 1u) << "letter " << k;
    EXPECT_EQ(letters.count(-k), 1u) << "letter -" << k;
  }
}

// T (per vertex) and T* (per face) are spanning trees, T* never crosses a
// loop edge, and T, T*-crossed edges and generators partition the edges.
void check_trees(const SystemOfLoops& s, const Connectivity& conn, const std::vector<char>& loop_edge) {
  const int nv = conn.num_vertices(), nf = conn.num_faces(), ne = conn.num_edges(), g = s.genus;
  ASSERT_EQ(static_cast<int>(s.tree_parent_halfedge.size()), nv);
  ASSERT_EQ(static_cast<int>(s.dual_tree_parent_halfedge.size()), nf);
  std::vector<int> role(ne, 0);  // 1 tree, 2 dual, 3 generator
  for (int v = 0; v < nv; ++v) {
    const int h = s.tree_parent_halfedge[v];
    if (v == s.base_vertex) {
      EXPECT_EQ(h, -1);
      continue;
    }
    ASSERT_GE(h, 0) << "vertex " << v << " has no tree parent";
    ASSERT_EQ(conn.head(h), v);
    EXPECT_EQ(role[conn.edge(h)], 0);
    role[conn.edge(h)] = 1;
  }
  // Reaches x without cycles.
  std::vector<int> depth(nv, -1);
  depth[s.base_vertex] = 0;
  for (int v = 0; v < nv; ++v) {
    std::vector<int> chain;
    int w = v;
    while (depth[w] < 0) {
      chain.push_back(w);
      w = conn.tail(s.tree_parent_halfedge[w]);
      ASSERT_LE(chain.size(), static_cast<size_t>(nv)) << "cycle in T";
    }
    int d = depth[w];
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) depth[*it] = ++d;
  }
  int roots = 0;
  for (int f = 0; f < nf; ++f) {
    const int h = s.dual_tree_parent_halfedge[f];
    if (h < 0) {
      ++roots;
      continue;
    }
    ASSERT_EQ(Connectivity::face(h), f);
    EXPECT_FALSE(loop_edge[conn.edge(h)]) << "T* crosses a loop edge";
    EXPECT_EQ(role[conn.edge(h)], 0) << "edge in both T and T*";
    role[conn.edge(h)] = 2;
  }
  EXPECT_EQ(roots, 1);
  std::vector<int> fdepth(nf, -1);
  for (int f = 0; f < nf; ++f) {
    std::vector<int> chain;
    int c = f;
    while (fdepth[c] < 0 && s.dual_tree_parent_halfedge[c] >= 0) {
      chain.push_back(c);
      c = Connectivity::face(conn.twin(s.dual_tree_parent_halfedge[c]));
      ASSERT_LE(chain.size(), static_cast<size_t>(nf)) << "cycle in T*";
    }
    if (fdepth[c] < 0) fdepth[c] = 0;
    int d = fdepth[c];
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) fdepth[*it] = ++d;
  }
  ASSERT_EQ(static_cast<int>(s.generator_edges.size()), 2 * g);
  for (int e : s.generator_edges) {
    EXPECT_EQ(role[e], 0) << "generator edge in T or T*";
    role[e] = 3;
  }
  for (int e = 0; e < ne; ++e) EXPECT_NE(role[e], 0) << "edge " << e << " in none of T, T*, generators";
  // Loop k = path(x, a) + generator k + path(b, x).
  for (int k = 0; k < 2 * g; ++k) {
    const int h = conn.edge_halfedge(s.generator_edges[k]);
    auto path_to = [&](int v) {
      std::vector<int> p;
      for (; v != s.base_vertex; v = conn.tail(s.tree_parent_halfedge[v])) p.push_back(v);
      p.push_back(s.base_vertex);
      std::reverse(p.begin(), p.end());
      return p;
    };
    std::vector<int> loop = path_to(conn.tail(h));
    std::vector<int> back = path_to(conn.head(h));
    loop.insert(loop.end(), back.rbegin(), back.rend());
    std::vector<int> rev(loop.rbegin(), loop.rend());
    EXPECT_TRUE(loop == s.loops[k] || rev == s.loops[k]) << "loop " << k << " is not path+generator+path";
  }
}

void check_refined(const TriMesh& input, const SystemOfLoops& s) {
  const int g = s.genus;
  const int x = s.base_vertex;
  ASSERT_EQ(static_cast<int>(s.loops.size()), 2 * g);
  const TriMesh& m = s.mesh;
  const Connectivity conn(m.F, m.num_vertices());
  EXPECT_EQ(conn.genus(), g);
  // Refined vertices reproduce their positions from their origin.
  ASSERT_EQ(static_cast<int>(s.origin_face.size()), m.num_vertices());
  ASSERT_EQ(s.origin_barycentric.rows(), m.num_vertices());
  const double scale = (input.V.colwise().maxCoeff() - input.V.colwise().minCoeff()).norm();
  for (int v = 0; v < m.num_vertices(); ++v) {
    const int f = s.origin_face[v];
    ASSERT_GE(f, 0);
    ASSERT_LT(f, input.num_faces());
    const Eigen::RowVector3d b = s.origin_barycentric.row(v);
    EXPECT_NEAR(b.sum(), 1.0, 1e-12);
    EXPECT_GE(b.minCoeff(), 0.0);
    Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k) p += b[k] * input.V.row(input.F(f, k));
    EXPECT_LT((p - m.V.row(v)).norm(), 1e-12 * scale) << "vertex " << v;
    if (v < input.num_vertices()) EXPECT_EQ(m.V.row(v), input.V.row(v));
  }
  // Refinement only splits faces: the same area, no overlapping triangles.
  EXPECT_NEAR(surface_area(m), surface_area(input), 1e-9 * surface_area(input));
  // Loops: closed edge paths from x, simple, disjoint except at x.
  std::vector<int> owner(m.num_vertices(), -1);
  std::vector<char> loop_edge(conn.num_edges(), 0);
  size_t total = 0;
  for (int k = 0; k < 2 * g; ++k) {
    const auto& L = s.loops[k];
    ASSERT_GE(L.size(), 3u);
    EXPECT_EQ(L.front(), x);
    EXPECT_EQ(L.back(), x);
    total += L.size() - 1;
    for (size_t i = 0; i + 1 < L.size(); ++i) {
      const int h = conn.find_halfedge(L[i], L[i + 1]);
      ASSERT_GE(h, 0) << "loop " << k << " step " << i << " is not an edge";
      EXPECT_FALSE(loop_edge[conn.edge(h)]) << "edge used twice";
      loop_edge[conn.edge(h)] = 1;
      if (i > 0) {
        EXPECT_NE(L[i], x) << "loop " << k << " passes x twice";
        EXPECT_EQ(owner[L[i]], -1) << "vertex " << L[i] << " on loops " << owner[L[i]] << " and " << k;
        owner[L[i]] = k;
      }
    }
  }
  // Cutting gives one disk bounded by the 4g-gon.
  const CutMesh cut = cut_mesh(m, s.loops);
  EXPECT_EQ(cut.euler_characteristic, 1);
  ASSERT_EQ(cut.boundary_loops.size(), 1u);
  EXPECT_EQ(cut.boundary_loops[0].size(), 2 * total);
  int x_copies = 0;
  for (int v : cut.boundary_loops[0]) x_copies += cut.original_vertex[v] == x ? 1 : 0;
  EXPECT_EQ(x_copies, 4 * g);
  check_word_letters(s.word, g);
  EXPECT_TRUE(equal_up_to_rotation(word_from_cut(cut, s), s.word));
  EXPECT_FALSE(s.word_text.empty());
  check_trees(s, conn, loop_edge);
}

struct Case {
  const char* name;
  TriMesh mesh;
  int genus;
};

const std::vector<Case>& shapes() {
  static std::vector<Case> c;  // generated once for all tests
  if (!c.empty()) return c;
  c.push_back({"torus", samples::torus_of_revolution(2.0, 0.7, 30, 14, 1), 1});
  c.push_back({"thin_torus", samples::torus_of_revolution(1.0, 0.1, 40, 5, 3), 1});
  for (int g = 1; g <= 6; ++g) c.push_back({"n_hole", samples::n_hole_torus(g, 28, true), g});
  c.push_back({"ugly_3", samples::n_hole_torus(3, 24, false), 3});
  c.push_back({"jittered_2", samples::jitter(samples::n_hole_torus(2, 24, true), 0.25, 7u), 2});
  return c;
}

TEST(SystemOfLoops, RefinedLoopsAreSimpleAndCutToADisk) {
  for (const Case& c : shapes()) {
    SCOPED_TRACE(std::string(c.name) + " genus " + std::to_string(c.genus));
    const int nv = c.mesh.num_vertices();
    for (int base : {-1, 0, nv / 2, nv - 1, (nv * 7) / 13}) {
      SCOPED_TRACE("base " + std::to_string(base));
      SystemOfLoopsOptions opt;
      opt.base_vertex = base;
      const SystemOfLoops s = system_of_loops(c.mesh, opt);
      EXPECT_EQ(s.genus, c.genus);
      if (base >= 0) EXPECT_EQ(s.base_vertex, base);
      EXPECT_TRUE(s.shortcut_used);
      check_refined(c.mesh, s);
      if (base == 0 || base == -1) {  // the full Euler-tour fallback, too
        opt.shortcut_branches = false;
        const SystemOfLoops full = system_of_loops(c.mesh, opt);
        EXPECT_FALSE(full.shortcut_used);
        check_refined(c.mesh, full);
        EXPECT_TRUE(equal_up_to_rotation(full.word, s.word));
      }
      if (::testing::Test::HasFailure()) return;
    }
  }
}

TEST(SystemOfLoops, UnrefinedGreedyLoopsCutToADiskAndGiveTheSameWord) {
  for (const Case& c : shapes()) {
    SCOPED_TRACE(c.name);
    for (int base : {-1, 3}) {
      SystemOfLoopsOptions opt;
      opt.base_vertex = base;
      opt.refine = false;
      const SystemOfLoops s = system_of_loops(c.mesh, opt);
      ASSERT_EQ(static_cast<int>(s.loops.size()), 2 * c.genus);
      EXPECT_EQ(s.mesh.V, c.mesh.V);
      const Connectivity conn(s.mesh.F, s.mesh.num_vertices());
      // Cut along T and the generators: one disk.
      std::vector<char> cut(conn.num_edges(), 0), loop_edge(conn.num_edges(), 0);
      for (int v = 0; v < conn.num_vertices(); ++v)
        if (s.tree_parent_halfedge[v] >= 0) cut[conn.edge(s.tree_parent_halfedge[v])] = 1;
      for (int e : s.generator_edges) cut[e] = 1;
      for (const auto& L : s.loops)
        for (size_t i = 0; i + 1 < L.size(); ++i) loop_edge[conn.edge(conn.find_halfedge(L[i], L[i + 1]))] = 1;
      const CutMesh d = cut_mesh_along_edges(s.mesh, conn, cut);
      EXPECT_EQ(d.euler_characteristic, 1);
      EXPECT_EQ(d.boundary_loops.size(), 1u);
      check_word_letters(s.word, c.genus);
      check_trees(s, conn, loop_edge);
      // The greedy loops are shortest-path loops; the refined ones are
      // homotopic to them, so both systems read the same relator.
      opt.refine = true;
      const SystemOfLoops r = system_of_loops(c.mesh, opt);
      EXPECT_EQ(r.base_vertex, s.base_vertex);
      EXPECT_TRUE(equal_up_to_rotation(r.word, s.word)) << r.word_text << " vs " << s.word_text;
    }
  }
}

// The same loops from two constructions: base vertex, both trees, the
// generators, the loops, the word and the (refined) mesh's vertices.
void expect_same_loops(const SystemOfLoops& a, const SystemOfLoops& b) {
  EXPECT_EQ(a.base_vertex, b.base_vertex);
  EXPECT_EQ(a.tree_parent_halfedge, b.tree_parent_halfedge);
  EXPECT_EQ(a.dual_tree_parent_halfedge, b.dual_tree_parent_halfedge);
  EXPECT_EQ(a.generator_edges, b.generator_edges);
  EXPECT_EQ(a.loops, b.loops);
  EXPECT_EQ(a.word, b.word);
  EXPECT_EQ(a.mesh.V, b.mesh.V);
}

// Issue 19: refine_system_of_loops reads the greedy basis off an unrefined
// system instead of computing it again; the refined system must be the one
// system_of_loops(refine = true) builds at that base vertex, field by field
// (both constructions, with the shortcut and without), and loops of another
// mesh or a refined system are refused.
TEST(SystemOfLoops, RefiningUnrefinedLoopsEqualsRefiningFromScratch) {
  for (const Case& c : shapes()) {
    SCOPED_TRACE(c.name + std::string(" genus ") + std::to_string(c.genus));
    const Connectivity conn(c.mesh.F, c.mesh.num_vertices());
    for (int base : {-1, 3, (c.mesh.num_vertices() * 7) / 13}) {
      for (bool shortcut : {true, false}) {
        SCOPED_TRACE("base " + std::to_string(base) + (shortcut ? " shortcut" : " full"));
        SystemOfLoopsOptions opt;
        opt.base_vertex = base;
        opt.shortcut_branches = shortcut;
        opt.refine = false;
        const SystemOfLoops u = system_of_loops(c.mesh, conn, opt);
        opt.refine = true;
        const SystemOfLoops fresh = system_of_loops(c.mesh, conn, opt);
        SystemOfLoopsOptions other = opt;
        other.base_vertex = -1;  // not read: the base vertex is u's
        const SystemOfLoops r = refine_system_of_loops(c.mesh, conn, u, other);
        expect_same_loops(r, fresh);
        EXPECT_EQ(r.mesh.F, fresh.mesh.F);
        EXPECT_EQ(r.origin_face, fresh.origin_face);
        EXPECT_EQ(r.origin_barycentric, fresh.origin_barycentric);
        EXPECT_EQ(r.face_origin, fresh.face_origin);
        EXPECT_EQ(r.shortcut_used, fresh.shortcut_used);
        check_refined(c.mesh, r);
        if (::testing::Test::HasFailure()) return;
      }
    }
  }
  const TriMesh t = samples::torus_of_revolution(2.0, 0.5, 12, 8);
  const Connectivity tc(t.F, t.num_vertices());
  const SystemOfLoops refined = system_of_loops(t, tc);
  EXPECT_THROW(refine_system_of_loops(t, tc, refined), InputError);
  SystemOfLoopsOptions opt;
  opt.refine = false;
  const TriMesh g2 = samples::n_hole_torus(2, 28, true);
  EXPECT_THROW(refine_system_of_loops(t, tc, system_of_loops(g2, opt)), InputError);
}

// Issue 19: one GreedyGraph per mesh, shared by the systems of loops at
// many base vertices (the pipeline's source cuts), gives the loops each
// call builds on its own, refined or not; a graph of another mesh is an
// InputError.
TEST(SystemOfLoops, SharedGreedyGraphGivesTheSameLoops) {
  for (const Case& c : shapes()) {
    SCOPED_TRACE(c.name + std::string(" genus ") + std::to_string(c.genus));
    const Connectivity conn(c.mesh.F, c.mesh.num_vertices());
    const GreedyGraph graph(c.mesh, conn);
    const int nv = c.mesh.num_vertices();
    for (int base : {-1, 0, nv / 3, nv / 2, nv - 1})
      for (bool refine : {false, true}) {
        SCOPED_TRACE("base " + std::to_string(base) + (refine ? " refined" : " unrefined"));
        SystemOfLoopsOptions opt;
        opt.base_vertex = base;
        opt.refine = refine;
        const SystemOfLoops own = system_of_loops(c.mesh, conn, opt);
        const SystemOfLoops shared = system_of_loops(c.mesh, conn, opt, &graph);
        expect_same_loops(shared, own);
        if (::testing::Test::HasFailure()) return;
      }
  }
  const TriMesh t = samples::torus_of_revolution(2.0, 0.5, 12, 8);
  const TriMesh g2 = samples::n_hole_torus(2, 28, true);
  const Connectivity tc(t.F, t.num_vertices()), gc(g2.F, g2.num_vertices());
  const GreedyGraph other(g2, gc);
  EXPECT_THROW(system_of_loops(t, tc, {}, &other), InputError);
  EXPECT_THROW(GreedyGraph(tc, std::vector<double>(3, 1.0)), InputError);
}

TEST(SystemOfLoops, CoarsestToriFromEveryBaseVertex) {
  // 9 to 16 vertices: every face near x carries several arcs, bends and
  // crossings at once.
  for (int variant = 0; variant < 4; ++variant)
    for (int n : {3, 4}) {
      const TriMesh t = samples::torus_of_revolution(2.0, 0.6, n, 3, variant);
      for (int base = 0; base < t.num_vertices(); ++base) {
        SCOPED_TRACE("variant " + std::to_string(variant) + " n " + std::to_string(n) + " base " + std::to_string(base));
        SystemOfLoopsOptions opt;
        opt.base_vertex = base;
        const SystemOfLoops s = system_of_loops(t, opt);
        EXPECT_TRUE(s.shortcut_used);
        check_refined(t, s);
        if (::testing::Test::HasFailure()) return;
      }
    }
}

// Loops in given edge weights (SystemOfLoopsOptions::edge_weights: the
// uniformization metric in uniformize): the base vertex is the weights'
// centre and T* a shortest-path tree of the dual. On a plate of 5 holes in a
// row (x in [0, 5]) weighted by 3D length the centre lies near x = 2.5; the
// loops must pass the same checks as the greedy ones (simple, disjoint, one
// disk with a 4g-gon word, T and T* spanning trees), and weights of the
// wrong size or non-positive are InputErrors.
TEST(SystemOfLoops, LoopsInGivenEdgeWeightsFromTheirCentre) {
  const TriMesh plate = samples::cad_plate(5, 16, 0.5);
  const Connectivity conn(plate.F, plate.num_vertices());
  std::vector<double> w(conn.num_edges());
  for (int e = 0; e < conn.num_edges(); ++e)
    w[e] = (plate.V.row(conn.edge_vertex(e, 0)) - plate.V.row(conn.edge_vertex(e, 1))).norm();
  const int centre = metric_centre_vertex(conn, w);
  EXPECT_NEAR(plate.V(centre, 0), 2.5, 0.75);
  // Weights stretching x by 10 beyond x = 4 move the centre right.
  std::vector<double> stretched = w;
  for (int e = 0; e < conn.num_edges(); ++e)
    if (plate.V(conn.edge_vertex(e, 0), 0) > 4 && plate.V(conn.edge_vertex(e, 1), 0) > 4) stretched[e] *= 10;
  EXPECT_GT(plate.V(metric_centre_vertex(conn, stretched), 0), 3.0);
  SystemOfLoopsOptions opt;
  opt.edge_weights = w;
  const SystemOfLoops s = system_of_loops(plate, opt);
  EXPECT_EQ(s.genus, 5);
  EXPECT_EQ(s.base_vertex, centre);
  check_refined(plate, s);
  opt.refine = false;
  const SystemOfLoops u = system_of_loops(plate, opt);
  const Connectivity uc(u.mesh.F, u.mesh.num_vertices());
  std::vector<char> loop_edge(uc.num_edges(), 0);
  for (const auto& L : u.loops)
    for (size_t i = 0; i + 1 < L.size(); ++i) loop_edge[uc.edge(uc.find_halfedge(L[i], L[i + 1]))] = 1;
  check_word_letters(u.word, 5);
  check_trees(u, uc, loop_edge);
  opt.edge_weights.pop_back();
  EXPECT_THROW(system_of_loops(plate, opt), InputError);
  opt.edge_weights = w;
  opt.edge_weights[3] = 0;
  EXPECT_THROW(system_of_loops(plate, opt), InputError);
}

TEST(SystemOfLoops, GenusZeroAndBadBaseVertexAreInputErrors) {
  EXPECT_THROW(system_of_loops(samples::sphere(2)), InputError);
  SystemOfLoopsOptions opt;
  const TriMesh t = samples::torus_of_revolution(2.0, 0.5, 12, 8);
  opt.base_vertex = t.num_vertices();
  EXPECT_THROW(system_of_loops(t, opt), InputError);
}

TEST(CutMesh, CuttingATorusAlongAMeridianGivesAnAnnulus) {
  // Independent of the loop code: a hand-made meridian on a grid torus.
  const int nmaj = 10, nmin = 6;
  const TriMesh t = samples::torus_of_revolution(2.0, 0.5, nmaj, nmin);
  const Connectivity conn(t.F, t.num_vertices());
  // Vertices i*nmin + j lie on one meridian for fixed i (grid layout).
  std::vector<int> meridian;
  for (int j = 0; j <= nmin; ++j) meridian.push_back(j % nmin);
  bool is_edge_path = true;
  for (size_t i = 0; i + 1 < meridian.size(); ++i) is_edge_path &= conn.find_halfedge(meridian[i], meridian[i + 1]) >= 0;
  if (!is_edge_path) {  // other grid layout: vertices i + j*nmaj
    meridian.clear();
    for (int j = 0; j <= nmin; ++j) meridian.push_back((j % nmin) * nmaj);
  }
  const CutMesh c = cut_mesh(t, {meridian});
  EXPECT_EQ(c.euler_characteristic, 0);
  EXPECT_EQ(c.boundary_loops.size(), 2u);
  EXPECT_EQ(c.mesh.num_vertices(), t.num_vertices() + nmin);
  EXPECT_THROW(cut_mesh(t, {{0, t.num_vertices() / 2 + 3}}), InputError);
}

}  // namespace
}  // namespace surfmap
