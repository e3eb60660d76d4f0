#pragma once
// Shared by the handle-class tests (test_geometric_classes.cpp,
// test_pants_classes.cpp): a surface uniformized with its canonical schema,
// a smooth stretch that leaves a genus-2 surface no isometries but the
// hyperelliptic one, and the identity test of a surface's self-classes.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/handle_basis.h"
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

// Whether a zero-mismatch class acting as the identity on homology is among
// `classes` (GeometricClass, PantsClass: fields `mismatch`, `theta`) of a
// surface mapped onto itself; n = 2g generators.
template <class Class>
bool has_identity_class(const std::vector<Class>& classes, int n) {
  for (const Class& c : classes)
    if (c.mismatch < 1e-8 && homology_matrix(c.theta, n) == homology_matrix(identity_map(n), n)) return true;
  return false;
}

}  // namespace surfmap::testing_support
