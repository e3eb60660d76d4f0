#include "surfmap/topology/mapping_class_search.h"

#include <algorithm>
#include <limits>
#include <set>
#include <utility>
#include <string>

#include <gtest/gtest.h>

#include "surfmap/error.h"

namespace surfmap {
namespace {

using IntVector = Eigen::Matrix<long long, Eigen::Dynamic, 1>;

const MappingClassMove& move_named(const std::vector<MappingClassMove>& moves, const std::string& name) {
  for (const MappingClassMove& m : moves)
    if (m.name == name) return m;
  throw std::runtime_error("no move " + name);
}

// The transvection x -> x + <c, x> c of a simple curve of class c.
IntMatrix transvection(const IntVector& c, int g) {
  const IntMatrix J = symplectic_form(g);
  return IntMatrix::Identity(2 * g, 2 * g) + c * (c.transpose() * J);
}

TEST(MappingClassSearch, TwistMovesAreExactAutomorphismsWithTheTwistsHomology) {
  for (int g = 2; g <= 5; ++g) {
    const int n = 2 * g;
    const std::vector<MappingClassMove> moves = twist_moves(g);
    EXPECT_EQ(static_cast<int>(twist_moves(g, false, false).size()), 8 * g - 4) << "genus " << g;
    const int bp = g >= 3 ? 4 * (g - 1) : 0;  // bounding pair maps and inverses
    EXPECT_EQ(static_cast<int>(twist_moves(g, false, true).size()), 8 * g - 4 + bp) << "genus " << g;
    EXPECT_GT(static_cast<int>(moves.size()), 8 * g - 4 + 10 * (g - 1) + bp) << "genus " << g;
    EXPECT_LE(static_cast<int>(moves.size()), 48 * g - 44 + bp) << "genus " << g;
    const Word R = canonical_relator(g);
    const IntMatrix J = symplectic_form(g);
    std::set<GroupMap> distinct;
    for (const MappingClassMove& m : moves) {
      // The relator is fixed exactly (not only up to conjugation), the
      // inverse composes to the identity, the action on H_1 is symplectic.
      EXPECT_TRUE(is_surface_automorphism(m.automorphism, g)) << m.name;
      EXPECT_TRUE(dehn_reduce(concat(substitute(R, m.automorphism.map), inverse(R)), R).empty()) << m.name;
      const IntMatrix M = homology_matrix(m.automorphism.map, n);
      EXPECT_EQ(M.transpose() * J * M, J) << m.name;
      distinct.insert(m.automorphism.map);
    }
    EXPECT_EQ(distinct.size(), moves.size()) << "genus " << g << ": some moves coincide";
    for (int i = 0; i < g; ++i) {
      IntVector a = IntVector::Zero(n), b = IntVector::Zero(n);
      a[2 * i] = 1, b[2 * i + 1] = 1;
      const std::string h = std::to_string(i + 1);
      EXPECT_EQ(homology_matrix(move_named(moves, "T(a" + h + ")").automorphism.map, n), transvection(a, g));
      EXPECT_EQ(homology_matrix(move_named(moves, "T(b" + h + ")").automorphism.map, n), transvection(b, g));
      EXPECT_EQ(homology_matrix(move_named(moves, "T(a" + h + ")^-1").automorphism.map, n),
                IntMatrix(2 * IntMatrix::Identity(n, n) - transvection(a, g)));  // (I + N)^-1 = I - N, N^2 = 0
      if (i + 1 < g) {
        // The chain curve through handles i and i+1: class a_i + a_i+1.
        IntVector c = IntVector::Zero(n);
        c[2 * i] = 1, c[2 * i + 2] = 1;
        EXPECT_EQ(homology_matrix(move_named(moves, "T(c" + h + ")").automorphism.map, n), transvection(c, g));
        // Separating curves: Torelli elements (trivial on homology), and not
        // inner automorphisms (a generator's image is not conjugate to it).
        const GroupMap& s = move_named(moves, "T(s" + h + ")").automorphism.map;
        EXPECT_EQ(homology_matrix(s, n), IntMatrix::Identity(n, n));
        const GroupMap& sc = move_named(moves, "[T(c" + h + ")] T(s" + h + ")").automorphism.map;
        EXPECT_EQ(homology_matrix(sc, n), IntMatrix::Identity(n, n));
        bool moved = false;
        for (int j = 0; j < n; ++j) moved = moved || !conjugate(dehn_reduce(sc[j], R), Word{j + 1});
        EXPECT_TRUE(moved) << "genus " << g << " conjugated T(s" << h << ") acts like an inner automorphism";
        // Bounding pair maps (genus >= 3): trivial on homology, and unlike
        // T(s_j) (which conjugates generators, each staying in its
        // conjugacy class) some generator's image is not conjugate to it.
        if (g >= 3) {
          const std::string hn = std::to_string(i + 2);
          for (const std::string& name :
               {"BP(T(a" + hn + "); T(a" + h + ") T(b" + h + ") T(c" + h + "))", "BP(T(a" + h + "); T(c" + h + ") T(b" + hn + ") T(a" + hn + "))"}) {
            const GroupMap& b = move_named(moves, name).automorphism.map;
            EXPECT_EQ(homology_matrix(b, n), IntMatrix::Identity(n, n)) << name;
            bool off = false;
            for (int j = 0; j < n; ++j) off = off || !conjugate(dehn_reduce(b[j], R), Word{j + 1});
            EXPECT_TRUE(off) << name << " fixes every generator's conjugacy class";
          }
        }
      }
    }
  }
  EXPECT_THROW(twist_moves(1), InputError);
}

// The descent on a known landscape: energy = total cyclically reduced length
// of the generators' images (conjugation invariant, minimal, 2g, exactly at
// the identity class among these). From the identity composed with twists
// along a_1 (twice) and b_2 and a separating twist, it must come back.
// The identity composed with the named moves on the source side, and the
// total length of a class's cyclically reduced words (the identity's: 2g).
struct TwistedClasses {
  explicit TwistedClasses(int genus) : g(genus), moves(twist_moves(genus)), reduce(canonical_relator(genus)) {}
  GroupMap after(std::initializer_list<const char*> names) const {
    GroupMap theta = identity_map(2 * g);
    for (const char* name : names) {
      theta = compose(theta, move_named(moves, name).automorphism.map);
      for (Word& w : theta) w = reduce(w);
    }
    return theta;
  }
  double length(const GroupMap& theta) const {
    double total = 0;
    for (const Word& w : theta) total += static_cast<double>(cyclic_reduce(reduce(w)).size());
    return total;
  }
  int g;
  std::vector<MappingClassMove> moves;
  DehnReducer reduce;
};

TEST(MappingClassSearch, DescentUndoesKnownTwists) {
  const int g = 2;
  const TwistedClasses tc(g);
  auto length = [&](const GroupMap& theta) { return tc.length(theta); };
  const GroupMap start = tc.after({"T(a1)", "T(a1)", "T(b2)^-1", "T(s1)"});
  ASSERT_GT(length(start), 2.0 * g);
  int evaluations = 0;
  TwistSearchOptions o;
  o.max_evaluations = 200;
  o.max_steps = 20;
  o.evaluations_per_step = 200;
  o.screen_steps = 0;
  o.pair_moves = false;  // (pairs: below)
  const TwistSearchResult r = twist_search(start, length(start), g, length, [&](const GroupMap& t) {
    ++evaluations;
    return length(t);
  }, o);
  EXPECT_EQ(r.energy, 2.0 * g);
  EXPECT_EQ(length(r.best), 2.0 * g);
  EXPECT_EQ(static_cast<int>(r.evaluations.size()), evaluations);
  EXPECT_LE(r.moves.size(), 4u);
  EXPECT_EQ(r.stop_reason, "no improving neighbour");
  // With pairs of moves after the singles stall: the same optimum, no pair
  // step needed, and the stop says the pairs were tried.
  {
    TwistSearchOptions po = o;
    po.pair_moves = true;
    po.max_evaluations = 2000;
    const TwistSearchResult rp = twist_search(start, length(start), g, length, length, po);
    EXPECT_EQ(rp.energy, 2.0 * g);
    EXPECT_EQ(rp.pair_steps, 0);
    EXPECT_EQ(rp.stop_reason, "no improving neighbour or pair");
  }
  // The screening descent alone (no energy evaluations but its end point's).
  o.screen_steps = 20;
  evaluations = 0;
  const TwistSearchResult s = twist_search(start, length(start), g, length, [&](const GroupMap& t) {
    ++evaluations;
    return length(t);
  }, o);
  EXPECT_EQ(s.energy, 2.0 * g);
  EXPECT_EQ(s.screen_scores.back(), 2.0 * g);
  // A budget of one evaluation stops there.
  o.screen_steps = 0;
  o.max_evaluations = 1;
  const TwistSearchResult b = twist_search(start, length(start), g, length, length, o);
  EXPECT_EQ(b.evaluations.size(), 1u);
  EXPECT_EQ(b.stop_reason, "evaluation budget");
}

// Issue 14 (session 26): the iterated local search (TwistSearchOptions::
// kicks). The energy is the words' length (the identity, 2g letters, is the
// one minimum) except at a trap T three twists from the identity, given 2g +
// 1/2 (T = T(a1)^2 T(b2)^-1): lower than every neighbour and pair of T (their words are longer), so
// the descent from T stops there, with pairs too; kicks of three random
// moves followed by descents reach the identity.
TEST(MappingClassSearch, KicksLeaveALocalMinimumThatPairsCannot) {
  const int g = 2;
  const TwistedClasses tc(g);
  auto length = [&](const GroupMap& theta) { return tc.length(theta); };
  const GroupMap trap = tc.after({"T(a1)", "T(a1)", "T(b2)^-1"});
  const double trap_energy = 2.0 * g + 0.5;
  ASSERT_GT(length(trap), trap_energy + 1);
  auto energy = [&](const GroupMap& theta) { return theta == trap ? trap_energy : length(theta); };
  TwistSearchOptions o;
  o.max_evaluations = 3000;
  o.max_steps = 20;
  o.evaluations_per_step = 200;
  o.screen_steps = 0;
  const TwistSearchResult stuck = twist_search(trap, trap_energy, g, length, energy, o);
  EXPECT_EQ(stuck.energy, trap_energy);
  EXPECT_EQ(stuck.stop_reason, "no improving neighbour or pair");
  EXPECT_EQ(stuck.kicks, 0);
  o.kicks = 4;
  o.kick_moves = 3;
  o.kick_evaluations = 400;
  int evaluations = 0;
  const TwistSearchResult kicked = twist_search(trap, trap_energy, g, length, [&](const GroupMap& t) {
    ++evaluations;
    return energy(t);
  }, o);
  EXPECT_EQ(kicked.energy, 2.0 * g);
  EXPECT_EQ(length(kicked.best), 2.0 * g);
  EXPECT_EQ(kicked.kicks, 4);
  EXPECT_GE(kicked.improving_kicks, 1);
  // Every evaluation is reported and within the budget; the kicks' are
  // marked by step -1 and named by their moves.
  EXPECT_EQ(static_cast<int>(kicked.evaluations.size()), evaluations);
  EXPECT_LE(evaluations, o.max_evaluations);
  int kick_evaluations = 0;
  for (const TwistSearchEvaluation& ev : kicked.evaluations)
    if (ev.step == -1) {
      ++kick_evaluations;
      EXPECT_EQ(ev.move.rfind("kick ", 0), 0u) << ev.move;
    }
  EXPECT_EQ(kick_evaluations, evaluations - static_cast<int>(stuck.evaluations.size()));
  EXPECT_NE(kicked.stop_reason.find("4 kicks"), std::string::npos) << kicked.stop_reason;
  // Every screening is counted, the kicks' and their descents' too (they were left out).
  int screens = 0;
  const TwistSearchResult counted = twist_search(trap, trap_energy, g, [&](const GroupMap& t) {
    ++screens;
    return length(t);
  }, energy, o);
  EXPECT_EQ(counted.screened, screens);
  EXPECT_GT(counted.screened, stuck.screened);
  // The kicks are drawn from the seed: the same seed, the same search.
  const TwistSearchResult again = twist_search(trap, trap_energy, g, length, energy, o);
  ASSERT_EQ(again.evaluations.size(), kicked.evaluations.size());
  for (size_t k = 0; k < again.evaluations.size(); ++k) EXPECT_EQ(again.evaluations[k].move, kicked.evaluations[k].move);
}

// Issue 14 (session 28; TwistSearchOptions::kicks_only, the pipeline's
// high kicks): from the trap above, no descent from the start (its first
// evaluation is a kick), but each kick is still followed by its own
// descent, which reaches the identity (the pipeline ran the kicks without
// their descents at first: 8 kicks, 8 solves, none lower).
TEST(MappingClassSearch, KicksOnlyStillDescendAfterEachKick) {
  const int g = 2;
  const TwistedClasses tc(g);
  auto length = [&](const GroupMap& theta) { return tc.length(theta); };
  const GroupMap trap = tc.after({"T(a1)", "T(a1)", "T(b2)^-1"});
  const double trap_energy = 2.0 * g + 0.5;
  auto energy = [&](const GroupMap& theta) { return theta == trap ? trap_energy : length(theta); };
  TwistSearchOptions o;
  o.kicks_only = true;
  o.kicks = 4;
  o.kick_evaluations = 400;
  o.max_evaluations = 4 * 401;
  const TwistSearchResult r = twist_search(trap, trap_energy, g, length, energy, o);
  ASSERT_FALSE(r.evaluations.empty());
  EXPECT_EQ(r.evaluations[0].move.rfind("kick 1 (", 0), 0u) << r.evaluations[0].move;
  for (const TwistSearchEvaluation& ev : r.evaluations) EXPECT_EQ(ev.step, -1) << ev.move;
  EXPECT_TRUE(r.screen_moves.empty());
  EXPECT_EQ(r.kicks, 4);
  EXPECT_GT(static_cast<int>(r.evaluations.size()), r.kicks);  // (the kicks' descents)
  EXPECT_EQ(r.energy, 2.0 * g);
  EXPECT_EQ(length(r.best), 2.0 * g);
  EXPECT_EQ(r.stop_reason.rfind("kicks only; 4 kicks, ", 0), 0u) << r.stop_reason;
}

// A kick with no neighbour to move to is not made, nor counted (every kick
// was counted before, made or not).
TEST(MappingClassSearch, KicksWithNoNeighbourAreNotCounted) {
  const int g = 2;
  const TwistedClasses tc(g);
  const GroupMap start = tc.after({"T(a1)"});
  // Only the start has a finite screen: no neighbour to evaluate or kick to.
  auto screen = [&](const GroupMap& theta) {
    return theta == start ? 1.0 : std::numeric_limits<double>::infinity();
  };
  int evaluations = 0;
  auto energy = [&](const GroupMap&) {
    ++evaluations;
    return 1.0;
  };
  TwistSearchOptions o;
  o.kicks = 3;
  const TwistSearchResult r = twist_search(start, 1.0, g, screen, energy, o);
  EXPECT_EQ(r.kicks, 0);
  EXPECT_EQ(r.improving_kicks, 0);
  EXPECT_EQ(evaluations, 0);
  EXPECT_TRUE(r.evaluations.empty());
  EXPECT_NE(r.stop_reason.find("; 0 kicks, 0 lower"), std::string::npos) << r.stop_reason;
}

// A count below its least is a one-line InputError naming the option (a
// kick of no moves, no choices or no descent evaluations was run before).
TEST(MappingClassSearch, SearchOptionsBelowTheirLeastAreInputErrors) {
  const int g = 2;
  const TwistedClasses tc(g);
  auto length = [&](const GroupMap& theta) { return tc.length(theta); };
  const GroupMap start = tc.after({"T(a1)"});
  const std::pair<const char*, void (*)(TwistSearchOptions&)> bad[] = {
      {"kicks", [](TwistSearchOptions& o) { o.kicks = -1; }},
      {"kick_moves", [](TwistSearchOptions& o) { o.kick_moves = 0; }},
      {"kick_choices", [](TwistSearchOptions& o) { o.kick_choices = 0; }},
      {"kick_evaluations", [](TwistSearchOptions& o) { o.kick_evaluations = 0; }},
      {"kick_evaluations", [](TwistSearchOptions& o) { o.kick_evaluations = -5; }},
      {"evaluations_per_step", [](TwistSearchOptions& o) { o.evaluations_per_step = 0; }},
      {"max_evaluations", [](TwistSearchOptions& o) { o.max_evaluations = -1; }},
      {"max_steps", [](TwistSearchOptions& o) { o.max_steps = -1; }},
      {"screen_steps", [](TwistSearchOptions& o) { o.screen_steps = -1; }},
      {"pair_starts", [](TwistSearchOptions& o) { o.pair_starts = -1; }},
      {"tolerance", [](TwistSearchOptions& o) { o.tolerance = std::numeric_limits<double>::quiet_NaN(); }},
      {"tolerance", [](TwistSearchOptions& o) { o.tolerance = -1e-3; }},
  };
  for (const auto& [name, spoil] : bad) {
    TwistSearchOptions o;
    o.kicks = 2;
    spoil(o);
    try {
      twist_search(start, length(start), g, length, length, o);
      ADD_FAILURE() << name << ": no error";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(name), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
}

// Issue 13 (session 27): one-sided moves (TwistSearchOptions::source_moves,
// target_moves), e.g. the Dehn twist along a short curve c = M(a1) that the
// canonical basis reaches only through a long conjugator M. The energy: 4 +
// 10 |k| on the powers T(c)^k (|k| <= 3, told apart by their homology, the
// transvection x -> x + k <v, x> v of c's class v), 1000 + the words' length
// elsewhere. From T(c)^3, three steps of T(c)^-1 on the source side return
// to the identity; the canonical moves alone lower nothing.
TEST(MappingClassSearch, OneSidedMovesUndoTwistsAlongAConjugatedCurve) {
  const int g = 2;
  const TwistedClasses tc(g);
  auto length = [&](const GroupMap& theta) { return tc.length(theta); };
  // M: a long automorphism; T(c) = M T(a1) M^-1.
  SurfaceAutomorphism M{identity_map(2 * g), identity_map(2 * g), 0};
  for (const char* name : {"T(b1)", "T(c1)", "T(a2)^-1", "T(s1)", "T(b2)", "T(c1)", "T(b1)^-1"}) {
    const auto m = std::find_if(tc.moves.begin(), tc.moves.end(), [&](const MappingClassMove& x) { return x.name == name; });
    ASSERT_NE(m, tc.moves.end()) << name;
    M.map = compose(M.map, m->automorphism.map);
    M.inverse = compose(m->automorphism.inverse, M.inverse);
    for (Word& w : M.map) w = tc.reduce(w);
    for (Word& w : M.inverse) w = tc.reduce(w);
  }
  SurfaceAutomorphism Ta1{identity_map(2 * g), identity_map(2 * g), 1};
  Ta1.map[1] = {2, 1};
  Ta1.inverse[1] = {2, -1};
  SurfaceAutomorphism Tc{compose(M.map, compose(Ta1.map, M.inverse)), compose(M.map, compose(Ta1.inverse, M.inverse)), 1};
  for (Word& w : Tc.map) w = tc.reduce(w);
  for (Word& w : Tc.inverse) w = tc.reduce(w);
  ASSERT_TRUE(is_surface_automorphism(Tc, g));
  GroupMap start = identity_map(2 * g);
  for (int k = 0; k < 3; ++k) {
    start = compose(start, Tc.map);
    for (Word& w : start) w = tc.reduce(w);
  }
  ASSERT_GT(length(start), 2.0 * g + 10);
  const IntMatrix J = symplectic_form(g);
  const Eigen::Matrix<long long, Eigen::Dynamic, 1> v = abelianize(M.map[0], 2 * g);
  const IntMatrix V = v;
  auto energy = [&](const GroupMap& theta) {
    const IntMatrix H = homology_matrix(theta, 2 * g);
    for (int k = -3; k <= 3; ++k)
      if (H == IntMatrix::Identity(2 * g, 2 * g) + k * V * (V.transpose() * J)) return 4.0 + 10.0 * std::abs(k);
    return 1000 + length(theta);
  };
  ASSERT_EQ(energy(start), 34.0);
  ASSERT_EQ(energy(identity_map(2 * g)), 4.0);
  TwistSearchOptions o;
  o.max_evaluations = 1000;
  o.max_steps = 3;
  o.evaluations_per_step = 1000;
  o.screen_steps = 0;
  o.pair_moves = false;
  const TwistSearchResult without = twist_search(start, energy(start), g, length, energy, o);
  EXPECT_EQ(without.energy, 34.0);
  EXPECT_TRUE(without.moves.empty());
  o.source_moves = {{"T(c)", Tc}, {"T(c)^-1", {Tc.inverse, Tc.map, 1}}};
  const TwistSearchResult with = twist_search(start, energy(start), g, length, energy, o);
  EXPECT_EQ(with.energy, 4.0);
  ASSERT_EQ(with.moves.size(), 3u);
  for (const std::string& m : with.moves) EXPECT_EQ(m, "source T(c)^-1");
  // The same move offered on the target side only, with the source side
  // off: from the identity twisted on the target side (T(c)^3 as a map of
  // the target letters), the search names it "target".
  o.source_moves.clear();
  o.target_moves = {{"T(c)", Tc}, {"T(c)^-1", {Tc.inverse, Tc.map, 1}}};
  o.source_side = false;
  const TwistSearchResult target = twist_search(start, energy(start), g, length, energy, o);
  EXPECT_EQ(target.energy, 4.0);
  ASSERT_EQ(target.moves.size(), 3u);
  for (const std::string& m : target.moves) EXPECT_EQ(m, "target T(c)^-1");
}

}  // namespace
}  // namespace surfmap
