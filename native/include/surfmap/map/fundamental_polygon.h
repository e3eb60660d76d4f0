#pragma once
// The target's fundamental polygon P (docs/method.md §2.6): the
// geodesic 4g-gon on the corners of the target's disk layout, a convex
// fundamental domain of its deck group in the Klein model, with the side
// maps built from those corners. Side i (corner c_i -> c_i+1, letter x) is
// glued to the side j of letter x^-1, traversed backwards, so its side map
// M_i takes (c_i, c_i+1) to (c_j+1, c_j) and the outside of side i to the
// inside of P along side j.
#include <complex>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/topology/words.h"
#include "surfmap/uniformize/deck_group.h"
#include "surfmap/uniformize/layout.h"

namespace surfmap {

class FundamentalPolygon {
 public:
  /// `layout`: the target's hyperbolic DiskLayout (4g sides, side_start,
  /// side letters `word`); `group`: its deck group (side words are
  /// multiplied out there, never through the loop generators' matrices).
  /// Both must outlive nothing: the polygon copies what it needs.
  FundamentalPolygon(const DiskLayout& layout, const DeckGroup& group);

  int num_sides() const { return static_cast<int>(side_map_.size()); }
  /// #sides side maps: side i's is the deck element of side letter word[i].
  const std::vector<hyperbolic::Mobius>& side_maps() const { return side_map_; }

  /// Moves z into P (side maps across the most violated side, at most 200
  /// of them; a point within 1e-13 Klein units outside a side counts as
  /// inside); returns the side word of the element applied (z -> g z).
  Word reduce(std::complex<double>& z) const;

  /// How far (in Klein units) z lies outside P; 0 inside.
  double outside_by(std::complex<double> z) const;

 private:
  /// Signed Klein distance of k from side i's line (> 0 inside).
  double inside_of_side(int i, std::complex<double> k) const;

  std::vector<std::complex<double>> kcorner_;  ///< #sides corners in the Klein model
  /// #sides side i's direction kcorner_[i+1] - kcorner_[i] and its length:
  /// fixed, so computed once (issue 19: inside_of_side runs for every side
  /// at every vertex of every Newton step, and |e| was a hypot each time).
  std::vector<std::complex<double>> kside_;
  std::vector<double> kside_length_;
  std::vector<hyperbolic::Mobius> side_map_;   ///< #sides
  std::vector<int> side_letter_;               ///< #sides letters (layout.word)
};

}  // namespace surfmap
