#pragma once
// The class search of the genus >= 2 ranking (SurfaceMapOptions::
// homotopy.search; topology/mapping_class_search.h; docs/method.md):
// when the best class on the coarse copy is far from the conformal bound
// 8 pi (g - 1), (1) lifted classes from more source cuts, then (2) a greedy
// descent over Dehn twists, every class evaluated by a converged solve on
// the coarse copy. Internal to src/map/hyperbolic_map.cpp.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "class_data.h"
#include "homotopy_classes.h"
#include "surfmap/map/class_lower_bound.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/mapping_class_search.h"

namespace surfmap::detail {

/// A class solved on the coarse copy: its map, coarse edges and converged solve.
struct CoarseEvaluation {
  GroupMap theta;
  std::vector<WeightedEdge> edges;
  HyperbolicHarmonicResult result;
  /// Why the solve returned false ("" when it succeeded): the SolveError's
  /// text, "not converged ...", "non-finite ..." or "pruned: curve bound ...".
  std::string failure;
};

/// Solves class theta on the coarse copy from the origin; false when the
/// solve fails, does not converge or is not finite (ev->failure says which).
using CoarseSolve = std::function<bool(const GroupMap& theta, CoarseEvaluation* ev)>;

/// A class found by the search, ready to be appended to the candidates.
struct FoundClass {
  HomotopyClass hc;  ///< description set; map and homology from `evaluation`
  ClassData data;
  CoarseEvaluation evaluation;
};

/// Stage 1: lifts from options.homotopy.search.cuts more cuts (`lifter`,
/// bases spread over the source's `num_vertices`; their source-only parts
/// prepared first on `threads` threads), each new class's data built by
/// `data_of` and solved on the coarse copy, lowest screen first, until one
/// comes within homotopy.search.gap of `conformal_bound`. Counts the classes
/// tried in info.cut_classes and the seconds in info.cuts_time_s.
std::vector<FoundClass> classes_from_more_cuts(CutLifter& lifter, SourceCuts& cuts, const ClassSpace& space,
                                               int num_vertices, int threads, double conformal_bound,
                                               const std::function<ClassData(const GroupMap&)>& data_of,
                                               const CoarseSolve& solve_coarse, const SurfaceMapOptions& options,
                                               HomotopySearchInfo& info);

/// Stage 1b (issue 14; docs/handle_classes.md "Geometric candidates"):
/// classes from short markings of the two surfaces' hyperbolic metrics
/// (map/geometric_classes.h), from short pants decompositions with
/// Fenchel–Nielsen twists (map/pants_classes.h) and, with
/// options.homotopy.search.greedy_pants, from the greedy short pants
/// decompositions (map/greedy_pants.h greedy_pants_classes; info's
/// greedy_pants fields): `source`/`target` lengths
/// in the default cut's canonical letters; the classes new by fingerprint
/// against `known`, at most options.homotopy.search.geometric of each kind,
/// lowest curve lower bound first (`bound_of`), each solved on the coarse
/// copy by `solve_coarse` (which prunes by the bound). Fills
/// info.geometric_* (both kinds) and the markings. `target_letters`
/// (optional, 2g words): when `target` reads another canonical basis than
/// `space` (HomotopySearchOptions::geometric_layout_basis), each of its
/// canonical letters as a word in the space's target letters; every class
/// is written in those before anything else reads it.
/// Issue 13 (session 25; HomotopySearchOptions::geometric_layout_basis):
/// the short canonical basis of a layout's boundary word `layout_word`
/// (CanonicalSchemaOptions::short_generators; `layout_schema`, generators
/// in the layout's letters) and each of its 2g generators as a Dehn-reduced
/// word in the canonical letters of `class_generators` (2g words in the
/// same layout letters generating the group; `class_letters`, their
/// schema's inverse, is tried first): `in_class_letters`. Exact up to one
/// common conjugation (invert_canonical_generators), which changes no
/// class. False with `why` when the class generators cannot be inverted.
bool layout_short_basis(const Word& layout_word, const std::vector<Word>& class_generators,
                        const std::vector<Word>& class_letters, CanonicalSchema* layout_schema,
                        GroupMap* in_class_letters, std::string* why);

std::vector<FoundClass> geometric_candidate_classes(const SurfaceGroupLengths& source, const SurfaceGroupLengths& target,
                                                    const ClassSpace& space, const std::vector<GroupMap>& known,
                                                    const std::function<double(const GroupMap&)>& bound_of,
                                                    const std::function<ClassData(const GroupMap&)>& data_of,
                                                    const CoarseSolve& solve_coarse, const SurfaceMapOptions& options,
                                                    HomotopySearchInfo& info, const GroupMap* target_letters = nullptr);

/// Stage 2: the twist search from `start_map` (candidate `start_index`,
/// composed with `start_twists`, testing/map_hooks.h; `start_energy` its
/// coarse energy, re-evaluated when twists are given). Fills `info` (moves,
/// energies, evaluations, stop reason, seconds) and returns the coarse
/// evaluation of the class reached when it improved on the start.
/// `source_moves`, `target_moves` (issue 13, session 27): one-sided moves
/// in `space`'s letters (TwistSearchOptions::source_moves, target_moves:
/// the twists along the surfaces' short curves); a start twist may also
/// name a source move. `high_kicks` (issue 14, session 28): no descent,
/// only HomotopySearchOptions::high_kicks kicks from the start, with their
/// own budget of high_kicks x (1 + kick_evaluations) solves.
std::optional<CoarseEvaluation> twist_class_search(const GroupMap& start_map, int start_index, double start_energy,
                                                   const ClassSpace& space, const CoarseSolve& solve_coarse,
                                                   const std::vector<std::string>& start_twists,
                                                   const SurfaceMapOptions& options, HomotopySearchInfo& info,
                                                   const std::vector<MappingClassMove>& source_moves = {},
                                                   const std::vector<MappingClassMove>& target_moves = {},
                                                   bool high_kicks = false);

/// Issue 13 (session 27; HomotopySearchOptions::curve_twists): the twists
/// along a surface's short curves (map/pants_classes.h short_curve_twists
/// from its short marking and short pants decomposition, `lengths` in the
/// class letters), each followed by its inverse, named "T(marking b3)",
/// "T(pants s2)^-1" (short_curve_twists' names);
/// `lengths_text` gets their curves' lengths, ascending.
std::vector<MappingClassMove> short_curve_moves(const SurfaceGroupLengths& lengths, std::string* lengths_text);

}  // namespace surfmap::detail
