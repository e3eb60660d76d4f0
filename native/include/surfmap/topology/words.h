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
/// Every freely reduced word of at most `radius` letters in the 2g letters
/// ±1..±2g, the empty word first, then by length (conjugators and lifts
/// searched by enumeration).
std::vector<Word> reduced_words_up_to(int genus, int radius);
/// Hash of a word's letters (for memos keyed by words).
struct WordHash {
  size_t operator()(const Word& w) const;
};
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
  /// Every word of `words` reduced (e.g. a group map's generator images).
  std::vector<Word> each(std::vector<Word> words) const;
  /// The same as (*this)(rotation of u starting at letter r), letter for
  /// letter, for u Dehn-reduced and freely reduced (an output of this
  /// reducer or a subword of one; u.size() >= r). Only the letters near the
  /// junction of u[r..] and u[..r) can change: their reduction runs until
  /// the last m - 1 letters pushed (m = floor(|R|/2) + 1) are untouched
  /// letters of u[..r), and the rest is copied (time O(|u|) copying plus
  /// the changed part, where the full reduction tests every letter).
  Word reduce_rotation(const Word& u, size_t r) const;
  /// Letters of a window Dehn's algorithm replaces: m = floor(|R|/2) + 1
  /// (0 without a relator).
  size_t window() const { return rotations_.empty() ? 0 : rotations_.front().size() / 2 + 1; }
  /// Whether the window() letters of the cyclic word u from `start` on
  /// (indices mod |u|; needs |u| >= window() >= 1) are the first letters of
  /// a rotation of R^±1, i.e. more than half of it.
  bool holds_more_than_half(const Word& u, size_t start) const;

 private:
  // Dehn's algorithm on the stack `out` fed with in[0..n) (file comment of
  // words.cpp); `in_reduced`: in is Dehn-reduced and freely reduced, so the
  // rest can be copied once m - 1 untouched letters of it are on top.
  void run(Word& out, const int* in, size_t n, bool in_reduced) const;
  std::vector<Word> rotations_;
  // Indices into rotations_ (in order) of the rotations starting with letter
  // x, at by_first_[x + max_letter_]: a window can only match those.
  std::vector<std::vector<int>> by_first_;
  int max_letter_ = 0;
};
/// Text form: letters named by `names` (index k-1 for letter k), inverses
/// written with "^-1", separated by spaces.
std::string to_text(const Word& w, const std::vector<std::string>& names);

}  // namespace surfmap
