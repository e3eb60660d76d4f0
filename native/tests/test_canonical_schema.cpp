#include "surfmap/topology/canonical_schema.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

#include "surfmap/error.h"

namespace surfmap {
namespace {

// A uniformly random one-vertex schema of genus g (rejection sampling over
// random words using each letter once with each sign).
Word random_schema(int g, std::mt19937& rng) {
  for (;;) {
    Word w;
    for (int k = 1; k <= 2 * g; ++k) w.insert(w.end(), {k, -k});
    std::shuffle(w.begin(), w.end(), rng);
    if (schema_vertex_count(w) == 1) return w;
  }
}

void expect_canonical(const Word& w, const CanonicalSchemaOptions& options = {}) {
  const CanonicalSchema s = canonical_schema(w, options);
  ASSERT_EQ(s.genus * 4, static_cast<int>(w.size()));
  ASSERT_EQ(static_cast<int>(s.generators.size()), 2 * s.genus);
  EXPECT_TRUE(conjugate(commutator_product(s.generators), w))
      << "commutator product is not conjugate to the input word";
  // The inverse substitution: replacing each generator by its word in the
  // loops turns letter k's expression back into letter k.
  ASSERT_EQ(static_cast<int>(s.letters.size()), 2 * s.genus);
  for (int k = 1; k <= 2 * s.genus; ++k) {
    Word back;
    for (int x : s.letters[k - 1]) {
      const Word& g = s.generators[std::abs(x) - 1];
      back = concat(back, x > 0 ? g : inverse(g));
    }
    EXPECT_EQ(back, Word{k}) << "letter " << k;
  }
  // The new generators must generate the whole group: their abelianisation
  // (exponent sums per letter) is unimodular, |det| = 1.
  const int n = 2 * s.genus;
  std::vector<std::vector<double>> M(n, std::vector<double>(n, 0.0));
  for (int i = 0; i < n; ++i)
    for (int x : s.generators[i]) M[i][std::abs(x) - 1] += x > 0 ? 1 : -1;
  double det = 1;
  for (int c = 0; c < n; ++c) {
    int piv = c;
    for (int r = c; r < n; ++r)
      if (std::abs(M[r][c]) > std::abs(M[piv][c])) piv = r;
    if (std::abs(M[piv][c]) < 1e-12) {
      det = 0;
      break;
    }
    if (piv != c) std::swap(M[piv], M[c]), det = -det;
    det *= M[c][c];
    for (int r = c + 1; r < n; ++r) {
      const double f = M[r][c] / M[c][c];
      for (int k = c; k < n; ++k) M[r][k] -= f * M[c][k];
    }
  }
  EXPECT_NEAR(std::abs(det), 1.0, 1e-9);
}

TEST(Words, ReduceInverseConjugate) {
  EXPECT_EQ(reduce({1, 2, -2, -1, 3}), (Word{3}));
  EXPECT_EQ(inverse({1, -2, 3}), (Word{-3, 2, -1}));
  EXPECT_TRUE(conjugate({1, 2, 3}, {3, 1, 2}));
  EXPECT_TRUE(conjugate({-4, 1, 2, 4}, {1, 2}));
  EXPECT_FALSE(conjugate({1, 2}, {2, -1}));
  EXPECT_EQ(to_text({1, -2}, {"a1", "b1"}), "a1 b1^-1");
}

TEST(Words, DehnReductionSolvesTheWordProblem) {
  std::mt19937 rng(3);
  for (int g = 2; g <= 5; ++g) {
    const Word R = random_schema(g, rng);
    // Conjugates of R^±1 multiplied together are the identity.
    for (int trial = 0; trial < 20; ++trial) {
      Word w;
      for (int k = 0; k < 3; ++k) {
        Word c;
        for (int q = 0; q < 4; ++q) c.push_back((1 + rng() % (2 * g)) * (rng() % 2 ? 1 : -1));
        Word rr = R;
        std::rotate(rr.begin(), rr.begin() + rng() % rr.size(), rr.end());
        w = concat({w, c, rng() % 2 ? rr : inverse(rr), inverse(c)});
      }
      EXPECT_TRUE(dehn_reduce(w, R).empty()) << "g=" << g;
    }
    // Non-trivial elements stay non-trivial; short words are kept as they are.
    EXPECT_FALSE(dehn_reduce(concat(Word{1}, R), R).empty());
    EXPECT_EQ(dehn_reduce(Word{1, 2}, R), (Word{1, 2}));
  }
}

TEST(Words, DehnReductionOfLongWordsIsReducedAndEquivalent) {
  // Words of 1e5 letters (products of substituted twisted classes reach
  // that): the result holds no more than half of any rotation of R^±1, is
  // freely reduced, represents the same element (w · dehn(w)^-1 reduces to
  // the identity) and is reduced again to itself.
  std::mt19937 rng(11);
  for (int g : {2, 3, 5}) {
    const Word R = random_schema(g, rng);
    const size_t n = R.size();
    std::vector<Word> rotations;
    for (const Word& r : {R, inverse(R)})
      for (size_t s = 0; s < n; ++s) {
        Word rot(r.begin() + s, r.end());
        rot.insert(rot.end(), r.begin(), r.begin() + s);
        rotations.push_back(rot);
      }
    Word w;
    for (int k = 0; k < 100000; ++k) {
      // Mostly pieces of relators, so that many replacements cascade.
      if (rng() % 3 == 0) {
        w.push_back((1 + rng() % (2 * g)) * (rng() % 2 ? 1 : -1));
      } else {
        const Word& r = rotations[rng() % rotations.size()];
        const size_t len = 1 + rng() % n;
        w.insert(w.end(), r.begin(), r.begin() + len);
        k += static_cast<int>(len) - 1;
      }
    }
    const DehnReducer dehn(R);
    const Word d = dehn(w);
    EXPECT_LT(d.size(), w.size());
    EXPECT_EQ(reduce(d), d);
    for (size_t i = 0; i + n / 2 < d.size(); ++i)
      for (const Word& r : rotations)
        ASSERT_FALSE(std::equal(r.begin(), r.begin() + n / 2 + 1, d.begin() + i)) << "g=" << g << " at " << i;
    EXPECT_TRUE(dehn(concat(w, inverse(d))).empty()) << "g=" << g;
    EXPECT_EQ(dehn(d), d);
  }
}

TEST(CanonicalSchema, CanonicalWordNeedsNoRewriting) {
  for (int g = 1; g <= 4; ++g) {
    Word w;
    for (int i = 0; i < g; ++i) w.insert(w.end(), {2 * i + 1, 2 * i + 2, -(2 * i + 1), -(2 * i + 2)});
    const CanonicalSchema s = canonical_schema(w);
    EXPECT_TRUE(conjugate(commutator_product(s.generators), w));
    for (const Word& gen : s.generators) EXPECT_EQ(gen.size(), 1u);
  }
}

TEST(CanonicalSchema, NonCanonicalGenusTwoWord) {
  // a b c a^-1 d c^-1 b^-1 d^-1 style words arise from greedy loops.
  expect_canonical({1, 2, -1, 3, -2, 4, -3, -4});
  expect_canonical({1, 3, 2, -1, -3, 4, -2, -4});
  expect_canonical({1, 2, 3, 4, -1, -2, -3, -4});
}

TEST(CanonicalSchema, RandomSchemataOfHighGenus) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 300; ++trial) {
    const int g = 1 + trial % 6;
    const Word w = random_schema(g, rng);
    ASSERT_EQ(schema_vertex_count(w), 1);
    expect_canonical(w);
  }
}

// Issue 13 (session 21): the classical moves conjugate the finished
// generators by every later move's conjugator, so their words grow handle by
// handle; with short_generators each generator is built from one rest word
// and never conjugated again: at most 2 x 4g letters whatever the genus, and
// still a canonical basis of the same group.
TEST(CanonicalSchema, ShortGeneratorsStayWithinTwiceTheWordLength) {
  std::mt19937 rng(21);
  CanonicalSchemaOptions shortest;
  shortest.short_generators = true;
  size_t classical_longest = 0, short_longest = 0;
  for (int trial = 0; trial < 120; ++trial) {
    const int g = 2 + trial % 11;
    const Word w = random_schema(g, rng);
    expect_canonical(w, shortest);
    const CanonicalSchema s = canonical_schema(w, shortest);
    for (const Word& gen : s.generators) {
      EXPECT_LE(gen.size(), 2 * w.size()) << "g=" << g;
      short_longest = std::max(short_longest, gen.size());
    }
    for (const Word& gen : canonical_schema(w).generators) classical_longest = std::max(classical_longest, gen.size());
  }
  EXPECT_LT(short_longest, classical_longest);
  // A word that is already canonical needs no rewriting either way.
  Word canonical;
  for (int i = 0; i < 5; ++i) canonical.insert(canonical.end(), {2 * i + 1, 2 * i + 2, -(2 * i + 1), -(2 * i + 2)});
  for (const Word& gen : canonical_schema(canonical, shortest).generators) EXPECT_EQ(gen.size(), 1u);
}

TEST(CanonicalSchema, RejectsWordsThatAreNotSchemata) {
  EXPECT_THROW(canonical_schema({1, 2, -1}), InputError);
  EXPECT_THROW(canonical_schema({1, 1, -2, -2}), InputError);
  EXPECT_THROW(canonical_schema({1, -1, 2, -2}), InputError);  // no interleaving: a sphere-like word
  EXPECT_THROW(canonical_schema({1, 2, 3, -1, 4, -3, -2, -4}), InputError);  // three vertices
}

}  // namespace
}  // namespace surfmap
