// Handle classes from short pants decompositions with Fenchel–Nielsen
// coordinates (map/pants_classes.h, docs/handle_classes.md "Pants
// decompositions").
#include "surfmap/map/pants_classes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "surfmap/samples/shapes.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/mapping_class_search.h"
#include "surfmap/uniformize/uniformize.h"
#include "uniformized_shapes.h"

namespace surfmap {
namespace {

using testing_support::axes_cross;
using testing_support::ball;
using testing_support::has_identity_class;
using testing_support::lopsided;
using testing_support::Uniformized;
using testing_support::uniformized;

// The same surface with its vertices and faces numbered in reverse: another
// cut, other canonical letters, the same metric.
TriMesh renumbered(const TriMesh& mesh) {
  TriMesh out = mesh;
  const int n = mesh.num_vertices(), m = static_cast<int>(mesh.F.rows());
  for (int v = 0; v < n; ++v) out.V.row(n - 1 - v) = mesh.V.row(v);
  for (int f = 0; f < m; ++f)
    for (int k = 0; k < 3; ++k) out.F(m - 1 - f, k) = n - 1 - mesh.F(f, k);
  return out;
}

SurfaceAutomorphism named_moves(int genus, const std::vector<std::string>& names) {
  return testing_support::then_moves({identity_map(2 * genus), identity_map(2 * genus), 0}, genus, names);
}

TEST(PantsClasses, StandardTwistsAreAutomorphismsAndSymmetriesPreserveTheCurves) {
  for (int g = 2; g <= 4; ++g) {
    const std::vector<StandardPantsCurve> curves = standard_pants_curves(g);
    ASSERT_EQ(static_cast<int>(curves.size()), 3 * g - 3);
    for (const StandardPantsCurve& c : curves) EXPECT_TRUE(is_surface_automorphism(c.twist, g)) << c.name;
    const std::vector<PantsSymmetry> sym = pants_symmetries(g);
    const size_t perms = g == 2 ? 2 : g == 3 ? 6 : 8;
    EXPECT_EQ(sym.size(), perms << g);
    const IntMatrix J = symplectic_form(g);
    const DehnReducer reduce(canonical_relator(g));
    for (const PantsSymmetry& s : sym) {
      const IntMatrix H = homology_matrix(s.map, 2 * g);
      EXPECT_EQ(H.transpose() * J * H, J);
      // A homomorphism of the surface group: the relator's image is trivial.
      EXPECT_TRUE(reduce(substitute(canonical_relator(g), s.map)).empty()) << g;
    }
  }
}

// Lengths and twist coordinates are conjugation invariant; one Dehn twist
// along a pants curve shifts its twist coordinate by its length; the pants
// curves' lifts never cross (while a1's and b1's do).
TEST(PantsClasses, CoordinatesAreInvariantAndTheCurvesDisjointAndSimple) {
  const Uniformized x = uniformized(lopsided(samples::n_hole_torus(2, 26, true)));
  const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
  const PantsDecomposition p = short_pants_decomposition(X, short_marking(X));
  ASSERT_EQ(p.curves.size(), 3u);
  EXPECT_EQ(p.stop_reason, "no shortening move");
  EXPECT_LE(p.total, p.start_total + 1e-9);
  EXPECT_TRUE(is_surface_automorphism(p.marking, 2));
  const DehnReducer reduce(canonical_relator(2));
  const std::vector<StandardPantsCurve> standard = standard_pants_curves(2);
  for (size_t c = 0; c < 3; ++c) {
    const PantsCurve& pc = p.curves[c];
    ASSERT_TRUE(std::isfinite(pc.length) && std::isfinite(pc.twist)) << pc.name;
    EXPECT_LE(std::abs(pc.twist), 0.5 * pc.length + 1e-6) << pc.name;  // normalised
    const Word e1 = reduce(substitute(standard[c].side1, p.marking.map));
    const Word e2 = reduce(substitute(standard[c].side2, p.marking.map));
    for (const Word& h : {Word{1}, Word{-2, 3}, Word{4, 4, -1}}) {
      auto cj = [&](const Word& w) { return reduce(concat({h, w, inverse(h)})); };
      EXPECT_NEAR(X.length(cj(pc.word)), pc.length, 1e-8 * pc.length);
      EXPECT_NEAR(twist_coordinate(X, cj(pc.word), cj(e1), cj(e2)), pc.twist, 1e-6) << pc.name;
    }
    // One twist: a shift by ±ℓ.
    GroupMap twisted = compose(p.marking.map, standard[c].twist.map);
    for (Word& w : twisted) w = reduce(w);
    const double t1 = pants_coordinates(X, twisted)[c].twist;
    EXPECT_NEAR(std::abs(t1 - pc.twist), pc.length, 1e-6 * pc.length) << pc.name;
  }
  // Simple and disjoint: no lift of a pants curve crosses another's axis.
  const std::vector<Word> conjugators = ball(2, 3);
  auto crossings = [&](const Word& u, const Word& v) {
    std::vector<hyperbolic::Mobius> m;
    int n = 0;
    for (const Word& h : conjugators)
      if (X.elements_in_frame_of_first({u, reduce(concat({h, v, inverse(h)}))}, &m) && axes_cross(m[0], m[1])) ++n;
    return n;
  };
  for (size_t c = 0; c < 3; ++c)
    for (size_t d = c; d < 3; ++d) EXPECT_EQ(crossings(p.curves[c].word, p.curves[d].word), 0) << c << " " << d;
  // (The check can fail: a1 and b1 of the marking cross.)
  EXPECT_GT(crossings(p.marking.map[0], p.marking.map[1]), 0);
}

// The same surface against itself and against a renumbered copy (another
// cut): the same pants lengths, and a class of zero mismatch; against
// itself that class is the identity.
TEST(PantsClasses, IdentityForTheSameSurfaceAndIsometryForACopy) {
  const Uniformized x = uniformized(lopsided(samples::n_hole_torus(2, 26, true)));
  const Uniformized y = uniformized(renumbered(lopsided(samples::n_hole_torus(2, 26, true))));
  const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
  const SurfaceGroupLengths Y(DeckGroup(y.u.layout), y.cs.generators, y.u.layout.word);
  const PantsDecomposition px = short_pants_decomposition(X, short_marking(X));
  const PantsDecomposition py = short_pants_decomposition(Y, short_marking(Y));
  std::vector<double> lx, ly;
  for (const PantsCurve& c : px.curves) lx.push_back(c.length);
  for (const PantsCurve& c : py.curves) ly.push_back(c.length);
  std::sort(lx.begin(), lx.end()), std::sort(ly.begin(), ly.end());
  for (size_t k = 0; k < lx.size(); ++k) EXPECT_NEAR(lx[k], ly[k], 1e-5 * lx[k]);
  const std::vector<PantsClass> self = pants_classes(X, px, X, px);
  ASSERT_FALSE(self.empty());
  EXPECT_LT(self[0].mismatch, 1e-8);
  EXPECT_TRUE(has_identity_class(self, 4));
  const std::vector<PantsClass> copy = pants_classes(X, px, Y, py);
  ASSERT_FALSE(copy.empty());
  EXPECT_LT(copy[0].mismatch, 1e-6) << copy[0].description;
  EXPECT_LT(copy[0].twist_mismatch, 1e-6);
}

// A known twist applied to one marking (T(a1)^2 T(s1)^-1 on the decomposition
// of the same surface) is undone by the twist matching: the class found is
// the identity, with twists -2 / +1 (or the reverse, by the twists' sign).
TEST(PantsClasses, AKnownDehnTwistIsUndone) {
  const Uniformized x = uniformized(lopsided(samples::n_hole_torus(2, 26, true)));
  const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
  const PantsDecomposition px = short_pants_decomposition(X, short_marking(X));
  const std::vector<StandardPantsCurve> standard = standard_pants_curves(2);
  const DehnReducer reduce(canonical_relator(2));
  PantsDecomposition twisted = px;
  for (const SurfaceAutomorphism* t : {&standard[0].twist, &standard[0].twist}) {
    twisted.marking.map = compose(twisted.marking.map, t->map);
    twisted.marking.inverse = compose(t->inverse, twisted.marking.inverse);
  }
  twisted.marking.map = compose(twisted.marking.map, standard[2].twist.inverse);  // s1 is the third curve
  twisted.marking.inverse = compose(standard[2].twist.map, twisted.marking.inverse);
  for (Word& w : twisted.marking.map) w = reduce(w);
  for (Word& w : twisted.marking.inverse) w = reduce(w);
  ASSERT_EQ(standard[2].name, "s1");
  twisted.curves = pants_coordinates(X, twisted.marking.map);
  const std::vector<PantsClass> classes = pants_classes(X, px, X, twisted);
  ASSERT_FALSE(classes.empty());
  bool undone = false;
  for (const PantsClass& c : classes)
    if (c.mismatch < 1e-8 && homology_matrix(c.theta, 4) == homology_matrix(identity_map(4), 4)) {
      undone = true;
      EXPECT_EQ(std::abs(c.twists[0]), 2) << c.description;
      EXPECT_EQ(std::abs(c.twists[2]), 1) << c.description;
    }
  EXPECT_TRUE(undone);
  // The same surface relabelled by a known mapping class: its inverse is
  // recovered with zero mismatch.
  const SurfaceAutomorphism psi = named_moves(2, {"T(a1)", "T(a1)", "T(b2)^-1", "T(s1)"});
  const SurfaceGroupLengths Y(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word, psi.map);
  const PantsDecomposition py = short_pants_decomposition(Y, short_marking(Y));
  const std::vector<PantsClass> found = pants_classes(X, px, Y, py);
  bool recovered = false;
  for (const PantsClass& c : found)
    recovered = recovered || (c.mismatch < 1e-8 && homology_matrix(c.theta, 4) == homology_matrix(psi.inverse, 4));
  EXPECT_TRUE(recovered);
}

TEST(PantsClasses, Genus3IdentityForTheSameSurface) {
  const Uniformized x = uniformized(samples::jitter(samples::n_hole_torus(3, 30, true), 0.2, 7));
  const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
  const PantsDecomposition p = short_pants_decomposition(X, short_marking(X));
  ASSERT_EQ(p.curves.size(), 6u);
  for (const PantsCurve& c : p.curves) EXPECT_TRUE(std::isfinite(c.length) && std::isfinite(c.twist)) << c.name;
  const std::vector<PantsClass> classes = pants_classes(X, p, X, p);
  ASSERT_FALSE(classes.empty());
  EXPECT_LT(classes[0].mismatch, 1e-8);
  EXPECT_TRUE(has_identity_class(classes, 6));
}

// Issue 13 (session 27): the twists along a surface's short curves
// (short_curve_twists: the short marking's generators and the short pants
// curves). Each is an automorphism whose map and inverse compose to the
// identity, fixes its curve (the same element: the same length), acts on
// homology as the transvection x -> x + <c, x> c of its curve's class (the
// identity for a separating curve), and lengthens the curves crossing its
// own while the pants curves disjoint from a pants curve keep their
// lengths; the list is sorted, each curve once, with the marking's and the
// pants decomposition's lengths.
TEST(PantsClasses, ShortCurveTwistsAreDehnTwistsAlongTheirCurves) {
  for (int genus : {2, 3}) {
    const Uniformized x = uniformized(lopsided(samples::n_hole_torus(genus, 22, true)));
    const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
    const ShortMarking mk = short_marking(X);
    const PantsDecomposition p = short_pants_decomposition(X, mk);
    const std::vector<CurveTwist> twists = short_curve_twists(X, mk, &p);
    const int n = 2 * genus;
    const DehnReducer reduce(canonical_relator(genus));
    const IntMatrix J = symplectic_form(genus);
    ASSERT_GE(static_cast<int>(twists.size()), n) << genus;
    ASSERT_LE(static_cast<int>(twists.size()), n + 3 * genus - 3);
    EXPECT_EQ(short_curve_twists(X, mk).size(), static_cast<size_t>(n));  // (the marking's alone: 2g distinct curves)
    int pants_listed = 0;
    for (size_t k = 0; k < twists.size(); ++k) {
      const CurveTwist& c = twists[k];
      SCOPED_TRACE(c.name);
      ASSERT_TRUE(std::isfinite(c.length));
      if (k > 0) EXPECT_LE(twists[k - 1].length, c.length);
      EXPECT_NEAR(X.length(c.curve), c.length, 1e-9 * c.length);
      EXPECT_TRUE(is_surface_automorphism(c.twist, genus));
      GroupMap round = compose(c.twist.map, c.twist.inverse);
      for (Word& w : round) w = reduce(w);
      EXPECT_EQ(round, identity_map(n));
      // Its curve is fixed: the same closed geodesic.
      EXPECT_NEAR(X.length(reduce(substitute(c.curve, c.twist.map))), c.length, 1e-7 * c.length);
      // The transvection of its class v: H x = x + s <v, x> v, one sign s.
      const IntMatrix H = homology_matrix(c.twist.map, n);
      const Eigen::Matrix<long long, Eigen::Dynamic, 1> v = abelianize(c.curve, n);
      const IntMatrix V = v.cast<IntMatrix::Scalar>();
      const IntMatrix plus = IntMatrix::Identity(n, n) + V * (V.transpose() * J);
      const IntMatrix minus = IntMatrix::Identity(n, n) - V * (V.transpose() * J);
      EXPECT_TRUE(H == plus || H == minus) << H;
      // It changes the length of a curve crossing its own: of some probe
      // x_i, x_i x_j^±1 of the marking (they cross every essential curve).
      double change = 0;
      for (const Word& probe : marking_probes(genus)) {
        const Word w = reduce(substitute(probe, mk.marking.map));
        change = std::max(change, std::abs(X.length(reduce(substitute(w, c.twist.map))) - X.length(w)));
      }
      EXPECT_GT(change, 1e-3);
      if (c.name.rfind("marking ", 0) == 0) {
        const int j = 2 * (std::stoi(c.name.substr(9)) - 1) + (c.name[8] == 'b');
        EXPECT_NEAR(c.length, mk.generator_lengths[j], 1e-9 * c.length);
      } else {
        ++pants_listed;
        // A pants twist leaves the other pants curves (disjoint) alone.
        for (const PantsCurve& q : p.curves)
          EXPECT_NEAR(X.length(reduce(substitute(q.word, c.twist.map))), q.length, 1e-7 * q.length) << q.name;
        const auto same = std::find_if(p.curves.begin(), p.curves.end(),
                                       [&](const PantsCurve& q) { return "pants " + q.name == c.name; });
        ASSERT_NE(same, p.curves.end());
        EXPECT_NEAR(c.length, same->length, 1e-9 * c.length);
      }
    }
    EXPECT_GE(pants_listed, genus - 1);  // (the separating curves s_j are never a marking's generators)
  }
}

}  // namespace
}  // namespace surfmap
