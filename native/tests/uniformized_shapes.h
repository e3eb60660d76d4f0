#pragma once
// Shared by the handle-class tests (test_geometric_classes.cpp,
// test_pants_classes.cpp): a surface uniformized with its canonical schema,
// and a smooth stretch that leaves a genus-2 surface no isometries but the
// hyperelliptic one.
#include <gtest/gtest.h>

#include <cmath>

#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/uniformize/uniformize.h"

namespace surfmap::testing_support {

struct Uniformized {
  UniformizeResult u;
  CanonicalSchema cs;
};

inline Uniformized uniformized(const TriMesh& mesh) {
  Uniformized x{uniformize(mesh), {}};
  EXPECT_TRUE(x.u.converged);
  x.cs = canonical_schema(x.u.layout.word);
  return x;
}

// A smooth non-uniform stretch: no (near) isometries but the hyperelliptic
// one, so the class of the identity is the only one whose probes keep their
// lengths.
inline TriMesh lopsided(TriMesh mesh) {
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    auto p = mesh.V.row(v);
    const double x = p(0), y = p(1);
    p(0) = x * (1.0 + 0.35 * x) + 0.1 * y * y;
    p(1) = y * (1.0 + 0.25 * std::sin(2.0 * x));
  }
  return mesh;
}

}  // namespace surfmap::testing_support
