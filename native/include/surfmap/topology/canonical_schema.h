#pragma once
// Canonical polygon schema, computed algebraically (docs/method.md §2.3 and §7;
// docs/method.md §2.2). The cut along a system of loops gives a 4g-gon whose cyclic
// boundary word W uses every loop letter once with each sign, but not in the
// canonical order a1 b1 a1^-1 b1^-1 ... ag bg ag^-1 bg^-1. The classical
// cut-and-paste moves of the classification of surfaces, done on words
// instead of on the mesh, give new generators (words in the loops) whose
// commutator product is conjugate to W. The mesh is never re-cut.
#include <vector>

#include "surfmap/topology/words.h"

namespace surfmap {

struct CanonicalSchema {
  int genus = 0;
  /// 2g words in the original loop letters: [a1, b1, a2, b2, ...]. Their
  /// commutator product a1 b1 a1^-1 b1^-1 ... is conjugate to the input word.
  std::vector<Word> generators;
  /// The inverse substitution: each original loop letter k (index k-1) as a
  /// word in the new generators, whose letters are 1..2g for a1, b1, a2, ...
  /// Evaluating these in a group where the a_i, b_i are known gives the
  /// image of every loop (docs/method.md §2.6).
  std::vector<Word> letters;
  /// Number of cut-and-paste moves applied (one per handle).
  int moves = 0;
};

struct CanonicalSchemaOptions {
  /// How each cut-and-paste move keeps the invariant "input word ~ finished
  /// commutators * rest". false (default, the classical order): the rest is
  /// rotated to the chosen pair and every finished generator is conjugated
  /// by the rotation and by the move's conjugator, so the conjugators pile
  /// up handle by handle (issue 13: on the raw genus-12 wheel's 48-letter
  /// word the generators reach 351 loop letters, matrices of |a| = 4e122).
  /// true: each move takes the pair at the first letter of the rest (every
  /// letter of a one-vertex word has an interleaved partner, so no
  /// rotation is needed), chooses the partner that gives the fewest
  /// letters, and conjugates only the new pair; the finished generators are
  /// never touched again, so each generator is a sub-word of one rest
  /// word (at most 4g letters, docs/robustness.md "Canonical generators").
  bool short_generators = false;
};

/// Number of vertices of the surface obtained by gluing the polygon's sides
/// as the word says (1 for the word of a system of loops through one point).
int schema_vertex_count(const Word& word);

/// `word`: cyclic boundary word of a one-vertex schema of an orientable closed
/// surface, length 4g, each letter ±1..±2g exactly once with each sign.
/// Throws InputError when the word is not of that kind (names the letter).
CanonicalSchema canonical_schema(const Word& word, const CanonicalSchemaOptions& options = {});

}  // namespace surfmap
