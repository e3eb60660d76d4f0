#pragma once
// Handle classes from the hyperbolic geometry of the two surfaces, independent
// of pose, cut and base vertex (issue 14; docs/handle_classes.md "Geometric
// candidates"; docs/method.md §2.10 ranks classes by energy, this lists them).
//
// A marking of a closed hyperbolic surface of genus g is a canonical basis
// a_1, b_1, ..., a_g, b_g of its surface group (relator [a1,b1]...[ag,bg]).
// short_marking() starts from the canonical basis of the surface's system of
// loops and applies the twists along each handle's own a_i, b_i
// (topology/mapping_class_search.h; exact automorphisms keeping the relator)
// while they shorten the handles' probe curves a_i, b_i, a_i b_i, a_i b_i^-1
// (the one-holed torus reduction, handle by handle: short a_i, b_i and
// b_i's twist about a_i close to the least). These moves and probes are
// mapped to each other by signed handle permutations, so two isometric
// surfaces whose markings differ by one reach markings that differ by one.
//
// geometric_classes(): for two such markings M_X, M_Y (new letter -> word in
// the caller's canonical letters, both ways), the classes
//     θ = M_Y ∘ P ∘ M_X^-1
// for the signed handle permutations P (handle i -> handle π(i), rotated by
// r_i quarter turns: (a, b) -> (a, b), (b, a^-1), (a^-1, b^-1), (b^-1, a) in
// homology, lifted exactly by lift_symplectic), the pairings that match the
// handles' probe lengths (Fenchel–Nielsen-like: a_i as pants curves, b_i and
// a_i b_i^±1 measuring the twists) first; then each class descends on the
// mismatch Σ_p (log ℓ_X(p) − log ℓ_Y(θ p))² over all probes x_j, x_i x_j^±1
// (marking_probes) by twists on either side (Lickorish, chain and
// separating twists; pairs of twists in genus 2), which fixes the handles'
// mixing and the Torelli part the lift leaves open. For an isometry X -> Y
// whose markings differ by a signed handle permutation, its class comes out
// with mismatch 0 (test_geometric_classes.cpp).
#include <functional>
#include <string>
#include <vector>

#include "surfmap/map/class_lower_bound.h"
#include "surfmap/topology/handle_basis.h"

namespace surfmap {

struct ShortMarkingOptions {
  /// Most moves taken (default 80).
  int max_steps = 80;
  /// A move must shorten the total probe length by more than this fraction
  /// (default 1e-9: round-off).
  double tolerance = 1e-9;
  /// When no single move shortens: the best pair of moves (default true),
  /// when there are at most `max_pairs` pairs (default 4000: genus <= 4).
  bool pair_moves = true;
  size_t max_pairs = 4000;
};

struct ShortMarking {
  /// map: marking letter j+1 -> word in the caller's canonical letters;
  /// inverse: back. Both Dehn-reduced.
  SurfaceAutomorphism marking;
  /// 2g lengths of the marking's generators (a1, b1, a2, ...).
  std::vector<double> generator_lengths;
  /// Total probe length at the start (the canonical basis) and at the end.
  double start_total = 0, total = 0;
  std::vector<std::string> moves;  ///< the moves taken, in order
  /// "no shortening move", "step budget" or "not evaluable" (a probe's length
  /// was NaN at the start: the marking is the identity).
  std::string stop_reason;
};

/// Symplectic homology matrix (2g x 2g, columns: images of a_1, b_1, ...)
/// of the signed handle pairing: marking handle i -> handle perm[i] turned by
/// rot[i] quarter turns ((a, b) -> (a, b), (b, a^-1), (a^-1, b^-1), (b^-1, a));
/// lift it with lift_symplectic. pairing_text: "marking handles 1->2
/// (quarter turn), 2->1".
IntMatrix pairing_homology(const std::vector<int>& perm, const std::vector<int>& rot);
std::string pairing_text(const std::vector<int>& perm, const std::vector<int>& rot);

/// The probe curves of a marking of genus g: x_j (2g) then x_i x_j and
/// x_i x_j^-1 for i < j (2g(2g-1)), as words in the marking's letters.
std::vector<Word> marking_probes(int genus);

/// Three-letter probes x_i x_j^±1 x_k^±1 for i < j < k (4 C(2g, 3) words):
/// what tells apart classes that match every marking probe
/// (geometric_classes, the classes of mismatch below 1e-12).
std::vector<Word> longer_probes(int genus);

/// The marking probes of a marking (marking_map: 2g words in X's canonical
/// letters) whose length in X is evaluable, with those lengths: the probes
/// every ranking by probes (geometric, pants and greedy pants classes)
/// compares. A probe whose length in X is not evaluable (NaN, infinite or
/// not positive) would add the same penalty to every class: it says nothing
/// about a class and hides the identity's 0, so it is left out; a probe not
/// evaluable in Y under one class still penalises that class.
struct EvaluableProbes {
  std::vector<Word> words;      ///< probes in X's canonical letters, Dehn-reduced
  std::vector<double> lengths;  ///< their lengths in X (finite, > 0), one per word
};
/// `words`: other probes in the marking's letters instead of its
/// marking_probes (empty: those).
EvaluableProbes evaluable_probes(const GroupMap& marking_map, const DehnReducer& reduce,
                                 const std::function<double(const Word&)>& length_in_x,
                                 const std::vector<Word>& words = {});

/// The probes of a marking's handles: a_i, b_i, a_i b_i, a_i b_i^-1 per
/// handle (4g words): the length short_marking() lowers. (Handle-local: a
/// signed handle permutation, lifted with conjugations, maps them to
/// conjugates of each other, so two isometric surfaces see the same
/// landscape from markings that differ by one.)
std::vector<Word> handle_probes(int genus);

/// Shortest marking reachable by moves (see the file comment). `lengths`:
/// the surface's lengths in the caller's canonical letters.
ShortMarking short_marking(const SurfaceGroupLengths& lengths, const ShortMarkingOptions& options = {});

/// A short closed geodesic: a cyclically reduced word (caller's canonical
/// letters) and its length.
struct ShortGeodesic {
  Word word;
  double length = 0;
};

/// The shortest closed geodesics freely homotopic to words of at most
/// `max_letters` (<= 3) letters in the marking's generators other than
/// powers x^k, one per length (curves of equal length to 1e-6 relative, e.g.
/// a word and its inverse or cyclic permutations, or curves exchanged by a
/// symmetry, are listed once), the `count` shortest, ascending.
std::vector<ShortGeodesic> short_geodesics(const SurfaceGroupLengths& lengths, const ShortMarking& marking,
                                           int max_letters = 3, int count = 12);

struct GeometricClassOptions {
  /// Handle pairings (permutation with per-handle quarter turns) kept after
  /// the handle-level length comparison (default 6); each is tried with
  /// every half-turn pattern, ranked by all probes.
  int pairings = 6;
  /// Up to this genus (default 7: 7! 2^7 pairings, 2^7 half-turn patterns
  /// each) every handle pairing and every half-turn pattern is scored.
  /// Beyond, the `pairings` best come from Murty's k-best assignments
  /// (best_signed_permutations, exact) and each pairing's half turns from a
  /// descent, one handle at a time while the mismatch drops (issue 13: at
  /// genus 11 the enumeration, 8e10 pairings, took 16 GB).
  int enumerated_genus = 7;
  /// Classes returned (default 8), lowest mismatch first.
  int max_classes = 8;
  /// Each class then descends on the mismatch by twists on either side
  /// (singles, then pairs while there are at most max_pairs): at most this
  /// many steps (default 40); pairs only up to 600 pairs: genus 2. Only
  /// the `descents` lowest-mismatch classes descend (default 4: each
  /// descent costs thousands of length evaluations).
  int descents = 4;
  /// Probe length evaluations after which no further descent step starts
  /// (default 200000, about a second; genus 2-3 never reach it).
  size_t length_budget = 200000;
  int max_steps = 40;
  size_t max_pairs = 600;
};

struct GeometricClass {
  GroupMap theta;                ///< X canonical letter -> word in Y's canonical letters
  std::vector<int> permutation;  ///< marking handle i of X -> marking handle permutation[i] of Y
  std::vector<int> rotation;     ///< quarter turns 0..3 of each handle
  double mismatch = 0;           ///< Σ over probes (log ℓ_X(p) − log ℓ_Y(θ p))²; probes whose length in X
                                 ///< is not evaluable are left out (they would count alike for every class),
                                 ///< one not evaluable in Y adds 1e6
  std::string description;       ///< e.g. "marking handles 1->2 (quarter turn), 2->1"
};

/// Classes X -> Y from the two short markings (file comment), lowest
/// mismatch first. `source`/`target`: the lengths the markings were built
/// with. Throws InputError on unequal genus.
std::vector<GeometricClass> geometric_classes(const SurfaceGroupLengths& source, const ShortMarking& source_marking,
                                              const SurfaceGroupLengths& target, const ShortMarking& target_marking,
                                              const GeometricClassOptions& options = {});

}  // namespace surfmap
