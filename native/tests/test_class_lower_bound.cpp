// The class lower bound from hyperbolic lengths (map/class_lower_bound.h,
// docs/handle_classes.md): lengths obey identities of hyperbolic geometry,
// and the bound never exceeds a solved energy.
#include "surfmap/map/class_lower_bound.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/map/coarse_source.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/testing/map_hooks.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/mapping_class_search.h"
#include "surfmap/uniformize/uniformize.h"
#include "../src/map/stages/class_search.h"
#include "../src/map/stages/homotopy_classes.h"
#include "../src/map/two_way_run.h"
#include "../src/map/class_bound_support.h"
#include "surfmap/topology/projected_loops.h"

namespace surfmap {
namespace {

SurfaceGroupLengths lengths_of(const TriMesh& mesh) {
  const UniformizeResult u = uniformize(mesh);
  EXPECT_TRUE(u.converged);
  const CanonicalSchema cs = canonical_schema(u.layout.word);
  return SurfaceGroupLengths(DeckGroup(u.layout), cs.generators, u.layout.word);
}

double half_trace(double length) { return std::cosh(length / 2); }

TEST(ClassLowerBound, LengthsObeyHyperbolicTraceIdentitiesAndTheCollarLemma) {
  const SurfaceGroupLengths X = lengths_of(samples::n_hole_torus(2, 26, true));
  ASSERT_EQ(X.genus(), 2);
  for (int i = 0; i < 2; ++i) {
    const int a = 2 * i + 1, b = 2 * i + 2;
    const double la = X.length({a}), lb = X.length({b}), lab = X.length({a, b}), labi = X.length({a, -b});
    ASSERT_GT(la, 0);
    ASSERT_GT(lb, 0);
    // Conjugation and inversion invariance (free homotopy classes).
    EXPECT_NEAR(X.length({-b, a, b}), la, 1e-8 * la);
    EXPECT_NEAR(X.length({-a}), la, 1e-8 * la);
    EXPECT_NEAR(X.length({3 - 2 * i, -a, -(3 - 2 * i)}), la, 1e-8 * la);
    // Two simple closed geodesics crossing once: sinh(la/2) sinh(lb/2) >= 1
    // (their collars would overlap otherwise).
    EXPECT_GE(std::sinh(la / 2) * std::sinh(lb / 2), 1.0 - 1e-9) << "handle " << i + 1;
    // tr(AB) + tr(AB^-1) = tr A tr B for matrices of SL(2): with |tr| and
    // an unknown sign of the lift, one of the sum or the difference of the
    // half traces of AB, AB^-1 equals 2 (tr A / 2)(tr B / 2).
    const double p = 2 * half_trace(la) * half_trace(lb), x = half_trace(lab), y = half_trace(labi);
    EXPECT_LT(std::min(std::abs(x + y - p), std::abs(std::abs(x - y) - p)), 1e-6 * p) << "handle " << i + 1;
  }
  // The separating curve [a1,b1] is longer than the pair's collar allows a
  // short curve to be: its length exceeds 2 arcsinh(1) (it meets no curve
  // crossing it once, but cuts off a one-holed torus of area 2 pi whose
  // boundary has length > 0; here simply: positive and finite).
  const double ls = X.length(commutator_product({{1}, {2}}));
  EXPECT_TRUE(std::isfinite(ls));
  EXPECT_GT(ls, 0);
  // The identity of the group is length 0; words too long to evaluate are NaN.
  EXPECT_EQ(X.length(canonical_relator(2)), 0.0);
  EXPECT_TRUE(std::isnan(X.length(std::vector<int>(50, 1), 10)));
}

TEST(ClassLowerBound, CollarModulusAndFamilies) {
  // M(l) = 2 arctan(1/sinh(l/2)) / l: above Maskit's 2 e^{-l/2} / l, and the
  // collar of a short curve is long (M ~ pi / l).
  for (double l : {0.01, 0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0}) {
    EXPECT_GE(collar_modulus(l), 2 * std::exp(-l / 2) / l) << l;
    EXPECT_LE(collar_modulus(l), M_PI / l) << l;
  }
  EXPECT_NEAR(collar_modulus(1e-4) * 1e-4, M_PI, 1e-3);
  for (int g = 2; g <= 4; ++g) {
    const std::vector<CurveFamily> fam = disjoint_curve_families(g);
    EXPECT_EQ(fam.size(), 4u * (1 + twist_moves(g, false, false).size()));
    const IntMatrix J = symplectic_form(g);
    for (const CurveFamily& f : fam) {
      ASSERT_EQ(static_cast<int>(f.curves.size()), 2 * g - 1) << f.name;
      // Disjoint curves have algebraic intersection 0 pairwise.
      for (size_t i = 0; i < f.curves.size(); ++i)
        for (size_t j = 0; j < f.curves.size(); ++j) {
          const auto ci = abelianize(f.curves[i], 2 * g), cj = abelianize(f.curves[j], 2 * g);
          EXPECT_EQ((ci.transpose() * J * cj)(0, 0), 0) << f.name;
        }
    }
  }
  EXPECT_THROW(disjoint_curve_families(1), InputError);
}

// The class fingerprint and screen of the pipeline (ClassSpace) use the one
// length function: a translation length is the same for every conjugate and
// every cyclic permutation of a word, and equals 2 arccosh(|tr|/2) of the
// determinant-normalised matrix of a short word. (The fingerprint once
// multiplied out far conjugates and divided the trace by a round-off
// determinant: 697 where 6.41 was right.)
TEST(ClassLowerBound, ClassSpaceLengthsAreConjugationInvariantTranslationLengths) {
  const TriMesh mesh = samples::n_hole_torus(2, 26, true);
  const UniformizeResult u = uniformize(mesh);
  ASSERT_TRUE(u.converged);
  const CanonicalSchema cs = canonical_schema(u.layout.word);
  const DeckGroup group(u.layout);
  const detail::ClassSpace space(2, u.loops, cs, cs, u.layout, group);
  const DehnReducer reduce_loops(u.layout.word), reduce_canonical(canonical_relator(2));
  // Short words: the normalised trace of the matrix itself.
  for (const Word& w : std::vector<Word>{{1}, {2}, {3}, {4}, {1, 2}, {1, -3}, {2, 4}, {1, 2, -3, 4}}) {
    const hyperbolic::Mobius m = group.evaluate(reduce_loops(substitute(w, cs.generators)));
    const double half = std::abs(m.a.real()) / std::sqrt(m.determinant());
    ASSERT_NEAR(m.determinant(), 1.0, 1e-6);
    const double l = space.target_length(w);
    EXPECT_NEAR(l, 2 * std::acosh(half), 1e-8 * std::max(1.0, l)) << "word of " << w.size() << " letters";
    // every cyclic permutation and its inverse
    for (size_t r = 1; r < w.size(); ++r) {
      Word turned(w.begin() + static_cast<long>(r), w.end());
      turned.insert(turned.end(), w.begin(), w.begin() + static_cast<long>(r));
      EXPECT_NEAR(space.target_length(turned), l, 1e-8 * std::max(1.0, l)) << "word " << w.size() << " turned " << r;
    }
    EXPECT_NEAR(space.target_length(inverse(w)), l, 1e-8 * std::max(1.0, l));
  }
  // A long conjugator (its matrix has entries far beyond the determinant's
  // precision): conjugates have the same lengths, and an inner automorphism
  // of the identity class has the identity's fingerprint and screen.
  Word c;
  for (int k = 0; k < 6; ++k) c.insert(c.end(), {1, 2, -3, 4, 2});
  c = reduce_canonical(c);
  ASSERT_GT(c.size(), 20u);
  for (const Word& w : std::vector<Word>{{1}, {2, 4}, {1, 2, -3, 4}}) {
    Word conj = c;
    conj.insert(conj.end(), w.begin(), w.end());
    const Word ci = inverse(c);
    conj.insert(conj.end(), ci.begin(), ci.end());
    const double l = space.target_length(w);
    EXPECT_NEAR(space.target_length(reduce_canonical(conj)), l, 1e-6 * std::max(1.0, l)) << "word of " << w.size() << " letters";
  }
  GroupMap inner(4);
  for (int j = 0; j < 4; ++j) {
    Word w = c;
    w.push_back(j + 1);
    const Word ci = inverse(c);
    w.insert(w.end(), ci.begin(), ci.end());
    inner[j] = reduce_canonical(w);
  }
  ASSERT_TRUE(space.is_isomorphism(inner));
  const std::vector<double> fi = space.fingerprint(identity_map(4)), fc = space.fingerprint(inner);
  ASSERT_EQ(fi.size(), fc.size());
  for (size_t k = 0; k < fi.size(); ++k) {
    EXPECT_TRUE(std::isfinite(fi[k]));
    EXPECT_NEAR(fc[k], fi[k], 1e-6 * std::max(1.0, fi[k])) << "probe " << k;
  }
  EXPECT_TRUE(detail::ClassSpace::same_fingerprint(fi, fc));
  const double si = space.screen(identity_map(4)), sc = space.screen(inner);
  EXPECT_TRUE(std::isfinite(si));
  EXPECT_NEAR(sc, si, 1e-6 * si);
}

// Issue 13 (session 21): the short canonical generators (cut-and-paste
// moves that conjugate only the new pair) present the same surface as the
// classical ones: every loop and product of loops has the same length
// through either basis (their `letters` are right), the canonical relator
// multiplied out through their matrices is +-identity to round-off relative
// to its partial products, and no short generator's side word is longer
// than the classical ones' longest (the classical conjugators pile up).
TEST(ClassLowerBound, ShortCanonicalGeneratorsPresentTheSameSurface) {
  const UniformizeResult u = uniformize(samples::wheel(5, 24, false));
  ASSERT_TRUE(u.converged);
  const int g = u.genus, n = 2 * g;
  ASSERT_EQ(g, 5);
  CanonicalSchemaOptions shortest;
  shortest.short_generators = true;
  const CanonicalSchema classical = canonical_schema(u.layout.word), brief = canonical_schema(u.layout.word, shortest);
  const DeckGroup group(u.layout);
  const SurfaceGroupLengths on_classical(group, classical.generators, u.layout.word),
      on_short(group, brief.generators, u.layout.word);
  for (int k = 1; k <= n; ++k)
    for (const Word& loops : std::vector<Word>{{k}, {k, k % n + 1}, {k, -(k % n + 1)}}) {
      const double l = on_classical.length(substitute(loops, classical.letters));
      ASSERT_TRUE(std::isfinite(l) && l > 0) << "loop word of letter " << k;
      EXPECT_NEAR(on_short.length(substitute(loops, brief.letters)), l, 1e-6 * l) << "loop word of letter " << k;
    }
  std::vector<Word> letters;
  for (int j = 1; j <= n; ++j) letters.push_back({j});
  std::vector<hyperbolic::Mobius> m;
  ASSERT_TRUE(on_short.elements_in_frame_of_first(letters, &m));
  hyperbolic::Mobius product;
  double condition = 1;
  for (int x : canonical_relator(g)) {
    product = (product * (x > 0 ? m[x - 1] : m[-x - 1].inverse())).normalized();
    condition = std::max(condition, std::pow(product.size(), 2));
  }
  EXPECT_LT(hyperbolic::distance_from_identity(product), 1e-10 * condition);
  size_t classical_longest = 0, short_longest = 0;
  for (int j = 0; j < n; ++j) {
    classical_longest = std::max(classical_longest, group.side_word(classical.generators[j]).size());
    short_longest = std::max(short_longest, group.side_word(brief.generators[j]).size());
  }
  EXPECT_LE(short_longest, classical_longest);
}

// Issue 13 (session 25; --geometric-layout-basis): the layout's short
// canonical basis written in another canonical basis's letters (here the
// classical schema's, as the class loops' are in the pipeline) presents the
// same elements: every generator and product of two has the same length
// read either way, and the layout basis's canonical relator is the identity
// in the class letters (Dehn's algorithm decides it exactly). Read as the
// same letters instead, the two bases disagree, so the change of letters is
// not the identity.
TEST(ClassLowerBound, LayoutShortBasisIsWrittenInTheClassLetters) {
  const UniformizeResult u = uniformize(samples::wheel(5, 24, false));
  ASSERT_TRUE(u.converged);
  const int g = u.genus, n = 2 * g;
  const CanonicalSchema classical = canonical_schema(u.layout.word);
  CanonicalSchema layout;
  GroupMap in_class;
  std::string why;
  ASSERT_TRUE(detail::layout_short_basis(u.layout.word, classical.generators, classical.letters, &layout, &in_class, &why))
      << why;
  ASSERT_EQ(static_cast<int>(in_class.size()), n);
  ASSERT_EQ(static_cast<int>(layout.generators.size()), n);
  EXPECT_TRUE(dehn_reduce(substitute(canonical_relator(g), in_class), canonical_relator(g)).empty());
  const DeckGroup group(u.layout);
  const SurfaceGroupLengths on_class(group, classical.generators, u.layout.word),
      on_layout(group, layout.generators, u.layout.word);
  int differ = 0;
  for (int j = 1; j <= n; ++j)
    for (int k = j; k <= n; ++k)
      for (const Word& w : j == k ? std::vector<Word>{{j}} : std::vector<Word>{{j, k}, {j, -k}}) {
        const double l = on_layout.length(w);
        ASSERT_TRUE(std::isfinite(l) && l > 0) << "word " << j << " " << w.back();
        EXPECT_NEAR(on_class.length(substitute(w, in_class)), l, 1e-6 * l) << "word " << j << " " << w.back();
        differ += !(std::abs(on_class.length(w) - l) <= 1e-3 * l);
      }
  EXPECT_GT(differ, 0);
}

// The bound of a class X -> X twisted k times along a1 grows like k^2 (the
// image of b1 winds k times around a1: its length grows like k l(a1)), and
// the identity's stays below the energy of the isometry, 8 pi (g - 1).
TEST(ClassLowerBound, TwistedSelfClassesOfASurface) {
  const SurfaceGroupLengths X = lengths_of(samples::n_hole_torus(2, 26, true));
  const ClassBoundEvaluator bound(X, disjoint_curve_families(2));
  const double conformal = 8 * M_PI;
  const ClassLowerBound id = bound(X, identity_map(4));
  EXPECT_LE(id.curve_bound, conformal);
  EXPECT_EQ(id.bound, conformal);
  const MappingClassMove twist = twist_moves(2, false, false)[0];
  ASSERT_EQ(twist.name, "T(a1)");
  auto twisted = [&](int k) {
    GroupMap theta = identity_map(4);
    for (int q = 0; q < k; ++q) {
      theta = compose(theta, twist.automorphism.map);
      for (Word& w : theta) w = dehn_reduce(w, canonical_relator(2));
    }
    return bound(X, theta).curve_bound;
  };
  const double b5 = twisted(5), b10 = twisted(10), b20 = twisted(20), b40 = twisted(40);
  EXPECT_GE(b5, id.curve_bound);
  EXPECT_GT(b10, b5);
  EXPECT_GT(b20, b10);
  EXPECT_GT(b40, b20);
  EXPECT_GT(b40, conformal);  // informative beyond the conformal bound
  EXPECT_GT(b40 / b20, 2.5);  // -> 4 as k grows
  EXPECT_LT(b40 / b20, 4.5);
}

// The bound against solved energies on generated pairs: every candidate of
// a dissimilar pair (solved at full resolution) and the twisted classes the
// search meets on a remeshed copy.
void expect_bounds_below_energies(const SurfaceMapResult& m, int* informative) {
  ASSERT_TRUE(m.class_bound_status.empty()) << m.class_bound_status;
  for (const HomotopyCandidate& c : m.candidates) {
    ASSERT_TRUE(std::isfinite(c.class_lower_bound)) << c.description;
    EXPECT_GE(c.class_lower_bound, conformal_bound(m.genus));
    EXPECT_LE(c.class_curve_bound, c.class_lower_bound);
    if (!c.solved || !std::isfinite(c.energy)) continue;
    EXPECT_LE(c.class_curve_bound, c.energy) << c.description << " (" << c.class_bound_curves << ")";
    if (c.class_curve_bound > conformal_bound(m.genus)) ++*informative;
  }
}

TEST(ClassLowerBound, NeverAboveTheSolvedEnergies) {
  int informative = 0;
  {
    const TriMesh a = samples::n_hole_torus(2, 26, true);
    const TriMesh b = samples::vase(30, true);
    SurfaceMapOptions o;
    o.homotopy.full_solves = 0;
    o.homotopy.coarse_vertices = 0;
    o.homotopy.two_way = false;  // (test_surface_map.cpp)
    const SurfaceMapResult m = surface_map(a, b, o);
    expect_bounds_below_energies(m, &informative);
    EXPECT_TRUE(std::isfinite(m.energy_ratio));
    EXPECT_NEAR(m.energy_ratio, m.candidates[m.chosen_candidate].energy / (8 * M_PI), 1e-12);
  }
  {
    const TriMesh a = samples::n_hole_torus(2, 26, true);
    const TriMesh b = samples::jitter(samples::n_hole_torus(2, 30, true), 0.2, 3);
    SurfaceMapOptions o;
    o.homotopy.full_solves = 0;
    o.homotopy.coarse_vertices = 0;
    o.homotopy.two_way = false;
    const SurfaceMapResult m = surface_map(a, b, o);
    expect_bounds_below_energies(m, &informative);
    EXPECT_LT(m.energy_ratio, 1.2);  // a copy: nearly conformal
    EXPECT_TRUE(m.quality_warning.empty()) << m.quality_warning;
  }
  {
    // The geometric classes (short markings) and the classes the restarted
    // search reaches, all solved at full resolution.
    const TriMesh a = samples::n_hole_torus(2, 26, true);
    const TriMesh b = samples::vase(30, true);
    SurfaceMapOptions o;
    o.homotopy.full_solves = 0;
    o.homotopy.search.cuts = 0;
    o.homotopy.two_way = false;
    // (The classical basis's candidates alone, the default until session
    // 25: the classes listed in both canonical bases
    // (LoopOptions::both_canonical_bases, the default since) include one
    // below geometric_ratio x the bound, so the geometric stage would not
    // run.)
    o.loops.short_canonical_generators = false;
    o.loops.both_canonical_bases = false;
    const SurfaceMapResult m = surface_map(a, b, o);
    EXPECT_GT(m.homotopy_search.geometric_classes, 0);
    int geometric = 0;
    for (const HomotopyCandidate& c : m.candidates) geometric += c.description.find("[geometric") != std::string::npos;
    EXPECT_GT(geometric, 0);
    expect_bounds_below_energies(m, &informative);
  }
  // Some of the wrong classes are ruled out by the curves alone.
  EXPECT_GT(informative, 0);
}

// Issue 19: the source's letters as a target read off its own loops (no
// uniformization) are the words source_class_bounds gives from its
// uniformized copy's class loops, on the flip path (the default metric).
TEST(ClassLowerBound, LettersFromOwnLoopsEqualTheUniformizedCopys) {
  const std::vector<std::pair<TriMesh, int>> shapes = {
      {samples::n_hole_torus(2, 26, true), 2}, {samples::vase(30, true), 2}, {samples::n_hole_torus(3, 32, true), 3}};
  for (const auto& [m, genus] : shapes) {
    const SurfaceMapOptions options;
    const SystemOfLoops sl = detail::source_loops(m, options);
    const CanonicalSchema cs = canonical_schema(sl.word);
    const Connectivity conn(m.F, m.num_vertices());
    const detail::SourceClassBounds b = detail::source_class_bounds(m, conn, sl, cs.generators, genus, options);
    ASSERT_TRUE(b.ok) << b.why;
    ASSERT_TRUE(b.uniformized.class_loops) << b.uniformized.class_loops_status;
    const detail::SourceLetters own = detail::source_letters_from_own_loops(m, conn, sl, cs.generators, genus, options);
    ASSERT_EQ(b.letters.as_target.size(), static_cast<size_t>(2 * genus)) << b.letters.as_target_status;
    EXPECT_EQ(own.as_target, b.letters.as_target) << own.as_target_status;
    EXPECT_EQ(own.as_target_inverse, b.letters.as_target_inverse);
    EXPECT_EQ(own.as_target_status, b.letters.as_target_status);
  }
}

// Issue 19: a remeshed copy, whose ranking stops at the overlay class, is
// mapped without the source's own uniformization: no bounds (the status says
// why), the same class, energy and letters as a target as when every class is
// ranked (ranking_gap < 0, which needs the bounds).
TEST(ClassLowerBound, RankingStoppedAtTheFirstClassSkipsTheSourcesUniformization) {
  const TriMesh a = samples::n_hole_torus(2, 30, true);
  const TriMesh b = samples::n_hole_torus(2, 32, true);
  SurfaceMapOptions o;
  o.homotopy.two_way = false;
  const SurfaceMapResult quick = surface_map(a, b, o);
  o.homotopy.ranking_gap = -1;
  const SurfaceMapResult all = surface_map(a, b, o);
  ASSERT_EQ(quick.ranking_status.rfind("stopped", 0), 0u) << quick.ranking_status;
  EXPECT_EQ(quick.class_bound_status.rfind("not computed", 0), 0u) << quick.class_bound_status;
  EXPECT_EQ(quick.class_bound_time_s, 0.0);
  for (const HomotopyCandidate& c : quick.candidates) EXPECT_TRUE(std::isnan(c.class_lower_bound)) << c.description;
  ASSERT_TRUE(all.class_bound_status.empty()) << all.class_bound_status;
  EXPECT_EQ(quick.chosen_candidate, all.chosen_candidate);
  EXPECT_NEAR(quick.final_energy, all.final_energy, 1e-9 * all.final_energy);
  ASSERT_EQ(quick.source_as_target.size(), 4u) << quick.source_as_target_status;
  EXPECT_EQ(quick.source_as_target, all.source_as_target);
  EXPECT_EQ(quick.source_as_target_inverse, all.source_as_target_inverse);
}

// The quality signal (docs/handle_classes.md "Quality signal"): the ratio is
// the chosen class's free energy over 8 pi (g - 1); after the fallback to
// positive weights on the source's own edges it is the class's energy with
// the intrinsic Delaunay cotangent weights (what the bound refers to), the
// own-edge energy's ratio reported beside it, and the warning follows the
// ratio used.
TEST(ClassLowerBound, QualityRatioUsesTheIntrinsicEnergyAfterTheOwnEdgeFallback) {
  const double bound = 8 * M_PI * 2;  // genus 3
  SurfaceMapResult r;
  r.genus = 3;
  r.candidates.resize(2);
  r.candidates[0].energy = 5.0 * bound;
  r.candidates[1].energy = 3.5 * bound;  // the chosen class, own-edge weights
  r.chosen_candidate = 1;
  detail::assess_quality(r);
  EXPECT_NEAR(r.energy_ratio, 3.5, 1e-12);
  EXPECT_TRUE(std::isnan(r.energy_ratio_own_edges));
  EXPECT_NE(r.quality_warning.find("may be twisted"), std::string::npos);
  r.intrinsic_class_energy = 1.4 * bound;
  detail::assess_quality(r);
  EXPECT_NEAR(r.energy_ratio, 1.4, 1e-12);
  EXPECT_NEAR(r.energy_ratio_own_edges, 3.5, 1e-12);
  EXPECT_EQ(r.quality_warning, "");
  r.intrinsic_class_energy = 3.2 * bound;  // twisted either way: still warned
  detail::assess_quality(r);
  EXPECT_NEAR(r.energy_ratio, 3.2, 1e-12);
  EXPECT_NE(r.quality_warning.find("may be twisted"), std::string::npos);
  EXPECT_EQ(r.quality_warning.find("mean D'"), std::string::npos);
}

// A genus-g result whose one candidate, chosen, has `ratio` x 8 pi (g - 1).
SurfaceMapResult one_class_result(int genus, double ratio) {
  SurfaceMapResult r;
  r.genus = genus;
  r.candidates.resize(1);
  r.candidates[0].energy = ratio * conformal_bound(genus);
  r.chosen_candidate = 0;
  return r;
}

// Session 26: a map whose images are stretched far past what straight
// triangles between them can show (mean D' >= 100) says so, beside the
// energy ratio's warning or alone; a usual mean D' adds nothing.
TEST(ClassLowerBound, WarningSaysWhenImagesAreTooStretchedForStraightTriangles) {
  SurfaceMapResult r = one_class_result(12, 71.7);
  r.mean_dilatation = 1.27e7;
  detail::assess_quality(r);
  EXPECT_NE(r.quality_warning.find("may be twisted"), std::string::npos) << r.quality_warning;
  EXPECT_NE(r.quality_warning.find("mean D' 1.27e+07"), std::string::npos) << r.quality_warning;
  EXPECT_NE(r.quality_warning.find("may fold"), std::string::npos) << r.quality_warning;
  r.candidates[0].energy = 1.5 * 8 * M_PI * 11;  // low energy, stretched images: still said
  detail::assess_quality(r);
  EXPECT_EQ(r.quality_warning.find("mean D' 1.27e+07"), 0u) << r.quality_warning;
  r.mean_dilatation = 4.0;
  detail::assess_quality(r);
  EXPECT_EQ(r.quality_warning, "");
}

// Issue 14: a warned ratio on which both directions agree (inverse classes, or
// inverse up to an isometry) says that no lower class was found from either
// side; not when the directions differ or were not compared, not below the
// warning, and once however often it is applied.
TEST(ClassLowerBound, WarningSaysWhenBothDirectionsEndOnTheClass) {
  SurfaceMapResult r = one_class_result(4, 4.5);
  detail::assess_quality(r);
  const std::string plain = r.quality_warning;
  ASSERT_NE(plain.find("may be twisted"), std::string::npos);
  for (const char* outcome : {"", "different"}) {
    r.directions.outcome = outcome;
    detail::qualify_quality_warning(r);
    EXPECT_EQ(r.quality_warning, plain) << outcome;
  }
  r.directions.outcome = "inverse";
  detail::qualify_quality_warning(r);
  detail::qualify_quality_warning(r);
  EXPECT_EQ(r.quality_warning.find(plain), 0u);
  EXPECT_NE(r.quality_warning.find("both directions end on this class (the other direction's class is its inverse)"),
            std::string::npos) << r.quality_warning;
  EXPECT_EQ(r.quality_warning.find("both directions"), r.quality_warning.rfind("both directions"));
  r.directions.outcome = "symmetric: both optimal";
  detail::assess_quality(r);
  detail::qualify_quality_warning(r);
  EXPECT_NE(r.quality_warning.find("up to an isometry"), std::string::npos) << r.quality_warning;
  r.candidates[0].energy = 1.5 * 8 * M_PI * 3;  // not warned: nothing added
  detail::assess_quality(r);
  detail::qualify_quality_warning(r);
  EXPECT_EQ(r.quality_warning, "");
}

}  // namespace
}  // namespace surfmap

namespace surfmap {
namespace {

// The generated genus-4 CAD plate (the development pair's plate,
// docs/handle_classes.md) as a source: its default loops carried onto its
// own uniformized copy (fixed metric, thousands of exact splits on long
// fan edges) give an isomorphism, so the plate has lengths, bounds and
// letters as a target. Joined by the fewest edges instead, a split edge was
// bypassed around a hole and one loop came out contractible.
// Issue 19: the ranking's bounds on its coarse copy (coarse_class_bounds):
// the copy's hyperbolic lengths are the source's within a few percent (the
// same surface at a quarter of the vertices), so are the curve bounds of
// twisted classes (what prunes), and the copy has no letters of the source.
TEST(ClassLowerBound, CoarseCopysBoundsAreTheSourcesWithinAFewPercent) {
  const TriMesh m = samples::n_hole_torus(2, 32, true);
  const SurfaceMapOptions options;
  const SystemOfLoops sl = detail::source_loops(m, options);
  const CanonicalSchema cs = canonical_schema(sl.word);
  const Connectivity conn(m.F, m.num_vertices());
  const CoarseSource copy = coarse_source(m, conn, {m.num_vertices() / 4});
  ASSERT_TRUE(copy.ok) << copy.why;
  const detail::SourceClassBounds fine = detail::source_class_bounds(m, conn, sl, cs.generators, 2, options);
  const detail::SourceClassBounds coarse = detail::coarse_class_bounds(copy.mesh, m, sl, cs.generators, 2, options);
  ASSERT_TRUE(fine.ok) << fine.why;
  ASSERT_TRUE(coarse.ok) << coarse.why;
  EXPECT_EQ(fine.copy_vertices, 0);
  EXPECT_EQ(coarse.copy_vertices, copy.mesh.num_vertices());
  EXPECT_TRUE(coarse.letters.as_target.empty());
  EXPECT_FALSE(coarse.letters.as_target_status.empty());
  // The probe curves x_j, x_i x_j^+-1 (ClassSpace::fingerprint's).
  for (int i = 1; i <= 4; ++i) {
    EXPECT_NEAR(coarse.source->length({i}) / fine.source->length({i}), 1.0, 0.02) << i;
    for (int j = i + 1; j <= 4; ++j)
      for (int sign : {1, -1})
        EXPECT_NEAR(coarse.source->length({i, sign * j}) / fine.source->length({i, sign * j}), 1.0, 0.02) << i << " " << j;
  }
  // Classes onto the source itself twisted 0..8 times along a1: the bound
  // grows from below the conformal bound to many times it.
  const MappingClassMove twist = twist_moves(2, false, false)[0];
  GroupMap theta = identity_map(4);
  for (int k = 0; k <= 8; ++k) {
    const double bf = (*fine.evaluator)(*fine.source, theta).curve_bound;
    const double bc = (*coarse.evaluator)(*fine.source, theta).curve_bound;
    EXPECT_NEAR(bc / bf, 1.0, 0.03) << k << " twists: " << bc << " on the copy, " << bf << " on the source";
    theta = compose(theta, twist.automorphism.map);
    for (Word& w : theta) w = dehn_reduce(w, canonical_relator(2));
  }
}

TEST(ClassLowerBound, CadPlateSourceCarriesOntoItsOwnUniformizedCopy) {
  const TriMesh m = samples::cad_plate(4, 64, 0.3);
  SurfaceMapOptions options;
  // The refined copy is the case in question; the flip path's T' is made
  // simplicial by exact flips now (uniformize/simplicial_flips.h), so it
  // no longer falls back to it by itself.
  options.uniformization.target_metric = UniformizationMetric::FixedConnectivity;
  const SystemOfLoops sl = detail::source_loops(m, options);
  const CanonicalSchema cs = canonical_schema(sl.word);
  const Connectivity conn(m.F, m.num_vertices());
  const detail::SourceClassBounds b = detail::source_class_bounds(m, conn, sl, cs.generators, 4, options);
  ASSERT_TRUE(b.ok) << b.why;
  ASSERT_GT(b.uniformized.refinement_splits, 0);  // the case in question: a refined copy
  EXPECT_EQ(b.letters.as_target.size(), 8u) << b.letters.as_target_status;
  // Every canonical generator is an essential curve: positive length.
  for (int j = 1; j <= 8; ++j) EXPECT_GT(b.source->length({j}), 0.05) << j;
  // The fewest-edge join (the overlay's default) is what failed here.
  const ProjectedLoopsResult fewest = project_loops(m, sl.loops, b.uniformized.loops, b.uniformized.layout.word);
  bool fewest_ok = fewest.ok;
  if (fewest_ok) {
    GroupMap iota(8);
    for (int j = 0; j < 8; ++j)
      iota[j] = dehn_reduce(substitute(substitute(cs.generators[j], fewest.loop_images), b.schema.letters),
                            canonical_relator(4));
    fewest_ok = homology_matrix(iota, 8).transpose() * symplectic_form(4) * homology_matrix(iota, 8) == symplectic_form(4);
  }
  EXPECT_FALSE(fewest_ok) << "the fewest-edge join now carries the plate: this test no longer covers the fix";
}

}  // namespace
}  // namespace surfmap
