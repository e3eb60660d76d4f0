#include "surfmap/topology/edge_homotopy.h"
#include "surfmap/topology/edge_words.h"

#include <gtest/gtest.h>

#include "surfmap/samples/shapes.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/topology/words.h"

namespace surfmap {
namespace {

const GroupOps<Word> kFreeGroup{Word{}, [](const Word& a, const Word& b) { return concat(a, b); },
                                [](const Word& a) { return inverse(a); }};

// A system of loops (refined or not, at a base vertex) and every edge's
// free-group element: loop k is the letter k + 1.
struct FreeGroupEdges {
  SystemOfLoops loops;
  Connectivity conn;
  std::vector<Word> value;
  FreeGroupEdges(const TriMesh& mesh, bool refine, int base_vertex)
      : loops(system_of_loops(mesh, options(refine, base_vertex))), conn(loops.mesh.F, loops.mesh.num_vertices()) {
    std::vector<Word> letters;
    for (size_t k = 0; k < loops.loops.size(); ++k) letters.push_back({static_cast<int>(k) + 1});
    value = edge_group_elements(conn, loops.tree_parent_halfedge, loops.dual_tree_parent_halfedge,
                                loops.generator_edges, loop_first_vertices(loops, conn), letters, kFreeGroup);
  }
  static SystemOfLoopsOptions options(bool refine, int base_vertex) {
    SystemOfLoopsOptions opt;
    opt.refine = refine;
    opt.base_vertex = base_vertex;
    return opt;
  }
};

void check_free_group_elements(const TriMesh& mesh, bool refine, int base_vertex) {
  const FreeGroupEdges free(mesh, refine, base_vertex);
  const SystemOfLoops& s = free.loops;
  const Connectivity& c = free.conn;
  const std::vector<Word>& value = free.value;
  auto of = [&](int h) {
    const int e = c.edge(h);
    return c.edge_halfedge(e) == h ? value[e] : inverse(value[e]);
  };
  for (int v = 0; v < c.num_vertices(); ++v)
    if (s.tree_parent_halfedge[v] >= 0) EXPECT_TRUE(value[c.edge(s.tree_parent_halfedge[v])].empty());
  int root = -1;
  for (int f = 0; f < c.num_faces(); ++f) {
    const Word around = concat({of(3 * f), of(3 * f + 1), of(3 * f + 2)});
    if (s.dual_tree_parent_halfedge[f] < 0) {
      root = f;
      // Around the root face the relation of the surface appears: the
      // product is conjugate to the boundary word or its inverse.
      EXPECT_TRUE(conjugate(around, s.word) || conjugate(around, inverse(s.word)))
          << "root face product " << to_text(around, {}) << " vs word " << s.word_text;
    } else {
      EXPECT_TRUE(around.empty()) << "face " << f;
    }
  }
  EXPECT_GE(root, 0);
}

TEST(EdgeHomotopy, FreeGroupElementsSatisfyFaceRelations) {
  const TriMesh torus = samples::torus_of_revolution(1.0, 0.4, 24, 12);
  check_free_group_elements(torus, false, -1);
  check_free_group_elements(torus, true, 17);
  const TriMesh g2 = samples::n_hole_torus(2, 40, true);
  check_free_group_elements(g2, false, -1);
  check_free_group_elements(g2, true, 5);
  const TriMesh g3 = samples::n_hole_torus(3, 40, false);  // raw marching tets, slivers
  check_free_group_elements(g3, false, 11);
}

// CutDiskEdgeWords (issue 19) reads single edges' words from the cut disk's
// boundary: every edge's word must be edge_group_elements' word, on greedy
// and refined systems of loops, at other base vertices, and asked for in
// any order (memoized).
void check_cut_disk_words(const TriMesh& mesh, bool refine, int base_vertex) {
  const FreeGroupEdges free(mesh, refine, base_vertex);
  const SystemOfLoops& s = free.loops;
  const Connectivity& c = free.conn;
  const std::vector<Word>& value = free.value;
  const CutDiskEdgeWords words(s, c);
  int nonempty = 0, mismatches = 0;
  for (int e = c.num_edges() - 1; e >= 0; e -= 2) mismatches += words(e) != value[e];
  for (int e = 0; e < c.num_edges(); ++e) {
    if (words(e) != value[e]) {
      ++mismatches;
      ADD_FAILURE() << "edge " << e << ": " << to_text(words(e), {}) << " vs " << to_text(value[e], {});
      if (mismatches > 5) break;
    }
    nonempty += !value[e].empty();
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(nonempty, 60);  // (not only tree edges and the 2g letters)
}

TEST(EdgeHomotopy, CutDiskWordsEqualThePeeledWords) {
  const TriMesh torus = samples::torus_of_revolution(1.0, 0.4, 24, 12);
  check_cut_disk_words(torus, false, -1);
  check_cut_disk_words(torus, true, 17);
  const TriMesh g2 = samples::n_hole_torus(2, 40, true);
  check_cut_disk_words(g2, false, -1);
  check_cut_disk_words(g2, false, g2.num_vertices() / 3);
  check_cut_disk_words(g2, true, 5);
  const TriMesh g3 = samples::n_hole_torus(3, 40, false);  // raw marching tets, slivers
  check_cut_disk_words(g3, false, 11);
  check_cut_disk_words(g3, true, 11);
}

}  // namespace
}  // namespace surfmap
