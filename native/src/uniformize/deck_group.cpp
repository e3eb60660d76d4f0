// Deck-group words evaluated through the side pairings (deck_group.h).
#include "surfmap/uniformize/deck_group.h"

#include <cstdlib>
#include <string>

#include "surfmap/error.h"

namespace surfmap {

using hyperbolic::Mobius;

DeckGroup::DeckGroup(const DiskLayout& layout)
    : side_(layout.side_pairings),
      generator_side_words_(layout.generator_side_words),
      relator_(layout.side_relator),
      reducer_(layout.side_relator) {
  if (layout.background != Background::Hyperbolic)
    throw InputError("DeckGroup: the layout is not hyperbolic (genus >= 2 needed)");
  const size_t n = layout.generators.size();
  if (side_.size() != n || generator_side_words_.size() != n || relator_.size() != 2 * n)
    throw InputError("DeckGroup: the layout has no side-pairing presentation (" + std::to_string(side_.size()) +
                     " side pairings, " + std::to_string(generator_side_words_.size()) + " generator words, relator of length " +
                     std::to_string(relator_.size()) + " for " + std::to_string(n) + " generators)");
}

Word DeckGroup::side_word(const Word& loop_word) const {
  Word w;
  for (int x : loop_word) {
    const int k = std::abs(x) - 1;
    if (k < 0 || k >= static_cast<int>(generator_side_words_.size()))
      throw InputError("DeckGroup: loop letter " + std::to_string(x) + " out of range");
    const Word g = x > 0 ? generator_side_words_[k] : inverse(generator_side_words_[k]);
    w.insert(w.end(), g.begin(), g.end());
  }
  return reduce(w);
}

Word DeckGroup::reduce(const Word& w) const { return reducer_(w); }

Mobius DeckGroup::evaluate_side_word(const Word& w) const {
  Mobius m;
  for (int x : w) {
    const int k = std::abs(x) - 1;
    if (k < 0 || k >= static_cast<int>(side_.size()))
      throw InputError("DeckGroup: side letter " + std::to_string(x) + " out of range");
    m = (m * (x > 0 ? side_[k] : side_[k].inverse())).normalized();
  }
  return m;
}

}  // namespace surfmap
