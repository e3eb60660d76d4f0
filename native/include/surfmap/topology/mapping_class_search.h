#pragma once
// Local search in the mapping class group for the homotopy class of least
// harmonic energy (docs/method.md §2.10).
//
// A class of maps S1 -> S2 between closed surfaces of genus g >= 2 is an
// isomorphism theta of the canonical surface groups (topology/handle_basis.h);
// every other class is theta ∘ phi for a mapping class phi of S1 (an
// automorphism of pi_1 sending the relator R to a conjugate of R, preserving
// orientation), or equivalently psi ∘ theta for one of S2. The candidate
// families of map/hyperbolic_map.cpp (overlays, canonical schemata, signed
// handle permutations and their lifts) pick theta from the loops of one cut,
// and when that cut's loops are skewed the best of them can be a twisted
// version of the geometric class: the same action on homology but composed
// with twists along some curve (a separating curve: a Torelli element), or
// off by a twist along a handle's curve. The harmonic energy of a class
// grows with such twists, so a greedy descent over a generating set of the
// mapping class group, each neighbour ranked by a converged solve on a
// coarse copy of the source, walks back towards the geometric class.
//
// Moves (all exact automorphisms of < x_1..x_2g | [x1,x2]...[x2g-1,x2g] >
// fixing the relator itself, letters a_i = x_2i-1, b_i = x_2i):
//  - T(a_i): the Dehn twist along a_i, b_i -> b_i a_i (homology b_i += a_i);
//  - T(b_i): along b_i, a_i -> a_i b_i^-1 (a_i -= b_i; the same handedness:
//    every twist acts on homology as x -> x + <c, x> c, c the curve's class);
//  - T(c_i), i < g: along the chain curve c_i = M_i(a_i) ~ a_i a_i+1 through
//    handles i and i+1, M_i the adjacent handle mixing of handle_basis.h:
//    T(c_i) = M_i T(a_i) M_i^-1 (a Dehn twist along the image of a simple
//    curve under a homeomorphism). The twists along a_i, b_i, c_i are
//    Lickorish's 3g - 1 generators of the mapping class group, so every
//    class is reachable;
//  - T(s_j), j < g: along the separating curve s_j = [a1,b1]...[aj,bj]
//    (conjugates handles 1..j by s_j): Torelli elements, which the
//    Lickorish twists reach only through long products (the 2-chain
//    relation (T(a)T(b))^6 = T(boundary)), while wrong lifts typically
//    differ from the geometric class by exactly such twists;
//  - with `torelli_conjugates`: T(s_j) conjugated by the Lickorish twists of
//    the handles on both sides of s_j (L T(s_j) L^-1 = T(L(s_j)), the twist
//    along another separating curve);
//  - with `bounding_pairs`, genus >= 3: bounding pair maps T(d) T(d')^-1
//    (d, d' disjoint, homologous, together bounding a genus-1 piece), from
//    the chain relation; for genus >= 3 such maps generate the Torelli group
//    (a known theorem), which separating twists alone do not (only these 4(g - 1)
//    are listed, not their conjugates).
// Each comes with both directions (the move and its inverse).
#include <functional>
#include <string>
#include <vector>

#include "surfmap/topology/handle_basis.h"

namespace surfmap {

struct MappingClassMove {
  std::string name;  ///< e.g. "T(a1)", "T(c2)^-1", "T(b2) T(s1) T(b2)^-1"
  SurfaceAutomorphism automorphism;
};

/// The moves listed in the file comment for `genus` >= 2, each followed by
/// its inverse: T(a_i), T(b_i) (i = 1..g), T(c_i), T(s_i) (i < g), and with
/// `torelli_conjugates` L T(s_j) L^-1 for the 20 conjugators L = T(c_j)^±1,
/// T(c_j)^±2, X T(c_j)^±1 with X = T(a_j)^±1, T(b_j)^±1, T(a_j+1)^±1,
/// T(b_j+1)^±1 (the other Lickorish twists commute with T(s_j)): 8g - 4
/// moves, at most 48g - 44 with the conjugates (those equal as words to an
/// earlier move are left out: 37 of 52 remain in genus 2). Every move is checked with
/// is_surface_automorphism; throws InputError for genus < 2.
/// With `bounding_pairs` (genus >= 3): 4(g - 1) more, T(a_j+1)^2 (T(a_j)
/// T(b_j) T(c_j))^-4 and T(a_j)^2 (T(c_j) T(b_j+1) T(a_j+1))^-4 and their
/// inverses (bounding pair maps by the chain relation,
/// mapping_class_search.cpp), each checked to be a nontrivial Torelli element.
std::vector<MappingClassMove> twist_moves(int genus, bool torelli_conjugates = true, bool bounding_pairs = true);

struct TwistSearchOptions {
  /// Most moves taken (default 6).
  int max_steps = 6;
  /// Most energy evaluations in all (default 40), and per step (default 8:
  /// the neighbours with the lowest screening score first).
  int max_evaluations = 40;
  int evaluations_per_step = 8;
  /// A neighbour must lower the energy by more than this fraction of the
  /// current energy to be moved to (default 1e-3: below the coarse copies'
  /// discretisation differences between classes).
  double tolerance = 1e-3;
  /// Neighbours whose words (the 2g images, summed) exceed this many letters
  /// are skipped (default 4000).
  size_t max_letters = 4000;
  /// Before the energy descent: up to this many steps of descent on the
  /// screening score alone (no energy evaluations; default 40). Its end
  /// point is evaluated, and the energy descent starts from it when it has
  /// the lower energy.
  int screen_steps = 40;
  /// Moves on the source side (theta ∘ phi) and on the target side
  /// (phi ∘ theta); both by default.
  bool source_side = true, target_side = true;
  /// Issue 13 (session 27; docs/history/robustness.md "Session 27 (branch edge27)"): more moves for one
  /// side only, beside twist_moves' (which act on both sides): source_moves
  /// as theta ∘ m, target_moves as m ∘ theta (automorphisms of the source's
  /// and of the target's canonical letters; e.g. the Dehn twists along
  /// either surface's short curves, map/pants_classes.h
  /// short_curve_twists), each listed with its inverse by the caller.
  /// Screened, evaluated, paired and kicked like the others; their
  /// neighbours are named "source <name>" / "target <name>". Default none.
  std::vector<MappingClassMove> source_moves, target_moves;
  /// When no single move improves: pairs of moves, the best
  /// `pair_starts` neighbours of that step (lowest energy) each composed
  /// with every move again, screened, and up to evaluations_per_step of the
  /// new ones evaluated, lowest screen first (default true, 3).
  bool pair_moves = true;
  int pair_starts = 3;
  /// Issue 14 (session 26; docs/handle_classes.md "The search, restarted"): iterated
  /// local search. After the descent stops, this many kicks (default 0:
  /// none): the best class so far composed with `kick_moves` moves, each
  /// drawn at random (seeded by `kick_seed`) among the `kick_choices`
  /// neighbours of lowest screen (within max_letters, finite screen), its
  /// energy evaluated, then a descent from it (these options without kicks
  /// or screening descent, at most `kick_evaluations` evaluations); its end
  /// replaces the best class when lower by more than the tolerance. Every
  /// evaluation counts against max_evaluations. twist_search throws
  /// InputError for a count below its least (kicks, max_steps, max_evaluations,
  /// screen_steps, pair_starts: 0; kick_moves, kick_evaluations, kick_choices,
  /// evaluations_per_step: 1) or a negative or non-finite tolerance.
  int kicks = 0;
  int kick_moves = 3;
  int kick_evaluations = 24;
  int kick_choices = 16;
  unsigned kick_seed = 1;
  /// Issue 14 (session 28): no screening descent and no descent from the
  /// start, which is taken as a local minimum already searched: only the
  /// kicks, each followed by its descent as above (default false).
  bool kicks_only = false;
};

/// One evaluated neighbour of the search.
struct TwistSearchEvaluation {
  int step = 0;          ///< step at which it was evaluated (0-based)
  std::string move;      ///< "source T(a1)" or "target T(s1)^-1"
  double screen = 0;     ///< its screening score
  double energy = 0;     ///< its energy (infinite when the evaluation failed)
};

struct TwistSearchResult {
  /// The class reached (words reduced by Dehn's algorithm), its energy, and
  /// the start's.
  GroupMap best;
  double start_energy = 0, energy = 0;
  /// The moves taken, in order, and the energy after each.
  std::vector<std::string> moves;
  std::vector<double> energies;
  /// Every energy evaluation, in order.
  std::vector<TwistSearchEvaluation> evaluations;
  /// Calls of `screen`: the start's, every neighbour generated within
  /// max_letters, and the kicks' descents' (a kick's end is its last move's
  /// neighbour, not screened again).
  int screened = 0;
  /// The screening descent: moves taken and the score after each.
  std::vector<std::string> screen_moves;
  std::vector<double> screen_scores;
  /// Steps taken by a pair of moves (TwistSearchOptions::pair_moves).
  int pair_steps = 0;
  /// Kicks made (TwistSearchOptions::kicks; one with no neighbour to move
  /// to is not made) and how many of them ended below the best class held
  /// before them.
  int kicks = 0, improving_kicks = 0;
  /// "no improving neighbour", "no improving neighbour or pair", "step
  /// budget", "evaluation budget"; with kicks followed by "; N kicks, M
  /// lower".
  std::string stop_reason;
};

/// Greedy descent from `start` (source canonical generator j+1 -> word in the
/// target's canonical generators) whose energy is `start_energy`. Each step
/// forms every neighbour theta ∘ m and m ∘ theta for the moves m of
/// twist_moves(genus), drops those already seen (same screening score to
/// 1e-9 relative: the score is meant to be conjugation invariant, e.g. built
/// from target lengths of images) or too long, evaluates up to
/// evaluations_per_step of them with `energy` in increasing order of
/// `screen`, and moves to the lowest when it improves by more than the
/// tolerance. `energy` returns +inf for a neighbour it cannot evaluate;
/// `screen` returns +inf for one not to evaluate at all.
TwistSearchResult twist_search(const GroupMap& start, double start_energy, int genus,
                               const std::function<double(const GroupMap&)>& screen,
                               const std::function<double(const GroupMap&)>& energy,
                               const TwistSearchOptions& options = {});

}  // namespace surfmap
