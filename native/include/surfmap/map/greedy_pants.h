#pragma once
// The greedy short pants decomposition of a closed hyperbolic surface
// (issue 14; docs/handle_classes.md "Greedy pants decomposition"): the
// shortest simple closed geodesic, then the shortest one disjoint from it
// and not homotopic to it, and so on until 3g − 3 curves (a maximal family
// of disjoint, pairwise non-homotopic essential simple closed curves is a
// pants decomposition). Unlike map/pants_classes.h's decomposition (a
// caterpillar reached by twists from a marking), it has whatever
// combinatorial type the surface's short curves give (e.g. three
// non-separating curves in genus 2). greedy_pants_classes() pairs two
// surfaces' greedy decompositions (below; in the class search's geometric
// stage).
//
// Candidates: the cyclically reduced words of up to `max_letters` letters in
// a short marking's generators (map/geometric_classes.h), proper powers,
// cyclic permutations and inverses left out, plus any curves the caller
// adds (e.g. the caterpillar decomposition's), by length 2 arccosh(|tr|/2).
//
// Simplicity and disjointness from the lifts' axes: two closed geodesics u,
// v cross exactly where a lift of v crosses the axis of a lift of u (the
// universal cover's geodesics). In the frame of u (its axis through the
// fundamental polygon: SurfaceGroupLengths::elements_in_frame_of_first, each
// lift evaluated as a word of its own) the lifts C v C^-1 tried are C = Q h P: Q a prefix of u's word (lifts along
// one period of u's axis), h every reduced word of up to `radius` marking
// letters, P a prefix of v's word (v's own cyclic permutations); a lift
// crossing the axis of U is counted once per crossing point modulo the
// translation by U. The count is the geometric intersection number i(u, v)
// (for u = v twice the self-intersections) as far as these conjugators
// reach: a lift that needs a longer conjugator is missed, so a "simple"
// or "disjoint" verdict is a heuristic for long words (tests check known
// intersection numbers); a lift with the axis of U is "the same curve".
#include <string>
#include <vector>

#include "surfmap/map/class_lower_bound.h"
#include "surfmap/map/geometric_classes.h"

namespace surfmap {

struct CurveIntersectionOptions {
  /// Conjugators h: reduced words of up to this many marking letters
  /// (default 1), lowered while |u| · |v| · #ball exceeds `max_lifts`
  /// (default 20000; each lift is a Dehn reduction and a side-word product).
  int radius = 1;
  size_t max_lifts = 20000;
  /// Only whether the curves cross (default false: count every crossing
  /// point): stop at the first crossing point found, `crossings` is then 1
  /// for any positive count and `same_curve` is only set if a lift on the
  /// axis came first. The greedy decomposition needs no more than that.
  bool stop_at_first_crossing = false;
};

struct CurveIntersection {
  /// Crossing points found (file comment): i(u, v) for u ≠ v, twice the
  /// self-intersections for u = v. -1 when the curves could not be
  /// evaluated (a word too long, or not hyperbolic).
  int crossings = -1;
  /// A lift of v has the axis of u (u ≠ v only): the same closed geodesic
  /// (or a power of it).
  bool same_curve = false;
};

/// Intersections of the closed geodesics of `u` and `v`, words in the
/// marking's letters (`marking`: ShortMarking::marking of `lengths`).
CurveIntersection curve_intersection(const SurfaceGroupLengths& lengths, const SurfaceAutomorphism& marking,
                                     const Word& u, const Word& v, const CurveIntersectionOptions& options = {});

struct GreedyPantsOptions {
  /// Candidate words of up to this many marking letters (default 0: 4 in
  /// genus 2, 3 in genus 3-4, 2 from genus 5).
  int max_letters = 0;
  /// Candidates examined at most (default 4000), shortest first.
  size_t max_examined = 4000;
  CurveIntersectionOptions intersection;
  /// Verdicts without counting (default true; false: every test counts all
  /// crossing points, as before; the same curves come out, slower): a curve
  /// shorter than 4 arcsinh(1) ≈ 3.53 is simple (the shortest closed
  /// geodesic with a self-intersection is that long, Yamada); two curves of
  /// different lengths with sinh(ℓ1/2) sinh(ℓ2/2) < 1 are disjoint (collar
  /// lemma); a crossing test stops at the first crossing point
  /// (CurveIntersectionOptions::stop_at_first_crossing).
  bool shortcuts = true;
};

struct GreedyPantsCurve {
  Word marking_word;  ///< in the marking's letters
  Word word;          ///< in the caller's canonical letters (Dehn-reduced)
  double length = 0;
};

struct GreedyPantsDecomposition {
  /// Up to 3g − 3 curves, in the order chosen (ascending length).
  std::vector<GreedyPantsCurve> curves;
  bool complete = false;  ///< 3g − 3 curves were found
  double total = 0;       ///< Σ lengths
  /// Candidates listed and examined; rejected as self-crossing, as crossing
  /// a chosen curve, as a chosen curve again; not evaluable.
  size_t candidates = 0, examined = 0, self_crossing = 0, crossing = 0, duplicates = 0, not_evaluable = 0;
  /// Calls of curve_intersection made (the cost: each tries up to
  /// |u| · |ball| · |v| lifts).
  size_t intersection_tests = 0;
  double time_s = 0;
};

/// The greedy decomposition (file comment). `marking`: a short marking of
/// `lengths` (short_marking()); `extra_curves`: more candidates, words in
/// the caller's canonical letters (e.g. PantsDecomposition::curves' words).
GreedyPantsDecomposition greedy_pants_decomposition(const SurfaceGroupLengths& lengths, const ShortMarking& marking,
                                                    const std::vector<Word>& extra_curves = {},
                                                    const GreedyPantsOptions& options = {});

struct GreedyPantsClassOptions {
  /// Starts: the signed handle pairings of the two short markings
  /// (geometric_classes() without its descent, its `pairings` and every
  /// half turn), the `starts` (default 8) lowest by the cost below descend.
  int starts = 8;
  /// Descent: single twist moves (topology/mapping_class_search.h,
  /// Lickorish, chain and separating twists) on either side, the best while
  /// it lowers the cost by more than 1e-9 relative, at most `max_steps`
  /// (default 30) steps; no step starts after a start's share of
  /// `length_budget` (default 400000 new length evaluations in all, a few
  /// seconds in genus 4).
  int max_steps = 30;
  size_t length_budget = 400000;
  /// When no single move lowers the cost: the best pair of moves, if there
  /// are at most this many pairs (default 1000: genus 2, 28 one-sided moves
  /// on either side, 784 pairs).
  size_t max_pairs = 1000;
  /// Weight of the twist term against the pants term (default 0.25).
  double twist_weight = 0.25;
  /// Classes returned (default 4), lowest cost first, distinct maps.
  int max_classes = 4;
};

struct GreedyPantsClass {
  GroupMap theta;    ///< X canonical letter -> word in Y's canonical letters
  GroupMap inverse;  ///< Y canonical letter -> word in X's (θ^-1, exact)
  /// Pants term: the mean of (log ℓ_X(c) − log ℓ_Y(θ c))² over X's greedy
  /// curves c and of (log ℓ_Y(d) − log ℓ_X(θ^-1 d))² over Y's greedy curves
  /// d (0 when θ maps one decomposition onto the other with equal lengths).
  double pants_mismatch = 0;
  /// Twist term: the mean of (log ℓ_X(p) − log ℓ_Y(θ p))² over X's marking
  /// probes x_j, x_i x_j^±1 (marking_probes): the curves that cross the
  /// pants curves, which Dehn twists along them lengthen. Probes whose
  /// length in X is not evaluable are left out (they would count alike for
  /// every class); one not evaluable in Y under θ adds 1e6.
  double twist_mismatch = 0;
  double cost = 0;  ///< pants_mismatch + twist_weight · twist_mismatch
  /// Σ_c collar_modulus(ℓ_X(c)) ℓ_Y(θ c)² over X's greedy curves: a lower
  /// bound of the class's energy (disjoint simple curves have disjoint
  /// collars; docs/handle_classes.md "The lower bound"), as far as the
  /// curves' simplicity and disjointness verdicts hold.
  double collar_bound = 0;
  std::string description;  ///< e.g. "greedy pants from marking handles 1->2, 2->1, then 5 twists"
};

/// Classes X -> Y that pair the two greedy decompositions' curves by length
/// and match the twists (docs/handle_classes.md "Greedy pants classes"):
/// from the signed handle pairings of the two short markings, a descent by
/// twists on either side on pants_mismatch + twist_weight · twist_mismatch,
/// carrying θ^-1 along (each move's exact inverse). Unlike pants_classes()
/// the two decompositions need not be of one combinatorial type (nor
/// complete): when they are not, the pants term is the best compromise
/// between mapping X's short curves to short curves of Y and back. Throws
/// InputError on unequal genus.
std::vector<GreedyPantsClass> greedy_pants_classes(const SurfaceGroupLengths& source, const ShortMarking& source_marking,
                                                   const GreedyPantsDecomposition& source_pants,
                                                   const SurfaceGroupLengths& target, const ShortMarking& target_marking,
                                                   const GreedyPantsDecomposition& target_pants,
                                                   const GreedyPantsClassOptions& options = {});

/// How many of `curves` (caller's canonical letters) are curves of the
/// greedy decomposition `greedy` (the same closed geodesic up to
/// orientation: a lift on its axis, or the same length and the same
/// intersection numbers with the marking's generators): 3g − 3 when the two decompositions
/// are the same.
int shared_pants_curves(const SurfaceGroupLengths& lengths, const ShortMarking& marking,
                        const GreedyPantsDecomposition& greedy, const std::vector<Word>& curves);

}  // namespace surfmap
