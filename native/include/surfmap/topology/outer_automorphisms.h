#pragma once
// Exact algebra of homotopy classes of maps between closed surfaces of genus
// g >= 2, on words (docs/handle_classes.md "Both directions"; issue 14).
//
// A class S -> T is an isomorphism of the canonical surface groups
//     pi_1 = < x_1 .. x_2g | R >,   R = [x_1, x_2] ... [x_2g-1, x_2g]
// given by generator images (topology/handle_basis.h GroupMap), defined only
// up to an inner automorphism (the base point's path). Two classes are the
// same when they differ by an inner automorphism; a class T -> S is the
// inverse of a class S -> T when their composite is inner.
//
// inner_automorphism_test: exact, by Dehn's algorithm (words.h; the
// presentation is C'(1/6) for g >= 2). The conjugator w of phi(x) = w x w^-1
// is read off phi(a_1): its Dehn-reduced word is peeled, cyclically, down
// to a single letter (u = y u' y^-1 -> w y, u'; or a rotation p^-1 u p that
// Dehn's algorithm shortens -> w p): a cyclically Dehn-reduced word
// conjugate to a single letter is that letter (small cancellation: an
// annular diagram around a word of length 1 puts more than half a relator on
// the other boundary). w is determined up to powers of a_1 (its
// centralizer), fixed by phi(b_1); then every generator is checked:
// w^-1 phi(x) w x^-1 reduces to the empty word.
//
// invert_automorphism: phi^-1 = R ∘ L, products of the moves of
// topology/mapping_class_search.h (Dehn twists along a_i, b_i, chain and
// separating curves, bounding pairs) and of exact lifts of symplectic
// matrices (lift_symplectic) with L ∘ phi ∘ R inner, found by a beam
// descent (single moves on either side, else pairs) on the total cyclically
// Dehn-reduced length of the images of the probe curves x_i, x_i x_j^±1
// (conjugation invariant). Signed handle permutations keep that length, so
// a state also ends when its composite with the lift of its inverse
// homology is inner, and a second start is phi ∘ lift(P^-1). When no move
// or pair shortens any state, the states and the starts are tested for
// periodicity: a periodic mapping class (a rotation of a symmetric polygon,
// as invisible to the word lengths as the permutations) has order
// m <= 4g + 2 (Wiman), so tau^m is inner and tau^-1 = tau^(m-1) exactly.
// The descent is a
// heuristic: it may stop before L ∘ phi ∘ R is inner (`ok` false says so);
// a returned inverse is checked exactly (phi ∘ inverse and inverse ∘ phi
// inner). When it stops, Nielsen reduction of the generator images
// (nielsen_inverse) is tried, checked the same way.
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/words.h"

namespace surfmap {

/// Cyclically Dehn-reduced form of w in the surface group of relator R: a
/// shortest cyclic word reachable by free cyclic reduction and Dehn's
/// algorithm on its rotations (conjugation invariant up to rotation; its
/// length is what the descent of invert_automorphism lowers).
Word cyclic_dehn_reduce(const Word& w, const DehnReducer& reduce);

/// cyclic_dehn_reduce's length, remembered by word: the descent of
/// invert_automorphism meets the same probe images again and again (a move
/// leaves the probes without its letters alone; neighbouring states share
/// most neighbours). Exact: a remembered length is the one computed for that
/// very word. Holds at most `max_letters` letters of keys (default 2^23,
/// 32 MB), then starts afresh. `reduce` (the canonical relator's reducer for
/// probe_curve_cost) must outlive the memo.
class CyclicLengthMemo {
 public:
  explicit CyclicLengthMemo(const DehnReducer& reduce, size_t max_letters = size_t{1} << 23);
  /// cyclic_dehn_reduce(w, reduce).size().
  size_t operator()(const Word& w);
  size_t hits() const { return hits_; }
  size_t misses() const { return misses_; }

 private:
  const DehnReducer& reduce_;
  size_t max_letters_, letters_ = 0, hits_ = 0, misses_ = 0;
  std::unordered_map<Word, size_t, WordHash> lengths_;
};

/// The descent's cost of invert_automorphism: the total cyclically
/// Dehn-reduced length of the images under `tau` (2g Dehn-reduced images,
/// canonical relator of genus g) of the probe curves x_i, then x_i x_j and
/// x_i x_j^-1 (i < j), in that order; conjugation invariant, least (one
/// letter per generator) for inner automorphisms. Stops as soon as the sum
/// reaches `limit` (returning that partial sum). With `memo` the lengths are
/// looked up (same result).
size_t probe_curve_cost(const GroupMap& tau, int genus, CyclicLengthMemo* memo = nullptr,
                        size_t limit = std::numeric_limits<size_t>::max());

struct InnerTest {
  bool inner = false;
  /// When inner: w with phi(x) = w x w^-1 for every generator x (Dehn-reduced).
  Word conjugator;
  /// Why not (e.g. "acts on homology as a non-identity matrix", "phi(a1) is
  /// not conjugate to a1"), or "" when inner.
  std::string why;
};

/// Whether `phi` (2g generator images, letters ±1..±2g, canonical relator of
/// genus g >= 2) is an inner automorphism (see the file comment). Exact.
/// Throws InputError when phi does not have 2g images or a letter is out of range.
InnerTest inner_automorphism_test(const GroupMap& phi, int genus);

/// Genus 2: the hyperelliptic involution (2g = 4 generator images, exact,
/// Dehn-reduced): the half turns of both handles, a -> (ab) a^-1 (ab)^-1,
/// b -> (ab) b^-1 (ab)^-1 (each fixes its commutator exactly), times the
/// power of the twist along the separating curve that makes it an
/// involution. It acts on homology as -I, is central in the mapping class
/// group and is an isometry of every hyperbolic metric of genus 2: two
/// classes differing by it have the same harmonic energy.
GroupMap hyperelliptic_involution();

/// How a class theta (source -> target, 2g generator images) and a class psi
/// of the opposite direction (target -> source) relate, exactly (issue 14):
/// inverse when psi ∘ theta is inner; at genus 2, when it is not, inverse up
/// to the hyperelliptic involution when psi ∘ theta ∘ iota is inner.
struct OppositeClasses {
  /// psi ∘ theta, each image Dehn-reduced.
  GroupMap composite;
  /// inner_automorphism_test of the composite.
  InnerTest inner;
  /// Genus 2, not inner, but inner after the hyperelliptic involution.
  bool up_to_hyperelliptic = false;
};
OppositeClasses compare_opposite_classes(const GroupMap& psi, const GroupMap& theta, int genus);

struct AutomorphismInverseOptions {
  /// Most descent moves (default 60); when no single move shortens, pairs
  /// of moves (default true) whose first move is one of the `pair_starts`
  /// best single moves (default 6).
  int max_steps = 60;
  bool pair_moves = true;
  int pair_starts = 6;
  /// States kept per step (default 3: the greedy descent alone stalls on
  /// about one in ten products of two moves in genus 3).
  int beam = 3;
  /// Neighbours whose words (letters, summed over the 2g images) exceed this
  /// and twice the current class's are skipped (default 20000).
  size_t max_letters = 20000;
  /// When the descent stalls or runs out of steps: nielsen_inverse (default
  /// true; false: fail as before). Its inverse is checked exactly too, and
  /// AutomorphismInverse::why then says so.
  bool nielsen = true;
  /// invert_product: most letters (summed over the 2g images, before
  /// reduction) of the running product or inverse (default 2^22: a few
  /// factors' inverses from the descent can run to thousands of letters
  /// each, their product to gigabytes).
  size_t max_product_letters = size_t{1} << 22;
};

struct AutomorphismInverse {
  bool ok = false;
  /// When ok: psi with phi ∘ psi and psi ∘ phi inner (Dehn-reduced words).
  GroupMap inverse;
  /// Moves of the descent and why it failed.
  int moves = 0;
  std::string why;
};

/// The inverse of the automorphism `phi` of the canonical surface group of
/// genus g >= 2, up to an inner automorphism (see the file comment). `ok`
/// false (with `why`) when phi's homology is not symplectic, or the descent
/// stops before reaching an inner automorphism.
AutomorphismInverse invert_automorphism(const GroupMap& phi, int genus, const AutomorphismInverseOptions& options = {});

/// The inverse of the product factors[0] ∘ factors[1] ∘ ... ∘ factors[k-1]
/// (each an automorphism of the canonical surface group of genus g >= 2, 2g
/// generator images), factor by factor: f_(k-1)^-1 ∘ ... ∘ f_0^-1, each
/// factor inverted by invert_automorphism unless known_inverses[i] (when
/// given and not empty) is its inverse. For products whose long words the
/// descent and the Nielsen reduction cannot invert while each factor's
/// shorter words do, or whose factors came from inverses already known (a
/// class composed through a generated shape: docs/handle_classes.md
/// "Through generated shapes"). The result is checked exactly like invert_automorphism's
/// (product ∘ inverse and inverse ∘ product inner; a wrong known inverse
/// fails there); `why` names the factor that did not invert.
AutomorphismInverse invert_product(const std::vector<GroupMap>& factors, int genus,
                                   const std::vector<GroupMap>& known_inverses = {},
                                   const AutomorphismInverseOptions& options = {});

/// phi^-1 by Nielsen reduction of the generator images (docs/handle_classes.md
/// "The two directions today"): the tuple t = (phi(x_1), ..., phi(x_2g)) is
/// shortened by Nielsen moves t_i <- t_i t_j^±1 or t_j^±1 t_i, or every
/// other t_i conjugated by t_j^±1 (the move that lowers the total
/// Dehn-reduced length most, each step), the same moves applied to
/// u = (x_1, ..., x_2g), so that phi(u_i) = t_i throughout. When no move
/// shortens and every t_i is conjugate to a single letter, distinct up to
/// sign, u gives the preimages of the generators up to that conjugation:
/// phi^-1 up to an inner automorphism (Dehn-reduced words). Every
/// generating 2g-tuple of a surface group is Nielsen equivalent to the
/// standard one, but the greedy order can stall; then, or when a u_i grows
/// beyond `max_letters`, the result is empty. The
/// caller checks the result (invert_automorphism does, exactly). Where the
/// probe descent is blind (it sees only conjugacy classes) this sees the
/// elements: the fertility -> genus-4 plate class, on which the descent
/// stalls after 10 moves, inverts in 37 Nielsen moves (2 ms).
GroupMap nielsen_inverse(const GroupMap& phi, int genus, size_t max_letters = 20000);

}  // namespace surfmap
