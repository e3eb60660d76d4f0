#pragma once
// Words in a free group. A letter is a nonzero int: +k is generator k (1-based)
// and -k its inverse. Used for polygon schemata and homotopy classes.
#include <string>
#include <vector>

namespace surfmap {

using Word = std::vector<int>;

/// Freely reduced form (no x x^-1 pairs).
Word reduce(const Word& w);
/// w^-1.
Word inverse(const Word& w);
/// Reduced concatenation u v.
Word concat(const Word& u, const Word& v);
Word concat(std::initializer_list<Word> parts);
/// Cyclically reduced form (reduced, and first letter not the inverse of the last).
Word cyclic_reduce(const Word& w);
/// True when u and v are conjugate in the free group (equal as cyclic words
/// after cyclic reduction).
bool conjugate(const Word& u, const Word& v);
/// Product of commutators a1 b1 a1^-1 b1^-1 ... for generators given as
/// words [a1, b1, a2, b2, ...].
Word commutator_product(const std::vector<Word>& generators);
/// Dehn's algorithm for the surface group with the single relator R (a
/// one-vertex schema word: every letter once with each sign, so pieces have
/// length 1 and the presentation is C'(1/6) for genus >= 2): while the word
/// holds more than half of a cyclic rotation of R or R^-1, replace that part
/// by the inverse of the rest. The result is freely reduced and represents
/// the same group element; the identity reduces to the empty word.
Word dehn_reduce(const Word& w, const Word& relator);
/// The same, with the relator's rotations prepared once (for many words).
/// An empty relator gives free reduction only.
class DehnReducer {
 public:
  explicit DehnReducer(const Word& relator);
  Word operator()(const Word& w) const;

 private:
  std::vector<Word> rotations_;
  /// Indices into rotations_ (in their order) by first letter x, at
  /// x + max_letter_: only these can match a window starting with x (genus
  /// 11: 2 of the 88 rotations, which Dehn's algorithm otherwise compares
  /// at every letter).
  std::vector<std::vector<int>> by_first_letter_;
  int max_letter_ = 0;
};
/// Text form: letters named by `names` (index k-1 for letter k), inverses
/// written with "^-1", separated by spaces.
std::string to_text(const Word& w, const std::vector<std::string>& names);

}  // namespace surfmap
