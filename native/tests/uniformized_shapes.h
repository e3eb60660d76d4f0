#pragma once
// Shared by the handle-class tests (test_geometric_classes.cpp,
// test_pants_classes.cpp): a surface uniformized with its canonical schema,
// a smooth stretch that leaves a genus-2 surface no isometries but the
// hyperelliptic one, the identity test of a surface's self-classes and
// automorphisms composed of named Dehn twists.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/mapping_class_search.h"
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

// (Also used by test_greedy_pants.cpp as an independent crossing check.)
// Whether the axes of two hyperbolic elements cross (endpoints linked on
// the circle at infinity); false for the same axis.
inline bool axes_cross(hyperbolic::Mobius p, hyperbolic::Mobius q) {
  auto ends = [](hyperbolic::Mobius m, double* u, double* v) {
    const double det = m.determinant();
    if (det > 0.5 && det < 2) m.a /= std::sqrt(det), m.b /= std::sqrt(det);
    const double im = m.a.imag(), root = std::sqrt(std::max(0.0, m.a.real() * m.a.real() - 1));
    const Complex bb = std::conj(m.b);
    *u = std::arg((Complex(0, im) + root) / bb), *v = std::arg((Complex(0, im) - root) / bb);
  };
  double p1, p2, q1, q2;
  ends(p, &p1, &p2), ends(q, &q1, &q2);
  auto close = [](double x, double y) { return std::abs(std::remainder(x - y, 2 * M_PI)) < 1e-7; };
  if ((close(p1, q1) && close(p2, q2)) || (close(p1, q2) && close(p2, q1))) return false;
  auto inside = [&](double x) {  // x strictly on the ccw arc from p1 to p2
    const double span = std::fmod(p2 - p1 + 4 * M_PI, 2 * M_PI), at = std::fmod(x - p1 + 4 * M_PI, 2 * M_PI);
    return at > 1e-9 && at < span - 1e-9;
  };
  return inside(q1) != inside(q2);
}

// psi followed by the named Dehn twists of twist_moves(genus) in order
// (names as "T(a1)", "T(b2)^-1"), words reduced; an unknown name fails.
inline SurfaceAutomorphism then_moves(SurfaceAutomorphism psi, int genus, const std::vector<std::string>& names) {
  const std::vector<MappingClassMove> moves = twist_moves(genus, false, false);
  const DehnReducer reduce(canonical_relator(genus));
  for (const std::string& name : names) {
    auto m = std::find_if(moves.begin(), moves.end(), [&](const MappingClassMove& x) { return x.name == name; });
    EXPECT_NE(m, moves.end()) << name;
    if (m == moves.end()) break;
    psi.map = compose(psi.map, m->automorphism.map);
    psi.inverse = compose(m->automorphism.inverse, psi.inverse);
    for (Word& w : psi.map) w = reduce(w);
    for (Word& w : psi.inverse) w = reduce(w);
  }
  return psi;
}

// Conjugators: every reduced word of up to `radius` letters.
inline std::vector<Word> ball(int genus, int radius) { return reduced_words_up_to(genus, radius); }

}  // namespace surfmap::testing_support
