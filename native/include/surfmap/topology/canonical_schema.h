#pragma once
// Canonical polygon schema, computed algebraically (docs/method.md §2.3 and §7;
// paper §IV-A). The cut along a system of loops gives a 4g-gon whose cyclic
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

/// Number of vertices of the surface obtained by gluing the polygon's sides
/// as the word says (1 for the word of a system of loops through one point).
int schema_vertex_count(const Word& word);

/// `word`: cyclic boundary word of a one-vertex schema of an orientable closed
/// surface, length 4g, each letter ±1..±2g exactly once with each sign.
/// Throws InputError when the word is not of that kind (names the letter).
CanonicalSchema canonical_schema(const Word& word);

}  // namespace surfmap
