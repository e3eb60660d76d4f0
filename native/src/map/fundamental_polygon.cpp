#include "surfmap/map/fundamental_polygon.h"

#include <algorithm>
#include <cmath>

namespace surfmap {

using Complex = std::complex<double>;

FundamentalPolygon::FundamentalPolygon(const DiskLayout& layout, const DeckGroup& group) {
  const int nsides = static_cast<int>(layout.side_start.size());
  kcorner_.resize(nsides);
  side_map_.resize(nsides);
  side_letter_.resize(nsides);
  for (int i = 0; i < nsides; ++i) {
    const int h = layout.boundary_halfedges[layout.side_start[i]];
    kcorner_[i] = hyperbolic::poincare_to_klein(layout.corners(h / 3, h % 3));
    // Side i carries letter w_i; its side map is D_k for w_i = +(k+1) and
    // D_k^-1 for -(k+1), i.e. side letter w_i (DiskLayout::side_relator).
    side_letter_[i] = layout.word[i];
    side_map_[i] = group.evaluate_side_word(Word{layout.word[i]});
  }
  kside_.resize(nsides);
  kside_length_.resize(nsides);
  for (int i = 0; i < nsides; ++i) {
    kside_[i] = kcorner_[(i + 1) % nsides] - kcorner_[i];
    kside_length_[i] = std::abs(kside_[i]);
  }
}

double FundamentalPolygon::inside_of_side(int i, Complex k) const {
  const Complex& e = kside_[i];
  const Complex d = k - kcorner_[i];
  return (e.real() * d.imag() - e.imag() * d.real()) / kside_length_[i];
}

Word FundamentalPolygon::reduce(Complex& z) const {
  Word acc;
  for (int guard = 0; guard < 200; ++guard) {
    const Complex k = hyperbolic::poincare_to_klein(z);
    int worst = -1;
    double worst_value = -1e-13;
    for (int i = 0; i < num_sides(); ++i) {
      const double side = inside_of_side(i, k);
      if (side < worst_value) worst_value = side, worst = i;
    }
    if (worst < 0) break;
    z = side_map_[worst].apply(z);
    acc.insert(acc.begin(), side_letter_[worst]);
  }
  return acc;
}

double FundamentalPolygon::outside_by(Complex z) const {
  const Complex k = hyperbolic::poincare_to_klein(z);
  double out_by = 0;
  for (int i = 0; i < num_sides(); ++i) out_by = std::max(out_by, -inside_of_side(i, k));
  return out_by;
}

}  // namespace surfmap
