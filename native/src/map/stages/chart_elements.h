#pragma once
// Chart changes of a genus >= 2 map given by per-vertex charts. Internal.
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/topology/words.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap::detail {

/// The effective element of halfedge h (tail's chart to head's) for a
/// solution with per-vertex charts (HyperbolicHarmonicResult or
/// HyperbolicInitialMapResult: #V z, vertex_deck, vertex_deck_word): from
/// reduced side words when the solver kept them (no round-off of long deck
/// matrices), else from the matrices. `halfedge_word`, `halfedge_rho`: #3F.
template <class Charts>
hyperbolic::Mobius effective_element(const Charts& r, int h, const Connectivity& sc, const DeckGroup& group,
                                     const std::vector<Word>& halfedge_word,
                                     const std::vector<hyperbolic::Mobius>& halfedge_rho) {
  const int i = sc.tail(h), j = sc.head(h);
  if (r.vertex_deck_word.size() == r.z.size())
    return group.evaluate_side_word(group.reduce(concat({r.vertex_deck_word[i], halfedge_word[h], inverse(r.vertex_deck_word[j])})));
  return (r.vertex_deck[i] * halfedge_rho[h] * r.vertex_deck[j].inverse()).normalized();
}

}  // namespace surfmap::detail
