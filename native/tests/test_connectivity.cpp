#include "surfmap/mesh/connectivity.h"

#include <gtest/gtest.h>

#include <set>

#include "surfmap/error.h"

namespace surfmap {
namespace {

// Octahedron, outward oriented.
RowMatrixX3i octahedron() {
  RowMatrixX3i F(8, 3);
  F << 0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5;
  return F;
}

// n x m torus grid, each quad split in two.
RowMatrixX3i torus_grid(int n, int m) {
  RowMatrixX3i F(2 * n * m, 3);
  int f = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const int a = i * m + j, b = ((i + 1) % n) * m + j, c = ((i + 1) % n) * m + (j + 1) % m,
                d = i * m + (j + 1) % m;
      F.row(f++) << a, b, c;
      F.row(f++) << a, c, d;
    }
  return F;
}

void check_invariants(const Connectivity& c) {
  for (int h = 0; h < c.num_halfedges(); ++h) {
    EXPECT_EQ(c.twin(c.twin(h)), h);
    EXPECT_NE(c.face(c.twin(h)), c.face(h));
    EXPECT_EQ(c.tail(c.twin(h)), c.head(h));
    EXPECT_EQ(c.edge(c.twin(h)), c.edge(h));
    EXPECT_EQ(c.next(c.next(c.next(h))), h);
    EXPECT_EQ(c.tail(c.rotate_ccw(h)), c.tail(h));
  }
  for (int e = 0; e < c.num_edges(); ++e) {
    const int h = c.edge_halfedge(e);
    EXPECT_EQ(c.edge(h), e);
    EXPECT_EQ(c.tail(h), c.edge_vertex(e, 0));
    EXPECT_LT(c.edge_vertex(e, 0), c.edge_vertex(e, 1));
  }
  int valence_sum = 0;
  for (int v = 0; v < c.num_vertices(); ++v) {
    const auto out = c.outgoing(v);
    std::set<int> heads;
    for (int h : out) {
      EXPECT_EQ(c.tail(h), v);
      heads.insert(c.head(h));
      EXPECT_EQ(c.find_halfedge(v, c.head(h)), h);
    }
    EXPECT_EQ(heads.size(), out.size());
    valence_sum += static_cast<int>(out.size());
  }
  EXPECT_EQ(valence_sum, 2 * c.num_edges());
}

TEST(Connectivity, OctahedronIsSphere) {
  Connectivity c(octahedron());
  EXPECT_EQ(c.num_vertices(), 6);
  EXPECT_EQ(c.num_edges(), 12);
  EXPECT_EQ(c.euler_characteristic(), 2);
  EXPECT_EQ(c.genus(), 0);
  check_invariants(c);
}

TEST(Connectivity, TorusGridHasGenusOne) {
  Connectivity c(torus_grid(7, 5));
  EXPECT_EQ(c.euler_characteristic(), 0);
  EXPECT_EQ(c.genus(), 1);
  check_invariants(c);
}

TEST(Connectivity, RejectsBoundaryNonManifoldAndMisorientation) {
  RowMatrixX3i open = octahedron().topRows(7);
  EXPECT_THROW(Connectivity{open}, InputError);
  RowMatrixX3i flipped = octahedron();
  std::swap(flipped(3, 0), flipped(3, 1));
  try {
    Connectivity c(flipped);
    FAIL() << "inconsistent orientation accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("inconsistently oriented"), std::string::npos) << e.what();
  }
  // Two octahedra glued at one vertex: every edge is manifold, vertex 0 is not.
  RowMatrixX3i two(16, 3);
  RowMatrixX3i second = octahedron().array() + 6;
  second = (second.array() == 6).select(0, second);
  two << octahedron(), second;
  try {
    Connectivity c(two, 12);
    FAIL() << "non-manifold vertex accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 0"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace surfmap
