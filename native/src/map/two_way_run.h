#pragma once
// The quality signal of a genus >= 2 result and the two-way run
// (docs/handle_classes.md, issue 14): when the chosen class's energy is far
// above the conformal bound 8 pi (g - 1), the pair is also mapped the other
// way, and the source's loops carried by that map's inverse give one more
// candidate class. Not public API (used by surface_map.cpp).
#include <functional>
#include <string>

#include "surfmap/map/class_lower_bound.h"  // conformal_bound
#include "surfmap/map/surface_map.h"

namespace surfmap::detail {

/// The public surface_map (the two-way run calls it with two_way off).
/// x with four significant digits (printf %.4g), as the quality statuses write
/// energies and ratios.
std::string four_digits(double x);

using MapFunction = std::function<SurfaceMapResult(const TriMesh&, const TriMesh&, const SurfaceMapOptions&)>;

/// Genus >= 2: SurfaceMapResult::energy_ratio (the chosen class's free
/// energy over 8 pi (g - 1)), quality_warning (plain words when the ratio is
/// 3 or more: the class may be twisted) and reverse_check (whether the
/// chosen class is one from the other direction). NaN / empty for genus < 2.
void assess_quality(SurfaceMapResult& result);

/// After the two-way run: when the ratio is warned about (3 or more) and the
/// two directions' classes were compared and found inverse (or inverse up to
/// an isometry), the warning says so too: both searches end on this pair of
/// classes, which does not prove it the best (fertility -> genus-4 CAD plate:
/// 6.65 x, and a class at 5.14 x exists, found through a third shape) nor
/// rules out that the shapes are conformally far apart
/// (docs/history/handle_classes.md "Is a better class reachable"). Once per result.
void qualify_quality_warning(SurfaceMapResult& result);

/// Genus >= 2, HomotopyOptions::two_way: maps the other way when `forward`
/// is at least two_way_ratio x the conformal bound, and when that direction
/// is better, maps again with the source's loops carried by its inverse as
/// one more candidate; `forward` becomes the lower-energy result
/// (two_way_status, two_way_time_s set). When that result's class and the
/// other direction's are not inverse ("different"), the other direction is
/// mapped once more given this class, and the pair of inverse classes of
/// lower total energy is kept in both (docs/handle_classes.md "The two directions today"; `forward`
/// is mapped again in the other direction's
/// class inverted when that pair is lower). When the other direction's
/// ratio is not lower (HomotopyOptions::cheap_direction_check), its class
/// inverted is solved here alone and this class inverted there alone, with
/// the same rules ("Both directions, cheaply"). Below two_way_ratio, at
/// HomotopyOptions::agreement_ratio or more, the other direction is mapped
/// one way and the pair of inverse classes of lower total energy is kept
/// (ties by a fixed order of the two meshes; directions.agreement says
/// what was done; docs/handle_classes.md "The two directions today"). Nothing for a
/// requested class.
/// `target_letters_inverse` (when given): the other direction's
/// source_as_target_inverse (the target's letters as a target -> its
/// letters as a source, 2g words) when that direction was mapped, for the
/// through-shape step's search in both directions; else left as it is.
void two_way_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                 SurfaceMapResult& forward, const MapFunction& map,
                 std::vector<std::vector<int>>* target_letters_inverse = nullptr);

/// A requested class index (homotopy.class_index) beyond the one-way
/// candidates: the two-way run's added class (its index in a default run's
/// result). Maps the other way and then this way with that candidate, into
/// `out`; false when the two-way run does not apply (the caller rethrows).
bool map_requested_two_way_class(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                 SurfaceMapResult& out, const MapFunction& map);

/// Genus >= 2 with the two-way run on, when every candidate class of the
/// one-way run folded (`failure`: its "no candidate class gave a bijective
/// map" error): maps the other way, and when that direction gives a map,
/// solves here the class of the source's loops carried by its inverse alone
/// (HomotopyOptions::images_only), or, when those loops do not carry, its
/// class inverted algebraically (reverse_class_only); when that folds too or
/// the other direction fails, and the source's base vertex was automatic,
/// maps once more one way from the cuts at the source's middle vertex
/// (loops.source_base_vertex = #V / 2, no two-way run). Into `out`
/// (two_way_status says which). False when the two-way run does not apply
/// or every attempt fails; `why` then says what failed (the caller adds it
/// to the one-way error).
/// docs/handle_classes.md "The two directions today".
/// `target_letters_inverse` as in two_way_map. The other direction's run
/// and the cuts at the middle vertex make no retry after folds of their own
/// (LoopOptions::fold_fallback off: the caller's run makes it once). With
/// `another_cut_left` given, when the other direction fails the cuts at the
/// middle vertex are left to the caller (for after its retry after folds,
/// docs/robustness.md "Canonical generators"): false, with
/// *another_cut_left set and `why` the other direction's failure.
bool rescue_by_the_other_direction(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                   SurfaceMapResult& out, const MapFunction& map, std::string& why,
                                   std::vector<std::vector<int>>* target_letters_inverse = nullptr,
                                   bool* another_cut_left = nullptr);
/// The rescue's last attempt: the source's cuts at its middle vertex
/// (loops.source_base_vertex = #V / 2), mapped one way with the class
/// searched in those cuts, no retry after folds. False (and `why` extended)
/// when a base vertex was given or it fails; else `out` is its map.
bool rescue_by_another_cut(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                           SurfaceMapResult& out, const MapFunction& map, std::string& why);

/// The class chosen for target -> source (`reverse`), written in the
/// letters of a source -> target run (`forward`): ι_S^-1 ∘ ψ ∘ ι_T^-1 with ψ
/// the reverse's chosen class (its source's cut letters -> its target's
/// letters) and ι the identity overlays of each surface's cut letters onto
/// its letters as a target (SurfaceMapResult::source_as_target), 2g words:
/// the form of HomotopyOptions::reverse_class. Empty, with `why`, when a
/// piece is missing.
std::vector<std::vector<int>> reverse_class_here(const SurfaceMapResult& forward, const SurfaceMapResult& reverse,
                                                 std::string& why);

/// The chosen class's energy as the ranking compared it: the intrinsic
/// Delaunay one when the map itself fell back to own-edge weights (the
/// other candidates' energies are intrinsic). NaN without a chosen class.
double chosen_energy(const SurfaceMapResult& r);
/// The agreement step's tie between two pairs of inverse classes' total
/// energies: both finite and within 1e-6 of each other. (An unsolved class
/// counts infinite, and |x - inf| <= 1e-6 inf holds for every x: taken for
/// a tie, an unsolved class inverted was adopted, an empty map; session 25.)
bool pair_totals_tie(double own_pair, double other_pair);

/// `options` without what belongs to the run they were given for, the one
/// list of what reverse_options, one_way_options (through_shape.cpp) and
/// single_class_options(.., SingleClass::Alone) clear: no class index, no
/// class words, no two-way run, no through-shape step, no source images, no
/// landmarks (the classes are ranked by their free energies) and no
/// solve-progress callback. A new option that must not pass from a run to
/// the runs it makes is cleared here.
SurfaceMapOptions without_the_runs_own(SurfaceMapOptions options);

/// The options of the other direction's run: without_the_runs_own, base
/// vertices swapped.
SurfaceMapOptions reverse_options(const SurfaceMapOptions& options);

/// What single_class_options clears besides the class search.
enum class SingleClass {
  /// Nothing more: the caller's landmarks, through-shape flag, class index
  /// and source images stay as `options` has them (the callers pass options
  /// that already lack what must not apply: the run's own options from
  /// paths that run only without a class index or source images, where the
  /// landmarks are held in the class too; or reverse_options,
  /// one_way_options, the through-shape legs' options).
  KeepTheRest,
  /// Also without_the_runs_own (no class index, no through-shape step, no
  /// source images, no landmarks, no solve-progress callback): the class's
  /// free energy alone (agree_below_two_way_ratio compares pairs of inverse
  /// classes by their free energies).
  Alone,
};

/// Options that solve one class alone (issue 14): `reverse_class` (the
/// other direction's class, in the letters of the run these options are
/// for) inverted algebraically is the only candidate
/// (HomotopyOptions::reverse_class_only), so no ranking, class search or
/// geometric classes; always no two-way run and no directions' comparison,
/// and no class_words (the one class is this one); what else is cleared:
/// `scope`.
SurfaceMapOptions single_class_options(SurfaceMapOptions options, std::vector<std::vector<int>> reverse_class,
                                       SingleClass scope);

}  // namespace surfmap::detail
