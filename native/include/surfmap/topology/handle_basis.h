#pragma once
// Handles of a closed surface in R^3 and the handle correspondences between
// two surfaces of genus g >= 2 (docs/method.md §2.10 and §7 "Meridians and
// longitudes"; docs/method.md §2.10).
//
// Homotopy classes of maps S1 -> S2 are outer isomorphisms of the surface
// groups. Both groups are presented canonically (topology/canonical_schema.h):
//   pi_1 = < x_1 .. x_2g | R >,   R = [x_1, x_2] [x_3, x_4] ... [x_2g-1, x_2g],
// handle i being the pair (a_i, b_i) = (x_2i-1, x_2i). A map of generators
// x_j -> w_j is an isomorphism of the surface groups when it comes from an
// automorphism of the free group that sends R to a conjugate of R; it is
// induced by an orientation-preserving homeomorphism exactly when its action
// on homology preserves the intersection form (symplectic, not
// anti-symplectic).
//
// Geometry (docs/method.md §7). For a cycle on a surface S embedded in R^3, bounding
// the solid V, the Seifert-type form L(x, y) = lk(x^-, y) (x pushed slightly
// into V, Gauss linking number with y) is well defined on H_1(S), and
// L - L^T is the intersection form. Meridians (cycles bounding discs inside
// V, like a torus's small circle) are its left kernel, 0-framed longitudes
// (bounding outside) its right kernel; each kernel has rank g and the two are
// dual under intersection. handle_basis() computes L on the 2g loops of a
// system of loops with the exact linking number of closed polygons,
// chooses a meridian basis (loops that are meridians when there are g of
// them, else a reduced integer kernel basis), the dual longitudes, orders the
// handles along the shape's longest axis and lifts the resulting symplectic
// change of basis to an automorphism of the surface group (elementary moves
// below, each an exact automorphism with an exact inverse).
//
// Candidates (handle_candidates): for every permutation pi of the handles and
// every per-handle orientation s_i = ±1 (s_i = -1 turns handle i by a half
// turn: (m, l) -> (m^-1, l^-1) up to conjugation, which keeps the orientation
// of the surface), the isomorphism m_i -> m'_pi(i)^s_i, l_i -> l'_pi(i)^s_i
// made exact by the conjugations that the lift inserts: a transposition of
// adjacent handles is (a_i, b_i, a_i+1, b_i+1) -> (c a_i+1 c^-1, c b_i+1 c^-1,
// a_i, b_i) with c = [a_i, b_i], which fixes [a_i,b_i][a_i+1,b_i+1] exactly;
// a half turn of handle i is (a, b) -> (ab) (a^-1, b^-1) (ab)^-1, which fixes
// [a_i, b_i] exactly. Every candidate is verified in the surface group
// (Dehn's algorithm: the image of R reduces to the identity; the inverse
// composes to the identity) and by its homology matrix (symplectic, unimodular).
// Candidates are ranked by a geometric score: distance of the handle
// positions (centroids of the longitude curves, i.e. of the holes, in the frame centred at the
// shape's vertex centroid and scaled by its bounding-box diagonal, no
// rotation: the two objects are assumed to be posed alike, handles side by
// side) plus a penalty when the meridians' and longitudes' vector areas point
// against each other. Isomorphisms that differ by Torelli elements (same
// homology, e.g. twists along a curve that separates handles) are not
// enumerated: the lift picks one, which reduce_separating_twists() can
// shorten; the geometric class for shapes posed alike comes from
// topology/projected_loops.h instead.
#include <array>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/words.h"

namespace surfmap {

using IntMatrix = Eigen::Matrix<long long, Eigen::Dynamic, Eigen::Dynamic>;

/// An endomorphism of the surface group: images[j] is the image of letter
/// j+1 (a word in the same letters 1..2g).
using GroupMap = std::vector<Word>;

/// w with every letter k replaced by images[k-1] (inverse for -k).
Word substitute(const Word& w, const GroupMap& images);
/// The identity of the group on letters 1..n (letter j -> the word {j}).
GroupMap identity_map(int n);
/// outer ∘ inner: letter j -> outer applied to inner[j].
GroupMap compose(const GroupMap& outer, const GroupMap& inner);
/// 2g x 2g integer matrix of the map on H_1: column j is the abelianised image of letter j+1.
IntMatrix homology_matrix(const GroupMap& map, int num_letters);
/// Abelianisation of w (counts of each letter, n entries).
Eigen::Matrix<long long, Eigen::Dynamic, 1> abelianize(const Word& w, int n);
/// Intersection form of the canonical basis: J(a_i, b_i) = 1, J(b_i, a_i) = -1.
IntMatrix symplectic_form(int genus);
/// The canonical relator [x1,x2]...[x2g-1,x2g].
Word canonical_relator(int genus);

/// An automorphism with an exact inverse (both as GroupMaps on 2g letters).
struct SurfaceAutomorphism {
  GroupMap map, inverse;
  int moves = 0;  ///< elementary moves composed
};

/// Lifts a symplectic integer matrix P (P^T J P = J, J = symplectic_form(g))
/// to an automorphism of the canonical surface group whose homology matrix is
/// P, by a symplectic Euclidean reduction with elementary moves (twists
/// a -> a b^q, b -> b a^q; adjacent handle swaps; one mixing move between
/// adjacent handles, a1 -> a1 a2, b2 -> b2 a2^-1 b1^-1 a2 up to conjugation,
/// conjugated by swaps for other pairs). Words are kept Dehn-reduced.
/// Throws InputError when P is not symplectic, SolveError if a check fails.
SurfaceAutomorphism lift_symplectic(const IntMatrix& P);

/// The mixing of adjacent handles i, i+1 (0-based, i + 1 < genus) that
/// lift_symplectic uses: a_i -> a_i a_i+1, homology a_i += a_i+1,
/// b_i+1 -= b_i; it fixes the canonical relator exactly. The image of a_i is
/// then a simple closed curve through both handles (a chain curve,
/// topology/mapping_class_search.h).
SurfaceAutomorphism adjacent_handle_mixing(int genus, int i);

/// Exact checks in the surface group of `genus`: the image of R is trivial
/// (Dehn's algorithm), inverse ∘ map and map ∘ inverse are the identity, and
/// the homology matrix is symplectic.
bool is_surface_automorphism(const SurfaceAutomorphism& a, int genus);

/// Gauss linking number of two closed polygons (vertex lists, the last
/// vertex joined to the first), exact for polygons: the signed crossings of
/// a generic parallel projection (an exact integer), or where that
/// projection is not generic to a safe margin the sum over segment pairs of
/// the signed solid angle they subtend, / 4 pi. The polygons must be
/// disjoint; the result is then an integer up to round-off.
double linking_number(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b);

/// Meridian/longitude basis of one surface (see the file comment).
struct HandleBasis {
  int genus = 0;
  /// True when the linking numbers were integral and consistent (L - L^T =
  /// ±J): meridians and longitudes are known. Otherwise the canonical basis
  /// itself is used (P = I) and `message` says why.
  bool geometric = false;
  std::string message;
  /// #loops x #loops rounded linking numbers lk(loop_k pushed inside, loop_l).
  IntMatrix loop_linking;
  /// Largest distance of a computed linking number from its integer.
  double linking_roundoff = 0;
  /// Symplectic 2g x 2g matrix: columns m_1, l_1, ..., m_g, l_g in the
  /// canonical basis's homology coordinates.
  IntMatrix P;
  /// Geometric generators as words in the canonical generators (map) and
  /// back (inverse).
  SurfaceAutomorphism to_canonical;
  /// Per handle (in the basis order): centroid of its longitude curve (the
  /// loops of its longitude, weighted by length and |coefficient|) and
  /// vector areas (1/2 ∮ x × dx) of its meridian and longitude, in the frame
  /// centred at the vertex centroid and scaled by the bounding-box diagonal.
  std::vector<Eigen::Vector3d> position, meridian_area, longitude_area;
  /// Loops that are meridians (indices into the loops given).
  std::vector<int> meridian_loops;
};

/// `mesh`: the mesh the loops live on (closed, outward oriented); `loops`:
/// the 2g closed vertex paths of a system of loops (SystemOfLoops::loops);
/// `schema`: canonical_schema of that system's boundary word.
HandleBasis handle_basis(const TriMesh& mesh, const std::vector<std::vector<int>>& loops,
                         const CanonicalSchema& schema);

/// One handle correspondence between two surfaces.
struct HandleCandidate {
  std::vector<int> permutation;  ///< source handle i -> target handle permutation[i]
  std::vector<int> sign;         ///< +1, or -1 for a half turn of the handle
  /// Source canonical generator j+1 -> word in the target's canonical generators.
  GroupMap map;
  /// The map on H_1 in canonical coordinates (target = homology * source).
  IntMatrix homology;
  double geometric_score = 0;
  std::string description;  ///< e.g. "handle 1 -> handle 2, handle 2 -> handle 1 (half turn)"
  /// A map's class given as words (HomotopyOptions::given_class): its index
  /// there, 0-based; -1 for every other class.
  int given_class = -1;
  /// Genus >= 2 map (src/map/stages/other_basis.h): `map` written in the
  /// other canonical basis than the run's, when its class search runs there
  /// (listed in the other basis only; or, in a classical run, listed in
  /// both bases or the same in either, searched in the short one). Empty
  /// otherwise.
  GroupMap other_basis_map;
};

/// The signed handle permutation that a map with the given homology matrix
/// (target = homology * source, canonical coordinates) induces between the
/// two handle bases, as in HandleCandidate; false (and a description "mixes
/// handles") when it is not one.
bool handle_correspondence_of(const HandleBasis& source, const HandleBasis& target, const IntMatrix& homology,
                              std::vector<int>* permutation, std::vector<int>* sign, std::string* description);

/// Lifts fix a class only up to the Torelli group (same action on
/// homology): e.g. the two ways round of a handle swap differ by a twist
/// along the curve separating the handles. This composes `map` (canonical
/// source generators -> words in the canonical target generators) greedily
/// with the twists T_j along the separating curves [a_1,b_1]...[a_j,b_j]
/// (j < g; T_j conjugates handles 1..j by that product, an exact
/// automorphism) on either side, while `cost` (e.g. the total length of the
/// source loops' images) decreases. Homology is unchanged.
GroupMap reduce_separating_twists(const GroupMap& map, int genus, const std::function<double(const GroupMap&)>& cost,
                                  int max_steps = 40);

/// A signed handle permutation: source handle i onto target handle perm[i]
/// with orientation sign[i] (+1 / −1), and its score (lower is better).
struct SignedPermutation {
  std::vector<int> perm, sign;
  double score = 0;
};

/// The `count` signed permutations of lowest total score Σ_i
/// pair_score[i g + perm[i]][sign[i] > 0 ? 0 : 1], in increasing score
/// (pair_score: g² entries, {score with sign +1, with sign −1}), without
/// enumerating the g! 2^g: the best sign of every pair gives each
/// permutation a base score; Murty's ranking of assignments (Hungarian
/// method per subproblem, O(count g⁴)) gives the `count` best permutations,
/// and each of them its `count` best sign patterns. Any signed permutation
/// among the `count` best has its permutation among the `count` best by
/// base score, so merging these is exact (ties in any order). Throws
/// InputError unless 1 <= g <= 64 and pair_score has g² entries.
std::vector<SignedPermutation> best_signed_permutations(int g, const std::vector<std::array<double, 2>>& pair_score,
                                                        int count);

/// Signed handle permutations ranked by geometric score, the first
/// `max_candidates` kept: up to genus 7 all g! 2^g are scored and ranked
/// (stable), beyond with best_signed_permutations (genus 11 had asked for
/// 8e10 of them, 20 GB before the map was killed); max_candidates <= 0 asks
/// for all up to genus 7 and for 1000 beyond. Each is checked exactly (Dehn's algorithm on
/// the relator's image, symplectic homology). A class whose words would
/// exceed 2e5 letters is left out (its deck elements could not be evaluated
/// in double precision), so fewer may come back, even none. Throws
/// InputError on unequal genus.
std::vector<HandleCandidate> handle_candidates(const HandleBasis& source, const HandleBasis& target,
                                               int max_candidates = 8);

}  // namespace surfmap
