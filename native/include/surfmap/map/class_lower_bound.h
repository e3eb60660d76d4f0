#pragma once
// A lower bound of the harmonic energy of a homotopy class of maps between
// closed hyperbolic surfaces, from hyperbolic lengths of curves alone, with
// no solve (docs/handle_classes.md; docs/method.md §2.10 ranks classes by energy).
//
// With E(f) = ∫|∇f|² dA (a conformal map between hyperbolic surfaces of
// genus g has E = 8π(g−1)), for every map f: X -> Y in the class θ and
// every embedded annulus A of X of modulus M (height over circumference)
// whose core curve is γ: every core circle of A maps to a curve freely
// homotopic to θγ, so of length at least ℓ_Y(θγ), and Cauchy–Schwarz on each
// circle then integration over the height give ∫_A |∇f|² >= M ℓ_Y(θγ)².
// The collar lemma gives, around every simple closed geodesic γ of X, an
// embedded annulus of modulus
//     M(ℓ) = 2 arctan(1 / sinh(ℓ/2)) / ℓ,          ℓ = ℓ_X(γ),
// and the collars of pairwise disjoint simple closed geodesics are pairwise
// disjoint, so for a family F of such curves
//     E(f) >= Σ_{γ in F} M(ℓ_X(γ)) ℓ_Y(θγ)².
// (M(ℓ) >= 2 e^{−ℓ/2} / ℓ, the bound Maskit's comparison of extremal and
// hyperbolic length gives for one curve.) The bound is the maximum over
// a list of families; the conformal bound 8π(g−1) holds for every class.
//
// Lengths come from the deck groups of the uniformized surfaces: a deck
// element A (SU(1,1)) translates along its axis by 2 arccosh(|tr A| / 2),
// the length of the closed geodesic freely homotopic to the loop.
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/words.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap {

/// The conformal lower bound 8π(g−1) of the harmonic energy E(f) = ∫|∇f|² dA
/// of a degree-one map between closed hyperbolic surfaces of genus `genus`
/// (twice the area 4π(g−1); a conformal map attains it): no class's energy
/// lies below it, and energy ratios are given over it (docs/handle_classes.md
/// "The lower bound"). Negative for genus 0 and zero for genus 1, where it
/// bounds nothing: callers use it for genus >= 2.
inline double conformal_bound(int genus) { return 8 * M_PI * (genus - 1); }

/// A closed hyperbolic surface's lengths of closed curves given as words in
/// canonical generators (a1, b1, a2, b2, ... = letters 1..2g).
class SurfaceGroupLengths {
 public:
  /// `group`: deck group of the surface's hyperbolic layout (its loop
  /// letters); `canonical_to_loops`: 2g words, canonical generator j+1 as a
  /// word in loop letters (CanonicalSchema::generators); `loop_relator`: the
  /// layout's boundary word (DiskLayout::word, for Dehn reduction of loop
  /// words); `caller_to_canonical` (optional, 2g words): the caller's
  /// canonical letters as words in these canonical letters, when the
  /// caller's words refer to another system of loops of the same surface
  /// (empty: the same letters).
  SurfaceGroupLengths(DeckGroup group, GroupMap canonical_to_loops, Word loop_relator,
                      GroupMap caller_to_canonical = {});
  int genus() const { return genus_; }
  /// Length of the closed geodesic freely homotopic to `w` (caller's
  /// canonical letters): 2 arccosh(|tr| / 2); 0 for the identity; NaN when
  /// the word reduces to more than `max_letters` loop letters or its trace
  /// cannot be trusted (leaves double range, or, for matrix entries beyond
  /// 1e12, the length from the double product disagrees with that from the
  /// extended-precision product by more than 1e-6 relative; the extended
  /// one is returned): too long to evaluate, callers must then not use it.
  double length(const Word& w, size_t max_letters = 4000) const;
  /// The deck element of `w` itself (caller's canonical letters), not a
  /// conjugate: for geometry that relates several elements (the axes of a
  /// pants curve and of its neighbours, map/pants_classes.h). False when the
  /// word reduces to more than `max_letters` loop letters or its matrix
  /// leaves double range.
  bool element(const Word& w, hyperbolic::Mobius* m, size_t max_letters = 4000) const;
  /// The deck elements of `words` (caller's canonical letters) all
  /// conjugated by one element u chosen so that the first one's side word
  /// is cyclically (and Dehn-) reduced: its axis then passes near the
  /// fundamental polygon and the matrices stay small (far conjugates have
  /// entries of 1e6 and more, and axis endpoints that round-off moves).
  /// Simultaneous conjugation keeps every relative position of the axes.
  bool elements_in_frame_of_first(const std::vector<Word>& words, std::vector<hyperbolic::Mobius>* out,
                                  size_t max_letters = 4000) const;

 private:
  // |tr| / 2 of a side word's matrix multiplied out in long double.
  long double half_trace_extended(const Word& side) const;
  DeckGroup group_;
  GroupMap canonical_to_loops_, caller_to_canonical_;
  DehnReducer reduce_canonical_, reduce_loops_;
  int genus_ = 0;
};

/// Modulus (height / circumference) of the standard collar around a simple
/// closed geodesic of length `length` > 0: 2 arctan(1 / sinh(ℓ/2)) / ℓ.
double collar_modulus(double length);

/// Pairwise disjoint simple closed curves, as words in canonical letters.
struct CurveFamily {
  std::string name;          ///< e.g. "a_i, s_j", "T(b1)(b_i, s_j)"
  std::vector<Word> curves;  ///< 2g - 1 words
};

/// Families of pairwise disjoint simple closed curves of the closed surface
/// of genus >= 2 (letters a_i = 2i-1, b_i = 2i, relator [a1,b1]...[ag,bg]):
/// {a_i} ∪ {s_j}, {b_i} ∪ {s_j}, {a_i b_i} ∪ {s_j}, {a_i b_i^-1} ∪ {s_j}
/// (s_j = [a1,b1]...[aj,bj], j < g, the curve separating handles 1..j from
/// the rest; for genus 2 each family is a pants decomposition) and, with
/// `move_images`, their images under every move of
/// topology/mapping_class_search.h twist_moves(genus, false, false)
/// (homeomorphisms keep curves simple and disjoint). Throws InputError for
/// genus < 2.
std::vector<CurveFamily> disjoint_curve_families(int genus, bool move_images = true);

struct ClassLowerBound {
  /// max over the families of Σ collar_modulus(ℓ_X(γ)) ℓ_Y(θγ)²; curves
  /// whose lengths cannot be evaluated (NaN) count 0, so it stays a bound.
  double curve_bound = 0;
  /// 8 π (g - 1): every degree-1 map's energy is at least twice the
  /// target's area.
  double conformal_bound = 0;
  /// max(curve_bound, conformal_bound).
  double bound = 0;
  /// The family attaining curve_bound (-1: none gave a positive bound), and
  /// its curves' lengths in X and of their images in Y.
  int family = -1;
  std::string family_name;
  std::vector<double> source_lengths, target_lengths;
};

/// Evaluates ClassLowerBound for classes θ: X -> Y (θ: X's canonical
/// generator j+1 -> word in Y's canonical letters) against fixed families of
/// X, whose lengths in X are computed once.
class ClassBoundEvaluator {
 public:
  ClassBoundEvaluator(const SurfaceGroupLengths& source, std::vector<CurveFamily> families);
  ClassLowerBound operator()(const SurfaceGroupLengths& target, const GroupMap& theta) const;
  const std::vector<CurveFamily>& families() const { return families_; }
  /// ℓ_X of family f's curves (NaN where not evaluable).
  const std::vector<double>& source_lengths(int f) const { return source_lengths_[f]; }

 private:
  std::vector<CurveFamily> families_;
  std::vector<std::vector<double>> source_lengths_;
  int genus_ = 0;
};

}  // namespace surfmap
