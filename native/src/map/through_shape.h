#pragma once
// The through-shape step (issue 14; docs/handle_classes.md "Through generated shapes"). Not public
// API (used by surface_map.cpp).
#include "surfmap/map/surface_map.h"
#include "surfmap/topology/handle_basis.h"
#include "two_way_run.h"

namespace surfmap::detail {

/// The class of source -> middle composed with the class of middle ->
/// target, in the letters of a source -> target run with `options`' loops:
/// middle_to_target ∘ ι_M^-1 ∘ source_to_middle, where ι_M^-1
/// (middle_to_target.source_as_target_inverse) rewrites the middle shape's
/// letters as a target into its letters as a source. Empty, with `why`, when
/// a run reported no class words or letters.
std::vector<std::vector<int>> composed_class(const SurfaceMapResult& source_to_middle,
                                             const SurfaceMapResult& middle_to_target, std::string& why);

/// A generated shape the source is mapped onto and the target from.
struct MiddleShape {
  std::string name;  ///< e.g. "genus-4 n-hole torus"
  TriMesh mesh;
};

/// The generated shapes of genus g the step maps through, cheapest first:
/// samples::cad_plate(g) (holes in a row, 4 (g + 1) + 128 g vertices) and
/// samples::n_hole_torus(g, resolution) (genus <= 8; a wheel from 5 on).
/// What could not be generated is said in `notes` ("; ..." each).
std::vector<MiddleShape> middle_shapes(int genus, int resolution, std::string& notes);

/// Whether `a` is `b` itself: the same faces, and the same vertices up to a
/// translation and a scale, to 1e-6 of the bounding box diagonal.
bool same_shape(const TriMesh& a, const TriMesh& b);

/// Whether the through-shape step runs for `forward` (after the two-way
/// run) at threshold `ratio` (HomotopyOptions::through_shape_ratio), read the
/// same way from either direction (session 29, branch class30): when its
/// energy ratio is at least `ratio`; else, when the two directions agree
/// (directions.outcome "inverse" or "symmetric: both optimal"), when this
/// class inverted is at `ratio` or more in the other direction
/// (directions.inverse_there_ratio), whose own run then takes the step;
/// else (not agreed) when the larger of the two one-way ratios
/// (`one_way_ratio`, this direction's first run, and
/// directions.other_one_way_ratio; NaN: unknown) is at least `ratio`. `why`:
/// "" when the ratio here reached it, else the reason (run or not run).
bool through_shape_reached(const SurfaceMapResult& forward, double one_way_ratio, double ratio, std::string& why);

/// Genus >= 2, HomotopyOptions::through_shape, default class, no landmarks:
/// when through_shape_reached, the
/// step through every shape of middle_shapes that is neither the source nor
/// the target itself (through_shapes_map, stopping at legs that cannot
/// help). Always sets through_shape_status (and through_shape_time_s when it
/// ran).
/// `target_letters_inverse`: the other direction's source_as_target_inverse
/// (two_way_map's), for the search in both directions (through_shapes_map).
/// `one_way_ratio`: this direction's energy ratio before the two-way run
/// (NaN when its one-way run failed).
void through_shape_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                       SurfaceMapResult& forward, const MapFunction& map,
                       const std::vector<std::vector<int>>& target_letters_inverse = {},
                       double one_way_ratio = std::numeric_limits<double>::quiet_NaN());

/// The step through the given shapes, whatever `forward`'s ratio: per shape
/// M, maps the source onto M and M onto the target (`map`, the two-way run
/// as in `options`) and composes their classes; with
/// `stop_at_legs_that_cannot_help`, a leg whose energy ratio is not below
/// `forward`'s ends that shape's attempt (its composed class would be about
/// as far from conformal as that leg at least), unless the leg retried in
/// `forward`'s class composed with the other end's leg and searched on
/// (source -> M: with target -> M; M -> target: forward's class inverted
/// with source -> M, searched on target -> M and inverted here; session
/// 20) is below it. The composed classes are
/// solved here together (HomotopyOptions::given_class, one after another:
/// ranked like any candidates, the best at full resolution), all listed
/// after `forward`'s candidates ("through a generated <name>"); when the
/// best is lower than `forward`'s energy its map is returned in `forward`
/// and it is chosen, unless the search in both directions below compared
/// pairs and `forward`'s class θ0 with θ0^-1 solved alone in the other
/// direction makes a pair of no higher total energy than the pair kept
/// there: then `forward` stays (session 28, branch class29: a class lower
/// here only would leave the two directions on different classes). `notes` (each "; ...") start the status. With the
/// two-way run on and `target_letters_inverse` (the target's letters as a
/// target -> as a source, 2g words, from a target -> source run with
/// reverse_options) given, the composed classes are then searched in both
/// directions (composed_classes_both_ways).
void through_shapes_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                        SurfaceMapResult& forward, const MapFunction& map, const std::vector<MiddleShape>& middles,
                        bool stop_at_legs_that_cannot_help, std::string notes = {},
                        const std::vector<std::vector<int>>& target_letters_inverse = {});

/// The two legs a composed class came from (through_shapes_map), for
/// inverting it factor by factor when its own words do not invert
/// (composed_classes_both_ways; docs/handle_classes.md "Through generated shapes").
struct ComposedLegs {
  /// The source -> M leg's class (the source's cut letters -> M's letters
  /// as a target), 2g words.
  GroupMap onto;
  /// The M -> target leg's class (M's cut letters -> the target's letters
  /// as a target) and M's letters as a target -> as a source
  /// (its source_as_target_inverse), 2g words each.
  GroupMap from, middle_letters_inverse;
  /// When the M -> target leg is a target -> M run's class inverted
  /// (leg_back_through_the_first_run): that class (the target's cut letters
  /// -> M's letters as a target), the leg's exact inverse; else empty.
  GroupMap from_inverse;
};

/// Issue 14, session 19 (docs/handle_classes.md "Through generated shapes"): `forward` is
/// this direction's result after the composed classes (`composed`, 2g words each in this run's letters,
/// named by `names`) were solved and searched on here, with class θ. The
/// composed classes, inverted and written in the other direction's letters
/// (through `forward`'s and `target_letters_inverse`), are solved and
/// searched on in the other direction (target -> source, one given-class
/// run), which ends on a class ψ. Unless ψ is θ's inverse, θ^-1 is solved
/// there alone and ψ^-1 here alone, and the pair of inverse classes with
/// the lower sum of energy ratios, (θ, θ^-1) or (ψ^-1, ψ), is kept:
/// `forward` becomes the ψ^-1 result when that pair is lower. When θ^-1
/// cannot be solved there, (ψ^-1, ψ) is taken only when ψ^-1 is lower here
/// than θ (else θ is kept, the directions not compared). The other
/// direction's own run, from the same composed classes inverted, meets the
/// same two searches and the same four energies, so both directions end on
/// one pair of inverse classes. A composed class that cannot be inverted
/// (invert_automorphism stalls) is replaced there by the other direction's
/// own composed class through the same shape (`middles[k]`, the shape of
/// composed class k; null or missing: none), from its two legs target -> M
/// and M -> source. Returns the status text ("; both
/// directions: ..."); `forward.directions` says "inverse" when agreed.
/// Before that fallback, a composed class whose legs are known (`legs[k]`)
/// is inverted factor by factor (invert_product: the source -> M leg and
/// the M -> target leg each inverted, or the latter's known inverse), since
/// the composite's long words can stall where the legs' do not (torus g4 ->
/// fertility, session 21).
/// `kept_pair_total` (when given): the total energy (E here + E' there, not
/// divided by the bound) of the pair of inverse classes `forward` ends on,
/// NaN when no pair was compared.
std::string composed_classes_both_ways(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                       const std::vector<std::vector<std::vector<int>>>& composed,
                                       const std::vector<std::string>& names,
                                       const std::vector<std::vector<int>>& target_letters_inverse,
                                       SurfaceMapResult& forward, const MapFunction& map,
                                       const std::vector<const TriMesh*>& middles = {},
                                       const std::vector<ComposedLegs>& legs = {},
                                       double* kept_pair_total = nullptr);

}  // namespace surfmap::detail
