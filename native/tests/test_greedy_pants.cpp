// The greedy short pants decomposition (map/greedy_pants.h,
// docs/handle_classes.md "Greedy pants decomposition"): intersection numbers
// of known curves, a complete decomposition whose curves no lift crosses
// (checked with the pants tests' own conjugator ball, another code path),
// and lengths independent of the cut and of a relabelling by a mapping class.
#include "surfmap/map/greedy_pants.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "surfmap/map/pants_classes.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/topology/mapping_class_search.h"
#include "surfmap/topology/outer_automorphisms.h"
#include "uniformized_shapes.h"

namespace surfmap {
namespace {

using testing_support::axes_cross;
using testing_support::ball;
using testing_support::has_identity_class;
using testing_support::lopsided;
using testing_support::Uniformized;
using testing_support::uniformized;

std::string counts(const GreedyPantsDecomposition& g) {
  return std::to_string(g.curves.size()) + " curves; of " + std::to_string(g.candidates) + " candidates " +
         std::to_string(g.examined) + " examined, " + std::to_string(g.self_crossing) + " self-crossing, " +
         std::to_string(g.crossing) + " crossing, " + std::to_string(g.duplicates) + " duplicates, " +
         std::to_string(g.not_evaluable) + " not evaluable";
}

std::vector<double> sorted_lengths(const GreedyPantsDecomposition& d) {
  std::vector<double> l;
  for (const GreedyPantsCurve& c : d.curves) l.push_back(c.length);
  std::sort(l.begin(), l.end());
  return l;
}

// In a marking's letters (a_i = 2i-1, b_i = 2i): i(a1, b1) = 1,
// i(a1, a2) = i(a1, b2) = 0, a1 b1 meets a1 once, the separating
// commutator [a1, b1] is simple and misses a1's neighbours' handle,
// a1^2 b1^2 crosses itself once (two crossing points of lifts), and a
// conjugate of a1 is the same curve.
TEST(GreedyPants, IntersectionNumbersOfKnownCurves) {
  const Uniformized x = uniformized(lopsided(samples::n_hole_torus(2, 26, true)));
  const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
  const ShortMarking m = short_marking(X);
  auto i = [&](const Word& u, const Word& v) { return curve_intersection(X, m.marking, u, v); };
  EXPECT_EQ(i({1}, {2}).crossings, 1);
  EXPECT_EQ(i({2}, {1}).crossings, 1);
  EXPECT_EQ(i({1}, {3}).crossings, 0);
  EXPECT_EQ(i({1}, {4}).crossings, 0);
  EXPECT_EQ(i({1}, {1}).crossings, 0);
  EXPECT_EQ(i({1}, {1, 2}).crossings, 1);
  EXPECT_EQ(i({1, 2, -1, -2}, {1, 2, -1, -2}).crossings, 0);
  EXPECT_EQ(i({1, 2, -1, -2}, {3}).crossings, 0);
  EXPECT_EQ(i({1, 2, -1, -2}, {1}).crossings, 0);
  EXPECT_EQ(i({1, 1, 2, 2}, {1, 1, 2, 2}).crossings, 2);
  EXPECT_FALSE(i({1}, {2}).same_curve);
  EXPECT_TRUE(i({1}, {2, 1, -2}).same_curve);
  EXPECT_TRUE(i({1}, {-1}).same_curve);
}

void expect_no_lift_crosses(const SurfaceGroupLengths& X, const GreedyPantsDecomposition& d) {
  const DehnReducer reduce(canonical_relator(X.genus()));
  const std::vector<Word> conjugators = ball(X.genus(), X.genus() == 2 ? 3 : 2);
  for (size_t c = 0; c < d.curves.size(); ++c)
    for (size_t e = c; e < d.curves.size(); ++e) {
      int n = 0;
      std::vector<hyperbolic::Mobius> m;
      for (const Word& h : conjugators)
        if (X.elements_in_frame_of_first({d.curves[c].word, reduce(concat({h, d.curves[e].word, inverse(h)}))}, &m) &&
            axes_cross(m[0], m[1]))
          ++n;
      EXPECT_EQ(n, 0) << c << " " << e;
    }
}

TEST(GreedyPants, Genus2CompleteSimpleDisjointAndIndependentOfTheCutAndMarking) {
  const TriMesh mesh = lopsided(samples::n_hole_torus(2, 26, true));
  const Uniformized x = uniformized(mesh);
  const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
  const ShortMarking mx = short_marking(X);
  const PantsDecomposition caterpillar = short_pants_decomposition(X, mx);
  std::vector<Word> extra_x;
  for (const PantsCurve& c : caterpillar.curves) extra_x.push_back(c.word);
  const GreedyPantsDecomposition g = greedy_pants_decomposition(X, mx, extra_x);
  ASSERT_TRUE(g.complete) << counts(g);
  ASSERT_EQ(g.curves.size(), 3u);
  expect_no_lift_crosses(X, g);
  // Greedy: the first curve is the shortest simple one, so no caterpillar
  // curve is shorter; the curves come in ascending order.
  double shortest_caterpillar = 1e300;
  for (const PantsCurve& c : caterpillar.curves) shortest_caterpillar = std::min(shortest_caterpillar, c.length);
  EXPECT_LE(g.curves[0].length, shortest_caterpillar * (1 + 1e-9));
  for (size_t k = 1; k < g.curves.size(); ++k) EXPECT_GE(g.curves[k].length, g.curves[k - 1].length);
  // The same surface relabelled by a known mapping class: the same lengths.
  const std::vector<MappingClassMove> moves = twist_moves(2, false, false);
  SurfaceAutomorphism psi{identity_map(4), identity_map(4), 0};
  const DehnReducer reduce(canonical_relator(2));
  for (const char* name : {"T(a1)", "T(a1)", "T(b2)^-1", "T(s1)"}) {
    auto mv = std::find_if(moves.begin(), moves.end(), [&](const MappingClassMove& mm) { return mm.name == name; });
    ASSERT_NE(mv, moves.end()) << name;
    psi.map = compose(psi.map, mv->automorphism.map);
    for (Word& w : psi.map) w = reduce(w);
  }
  const SurfaceGroupLengths Y(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word, psi.map);
  // (The candidates are short words of each surface's own short marking,
  // which can miss a short curve: the caterpillar decomposition's curves
  // join them, as in the pipeline.)
  const ShortMarking my = short_marking(Y);
  std::vector<Word> extra_y;
  for (const PantsCurve& c : short_pants_decomposition(Y, my).curves) extra_y.push_back(c.word);
  const GreedyPantsDecomposition gy = greedy_pants_decomposition(Y, my, extra_y);
  ASSERT_TRUE(gy.complete) << counts(gy);
  const std::vector<double> lx = sorted_lengths(g), ly = sorted_lengths(gy);
  for (size_t k = 0; k < lx.size(); ++k) EXPECT_NEAR(lx[k], ly[k], 1e-6 * lx[k]) << k;
}

TEST(GreedyPants, Genus3CompleteAndTheCaterpillarsCurvesSimpleAndDisjoint) {
  const Uniformized x = uniformized(samples::jitter(samples::n_hole_torus(3, 30, true), 0.2, 7));
  const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
  const ShortMarking mx = short_marking(X);
  const PantsDecomposition caterpillar = short_pants_decomposition(X, mx);
  std::vector<Word> extra;
  for (const PantsCurve& c : caterpillar.curves) extra.push_back(c.word);
  const GreedyPantsDecomposition g = greedy_pants_decomposition(X, mx, extra);
  ASSERT_TRUE(g.complete) << counts(g);
  ASSERT_EQ(g.curves.size(), 6u);
  expect_no_lift_crosses(X, g);
  // The greedy choice is the shortest simple curve first: no caterpillar
  // curve (all simple) is shorter.
  for (const PantsCurve& c : caterpillar.curves) EXPECT_GE(c.length, g.curves[0].length * (1 - 1e-9)) << c.name;
  // Every caterpillar curve is simple and disjoint from the other
  // caterpillar curves (a homeomorphism's image of the standard curves).
  const DehnReducer reduce(canonical_relator(3));
  for (size_t c = 0; c < extra.size(); ++c)
    for (size_t e = c; e < extra.size(); ++e) {
      const Word u = cyclic_reduce(reduce(substitute(extra[c], mx.marking.inverse)));
      const Word v = cyclic_reduce(reduce(substitute(extra[e], mx.marking.inverse)));
      EXPECT_EQ(curve_intersection(X, mx.marking, u, v).crossings, 0) << caterpillar.curves[c].name << " "
                                                                        << caterpillar.curves[e].name;
    }
}

// The verdicts without counting (the collar lemma, Yamada's bound on the
// shortest non-simple geodesic, the first crossing point) choose the same
// curves as counting every crossing, with fewer intersection tests; the
// first crossing point says "crossing" exactly when the count is positive.
TEST(GreedyPants, ShortcutsChooseTheSameCurvesAsFullCounts) {
  for (int genus : {2, 3}) {
    const Uniformized x = uniformized(genus == 2 ? lopsided(samples::n_hole_torus(2, 26, true))
                                                 : samples::jitter(samples::n_hole_torus(3, 30, true), 0.2, 7));
    const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
    const ShortMarking mx = short_marking(X);
    std::vector<Word> extra;
    for (const PantsCurve& c : short_pants_decomposition(X, mx).curves) extra.push_back(c.word);
    GreedyPantsOptions full;
    full.shortcuts = false;
    const GreedyPantsDecomposition fast = greedy_pants_decomposition(X, mx, extra);
    const GreedyPantsDecomposition slow = greedy_pants_decomposition(X, mx, extra, full);
    ASSERT_EQ(fast.curves.size(), slow.curves.size()) << genus << ": " << counts(fast) << " / " << counts(slow);
    for (size_t k = 0; k < fast.curves.size(); ++k) EXPECT_EQ(fast.curves[k].marking_word, slow.curves[k].marking_word);
    EXPECT_EQ(fast.complete, slow.complete);
    EXPECT_EQ(fast.examined, slow.examined);
    EXPECT_LT(fast.intersection_tests, slow.intersection_tests);
    // Verdicts of the first crossing point against the counts, on short
    // words of the marking (simple, crossing and self-crossing pairs).
    CurveIntersectionOptions first;
    first.stop_at_first_crossing = true;
    const std::vector<Word> words = {{1}, {2}, {3}, {1, 2}, {1, -2}, {1, 3}, {2, 4}, {1, 1, 2, 2}, {1, 2, -1, -2}};
    int crossing_pairs = 0;
    for (const Word& u : words)
      for (const Word& v : words) {
        const CurveIntersection count = curve_intersection(X, mx.marking, u, v);
        const CurveIntersection verdict = curve_intersection(X, mx.marking, u, v, first);
        ASSERT_GE(count.crossings, 0);
        EXPECT_EQ(verdict.crossings > 0, count.crossings > 0);
        crossing_pairs += count.crossings > 0;
      }
    EXPECT_GT(crossing_pairs, 0);
  }
}

void expect_exact_inverses(const std::vector<GreedyPantsClass>& classes, int genus) {
  for (const GreedyPantsClass& c : classes) {
    EXPECT_TRUE(inner_automorphism_test(compose(c.inverse, c.theta), genus).inner) << c.description;
    EXPECT_TRUE(inner_automorphism_test(compose(c.theta, c.inverse), genus).inner) << c.description;
  }
}

// A surface against itself: the identity class, with cost 0; the collar
// bound over the greedy curves of the identity (a conformal map, energy
// 8π(g−1)) cannot exceed 8π(g−1).
TEST(GreedyPantsClasses, IdentityForTheSameSurfaceAndTheCollarBoundBelowItsEnergy) {
  const Uniformized x = uniformized(samples::jitter(samples::n_hole_torus(3, 30, true), 0.2, 7));
  const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
  const ShortMarking mx = short_marking(X);
  std::vector<Word> extra;
  for (const PantsCurve& c : short_pants_decomposition(X, mx).curves) extra.push_back(c.word);
  const GreedyPantsDecomposition g = greedy_pants_decomposition(X, mx, extra);
  ASSERT_GE(g.curves.size(), 3u) << counts(g);
  const std::vector<GreedyPantsClass> classes = greedy_pants_classes(X, mx, g, X, mx, g);
  ASSERT_FALSE(classes.empty());
  EXPECT_LT(classes[0].cost, 1e-8);
  struct Named {  // (has_identity_class reads `theta` and `mismatch`)
    GroupMap theta;
    double mismatch;
  };
  std::vector<Named> named;
  for (const GreedyPantsClass& c : classes) named.push_back({c.theta, c.cost});
  EXPECT_TRUE(has_identity_class(named, 6));
  const double conformal = 8 * M_PI * 2;
  for (const GreedyPantsClass& c : classes)
    if (c.cost < 1e-8) EXPECT_LE(c.collar_bound, conformal * (1 + 1e-9)) << c.description;
  expect_exact_inverses(classes, 3);
}

// Two different surfaces (decompositions of different lengths): the classes
// come with exact inverses, the pants term pairs each surface's shortest
// curve with a curve of the other no longer than its longest greedy curve.
TEST(GreedyPantsClasses, DifferentSurfacesGetExactInversesAndShortCurvesPaired) {
  const Uniformized x = uniformized(lopsided(samples::n_hole_torus(2, 26, true)));
  const Uniformized y = uniformized(samples::jitter(samples::n_hole_torus(2, 30, true), 0.25, 3));
  const SurfaceGroupLengths X(DeckGroup(x.u.layout), x.cs.generators, x.u.layout.word);
  const SurfaceGroupLengths Y(DeckGroup(y.u.layout), y.cs.generators, y.u.layout.word);
  const ShortMarking mx = short_marking(X), my = short_marking(Y);
  const GreedyPantsDecomposition gx = greedy_pants_decomposition(X, mx), gy = greedy_pants_decomposition(Y, my);
  ASSERT_FALSE(gx.curves.empty() || gy.curves.empty());
  const std::vector<GreedyPantsClass> classes = greedy_pants_classes(X, mx, gx, Y, my, gy);
  ASSERT_FALSE(classes.empty());
  expect_exact_inverses(classes, 2);
  const DehnReducer reduce(canonical_relator(2));
  const GreedyPantsClass& best = classes[0];
  EXPECT_LE(Y.length(reduce(substitute(gx.curves[0].word, best.theta))), gy.curves.back().length * (1 + 1e-9));
  EXPECT_LE(X.length(reduce(substitute(gy.curves[0].word, best.inverse))), gx.curves.back().length * (1 + 1e-9));
  for (size_t k = 1; k < classes.size(); ++k) EXPECT_GE(classes[k].cost, classes[k - 1].cost);
}

}  // namespace
}  // namespace surfmap
